//! The on-disk cache (`--cache DIR`): node results kept between runs and processes, so a
//! re-run of an unchanged batch does no node work, and farm tasks sharing a folder share
//! results.
//!
//! One file per result, `DIR/ab/abcdef….kgc`, named by the node's [`Fingerprint`] (taken
//! with file contents, not times). A file holds a magic line, the SHA-256 of its payload and
//! the payload: the node's outputs and warnings as MessagePack, and for nodes that write
//! files, those files' bytes, so a hit restores them into the new output folder. Files are
//! written atomically, so readers in other processes see a whole entry or none; an entry
//! that fails its check is ignored, deleted and rebuilt. The folder is kept under a size
//! bound by deleting the least recently used entries.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime};

use kinegraph_nodes::formats::atomic::write_atomic;
use kinegraph_nodes::node::Value;
use sha2::{Digest, Sha256};

use super::fingerprint::Fingerprint;

/// First bytes of every entry; a format change bumps the digit.
const MAGIC: &[u8; 8] = b"KGCACHE1";
/// Entry file extension.
const EXTENSION: &str = "kgc";
/// Default size bound.
pub const DEFAULT_MAX_BYTES: u64 = 4 << 30;
/// Temporary files older than this are left over from killed writers and are removed.
const STALE_TEMP: Duration = Duration::from_secs(3600);

/// A node's cached result.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub struct Entry {
    /// Output values in schema order.
    pub outputs: Vec<Option<Value>>,
    /// The warnings the node raised when it ran.
    pub warnings: Vec<String>,
    /// Files the node wrote, relative to its output folder, with their bytes.
    pub files: Vec<StoredFile>,
}

/// A file an exporting node wrote.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
pub struct StoredFile {
    /// Path relative to the run's output folder.
    pub relative: PathBuf,
    /// The bytes written.
    #[serde(with = "serde_bytes")]
    pub bytes: Vec<u8>,
}

/// Why a cache folder cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    /// The folder cannot be created or is not a folder.
    #[error("cache folder {}: {source}", path.display())]
    Folder {
        /// The folder.
        path: PathBuf,
        /// What the file system said.
        source: std::io::Error,
    },
}

/// What looking an entry up found.
#[derive(Debug)]
pub enum Lookup {
    /// A valid entry.
    Hit(Box<Entry>),
    /// No entry.
    Miss,
    /// An entry that failed its check or could not be decoded; it has been removed.
    Corrupt(String),
}

/// A cache folder with a size bound.
#[derive(Debug)]
pub struct DiskCache {
    dir: PathBuf,
    max_bytes: u64,
    /// Cleared by the first failed store, so a read-only or full folder warns once
    /// and the run goes on uncached.
    writable: AtomicBool,
}

impl DiskCache {
    /// Opens (creating it if needed) the cache folder `dir`, bounded to `max_bytes`.
    pub fn open(dir: &Path, max_bytes: u64) -> Result<Self, CacheError> {
        let folder_error = |source| CacheError::Folder { path: dir.to_path_buf(), source };
        std::fs::create_dir_all(dir).map_err(folder_error)?;
        if !std::fs::metadata(dir).map_err(folder_error)?.is_dir() {
            return Err(folder_error(std::io::Error::other("not a folder")));
        }
        Ok(DiskCache { dir: dir.to_path_buf(), max_bytes, writable: AtomicBool::new(true) })
    }

