//! The solvers that run per frame allocate nothing once set up (issue 23): a counting
//! global allocator (the `allocation-counter` crate, per thread) around a weighted IK solve
//! with one and with several effectors, around frames of online retargeting, and around
//! PSD and WPSD frames (Rhee et al.) on the bar-net arm.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use glam::{DVec3, Quat, Vec3};
use kinegraph_nodes::builtin::barnet::{LoadParams, Selection, build, deform_net};
use kinegraph_nodes::builtin::ik::retarget::{OnlineRetargeter, RetargetParams};
use kinegraph_nodes::builtin::pose_space::{PoseDistance, PoseSpaceModel, PoseSpaceParams};
use kinegraph_nodes::kernels::arm::{SAMPLE_POSES, arm_clip, arm_flex_clip, arm_mesh};
use kinegraph_nodes::kernels::ik::{IkPose, IkRig, IkSolver, SolveParams};
use kinegraph_nodes::kernels::pose_vector::pose_vector;
use kinegraph_nodes::kernels::skinning::{AutoWeightParams, BindMode, bind, clip_skinning_matrices};
use kinegraph_nodes::model::{Joint, Skeleton};

/// A pelvis with a root translation and two 6-DOF legs; the toes are effectors
/// (`both_feet`) or only the left one.
fn legs(both_feet: bool) -> IkRig {
    let mut joints = vec![Joint::new("pelvis", None, Vec3::new(0.0, 0.9, 0.0))];
    for (side, x) in [("l", 0.1), ("r", -0.1)] {
        let hip = joints.len();
        joints.push(Joint::new(format!("hip_{side}"), Some(0), Vec3::new(x, 0.0, 0.0)));
        joints.push(Joint::new(format!("knee_{side}"), Some(hip), Vec3::new(0.0, -0.45, 0.0)));
        joints.push(Joint::new(format!("ankle_{side}"), Some(hip + 1), Vec3::new(0.0, -0.42, 0.0)));
        joints.push(Joint::new(format!("toe_{side}"), Some(hip + 2), Vec3::new(0.0, -0.05, 0.15)));
    }
    let mut rig = IkRig::new(Arc::new(Skeleton::new(joints).unwrap()));
    rig.add_root_translation(0.3);
    for hip in [1, 5] {
        rig.add_joint(hip, [true; 3], 1.0);
        rig.add_joint(hip + 1, [true, false, false], 1.0);
        rig.add_joint(hip + 2, [true, false, true], 0.5);
    }
    rig.add_effector(4);
    if both_feet {
        rig.add_effector(8);
    }
    rig.finish().unwrap()
}

/// Reachable toe goals around the rest pose at phase `t` (radians of a stride).
fn goals(t: f64, both_feet: bool) -> Vec<DVec3> {
    let left = DVec3::new(0.1 + 0.03 * t.sin(), 0.1 + 0.05 * t.cos(), 0.15 + 0.2 * t.sin());
    let right = DVec3::new(-0.1 - 0.02 * t.cos(), 0.08 + 0.04 * t.sin(), 0.15 - 0.2 * t.sin());
    if both_feet { vec![left, right] } else { vec![left] }
}

fn rest_pose(rig: &IkRig) -> IkPose {
    let rest: Vec<Vec3> = rig.skeleton().joints().iter().map(|j| j.rest_offset).collect();
    rig.pose_from(&vec![Quat::IDENTITY; rest.len()], &rest)
}

fn solve_allocations(both_feet: bool) -> (u64, usize) {
    let rig = legs(both_feet);
    let start = rest_pose(&rig);
    let mut solver = IkSolver::new(rig);
    let mut pose = start.clone();
    // The first solve makes the solver's scratch pose; from then on nothing is allocated.
    solver.solve(&mut pose, &goals(0.0, both_feet), &SolveParams::default());
    let all_goals: Vec<Vec<DVec3>> = (1..40).map(|i| goals(i as f64 * 0.37, both_feet)).collect();
    let mut converged = 0;
    let info = allocation_counter::measure(|| {
        for g in &all_goals {
            pose.clone_from(&start);
            converged += usize::from(solver.solve(&mut pose, g, &SolveParams::default()).converged);
        }
    });
    (info.count_total, converged)
}

