//! The on-disk cache on the real corpus: every BVH of `../shared/data/bvh` (39 clips,
//! 25 MB) through the README's batch graph (`clip.load` → `export.glb`), as `kg batch`
//! runs it: one compiled graph per clip, one engine for the whole batch.
//!
//! - **cold**: an empty cache folder (the first batch: every node runs and is stored);
//! - **warm**: the folder a previous batch filled, read by a new engine (a second `kg
//!   batch` process: nothing in memory, every result and export restored from disk);
//! - **no cache**: the same batch without `--cache`, for the cost of storing.
//!
//! The bench prints warm ÷ cold. Run: `cargo bench --bench cache -- --warm-up-time 1`.
//! Figures go in notes, never in asserts.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use kinegraph::document::{EdgeDoc, GraphDoc, NodeDoc, SourceMap};
use kinegraph::engine::{DEFAULT_MAX_BYTES, DiskCache, Engine, NodeStatus, RunOptions, compile};
use kinegraph::graph::Graph;
use kinegraph_nodes::node::ParamValue;

/// The batch graph of the README for one clip.
fn to_glb(clip: &Path) -> GraphDoc {
    let mut doc = GraphDoc::new();
    let text = |s: &str| ParamValue::Text(s.to_string());
    let params = |pairs: &[(&str, ParamValue)]| pairs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
    doc.nodes.insert(
        "load".into(),
        NodeDoc { kind: "clip.load".into(), params: params(&[("path", text(&clip.to_string_lossy()))]), bypass: false },
    );
    doc.nodes.insert(
        "glb".into(),
        NodeDoc { kind: "export.glb".into(), params: params(&[("file", text("clip.glb"))]), bypass: false },
    );
    doc.edges.push(EdgeDoc { from: "load.clip".into(), to: "glb.clip".into() });
    doc
}

/// Runs the batch over `clips` into `out` (one folder per clip, made first, as `kg batch`
/// does); returns (nodes run, nodes served from a cache). A failed node stops the bench:
/// it would measure failures, not work.
fn batch(engine: &Engine, clips: &[PathBuf], out: &Path) -> (usize, usize) {
    let (mut ran, mut cached) = (0, 0);
    for (i, clip) in clips.iter().enumerate() {
        let graph = Graph::from_doc(&to_glb(clip)).unwrap();
        let compiled = compile(&graph, engine.registry(), Path::new("batch.ron"), &SourceMap::default()).unwrap();
        let mut options = RunOptions::new(PathBuf::from("."));
        let run_out = out.join(i.to_string());
        std::fs::create_dir_all(&run_out).unwrap();
        options.out_dir = Some(run_out);
        let report = engine.run(&compiled, &options);
        assert!(report.succeeded(), "{}: {:?}", clip.display(), report.nodes);
        ran += report.count(NodeStatus::Ok);
        cached += report.count(NodeStatus::Cached);
    }
    (ran, cached)
}

fn engine_with(cache: Option<&Path>) -> Engine {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    match cache {
        Some(dir) => engine.with_disk_cache(DiskCache::open(dir, DEFAULT_MAX_BYTES).unwrap()),
        None => engine,
    }
}

fn corpus_batch(c: &mut Criterion) {
    let Some(data) = kinegraph_nodes::corpus::shared_data() else { return };
    let clips = kinegraph_nodes::corpus::files_with_extension(&data.join("bvh"), "bvh");
    let scratch = tempfile::tempdir().unwrap();
    let filled = scratch.path().join("filled");
    let (ran, _) = batch(&engine_with(Some(&filled)), &clips, &scratch.path().join("fill-out"));
    let (ran_warm, cached_warm) = batch(&engine_with(Some(&filled)), &clips, &scratch.path().join("check-out"));
    println!("corpus: {} clips; first batch ran {ran} nodes; second ran {ran_warm}, {cached_warm} cached", clips.len());

    let mut group = c.benchmark_group("corpus batch");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    let mut cold = Vec::new();
    let mut warm = Vec::new();
    group.bench_function("cold cache", |b| {
        b.iter_batched(
            || tempfile::tempdir_in(scratch.path()).unwrap(),
            |dir| {
                let t = Instant::now();
                batch(&engine_with(Some(&dir.path().join("cache"))), &clips, &dir.path().join("out"));
                cold.push(t.elapsed().as_secs_f64());
            },
            BatchSize::PerIteration,
        )
    });
    group.bench_function("warm cache (second process)", |b| {
        b.iter_batched(
            || tempfile::tempdir_in(scratch.path()).unwrap(),
            |dir| {
                let t = Instant::now();
                batch(&engine_with(Some(&filled)), &clips, dir.path());
                warm.push(t.elapsed().as_secs_f64());
            },
            BatchSize::PerIteration,
        )
    });
    group.bench_function("no cache", |b| {
        b.iter_batched(
            || tempfile::tempdir_in(scratch.path()).unwrap(),
            |dir| batch(&engine_with(None), &clips, dir.path()),
            BatchSize::PerIteration,
        )
    });
    group.finish();
    let (cold, warm) = (median(cold), median(warm));
    println!(
        "median batch: cold {:.0} ms, warm {:.0} ms: {:.1}× faster",
        cold * 1e3,
        warm * 1e3,
        cold / warm.max(1e-9)
    );
}

fn median(mut seconds: Vec<f64>) -> f64 {
    seconds.sort_by(f64::total_cmp);
    seconds.get(seconds.len() / 2).copied().unwrap_or(f64::NAN)
}

criterion_group!(benches, corpus_batch);
criterion_main!(benches);
