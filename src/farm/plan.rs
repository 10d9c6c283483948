//! The plan file: a deterministic list of graph runs (tasks) for a farm.
//!
//! A plan is JSON with sorted keys and no timestamps, so planning the same graph over the
//! same files twice gives identical bytes. Paths given absolute stay absolute; every other
//! path is stored relative to the plan file's own folder, so a plan moves with the tree it
//! describes and any farm host that mounts the tree can run it, whatever its current
//! directory.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::output::check_folder_name;

/// The `format` field of every plan file.
pub const PLAN_FORMAT: &str = "kinegraph.plan";
/// The plan file version this kinegraph writes and reads.
pub const PLAN_VERSION: u32 = 1;

/// Why a plan could not be read, written or trusted.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The plan file is not a plan this kinegraph understands.
    #[error("{path}: {message}")]
    Invalid {
        /// The plan file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

/// A content-addressed file: its path and SHA-256.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct HashedFile {
    /// Absolute as given, else relative to the plan file's folder, `/`-separated.
    pub path: String,
    /// Lower-case hex SHA-256 of the file's bytes.
    pub sha256: String,
    /// The file's size in bytes, where recorded (task reports' outputs).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<u64>,
}

impl HashedFile {
    /// Why the file at `path` is not this one (missing, not a plain file, another size,
    /// other bytes); `None` when it is.
    pub fn mismatch(&self, path: &Path) -> Option<String> {
        let meta = match std::fs::symlink_metadata(path) {
            Ok(m) => m,
            Err(e) => return Some(format!("{}: {e}", path.display())),
        };
        if !meta.is_file() {
            return Some(format!("{}: not a plain file", path.display()));
        }
        if let Some(size) = self.size
            && meta.len() != size
        {
            return Some(format!("{}: {} bytes, the report says {size}", path.display(), meta.len()));
        }
        match sha256_file(path) {
            Ok(h) if h == self.sha256 => None,
            Ok(h) => Some(format!("{}: sha256 {h}, the report says {}", path.display(), self.sha256)),
            Err(e) => Some(e.to_string()),
        }
    }
}

/// A task of another plan that must finish before a task of this one can start.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Dependency {
    /// The other plan file, relative to this plan's folder.
    pub plan: String,
    /// The task id in that plan.
    pub task: String,
    /// Its index in that plan.
    pub index: usize,
}

/// One graph run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Task {
    /// Position in the plan; what `--task-index` and the farm's array index name.
    pub index: usize,
    /// Stable, readable id: the input file stems (disambiguated), also the output folder.
    pub id: String,
    /// Input-file bindings (graph input or `node.param` → file). A file another plan makes
    /// has no hash yet (`sha256` empty) and is listed in `depends_on`.
    pub inputs: BTreeMap<String, HashedFile>,
    /// Other `--set` overrides (graph input or `node.param` → value text).
    pub set: BTreeMap<String, String>,
    /// Files the run writes, relative to the run's output root (`<id>/<file>`).
    pub outputs: Vec<String>,
    /// Tasks of other plans whose outputs this task reads.
    #[serde(default)]
    pub depends_on: Vec<Dependency>,
}

impl Task {
    /// The task's output folder, relative to the run's output root.
    pub fn out_dir(&self) -> &str {
        &self.id
    }
}

/// A task list for one graph.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// Always [`PLAN_FORMAT`].
    pub format: String,
    /// Always [`PLAN_VERSION`].
    pub version: u32,
    /// The graph file and its hash.
    pub graph: HashedFile,
    /// Plans whose outputs feed this one, relative to this plan's folder.
    #[serde(default)]
    pub after: Vec<String>,
    /// The tasks, in index order.
    pub tasks: Vec<Task>,
}

impl Plan {
    /// The plan as canonical JSON text: sorted keys (serde_json's map is a BTreeMap here),
    /// two-space indent, trailing newline.
    pub fn to_json(&self) -> String {
        let value = serde_json::to_value(self).unwrap_or(serde_json::Value::Null);
        let mut text = serde_json::to_string_pretty(&value).unwrap_or_default();
        text.push('\n');
        text
    }

