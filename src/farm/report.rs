//! Per-task reports (also the idempotency marker) and the merged summary of a plan's run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::plan::{HashedFile, Plan, PlanError, Task, sha256_file};

/// Folder under the run's output root that holds one report per task.
pub const REPORTS_DIR: &str = "reports";

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
        out.join(REPORTS_DIR).join(format!("{}.json", task.id))
    }

    /// Reads a report; `None` when there is none (or it cannot be parsed: it is then
    /// treated as absent and the task runs again).
    pub fn read(path: &Path) -> Option<TaskReport> {
        let text = std::fs::read_to_string(path).ok()?;
        serde_json::from_str(&text).ok()
    }

    /// Writes the report atomically (creating the reports folder).
    pub fn write(&self, path: &Path) -> Result<(), PlanError> {
        let io = |message: String| PlanError::Io { path: path.to_path_buf(), message };
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| io(e.to_string()))?;
        }
        let mut text = serde_json::to_string_pretty(self).map_err(|e| io(e.to_string()))?;
        text.push('\n');
        kinegraph_nodes::formats::atomic::write_atomic(path, text.as_bytes()).map_err(|e| io(e.message))
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
            && self.outputs.iter().all(|o| sha256_file(&out.join(&o.path)).is_ok_and(|h| h == o.sha256))
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
    /// Counts per status (`ok`, `skipped`, `failed`, `invalid`, `missing`), every key present.
    pub counts: BTreeMap<String, usize>,
    /// Sum of the attempts' seconds.
    pub total_seconds: f64,
    /// Per task, in index order.
    pub per_task: Vec<TaskSummary>,
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

/// Collects the reports of `plan`'s tasks from the output root `out`.
pub fn merge(plan: &Plan, out: &Path) -> Summary {
    let mut counts: BTreeMap<String, usize> =
        ["ok", "skipped", "failed", "invalid", "missing"].iter().map(|s| (s.to_string(), 0)).collect();
    let mut per_task = Vec::with_capacity(plan.tasks.len());
    for task in &plan.tasks {
        let line = match TaskReport::read(&TaskReport::path(out, task)).filter(|r| r.id == task.id) {
            Some(r) => TaskSummary {
                index: task.index,
                id: task.id.clone(),
                status: serde_name(r.status),
                seconds: r.seconds,
                error: r.error,
            },
            None => TaskSummary {
                index: task.index,
                id: task.id.clone(),
                status: "missing".into(),
                seconds: 0.0,
                error: None,
            },
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
    }
}