    /// The cache folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn entry_path(&self, key: &Fingerprint) -> PathBuf {
        let hex = key.hex();
        self.dir.join(&hex[..2]).join(format!("{hex}.{EXTENSION}"))
    }

    /// The entry for `key`. A hit marks the entry as recently used.
    pub fn get(&self, key: &Fingerprint) -> Lookup {
        let path = self.entry_path(key);
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(_) => return Lookup::Miss,
        };
        match decode(&bytes) {
            Ok(entry) => {
                // The time of last use drives eviction; failing to set it only ages the entry.
                let _ =
                    std::fs::File::options().write(true).open(&path).and_then(|f| f.set_modified(SystemTime::now()));
                Lookup::Hit(Box::new(entry))
            }
            Err(why) => {
                let _ = std::fs::remove_file(&path);
                Lookup::Corrupt(why)
            }
        }
    }

    /// Stores `entry` under `key`. Returns a warning the first time storing fails (a
    /// read-only or full folder); later stores in this process are skipped silently.
    pub fn put(&self, key: &Fingerprint, entry: &Entry) -> Option<String> {
        if !self.writable.load(Ordering::Relaxed) {
            return None;
        }
        let path = self.entry_path(key);
        let result = encode(entry).and_then(|bytes| {
            if let Some(shard) = path.parent() {
                std::fs::create_dir_all(shard).map_err(|e| format!("{}: {e}", shard.display()))?;
            }
            write_atomic(&path, &bytes).map_err(|e| e.to_string())
        });
        let why = result.err()?;
        // Of stores failing at the same time in several threads, only the first warns.
        self.writable.swap(false, Ordering::Relaxed).then(|| {
            format!(
                "the cache folder {} cannot take results ({why}); this run goes on without storing them",
                self.dir.display()
            )
        })
    }

    /// Deletes the least recently used entries until the folder is within its bound, and
    /// temporary files left by killed writers. Returns the bytes the cache then holds.
    pub fn trim(&self) -> u64 {
        let mut entries: Vec<(SystemTime, u64, PathBuf)> = Vec::new();
        let now = SystemTime::now();
        for shard in std::fs::read_dir(&self.dir).into_iter().flatten().flatten() {
            if !shard.file_type().is_ok_and(|t| t.is_dir()) {
                continue;
            }
            for file in std::fs::read_dir(shard.path()).into_iter().flatten().flatten() {
                let Ok(meta) = file.metadata() else { continue };
                let path = file.path();
                let modified = meta.modified().unwrap_or(now);
                if path.extension().is_some_and(|e| e == EXTENSION) {
                    entries.push((modified, meta.len(), path));
                } else if file.file_name().to_string_lossy().starts_with(".kg-tmp-")
                    && now.duration_since(modified).is_ok_and(|age| age > STALE_TEMP)
                {
                    let _ = std::fs::remove_file(&path);
                }
            }
        }
        let mut total: u64 = entries.iter().map(|(_, size, _)| size).sum();
        entries.sort();
        for (_, size, path) in entries {
            if total <= self.max_bytes {
                break;
            }
            if std::fs::remove_file(&path).is_ok() {
                total -= size;
            }
        }
        total
    }
}

fn encode(entry: &Entry) -> Result<Vec<u8>, String> {
    let payload = rmp_serde::to_vec(entry).map_err(|e| format!("cannot encode the result: {e}"))?;
    let mut bytes = Vec::with_capacity(payload.len() + 40);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&Sha256::digest(&payload));
    bytes.extend_from_slice(&payload);
    Ok(bytes)
}

