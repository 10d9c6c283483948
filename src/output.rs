//! The run's output folder (`--out`) and every file kg saves: one place that decides how.
//!
//! - Every file is written by [`kinegraph_nodes::formats::atomic`]: a random `O_EXCL`
//!   temporary file beside the target, synced, renamed, the folder synced.
//! - Inside an output folder, files go through [`save_within`]: each folder under `--out`
//!   is made (or checked) as a real folder, never followed through a link.
//! - A run or batch holds [`OutLock::exclusive`] on its `--out` for its whole life, so a
//!   second one on the same folder refuses at once, naming the holder; farm tasks, which
//!   share one output root, hold [`OutLock::shared`] (and a [`Lease`] per task).
//! - Temporary files of runs that died ([`remove_stale_temps`]) are removed by the next
//!   run that holds the folder.

use std::fs::{File, OpenOptions};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use kinegraph_nodes::formats::atomic::{TEMP_PREFIX, create_dir_within, temp_file_pid, write_atomic, write_within};

/// The lock file at the top of an output folder.
pub const LOCK_FILE: &str = ".kg-lock";

/// Names kg itself uses at the top of an output folder (farm reports, the merged summary,
/// the batch report): no task or batch run may take one. Names starting with `.` (staging
/// folders, locks, leases, temporary files) are kg's too.
pub const RESERVED_NAMES: &[&str] = &["reports", "summary.json", "batch_report.json"];

/// Longest folder name a task or batch run may have, in bytes (its report adds `.json`).
pub const MAX_NAME_BYTES: usize = 200;

/// Checks that `name` can be a task's or batch run's folder directly under an output
/// folder: one non-empty path component, no separator, no control character, not starting
/// with `.`, not one of [`RESERVED_NAMES`] (in any letter case), at most
/// [`MAX_NAME_BYTES`]. The error says which rule it breaks.
pub fn check_folder_name(name: &str) -> Result<(), String> {
    if name.is_empty() {
        Err("is empty".into())
    } else if name.starts_with('.') {
        Err("starts with '.' (such names are kg's own: staging folders, locks, temporary files)".into())
    } else if name.contains(['/', '\\']) {
        Err("holds a path separator".into())
    } else if name.chars().any(char::is_control) {
        Err("holds a control character".into())
    } else if RESERVED_NAMES.iter().any(|r| r.eq_ignore_ascii_case(name)) {
        Err(format!("is reserved for kg's own files ({})", RESERVED_NAMES.join(", ")))
    } else if name.len() > MAX_NAME_BYTES {
        Err(format!("is longer than {MAX_NAME_BYTES} bytes"))
    } else {
        Ok(())
    }
}

/// Folder names for `raw` labels (input file stems) that pass [`check_folder_name`] and
/// are unique (ignoring letter case, for case-insensitive file systems), in order: path
/// separators and control characters become `_`, a leading `.` becomes `_`, an empty name
/// `_`, long names are cut, and a reserved or already taken name gets `_2`, `_3`, ….
pub fn safe_unique_names(raw: &[String]) -> Vec<String> {
    let mut taken: std::collections::BTreeSet<String> = RESERVED_NAMES.iter().map(|r| r.to_ascii_lowercase()).collect();
    raw.iter()
        .map(|label| {
            let mut base: String =
                label.chars().map(|c| if c == '/' || c == '\\' || c.is_control() { '_' } else { c }).collect();
            if base.starts_with('.') {
                base.replace_range(..1, "_");
            }
            if base.is_empty() {
                base.push('_');
            }
            let mut end = base.len().min(MAX_NAME_BYTES - 8);
            while !base.is_char_boundary(end) {
                end -= 1;
            }
            base.truncate(end);
            let mut name = base.clone();
            let mut n = 2;
            while !taken.insert(name.to_lowercase()) {
                name = format!("{base}_{n}");
                n += 1;
            }
            name
        })
        .collect()
}

