//! `kg run`, `kg check` and `kg convert`, and the loading steps every command shares.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use kinegraph_nodes::node::{ParamValue, Registry};

use super::{EXIT_BUSY, EXIT_CANCELLED, EXIT_FAILED, EXIT_INVALID};
use crate::document;
use crate::engine::{CompiledGraph, Engine, NodeStatus, RunEvent, RunOptions, RunReport, compile_file};
pub use crate::graph::Setting;
use crate::graph::{Graph, GraphFile, LoadError, NodeId, Overrides, ParamPath, PortRef};
use crate::output::{OutLock, remove_own_temps, remove_stale_temps};

/// `path` made absolute against the current directory.
pub fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// The cancellation flag that Ctrl-C (SIGINT), SIGTERM and SIGHUP set (the handler is
/// installed once per process, on the first call). Evaluation stops at the next node
/// boundary or cancellation check, and the commands then report what ran.
pub fn cancel_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let handler_flag = flag.clone();
        if let Err(e) = ctrlc::set_handler(move || handler_flag.store(true, Ordering::Relaxed)) {
            errln!("warning: Ctrl-C and SIGTERM will not cancel cleanly: {e}");
        }
        flag
    })
    .clone()
}

/// Loads, validates and runs a graph; returns the report or the exit code for an invalid
/// graph (after printing why).
pub fn execute(
    engine: &Engine,
    loaded: &GraphFile,
    out: Option<&Path>,
    threads: Option<usize>,
    targets: Option<Vec<String>>,
    progress: bool,
) -> Result<RunReport, u8> {
    let compiled = compile_file(loaded, engine.registry()).map_err(|e| {
        err!("{e}");
        EXIT_INVALID
    })?;
    execute_compiled(engine, loaded, &compiled, out, threads, targets, progress)
}

/// [`execute`] for a graph compiled already (`kg watch` also reads its file list from it).
pub fn execute_compiled(
    engine: &Engine,
    loaded: &GraphFile,
    compiled: &CompiledGraph<'_>,
    out: Option<&Path>,
    threads: Option<usize>,
    targets: Option<Vec<String>>,
    progress: bool,
) -> Result<RunReport, u8> {
    if let Some(targets) = &targets {
        let unknown: Vec<&String> = targets.iter().filter(|t| compiled.index_of(t).is_none()).collect();
        if !unknown.is_empty() {
            errln!("{}: --target names unknown nodes: {unknown:?}", loaded.path.display());
            return Err(EXIT_INVALID);
        }
    }
    if let Some(out) = out
        && let Err(e) = std::fs::create_dir_all(out)
    {
        errln!("{}: cannot create the output folder: {e}", out.display());
        return Err(EXIT_INVALID);
    }
    let bar = (progress && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} nodes {msg}")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let observer = |event: &RunEvent| {
        if let Some(bar) = &bar {
            match event {
                RunEvent::Planned { total } => bar.set_length(*total as u64),
                RunEvent::Started { node } => bar.set_message(node.clone()),
                RunEvent::Finished { .. } => bar.inc(1),
                RunEvent::Progress { .. } => bar.tick(),
            }
        }
    };
    let options = RunOptions {
        base_dir: loaded.base_dir(),
        out_dir: out.map(absolute),
        targets,
        cancel: cancel_flag(),
        threads,
        observer: Some(&observer),
    };
    let report = engine.run(compiled, &options);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    Ok(report)
}

/// Prints a human-readable report on stderr.
pub fn print_report(graph: &Path, report: &RunReport) {
    for (id, node) in &report.nodes {
        let status = match node.status {
            NodeStatus::Ok => "ok",
            NodeStatus::Cached => "cached",
            NodeStatus::Error => "ERROR",
            NodeStatus::Blocked => "blocked",
            NodeStatus::Cancelled => "cancelled",
            NodeStatus::Bypassed => "bypassed",
        };
        errln!("  {status:<9} {id} ({}) {:.3} s", node.kind, node.seconds);
        for w in &node.warnings {
            errln!("            warning: {w}");
        }
        if let Some(e) = &node.error {
            errln!("            {e}");
        }
    }
    for f in &report.files_written {
        errln!("  wrote {}", f.display());
    }
    let failed =
        report.count(NodeStatus::Error) + report.count(NodeStatus::Blocked) + report.count(NodeStatus::Cancelled);
    errln!("{}: {} nodes, {} failed or blocked, {:.3} s", graph.display(), report.nodes.len(), failed, report.seconds);
}

/// The `--json` report object; `status` is `ok`, `failed` or `cancelled`.
pub fn json_report(graph: &Path, report: &RunReport, exit_code: u8) -> serde_json::Value {
    let status = match exit_code {
        0 => "ok",
        EXIT_CANCELLED => "cancelled",
        _ => "failed",
    };
    serde_json::json!({
        "graph": graph,
        "status": status,
        "exit_code": exit_code,
        "ok": report.succeeded(),
        "seconds": report.seconds,
        "nodes": report.nodes,
        "files_written": report.files_written,
        "reports": report.reports(),
    })
}

/// The exit code of a run: 0, [`EXIT_FAILED`], or [`EXIT_CANCELLED`] when a signal stopped
/// it before every node ran.
pub fn exit_code(report: &RunReport) -> u8 {
    if report.succeeded() {
        0
    } else if report.count(NodeStatus::Cancelled) > 0 {
        EXIT_CANCELLED
    } else {
        EXIT_FAILED
    }
}