fn decode(bytes: &[u8]) -> Result<Entry, String> {
    let (magic, rest) = bytes.split_at_checked(MAGIC.len()).ok_or("the entry is truncated")?;
    if magic != MAGIC {
        return Err("the entry is not a kinegraph cache entry of this version".into());
    }
    let (digest, payload) = rest.split_at_checked(32).ok_or("the entry is truncated")?;
    if Sha256::digest(payload).as_slice() != digest {
        return Err("the entry's checksum does not match its contents".into());
    }
    rmp_serde::from_slice(payload).map_err(|e| format!("the entry cannot be decoded: {e}"))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn key(n: u8) -> Fingerprint {
        Fingerprint([n; 32])
    }

    fn entry(x: f64) -> Entry {
        Entry { outputs: vec![Some(Value::Scalar(x)), None], warnings: vec!["w".into()], files: Vec::new() }
    }

    #[test]
    fn an_entry_comes_back_as_stored_and_a_damaged_one_is_a_removed_miss() {
        let dir = tempfile::tempdir().unwrap();
        let cache = DiskCache::open(dir.path(), DEFAULT_MAX_BYTES).unwrap();
        assert!(matches!(cache.get(&key(1)), Lookup::Miss));
        assert!(cache.put(&key(1), &entry(2.5)).is_none());
        match cache.get(&key(1)) {
            Lookup::Hit(e) => {
                assert_eq!(e.outputs, vec![Some(Value::Scalar(2.5)), None]);
                assert_eq!(e.warnings, vec!["w".to_string()]);
            }
            other => panic!("expected a hit, got {other:?}"),
        }
        // Flip one payload byte: the checksum catches it.
        let path = cache.entry_path(&key(1));
        let mut bytes = std::fs::read(&path).unwrap();
        let last = bytes.len() - 1;
        bytes[last] ^= 0xff;
        std::fs::write(&path, &bytes).unwrap();
        assert!(matches!(cache.get(&key(1)), Lookup::Corrupt(_)));
        assert!(!path.exists(), "a corrupt entry is removed so it is rebuilt");
        // A truncated file and a foreign file are refused the same way.
        std::fs::write(&path, b"KGCA").unwrap();
        assert!(matches!(cache.get(&key(1)), Lookup::Corrupt(_)));
        std::fs::write(&path, b"not a cache entry at all, but long enough to have a digest").unwrap();
        assert!(matches!(cache.get(&key(1)), Lookup::Corrupt(_)));
    }

    #[test]
    fn trimming_keeps_the_most_recently_used_entries_within_the_bound() {
        let dir = tempfile::tempdir().unwrap();
        let probe = DiskCache::open(dir.path(), DEFAULT_MAX_BYTES).unwrap();
        probe.put(&key(0), &entry(0.0));
        let size = std::fs::metadata(probe.entry_path(&key(0))).unwrap().len();
        // Room for two entries.
        let cache = DiskCache::open(dir.path(), 2 * size).unwrap();
        let base = SystemTime::now() - Duration::from_secs(1000);
        for n in 1..=3u8 {
            cache.put(&key(n), &entry(f64::from(n)));
            let when = base + Duration::from_secs(u64::from(n) * 10);
            std::fs::File::options().write(true).open(cache.entry_path(&key(n))).unwrap().set_modified(when).unwrap();
        }
        let when = base - Duration::from_secs(10);
        std::fs::File::options().write(true).open(cache.entry_path(&key(0))).unwrap().set_modified(when).unwrap();
        // Entry 1 is used now, so it is the newest; 0 and 2 are the oldest.
        assert!(matches!(cache.get(&key(1)), Lookup::Hit(_)));
        assert_eq!(cache.trim(), 2 * size);
        let kept: Vec<u8> = (0..=3).filter(|n| cache.entry_path(&key(*n)).exists()).collect();
        assert_eq!(kept, vec![1, 3]);
    }

    #[test]
    fn a_folder_that_cannot_take_results_warns_once_and_the_run_goes_on() {
        let dir = tempfile::tempdir().unwrap();
        let cache = DiskCache::open(dir.path(), DEFAULT_MAX_BYTES).unwrap();
        // A file where key 1's shard folder belongs: storing fails (as on a full disk, or
        // a read-only folder for a user other than root, whom permissions do not stop).
        std::fs::write(dir.path().join("01"), b"").unwrap();
        let first = cache.put(&key(1), &entry(1.0));
        assert!(first.is_some_and(|w| w.contains("cannot take results")));
        assert!(cache.put(&key(2), &entry(2.0)).is_none(), "one warning, not one per node");
        assert!(matches!(cache.get(&key(2)), Lookup::Miss), "stores stop after the failure");
    }
}