/// Writes `bytes` to `path` (a file the user named, anywhere) atomically, creating its
/// folder; the error names the file.
pub fn save_file(path: &Path, bytes: &[u8]) -> Result<(), String> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: cannot create the folder: {e}", dir.display()))?;
    }
    write_atomic(path, bytes).map_err(|e| e.to_string())
}

/// Writes `bytes` atomically to `out/relative`, making its folders as real folders inside
/// `out` (a link inside `out` is refused, never followed); gives the full path.
pub fn save_within(out: &Path, relative: &Path, bytes: &[u8]) -> Result<PathBuf, String> {
    write_within(out, relative, bytes).map_err(|e| e.to_string())
}

/// Makes the folder `out/relative` as real folders inside `out` (a link inside `out` is
/// refused, never followed); gives its path.
pub fn folder_within(out: &Path, relative: &Path) -> Result<PathBuf, String> {
    create_dir_within(out, relative).map_err(|e| e.to_string())
}

/// Opens (creating) a small control file for reading and writing, never through a link.
fn open_control_file(path: &Path) -> std::io::Result<File> {
    let mut options = OpenOptions::new();
    options.read(true).write(true).create(true).truncate(false);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW);
    }
    options.open(path)
}

/// This machine's name, for lock and lease files (`unknown` when it cannot be read).
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_string())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "unknown".into())
}

/// True unless process `pid` on this machine is known to have exited. Where that cannot
/// be told (no `/proc`), every process counts as alive, so nothing of it is removed.
pub fn pid_alive(pid: u32) -> bool {
    let proc = Path::new("/proc");
    !proc.join("self").exists() || proc.join(pid.to_string()).exists()
}

/// Who holds a lock or lease, as its file says (`pid 12 on host h`).
fn holder_text(file: &mut File) -> String {
    let mut text = String::new();
    let _ = file.rewind().and_then(|()| file.read_to_string(&mut text));
    let text = text.trim();
    if text.is_empty() { "another kg".into() } else { text.chars().take(200).collect() }
}

/// Replaces the file's text with this process's pid and host.
fn write_holder(file: &mut File) -> std::io::Result<()> {
    file.set_len(0)?;
    file.rewind()?;
    writeln!(file, "pid {} on host {}", std::process::id(), host_name())?;
    file.sync_all()
}

/// An advisory lock on an output folder, held until dropped.
#[derive(Debug)]
pub struct OutLock {
    file: File,
    path: PathBuf,
    exclusive: bool,
}

impl OutLock {
    /// Takes `out` for a whole `kg run` or `kg batch` (creating it): refuses, naming the
    /// holder's pid, while another kg holds it in any way.
    pub fn exclusive(out: &Path) -> Result<OutLock, String> {
        Self::take(out, true)
    }

    /// Takes `out` for one farm task: tasks share the folder with each other, not with a
    /// `kg run` or `kg batch`.
    pub fn shared(out: &Path) -> Result<OutLock, String> {
        Self::take(out, false)
    }

    fn take(out: &Path, exclusive: bool) -> Result<OutLock, String> {
        std::fs::create_dir_all(out).map_err(|e| format!("{}: cannot create the output folder: {e}", out.display()))?;
        let path = out.join(LOCK_FILE);
        loop {
            let mut file =
                open_control_file(&path).map_err(|e| format!("{}: cannot open the lock: {e}", path.display()))?;
            let taken = if exclusive { file.try_lock() } else { file.try_lock_shared() };
            match taken {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    let holder = if exclusive && file.metadata().is_ok_and(|m| m.len() == 0) {
                        "farm tasks".to_string()
                    } else {
                        holder_text(&mut file)
                    };
                    return Err(format!(
                        "{}: the output folder is in use by {holder} (lock {}); wait for it to finish or use another --out",
                        out.display(),
                        path.display()
                    ));
                }
                Err(std::fs::TryLockError::Error(e)) => {
                    return Err(format!("{}: cannot lock: {e}", path.display()));
                }
            }
            // An exclusive holder removes the file when done: a lock on a removed file
            // guards nothing, so start again on the new one.
            if !same_file(&file, &path) {
                continue;
            }
            if exclusive {
                write_holder(&mut file).map_err(|e| format!("{}: {e}", path.display()))?;
            }
            return Ok(OutLock { file, path, exclusive });
        }
    }
}

