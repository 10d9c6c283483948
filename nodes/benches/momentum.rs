//! Optimal-timing search of the angular-momentum concatenation (Shum et al. 2009) on the
//! real CMU corpus: one pair of 120 fps cartwheels, and all ordered pairs of 40 clips.
//! Run: `cargo bench -p kinegraph-nodes --bench momentum`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use kinegraph_nodes::builtin::clip_edit::trim;
use kinegraph_nodes::builtin::momentum::concat::{TimingSearch, TimingSide};
use kinegraph_nodes::corpus::{files_with_extension, shared_data};
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::analysis::{Analysis, AnalysisOptions, analyse};

fn load(path: &std::path::Path, from: f64, to: f64) -> Option<Analysis> {
    let (clip, _) = read_bvh_file(path, BvhReadOptions::default()).ok()?.value;
    let clip = trim(&clip, from, Some(to)).ok()?;
    analyse(Arc::new(clip), &AnalysisOptions::default(), None, None).ok()
}

/// The forward rule's blendable periods: after the first clip's peak, up to the second's.
fn search(a: &Analysis, b: &Analysis) -> f64 {
    let after: Vec<bool> =
        (0..a.smoothed.len()).map(|f| f >= a.phases.main_frame && a.phases.main.contains(f)).collect();
    let before: Vec<bool> =
        (0..b.smoothed.len()).map(|g| g <= b.phases.main_frame && b.phases.main.contains(g)).collect();
    TimingSearch {
        first: TimingSide { momentum: &a.smoothed, arms_m: &a.track.arms_m, allowed: &after },
        second: TimingSide { momentum: &b.smoothed, arms_m: &b.track.arms_m, allowed: &before },
        masses_kg: &a.track.masses_kg,
        first_start: a.phases.main_frame,
        weights: [1.0; 3],
        min_offset: isize::MIN,
    }
    .run()
    .map_or(f64::NAN, |t| t.cost())
}

fn bench(c: &mut Criterion) {
    let Some(data) = shared_data() else { return };
    let cartwheels = data.join("bvh/cmu/144_01.bvh");
    let (a, b) = (load(&cartwheels, 1.3, 4.3).unwrap(), load(&cartwheels, 8.6, 11.3).unwrap());
    c.bench_function("optimal_timing/cartwheel_pair_120fps", |bench| bench.iter(|| black_box(search(&a, &b))));
    // 40 clips: 2-second windows of every 120 fps CMU clip, as many as it takes.
    let mut clips = Vec::new();
    'files: for path in files_with_extension(&data.join("bvh/cmu"), "bvh") {
        for k in 0..4 {
            if clips.len() == 40 {
                break 'files;
            }
            if let Some(an) = load(&path, 0.01 + 2.0 * k as f64, 2.01 + 2.0 * k as f64)
                && (an.clip.fps() - 120.0).abs() < 0.1
                && an.clip.frame_count() > 200
            {
                clips.push(an);
            }
        }
    }
    assert_eq!(clips.len(), 40);
    let mut group = c.benchmark_group("optimal_timing");
    group.sample_size(10);
    group.bench_function("all_ordered_pairs_of_40_clips", |bench| {
        bench.iter(|| {
            let mut total = 0.0;
            for (i, a) in clips.iter().enumerate() {
                for (j, b) in clips.iter().enumerate() {
                    if i != j {
                        total += search(a, b);
                    }
                }
            }
            black_box(total)
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
