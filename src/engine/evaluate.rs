//! Evaluation: a plan restricted to what the targets need, fingerprints for caching, and
//! a dependency-counting scheduler on rayon so independent branches run in parallel.
//!
//! Steps: 1. collect the targets' ancestors; 2. fingerprint each needed node from its
//! kind, parameters, input files' size and modification time, and its inputs'
//! fingerprints; 3. start every node whose inputs are ready; when one finishes, start
//! the dependents it completes; 4. a failure marks everything downstream blocked while
//! other branches go on.

use std::collections::{BTreeMap, HashMap};
use std::hash::{Hash, Hasher};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use kinegraph_nodes::node::{NodeContext, NodeError, NodeOutcome, Registry, RunServices, Value};

use super::compile::CompiledGraph;
use super::report::{NodeReport, NodeStatus, RunReport};

/// Something that happened during a run, for progress displays.
#[derive(Clone, Debug)]
pub enum RunEvent {
    /// The plan is made: this many nodes will be visited.
    Planned {
        /// Needed nodes.
        total: usize,
    },
    /// A node started.
    Started {
        /// Node id.
        node: String,
    },
    /// A node reported progress (0..=1).
    Progress {
        /// Node id.
        node: String,
        /// Fraction done.
        fraction: f32,
    },
    /// A node finished.
    Finished {
        /// Node id.
        node: String,
        /// How.
        status: NodeStatus,
    },
}

/// How to run a graph.
pub struct RunOptions<'a> {
    /// Folder relative input paths resolve against (the graph file's folder).
    pub base_dir: PathBuf,
    /// Where exports write; `None` makes exporting nodes fail.
    pub out_dir: Option<PathBuf>,
    /// Node ids whose results are wanted; `None` means every sink (node nobody reads).
    pub targets: Option<Vec<String>>,
    /// Set from another thread (Ctrl-C, the editor) to stop the run.
    pub cancel: Arc<AtomicBool>,
    /// Worker threads; `None` uses rayon's global pool.
    pub threads: Option<usize>,
    /// Receives progress events, from worker threads.
    pub observer: Option<&'a (dyn Fn(&RunEvent) + Sync)>,
}

impl RunOptions<'_> {
    /// Options with no output folder, every sink as target and no observer.
    pub fn new(base_dir: PathBuf) -> Self {
        RunOptions {
            base_dir,
            out_dir: None,
            targets: None,
            cancel: Arc::new(AtomicBool::new(false)),
            threads: None,
            observer: None,
        }
    }
}

/// Outputs and warnings of a node, as kept in the cache.
struct Cached {
    outputs: Vec<Option<Value>>,
    warnings: Vec<String>,
}

/// The evaluator: a node registry and a result cache that lives across runs, so a re-run
/// after one parameter change recomputes only what depends on it.
pub struct Engine {
    registry: Registry,
    cache: Mutex<HashMap<u64, Arc<Cached>>>,
}

/// A node's state inside one run.
enum Slot {
    Pending,
    Done { outputs: Vec<Option<Value>> },
    Failed,
}

struct RunState {
    remaining_inputs: Vec<usize>,
    slots: Vec<Slot>,
    reports: BTreeMap<String, NodeReport>,
    files: Vec<PathBuf>,
}

impl Engine {
    /// An engine over `registry` with an empty cache.
    pub fn new(registry: Registry) -> Self {
        Engine { registry, cache: Mutex::new(HashMap::new()) }
    }

    /// The node registry.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// Forgets every cached result.
    pub fn clear_cache(&self) {
        self.cache.lock().unwrap_or_else(PoisonError::into_inner).clear();
    }

