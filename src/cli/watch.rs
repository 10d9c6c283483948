//! `kg watch`: runs a graph, then again whenever the graph file, one of its subgraph files
//! or one of the files it reads changes. One engine lives across runs, so only what a change reaches is
//! recomputed (its cache keys on parameters and on input files' size and modification
//! time: a changed or deleted input is never served stale). Ctrl-C stops it.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{RecvTimeoutError, channel};
use std::time::{Duration, Instant};

use notify::{RecursiveMode, Watcher};

use super::run::{Setting, absolute, cancel_flag, execute_compiled, json_report, print_report};
use super::{EXIT_BUSY, EXIT_FAILED, EXIT_INVALID};
use crate::engine::{Engine, compile_file};
use crate::graph::GraphFile;
use crate::output::OutLock;

/// How long to let a burst of file events (an editor's write, rename, chmod) settle.
const SETTLE: Duration = Duration::from_millis(25);

pub(super) fn watch_command(
    graph: &Path,
    settings: &[Setting],
    out: &Path,
    json: bool,
    threads: Option<usize>,
    engine: Engine,
) -> u8 {
    let cancel = cancel_flag();
    let (tx, rx) = channel();
    let mut watcher = match notify::recommended_watcher(tx) {
        Ok(w) => w,
        Err(e) => {
            errln!("kg watch: cannot watch files here: {e}");
            return EXIT_FAILED;
        }
    };
    // Like `kg run`, a watch owns its output folder while it lives.
    let _lock = match OutLock::exclusive(out) {
        Ok(lock) => lock,
        Err(e) => {
            errln!("{e}");
            return EXIT_BUSY;
        }
    };
    let mut folders: BTreeSet<PathBuf> = BTreeSet::new();
    let out_dir = absolute(out);
    loop {
        let started = Instant::now();
        let files = run_once(&engine, graph, settings, out, json, threads);
        // Folders are watched, not files: editors save by writing a new file and renaming it.
        // A folder the graph reads (a clip set) is watched with everything under it.
        let read_folders: Vec<&PathBuf> = files.iter().filter(|f| f.is_dir()).collect();
        let watched = files.iter().filter_map(|f| f.parent()).map(|f| (f, RecursiveMode::NonRecursive));
        let recursive = read_folders.iter().map(|f| (f.as_path(), RecursiveMode::Recursive));
        for (folder, mode) in recursive.chain(watched) {
            if !folders.contains(folder) && folder.is_dir() {
                match watcher.watch(folder, mode) {
                    Ok(()) => {
                        folders.insert(folder.to_path_buf());
                    }
                    Err(e) => errln!("warning: {} will not be watched: {e}", folder.display()),
                }
            }
        }
        errln!(
            "kg watch: ran in {:.0} ms; watching {} file(s) — Ctrl-C stops",
            started.elapsed().as_secs_f64() * 1e3,
            files.len()
        );
        let changed = loop {
            if cancel.load(Ordering::Relaxed) {
                errln!("kg watch: stopped");
                return 0;
            }
            match rx.recv_timeout(Duration::from_millis(50)) {
                // Reading a file is not changing it: our own runs open the graph and its
                // inputs, and reacting to that would re-run forever.
                Ok(Ok(event)) if event.kind.is_access() => {}
                Ok(Ok(event)) => {
                    // Our own exports may land inside a folder the graph reads: not a change.
                    let read = |p: &PathBuf| {
                        let p = absolute(p);
                        files.contains(&p)
                            || (read_folders.iter().any(|f| p.starts_with(f)) && !p.starts_with(&out_dir))
                    };
                    if let Some(path) = event.paths.iter().find(|p| read(p)) {
                        break path.clone();
                    }
                }
                Ok(Err(e)) => errln!("warning: file watching: {e}"),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return EXIT_FAILED,
            }
        };
        std::thread::sleep(SETTLE);
        while rx.try_recv().is_ok() {}
        errln!("kg watch: {} changed", changed.display());
    }
}

/// Runs the graph once and prints its report; returns the files to watch: the graph and
/// every file it reads (all absolute). An invalid graph prints why and watches the graph.
fn run_once(
    engine: &Engine,
    graph: &Path,
    settings: &[Setting],
    out: &Path,
    json: bool,
    threads: Option<usize>,
) -> BTreeSet<PathBuf> {
    let mut files = BTreeSet::from([absolute(graph)]);
    let loaded = match GraphFile::load_with(graph, settings, engine.registry()) {
        Ok(l) => l,
        Err(e) => {
            errln!("{e}");
            return files;
        }
    };
    // Compiled once: the run and the list of files to watch come from the same graph.
    let compiled = match compile_file(&loaded, engine.registry()) {
        Ok(compiled) => compiled,
        Err(e) => {
            err!("{e}");
            if json {
                outln!("{}", serde_json::json!({ "graph": graph, "exit_code": EXIT_INVALID, "ok": false }));
            }
            return files;
        }
    };
    let base = loaded.base_dir();
    files.extend(compiled.input_files().map(|f| absolute(&base.join(f))));
    files.extend(compiled.includes.iter().cloned());
    match execute_compiled(engine, &loaded, &compiled, Some(out), threads, None, false) {
        Ok(report) => {
            let code = if report.succeeded() { 0 } else { EXIT_FAILED };
            if json {
                outln!("{}", json_report(graph, &report, code));
            } else {
                print_report(graph, &report);
            }
        }
        Err(code) if json => outln!("{}", serde_json::json!({ "graph": graph, "exit_code": code, "ok": false })),
        Err(_) => {}
    }
    files
}
