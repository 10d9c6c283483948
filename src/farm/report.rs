//! Per-task reports (also the idempotency marker) and the merged summary of a plan's run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::plan::{HashedFile, Plan, PlanError, Task};

/// Folder under the run's output root that holds one report per task.
pub const REPORTS_DIR: &str = "reports";
/// The merged summary's default name at the top of the output root.
pub const SUMMARY_FILE: &str = "summary.json";

/// How a task's last attempt ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TaskStatus {
    /// Ran and wrote every expected output.
    Ok,
    /// Did nothing: the outputs of an earlier successful attempt were present with matching
    /// hashes.
    Skipped,
    /// A node failed (exit code 1); no output of the attempt was kept.
    Failed,
    /// The graph, the plan or an input was invalid (exit code 2).
    Invalid,
    /// A signal (SIGINT, SIGTERM) stopped the attempt (exit code 130); nothing of it was
    /// kept.
    Cancelled,
}

/// What one attempt at a task did; written atomically to `reports/<id>.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TaskReport {
    /// The task's index in the plan.
    pub index: usize,
    /// The task id.
    pub id: String,
    /// How the attempt ended.
    pub status: TaskStatus,
    /// The exit code `kg run` gave.
    pub exit_code: u8,
    /// Wall time of the attempt, seconds (0 for a skip).
    pub seconds: f64,
    /// Hash of the graph the attempt ran.
    pub graph_sha256: String,
    /// Hashes of the inputs the attempt read, by binding name.
    pub inputs: BTreeMap<String, String>,
    /// The outputs, relative to the run's output root, with their hashes (empty on failure).
    pub outputs: Vec<HashedFile>,
    /// Per node id: its status (`ok`, `error`, `blocked`, …), when the graph ran.
    #[serde(default)]
    pub nodes: BTreeMap<String, String>,
    /// The first error, when the attempt failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl TaskReport {
    /// Where the report of `task` lives under the output root `out`.
    pub fn path(out: &Path, task: &Task) -> PathBuf {
        out.join(Self::relative_path(&task.id))
    }

    /// Reads a report; `None` when there is none (or it cannot be parsed: it is then
    /// treated as absent and the task runs again).
    pub fn read(path: &Path) -> Option<TaskReport> {
        Self::load(path).ok().flatten()
    }

    /// Reads a report: `Ok(None)` when there is none, an error naming the file when it
    /// cannot be read or parsed.
    pub fn load(path: &Path) -> Result<Option<TaskReport>, String> {
        let text = match std::fs::read_to_string(path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("{}: {e}", path.display())),
        };
        serde_json::from_str(&text).map(Some).map_err(|e| format!("{}: not a task report: {e}", path.display()))
    }

    /// Where the report of the task with id `id` lives, relative to the output root.
    pub fn relative_path(id: &str) -> PathBuf {
        Path::new(REPORTS_DIR).join(format!("{id}.json"))
    }

    /// Writes the report atomically under the output root `out` (making the reports
    /// folder, never through a link).
    pub fn write(&self, out: &Path) -> Result<(), PlanError> {
        let relative = Self::relative_path(&self.id);
        let io = |message: String| PlanError::Io { path: out.join(&relative), message };
        let mut text = serde_json::to_string_pretty(self).map_err(|e| io(e.to_string()))?;
        text.push('\n');
        crate::output::save_within(out, &relative, text.as_bytes()).map(|_| ()).map_err(io)
    }

    /// True when this report proves `task` done for this graph and these input hashes: it
    /// succeeded, it lists exactly the task's outputs, and each is on disk under `out` with
    /// the recorded hash.
    pub fn is_up_to_date(
        &self,
        task: &Task,
        graph_sha256: &str,
        inputs: &BTreeMap<String, String>,
        out: &Path,
    ) -> bool {
        let listed: Vec<&str> = self.outputs.iter().map(|o| o.path.as_str()).collect();
        let expected: Vec<&str> = task.outputs.iter().map(String::as_str).collect();
        matches!(self.status, TaskStatus::Ok | TaskStatus::Skipped)
            && self.graph_sha256 == graph_sha256
            && &self.inputs == inputs
            && listed == expected
            && self.outputs.iter().all(|o| o.mismatch(&out.join(&o.path)).is_none())
    }

    /// Why the outputs on disk under `out` are not what this report of `task` recorded
    /// (an output missing, resized or changed, or the list not the task's); `None` when
    /// they are.
    pub fn check_outputs(&self, task: &Task, out: &Path) -> Option<String> {
        let listed: Vec<&str> = self.outputs.iter().map(|o| o.path.as_str()).collect();
        let expected: Vec<&str> = task.outputs.iter().map(String::as_str).collect();
        if listed != expected {
            return Some(format!("the report lists outputs {listed:?}, the plan {expected:?}"));
        }
        let problems: Vec<String> = self.outputs.iter().filter_map(|o| o.mismatch(&out.join(&o.path))).collect();
        (!problems.is_empty()).then(|| format!("outputs differ from the report: {}", problems.join("; ")))
    }
}

