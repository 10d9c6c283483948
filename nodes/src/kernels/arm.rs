//! A generated arm for skinning demos and tests: a four-joint chain (clavicle, upper arm,
//! forearm, hand) held out along +X, a closed tube mesh with a biceps swell on the front
//! (+Z), a flexing clip and a handful of sample poses. Simple shapes, made here, so the
//! skinning examples need no outside data.
//!
//! A kernel (a fixture shared as data): `generate.arm` outputs it, and the skinning, bar-net
//! and pose-space tests deform it.

use std::f32::consts::TAU;
use std::sync::Arc;

use glam::{Quat, Vec3};

use crate::model::{Clip, ClipError, ImportScale, Joint, Mesh, Skeleton};

/// Shoulder height of the arm (metres).
pub const SHOULDER_HEIGHT_M: f32 = 1.4;
/// Upper arm length, shoulder to elbow (metres).
pub const UPPER_ARM_M: f32 = 0.30;
/// Forearm length, elbow to wrist (metres).
pub const FOREARM_M: f32 = 0.27;
/// How far the mesh reaches past the wrist (metres).
const HAND_STUB_M: f32 = 0.06;
/// The shoulder joint's distance from the clavicle root (metres).
const CLAVICLE_M: f32 = 0.05;

/// The arm's skeleton: `clavicle` (root), `upper_arm` (shoulder), `forearm` (elbow),
/// `hand` (wrist), `hand_end` (end site). Rest pose straight along +X.
pub fn arm_skeleton() -> Result<Skeleton, crate::model::SkeletonError> {
    let mut end = Joint::new("hand_end", Some(3), Vec3::new(HAND_STUB_M, 0.0, 0.0));
    end.end_site = true;
    Skeleton::new(vec![
        Joint::new("clavicle", None, Vec3::new(0.0, SHOULDER_HEIGHT_M, 0.0)),
        Joint::new("upper_arm", Some(0), Vec3::new(CLAVICLE_M, 0.0, 0.0)),
        Joint::new("forearm", Some(1), Vec3::new(UPPER_ARM_M, 0.0, 0.0)),
        Joint::new("hand", Some(2), Vec3::new(FOREARM_M, 0.0, 0.0)),
        end,
    ])
}

/// Local rotations of one arm pose: `shoulder_rad` raises the arm (about +Z),
/// `elbow_rad` flexes the forearm forward towards +Z, `wrist_rad` twists the hand about
/// the forearm (X).
pub fn arm_pose(shoulder_rad: f32, elbow_rad: f32, wrist_rad: f32) -> [Quat; 5] {
    [
        Quat::IDENTITY,
        Quat::from_rotation_z(shoulder_rad),
        Quat::from_rotation_y(-elbow_rad),
        Quat::from_rotation_x(wrist_rad),
        Quat::IDENTITY,
    ]
}

/// A clip of the given `(shoulder, elbow, wrist)` poses (radians), one per frame.
pub fn arm_clip(poses: &[(f32, f32, f32)], fps: f64) -> Result<Clip, ClipError> {
    let skeleton = Arc::new(arm_skeleton()?);
    let offsets: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
    let rotations = poses.iter().flat_map(|&(s, e, w)| arm_pose(s, e, w)).collect();
    let translations = poses.iter().flat_map(|_| offsets.iter().copied()).collect();
    Clip::new(skeleton, fps, rotations, translations, ImportScale::METRES)
}

/// The flexing motion: the elbow bends from straight to 2.4 rad and back once, the
/// shoulder lifts and lowers, the wrist twists twice.
pub fn arm_flex_clip(frames: usize, fps: f64) -> Result<Clip, ClipError> {
    let poses: Vec<(f32, f32, f32)> = (0..frames)
        .map(|f| {
            let phase = TAU * f as f32 / frames.max(2).saturating_sub(1) as f32;
            (0.25 * phase.sin(), 1.2 * (1.0 - phase.cos()), 0.45 * (2.0 * phase).sin())
        })
        .collect();
    arm_clip(&poses, fps)
}

/// Eight sample poses `(shoulder, elbow, wrist)` spanning the flex clip's range: elbow
/// straight to 2.4 rad at two shoulder heights, wrists varied so the poses differ in every
/// joint (the weight fit and pose-space blending need that).
pub const SAMPLE_POSES: [(f32, f32, f32); 8] = [
    (0.0, 0.0, 0.0),
    (0.0, 0.8, 0.5),
    (0.0, 1.6, -0.5),
    (0.0, 2.4, 0.3),
    (0.25, 0.0, -0.4),
    (0.25, 0.8, 0.0),
    (0.25, 1.6, 0.4),
    (-0.25, 2.4, -0.3),
];

