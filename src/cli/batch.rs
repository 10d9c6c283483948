//! `kg batch`: one run of a graph per input file, in parallel, continuing past failures,
//! with a summary table and a JSON report (also saved as `batch_report.json` in --out).

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Instant, SystemTime};

use serde::Serialize;

use super::run::{Setting, absolute, cancel_flag, execute, exit_code};
use super::{EXIT_BUSY, EXIT_CANCELLED, EXIT_FAILED, EXIT_INVALID};
use crate::engine::{Engine, NodeReport, NodeStatus};
use crate::farm::inputs::{expand_glob, run_folder_names};
use crate::graph::GraphFile;
use crate::output::{OutLock, folder_within, remove_own_temps, remove_stale_temps, safe_unique_names, save_within};

/// The batch report's name at the top of `--out`.
pub const BATCH_REPORT: &str = "batch_report.json";

/// How one input file's run ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RunStatus {
    /// Every node ran (or was cached).
    Ok,
    /// A node failed, or the graph or its folder was refused.
    Failed,
    /// A signal stopped it while it ran.
    Cancelled,
    /// A signal stopped the batch before it started.
    NotRun,
}

impl RunStatus {
    /// The word the summary table shows.
    pub fn label(self) -> &'static str {
        match self {
            RunStatus::Ok => "ok",
            RunStatus::Failed => "FAILED",
            RunStatus::Cancelled => "cancelled",
            RunStatus::NotRun => "not run",
        }
    }
}

/// One input file's run.
#[derive(Debug, Serialize)]
pub struct BatchRun {
    /// The input file.
    pub input: PathBuf,
    /// How it ended.
    pub status: RunStatus,
    /// Where its exports went.
    pub out_dir: PathBuf,
    /// Exit code this run alone would have had.
    pub exit_code: u8,
    /// Seconds.
    pub seconds: f64,
    /// Per-node reports.
    pub nodes: BTreeMap<String, NodeReport>,
    /// Files written.
    pub files_written: Vec<PathBuf>,
    /// First error, for the summary.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl BatchRun {
    /// A run that did not evaluate the graph, with its exit code and why.
    pub fn refused(input: &Path, out_dir: &Path, exit_code: u8, error: String) -> BatchRun {
        BatchRun {
            input: input.to_path_buf(),
            status: if exit_code == EXIT_CANCELLED { RunStatus::NotRun } else { RunStatus::Failed },
            out_dir: absolute(out_dir),
            exit_code,
            seconds: 0.0,
            nodes: BTreeMap::new(),
            files_written: Vec::new(),
            error: Some(error),
        }
    }
}

/// One run of `graph` with `settings` into `out_dir`, as `kg batch` and `kg run --plan`
/// do it: never panics, always gives a [`BatchRun`] (`input` only labels it).
pub fn run_once(
    engine: &Engine,
    graph: &Path,
    settings: &[Setting],
    input: &Path,
    out_dir: &Path,
    threads: Option<usize>,
) -> BatchRun {
    let t = Instant::now();
    let result =
        GraphFile::load_with(graph, settings, engine.registry()).map_err(|e| (EXIT_INVALID, e)).and_then(|loaded| {
            execute(engine, &loaded, Some(out_dir), threads, None, false).map_err(|c| (c, "invalid graph".to_string()))
        });
    let (exit_code, nodes, files_written, error) = match result {
        Ok(report) => {
            let error = report.nodes.iter().find_map(|(id, n)| {
                n.error.as_ref().filter(|_| n.status == NodeStatus::Error).map(|e| format!("{id}: {e}"))
            });
            (exit_code(&report), report.nodes, report.files_written, error)
        }
        Err((code, error)) => (code, BTreeMap::new(), Vec::new(), Some(error)),
    };
    let error = error.or_else(|| (exit_code == EXIT_CANCELLED).then(|| "cancelled by a signal".to_string()));
    let status = match exit_code {
        0 => RunStatus::Ok,
        EXIT_CANCELLED => RunStatus::Cancelled,
        _ => RunStatus::Failed,
    };
    BatchRun {
        input: input.to_path_buf(),
        status,
        out_dir: absolute(out_dir),
        exit_code,
        seconds: t.elapsed().as_secs_f64(),
        nodes,
        files_written,
        error,
    }
}