    /// Runs `graph` (compiled against this engine's registry).
    pub fn run(&self, graph: &CompiledGraph<'_>, options: &RunOptions<'_>) -> RunReport {
        let started = Instant::now();
        let needed = needed_nodes(graph, options.targets.as_deref());
        let fingerprints = fingerprints(graph, &options.base_dir);
        if let Some(observe) = options.observer {
            observe(&RunEvent::Planned { total: needed.iter().filter(|n| **n).count() });
        }
        // Per node: how many distinct needed upstream nodes it still waits for.
        let remaining_inputs = graph
            .nodes
            .iter()
            .map(|n| {
                let mut sources: Vec<usize> =
                    n.inputs.iter().flatten().map(|(src, _)| *src).filter(|s| needed[*s]).collect();
                sources.sort_unstable();
                sources.dedup();
                sources.len()
            })
            .collect();
        let state = Mutex::new(RunState {
            remaining_inputs,
            slots: graph.nodes.iter().map(|_| Slot::Pending).collect(),
            reports: BTreeMap::new(),
            files: Vec::new(),
        });
        let services =
            RunServices { base_dir: &options.base_dir, out_dir: options.out_dir.as_deref(), cancel: &options.cancel };
        let ready: Vec<usize> = graph
            .order
            .iter()
            .copied()
            .filter(|&i| needed[i] && graph.nodes[i].inputs.iter().flatten().all(|(src, _)| !needed[*src]))
            .collect();
        let job = Job {
            engine: self,
            graph,
            needed: &needed,
            fingerprints: &fingerprints,
            state: &state,
            services: &services,
            options,
        };
        let schedule = || {
            rayon::scope(|scope| {
                for i in ready {
                    scope.spawn(move |s| job.run_node(s, i));
                }
            })
        };
        match options.threads.and_then(|n| rayon::ThreadPoolBuilder::new().num_threads(n).build().ok()) {
            Some(pool) => pool.install(schedule),
            None => schedule(),
        }
        let state = state.into_inner().unwrap_or_else(PoisonError::into_inner);
        let mut outputs = BTreeMap::new();
        for (node, slot) in graph.nodes.iter().zip(state.slots) {
            if let Slot::Done { outputs: o } = slot {
                outputs.insert(node.id.clone(), o);
            }
        }
        let mut files = state.files;
        files.sort();
        RunReport { nodes: state.reports, files_written: files, seconds: started.elapsed().as_secs_f64(), outputs }
    }
}

#[derive(Clone, Copy)]
struct Job<'a, 'g> {
    engine: &'a Engine,
    graph: &'a CompiledGraph<'g>,
    needed: &'a [bool],
    fingerprints: &'a [u64],
    state: &'a Mutex<RunState>,
    services: &'a RunServices<'a>,
    options: &'a RunOptions<'a>,
}

