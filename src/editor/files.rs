//! What the editor keeps between sessions, under one settings folder: the recent files and
//! autosaves of unsaved edits, so a crash loses at most one autosave interval of work.
//!
//! An autosave is a small RON file per graph, `autosave/<key>.ron`, holding the graph's path
//! (none for an untitled graph) and the document text; the key is a hash of the absolute
//! path, so two graphs with the same name in different folders never share one. Autosaves
//! are written atomically and removed when the graph is saved; one found on opening whose
//! text differs from the file is offered back to the user.

use std::path::{Path, PathBuf};

use kinegraph_nodes::formats::atomic::write_atomic;
use serde::{Deserialize, Serialize};

/// How many recent files the File menu lists.
pub const RECENT_LIMIT: usize = 10;

/// The settings folder: `KG_CONFIG_DIR` when set, else the platform's config folder
/// (`~/.config/kinegraph` on Linux).
pub fn default_settings_dir() -> PathBuf {
    std::env::var_os("KG_CONFIG_DIR").map(PathBuf::from).unwrap_or_else(|| {
        directories::ProjectDirs::from("", "", "kinegraph")
            .map(|d| d.config_dir().to_path_buf())
            .unwrap_or_else(|| std::env::temp_dir().join("kinegraph"))
    })
}

/// The recent-files list, newest first, stored as `recent.ron` in the settings folder.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RecentFiles {
    /// Absolute paths, newest first, without repeats.
    pub paths: Vec<PathBuf>,
}

impl RecentFiles {
    /// The list in `dir`; empty when there is none or it cannot be read (a damaged list
    /// must not stop the editor from starting).
    pub fn load(dir: &Path) -> Self {
        std::fs::read_to_string(dir.join("recent.ron")).ok().and_then(|t| ron::from_str(&t).ok()).unwrap_or_default()
    }

    /// Puts `path` first and writes the list to `dir`.
    pub fn touch(&mut self, dir: &Path, path: &Path) -> Result<(), String> {
        let path = absolute(path);
        self.paths.retain(|p| *p != path);
        self.paths.insert(0, path);
        self.paths.truncate(RECENT_LIMIT);
        write_ron(&dir.join("recent.ron"), self)
    }
}

/// Unsaved work of one graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Autosave {
    /// The graph's file, `None` for an untitled graph.
    pub source: Option<PathBuf>,
    /// The document as graph-file text.
    pub text: String,
}

/// Where the autosave of the graph at `source` (or of the untitled graph) lives.
pub fn autosave_path(dir: &Path, source: Option<&Path>) -> PathBuf {
    let key = match source {
        Some(p) => format!("{:016x}", fnv1a(absolute(p).to_string_lossy().as_bytes())),
        None => "untitled".into(),
    };
    dir.join("autosave").join(format!("{key}.ron"))
}

/// Writes `text` as the autosave of `source`.
pub fn write_autosave(dir: &Path, source: Option<&Path>, text: &str) -> Result<(), String> {
    let save = Autosave { source: source.map(absolute), text: text.to_string() };
    write_ron(&autosave_path(dir, source), &save)
}

/// The autosave of `source` worth offering: one exists and its text differs from
/// `current_text` (what the file holds now, or an empty graph's text when untitled).
pub fn recoverable(dir: &Path, source: Option<&Path>, current_text: &str) -> Option<Autosave> {
    let text = std::fs::read_to_string(autosave_path(dir, source)).ok()?;
    let save: Autosave = ron::from_str(&text).ok()?;
    (save.text != current_text).then_some(save)
}

/// Removes the autosave of `source` (after a save, or when the user discards it).
pub fn discard_autosave(dir: &Path, source: Option<&Path>) {
    let _ = std::fs::remove_file(autosave_path(dir, source));
}

fn write_ron<T: Serialize>(path: &Path, value: &T) -> Result<(), String> {
    let text = ron::ser::to_string_pretty(value, ron::ser::PrettyConfig::new()).map_err(|e| e.to_string())?;
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).map_err(|e| format!("{}: {e}", parent.display()))?;
    }
    write_atomic(path, text.as_bytes()).map_err(|e| e.message)
}

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// FNV-1a, 64 bits: a stable file-name key (std's hasher is not stable across releases).
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn recent_files_keep_the_newest_first_without_repeats_and_survive_a_restart() {
        let dir = tempfile::tempdir().unwrap();
        let mut recent = RecentFiles::load(dir.path());
        assert!(recent.paths.is_empty());
        for i in 0..12 {
            recent.touch(dir.path(), &dir.path().join(format!("g{i}.ron"))).unwrap();
        }
        recent.touch(dir.path(), &dir.path().join("g5.ron")).unwrap();
        let again = RecentFiles::load(dir.path());
        assert_eq!(again, recent);
        assert_eq!(again.paths.len(), RECENT_LIMIT);
        assert_eq!(again.paths[0], dir.path().join("g5.ron"));
        assert_eq!(again.paths[1], dir.path().join("g11.ron"));
        assert_eq!(again.paths.iter().filter(|p| p.ends_with("g5.ron")).count(), 1);
        // A damaged list is an empty one, not a failure.
        std::fs::write(dir.path().join("recent.ron"), "(paths: [").unwrap();
        assert!(RecentFiles::load(dir.path()).paths.is_empty());
    }

    #[test]
    fn an_autosave_is_offered_only_while_it_differs_from_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("x/graph.ron"), dir.path().join("y/graph.ron"));
        assert_ne!(autosave_path(dir.path(), Some(&a)), autosave_path(dir.path(), Some(&b)));
        assert!(recoverable(dir.path(), Some(&a), "saved").is_none());
        write_autosave(dir.path(), Some(&a), "edited").unwrap();
        let found = recoverable(dir.path(), Some(&a), "saved").unwrap();
        assert_eq!((found.source.as_deref(), found.text.as_str()), (Some(a.as_path()), "edited"));
        assert!(recoverable(dir.path(), Some(&a), "edited").is_none(), "same text: nothing to recover");
        assert!(recoverable(dir.path(), Some(&b), "saved").is_none(), "another graph's autosave");
        write_autosave(dir.path(), None, "untitled work").unwrap();
        assert_eq!(recoverable(dir.path(), None, "").unwrap().text, "untitled work");
        discard_autosave(dir.path(), Some(&a));
        assert!(recoverable(dir.path(), Some(&a), "saved").is_none());
    }
}
