//! Engine benchmarks on graphs built in code (no files involved):
//!
//! 1. **Overhead per node**: a 1,000-node chain (`scalar.constant` then 999 `scalar.add`),
//!    every node evaluated (fresh engine, empty cache), and the same graph re-run with
//!    every node a target and every result already cached. The bench prints the time per
//!    node.
//! 2. **Parallel speed-up**: two independent chains of four `bench.spin` nodes (about
//!    50 ms of arithmetic each) run on 1 and on 2 worker threads with an empty cache. The
//!    bench prints the speed-up.
//! 3. **Incremental re-run**: a 20-node graph (a constant feeding a 14-node chain and a
//!    5-node branch) run once, then one parameter in the middle of the chain changed,
//!    recompiled and run again on the same engine. The bench prints how many nodes ran
//!    and how many came from the cache.
//!
//! Run: `cargo bench --bench engine -- --warm-up-time 1 --measurement-time 5`.
//! Figures go in notes, never in asserts (only the incremental counts are checked, as a
//! guard that the bench measures what it says).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use kinegraph::document::{EdgeDoc, GraphDoc, NodeDoc, SourceMap};
use kinegraph::engine::{CompiledGraph, Engine, NodeStatus, RunOptions, compile};
use kinegraph::graph::Graph;
use kinegraph_nodes::node::{
    FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, ParamValue, Registry,
};

/// Nodes in the overhead chain.
const CHAIN_LEN: usize = 1000;
/// Wall time one `bench.spin` evaluation aims at.
const SPIN_TARGET: Duration = Duration::from_millis(50);

// ---------------------------------------------------------------------------------------
// The heavy test node.

/// Loop iterations of one spin evaluation, calibrated once to [`SPIN_TARGET`].
static SPIN_ITERATIONS: AtomicU64 = AtomicU64::new(0);

const SPIN_IN: Input<f64> = Input::optional("x", "Seed value (0 when unconnected).");
const SPIN_SALT: FloatParam = FloatParam::new("salt", "Mixed into the arithmetic.", 0.0, -1e6, 1e6, "");
const SPIN_OUT: Output<f64> = Output::new("y", "Result of the arithmetic.");

/// `bench.spin`: deterministic busy arithmetic standing in for an expensive kernel.
struct Spin;

static SPIN: NodeSchema = NodeSchema {
    kind: "bench.spin",
    category: "bench",
    doc: "Spends about 50 ms on deterministic arithmetic (benchmark only).",
    inputs: &[SPIN_IN.spec()],
    outputs: &[SPIN_OUT.spec()],
    params: &[SPIN_SALT.0],
    writes_files: false,
    version: 1,
};

/// The kernel: `iterations` steps of a logistic-style recurrence seeded by `x` and
/// `salt`. Pure: the same arguments always give the same result.
fn spin(x: f64, salt: f64, iterations: u64) -> f64 {
    let mut v = 0.5 + 0.25 * ((x + salt).sin());
    for _ in 0..iterations {
        v = black_box(3.9 * v * (1.0 - v));
    }
    x + v
}

impl Node for Spin {
    fn schema(&self) -> &'static NodeSchema {
        &SPIN
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let x = ctx.optional_input(&SPIN_IN)?.unwrap_or(0.0);
        let salt = ctx.float(&SPIN_SALT)?;
        ctx.set_output(&SPIN_OUT, spin(x, salt, SPIN_ITERATIONS.load(Ordering::Relaxed)));
        Ok(())
    }
}

/// Sets [`SPIN_ITERATIONS`] so one evaluation takes about [`SPIN_TARGET`] on this machine.
fn calibrate_spin() {
    let probe = 2_000_000u64;
    let started = Instant::now();
    black_box(spin(0.0, 0.0, probe));
    let per_iteration = started.elapsed().as_secs_f64() / probe as f64;
    let iterations = (SPIN_TARGET.as_secs_f64() / per_iteration.max(1e-12)) as u64;
    SPIN_ITERATIONS.store(iterations, Ordering::Relaxed);
    let started = Instant::now();
    black_box(spin(0.0, 0.0, iterations));
    eprintln!(
        "bench.spin: {iterations} iterations per evaluation, measured {:.1} ms",
        started.elapsed().as_secs_f64() * 1e3
    );
}

