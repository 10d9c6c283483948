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

/// The pose vector of one frame (the kernel's representation: each joint's rotation
/// vector from its rest rotation, the root's zero), in f64.
fn pose_of(skeleton: &kinegraph_nodes::model::Skeleton, rotations: &[glam::Quat]) -> Vec<glam::DVec3> {
    kinegraph_nodes::kernels::pose_vector::pose_vector(skeleton, rotations).iter().map(|v| v.as_dvec3()).collect()
}

/// Rhee et al.'s WPSD, the paper's equations evaluated here in f64 with nalgebra, vertex by
/// vertex: the displacements d_k = (Σ w T_k)⁻¹ v_k − v₀ of the samples, the vertex's
/// distance γ(p, p_k) = √(Σ_j w_j ‖p_j − p_kj‖²) with its own skinning weights w_j
/// (`PoseDistance::JointWeight`; all w_j = 1 is PSD), Gaussians of width σ = the mean
/// distance between samples, the RBF interpolation Φ c = D, and v = (Σ w T)(v₀ + Σ_k c_k
/// φ_k(p)). `deform` agrees at held-out frames of the flex clip, for both distances, and
/// the two distances differ there by more than that agreement.
#[test]
fn wpsd_and_psd_follow_the_papers_equations_evaluated_by_hand() {
    use kinegraph_nodes::kernels::skinning::{blend_matrices, clip_skinning_matrices};
    use nalgebra::{DMatrix, DVector};
    let (mesh, samples, truth) = arm_truth();
    let skin = mesh.skin.as_ref().unwrap();
    let skeleton = samples.clip.skeleton();
    let k = samples.frame_count();
    let sample_poses: Vec<Vec<glam::DVec3>> =
        (0..k).map(|f| pose_of(skeleton, samples.clip.frame_rotations(f))).collect();
    let sample_matrices = clip_skinning_matrices(&samples.clip, skin);
    let frame_matrices = clip_skinning_matrices(&truth.clip, skin);
    let joints = skeleton.len();
    let vertices: Vec<usize> = (0..mesh.positions.len()).step_by(3).collect();
    let frames = [5, 13, 22, 31];
    let mut largest_gap = 0.0f64;
    let mut outputs = Vec::new();
    for (distance, paper) in [(PoseDistance::JointWeight, true), (PoseDistance::Uniform, false)] {
        let out = deform(&mesh, &truth.clip, Some(&samples), method(distance)).unwrap();
        let mut worst = 0.0f64;
        for &v in &vertices {
            let v0 = mesh.positions[v].as_dvec3();
            let (vj, vw) = (skin.joints[v], skin.weights[v]);
            let weight_of = |j: usize| -> f64 {
                if !paper {
                    return 1.0;
                }
                vj.iter().zip(vw).filter(|(jj, _)| usize::from(**jj) == j).map(|(_, w)| f64::from(w)).sum()
            };
            let gamma = |a: &[glam::DVec3], b: &[glam::DVec3]| {
                (0..joints).map(|j| weight_of(j) * (a[j] - b[j]).length_squared()).sum::<f64>().sqrt()
            };
            let mut d = DMatrix::<f64>::zeros(k, 3);
            for s in 0..k {
                let blend = blend_matrices(&sample_matrices[s * joints..(s + 1) * joints], &vj, &vw);
                let back = blend.inverse().transform_point3(samples.frame_positions(s)[v]).as_dvec3() - v0;
                for c in 0..3 {
                    d[(s, c)] = back[c];
                }
            }
            let distances = DMatrix::from_fn(k, k, |a, b| gamma(&sample_poses[a], &sample_poses[b]));
            let sigma = distances.sum() / (k * (k - 1)) as f64;
            let phi = |g: f64| (-g * g / (2.0 * sigma * sigma)).exp();
            let big_phi = DMatrix::from_fn(k, k, |a, b| phi(distances[(a, b)]) + if a == b { 1e-9 } else { 0.0 });
            let c = big_phi.lu().solve(&d).unwrap();
            for &f in &frames {
                let pose = pose_of(skeleton, truth.clip.frame_rotations(f));
                let weights = DVector::from_fn(k, |s, _| phi(gamma(&pose, &sample_poses[s])));
                let disp = c.transpose() * weights;
                let rest = v0 + glam::DVec3::new(disp[0], disp[1], disp[2]);
                let blend = blend_matrices(&frame_matrices[f * joints..(f + 1) * joints], &vj, &vw);
                let expected = blend.transform_point3(rest.as_vec3()).as_dvec3();
                worst = worst.max((out.frame_positions(f)[v].as_dvec3() - expected).length());
            }
        }
        eprintln!("{distance:?}: largest difference from the equations {worst:.2e} m over {} vertices", vertices.len());
        assert!(worst < 1e-5, "{distance:?}: {worst} m");
        largest_gap = largest_gap.max(worst);
        outputs.push(out);
    }
    let apart = frames
        .iter()
        .flat_map(|&f| vertices.iter().map(move |&v| (f, v)))
        .map(|(f, v)| f64::from((outputs[0].frame_positions(f)[v] - outputs[1].frame_positions(f)[v]).length()))
        .fold(0.0, f64::max);
    eprintln!("WPSD and PSD apart by up to {apart:.2e} m");
    assert!(apart > 100.0 * largest_gap.max(1e-7), "{apart}");
}