impl Drop for OutLock {
    fn drop(&mut self) {
        // The last holder removes the file while still holding it exclusively (see `take`),
        // so a finished run leaves the folder as it found it. A shared holder is the last
        // when it can turn its lock exclusive.
        if self.exclusive || self.file.try_lock().is_ok() {
            let _ = std::fs::remove_file(&self.path);
            let _ = self.file.set_len(0);
        }
    }
}

/// A task's lease: a file `out/.kg-lease-<id>` with the running attempt's host and pid,
/// locked while it runs. A second attempt of the same task finds it locked and refuses,
/// instead of removing the running attempt's staging folder.
#[derive(Debug)]
pub struct Lease {
    file: File,
    path: PathBuf,
}

impl Lease {
    /// The lease file of task `id` under `out`.
    pub fn path(out: &Path, id: &str) -> PathBuf {
        out.join(format!(".kg-lease-{id}"))
    }

    /// Takes the lease of task `id`, or says who holds it.
    pub fn take(out: &Path, id: &str) -> Result<Lease, String> {
        let path = Self::path(out, id);
        loop {
            let mut file =
                open_control_file(&path).map_err(|e| format!("{}: cannot open the lease: {e}", path.display()))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    return Err(format!(
                        "task '{id}' is already running ({}, lease {}); not starting a second attempt",
                        holder_text(&mut file),
                        path.display()
                    ));
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(format!("{}: cannot lock: {e}", path.display())),
            }
            // The holder before us may have removed the file between our open and our lock:
            // then the lock is on a file nobody else sees, so start again.
            if !same_file(&file, &path) {
                continue;
            }
            write_holder(&mut file).map_err(|e| format!("{}: {e}", path.display()))?;
            return Ok(Lease { file, path });
        }
    }
}

impl Drop for Lease {
    fn drop(&mut self) {
        // Removed while still locked, so a waiting attempt re-checks (see `take`).
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.set_len(0);
    }
}

/// True when the open `file` is the one at `path` now.
fn same_file(file: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (file.metadata(), std::fs::symlink_metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = (file, path);
        true
    }
}

/// Removes the temporary files under `dir` (recursively, never through links) that no
/// live writer owns: made by a process that has exited, or before `started` (the start of
/// the run that now holds the folder's lock) by any process but this one. Gives how many
/// were removed.
pub fn remove_stale_temps(dir: &Path, started: SystemTime) -> usize {
    let me = std::process::id();
    remove_temps(dir, &|pid, modified| pid != me && (!pid_alive(pid) || modified.is_some_and(|m| m < started)))
}

/// Removes this process's own temporary files under `dir` (after a cancelled run).
pub fn remove_own_temps(dir: &Path) -> usize {
    let me = std::process::id();
    remove_temps(dir, &|pid, _| pid == me)
}

fn remove_temps(dir: &Path, stale: &dyn Fn(u32, Option<SystemTime>) -> bool) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else { return 0 };
    let mut removed = 0;
    for entry in entries.flatten() {
        let Ok(kind) = entry.file_type() else { continue };
        let name = entry.file_name().to_string_lossy().into_owned();
        if kind.is_dir() {
            removed += remove_temps(&entry.path(), stale);
        } else if let Some(pid) = temp_file_pid(&name) {
            let modified = entry.metadata().and_then(|m| m.modified()).ok();
            if stale(pid, modified) && std::fs::remove_file(entry.path()).is_ok() {
                removed += 1;
            }
        }
    }
    removed
}

