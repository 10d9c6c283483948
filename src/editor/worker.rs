//! The editor's evaluation worker: one thread owning an [`Engine`], so its cache lives
//! across edits and a parameter change recomputes only what depends on it.
//!
//! Steps per request: 1. the UI submits a snapshot of the document with a new request id,
//! which cancels the run in flight; 2. the thread skips every queued request but the
//! newest; 3. it validates, leaving out the nodes a problem names and everything downstream
//! of them (a dangling node half-wired stops only what depends on it), then runs every node
//! left that writes no file (exports run only from `kg run`); 4. progress events and the
//! final outcome go back tagged with the request id, and [`Worker::poll`] drops whatever
//! belongs to an older request. The UI never waits.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use kinegraph_nodes::node::Registry;

use crate::engine::{
    CompiledGraph, Engine, GraphErrors, NodeStatus, RunEvent, RunOptions, RunReport, Unsaved, compile_file_with,
};
use crate::graph::{Graph, GraphFile, NodeId};

/// Called from the worker thread whenever it has news (the editor asks for a repaint).
pub type Waker = Arc<dyn Fn() + Send + Sync>;

/// What the worker says about one request.
#[derive(Debug)]
pub enum WorkerMessage {
    /// A node started.
    Started {
        /// Node id.
        node: String,
    },
    /// A node finished.
    Finished {
        /// Node id.
        node: String,
        /// How it ended.
        status: NodeStatus,
    },
    /// The graph did not validate and no part of it could run (a problem names no node,
    /// or every node is invalid or downstream of one).
    Invalid(GraphErrors),
    /// The run of the valid part ended (possibly cancelled).
    Done {
        /// What ran.
        report: RunReport,
        /// The problems of the nodes left out, if any were.
        problems: Option<GraphErrors>,
        /// Nodes left out: named by a problem, or downstream of one.
        left_out: BTreeSet<String>,
    },
}

impl WorkerMessage {
    /// True for the message that ends a request.
    fn is_last(&self) -> bool {
        matches!(self, WorkerMessage::Done { .. } | WorkerMessage::Invalid(_))
    }
}

/// The part of a graph that validates, compiled, with what was left out to get there.
struct Runnable<'r> {
    compiled: CompiledGraph<'r>,
    problems: Option<GraphErrors>,
    left_out: BTreeSet<String>,
}

/// Compiles `graph`; while it does not validate, the nodes its problems name are left out
/// with everything downstream of them and the rest is tried again. `Err` holds every problem
/// found when nothing can run.
fn runnable<'r>(
    graph: &Graph,
    path: &Path,
    registry: &'r Registry,
    unsaved: &Unsaved,
) -> Result<Runnable<'r>, GraphErrors> {
    let mut graph = graph.clone();
    let mut problems: Option<GraphErrors> = None;
    let mut left_out = BTreeSet::new();
    loop {
        let errors = match compile_file_with(&GraphFile::in_memory(graph.clone(), path), registry, unsaved) {
            Ok(compiled) => return Ok(Runnable { compiled, problems, left_out }),
            Err(errors) => errors,
        };
        // A problem inside a subgraph names its node as `outer/inner`.
        let named: Option<BTreeSet<NodeId>> = errors
            .diagnostics
            .iter()
            .map(|d| {
                let node = d.node.as_deref()?;
                [node, node.split('/').next().unwrap_or(node)].into_iter().find(|n| graph.contains(n)).map(NodeId::from)
            })
            .collect();
        let all = match problems.take() {
            Some(mut all) => {
                all.diagnostics.extend(errors.diagnostics);
                all
            }
            None => errors,
        };
        let Some(named) = named else { return Err(all) };
        let out: Vec<NodeId> = graph.downstream_of(&named).into_iter().collect();
        if out.is_empty() || out.len() == graph.nodes().len() || graph.remove_nodes(&out).is_err() {
            return Err(all);
        }
        left_out.extend(out.iter().map(ToString::to_string));
        problems = Some(all);
    }
}

/// One evaluation request.
struct Job {
    request: u64,
    graph: Graph,
    base_dir: PathBuf,
    unsaved: Unsaved,
    cancel: Arc<AtomicBool>,
}

