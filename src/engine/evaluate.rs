//! Evaluation: fingerprints for caching, a plan restricted to what the targets need, and
//! a dependency-counting scheduler on rayon so independent branches run in parallel.
//!
//! Steps: 1. fingerprint every node from its kind and version, parameters, the files it
//! reads and its inputs' fingerprints ([`super::fingerprint`]); 2. walk back from the
//! targets, looking each node up in the caches: a node found there is not run and what
//! only it reads is not visited; 3. start every node whose inputs are ready; when one
//! finishes, start the dependents it completes; 4. a failure marks everything downstream
//! blocked while other branches go on.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use kinegraph_nodes::formats::atomic::write_within;
use kinegraph_nodes::node::{NodeContext, NodeError, NodeOutcome, NodeSchema, Registry, RunServices, Value};

use super::compile::CompiledGraph;
use super::disk_cache::{DiskCache, Entry, Lookup, StoredFile};
use super::fingerprint::{FileIdentity, Fingerprint, fingerprints};
use super::memory::default_memory_limit;
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

/// Outputs and warnings of a node, as kept in the in-memory cache, with the number of the
/// run that last used them.
struct Cached {
    outputs: Vec<Option<Value>>,
    warnings: Vec<String>,
    last_used: AtomicU64,
}

/// Runs an in-memory result survives unused: enough that undoing a few edits in the editor
/// is instant, few enough that the cache holds at most a few generations of the graph's
/// results instead of growing for a whole session.
pub const MEMORY_KEEP_RUNS: u64 = 8;

/// The evaluator: a node registry and a result cache that lives across runs, so a re-run
/// after one parameter change recomputes only what depends on it; optionally a cache folder
/// that keeps results between processes.
pub struct Engine {
    registry: Registry,
    cache: Mutex<HashMap<Fingerprint, Arc<Cached>>>,
    disk: Option<DiskCache>,
    /// Runs started so far; numbers the runs for the in-memory cache's eviction.
    runs: AtomicU64,
    /// Bytes one node may plan to allocate (see `engine::memory`).
    memory_limit: u64,
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
    /// Per node: the result found before the run (in memory or in the cache folder, with
    /// the files an export wrote), taken when the node's turn comes.
    found: Vec<Option<Entry>>,
    /// Per node: what the caches had to say (a damaged entry, a folder that cannot be written).
    cache_warnings: Vec<Vec<String>>,
    reports: BTreeMap<String, NodeReport>,
    files: Vec<PathBuf>,
}

impl Engine {
    /// An engine over `registry` with an empty cache.
    pub fn new(registry: Registry) -> Self {
        Engine {
            registry,
            cache: Mutex::new(HashMap::new()),
            disk: None,
            runs: AtomicU64::new(0),
            memory_limit: default_memory_limit(),
        }
    }

    /// This engine with nodes refusing to plan allocations above `bytes` (`--max-memory`).
    pub fn with_memory_limit(mut self, bytes: u64) -> Self {
        self.memory_limit = bytes;
        self
    }

    /// This engine, also keeping results in (and serving them from) `disk`.
    pub fn with_disk_cache(mut self, disk: DiskCache) -> Self {
        self.disk = Some(disk);
        self
    }

    /// The cache folder, if any.
    pub fn disk_cache(&self) -> Option<&DiskCache> {
        self.disk.as_ref()
    }

    /// The node registry.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// How many results the in-memory cache holds.
    pub fn cached_results(&self) -> usize {
        self.memory().len()
    }

    /// Forgets every cached result.
    pub fn clear_cache(&self) {
        self.memory().clear();
    }

    fn memory(&self) -> std::sync::MutexGuard<'_, HashMap<Fingerprint, Arc<Cached>>> {
        self.cache.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Keeps a node's result in memory, as used by run `run_number`.
    fn remember(&self, key: &Fingerprint, outputs: &[Option<Value>], warnings: &[String], run_number: u64) {
        let cached =
            Cached { outputs: outputs.to_vec(), warnings: warnings.to_vec(), last_used: AtomicU64::new(run_number) };
        self.memory().insert(*key, Arc::new(cached));
    }

