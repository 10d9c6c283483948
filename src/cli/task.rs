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
use crate::engine::Engine;
use crate::farm::attempt::{check_inputs, publish, remove_stale_attempts, staging_prefix};
use crate::farm::plan::{normalised_absolute, plan_dir, sha256_file};
use crate::farm::report::serde_name;
use crate::farm::{Plan, TaskReport, TaskStatus};
use crate::output::{Lease, OutLock};

/// Prints `message` and gives the exit code for an invalid plan, task or input.
fn invalid(message: impl std::fmt::Display) -> u8 {
    errln!("{message}");
    EXIT_INVALID
}

/// Runs task `index` of the plan at `plan_path` into the output root `out`.
pub(super) fn task_command(
    plan_path: &Path,
    index: usize,
    graph: Option<&Path>,
    out: &Path,
    threads: Option<usize>,
    json: bool,
    engine: Engine,
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
            errln!("{e}");
            return EXIT_BUSY;
        }
    };
    let _lease = match Lease::take(out, &task.id) {
        Ok(lease) => lease,
        Err(e) => {
            errln!("{}: task {index}: {e}", plan_path.display());
            return EXIT_BUSY;
        }
    };
    // Under the lease no other attempt runs: what a killed one left goes first, also
    // when this attempt then finds the task done (a kill can land while a report of
    // "skipped" is being written).
    remove_stale_attempts(out, task);
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
        errln!(
            "task {index} ({}): already done, {} outputs present with matching hashes; nothing to do",
            task.id,
            report.outputs.len()
        );
        return finish(&report, out, json);
    }

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
            errln!("task {index} ({}): ok, {} outputs, {:.3} s", task.id, report.outputs.len(), report.seconds)
        }
        (TaskStatus::Cancelled, _) => errln!("task {index} ({}): cancelled by a signal; nothing kept", task.id),
        (_, Some(e)) => errln!("task {index} ({}): FAILED: {e}", task.id),
        (_, None) => errln!("task {index} ({}): FAILED (exit code {})", task.id, report.exit_code),
    }
    finish(&report, out, json)
}

/// Writes the task report (the idempotency marker), prints it with `--json`, and gives the
/// exit code.
fn finish(report: &TaskReport, out: &Path, json: bool) -> u8 {
    if let Err(e) = report.write(out) {
        errln!("{e}");
        return EXIT_FAILED.max(report.exit_code);
    }
    if json {
        outln!("{}", serde_json::to_string(report).unwrap_or_default());
    }
    report.exit_code
}