impl Job<'_, '_> {
    fn lock(&self) -> std::sync::MutexGuard<'_, RunState> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn observe(&self, event: RunEvent) {
        if let Some(observe) = self.options.observer {
            observe(&event);
        }
    }

    fn run_node<'s>(self, scope: &rayon::Scope<'s>, index: usize)
    where
        Self: 's,
    {
        let node = &self.graph.nodes[index];
        let schema = node.node.schema();
        // Gather inputs, or find the upstream failure that blocks this node.
        let mut inputs = Vec::with_capacity(node.inputs.len());
        let mut blocked_by = None;
        {
            let state = self.lock();
            for input in &node.inputs {
                match input {
                    None => inputs.push(None),
                    Some((src, out)) => match &state.slots[*src] {
                        Slot::Done { outputs } => inputs.push(outputs.get(*out).cloned().flatten()),
                        _ => {
                            blocked_by = Some(self.graph.nodes[*src].id.clone());
                            inputs.push(None);
                        }
                    },
                }
            }
        }
        let cancelled = self.services.cancel.load(Ordering::Relaxed);
        let fingerprint = self.fingerprints[index];
        let started = Instant::now();
        let (status, outcome, error) = if cancelled {
            (NodeStatus::Cancelled, None, Some("run cancelled".to_string()))
        } else if let Some(upstream) = blocked_by {
            (NodeStatus::Blocked, None, Some(format!("upstream node '{upstream}' did not produce a result")))
        } else if let Some(hit) = (!schema.writes_files).then(|| self.cached(fingerprint)).flatten() {
            let outcome =
                NodeOutcome { outputs: hit.outputs.clone(), warnings: hit.warnings.clone(), files_written: Vec::new() };
            (NodeStatus::Cached, Some(outcome), None)
        } else {
            self.observe(RunEvent::Started { node: node.id.clone() });
            let id = node.id.clone();
            let progress = move |fraction: f32| self.observe(RunEvent::Progress { node: id.clone(), fraction });
            let mut ctx = NodeContext::new(schema, inputs, &node.params, self.services, &progress);
            match node.node.eval(&mut ctx) {
                Ok(()) => {
                    let outcome = ctx.finish();
                    if !schema.writes_files {
                        let cached = Cached { outputs: outcome.outputs.clone(), warnings: outcome.warnings.clone() };
                        self.engine
                            .cache
                            .lock()
                            .unwrap_or_else(PoisonError::into_inner)
                            .insert(fingerprint, Arc::new(cached));
                    }
                    (NodeStatus::Ok, Some(outcome), None)
                }
                Err(NodeError::Cancelled) => (NodeStatus::Cancelled, None, Some("run cancelled".to_string())),
                Err(e) => (NodeStatus::Error, None, Some(e.to_string())),
            }
        };
        let seconds =
            if matches!(status, NodeStatus::Ok | NodeStatus::Error) { started.elapsed().as_secs_f64() } else { 0.0 };
        let mut ready = Vec::new();
        {
            let mut state = self.lock();
            let (slot, warnings) = match outcome {
                Some(o) => {
                    state.files.extend(o.files_written);
                    (Slot::Done { outputs: o.outputs }, o.warnings)
                }
                None => (Slot::Failed, Vec::new()),
            };
            state.slots[index] = slot;
            state.reports.insert(
                node.id.clone(),
                NodeReport { kind: schema.kind.to_string(), status, seconds, warnings, error },
            );
            for &d in &node.dependents {
                if self.needed[d] {
                    state.remaining_inputs[d] -= 1;
                    if state.remaining_inputs[d] == 0 {
                        ready.push(d);
                    }
                }
            }
        }
        self.observe(RunEvent::Finished { node: node.id.clone(), status });
        for d in ready {
            scope.spawn(move |s| self.run_node(s, d));
        }
    }

    fn cached(&self, fingerprint: u64) -> Option<Arc<Cached>> {
        self.engine.cache.lock().unwrap_or_else(PoisonError::into_inner).get(&fingerprint).cloned()
    }
}

/// Marks the targets and everything they read from.
fn needed_nodes(graph: &CompiledGraph<'_>, targets: Option<&[String]>) -> Vec<bool> {
    let mut needed = vec![false; graph.nodes.len()];
    let mut stack: Vec<usize> = match targets {
        Some(ids) => ids.iter().filter_map(|id| graph.index_of(id)).collect(),
        None => (0..graph.nodes.len()).filter(|&i| graph.nodes[i].dependents.is_empty()).collect(),
    };
    while let Some(i) = stack.pop() {
        if !std::mem::replace(&mut needed[i], true) {
            stack.extend(graph.nodes[i].inputs.iter().flatten().map(|(src, _)| *src));
        }
    }
    needed
}

/// Fingerprints in topological order: (kind, params, input files' size and mtime,
/// upstream fingerprints). Equal fingerprints mean equal results.
fn fingerprints(graph: &CompiledGraph<'_>, base_dir: &std::path::Path) -> Vec<u64> {
    let mut out = vec![0u64; graph.nodes.len()];
    for &i in &graph.order {
        let node = &graph.nodes[i];
        let schema = node.node.schema();
        let mut h = std::hash::DefaultHasher::new();
        schema.kind.hash(&mut h);
        for (name, value) in &node.params {
            name.hash(&mut h);
            format!("{value:?}").hash(&mut h);
        }
        // A file changed (or gone) since the last run is a new input.
        for path in node.input_files() {
            let meta = std::fs::metadata(base_dir.join(path)).ok();
            meta.as_ref().map(|m| m.len()).hash(&mut h);
            meta.and_then(|m| m.modified().ok()).hash(&mut h);
        }
        for input in &node.inputs {
            input.map(|(src, port)| (out[src], port)).hash(&mut h);
        }
        out[i] = h.finish();
    }
    out
}