// ---------------------------------------------------------------------------------------
// Graph building helpers.

fn node(kind: &str, params: &[(&str, f64)]) -> NodeDoc {
    let params: BTreeMap<String, ParamValue> =
        params.iter().map(|(name, v)| (name.to_string(), ParamValue::Float(*v))).collect();
    NodeDoc { kind: kind.to_string(), params, bypass: false }
}

fn edge(from: &str, to: &str) -> EdgeDoc {
    EdgeDoc { from: from.to_string(), to: to.to_string() }
}

/// Validates `doc`, panicking with every diagnostic when the bench built it wrong.
fn compiled<'r>(doc: &GraphDoc, registry: &'r Registry) -> CompiledGraph<'r> {
    let graph = Graph::from_doc(doc).unwrap_or_else(|e| panic!("{e:?}"));
    compile(&graph, registry, Path::new("bench.ron"), &SourceMap::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// Run options with a base folder that is never read (no node here touches files).
fn options(threads: Option<usize>) -> RunOptions<'static> {
    let mut options = RunOptions::new(PathBuf::from("."));
    options.threads = threads;
    options
}

/// `c0` (constant) → `n0001` → … → `n0999`, each `scalar.add` reading the previous one.
fn chain_graph(len: usize) -> GraphDoc {
    let mut doc = GraphDoc::new();
    doc.nodes.insert("c0".into(), node("scalar.constant", &[("value", 1.0)]));
    let mut previous = "c0.value".to_string();
    for i in 1..len {
        let id = format!("n{i:04}");
        doc.nodes.insert(id.clone(), node("scalar.add", &[("offset", 1.0)]));
        doc.edges.push(edge(&previous, &format!("{id}.a")));
        previous = format!("{id}.sum");
    }
    doc
}

/// Two independent chains `a1 → … → a4` and `b1 → … → b4` of spin nodes.
fn spin_graph() -> GraphDoc {
    let mut doc = GraphDoc::new();
    for chain in ["a", "b"] {
        for i in 1..=4 {
            let salt = if chain == "a" { i as f64 } else { -(i as f64) };
            doc.nodes.insert(format!("{chain}{i}"), node("bench.spin", &[("salt", salt)]));
            if i > 1 {
                doc.edges.push(edge(&format!("{chain}{}.y", i - 1), &format!("{chain}{i}.x")));
            }
        }
    }
    doc
}

/// Chain nodes after the constant in the incremental graph.
const INCR_CHAIN: usize = 14;
/// Branch nodes in the incremental graph.
const INCR_BRANCH: usize = 5;
/// The chain node whose parameter the incremental bench changes.
const INCR_CHANGED: &str = "chain07";

/// `src` feeding `chain01 → … → chain14` and, separately, `branch1 → … → branch5`:
/// 20 nodes. Changing `chain07` leaves 8 nodes to recompute (`chain07`..`chain14`).
fn incremental_graph() -> GraphDoc {
    let mut doc = GraphDoc::new();
    doc.nodes.insert("src".into(), node("scalar.constant", &[("value", 2.0)]));
    for (prefix, len) in [("chain", INCR_CHAIN), ("branch", INCR_BRANCH)] {
        let mut previous = "src.value".to_string();
        for i in 1..=len {
            let id = if prefix == "chain" { format!("chain{i:02}") } else { format!("branch{i}") };
            // Distinct offsets per branch: equal (kind, params, inputs) would share a
            // fingerprint, and the engine would rightly serve one from the other's result.
            let offset = if prefix == "chain" { i as f64 } else { i as f64 + 0.5 };
            doc.nodes.insert(id.clone(), node("scalar.add", &[("offset", offset)]));
            doc.edges.push(edge(&previous, &format!("{id}.a")));
            previous = format!("{id}.sum");
        }
    }
    doc
}

