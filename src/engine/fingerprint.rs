//! Fingerprints: everything a node's result depends on, hashed, so that equal fingerprints
//! mean equal results. They key both the in-memory cache and the on-disk one.

use std::path::Path;

use kinegraph_nodes::node::ParamKind;
use sha2::{Digest, Sha256};

use super::compile::CompiledGraph;

/// A node's fingerprint: SHA-256 over the engine's version, the node's kind and version, its
/// parameters, the files it reads and its inputs' fingerprints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Fingerprint(pub(super) [u8; 32]);

impl Fingerprint {
    /// Lowercase hexadecimal, as used for cache file names.
    pub fn hex(&self) -> String {
        self.0.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// How the files a node reads enter its fingerprint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileIdentity {
    /// Size and modification time: cheap, and enough within one process.
    Stamp,
    /// The bytes themselves: for keys that outlive the process (the on-disk cache), where a
    /// copied or touched file must still hit and an edited one, whatever its time, must not.
    Content,
}

/// Folder entries walked at most when fingerprinting an input folder (as `load.clip_set`).
const MAX_FOLDER_ENTRIES: usize = 200_000;

/// Fingerprints of every node, computed in topological order.
pub fn fingerprints(graph: &CompiledGraph<'_>, base_dir: &Path, identity: FileIdentity) -> Vec<Fingerprint> {
    let mut out = vec![Fingerprint([0; 32]); graph.nodes.len()];
    for &i in &graph.order {
        let node = &graph.nodes[i];
        let schema = node.node.schema();
        let mut h = Hasher(Sha256::new());
        h.text(concat!("kinegraph ", env!("CARGO_PKG_VERSION")));
        h.text(schema.kind);
        h.number(u64::from(schema.version));
        for (name, value) in &node.params {
            h.text(name);
            h.text(&format!("{value:?}"));
        }
        for (name, path) in node.input_files() {
            let kind = schema.param(name).map(|p| p.kind);
            let path = base_dir.join(path);
            match kind {
                Some(ParamKind::InputFolder { extensions, .. }) => h.folder(&path, extensions, identity),
                _ => h.file(&path, identity),
            }
        }
        if let Some(pass) = &node.pass_through {
            h.text("bypass");
            pass.iter().for_each(|input| h.number(input.map_or(u64::MAX, |i| i as u64)));
        }
        for input in &node.inputs {
            match input {
                Some((src, port)) => {
                    h.0.update(out[*src].0);
                    h.number(*port as u64);
                }
                None => h.text("-"),
            }
        }
        out[i] = Fingerprint(h.0.finalize().into());
    }
    out
}

/// SHA-256 fed with length-prefixed fields, so no two different field lists collide.
struct Hasher(Sha256);

impl Hasher {
    fn number(&mut self, n: u64) {
        self.0.update(n.to_le_bytes());
    }

    fn text(&mut self, s: &str) {
        self.number(s.len() as u64);
        self.0.update(s.as_bytes());
    }

    /// A file as `identity` sees it; a missing or unreadable file hashes as such, so it
    /// changes the fingerprint when it appears.
    fn file(&mut self, path: &Path, identity: FileIdentity) {
        match identity {
            FileIdentity::Stamp => match std::fs::metadata(path) {
                Ok(meta) => {
                    self.number(meta.len());
                    let since = meta.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
                    self.number(since.map_or(0, |d| d.as_nanos() as u64));
                }
                Err(_) => self.text("missing"),
            },
            FileIdentity::Content => match crate::digest::sha256_file(path) {
                Ok(hex) => self.text(&hex),
                Err(_) => self.text("unreadable"),
            },
        }
    }

    /// A folder: the relative name and identity of every file under it with one of
    /// `extensions`, so an added, removed, renamed or edited file changes the fingerprint.
    fn folder(&mut self, dir: &Path, extensions: &[&str], identity: FileIdentity) {
        match kinegraph_nodes::corpus::files_under(dir, extensions, MAX_FOLDER_ENTRIES) {
            Ok(files) => {
                self.number(files.len() as u64);
                for file in files {
                    self.text(&file.strip_prefix(dir).unwrap_or(&file).to_string_lossy());
                    self.file(&file, identity);
                }
            }
            Err(e) => self.text(&e),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn fields_are_length_prefixed_so_shifted_boundaries_differ() {
        let digest = |parts: &[&str]| {
            let mut h = Hasher(Sha256::new());
            parts.iter().for_each(|p| h.text(p));
            h.0.finalize()
        };
        assert_ne!(digest(&["ab", "c"]), digest(&["a", "bc"]));
        assert_eq!(digest(&["ab", "c"]), digest(&["ab", "c"]));
    }

    #[test]
    fn content_identity_follows_the_bytes_not_the_time_and_folders_follow_their_files() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.bvh");
        let of = |path: &Path, identity| {
            let mut h = Hasher(Sha256::new());
            h.file(path, identity);
            h.0.finalize()
        };
        std::fs::write(&file, "one").unwrap();
        let before = of(&file, FileIdentity::Content);
        let when = std::time::SystemTime::UNIX_EPOCH + std::time::Duration::from_secs(1_000_000);
        std::fs::File::options().write(true).open(&file).unwrap().set_modified(when).unwrap();
        assert_eq!(of(&file, FileIdentity::Content), before, "touching a file keeps its content key");
        std::fs::write(&file, "two").unwrap();
        assert_ne!(of(&file, FileIdentity::Content), before);
        assert_ne!(of(&dir.path().join("gone.bvh"), FileIdentity::Content), before);

        let folder = |identity| {
            let mut h = Hasher(Sha256::new());
            h.folder(dir.path(), &["bvh"], identity);
            h.0.finalize()
        };
        let with_one = folder(FileIdentity::Content);
        std::fs::write(dir.path().join("notes.txt"), "ignored").unwrap();
        assert_eq!(folder(FileIdentity::Content), with_one, "files of other kinds do not count");
        std::fs::write(dir.path().join("b.bvh"), "new").unwrap();
        assert_ne!(folder(FileIdentity::Content), with_one, "an added clip changes the key");
    }
}