    /// Reads and checks a plan file.
    pub fn read(path: &Path) -> Result<Plan, PlanError> {
        let io = |e: std::io::Error| PlanError::Io { path: path.to_path_buf(), message: e.to_string() };
        let invalid = |message: String| PlanError::Invalid { path: path.to_path_buf(), message };
        let text = std::fs::read_to_string(path).map_err(io)?;
        let header: serde_json::Value = serde_json::from_str(&text).map_err(|e| invalid(format!("not JSON: {e}")))?;
        if header.get("format").and_then(|f| f.as_str()) != Some(PLAN_FORMAT) {
            return Err(invalid(format!("not a kinegraph plan (expected \"format\": \"{PLAN_FORMAT}\")")));
        }
        let version = header.get("version").and_then(|v| v.as_u64()).unwrap_or(0);
        if version != u64::from(PLAN_VERSION) {
            return Err(invalid(format!("plan version {version} is not {PLAN_VERSION}: re-plan with this kg")));
        }
        let plan: Plan = serde_json::from_value(header).map_err(|e| invalid(e.to_string()))?;
        if let Some((i, task)) = plan.tasks.iter().enumerate().find(|(i, t)| t.index != *i) {
            return Err(invalid(format!("task {:?} has index {} but is listed at {i}", task.id, task.index)));
        }
        plan.check_ids().map_err(invalid)?;
        Ok(plan)
    }

    /// Checks that every task id can be its output folder (a single safe path component,
    /// not a name kg uses: [`check_folder_name`]), that ids are unique, and that every
    /// output lies inside its task's folder; a tampered plan must not send a task's files
    /// or report outside the output root, or over another task's.
    pub fn check_ids(&self) -> Result<(), String> {
        let mut seen: BTreeMap<String, usize> = BTreeMap::new();
        for task in &self.tasks {
            check_folder_name(&task.id).map_err(|why| format!("task {}: id {:?} {why}", task.index, task.id))?;
            if let Some(other) = seen.insert(task.id.to_lowercase(), task.index) {
                return Err(format!("task {}: id {:?} is also the id of task {other}", task.index, task.id));
            }
            for output in &task.outputs {
                let inside = output.strip_prefix(&format!("{}/", task.id)).is_some_and(|rest| {
                    let rest = Path::new(rest);
                    rest.components().next().is_some() && rest.components().all(|c| matches!(c, Component::Normal(_)))
                });
                if !inside {
                    return Err(format!(
                        "task {}: output {output:?} is not a file inside the task's folder '{}/'",
                        task.index, task.id
                    ));
                }
            }
        }
        Ok(())
    }

    /// The task at `index`, or an error naming the plan's size.
    pub fn task(&self, index: usize, path: &Path) -> Result<&Task, PlanError> {
        self.tasks.get(index).ok_or_else(|| PlanError::Invalid {
            path: path.to_path_buf(),
            message: format!(
                "--task-index {index} is out of range: the plan has {} tasks (0..={})",
                self.tasks.len(),
                self.tasks.len().saturating_sub(1)
            ),
        })
    }
}

/// Lower-case hex SHA-256 of a file's bytes ([`crate::digest::sha256_file`]), an error
/// naming the file.
pub fn sha256_file(path: &Path) -> Result<String, PlanError> {
    crate::digest::sha256_file(path).map_err(|e| PlanError::Io { path: path.to_path_buf(), message: e.to_string() })
}

/// `path` made absolute against the current directory, with `.` and `..` removed lexically.
pub fn normalised_absolute(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut out = PathBuf::new();
    for component in absolute.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

/// `path` relative to the folder `base` (both taken against the current directory), as
/// `/`-separated text: what a plan stores.
pub fn relative_to(path: &Path, base: &Path) -> String {
    let path = normalised_absolute(path);
    let base = normalised_absolute(base);
    let common = path.components().zip(base.components()).take_while(|(a, b)| a == b).count();
    let ups = base.components().count() - common;
    let parts: Vec<String> = std::iter::repeat_n("..".to_string(), ups)
        .chain(path.components().skip(common).map(|c| c.as_os_str().to_string_lossy().into_owned()))
        .collect();
    if parts.is_empty() { ".".into() } else { parts.join("/") }
}

/// The folder a plan's relative paths resolve against.
pub fn plan_dir(plan_path: &Path) -> PathBuf {
    normalised_absolute(plan_path).parent().map(Path::to_path_buf).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn relative_paths_climb_and_descend() {
        assert_eq!(relative_to(Path::new("/a/b/c.bvh"), Path::new("/a/x/y")), "../../b/c.bvh");
        assert_eq!(relative_to(Path::new("/a/x/y/c.bvh"), Path::new("/a/x")), "y/c.bvh");
        assert_eq!(relative_to(Path::new("/a/./x/../b.ron"), Path::new("/a")), "b.ron");
        assert_eq!(relative_to(Path::new("/a"), Path::new("/a")), ".");
    }

    #[test]
    fn a_file_that_is_not_a_plan_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.json");
        std::fs::write(&path, r#"{"format": "other"}"#).unwrap();
        let err = Plan::read(&path).unwrap_err().to_string();
        assert!(err.contains("p.json") && err.contains("not a kinegraph plan"), "{err}");
    }
}
