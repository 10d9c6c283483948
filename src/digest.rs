//! SHA-256 as kinegraph uses it everywhere: lower-case hex of bytes and of files (plans,
//! task reports, regression facts, cache keys).

use std::path::Path;

use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}

/// Lower-case hex SHA-256 of a file's bytes, read in chunks (corpus files and exports can
/// be large).
pub fn sha256_file(path: &Path) -> std::io::Result<String> {
    let mut digest = Sha256::new();
    std::io::copy(&mut std::fs::File::open(path)?, &mut digest)?;
    Ok(format!("{:x}", digest.finalize()))
}