    /// Runs `graph` (compiled against this engine's registry).
    pub fn run(&self, graph: &CompiledGraph<'_>, options: &RunOptions<'_>) -> RunReport {
        let started = Instant::now();
        let run_number = self.runs.fetch_add(1, Ordering::Relaxed) + 1;
        // Keys that outlive the process must follow file contents, not times.
        let identity = if self.disk.is_some() { FileIdentity::Content } else { FileIdentity::Stamp };
        let fingerprints = fingerprints(graph, &options.base_dir, identity);
        let Plan { needed, found, cache_warnings } = self.plan(graph, options, &fingerprints, run_number);
        if let Some(observe) = options.observer {
            observe(&RunEvent::Planned { total: needed.iter().filter(|n| **n).count() });
        }
        // Per node that must run: how many distinct needed upstream nodes it still waits for.
        let waits: Vec<bool> = (0..graph.nodes.len()).map(|i| needed[i] && found[i].is_none()).collect();
        let remaining_inputs: Vec<usize> = graph
            .nodes
            .iter()
            .zip(&waits)
            .map(|(n, waits)| {
                let mut sources: Vec<usize> =
                    n.inputs.iter().flatten().map(|(src, _)| *src).filter(|s| needed[*s]).collect();
                sources.sort_unstable();
                sources.dedup();
                if *waits { sources.len() } else { 0 }
            })
            .collect();
        let ready: Vec<usize> =
            graph.order.iter().copied().filter(|&i| needed[i] && remaining_inputs[i] == 0).collect();
        let state = Mutex::new(RunState {
            remaining_inputs,
            slots: graph.nodes.iter().map(|_| Slot::Pending).collect(),
            found,
            cache_warnings,
            reports: BTreeMap::new(),
            files: Vec::new(),
        });
        let services = RunServices {
            base_dir: &options.base_dir,
            out_dir: options.out_dir.as_deref(),
            cancel: &options.cancel,
            memory_limit_bytes: self.memory_limit,
        };
        let job = Job {
            engine: self,
            run_number,
            graph,
            waits: &waits,
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
        self.memory().retain(|_, c| c.last_used.load(Ordering::Relaxed) + MEMORY_KEEP_RUNS > run_number);
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

/// What a run will do: which nodes it visits and which of those have a result already.
struct Plan {
    needed: Vec<bool>,
    found: Vec<Option<Entry>>,
    cache_warnings: Vec<Vec<String>>,
}

impl Engine {
    /// Walks back from the targets (default: every sink), looking each node up in the
    /// caches: a node found there is not run, and what only it reads is not visited at
    /// all, so a re-run of unchanged work reads just the results it hands over.
    fn plan(&self, graph: &CompiledGraph<'_>, options: &RunOptions<'_>, keys: &[Fingerprint], run_number: u64) -> Plan {
        let n = graph.nodes.len();
        let mut plan =
            Plan { needed: vec![false; n], found: (0..n).map(|_| None).collect(), cache_warnings: vec![Vec::new(); n] };
        let mut stack: Vec<usize> = match options.targets.as_deref() {
            Some(ids) => ids.iter().filter_map(|id| graph.index_of(id)).collect(),
            None => (0..n).filter(|&i| graph.nodes[i].dependents.is_empty()).collect(),
        };
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut plan.needed[i], true) {
                continue;
            }
            let schema = graph.nodes[i].node.schema();
            // A bypassed node hands its inputs on: it has no result of its own to look up.
            let found = match graph.nodes[i].pass_through {
                Some(_) => None,
                None => {
                    self.lookup(schema, &keys[i], options.out_dir.is_some(), run_number, &mut plan.cache_warnings[i])
                }
            };
            match found {
                Some(found) => plan.found[i] = Some(found),
                None => stack.extend(graph.nodes[i].inputs.iter().flatten().map(|(src, _)| *src)),
            }
        }
        plan
    }

    /// A result kept from an earlier run: from memory, or from the cache folder (for an
    /// exporting node, with its files' bytes, and only when this run can write them).
    /// Exports are never taken from memory: their files may have changed since.
    fn lookup(
        &self,
        schema: &NodeSchema,
        key: &Fingerprint,
        can_write: bool,
        run_number: u64,
        warnings: &mut Vec<String>,
    ) -> Option<Entry> {
        if !schema.writes_files
            && let Some(hit) = self.memory().get(key)
        {
            hit.last_used.fetch_max(run_number, Ordering::Relaxed);
            return Some(Entry { outputs: hit.outputs.clone(), warnings: hit.warnings.clone(), files: Vec::new() });
        }
        let disk = self.disk.as_ref()?;
        if schema.writes_files && !can_write {
            return None;
        }
        let entry = match disk.get(key) {
            Lookup::Hit(entry) => entry,
            Lookup::Miss => return None,
            Lookup::Corrupt(why) => {
                warnings.push(format!("a damaged entry in the cache folder was ignored and rebuilt ({why})"));
                return None;
            }
        };
        if !schema.writes_files {
            self.remember(key, &entry.outputs, &entry.warnings, run_number);
        }
        Some(*entry)
    }
}

/// An engine with a cache folder trims the folder to its size bound when it goes away: at
/// the end of a `kg` command, or when the editor closes.
impl Drop for Engine {
    fn drop(&mut self) {
        if let Some(disk) = &self.disk {
            disk.trim();
        }
    }
}

#[derive(Clone, Copy)]
struct Job<'a, 'g> {
    engine: &'a Engine,
    run_number: u64,
    graph: &'a CompiledGraph<'g>,
    /// Nodes that run (needed and not found in a cache): they wait for their inputs.
    waits: &'a [bool],
    fingerprints: &'a [Fingerprint],
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
        let (found, mut cache_warnings) = {
            let mut state = self.lock();
            for input in node.inputs.iter().filter(|_| self.waits[index]) {
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
            (state.found[index].take(), std::mem::take(&mut state.cache_warnings[index]))
        };
        let cancelled = self.services.cancel.load(Ordering::Relaxed);
        let fingerprint = self.fingerprints[index];
        let started = Instant::now();
        let (status, outcome, error) = if cancelled {
            (NodeStatus::Cancelled, None, Some("run cancelled".to_string()))
        } else if let Some(found) = found {
            match self.restore(found) {
                Ok(outcome) => (NodeStatus::Cached, Some(outcome), None),
                Err(e) => (NodeStatus::Error, None, Some(e)),
            }
        } else if let Some(upstream) = blocked_by {
            (NodeStatus::Blocked, None, Some(format!("upstream node '{upstream}' did not produce a result")))
        } else if let Some(pass) = &node.pass_through {
            let outputs = pass.iter().map(|input| input.and_then(|i| inputs[i].clone())).collect();
            (NodeStatus::Bypassed, Some(NodeOutcome { outputs, warnings: Vec::new(), files_written: Vec::new() }), None)
        } else {
            self.observe(RunEvent::Started { node: node.id.clone() });
            let id = node.id.clone();
            let progress = move |fraction: f32| self.observe(RunEvent::Progress { node: id.clone(), fraction });
            let mut ctx = NodeContext::new(schema, inputs, &node.params, self.services, &progress);
            match node.node.eval(&mut ctx) {
                Ok(()) => {
                    let outcome = ctx.finish();
                    self.keep(schema, &fingerprint, &outcome, &mut cache_warnings);
                    (NodeStatus::Ok, Some(outcome), None)
                }
                Err(NodeError::Cancelled) => (NodeStatus::Cancelled, None, Some("run cancelled".to_string())),
                Err(e) => (NodeStatus::Error, None, Some(e.with_causes())),
            }
        };
        let seconds =
            if matches!(status, NodeStatus::Ok | NodeStatus::Error) { started.elapsed().as_secs_f64() } else { 0.0 };
        // Counted before taking the lock: a volume or family output has many arrays.
        let output_bytes: u64 =
            outcome.as_ref().map_or(0, |o| o.outputs.iter().flatten().map(Value::array_bytes).sum());
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
            let warnings = [warnings, cache_warnings].concat();
            state.slots[index] = slot;
            state.reports.insert(
                node.id.clone(),
                NodeReport { kind: schema.kind.to_string(), status, seconds, output_bytes, warnings, error },
            );
            for &d in &node.dependents {
                if self.waits[d] {
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

    /// Writes back the files an exporting node made when its result was stored, and
    /// hands over the outputs.
    fn restore(&self, found: Entry) -> Result<NodeOutcome, String> {
        let mut files_written = Vec::with_capacity(found.files.len());
        if !found.files.is_empty() {
            let out_dir = self.services.out_dir.ok_or("this run has no output folder, so nothing may be written")?;
            for file in &found.files {
                files_written.push(write_within(out_dir, &file.relative, &file.bytes).map_err(|e| e.to_string())?);
            }
        }
        Ok(NodeOutcome { outputs: found.outputs, warnings: found.warnings, files_written })
    }

    /// Keeps a fresh result in memory (not for exports) and in the cache folder (exports
    /// with their files' bytes).
    fn keep(&self, schema: &NodeSchema, key: &Fingerprint, outcome: &NodeOutcome, warnings: &mut Vec<String>) {
        if !schema.writes_files {
            self.engine.remember(key, &outcome.outputs, &outcome.warnings, self.run_number);
        }
        let Some(disk) = self.engine.disk.as_ref() else { return };
        let mut files = Vec::with_capacity(outcome.files_written.len());
        for path in &outcome.files_written {
            let relative = self.services.out_dir.and_then(|out| path.strip_prefix(out).ok());
            match (relative, std::fs::read(path)) {
                (Some(relative), Ok(bytes)) => files.push(StoredFile { relative: relative.to_path_buf(), bytes }),
                // Not kept rather than kept without a file it made.
                _ => return,
            }
        }
        let entry = Entry { outputs: outcome.outputs.clone(), warnings: outcome.warnings.clone(), files };
        warnings.extend(disk.put(key, &entry));
    }
}
