//! Transition graph (Peng 2007) on the real CMU corpus (the largest skeleton family of
//! `shared/data/bvh`, at 30 fps): clustering, candidate paths for every cluster pair (the
//! paper's 3,600-frame corpus size, and the whole corpus at ~160 and ~190 clusters),
//! synthesis per output frame, and the whole corpus end to end.
//!
//! Run: `cargo bench -p kinegraph-nodes --bench transitions`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use kinegraph_nodes::builtin::transitions::actions::{Action, ActionLabels, find_actions};
use kinegraph_nodes::builtin::transitions::play_sequence;
use kinegraph_nodes::builtin::transitions::synthesis::SynthesisParams;
use kinegraph_nodes::cancel::Cancel;
use kinegraph_nodes::kernels::clip_set::load_clip_set;
use kinegraph_nodes::kernels::transition_graph::cluster::{cluster, corpus_features, two_pass};
use kinegraph_nodes::kernels::transition_graph::distance::DistanceParams;
use kinegraph_nodes::kernels::transition_graph::graph::{Direction, TransitionGraph, build_graph};
use kinegraph_nodes::kernels::transition_graph::paths::{PathLimits, k_best_paths};
use kinegraph_nodes::model::ClipSet;
use rand::SeedableRng;

const RADIUS: f32 = 0.6;
const LIMITS: PathLimits = PathLimits { k: 5, max_cost: f64::INFINITY };

fn bench(c: &mut Criterion) {
    let Some(data) = kinegraph_nodes::corpus::shared_data() else { return };
    let folder = data.join("bvh");
    let set = Arc::new(load_clip_set(&folder, "*.bvh", 30.0, None, None).expect("corpus loads").set);
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
    c.bench_function("cluster_3600_frames", |b| b.iter(|| black_box(two_pass(&small_features, RADIUS, Cancel::NEVER))));
    c.bench_function("cluster_whole_corpus", |b| b.iter(|| black_box(two_pass(&features, RADIUS, Cancel::NEVER))));

    let all_pairs = |name: &str, radius: f32, set: Arc<ClipSet>, c: &mut Criterion| {
        let graph = build_graph(
            Arc::new(cluster(set, params.clone(), radius, Cancel::NEVER).unwrap()),
            Direction::Directed,
            LIMITS,
        );
        let adjacency = graph.adjacency();
        let subproblems: usize =
            (0..adjacency.len() as u32).map(|s| k_best_paths(&adjacency, s, LIMITS).subproblems).sum();
        eprintln!(
            "{name}: r = {radius}, {}, {subproblems} sub-problems",
            graph.summary_with_paths(Cancel::NEVER).unwrap()
        );
        c.bench_function(name, |b| {
            b.iter(|| {
                for s in 0..adjacency.len() as u32 {
                    black_box(k_best_paths(&adjacency, s, LIMITS));
                }
            })
        });
        graph
    };
    all_pairs("paths_all_pairs_subset", RADIUS, Arc::new(small), c);
    // About the paper's 164 clusters: the whole corpus at a larger radius.
    all_pairs("paths_all_pairs_whole_corpus_r0.7", 0.7, set.clone(), c);
    let graph = all_pairs("paths_all_pairs_whole_corpus", RADIUS, set.clone(), c);

    // Synthesis: walk → punch → kick as `motion.sequence` plays it, with the path tables
    // already cached; per output frame = time / frames of the transitions synthesised.
    // Once with the whole takes, once with the single strikes of the example's label file,
    // once with every pair of clusters left without a path (the Bézier fallback).
    let whole = find_actions(&set, &BTreeMap::new(), &["02_01", "02_05", "144_05"]).expect("clips in the corpus");
    let label_file = concat!(env!("CARGO_MANIFEST_DIR"), "/../graphs/labels/walk_punch_kick.ron");
    let labelled = ActionLabels::parse(&std::fs::read_to_string(label_file).expect("label file"))
        .and_then(|l| l.resolve(&set))
        .expect("labels fit the corpus");
    let strikes = find_actions(&set, &labelled, &["walk", "punch", "kick"]).expect("labelled actions");
    let no_paths = PathLimits { max_cost: 0.0, ..LIMITS };
    let fallback_graph = build_graph(graph.clusters.clone(), Direction::Directed, no_paths);
    let run = |g: &TransitionGraph, actions: &[Action]| {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        play_sequence(g, actions, &SynthesisParams::default(), &mut rng)
    };
    for (name, g, actions) in [
        ("synthesis_two_transitions", &graph, &whole),
        ("synthesis_two_transitions_single_strikes", &graph, &strikes),
        ("synthesis_two_fallbacks", &fallback_graph, &whole),
    ] {
        let (motion, infos) = run(g, actions);
        let frames: usize = infos.iter().map(|i| i.frames.len()).sum();
        eprintln!("{name}: {frames} transition frames of {} output frames per run", motion.frame_count());
        c.bench_function(name, |b| b.iter(|| black_box(run(g, actions))));
    }

    c.bench_function("end_to_end_whole_corpus", |b| {
        b.iter(|| {
            let g = build_graph(
                Arc::new(cluster(set.clone(), params.clone(), RADIUS, Cancel::NEVER).unwrap()),
                Direction::Directed,
                LIMITS,
            );
            black_box(run(&g, &whole))
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = bench
}
criterion_main!(benches);
