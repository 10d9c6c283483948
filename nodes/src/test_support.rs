//! Helpers shared by tests (unit, integration and benches); compiled only for tests or
//! with the `test-support` feature.

use std::path::PathBuf;

/// The shared test corpus (`shared/data`, beside the workspace; `KG_SHARED_DATA`
/// overrides). When it is missing: panics with a clear message if `CI` is set (a CI run
/// must not silently skip), otherwise prints why the calling test is skipped and returns
/// `None`.
pub fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("KG_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data"))
        });
    if dir.join("README.md").is_file() {
        return Some(dir);
    }
    if std::env::var_os("CI").is_some() {
        panic!(
            "shared test data not found at {} (set KG_SHARED_DATA); CI requires it",
            dir.display()
        );
    }
    eprintln!(
        "skipping: shared test data not found at {} (set KG_SHARED_DATA)",
        dir.display()
    );
    None
}
