//! Weighted IK solves of a 6-DOF leg to 1e-4 m, procedural walks of the mannequin (frames
//! made per second, legs by weighted IK), and online retargeting of a real CMU walk onto a
//! 60 % skeleton (full body: feet and hands tracked).
//! Run: `cargo bench -p kinegraph-nodes --bench ik`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{DVec3, Quat, Vec3};
use kinegraph_nodes::builtin::clip_edit::trim;
use kinegraph_nodes::builtin::ik::gait::{GaitParams, GaitPreset, procedural_gait};
use kinegraph_nodes::builtin::ik::retarget::{Effectors, RetargetParams, retarget_clip};
use kinegraph_nodes::builtin::ik::scale::{parse_rules, scale_clip};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::body::find_landmarks;
use kinegraph_nodes::kernels::contacts::{ContactThresholds, detect_contacts};
use kinegraph_nodes::kernels::ik::{IkRig, IkSolver, SolveParams};
use kinegraph_nodes::kernels::mannequin::mannequin_skeleton;
use kinegraph_nodes::model::{Joint, Skeleton, forward_kinematics};
use kinegraph_nodes::node::Choice;

/// Hip (3 DOFs), knee (1), ankle (2): a 6-DOF leg.
fn leg() -> IkRig {
    let skeleton = Arc::new(
        Skeleton::new(vec![
            Joint::new("hip", None, Vec3::new(0.0, 0.9, 0.0)),
            Joint::new("knee", Some(0), Vec3::new(0.0, -0.45, 0.0)),
            Joint::new("ankle", Some(1), Vec3::new(0.0, -0.42, 0.0)),
            Joint::new("toe", Some(2), Vec3::new(0.0, -0.05, 0.15)),
        ])
        .unwrap(),
    );
    let mut rig = IkRig::new(skeleton);
    rig.add_joint(0, [true; 3], 1.0);
    rig.add_joint(1, [true, false, false], 1.0);
    rig.add_joint(2, [true, false, true], 1.0);
    rig.add_effector(3);
    rig.finish().unwrap()
}

fn bench(c: &mut Criterion) {
    let rig = leg();
    let rest: Vec<Vec3> = rig.skeleton().joints().iter().map(|j| j.rest_offset).collect();
    let start = rig.pose_from(&[Quat::IDENTITY; 4], &rest);
    let mut solver = IkSolver::new(rig);
    // 64 reachable goals around the foot's rest place (a swing's worth of positions).
    let goals: Vec<DVec3> = (0..64)
        .map(|i| {
            let t = i as f64 / 64.0 * std::f64::consts::TAU;
            DVec3::new(0.05 * t.sin(), 0.1 + 0.08 * (2.0 * t).cos(), 0.15 + 0.3 * t.cos())
        })
        .collect();
    let params = SolveParams::default();
    let mut pose = start.clone();
    let mut unconverged = 0;
    for g in &goals {
        pose.clone_from(&start);
        unconverged += usize::from(!solver.solve(&mut pose, &[*g], &params).converged);
    }
    assert_eq!(unconverged, 0, "every benchmark goal is reachable");
    let mut group = c.benchmark_group("ik");
    group.throughput(Throughput::Elements(goals.len() as u64));
    group.bench_function("leg_6dof_solve_1e-4m", |b| {
        b.iter(|| {
            for g in &goals {
                pose.clone_from(&start);
                black_box(solver.solve(&mut pose, &[*g], &params));
            }
        })
    });
    group.finish();

    let skeleton = Arc::new(mannequin_skeleton().unwrap());
    let mut group = c.benchmark_group("gait");
    for preset in [GaitPreset::Normal, GaitPreset::InjuredLeftLeg] {
        let params = GaitParams { legs: preset.legs(), ..GaitParams::default() };
        let frames = procedural_gait(&skeleton, &params).unwrap().clip.frame_count();
        group.throughput(Throughput::Elements(frames as u64));
        group.bench_function(format!("mannequin_{}_4s_30fps_frames", preset.name()), |b| {
            b.iter(|| black_box(procedural_gait(&skeleton, &params).unwrap()))
        });
    }
    group.finish();

    let Some(data) = shared_data() else { return };
    let (source, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    let source = trim(&source, 0.01, None).unwrap();
    let target = scale_clip(&source, 0.6, &parse_rules("UpLeg=0.62, Leg=0.52, Foot=0.7, Spine=0.65").unwrap()).unwrap();
    let contacts = detect_contacts(
        &source,
        &forward_kinematics(&source),
        &find_landmarks(source.skeleton()).unwrap(),
        &ContactThresholds::default(),
    );
    // The node's defaults (the paper's update and up to two chord corrections a frame), and
    // the paper's single update alone (`max_corrections: 0`).
    let params = RetargetParams { settle_iterations: 0, ..RetargetParams::default() };
    let single = RetargetParams { max_corrections: 0, ..params };
    let mut group = c.benchmark_group("retarget");
    group.throughput(Throughput::Elements(source.frame_count() as u64));
    group.sample_size(20);
    for (name, params) in [("cmu_02_01_full_body_frames", params), ("cmu_02_01_full_body_single_update_frames", single)]
    {
        group.bench_function(name, |b| {
            b.iter(|| {
                black_box(retarget_clip(&source, &target, Some(&contacts), Effectors::FeetAndHands, params).unwrap())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
