//! One attempt at a farm task, as the library sees it: the inputs checked against the
//! plan's hashes, a hidden staging folder per attempt, what killed attempts left removed,
//! and a successful attempt's outputs moved into place and hashed. `kg run --plan` drives
//! it (locks, leases, reports).

use std::collections::BTreeMap;
use std::path::Path;

use super::plan::{normalised_absolute, sha256_file};
use super::report::REPORTS_DIR;
use super::{HashedFile, Task};
use crate::output::is_temp_of;

/// The task's input hashes as they are on disk now; an error when a file is missing or
/// differs from the hash the plan recorded.
pub fn check_inputs(task: &Task, base: &Path, plan_path: &Path) -> Result<BTreeMap<String, String>, String> {
    let mut hashes = BTreeMap::new();
    for (name, file) in &task.inputs {
        let path = normalised_absolute(&base.join(&file.path));
        let actual = sha256_file(&path).map_err(|e| {
            let upstream: Vec<String> =
                task.depends_on.iter().map(|d| format!("task {} ({}) of {}", d.index, d.task, d.plan)).collect();
            let hint = if file.sha256.is_empty() && !upstream.is_empty() {
                format!(" (made by {}: has it finished?)", upstream.join(", "))
            } else {
                String::new()
            };
            format!("{}: task {} ({}): input '{name}': {e}{hint}", plan_path.display(), task.index, task.id)
        })?;
        if !file.sha256.is_empty() && actual != file.sha256 {
            return Err(format!(
                "{}: task {} ({}): input '{name}' ({}) changed since planning: sha256 {actual}, the plan says {}; re-run `kg plan`",
                plan_path.display(),
                task.index,
                task.id,
                path.display(),
                file.sha256
            ));
        }
        hashes.insert(name.clone(), actual);
    }
    Ok(hashes)
}

/// The name prefix of the task's staging folders under the output root; the full name is
/// `.<id>.partial-<pid>-<random>`.
pub fn staging_prefix(task: &Task) -> String {
    format!(".{}.partial-", task.id)
}

/// True when `name` is a staging folder of `task` (not of a task whose id merely starts
/// like it, e.g. `a` and `a.partial-2`).
fn is_staging_of(name: &str, task: &Task) -> bool {
    name.strip_prefix(&staging_prefix(task)).and_then(|rest| rest.split_once('-')).is_some_and(|(pid, random)| {
        !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()) && random.bytes().all(|b| b.is_ascii_alphanumeric())
    })
}

/// Removes what earlier attempts of the task left behind when killed: staging folders and
/// temporary report files. Only called while holding the task's lease, so none of them
/// belongs to a running attempt.
pub fn remove_stale_attempts(out: &Path, task: &Task) {
    if let Ok(entries) = std::fs::read_dir(out) {
        for entry in entries.flatten() {
            let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
            if is_dir && is_staging_of(&entry.file_name().to_string_lossy(), task) {
                let _ = std::fs::remove_dir_all(entry.path());
            }
        }
    }
    let report_name = format!("{}.json", task.id);
    if let Ok(entries) = std::fs::read_dir(out.join(REPORTS_DIR)) {
        for entry in entries.flatten() {
            if is_temp_of(&entry.file_name().to_string_lossy(), &report_name) {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
}

/// Moves a successful attempt's outputs into place and hashes them; an error (and the
/// staging folder removed) when an expected output is missing or the move fails.
pub fn publish(task: &Task, staging: &Path, out: &Path) -> Result<Vec<HashedFile>, String> {
    let prefix = format!("{}/", task.id);
    for output in &task.outputs {
        let in_staging = staging.join(output.strip_prefix(&prefix).unwrap_or(output));
        if !in_staging.is_file() {
            return Err(format!("expected output '{output}' was not written"));
        }
    }
    let final_dir = out.join(task.out_dir());
    if final_dir.exists() {
        std::fs::remove_dir_all(&final_dir).map_err(|e| format!("{}: cannot replace: {e}", final_dir.display()))?;
    }
    std::fs::rename(staging, &final_dir)
        .map_err(|e| format!("{}: cannot move outputs into place: {e}", final_dir.display()))?;
    task.outputs
        .iter()
        .map(|o| {
            let path = out.join(o);
            let size = std::fs::metadata(&path).map_err(|e| format!("{}: {e}", path.display()))?.len();
            Ok(HashedFile { path: o.clone(), sha256: sha256_file(&path).map_err(|e| e.to_string())?, size: Some(size) })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staging_folders_are_told_apart_from_those_of_tasks_with_longer_ids() {
        let task = |id: &str| Task {
            index: 0,
            id: id.into(),
            inputs: BTreeMap::new(),
            set: BTreeMap::new(),
            outputs: Vec::new(),
            depends_on: Vec::new(),
        };
        assert!(is_staging_of(".a.partial-123-AbC9xYz", &task("a")));
        assert!(!is_staging_of(".a.partial-1.partial-123-AbC9xYz", &task("a")));
        assert!(is_staging_of(".a.partial-1.partial-123-AbC9xYz", &task("a.partial-1")));
        assert!(!is_staging_of(".a.partial-", &task("a")));
        assert!(!is_staging_of(".ab.partial-1-x", &task("a")));
    }
}
