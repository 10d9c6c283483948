//! Locating the shared real-data corpus (`../shared/data` beside the repository) for tests
//! and benchmarks.

use std::path::PathBuf;

/// The corpus directory: `$KG_SHARED_DATA` if set, else `shared/data` beside the
/// repository. Returns `None` (after printing why) when it is absent so a developer
/// without the data can still run the rest; panics when `CI` is set, because there the
/// data must be present and a silent skip would hide a broken test run.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("KG_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data")));
    if dir.join("MANIFEST.sha256").is_file() || dir.join("bvh").is_dir() {
        return Some(dir);
    }
    if std::env::var_os("CI").is_some() {
        panic!("CI is set but the shared data corpus is missing at {}", dir.display());
    }
    eprintln!("skipping: shared data corpus not found at {} (set KG_SHARED_DATA)", dir.display());
    None
}

/// The real jumps, hops and flips of the corpus (paths under the corpus folder) that the
/// momentum-editing tests measure: CMU 16_01, 13_32, 01_01, 90_05, 88_01, MASS backflip.
pub const JUMP_CLIPS: [&str; 6] = [
    "bvh/cmu/16_01.bvh",
    "bvh/cmu_daz/13_32.bvh",
    "bvh/cmu/01_01.bvh",
    "bvh/cmu/90_05.bvh",
    "bvh/cmu/88_01.bvh",
    "bvh/mass_humanik/backflip.bvh",
];

/// Every file under `dir` (recursively) whose extension is `ext`, sorted (see
/// [`files_under`]; no limit).
pub fn files_with_extension(dir: &std::path::Path, ext: &str) -> Vec<PathBuf> {
    files_under(dir, &[ext], usize::MAX).unwrap_or_default()
}

/// Every file under `dir` (recursively) whose extension is one of `exts` (any case), sorted.
/// The walk stays under `dir`: a symbolic link to a folder is not followed, so a link loop
/// or a link to `/` cannot make it endless. More than `max_entries` entries visited is an
/// error that says so (a walk of a whole disk is a mistake, not a wait).
pub fn files_under(dir: &std::path::Path, exts: &[&str], max_entries: usize) -> Result<Vec<PathBuf>, String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    let mut visited = 0usize;
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries.flatten() {
            visited += 1;
            if visited > max_entries {
                return Err(format!(
                    "{} holds more than {max_entries} files and folders: give a narrower folder",
                    dir.display()
                ));
            }
            let p = entry.path();
            // The entry's own type: a link is a link, never the folder it points at.
            let Ok(kind) = entry.file_type() else { continue };
            if kind.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| exts.iter().any(|x| e.eq_ignore_ascii_case(x))) {
                out.push(p);
            }
        }
    }
    out.sort();
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn a_link_loop_or_a_link_out_is_not_followed_and_huge_folders_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("a/b")).unwrap();
        std::fs::write(dir.path().join("a/b/x.bvh"), "").unwrap();
        std::fs::write(dir.path().join("a/y.BVH"), "").unwrap();
        std::fs::write(dir.path().join("a/z.txt"), "").unwrap();
        std::os::unix::fs::symlink(dir.path().join("a"), dir.path().join("a/b/loop")).unwrap();
        std::os::unix::fs::symlink("/", dir.path().join("a/root")).unwrap();
        let found = files_under(&dir.path().join("a"), &["bvh"], 1000).unwrap();
        assert_eq!(found, vec![dir.path().join("a/b/x.bvh"), dir.path().join("a/y.BVH")]);
        let err = files_under(&dir.path().join("a"), &["bvh"], 3).unwrap_err();
        assert!(err.contains("more than 3"), "{err}");
    }
}
