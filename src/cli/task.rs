//! `kg run --plan PLAN --task-index I`: one task of a plan, through the same evaluator as
//! `kg run`, idempotently.
//!
//! The task runs into a hidden staging folder beside its output folder; only a successful
//! run is moved into place, so a failed or interrupted attempt never leaves partial
//! outputs. The task's report (`reports/<id>.json`, written atomically last) records the
//! output hashes; a retry that finds it with every output present and matching does
//! nothing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::batch::{BatchRun, run_once};
use super::run::Setting;
use super::{EXIT_BUSY, EXIT_CANCELLED, EXIT_FAILED, EXIT_INVALID};
use crate::farm::plan::{normalised_absolute, plan_dir, sha256_file};
use crate::farm::report::{REPORTS_DIR, serde_name};
use crate::farm::{HashedFile, Plan, Task, TaskReport, TaskStatus};
use crate::output::{Lease, OutLock, is_temp_of};

/// Prints `message` and gives the exit code for an invalid plan, task or input.
fn invalid(message: impl std::fmt::Display) -> u8 {
    eprintln!("{message}");
    EXIT_INVALID
}

/// The task's input hashes as they are on disk now; an error when a file is missing or
/// differs from the hash the plan recorded.
fn check_inputs(task: &Task, base: &Path, plan_path: &Path) -> Result<BTreeMap<String, String>, String> {
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
fn staging_prefix(task: &Task) -> String {
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
fn remove_stale_attempts(out: &Path, task: &Task) {
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
fn publish(task: &Task, staging: &Path, out: &Path) -> Result<Vec<HashedFile>, String> {
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

/// Runs task `index` of the plan at `plan_path` into the output root `out`.
pub(super) fn task_command(
    plan_path: &Path,
    index: usize,
    graph: Option<&Path>,
    out: &Path,
    threads: Option<usize>,
    json: bool,
    cache: &super::CacheArgs,
) -> u8 {
    let started = Instant::now();
    // From here on a signal cancels cleanly instead of killing the task.
    let _ = super::run::cancel_flag();
    let plan = match Plan::read(plan_path) {
        Ok(p) => p,
        Err(e) => return invalid(e),
    };
    let task = match plan.task(index, plan_path) {
        Ok(t) => t,
        Err(e) => return invalid(e),
    };
    let base = plan_dir(plan_path);
    let graph_path = normalised_absolute(&base.join(&plan.graph.path));
    if let Some(given) = graph
        && normalised_absolute(given) != normalised_absolute(&graph_path)
    {
        return invalid(format!(
            "{}: the plan is of graph {}, not {}",
            plan_path.display(),
            graph_path.display(),
            given.display()
        ));
    }
    match sha256_file(&graph_path) {
        Ok(h) if h == plan.graph.sha256 => {}
        Ok(_) => {
            return invalid(format!(
                "{}: graph {} changed since planning; re-run `kg plan`",
                plan_path.display(),
                graph_path.display()
            ));
        }
        Err(e) => return invalid(format!("{}: {e}", plan_path.display())),
    }
    let input_hashes = match check_inputs(task, &base, plan_path) {
        Ok(h) => h,
        Err(e) => return invalid(e),
    };
    let _lock = match OutLock::shared(out) {
        Ok(lock) => lock,
        Err(e) => {
            eprintln!("{e}");
            return EXIT_BUSY;
        }
    };
    let _lease = match Lease::take(out, &task.id) {
        Ok(lease) => lease,
        Err(e) => {
            eprintln!("{}: task {index}: {e}", plan_path.display());
            return EXIT_BUSY;
        }
    };
    let report_path = TaskReport::path(out, task);
    let previous = TaskReport::read(&report_path);
    if let Some(previous) = previous.filter(|r| r.is_up_to_date(task, &plan.graph.sha256, &input_hashes, out)) {
        let report = TaskReport {
            status: TaskStatus::Skipped,
            seconds: started.elapsed().as_secs_f64(),
            nodes: BTreeMap::new(),
            error: None,
            ..previous
        };
        eprintln!(
            "task {index} ({}): already done, {} outputs present with matching hashes; nothing to do",
            task.id,
            report.outputs.len()
        );
        return finish(&report, out, json);
    }

    remove_stale_attempts(out, task);
    // A fresh folder under a random name (`mkdir` fails on anything planted there).
    let staging = match tempfile::Builder::new()
        .prefix(&format!("{}{}-", staging_prefix(task), std::process::id()))
        .tempdir_in(out)
    {
        Ok(dir) => dir.keep(),
        Err(e) => return invalid(format!("{}: cannot make a staging folder: {e}", out.display())),
    };
    let mut settings: Vec<Setting> =
        task.set.iter().map(|(name, value)| Setting { name: name.clone(), value: value.clone() }).collect();
    settings.extend(task.inputs.iter().map(|(name, file)| Setting {
        name: name.clone(),
        value: normalised_absolute(&base.join(&file.path)).to_string_lossy().into_owned(),
    }));
    let engine = match cache.engine() {
        Ok(engine) => engine,
        Err(code) => return code,
    };
    let label = PathBuf::from(&task.id);
    let mut run: BatchRun = run_once(&engine, &graph_path, &settings, &label, &staging, threads);
    let outputs = if run.exit_code == 0 {
        publish(task, &staging, out).unwrap_or_else(|e| {
            run.exit_code = EXIT_FAILED;
            run.error = Some(e);
            Vec::new()
        })
    } else {
        Vec::new()
    };
    if run.exit_code != 0 {
        // Nothing of a failed attempt, nor an older result it would contradict, survives.
        let _ = std::fs::remove_dir_all(&staging);
        let _ = std::fs::remove_dir_all(out.join(task.out_dir()));
    }
    let report = TaskReport {
        index,
        id: task.id.clone(),
        status: match run.exit_code {
            0 => TaskStatus::Ok,
            EXIT_FAILED => TaskStatus::Failed,
            EXIT_CANCELLED => TaskStatus::Cancelled,
            _ => TaskStatus::Invalid,
        },
        exit_code: run.exit_code,
        seconds: started.elapsed().as_secs_f64(),
        graph_sha256: plan.graph.sha256.clone(),
        inputs: input_hashes,
        outputs,
        nodes: run.nodes.iter().map(|(id, n)| (id.clone(), serde_name(n.status))).collect(),
        error: run.error.clone(),
    };
    match (report.status, &report.error) {
        (TaskStatus::Ok, _) => {
            eprintln!("task {index} ({}): ok, {} outputs, {:.3} s", task.id, report.outputs.len(), report.seconds)
        }
        (TaskStatus::Cancelled, _) => eprintln!("task {index} ({}): cancelled by a signal; nothing kept", task.id),
        (_, Some(e)) => eprintln!("task {index} ({}): FAILED: {e}", task.id),
        (_, None) => eprintln!("task {index} ({}): FAILED (exit code {})", task.id, report.exit_code),
    }
    finish(&report, out, json)
}

/// Writes the task report (the idempotency marker), prints it with `--json`, and gives the
/// exit code.
fn finish(report: &TaskReport, out: &Path, json: bool) -> u8 {
    if let Err(e) = report.write(out) {
        eprintln!("{e}");
        return EXIT_FAILED.max(report.exit_code);
    }
    if json {
        outln!("{}", serde_json::to_string(report).unwrap_or_default());
    }
    report.exit_code
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
