//! Momentum-based editing on CMU 16_01 (322 frames at 120 fps, as clip.load reads it). Issue 15 goals: < 2 s per
//! edit of a 2–3 s jump; a 5×5 family < 30 s; family blend < 50 µs per frame.
//! - one edit: landing moved by (0.3, −0.5) m as in graphs/jump_further.ron;
//! - a 5×5 grid family of the landing (±0.2 m along and across the jump), samples in parallel;
//! - a blend inside a 2×2 family cell (4 samples, every frame; divide by 322 for per frame).
//!
//! Run: `cargo bench -p kinegraph-nodes --bench momentum_edit`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::kernels::body::{MassTable, body_model};
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::kernels::family::{AxisSweep, FamilySpec, populate};
use kinegraph_nodes::kernels::family_blend::blend_family;
use kinegraph_nodes::kernels::load::{ClipLoadOptions, LeadingTPose, load_clip};
use kinegraph_nodes::kernels::momentum_edit::GroundEdit;
use kinegraph_nodes::kernels::momentum_solve::{EditSetup, SolveOptions, momentum_edit};
use kinegraph_nodes::kernels::stages::stage_clip;
use kinegraph_nodes::model::{FamilyKind, FrameRange, forward_kinematics};

fn bench(c: &mut Criterion) {
    let Some(data) = shared_data() else { return };
    // As clip.load gives it: without cgspeed's T-pose frame before the motion.
    let options = ClipLoadOptions { t_pose: LeadingTPose::Drop, ..Default::default() };
    let clip = load_clip(&data.join("bvh/cmu/16_01.bvh"), options).unwrap().value;
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
    let unedited = [GroundEdit::default(); 2];
    let base = EditSetup { edits: &unedited, ..setup };
    let grid = |count: usize| FamilySpec {
        kind: FamilyKind::Grid,
        stage: 1,
        axes: vec![AxisSweep { from: -0.2, to: 0.2, count }; 2],
    };
    group.bench_function("16_01 family 5x5 grid", |b| {
        b.iter(|| black_box(populate(base, &grid(5), &SolveOptions::default()).unwrap().family.solved_count()))
    });
    let family = populate(base, &grid(2), &SolveOptions::default()).unwrap().family;
    assert_eq!(family.solved_count(), 4, "{:?}", family.summary());
    group.sample_size(50);
    group.bench_function("16_01 family blend, 322 frames", |b| {
        b.iter(|| black_box(blend_family(&family, &[0.05, -0.1]).unwrap().frame_count()))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