/// True when `name` is a temporary file of [`write_atomic`] for a target named `target`.
pub fn is_temp_of(name: &str, target: &str) -> bool {
    name.starts_with(TEMP_PREFIX) && temp_file_pid(name).is_some() && name.ends_with(&format!(".{target}"))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn folder_names_are_single_safe_unreserved_components() {
        for bad in ["", ".", "..", "../../x", "/abs", "a/b", "a\\b", "a\0b", "a\nb", "reports", "Summary.JSON", ".x"] {
            assert!(check_folder_name(bad).is_err(), "{bad:?}");
        }
        assert!(check_folder_name(&"x".repeat(MAX_NAME_BYTES + 1)).is_err());
        for good in ["walk", "02_01", "cmu-02_02+punch", "reports_2", "marche à pied"] {
            assert_eq!(check_folder_name(good), Ok(()), "{good:?}");
        }
    }

    #[test]
    fn safe_unique_names_fix_and_suffix_in_order() {
        let raw: Vec<String> =
            ["reports", "walk", "Walk", "walk", "..", "", "a/b", "batch_report.json", "x\0y", "walk_2"]
                .iter()
                .map(|s| s.to_string())
                .collect();
        let names = safe_unique_names(&raw);
        assert_eq!(
            names,
            ["reports_2", "walk", "Walk_2", "walk_3", "_.", "_", "a_b", "batch_report.json_2", "x_y", "walk_2_2"]
        );
        for n in &names {
            assert_eq!(check_folder_name(n), Ok(()), "{n:?}");
        }
        let long = safe_unique_names(&["é".repeat(300)]);
        assert!(check_folder_name(&long[0]).is_ok());
    }

    #[test]
    fn a_second_exclusive_lock_is_refused_naming_the_holder() {
        let dir = tempfile::tempdir().unwrap();
        let first = OutLock::exclusive(dir.path()).unwrap();
        let err = OutLock::exclusive(dir.path()).unwrap_err();
        assert!(err.contains(&format!("pid {}", std::process::id())), "{err}");
        assert!(OutLock::shared(dir.path()).is_err());
        drop(first);
        let a = OutLock::shared(dir.path()).unwrap();
        let _b = OutLock::shared(dir.path()).unwrap();
        let err = OutLock::exclusive(dir.path()).unwrap_err();
        assert!(err.contains("farm tasks"), "{err}");
        drop(a);
    }

    #[test]
    fn a_lease_is_refused_while_held_and_free_after() {
        let dir = tempfile::tempdir().unwrap();
        let lease = Lease::take(dir.path(), "walk").unwrap();
        let err = Lease::take(dir.path(), "walk").unwrap_err();
        assert!(err.contains("already running") && err.contains(&host_name()), "{err}");
        assert!(Lease::take(dir.path(), "run").is_ok());
        drop(lease);
        assert!(!Lease::path(dir.path(), "walk").exists());
        assert!(Lease::take(dir.path(), "walk").is_ok());
    }

    #[cfg(unix)]
    #[test]
    fn a_link_planted_at_the_lock_file_is_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        std::fs::write(&victim, b"precious").unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        std::os::unix::fs::symlink(&victim, out.join(LOCK_FILE)).unwrap();
        assert!(OutLock::exclusive(&out).is_err());
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }

    #[test]
    fn temporaries_of_exited_processes_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead = child.id();
        child.wait().unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let stale = dir.path().join(format!(".kg-tmp-{dead}-abcdefghij.walk.bvh"));
        let stale_deep = dir.path().join(format!("sub/.kg-tmp-{dead}-abcdefghij.walk.glb"));
        let mine = dir.path().join(format!(".kg-tmp-{}-abcdefghij.walk.bvh", std::process::id()));
        let other = dir.path().join("walk.bvh");
        for f in [&stale, &stale_deep, &mine, &other] {
            std::fs::write(f, b"x").unwrap();
        }
        let earlier = SystemTime::now() - std::time::Duration::from_secs(3600);
        assert_eq!(remove_stale_temps(dir.path(), earlier), 2);
        assert!(!stale.exists() && !stale_deep.exists() && mine.exists() && other.exists());
        assert_eq!(remove_own_temps(dir.path()), 1);
        assert!(!mine.exists());
    }
}