/// One task's line in the summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TaskSummary {
    /// The task's index.
    pub index: usize,
    /// The task id.
    pub id: String,
    /// Its last attempt's status, or `missing` when it has no report.
    pub status: String,
    /// Seconds of the last attempt.
    pub seconds: f64,
    /// The error of a failed attempt.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The merged reports of a plan's tasks.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// The plan's graph.
    pub graph: String,
    /// Tasks in the plan.
    pub tasks: usize,
    /// Counts per status (`ok`, `skipped`, `failed`, `invalid`, `cancelled`, `missing`),
    /// every key present.
    pub counts: BTreeMap<String, usize>,
    /// Sum of the attempts' seconds.
    pub total_seconds: f64,
    /// Per task, in index order.
    pub per_task: Vec<TaskSummary>,
    /// Reports that could not be read (each names its file); their tasks count as failed.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

impl Summary {
    /// True when every task finished (ran or was already done).
    pub fn all_done(&self) -> bool {
        self.per_task.iter().all(|t| t.status == "ok" || t.status == "skipped")
    }
}

/// The name serde gives a unit enum variant (`TaskStatus::Ok` → `"ok"`).
pub fn serde_name(value: impl Serialize) -> String {
    serde_json::to_value(value).ok().and_then(|v| v.as_str().map(str::to_string)).unwrap_or_default()
}

/// Collects the reports of `plan`'s tasks from the output root `out`, and checks every
/// output a successful report lists against the disk (present, same size, same SHA-256):
/// a task whose outputs are missing or changed counts as `failed`, with the reason. A
/// report that cannot be read is a warning naming the file, and its task counts as
/// `failed`; a task without a report is `missing`.
pub fn merge(plan: &Plan, out: &Path) -> Summary {
    let mut counts: BTreeMap<String, usize> =
        ["ok", "skipped", "failed", "invalid", "cancelled", "missing"].iter().map(|s| (s.to_string(), 0)).collect();
    let mut per_task = Vec::with_capacity(plan.tasks.len());
    let mut warnings = Vec::new();
    for task in &plan.tasks {
        let line = |status: &str, seconds: f64, error: Option<String>| TaskSummary {
            index: task.index,
            id: task.id.clone(),
            status: status.to_string(),
            seconds,
            error,
        };
        let path = TaskReport::path(out, task);
        let line = match TaskReport::load(&path) {
            Ok(Some(r)) if r.id != task.id => {
                let why = format!("{}: the report is of task {:?}, not {:?}", path.display(), r.id, task.id);
                warnings.push(why.clone());
                line("failed", r.seconds, Some(why))
            }
            Ok(Some(r)) if matches!(r.status, TaskStatus::Ok | TaskStatus::Skipped) => match r.check_outputs(task, out)
            {
                None => line(&serde_name(r.status), r.seconds, r.error),
                Some(why) => line("failed", r.seconds, Some(why)),
            },
            Ok(Some(r)) => line(&serde_name(r.status), r.seconds, r.error),
            Ok(None) => line("missing", 0.0, None),
            Err(e) => {
                warnings.push(e.clone());
                line("failed", 0.0, Some(format!("unreadable report: {e}")))
            }
        };
        *counts.entry(line.status.clone()).or_default() += 1;
        per_task.push(line);
    }
    Summary {
        graph: plan.graph.path.clone(),
        tasks: plan.tasks.len(),
        counts,
        total_seconds: per_task.iter().map(|t| t.seconds).sum(),
        per_task,
        warnings,
    }
}
