//! Pose-space deformation of the generated arm against bar-net ground truth: two node
//! families (`skin.deform` and `barnet.*`) compared, so the test lives outside both.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use glam::Vec3;
use kinegraph_nodes::builtin::barnet::{LoadParams, Selection, build, deform_net};
use kinegraph_nodes::builtin::pose_space::{DeformMethod, PoseDistance, PoseSpaceError, PoseSpaceParams, deform};
use kinegraph_nodes::kernels::arm::{SAMPLE_POSES, arm_clip, arm_flex_clip, arm_mesh};
use kinegraph_nodes::kernels::skinning::{AutoWeightParams, BindMode, bind};
use kinegraph_nodes::model::{Mesh, MeshSequence};

/// The bound arm, bar-net ground truth at the sample poses and along the flex clip.
fn arm_truth() -> (Arc<Mesh>, MeshSequence, MeshSequence) {
    let flex = Arc::new(arm_flex_clip(40, 24.0).unwrap());
    let mesh =
        Arc::new(bind(&arm_mesh(24, 12), flex.skeleton(), BindMode::Automatic, AutoWeightParams::default()).unwrap());
    let biceps = Selection::Box(Vec3::new(0.11, 1.34, 0.012), Vec3::new(0.31, 1.46, 0.1));
    let net = build(mesh.clone(), &biceps, 1.0, 1.0).unwrap();
    let loads = LoadParams { driver: Some(2), ramp_start_rad: 0.2, ramp_full_rad: 2.0, bulge_n: 0.05, pressure_n: 0.0 };
    let samples = deform_net(&net, &Arc::new(arm_clip(&SAMPLE_POSES, 24.0).unwrap()), &loads).unwrap();
    let truth = deform_net(&net, &flex, &loads).unwrap();
    (mesh, samples, truth)
}

fn max_error(a: &MeshSequence, b: &MeshSequence) -> f32 {
    a.positions_m().iter().zip(b.positions_m()).map(|(p, q)| (*p - *q).length()).fold(0.0, f32::max)
}

fn rms_error(a: &MeshSequence, b: &MeshSequence) -> f64 {
    let sum: f64 =
        a.positions_m().iter().zip(b.positions_m()).map(|(p, q)| f64::from((*p - *q).length_squared())).sum();
    (sum / a.positions_m().len() as f64).sqrt()
}

fn method(distance: PoseDistance) -> DeformMethod {
    DeformMethod::PoseSpace(PoseSpaceParams { distance, ..PoseSpaceParams::default() })
}

#[test]
fn psd_and_wpsd_reproduce_their_sample_poses() {
    let (mesh, samples, _) = arm_truth();
    for distance in [PoseDistance::Uniform, PoseDistance::JointWeight, PoseDistance::JointAndChildren] {
        let out = deform(&mesh, &samples.clip, Some(&samples), method(distance)).unwrap();
        let err = max_error(&out, &samples);
        assert!(err < 1e-4, "{distance:?}: {err} m");
    }
    // PCA keeping K − 1 components spans the centred displacements: still exact.
    let params = PoseSpaceParams { principal_poses: SAMPLE_POSES.len() - 1, ..PoseSpaceParams::default() };
    let out = deform(&mesh, &samples.clip, Some(&samples), DeformMethod::PoseSpace(params)).unwrap();
    assert!(max_error(&out, &samples) < 1e-4);
}

#[test]
fn wpsd_generalises_better_than_psd_at_held_out_poses() {
    let (mesh, samples, truth) = arm_truth();
    let lbs = deform(&mesh, &truth.clip, None, DeformMethod::Lbs).unwrap();
    let psd = deform(&mesh, &truth.clip, Some(&samples), method(PoseDistance::Uniform)).unwrap();
    let wpsd = deform(&mesh, &truth.clip, Some(&samples), method(PoseDistance::JointAndChildren)).unwrap();
    let (e_lbs, e_psd, e_wpsd) = (rms_error(&lbs, &truth), rms_error(&psd, &truth), rms_error(&wpsd, &truth));
    eprintln!("held-out RMS error: LBS {e_lbs:.5} m, PSD {e_psd:.5} m, WPSD {e_wpsd:.5} m");
    assert!(e_wpsd < e_psd, "WPSD {e_wpsd} vs PSD {e_psd}");
    assert!(e_psd < e_lbs, "PSD {e_psd} vs LBS {e_lbs}");
}

#[test]
fn pose_space_refuses_mismatched_samples() {
    let (mesh, samples, _) = arm_truth();
    let small = Arc::new(
        bind(&arm_mesh(4, 4), samples.clip.skeleton(), BindMode::Automatic, AutoWeightParams::default()).unwrap(),
    );
    assert!(matches!(
        deform(&small, &samples.clip, Some(&samples), method(PoseDistance::Uniform)),
        Err(PoseSpaceError::Samples(_))
    ));
    assert!(deform(&mesh, &samples.clip, None, method(PoseDistance::Uniform)).is_err());
}
