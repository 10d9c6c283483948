//! The editor's evaluation worker: one thread owning an [`Engine`], so its cache lives
//! across edits and a parameter change recomputes only what depends on it.
//!
//! Steps per request: 1. the UI submits a snapshot of the document with a new request id,
//! which cancels the run in flight; 2. the thread skips every queued request but the
//! newest; 3. it validates, then runs every node that writes no file (exports run only from
//! `kg run`); 4. progress events and the final outcome go back tagged with the request id,
//! and [`Worker::poll`] drops whatever belongs to an older request. The UI never waits.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

use crate::engine::{Engine, GraphErrors, NodeStatus, RunEvent, RunOptions, RunReport, compile_file};
use crate::graph::{Graph, GraphFile};

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
    /// The graph did not validate: nothing ran.
    Invalid(GraphErrors),
    /// The run ended (possibly cancelled).
    Done(RunReport),
}

/// One evaluation request.
struct Job {
    request: u64,
    graph: Graph,
    base_dir: PathBuf,
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
        self.cancel.store(true, Ordering::Relaxed);
        self.cancel = Arc::new(AtomicBool::new(false));
        self.latest += 1;
        let job = Job { request: self.latest, graph, base_dir, cancel: self.cancel.clone() };
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
            if matches!(message, WorkerMessage::Done(_) | WorkerMessage::Invalid(_)) {
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
                    if matches!(message, WorkerMessage::Done(_) | WorkerMessage::Invalid(_)) {
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
        let file = GraphFile::in_memory(job.graph.clone(), &job.base_dir.join("(editor)"));
        let compiled = match compile_file(&file, engine.registry()) {
            Ok(compiled) => compiled,
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
        send(WorkerMessage::Done(report));
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
        let Some(WorkerMessage::Done(report)) = worker.wait() else { panic!("no report") };
        assert!(report.succeeded(), "{report:?}");
        assert!(!report.nodes.contains_key("glb") && !report.nodes.contains_key("bvh"));
        assert_eq!(report.nodes["resample"].status, NodeStatus::Ok);

        let fps = ParamPath::parse("resample.fps").unwrap();
        doc.set_param(&kinegraph_nodes::builtin::registry(), &fps, &kinegraph_nodes::node::ParamValue::Float(12.0))
            .unwrap();
        worker.submit(doc, base);
        let Some(WorkerMessage::Done(report)) = worker.wait() else { panic!("no report") };
        assert_eq!(report.nodes["trim"].status, NodeStatus::Cached);
        assert_eq!(report.nodes["resample"].status, NodeStatus::Ok);
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
        // Whatever the first request produced is never seen: only the invalid second one.
        match worker.wait() {
            Some(WorkerMessage::Invalid(errors)) => assert!(!errors.diagnostics.is_empty()),
            other => panic!("expected the second request's validation errors, got {other:?}"),
        }
        assert!(!worker.running());
        assert!(worker.poll().is_none());
    }
}