/// Handle to the evaluation thread.
pub struct Worker {
    jobs: Option<Sender<Job>>,
    messages: Receiver<(u64, WorkerMessage)>,
    latest: u64,
    finished: u64,
    cancel: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts the thread evaluating with `engine`; `wake` is called on every message.
    pub fn spawn(engine: Engine, wake: Waker) -> Worker {
        let (jobs, job_rx) = channel::<Job>();
        let (msg_tx, messages) = channel();
        let thread = std::thread::Builder::new()
            .name("kg-evaluate".into())
            .spawn(move || worker_loop(engine, &job_rx, &msg_tx, &wake))
            .ok();
        Worker { jobs: Some(jobs), messages, latest: 0, finished: 0, cancel: Arc::new(AtomicBool::new(false)), thread }
    }

    /// Asks for an evaluation of `graph` (relative paths resolve against `base_dir`),
    /// cancelling the one in flight. Returns the new request id.
    pub fn submit(&mut self, graph: Graph, base_dir: PathBuf) -> u64 {
        self.submit_with(graph, base_dir, Unsaved::new())
    }

    /// [`Worker::submit`], with subgraph files read from `unsaved` where it has them.
    pub fn submit_with(&mut self, graph: Graph, base_dir: PathBuf, unsaved: Unsaved) -> u64 {
        self.cancel.store(true, Ordering::Relaxed);
        self.cancel = Arc::new(AtomicBool::new(false));
        self.latest += 1;
        let job = Job { request: self.latest, graph, base_dir, unsaved, cancel: self.cancel.clone() };
        if let Some(jobs) = &self.jobs {
            // A closed channel means the thread is gone; `running` then stays true and the
            // editor shows the graph as not evaluated, which is the honest state.
            let _ = jobs.send(job);
        }
        self.latest
    }

    /// The id of the newest request.
    pub fn latest_request(&self) -> u64 {
        self.latest
    }

    /// True while the newest request has not finished.
    pub fn running(&self) -> bool {
        self.finished < self.latest
    }

    /// The next message of the newest request, dropping stale ones. Never blocks.
    pub fn poll(&mut self) -> Option<WorkerMessage> {
        while let Ok((request, message)) = self.messages.try_recv() {
            if request != self.latest {
                continue;
            }
            if message.is_last() {
                self.finished = request;
            }
            return Some(message);
        }
        None
    }