/// Radius (metres) of the arm at distance `x_m` from the shoulder along the arm, around
/// the angle `around_rad` (0 = +Z, the front): a tapering tube with a biceps swell on the
/// front of the upper arm.
fn arm_radius(x_m: f32, around_rad: f32) -> f32 {
    let length = UPPER_ARM_M + FOREARM_M + HAND_STUB_M;
    let base = 0.05 - 0.022 * (x_m / length).clamp(0.0, 1.0);
    let along = ((x_m - 0.05) / (UPPER_ARM_M - 0.1)).clamp(0.0, 1.0);
    let biceps = (std::f32::consts::PI * along).sin().powi(2) * around_rad.cos().max(0.0).powi(2);
    base + 0.012 * biceps
}

/// A closed tube around the arm's rest pose: `rings` rings of `segments` vertices from
/// the shoulder to past the wrist, and one cap vertex at each end. Counter-clockwise
/// outward-facing triangles; normals computed from them.
pub fn arm_mesh(rings: usize, segments: usize) -> Mesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let start = Vec3::new(CLAVICLE_M, SHOULDER_HEIGHT_M, 0.0);
    let length = UPPER_ARM_M + FOREARM_M + HAND_STUB_M;
    let mut positions = Vec::with_capacity(rings * segments + 2);
    for r in 0..rings {
        let x = length * r as f32 / (rings - 1) as f32;
        for s in 0..segments {
            let a = TAU * s as f32 / segments as f32;
            let radius = arm_radius(x, a);
            positions.push(start + Vec3::new(x, radius * a.sin(), radius * a.cos()));
        }
    }
    let cap_start = positions.len() as u32;
    positions.push(start);
    positions.push(start + Vec3::new(length, 0.0, 0.0));
    let index = |r: usize, s: usize| (r * segments + s % segments) as u32;
    let mut triangles = Vec::with_capacity(2 * rings * segments);
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (index(r, s), index(r, s + 1), index(r + 1, s + 1), index(r + 1, s));
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
        }
    }
    for s in 0..segments {
        triangles.push([cap_start, index(0, s), index(0, s + 1)]);
        triangles.push([cap_start + 1, index(rings - 1, s + 1), index(rings - 1, s)]);
    }
    let normals = Mesh::compute_normals(&positions, &triangles);
    Mesh { name: "arm".into(), positions, normals, uvs: None, triangles, ..Mesh::default() }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::model::forward_kinematics;

    #[test]
    fn the_mesh_is_closed_and_its_normals_point_outwards() {
        let mesh = arm_mesh(10, 8);
        assert_eq!(mesh.positions.len(), 82);
        // Closed: every edge is shared by exactly two triangles.
        let mut edges = std::collections::BTreeMap::new();
        for t in &mesh.triangles {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
                *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        assert!(edges.values().all(|&c| c == 2));
        for (p, n) in mesh.positions.iter().zip(&mesh.normals).take(80) {
            let axis_point = Vec3::new(p.x, SHOULDER_HEIGHT_M, 0.0);
            assert!(n.dot(*p - axis_point) > 0.0);
        }
    }

    #[test]
    fn flexing_the_elbow_by_a_right_angle_points_the_forearm_forward() {
        let clip = arm_clip(&[(0.0, std::f32::consts::FRAC_PI_2, 0.0)], 24.0).unwrap();
        let poses = forward_kinematics(&clip);
        let elbow = poses.position(0, 2);
        let wrist = poses.position(0, 3);
        assert!(((wrist - elbow) - Vec3::new(0.0, 0.0, FOREARM_M)).length() < 1e-5);
    }

    /// The memory estimate nodes check before building a mesh brackets what an arm mesh
    /// really holds (its buffers' bytes, counted here from the built mesh), to within 3×.
    #[test]
    fn the_mesh_memory_estimate_brackets_a_built_mesh() {
        let (rings, segments) = (40, 24);
        let mesh = arm_mesh(rings, segments);
        let held = mesh.positions.len() * 12
            + mesh.normals.len() * 12
            + mesh.uvs.as_ref().map_or(0, |u| u.len() * 8)
            + mesh.triangles.len() * 12;
        let estimate = Mesh::estimated_bytes(rings * segments + 2, 2 * rings * segments) as usize;
        assert!(estimate >= held && estimate <= 3 * held, "estimate {estimate} B, held {held} B");
    }
}
