//! Safe file writes: every file kinegraph writes (exports, reports, plans, summaries,
//! autosaves) goes through [`write_atomic`], and every file written inside a run's output
//! folder through [`write_within`].
//!
//! Steps of [`write_atomic`]:
//! 1. create a temporary file beside the target with `O_CREAT | O_EXCL | O_NOFOLLOW` under
//!    a random name, `.kg-tmp-<pid>-<random>.<target name>` ([`TEMP_PREFIX`]): a name
//!    nobody can predict, and a file or link planted there makes the open fail and another
//!    name be tried, so the bytes never go through a link;
//! 2. write the bytes and `fsync` the file;
//! 3. rename it over the target (a link at the target is replaced, not followed);
//! 4. on unix, `fsync` the folder so the rename itself survives a crash.
//!
//! A crash or kill leaves at worst a temporary file, never a half-written target; the pid
//! in its name lets a later run tell whose it was and remove it.
//!
//! [`create_dirs_within`] makes the folders of a relative path under a root one at a time
//! and refuses any component that is a symbolic link or not a folder, so a link planted
//! inside an output folder cannot send a write elsewhere.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Component, Path, PathBuf};

use super::error::{FormatError, FormatErrorKind};

/// The name prefix of every temporary file [`write_atomic`] makes.
pub const TEMP_PREFIX: &str = ".kg-tmp-";

/// Buffer between a streaming writer and its temporary file: large enough that a writer
/// emitting one line at a time costs few system calls.
const WRITE_BUFFER_BYTES: usize = 1 << 20;

/// Longest part of the target's name kept in a temporary file's name (bytes), so the
/// temporary name stays under the usual 255-byte limit.
const TEMP_NAME_TAIL: usize = 160;

/// The pid written in the name of a temporary file [`write_atomic`] made; `None` for any
/// other name.
pub fn temp_file_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix(TEMP_PREFIX)?;
    rest.split_once('-')?.0.parse().ok()
}

/// Opens a new file for writing: fails when anything (a file, a link) is already at `path`.
fn create_new_nofollow(path: &Path) -> std::io::Result<File> {
    let mut options = OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NOFOLLOW);
    }
    options.open(path)
}

/// `fsync` of a folder, so a rename into it is durable; file systems that cannot sync a
/// folder (`EINVAL`) are not an error.
fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        match File::open(dir).and_then(|d| d.sync_all()) {
            Err(e) if e.kind() == std::io::ErrorKind::InvalidInput => Ok(()),
            other => other,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

/// The tail of a temporary file's name: `.` and the target's name, cut to
/// [`TEMP_NAME_TAIL`] bytes at a character boundary.
fn temp_suffix(path: &Path) -> String {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let mut end = name.len().min(TEMP_NAME_TAIL);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    format!(".{}", &name[..end])
}

/// Writes `bytes` to `path` atomically (see the module docs); the parent folder must exist.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FormatError> {
    write_atomic_with(path, |out| out.write_all(bytes))
}

/// [`write_atomic`] for a writer that streams its bytes into the (buffered) temporary file,
/// so a large export never holds its whole text in memory. An error from `write` removes
/// the temporary file and leaves the target as it was.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), FormatError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let prefix = format!("{TEMP_PREFIX}{}-", std::process::id());
    let suffix = temp_suffix(path);
    let mut tmp = tempfile::Builder::new()
        .prefix(&prefix)
        .suffix(&suffix)
        .rand_bytes(10)
        .make_in(dir, create_new_nofollow)
        .map_err(|e| FormatError::io(path, &e))?;
    // On any error below, dropping `tmp` removes the temporary file.
    let mut buffered = BufWriter::with_capacity(WRITE_BUFFER_BYTES, tmp.as_file_mut());
    write(&mut buffered).and_then(|()| buffered.flush()).map_err(|e| FormatError::io(path, &e))?;
    drop(buffered);
    tmp.as_file().sync_all().map_err(|e| FormatError::io(path, &e))?;
    tmp.persist(path).map_err(|e| FormatError::io(path, &e.error))?;
    sync_dir(dir).map_err(|e| FormatError::io(dir, &e))
}