pub(super) fn run_command(
    graph: &Path,
    settings: &[Setting],
    out: &Path,
    json: bool,
    threads: Option<usize>,
    targets: Vec<String>,
    engine: Engine,
) -> u8 {
    let cancel = cancel_flag();
    let loaded = match GraphFile::load_with(graph, settings, engine.registry()) {
        Ok(l) => l,
        Err(e) => {
            errln!("{e}");
            return EXIT_INVALID;
        }
    };
    let targets = (!targets.is_empty()).then_some(targets);
    let started = std::time::SystemTime::now();
    let _lock = match OutLock::exclusive(out) {
        Ok(lock) => lock,
        Err(e) => {
            errln!("{e}");
            return EXIT_BUSY;
        }
    };
    remove_stale_temps(out, started);
    let report = match execute(&engine, &loaded, Some(out), threads, targets, !json) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let code = exit_code(&report);
    if cancel.load(Ordering::Relaxed) {
        remove_own_temps(out);
    }
    if json {
        outln!("{}", json_report(graph, &report, code));
    } else {
        print_report(graph, &report);
    }
    code
}

pub(super) fn check_command(graphs: &[PathBuf], json: bool) -> u8 {
    let registry = kinegraph_nodes::builtin::registry();
    let mut worst = 0;
    let mut results = Vec::new();
    for path in graphs {
        // Problems inside a subgraph name the subgraph's file.
        let located = |e: crate::graph::GraphErrors| -> Vec<String> {
            e.diagnostics.iter().map(|d| format!("{}:{d}", e.path.display())).collect()
        };
        let outcome = match GraphFile::load(path) {
            Err(LoadError::Document(e)) => Err(vec![e.to_string()]),
            Err(LoadError::Structure(e)) => Err(located(e)),
            Ok(loaded) => compile_file(&loaded, &registry).map(|_| ()).map_err(located),
        };
        match &outcome {
            Ok(()) => {
                if !json {
                    errln!("{}: ok", path.display());
                }
            }
            Err(problems) => {
                worst = EXIT_INVALID;
                if !json {
                    for p in problems {
                        errln!("{p}");
                    }
                }
            }
        }
        results.push(
            serde_json::json!({ "graph": path, "ok": outcome.is_ok(), "problems": outcome.err().unwrap_or_default() }),
        );
    }
    if json {
        outln!("{}", serde_json::Value::Array(results));
    }
    worst
}

/// The built-in load → export graph `kg convert` runs.
pub fn convert_graph(input: &Path, output: &Path, registry: &Registry) -> Result<Graph, String> {
    let ext = kinegraph_nodes::formats::extension(output);
    let export = match ext.as_str() {
        "bvh" => "export.bvh",
        "glb" => "export.glb",
        _ => return Err(format!("{}: the output must end in .bvh or .glb", output.display())),
    };
    let file_name = output.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let (load, save) = (NodeId::from("load"), NodeId::from("export"));
    let mut graph = Graph::new();
    graph.set_description("kg convert");
    let build = |graph: &mut Graph| -> Result<(), crate::graph::GraphError> {
        graph.add_node(registry, load.clone(), "clip.load", (0.0, 0.0))?;
        graph.add_node(registry, save.clone(), export, (240.0, 0.0))?;
        let input = ParamValue::Text(absolute(input).to_string_lossy().into_owned());
        graph.set_param(registry, &ParamPath::new(load.clone(), "path"), &input)?;
        graph.set_param(registry, &ParamPath::new(save.clone(), "file"), &ParamValue::Text(file_name))?;
        graph.connect(registry, &PortRef::new(load.clone(), "clip"), &PortRef::new(save.clone(), "clip"))?;
        Ok(())
    };
    build(&mut graph).map_err(|e| format!("{}: {e}", output.display()))?;
    Ok(graph)
}

pub(super) fn convert_command(input: &Path, output: &Path, settings: &[Setting]) -> u8 {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let mut graph = match convert_graph(input, output, engine.registry()) {
        Ok(g) => g,
        Err(e) => {
            errln!("{e}");
            return EXIT_INVALID;
        }
    };
    let prefixed: Vec<Setting> =
        settings.iter().map(|s| Setting { name: format!("load.{}", s.name), value: s.value.clone() }).collect();
    if let Err(e) = Overrides(prefixed).apply(&mut graph, engine.registry()) {
        errln!("--set {e}");
        return EXIT_INVALID;
    }
    let out_dir = output.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let loaded = GraphFile::in_memory(graph, Path::new("<kg convert>"));
    let report = match execute(&engine, &loaded, Some(out_dir), None, None, true) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let code = exit_code(&report);
    print_report(&loaded.path, &report);
    code
}

pub(super) fn fmt_command(graphs: &[PathBuf], check: bool) -> u8 {
    let mut code = 0;
    for path in graphs {
        let loaded = match document::load_file(path) {
            Ok(l) => l,
            Err(e) => {
                errln!("{e}");
                code = EXIT_INVALID;
                continue;
            }
        };
        let canonical = document::to_string(&loaded.doc);
        let current = std::fs::read_to_string(path).unwrap_or_default();
        if canonical == current {
            continue;
        }
        if check {
            errln!("{}: not in canonical form (run kg fmt)", path.display());
            code = code.max(EXIT_FAILED);
        } else if loaded.source.has_comments() {
            errln!(
                "{}: not rewritten: it has comments, which the canonical form cannot keep (remove them to format it)",
                path.display()
            );
            code = code.max(EXIT_FAILED);
        } else if let Err(e) = document::save_file(&loaded.doc, path) {
            errln!("{e}");
            code = EXIT_INVALID;
        } else {
            errln!(
                "{}: rewritten{}",
                path.display(),
                if loaded.file_version < document::written_version(&loaded.doc) { " (migrated)" } else { "" }
            );
        }
    }
    code
}
