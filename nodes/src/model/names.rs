//! Name suggestions for messages: the "did you mean" of every validation error, whether it
//! names a node kind, a port, a parameter or a joint. Below the contract and the kernels so
//! both can suggest names the same way.

/// The candidate closest to `name` by edit distance, if it is close enough to be a typo
/// (at most about half its length away): the "did you mean" of every validation message.
pub fn nearest_name<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    candidates
        .into_iter()
        .map(|c| (edit_distance(c, name), c))
        .filter(|(d, c)| *d <= c.len() / 2 + 1)
        .min()
        .map(|(_, c)| c)
}

/// `" (did you mean 'x'?)"` for the candidate nearest `name` ([`nearest_name`]), or nothing:
/// the one way every message suggests a name.
pub fn did_you_mean<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    hint_for(nearest_name(name, candidates))
}

/// `" (did you mean 'x'?)"` for a suggestion already found, or nothing.
pub fn hint_for(suggestion: Option<&str>) -> String {
    suggestion.map(|c| format!(" (did you mean '{c}'?)")).unwrap_or_default()
}

/// Levenshtein distance between two short names.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_hand_cases() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("clip.load", "clip.load"), 0);
    }
}