/// `run_one` over every input, `jobs` inputs at a time (default: one per core), in input
/// order. Each worker is a thread of its own that takes the next input when it is done; the
/// inputs' nodes run on rayon's global pool, which they share. Inputs used to be rayon tasks
/// on the same pool as their nodes: a thread waiting on one input's nodes then took up
/// other inputs' work and the two threads of a two-job batch sat idle a third of the time.
fn run_inputs(
    inputs: &[PathBuf],
    names: &[String],
    jobs: Option<usize>,
    run_one: impl Fn((&PathBuf, &String)) -> BatchRun + Sync,
) -> Vec<BatchRun> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let workers = jobs.filter(|&j| j > 0).unwrap_or(cores).clamp(1, inputs.len().max(1));
    let next = AtomicUsize::new(0);
    let mut runs: Vec<(usize, BatchRun)> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let (Some(path), Some(name)) = (inputs.get(i), names.get(i)) else { break };
                        done.push((i, run_one((path, name))));
                    }
                    done
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic))).collect()
    });
    runs.sort_by_key(|(i, _)| *i);
    runs.into_iter().map(|(_, run)| run).collect()
}

pub(super) fn batch_command(
    graph: &Path,
    input: &Setting,
    out: &Path,
    jobs: Option<usize>,
    settings: &[Setting],
    json: bool,
    engine: Engine,
) -> u8 {
    let cancel = cancel_flag();
    // Validate the graph and the input name once, before any work.
    if let Err(e) = GraphFile::load_with(graph, settings, engine.registry())
        .and_then(|l| l.graph.resolve(&input.name).map(|_| ()).map_err(|e| format!("--input {}: {e}", input.name)))
    {
        errln!("{e}");
        return EXIT_INVALID;
    }
    let inputs = match expand_glob(input) {
        Ok(inputs) => inputs,
        Err(e) => {
            errln!("{e}");
            return EXIT_INVALID;
        }
    };
    let names = safe_unique_names(&run_folder_names(&inputs));
    let _lock = match OutLock::exclusive(out) {
        Ok(lock) => lock,
        Err(e) => {
            errln!("{e}");
            return EXIT_BUSY;
        }
    };
    let bar = (!json && std::io::stderr().is_terminal()).then(|| indicatif::ProgressBar::new(inputs.len() as u64));
    let started = Instant::now();
    remove_stale_temps(out, SystemTime::now());
    let run_one = |(path, name): (&PathBuf, &String)| -> BatchRun {
        if cancel.load(Ordering::Relaxed) {
            return BatchRun::refused(path, &out.join(name), EXIT_CANCELLED, "not run: the batch was cancelled".into());
        }
        let mut all = settings.to_vec();
        all.push(Setting { name: input.name.clone(), value: path.to_string_lossy().into_owned() });
        let run = match folder_within(out, Path::new(name)) {
            Ok(run_dir) => run_once(&engine, graph, &all, path, &run_dir, None),
            Err(e) => BatchRun::refused(path, &out.join(name), EXIT_FAILED, e),
        };
        if let Some(bar) = &bar {
            bar.inc(1);
        }
        run
    };
    let runs = run_inputs(&inputs, &names, jobs, run_one);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let count = |status: RunStatus| runs.iter().filter(|r| r.status == status).count();
    let (ok, failed, cancelled, not_run) =
        (count(RunStatus::Ok), count(RunStatus::Failed), count(RunStatus::Cancelled), count(RunStatus::NotRun));
    if cancel.load(Ordering::Relaxed) {
        remove_own_temps(out);
    }
    let report = serde_json::json!({
        "graph": graph,
        "input": input.name,
        "pattern": input.value,
        "ok": ok,
        "failed": failed,
        "cancelled": cancelled,
        "not_run": not_run,
        "seconds": started.elapsed().as_secs_f64(),
        "runs": runs,
    });
    let report_text = serde_json::to_string_pretty(&report).unwrap_or_default();
    if let Err(e) = save_within(out, Path::new(BATCH_REPORT), report_text.as_bytes()) {
        errln!("warning: could not save batch_report.json: {e}");
    }
    if json {
        outln!("{report_text}");
    } else {
        errln!("{:<9} {:>8}  {:<40} detail", "status", "seconds", "input");
        for r in &runs {
            let detail = r.error.clone().unwrap_or_else(|| format!("{} files", r.files_written.len()));
            errln!("{:<9} {:>8.3}  {:<40} {detail}", r.status.label(), r.seconds, r.input.display());
        }
        let stopped =
            if cancelled + not_run > 0 { format!(", {cancelled} cancelled, {not_run} not run") } else { String::new() };
        errln!(
            "{} runs: {ok} ok, {failed} failed{stopped}, {:.2} s; report in {}",
            runs.len(),
            started.elapsed().as_secs_f64(),
            out.join(BATCH_REPORT).display()
        );
    }
    if cancelled + not_run > 0 {
        EXIT_CANCELLED
    } else if failed > 0 {
        EXIT_FAILED
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;
    use std::sync::atomic::AtomicUsize;
    use std::time::Duration;

    use super::*;

    fn inputs(n: usize) -> (Vec<PathBuf>, Vec<String>) {
        ((0..n).map(|i| PathBuf::from(format!("in_{i}.bvh"))).collect(), (0..n).map(|i| format!("in_{i}")).collect())
    }

    /// Every input runs once, results come back in input order, and no more than `jobs`
    /// inputs are in flight at once.
    #[test]
    fn inputs_run_once_each_in_order_at_most_jobs_at_a_time() {
        let (paths, names) = inputs(25);
        for jobs in [Some(1), Some(3), None] {
            let (in_flight, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
            let calls = Mutex::new(Vec::new());
            let runs = run_inputs(&paths, &names, jobs, |(path, name)| {
                let now = in_flight.fetch_add(1, Ordering::SeqCst) + 1;
                most.fetch_max(now, Ordering::SeqCst);
                std::thread::sleep(Duration::from_millis(2));
                calls.lock().unwrap().push(name.clone());
                in_flight.fetch_sub(1, Ordering::SeqCst);
                BatchRun::refused(path, Path::new(name), EXIT_FAILED, name.clone())
            });
            let order: Vec<String> = runs.iter().map(|r| r.error.clone().unwrap_or_default()).collect();
            assert_eq!(order, names, "{jobs:?}");
            let mut called = calls.into_inner().unwrap();
            called.sort();
            let mut want = names.clone();
            want.sort();
            assert_eq!(called, want, "{jobs:?}: every input exactly once");
            let limit = jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
            assert!(most.load(Ordering::SeqCst) <= limit, "{jobs:?}: {} at once", most.load(Ordering::SeqCst));
        }
    }

    /// With two jobs, two inputs really run at the same time: each of the first two waits
    /// (up to 10 s) for the other to start.
    #[test]
    fn two_jobs_run_two_inputs_at_once() {
        let (paths, names) = inputs(2);
        let started = AtomicUsize::new(0);
        let met = AtomicUsize::new(0);
        run_inputs(&paths, &names, Some(2), |(path, name)| {
            started.fetch_add(1, Ordering::SeqCst);
            let deadline = Instant::now() + Duration::from_secs(10);
            while started.load(Ordering::SeqCst) < 2 && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(1));
            }
            if started.load(Ordering::SeqCst) == 2 {
                met.fetch_add(1, Ordering::SeqCst);
            }
            BatchRun::refused(path, Path::new(name), EXIT_FAILED, String::new())
        });
        assert_eq!(met.load(Ordering::SeqCst), 2);
    }
}