    /// Blocks until the newest request has finished and returns its last message
    /// (for tests and headless use).
    pub fn wait(&mut self) -> Option<WorkerMessage> {
        while self.running() {
            match self.messages.recv() {
                Ok((request, message)) if request == self.latest => {
                    if message.is_last() {
                        self.finished = request;
                        return Some(message);
                    }
                }
                Ok(_) => {}
                Err(_) => return None,
            }
        }
        None
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

fn worker_loop(engine: Engine, jobs: &Receiver<Job>, messages: &Sender<(u64, WorkerMessage)>, wake: &Waker) {
    while let Ok(mut job) = jobs.recv() {
        while let Ok(newer) = jobs.try_recv() {
            job = newer;
        }
        let send = |message: WorkerMessage| {
            let _ = messages.send((job.request, message));
            wake();
        };
        // Relative paths (subgraph files among them) resolve against the graph's folder.
        let Runnable { compiled, problems, left_out } =
            match runnable(&job.graph, &job.base_dir.join("(editor)"), engine.registry(), &job.unsaved) {
                Ok(runnable) => runnable,
                Err(errors) => {
                    send(WorkerMessage::Invalid(errors));
                    continue;
                }
            };
        let targets: Vec<String> =
            compiled.nodes.iter().filter(|n| !n.node.schema().writes_files).map(|n| n.id.clone()).collect();
        let observer = |event: &RunEvent| match event {
            RunEvent::Started { node } => send(WorkerMessage::Started { node: node.clone() }),
            RunEvent::Finished { node, status } => {
                send(WorkerMessage::Finished { node: node.clone(), status: *status });
            }
            RunEvent::Planned { .. } | RunEvent::Progress { .. } => {}
        };
        let mut options = RunOptions::new(job.base_dir.clone());
        options.targets = Some(targets);
        options.cancel = job.cancel.clone();
        options.observer = Some(&observer);
        let report = engine.run(&compiled, &options);
        send(WorkerMessage::Done { report, problems, left_out });
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::graph::{GraphFile, ParamPath, PortRef};

    fn demo() -> (Graph, PathBuf) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        let loaded = GraphFile::load(&path).unwrap();
        let base = loaded.base_dir();
        (loaded.graph, base)
    }

    #[test]
    fn runs_the_demo_without_exports_then_reuses_the_cache() {
        let (mut doc, base) = demo();
        let mut worker = Worker::spawn(Engine::new(kinegraph_nodes::builtin::registry()), Arc::new(|| {}));
        worker.submit(doc.clone(), base.clone());
        let Some(WorkerMessage::Done { report, .. }) = worker.wait() else { panic!("no report") };
        assert!(report.succeeded(), "{report:?}");
        assert!(!report.nodes.contains_key("glb") && !report.nodes.contains_key("bvh"));
        assert_eq!(report.nodes["resample"].status, NodeStatus::Ok);

        let fps = ParamPath::parse("resample.fps").unwrap();
        doc.set_param(&kinegraph_nodes::builtin::registry(), &fps, &kinegraph_nodes::node::ParamValue::Float(12.0))
            .unwrap();
        worker.submit(doc, base);
        let Some(WorkerMessage::Done { report, .. }) = worker.wait() else { panic!("no report") };
        assert_eq!(report.nodes["trim"].status, NodeStatus::Cached);
        assert_eq!(report.nodes["resample"].status, NodeStatus::Ok);
    }

    #[test]
    fn a_dangling_node_stops_only_what_depends_on_it() {
        let (mut doc, base) = demo();
        let registry = kinegraph_nodes::builtin::registry();
        // A trim with nothing on its required input, feeding a resample: both are left out.
        doc.add_node(&registry, NodeId::from("dangling"), "clip.trim", (0.0, 0.0)).unwrap();
        doc.add_node(&registry, NodeId::from("after"), "clip.resample", (0.0, 0.0)).unwrap();
        doc.connect(&registry, &PortRef::parse("dangling.clip").unwrap(), &PortRef::parse("after.clip").unwrap())
            .unwrap();
        let mut worker = Worker::spawn(Engine::new(registry), Arc::new(|| {}));
        worker.submit(doc, base);
        let Some(WorkerMessage::Done { report, problems, left_out }) = worker.wait() else { panic!("no report") };
        for id in ["clip", "trim", "resample", "mesh"] {
            assert_eq!(report.nodes[id].status, NodeStatus::Ok, "{id}");
        }
        assert_eq!(left_out, BTreeSet::from(["after".to_string(), "dangling".to_string()]));
        assert!(!report.nodes.contains_key("dangling") && !report.nodes.contains_key("after"));
        let problems = problems.unwrap();
        assert!(
            problems
                .diagnostics
                .iter()
                .any(|d| d.node.as_deref() == Some("dangling") && d.item.as_deref() == Some("clip")),
            "{problems}"
        );
    }

    #[test]
    fn stale_requests_are_dropped() {
        let (doc, base) = demo();
        let mut worker = Worker::spawn(Engine::new(kinegraph_nodes::builtin::registry()), Arc::new(|| {}));
        let first = worker.submit(doc.clone(), base.clone());
        let mut broken = doc;
        broken.disconnect(&PortRef::parse("clip.clip").unwrap(), &PortRef::parse("trim.clip").unwrap()).unwrap();
        let second = worker.submit(broken, base);
        assert!(second > first);
        // Whatever the first request produced is never seen: only the second one, which ran
        // what does not depend on the cut wire.
        match worker.wait() {
            Some(WorkerMessage::Done { problems: Some(errors), left_out, .. }) => {
                assert!(errors.diagnostics.iter().any(|d| d.node.as_deref() == Some("trim")), "{errors}");
                assert!(left_out.contains("trim") && left_out.contains("resample") && !left_out.contains("clip"));
            }
            _ => panic!("expected the second request's run with its validation errors"),
        }
        assert!(!worker.running());
        assert!(worker.poll().is_none());
    }
}
