//! Numbers of a BVH frame row.
//!
//! Nearly every value in real files is a plain decimal such as `-18.0446`, read by a byte
//! loop whose branches the processor predicts well (the fraction four digits at a time);
//! anything else (exponents, `nan`, very long numbers) goes to `fast_float2`, whose result
//! is checked like the others.

/// Parses the whitespace-separated numbers of one row into `values` (extra ones are only
/// counted) and returns how many there were, or the offending token.
#[inline]
pub(super) fn parse_row(line: &[u8], values: &mut [f32]) -> Result<usize, String> {
    let mut count = 0;
    let mut pos = 0;
    loop {
        while let Some(b' ' | b'\t' | b'\r' | b'\x0c') = line.get(pos) {
            pos += 1;
        }
        let rest = &line[pos..];
        if rest.is_empty() {
            return Ok(count);
        }
        let parsed = parse_plain_decimal(rest).map(Ok).unwrap_or_else(|| fast_float2::parse_partial::<f32, _>(rest));
        match parsed {
            Ok((v, used)) if v.is_finite() && rest.get(used).is_none_or(|b| b.is_ascii_whitespace()) => {
                if let Some(slot) = values.get_mut(count) {
                    *slot = v;
                }
                count += 1;
                pos += used;
            }
            _ => {
                let end = rest.iter().position(|b| b.is_ascii_whitespace()).unwrap_or(rest.len());
                return Err(String::from_utf8_lossy(&rest[..end]).into_owned());
            }
        }
    }
}

/// Negative powers of ten, each the nearest f64.
const INV_POW10: [f64; 16] =
    [1e0, 1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15];

/// Byte-at-a-time path for plain decimals (`-12.34567`) of at most 15 digits without an
/// exponent. The digits form an exact integer; scaling it by the f64 nearest a negative
/// power of ten errs by about 1e-16 relative (a multiply, several times cheaper than the
/// exactly rounded division), far below the final f32 rounding, so the result is within
/// one f32 ulp of the correctly rounded value. Anything else (exponents, `nan`, long
/// numbers) returns `None` for the general parser.
#[inline]
fn parse_plain_decimal(bytes: &[u8]) -> Option<(f32, usize)> {
    let mut pos = 0;
    let negative = match bytes.first() {
        Some(b'-') => {
            pos = 1;
            true
        }
        Some(b'+') => {
            pos = 1;
            false
        }
        _ => false,
    };
    // The integer digits, then (after a point) the fraction digits: two tight loops on
    // "is a digit", the count checked once at the end.
    let mut mantissa: u64 = 0;
    let integer_start = pos;
    while let Some(d) = bytes.get(pos).map(|b| b.wrapping_sub(b'0')).filter(|d| *d < 10) {
        mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(d));
        pos += 1;
    }
    let integer_digits = pos - integer_start;
    let mut fraction_digits = 0;
    if bytes.get(pos) == Some(&b'.') {
        pos += 1;
        let fraction_start = pos;
        // Four at a time first (CMU's decimals are four digits long).
        while let Some(four) = four_digits(&bytes[pos..]) {
            mantissa = mantissa.wrapping_mul(10_000).wrapping_add(four);
            pos += 4;
        }
        while let Some(d) = bytes.get(pos).map(|b| b.wrapping_sub(b'0')).filter(|d| *d < 10) {
            mantissa = mantissa.wrapping_mul(10).wrapping_add(u64::from(d));
            pos += 1;
        }
        fraction_digits = pos - fraction_start;
    }
    let digits = integer_digits + fraction_digits;
    if digits == 0 || digits > 15 || matches!(bytes.get(pos), Some(b'e' | b'E' | b'.')) {
        return None;
    }
    // At most 15 digits: exact as i64 and as f64, and i64 → f64 is one instruction where
    // u64 → f64 takes several on x86-64.
    let magnitude = mantissa as i64 as f64 * INV_POW10[fraction_digits];
    Some((if negative { -magnitude } else { magnitude } as f32, pos))
}

