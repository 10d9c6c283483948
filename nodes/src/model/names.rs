//! Name suggestions for messages: the "did you mean" of every validation error, whether it
//! names a node kind, a port, a parameter or a joint. Below the contract and the kernels so
//! both can suggest names the same way.

/// The candidate closest to `name` by edit distance, if it is close enough to be a typo
/// (at most about half its length away): the "did you mean" of every validation message.
/// Candidates whose length alone puts them too far away are skipped before the distance is
/// computed, so a long garbage name costs no more than a short one.
pub fn nearest_name<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let name_len = name.chars().count();
    candidates
        .into_iter()
        .filter_map(|c| {
            let limit = c.len() / 2 + 1;
            // The distance is at least the difference in length.
            if name_len.abs_diff(c.chars().count()) > limit {
                return None;
            }
            let d = edit_distance(c, name);
            (d <= limit).then_some((d, c))
        })
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

    #[test]
    fn suggestions_are_typos_only_whatever_the_length() {
        let kinds = ["clip.load", "clip.trim", "export.glb"];
        assert_eq!(nearest_name("clip.lod", kinds), Some("clip.load"));
        assert_eq!(nearest_name("cIip.trim", kinds), Some("clip.trim"));
        // Near in spelling but far in length: no suggestion, as the full distance says.
        let long = format!("clip.load{}", "x".repeat(10_000));
        assert!(edit_distance("clip.load", &long) > "clip.load".len() / 2 + 1);
        assert_eq!(nearest_name(&long, kinds), None);
        // At the limit (half of 9, plus one) and one past it.
        assert_eq!(nearest_name("clip.loadxxxxx", kinds), Some("clip.load"));
        assert_eq!(nearest_name("clip.loadxxxxxx", kinds), None);
    }
}
