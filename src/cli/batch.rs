//! `kg batch`: one run of a graph per input file, in parallel, continuing past failures,
//! with a summary table and a JSON report (also saved as `batch_report.json` in --out).

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use super::run::{Setting, absolute, execute, load_graph};
use super::{EXIT_FAILED, EXIT_INVALID};
use crate::engine::{Engine, NodeReport, NodeStatus};

/// One input file's run.
#[derive(Debug, Serialize)]
pub struct BatchRun {
    /// The input file.
    pub input: PathBuf,
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

/// The files a `NAME=GLOB` binding matches, sorted; an error naming the glob when it is
/// malformed or matches no file.
pub fn expand_glob(input: &Setting) -> Result<Vec<PathBuf>, String> {
    let mut inputs: Vec<PathBuf> = match glob::glob(&input.value) {
        Ok(paths) => paths.filter_map(Result::ok).filter(|p| p.is_file()).collect(),
        Err(e) => return Err(format!("--input {}: bad glob: {e}", input.value)),
    };
    inputs.sort();
    if inputs.is_empty() {
        return Err(format!("--input {}: no files match", input.value));
    }
    Ok(inputs)
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
    let result = load_graph(graph, settings, engine.registry()).map_err(|e| (EXIT_INVALID, e)).and_then(|loaded| {
        execute(engine, &loaded, Some(out_dir), threads, None, false).map_err(|c| (c, "invalid graph".to_string()))
    });
    let (exit_code, nodes, files_written, error) = match result {
        Ok(report) => {
            let error = report.nodes.iter().find_map(|(id, n)| {
                n.error.as_ref().filter(|_| n.status == NodeStatus::Error).map(|e| format!("{id}: {e}"))
            });
            (if report.succeeded() { 0 } else { EXIT_FAILED }, report.nodes, report.files_written, error)
        }
        Err((code, error)) => (code, BTreeMap::new(), Vec::new(), Some(error)),
    };
    BatchRun {
        input: input.to_path_buf(),
        out_dir: absolute(out_dir),
        exit_code,
        seconds: t.elapsed().as_secs_f64(),
        nodes,
        files_written,
        error,
    }
}

/// Output subfolder names: the file stem, disambiguated by parent folders when two inputs
/// share a stem (e.g. `cmu/02_02.bvh` and `cmu_daz/02_02.bvh`).
pub fn run_folder_names(inputs: &[PathBuf]) -> Vec<String> {
    let name_at = |p: &Path, depth: usize| -> String {
        let mut parts: Vec<String> =
            p.components().rev().take(depth + 1).map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
        parts.reverse();
        if let Some(last) = parts.last_mut() {
            *last = Path::new(last.as_str()).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        }
        parts.join("-")
    };
    let mut names: Vec<String> = inputs.iter().map(|p| name_at(p, 0)).collect();
    for depth in 1..4 {
        let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
        for n in &names {
            *counts.entry(n.as_str()).or_default() += 1;
        }
        let clashing: Vec<bool> = names.iter().map(|n| counts[n.as_str()] > 1).collect();
        if !clashing.contains(&true) {
            break;
        }
        for (i, clash) in clashing.into_iter().enumerate() {
            if clash {
                names[i] = name_at(&inputs[i], depth);
            }
        }
    }
    names
}

pub(super) fn batch_command(
    graph: &Path,
    input: &Setting,
    out: &Path,
    jobs: Option<usize>,
    settings: &[Setting],
    json: bool,
) -> u8 {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    // Validate the graph and the input name once, before any work.
    if let Err(e) = load_graph(graph, settings, engine.registry())
        .and_then(|l| l.graph.resolve(&input.name).map(|_| ()).map_err(|e| format!("--input {}: {e}", input.name)))
    {
        eprintln!("{e}");
        return EXIT_INVALID;
    }
    let inputs = match expand_glob(input) {
        Ok(inputs) => inputs,
        Err(e) => {
            eprintln!("{e}");
            return EXIT_INVALID;
        }
    };
    let names = run_folder_names(&inputs);
    let bar = (!json && std::io::stderr().is_terminal()).then(|| indicatif::ProgressBar::new(inputs.len() as u64));
    let started = Instant::now();
    let run_one = |(path, name): (&PathBuf, &String)| -> BatchRun {
        let mut all = settings.to_vec();
        all.push(Setting { name: input.name.clone(), value: path.to_string_lossy().into_owned() });
        let run = run_once(&engine, graph, &all, path, &out.join(name), None);
        if let Some(bar) = &bar {
            bar.inc(1);
        }
        run
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(jobs.unwrap_or(0)).build();
    let runs: Vec<BatchRun> = match pool {
        Ok(pool) => pool.install(|| inputs.par_iter().zip(&names).map(run_one).collect()),
        Err(_) => inputs.iter().zip(&names).map(run_one).collect(),
    };
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let failed = runs.iter().filter(|r| r.exit_code != 0).count();
    let report = serde_json::json!({
        "graph": graph,
        "input": input.name,
        "pattern": input.value,
        "ok": runs.len() - failed,
        "failed": failed,
        "seconds": started.elapsed().as_secs_f64(),
        "runs": runs,
    });
    let report_text = serde_json::to_string_pretty(&report).unwrap_or_default();
    if let Err(e) = std::fs::create_dir_all(out).map_err(|e| e.to_string()).and_then(|()| {
        kinegraph_nodes::formats::atomic::write_atomic(&out.join("batch_report.json"), report_text.as_bytes())
            .map_err(|e| e.to_string())
    }) {
        eprintln!("warning: could not save batch_report.json: {e}");
    }
    if json {
        println!("{report_text}");
    } else {
        eprintln!("{:<8} {:>8}  {:<40} detail", "status", "seconds", "input");
        for r in &runs {
            let status = if r.exit_code == 0 { "ok" } else { "FAILED" };
            let detail = r.error.clone().unwrap_or_else(|| format!("{} files", r.files_written.len()));
            eprintln!("{status:<8} {:>8.3}  {:<40} {detail}", r.seconds, r.input.display());
        }
        eprintln!(
            "{} runs: {} ok, {failed} failed, {:.2} s; report in {}",
            runs.len(),
            runs.len() - failed,
            started.elapsed().as_secs_f64(),
            out.join("batch_report.json").display()
        );
    }
    if failed > 0 { EXIT_FAILED } else { 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folder_names_disambiguate_shared_stems() {
        let inputs: Vec<PathBuf> =
            ["d/cmu/02_02.bvh", "d/cmu_daz/02_02.bvh", "d/cmu/01_01.bvh"].iter().map(PathBuf::from).collect();
        assert_eq!(run_folder_names(&inputs), vec!["cmu-02_02", "cmu_daz-02_02", "01_01"]);
    }
}
