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

/// Every file under `dir` (recursively) whose extension is `ext`, sorted.
pub fn files_with_extension(dir: &std::path::Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries.flatten() {
            let p = entry.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}
