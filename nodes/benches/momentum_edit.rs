//! One momentum-based edit (issue 15 goal: < 2 s per edit of a 2–3 s jump): CMU 16_01
//! (323 frames at 120 fps), landing moved by (0.3, −0.5) m as in graphs/jump_further.ron.
//! Run: `cargo bench -p kinegraph-nodes --bench momentum_edit`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::kernels::body::{MassTable, body_model};
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::kernels::load::{ClipLoadOptions, load_clip};
use kinegraph_nodes::kernels::momentum_edit::GroundEdit;
use kinegraph_nodes::kernels::momentum_solve::{EditSetup, SolveOptions, momentum_edit};
use kinegraph_nodes::kernels::stages::stage_clip;
use kinegraph_nodes::model::{FrameRange, forward_kinematics};

fn bench(c: &mut Criterion) {
    let Some(data) = shared_data() else { return };
    let clip = load_clip(&data.join("bvh/cmu/16_01.bvh"), ClipLoadOptions::default()).unwrap().value;
    let model = body_model(clip.skeleton(), 70.0, MassTable::DeLevaMale, None).unwrap();
    let stages = stage_clip(&clip, &model, None, None).unwrap().stages;
    let (contacts, feet) = contacts_of(&clip, &forward_kinematics(&clip), &ContactThresholds::default()).unwrap();
    let planted: Vec<(usize, FrameRange)> =
        contacts.feet.iter().zip(feet).flat_map(|(c, j)| c.intervals.iter().map(move |r| (j, *r))).collect();
    let edits = [GroundEdit::default(), GroundEdit { offset_m: DVec3::new(0.3, 0.0, -0.5), turn_rad: 0.0 }];
    let setup = EditSetup { clip: &clip, stages: &stages, model: &model, feet, planted: &planted, edits: &edits };
    let mut group = c.benchmark_group("momentum_edit");
    group.sample_size(10);
    group.bench_function("16_01 landing +(0.3, -0.5) m", |b| {
        b.iter(|| black_box(momentum_edit(setup, &SolveOptions::default()).unwrap().1.iterations))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