/// The components of `relative` when it is a plain relative path (no root, no `..`; `.`
/// dropped); an error naming it otherwise.
fn plain_components<'a>(root: &Path, relative: &'a Path) -> Result<Vec<Component<'a>>, FormatError> {
    let components: Vec<Component> = relative.components().filter(|c| !matches!(c, Component::CurDir)).collect();
    if components.iter().any(|c| !matches!(c, Component::Normal(_))) {
        return Err(FormatError::file(
            &root.join(relative),
            FormatErrorKind::Io,
            format!("'{}' is not a path inside the output folder {}", relative.display(), root.display()),
        ));
    }
    Ok(components)
}

/// Makes the folder `relative` under `root`, one component at a time, and gives
/// `root/relative`. Refuses (naming the path) a `relative` that is absolute or climbs with
/// `..`, and any component that exists as a symbolic link or as a file. `root` itself is
/// taken as given (it may be a link the user chose).
pub fn create_dir_within(root: &Path, relative: &Path) -> Result<PathBuf, FormatError> {
    let components = plain_components(root, relative)?;
    let mut at = root.to_path_buf();
    for component in &components {
        at.push(component);
        let refuse = |message: String| FormatError::file(&at, FormatErrorKind::Io, message);
        match std::fs::symlink_metadata(&at) {
            Ok(m) if m.file_type().is_symlink() => {
                return Err(refuse(
                    "is a symbolic link; nothing is written through links inside the output folder".into(),
                ));
            }
            Ok(m) if m.is_dir() => {}
            Ok(_) => return Err(refuse("exists and is not a folder".into())),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                // `mkdir` never follows a link; a real folder made meanwhile by someone
                // else is fine.
                if let Err(e) = std::fs::create_dir(&at)
                    && !std::fs::symlink_metadata(&at).is_ok_and(|m| m.is_dir())
                {
                    return Err(refuse(format!("cannot create the folder: {e}")));
                }
            }
            Err(e) => return Err(refuse(e.to_string())),
        }
    }
    Ok(at)
}

/// Makes the folders of the file path `relative` under `root` as [`create_dir_within`]
/// does, and gives `root/relative`.
pub fn create_dirs_within(root: &Path, relative: &Path) -> Result<PathBuf, FormatError> {
    let components = plain_components(root, relative)?;
    let Some((_file, dirs)) = components.split_last() else {
        return Err(FormatError::file(root, FormatErrorKind::Io, "an empty file name in the output folder"));
    };
    let dir: PathBuf = dirs.iter().collect();
    Ok(create_dir_within(root, &dir)?.join(components[components.len() - 1]))
}

/// Writes `bytes` atomically to `root/relative`, making its folders without following any
/// link inside `root` ([`create_dirs_within`]); gives the full path.
pub fn write_within(root: &Path, relative: &Path, bytes: &[u8]) -> Result<PathBuf, FormatError> {
    write_within_with(root, relative, |out| out.write_all(bytes))
}