/// Median of recorded per-iteration seconds.
fn median(samples: &Mutex<Vec<f64>>) -> f64 {
    let mut v = samples.lock().unwrap().clone();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Times `iters` calls of `f`, recording the mean per call into `samples`.
fn timed(iters: u64, samples: &Mutex<Vec<f64>>, mut f: impl FnMut()) -> Duration {
    let started = Instant::now();
    for _ in 0..iters {
        f();
    }
    let elapsed = started.elapsed();
    samples.lock().unwrap().push(elapsed.as_secs_f64() / iters.max(1) as f64);
    elapsed
}

// ---------------------------------------------------------------------------------------
// Benchmarks.

/// 1. Per-node overhead: uncached and all-cached runs of the 1,000-node chain.
fn overhead(c: &mut Criterion) {
    let registry = kinegraph_nodes::builtin::registry();
    let doc = chain_graph(CHAIN_LEN);
    let graph = compiled(&doc, &registry);
    let run_options = options(None);

    let mut group = c.benchmark_group("overhead_chain_1000");
    group.throughput(Throughput::Elements(CHAIN_LEN as u64));

    let uncached = Mutex::new(Vec::new());
    group.bench_function("uncached", |b| {
        b.iter_custom(|iters| {
            // A fresh engine per run; engines are made and dropped outside the timing.
            let engines: Vec<Engine> = (0..iters).map(|_| Engine::new(Registry::empty())).collect();
            let mut engines = engines.into_iter();
            let mut reports = Vec::with_capacity(iters as usize);
            let elapsed = timed(iters, &uncached, || {
                let engine = engines.next().unwrap();
                reports.push((engine.run(&graph, &run_options), engine));
            });
            let (report, _) = reports.last().unwrap();
            assert_eq!(report.count(NodeStatus::Ok), CHAIN_LEN, "every node must run");
            drop(reports);
            elapsed
        })
    });

    // Every node a target (as in the editor): each one is looked up and served from the
    // cache. With only the sink as target, the sink alone would be visited.
    let mut every_node = options(None);
    every_node.targets = Some(graph.nodes.iter().map(|n| n.id.clone()).collect());
    let warm = Engine::new(Registry::empty());
    warm.run(&graph, &every_node);
    let cached = Mutex::new(Vec::new());
    group.bench_function("all_cached", |b| {
        b.iter_custom(|iters| {
            timed(iters, &cached, || {
                black_box(warm.run(&graph, &every_node));
            })
        })
    });
    group.finish();

    let report = warm.run(&graph, &every_node);
    assert_eq!(report.count(NodeStatus::Cached), CHAIN_LEN, "the warm engine must serve everything from cache");
    let (u, k) = (median(&uncached), median(&cached));
    eprintln!(
        "overhead: uncached {:.3} ms per run = {:.2} µs per node; all cached {:.3} ms per run = {:.2} µs per node",
        u * 1e3,
        u * 1e6 / CHAIN_LEN as f64,
        k * 1e3,
        k * 1e6 / CHAIN_LEN as f64
    );
}

/// 2. Parallel speed-up: two chains of four 50 ms spin nodes on 1 and 2 threads.
fn parallel(c: &mut Criterion) {
    calibrate_spin();
    let mut registry = kinegraph_nodes::builtin::registry();
    registry.add(Box::new(Spin));
    let doc = spin_graph();
    let graph = compiled(&doc, &registry);
    let engine = Engine::new(Registry::empty());

    let mut group = c.benchmark_group("parallel_two_spin_chains");
    group.sample_size(10);
    let mut medians = Vec::new();
    for threads in [1usize, 2] {
        let run_options = options(Some(threads));
        let samples = Mutex::new(Vec::new());
        // Node seconds summed over the run divided by its wall time: the parallelism
        // actually achieved (near 1 on one thread, near 2 on two idle cores).
        let overlap = Mutex::new(Vec::new());
        group.bench_function(format!("threads_{threads}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    engine.clear_cache();
                    let started = Instant::now();
                    let report = engine.run(&graph, &run_options);
                    let elapsed = started.elapsed();
                    assert_eq!(report.count(NodeStatus::Ok), 8, "all eight spin nodes must run");
                    samples.lock().unwrap().push(elapsed.as_secs_f64());
                    let busy: f64 = report.nodes.values().map(|n| n.seconds).sum();
                    overlap.lock().unwrap().push(busy / elapsed.as_secs_f64());
                    total += elapsed;
                }
                total
            })
        });
        medians.push(median(&samples));
        eprintln!("parallel: threads {threads}: node seconds / wall = {:.2}", median(&overlap));
    }
    group.finish();
    eprintln!(
        "parallel: 1 thread {:.1} ms, 2 threads {:.1} ms, speed-up {:.2}× (ideal 2×, 8 nodes × ~50 ms)",
        medians[0] * 1e3,
        medians[1] * 1e3,
        medians[0] / medians[1]
    );
}

