//! Transition graph (Peng 2007) on the real CMU corpus (the largest skeleton family of
//! `shared/data/bvh`, at 30 fps): clustering, candidate paths for every cluster pair,
//! synthesis per output frame, and the whole corpus end to end.
//!
//! Run: `cargo bench -p kinegraph-nodes --bench transitions`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use kinegraph_nodes::builtin::transitions::cluster::{cluster, corpus_features, two_pass};
use kinegraph_nodes::builtin::transitions::distance::DistanceParams;
use kinegraph_nodes::builtin::transitions::graph::{Direction, build_graph};
use kinegraph_nodes::builtin::transitions::load_clip_set;
use kinegraph_nodes::builtin::transitions::paths::{PathLimits, k_best_paths};
use kinegraph_nodes::builtin::transitions::synthesis::{Motion, SynthesisParams, append_transition};
use kinegraph_nodes::model::ClipSet;
use rand::SeedableRng;

const RADIUS: f32 = 0.6;
const LIMITS: PathLimits = PathLimits { k: 5, max_cost: f64::INFINITY };

fn bench(c: &mut Criterion) {
    let Some(data) = kinegraph_nodes::corpus::shared_data() else { return };
    let folder = data.join("bvh");
    let set = Arc::new(load_clip_set(&folder, "*.bvh", 30.0, None).expect("corpus loads").set);
    let params = DistanceParams::lee_defaults(set.skeleton(), 0.003);
    let (features, _) = corpus_features(&set, &params);
    // The paper's corpus size: the first clips (by name) up to ~3,600 frames.
    let mut small = Vec::new();
    for c in set.clips() {
        if small.iter().map(|c: &kinegraph_nodes::model::NamedClip| c.clip.frame_count()).sum::<usize>() < 3600 {
            small.push(c.clone());
        }
    }
    let small = ClipSet::new(small).expect("subset of a valid set");
    let (small_features, _) = corpus_features(&small, &params);
    eprintln!("corpus: {} frames; subset: {} frames", features.len(), small_features.len());
    c.bench_function("cluster_3600_frames", |b| b.iter(|| black_box(two_pass(&small_features, RADIUS))));
    c.bench_function("cluster_whole_corpus", |b| b.iter(|| black_box(two_pass(&features, RADIUS))));

    let small_graph =
        build_graph(Arc::new(cluster(Arc::new(small), params.clone(), RADIUS)), Direction::Directed, LIMITS);
    let adjacency = small_graph.adjacency();
    eprintln!("subset graph: {}", small_graph.summary(true));
    c.bench_function("paths_all_pairs_subset", |b| {
        b.iter(|| {
            for s in 0..adjacency.len() as u32 {
                black_box(k_best_paths(&adjacency, s, LIMITS));
            }
        })
    });

    let graph = build_graph(Arc::new(cluster(set.clone(), params.clone(), RADIUS)), Direction::Directed, LIMITS);
    let adjacency = graph.adjacency();
    eprintln!("whole graph: {}", graph.summary(true));
    c.bench_function("paths_all_pairs_whole_corpus", |b| {
        b.iter(|| {
            for s in 0..adjacency.len() as u32 {
                black_box(k_best_paths(&adjacency, s, LIMITS));
            }
        })
    });

    // Synthesis: walk → punch → kick with the path tables already cached; per output frame
    // = time / frames of the transitions synthesised.
    let names = ["02_01", "02_05", "144_05"];
    let clips: Vec<Motion> = names.iter().map(|n| Motion::of_clip(&set.get(n).expect("in corpus").clip)).collect();
    let run = || {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut out = clips[0].clone();
        let mut frames = 0;
        for next in &clips[1..] {
            frames += append_transition(&graph, &mut out, next, &SynthesisParams::default(), &mut rng).frames.len();
        }
        (out, frames)
    };
    let (_, frames) = run();
    eprintln!("synthesis: {frames} transition frames per run");
    c.bench_function("synthesis_two_transitions", |b| b.iter(|| black_box(run())));

    c.bench_function("end_to_end_whole_corpus", |b| {
        b.iter(|| {
            let g = build_graph(Arc::new(cluster(set.clone(), params.clone(), RADIUS)), Direction::Directed, LIMITS);
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
            let mut out = clips[0].clone();
            for next in &clips[1..] {
                append_transition(&g, &mut out, next, &SynthesisParams::default(), &mut rng);
            }
            black_box(out)
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