/// The value of `bytes[..4]` when those are four ASCII digits. Four bytes are read as one
/// little-endian word: each byte's high nibble must be 3 and its low nibble at most 9
/// (adding 6 must not carry out of it); then two multiply-adds combine the digits in pairs
/// and the pairs.
#[inline]
fn four_digits(bytes: &[u8]) -> Option<u64> {
    let word = u32::from_le_bytes(bytes.get(..4)?.try_into().ok()?);
    let all_digits = word & 0xF0F0_F0F0 == 0x3030_3030 && (word + 0x0606_0606) & 0xF0F0_F0F0 == 0x3030_3030;
    if !all_digits {
        return None;
    }
    let digits = u64::from(word - 0x3030_3030);
    // Bytes 0 and 2 become 10·d0 + d1 and 10·d2 + d3, then 100·(10·d0 + d1) + 10·d2 + d3.
    let pairs = (digits * 10 + (digits >> 8)) & 0x00FF_00FF;
    Some(((pairs * (1 + (100 << 16))) >> 16) & 0xFFFF)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A xorshift stream of numbers below `n`.
    fn stream(seed: u64) -> impl FnMut(u64) -> u64 {
        let mut state = seed;
        move |n| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        }
    }

    /// A random plain decimal of 1-15 digits with the point anywhere and any sign.
    fn random_decimal(next: &mut impl FnMut(u64) -> u64) -> String {
        let digits = 1 + next(15) as usize;
        let point = next(digits as u64 + 2) as usize;
        let mut text = String::from(["", "-", "+"][next(3) as usize]);
        for d in 0..digits {
            if d == point {
                text.push('.');
            }
            text.push(char::from(b'0' + next(10) as u8));
        }
        text
    }

    fn within_one_ulp(v: f32, expected: f32) -> bool {
        (v - expected).abs() <= expected.abs() * f32::EPSILON
    }

    /// Every four-digit string gives its value; a non-digit in any place (the bytes next to
    /// '0' and '9', a point, a space, a sign) is refused.
    #[test]
    fn four_digits_reads_every_four_digit_string_and_nothing_else() {
        for n in 0..10_000u64 {
            let text = format!("{n:04}");
            assert_eq!(four_digits(text.as_bytes()), Some(n), "{text}");
            for place in 0..4 {
                for bad in [b'/', b':', b'.', b' ', b'-', b'+', b'e', 0x80 | b'5'] {
                    let mut bytes = text.clone().into_bytes();
                    bytes[place] = bad;
                    assert_eq!(four_digits(&bytes), None, "{bytes:?}");
                }
            }
        }
        assert_eq!(four_digits(b"123"), None);
    }

    /// The byte loop agrees with the standard library's correctly rounded parser to within
    /// one f32 ulp, and declines what it does not handle.
    #[test]
    fn plain_decimal_path_agrees_with_std() {
        for text in ["0", "-0.0", "12.34567", "-179.99999", ".0083333", "5.", "-1234567.891", "0.000001", "+3.5"] {
            let (v, used) = parse_plain_decimal(text.as_bytes()).unwrap();
            let expected: f32 = text.parse().unwrap();
            assert_eq!(used, text.len(), "{text}");
            assert!(within_one_ulp(v, expected), "{text}: {v} vs {expected}");
        }
        let mut next = stream(0x853c_49e6_748f_ea9b);
        for _ in 0..20_000 {
            let text = random_decimal(&mut next);
            let expected: f32 = text.parse().unwrap();
            for tail in ["", " 1.5", "\t", "\r"] {
                let (v, used) = parse_plain_decimal(format!("{text}{tail}").as_bytes()).unwrap();
                assert_eq!(used, text.len(), "{text:?}{tail:?}");
                assert!(within_one_ulp(v, expected), "{text}: {v} vs {expected}");
            }
        }
        for text in ["1e5", "nan", "-", ".", "1234567890123456", "12345678901234567890123456789"] {
            assert!(parse_plain_decimal(text.as_bytes()).is_none_or(|(_, used)| used < text.len()), "{text}");
        }
    }

    /// Whole rows of mixed notations (plain, exponent, long, any separator) parse to the
    /// same values as splitting the row and parsing each token with std; a bad token is
    /// reported whole wherever it sits.
    #[test]
    fn rows_agree_with_std_token_by_token() {
        let mut next = stream(0xd1b5_4a32_d192_ed03);
        for _ in 0..2_000 {
            let count = 1 + next(70) as usize;
            let mut row = String::new();
            for _ in 0..count {
                let token = match next(10) {
                    0 => format!("{}e{}", random_decimal(&mut next), next(20) as i64 - 10),
                    1 => format!("{}", next(1_000_000_000)),
                    _ => random_decimal(&mut next),
                };
                row.push_str(&token);
                row.push_str([" ", "  ", "\t", " \t"][next(4) as usize]);
            }
            let expected: Vec<f32> = row.split_whitespace().map(|t| t.parse().unwrap()).collect();
            let mut values = vec![0.0; count];
            assert_eq!(parse_row(row.trim_end().as_bytes(), &mut values), Ok(count), "{row}");
            for (v, e) in values.iter().zip(&expected) {
                assert!(within_one_ulp(*v, *e), "{row}: {v} vs {e}");
            }
        }
        let mut values = [0.0; 8];
        for (row, bad) in [
            ("1.0 2.0 3.0 4.0 5.0 6.5x 7.0 8.0 9.0 10.0", "6.5x"),
            ("1.0 nan 3.0", "nan"),
            ("1.0 2.0 3.0 4.0 5.0 6.0 7.0 1e99", "1e99"),
            ("-12.5,3.0 4.0 5.0 6.0 7.0 8.0 9.0", "-12.5,3.0"),
        ] {
            assert_eq!(parse_row(row.as_bytes(), &mut values), Err(bad.to_string()), "{row}");
        }
    }
}