/// 3. Incremental re-run: change one parameter mid-chain, recompile and re-run.
fn incremental(c: &mut Criterion) {
    let registry = kinegraph_nodes::builtin::registry();
    let doc = incremental_graph();
    assert_eq!(doc.nodes.len(), 1 + INCR_CHAIN + INCR_BRANCH);
    let mut changed = doc.clone();
    if let Some(node) = changed.nodes.get_mut(INCR_CHANGED) {
        node.params.insert("offset".into(), ParamValue::Float(100.0));
    }
    let run_options = options(None);

    // The counts, once, for the record.
    let engine = Engine::new(Registry::empty());
    let first = engine.run(&compiled(&doc, &registry), &run_options);
    let started = Instant::now();
    let second = engine.run(&compiled(&changed, &registry), &run_options);
    let once = started.elapsed();
    let (ok, hit) = (second.count(NodeStatus::Ok), second.count(NodeStatus::Cached));
    eprintln!(
        "incremental: first run {} ok / {} cached; after changing {INCR_CHANGED}.offset: {ok} ok / {hit} cached \
         (one-off recompile + run {:.1} µs)",
        first.count(NodeStatus::Ok),
        first.count(NodeStatus::Cached),
        once.as_secs_f64() * 1e6
    );
    assert_eq!(first.count(NodeStatus::Ok), doc.nodes.len(), "a fresh engine must run every node");
    // chain07..chain14 recompute; chain06 and the branch's end are served from the cache,
    // and what only they read is not visited.
    assert_eq!((ok, hit), (8, 2), "only chain07..chain14 should recompute");

    let mut group = c.benchmark_group("incremental_20_nodes");
    let rerun = Mutex::new(Vec::new());
    group.bench_function("change_one_param_recompile_rerun", |b| {
        b.iter_batched(
            || {
                let engine = Engine::new(Registry::empty());
                engine.run(&compiled(&doc, &registry), &run_options);
                engine
            },
            |engine| {
                let started = Instant::now();
                let graph = compiled(&changed, &registry);
                let report = engine.run(&graph, &run_options);
                rerun.lock().unwrap().push(started.elapsed().as_secs_f64());
                (report, engine)
            },
            BatchSize::SmallInput,
        )
    });
    let cold = Mutex::new(Vec::new());
    group.bench_function("cold_compile_run", |b| {
        b.iter_batched(
            || Engine::new(Registry::empty()),
            |engine| {
                let started = Instant::now();
                let graph = compiled(&changed, &registry);
                let report = engine.run(&graph, &run_options);
                cold.lock().unwrap().push(started.elapsed().as_secs_f64());
                (report, engine)
            },
            BatchSize::SmallInput,
        )
    });
    group.finish();
    eprintln!(
        "incremental: re-run after one change {:.1} µs (8 ok / 2 cached, 10 not visited) vs cold {:.1} µs (20 ok)",
        median(&rerun) * 1e6,
        median(&cold) * 1e6
    );
}

criterion_group!(benches, overhead, parallel, incremental);
criterion_main!(benches);
