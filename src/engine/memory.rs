//! The memory limit of a run. Nodes whose output size follows from their params (a mesh's
//! resolution, a clip's frame rate × duration, a baked mesh per frame) estimate it before
//! allocating and refuse beyond the limit, naming the param to change, so a value inside
//! a param's range cannot abort the process with an out-of-memory kill and no report.
//! The limit is per node, not summed over nodes running at the same time.

/// Share of the machine's physical memory a node may ask for when no limit is given.
const DEFAULT_SHARE: f64 = 0.8;

/// The limit when `--max-memory` is not given: 80 % of the physical memory (Linux), or no
/// limit where the amount cannot be read.
pub fn default_memory_limit() -> u64 {
    physical_memory_bytes().map_or(u64::MAX, |bytes| (bytes as f64 * DEFAULT_SHARE) as u64)
}

/// `MemTotal` of `/proc/meminfo`, in bytes.
fn physical_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.trim_start_matches("MemTotal:").trim().trim_end_matches("kB").trim().parse().ok()?;
    kib.checked_mul(1024)
}

/// Parses a size for `--max-memory`: a number with an optional unit `K`, `M`, `G` or `T`
/// (powers of 1024; `KiB`, `MB` and the like are read the same), a bare number being MiB.
pub fn parse_memory_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number.parse().map_err(|_| format!("'{text}' is not a size (e.g. 8G, 512M, 2048)"))?;
    let shift = match unit.trim().to_ascii_uppercase().trim_end_matches('B').trim_end_matches('I') {
        "K" => 10,
        "" | "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("'{text}': unknown unit '{unit}' (use K, M, G or T)")),
    };
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("'{text}' is not a usable memory size"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_read_with_binary_units_and_mib_by_default() {
        assert_eq!(parse_memory_size("8G"), Ok(8 << 30));
        assert_eq!(parse_memory_size("8GiB"), Ok(8 << 30));
        assert_eq!(parse_memory_size("512m"), Ok(512 << 20));
        assert_eq!(parse_memory_size("2048"), Ok(2048 << 20));
        assert_eq!(parse_memory_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_memory_size("64K"), Ok(64 << 10));
        assert!(parse_memory_size("lots").is_err());
        assert!(parse_memory_size("8X").is_err());
        assert!(parse_memory_size("0").is_err());
    }

    #[test]
    fn the_default_limit_is_most_of_the_machines_memory() {
        let limit = default_memory_limit();
        if let Some(total) = physical_memory_bytes() {
            assert!(limit < total && limit > total / 2, "{limit} of {total}");
        }
    }
}
