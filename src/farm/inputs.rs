//! The files a batch or a farm plan runs over: a glob's matches, and one output folder
//! name per file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::graph::Setting;

/// The files a `NAME=GLOB` binding matches, sorted; an error naming the glob when it is
/// malformed or matches no file.
pub fn expand_glob(input: &Setting) -> Result<Vec<PathBuf>, String> {
    let mut inputs: Vec<PathBuf> = match glob::glob(&input.value) {
        Ok(paths) => paths.filter_map(Result::ok).filter(|p| p.is_file()).collect(),
        Err(e) => return Err(format!("--input {}: bad glob: {e}", input.value)),
    };
    inputs.sort();
    if inputs.is_empty() {
        return Err(format!("--input {}: no files match", input.value));
    }
    Ok(inputs)
}

/// Output subfolder names: the file stem, disambiguated by parent folders when two inputs
/// share a stem (e.g. `cmu/02_02.bvh` and `cmu_daz/02_02.bvh`).
pub fn run_folder_names(inputs: &[PathBuf]) -> Vec<String> {
    let name_at = |p: &Path, depth: usize| -> String {
        let mut parts: Vec<String> =
            p.components().rev().take(depth + 1).map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
        parts.reverse();
        if let Some(last) = parts.last_mut() {
            *last = Path::new(last.as_str()).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        }
        parts.join("-")
    };
    let mut names: Vec<String> = inputs.iter().map(|p| name_at(p, 0)).collect();
    for depth in 1..4 {
        let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
        for n in &names {
            *counts.entry(n.as_str()).or_default() += 1;
        }
        let clashing: Vec<bool> = names.iter().map(|n| counts[n.as_str()] > 1).collect();
        if !clashing.contains(&true) {
            break;
        }
        for (i, clash) in clashing.into_iter().enumerate() {
            if clash {
                names[i] = name_at(&inputs[i], depth);
            }
        }
    }
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folder_names_disambiguate_shared_stems() {
        let inputs: Vec<PathBuf> =
            ["d/cmu/02_02.bvh", "d/cmu_daz/02_02.bvh", "d/cmu/01_01.bvh"].iter().map(PathBuf::from).collect();
        assert_eq!(run_folder_names(&inputs), vec!["cmu-02_02", "cmu_daz-02_02", "01_01"]);
    }
}