#[test]
fn weighted_ik_with_one_effector_allocates_nothing_per_solve() {
    let (allocations, converged) = solve_allocations(false);
    assert_eq!(converged, 39, "the goals are reachable, so the solves did real work");
    assert_eq!(allocations, 0);
}

#[test]
fn weighted_ik_with_two_effectors_allocates_nothing_per_solve() {
    let (allocations, converged) = solve_allocations(true);
    assert_eq!(converged, 39, "the goals are reachable, so the solves did real work");
    assert_eq!(allocations, 0);
}

#[test]
fn online_retargeting_allocates_nothing_per_frame() {
    let rig = legs(true);
    let source = rest_pose(&rig);
    let mut filter = OnlineRetargeter::new(rig, source.clone(), RetargetParams::default());
    filter.step(&source, &goals(0.0, true));
    // A stride over 120 frames: goals move about 1 cm per frame, as a walk's toes do at 30 fps.
    let frames: Vec<Vec<DVec3>> = (1..120).map(|i| goals(i as f64 * 0.05, true)).collect();
    let mut worst = 0.0f64;
    let info = allocation_counter::measure(|| {
        for g in &frames {
            worst = worst.max(filter.step(&source, g).error_m);
        }
    });
    assert!(worst < 0.02, "the filter tracked the goals (worst {worst} m), so the frames did real work");
    assert_eq!(info.count_total, 0);
}

#[test]
fn psd_and_wpsd_frames_allocate_nothing() {
    // The benchmark's arm (200 rings × 32 segments + 2 caps = 6,402 vertices here), 8 bar-net bulge samples, a flexing clip.
    let clip = arm_flex_clip(12, 24.0).unwrap();
    let mesh =
        Arc::new(bind(&arm_mesh(200, 32), clip.skeleton(), BindMode::Automatic, AutoWeightParams::default()).unwrap());
    let skin = mesh.skin.as_ref().unwrap();
    let biceps = Selection::Box(Vec3::new(0.11, 1.34, 0.012), Vec3::new(0.31, 1.46, 0.1));
    let net = build(mesh.clone(), &biceps, 1.0, 1.0).unwrap();
    let loads = LoadParams { driver: Some(2), ramp_start_rad: 0.2, ramp_full_rad: 2.0, bulge_n: 0.05, pressure_n: 0.0 };
    let samples = deform_net(&net, &Arc::new(arm_clip(&SAMPLE_POSES, 24.0).unwrap()), &loads).unwrap();
    let joints = clip.joint_count();
    let matrices = clip_skinning_matrices(&clip, skin);
    let poses: Vec<Vec<Vec3>> =
        (0..clip.frame_count()).map(|f| pose_vector(clip.skeleton(), clip.frame_rotations(f))).collect();
    // One worker, the test's own thread: the per-thread counter then sees all the work.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).use_current_thread().build().unwrap();
    let seen = allocation_counter::measure(|| {
        pool.install(|| {
            use rayon::prelude::*;
            (0..4).into_par_iter().for_each(|i| drop(std::hint::black_box(vec![i as u8; 16])));
        })
    });
    assert_eq!(seen.count_total, 4, "allocations inside the pool's parallel loops are counted");
    let psd = PoseSpaceParams { distance: PoseDistance::Uniform, ..PoseSpaceParams::default() };
    for (name, params) in [("PSD", psd), ("WPSD", PoseSpaceParams::default())] {
        let model = PoseSpaceModel::train(&mesh, &samples, params).unwrap();
        let mut scratch = model.scratch(mesh.positions.len());
        let mut out = vec![Vec3::ZERO; mesh.positions.len()];
        let mut moved = 0.0f32;
        let info = allocation_counter::measure(|| {
            pool.install(|| {
                for (f, pose) in poses.iter().enumerate() {
                    let m = &matrices[f * joints..(f + 1) * joints];
                    model.deform_frame(&mesh, skin, pose, m, &mut out, &mut scratch);
                    moved = moved.max(out.iter().zip(&mesh.positions).map(|(a, b)| a.distance(*b)).fold(0.0, f32::max));
                }
            })
        });
        assert!(moved > 0.05, "{name}: the arm flexed ({moved} m), so the frames did real work");
        assert_eq!(info.count_total, 0, "{name}");
    }
}