/// [`write_within`] for a streaming writer (see [`write_atomic_with`]).
pub fn write_within_with(
    root: &Path,
    relative: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<PathBuf, FormatError> {
    let path = create_dirs_within(root, relative)?;
    write_atomic_with(&path, write)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    }

    #[test]
    fn writes_and_replaces_without_leaving_temporaries() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bin");
        write_atomic(&path, b"one").unwrap();
        write_atomic(&path, b"two").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"two");
        assert_eq!(names(dir.path()), ["a.bin"]);
    }

    /// A streaming writer that fails part-way (a full disk, a cancelled export) leaves the
    /// previous file whole and no temporary file behind.
    #[test]
    fn a_stream_that_fails_midway_changes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.bvh");
        write_atomic(&path, b"previous").unwrap();
        let err = write_atomic_with(&path, |out| {
            out.write_all(&[b'x'; 3 * WRITE_BUFFER_BYTES])?;
            Err(std::io::Error::other("disk full"))
        })
        .unwrap_err();
        assert!(err.to_string().contains("disk full") && err.to_string().contains("a.bvh"), "{err}");
        assert_eq!(std::fs::read(&path).unwrap(), b"previous");
        assert_eq!(names(dir.path()), ["a.bvh"]);
        // Streamed in many small writes, the file holds exactly what was written.
        write_atomic_with(&path, |out| (0..100_000u32).try_for_each(|i| writeln!(out, "{i}"))).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 100_000);
        assert_eq!(text.lines().last(), Some("99999"));
    }

    #[test]
    fn missing_directory_is_a_located_error() {
        let err = write_atomic(Path::new("/nonexistent-dir/x.glb"), b"x").unwrap_err();
        assert!(err.to_string().contains("/nonexistent-dir/x.glb"));
    }

    #[cfg(unix)]
    #[test]
    fn a_link_planted_at_the_old_temporary_name_does_not_redirect_the_write() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir(&out).unwrap();
        // The name the writer used to pick: predictable from the target and the pid.
        let planted = out.join(format!(".walk.bvh.{}.tmp", std::process::id()));
        std::os::unix::fs::symlink(&victim, &planted).unwrap();
        let target = out.join("walk.bvh");
        write_atomic(&target, b"motion").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious", "the link's target was overwritten");
        let meta = std::fs::symlink_metadata(&target).unwrap();
        assert!(meta.file_type().is_file(), "the output is a link, not a file");
        assert_eq!(std::fs::read(&target).unwrap(), b"motion");
    }

    #[cfg(unix)]
    #[test]
    fn the_temporary_file_is_never_opened_through_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        let link = dir.path().join(".kg-tmp-1-abc.x");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        assert!(create_new_nofollow(&link).is_err());
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    }

    #[cfg(unix)]
    #[test]
    fn a_link_at_the_target_is_replaced_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        let target = dir.path().join("walk.bvh");
        std::os::unix::fs::symlink(&victim, &target).unwrap();
        write_atomic(&target, b"motion").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(std::fs::symlink_metadata(&target).unwrap().file_type().is_file());
    }

    #[test]
    fn temporary_names_carry_the_pid_and_the_target() {
        assert_eq!(temp_file_pid(".kg-tmp-1234-AbCdEfGhIj.walk.bvh"), Some(1234));
        assert_eq!(temp_file_pid(".walk.bvh.1234.tmp"), None);
        assert_eq!(temp_suffix(Path::new("a/walk.bvh")), ".walk.bvh");
        assert!(temp_suffix(Path::new(&"é".repeat(200))).len() <= TEMP_NAME_TAIL + 1);
    }

    #[cfg(unix)]
    #[test]
    fn a_linked_folder_inside_the_root_is_refused_and_its_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let elsewhere = dir.path().join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        let root = dir.path().join("out");
        std::fs::create_dir(&root).unwrap();
        std::os::unix::fs::symlink(&elsewhere, root.join("task")).unwrap();
        let err = write_within(&root, Path::new("task/walk.bvh"), b"motion").unwrap_err();
        assert!(err.to_string().contains("symbolic link"), "{err}");
        assert!(names(&elsewhere).is_empty());
    }

    #[test]
    fn paths_that_climb_out_or_cross_a_file_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("file"), b"").unwrap();
        for bad in ["../x.bvh", "/abs/x.bvh", "a/../../x.bvh", "file/x.bvh", ""] {
            assert!(write_within(dir.path(), Path::new(bad), b"x").is_err(), "{bad}");
        }
        let written = write_within(dir.path(), Path::new("a/b/c.bvh"), b"x").unwrap();
        assert_eq!(std::fs::read(written).unwrap(), b"x");
    }
}
