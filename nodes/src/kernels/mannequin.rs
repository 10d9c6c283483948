//! A small synthetic humanoid for demos and tests: a 1.7 m, 20-joint skeleton with a
//! swinging-limb cycle and a skinned box mesh. It is deliberately simple (sinusoids, not a
//! gait model) and exists so the project ships example data it made itself.
//!
//! A kernel (a fixture shared as data): `generate.mannequin` outputs it, and the gait
//! generator and the IK and body-role tests stand on its skeleton.

use std::f32::consts::TAU;
use std::sync::Arc;

use glam::{Mat4, Quat, Vec3};

use crate::model::{Clip, ClipError, ImportScale, Joint, Mesh, Skeleton, Skin};

/// (name, parent name, rest offset from the parent in metres; +Z forward, +X left).
const BONES: [(&str, &str, [f32; 3]); 20] = [
    ("Hips", "", [0.0, 0.95, 0.0]),
    ("Spine", "Hips", [0.0, 0.12, 0.0]),
    ("Chest", "Spine", [0.0, 0.2, 0.0]),
    ("Neck", "Chest", [0.0, 0.2, 0.0]),
    ("Head", "Neck", [0.0, 0.1, 0.0]),
    ("HeadTop", "Head", [0.0, 0.2, 0.0]),
    ("LeftArm", "Chest", [0.18, 0.17, 0.0]),
    ("LeftForeArm", "LeftArm", [0.0, -0.28, 0.0]),
    ("LeftHand", "LeftForeArm", [0.0, -0.25, 0.0]),
    ("RightArm", "Chest", [-0.18, 0.17, 0.0]),
    ("RightForeArm", "RightArm", [0.0, -0.28, 0.0]),
    ("RightHand", "RightForeArm", [0.0, -0.25, 0.0]),
    ("LeftUpLeg", "Hips", [0.09, -0.05, 0.0]),
    ("LeftLeg", "LeftUpLeg", [0.0, -0.42, 0.0]),
    ("LeftFoot", "LeftLeg", [0.0, -0.42, 0.0]),
    ("LeftToe", "LeftFoot", [0.0, -0.06, 0.14]),
    ("RightUpLeg", "Hips", [-0.09, -0.05, 0.0]),
    ("RightLeg", "RightUpLeg", [0.0, -0.42, 0.0]),
    ("RightFoot", "RightLeg", [0.0, -0.42, 0.0]),
    ("RightToe", "RightFoot", [0.0, -0.06, 0.14]),
];

/// The mannequin's skeleton (metres, Y up, facing +Z).
pub fn mannequin_skeleton() -> Result<Skeleton, crate::model::SkeletonError> {
    let joints = BONES
        .iter()
        .map(|(name, parent, offset)| {
            let parent = BONES.iter().position(|(n, _, _)| n == parent);
            Joint::new(*name, parent, Vec3::from(*offset))
        })
        .collect();
    Skeleton::new(joints)
}

/// `cycles` swing cycles over `frames` frames at `fps`, travelling forward (+Z) at
/// `speed_m_per_s`.
pub fn mannequin_clip(frames: usize, fps: f64, cycles: f32, speed_m_per_s: f32) -> Result<Clip, ClipError> {
    let skeleton = Arc::new(mannequin_skeleton()?);
    let index = |name: &str| skeleton.index_of(name).unwrap_or(0);
    let (l_up, r_up, l_knee, r_knee) = (index("LeftUpLeg"), index("RightUpLeg"), index("LeftLeg"), index("RightLeg"));
    let (l_arm, r_arm, l_elbow, r_elbow) =
        (index("LeftArm"), index("RightArm"), index("LeftForeArm"), index("RightForeArm"));
    let mut rotations = Vec::with_capacity(frames * skeleton.len());
    let mut translations = Vec::with_capacity(frames * skeleton.len());
    for f in 0..frames {
        let t_secs = f as f32 / fps as f32;
        let phase = TAU * cycles * f as f32 / frames.max(1) as f32;
        let swing = 0.45 * phase.sin();
        let mut frame_rotations = vec![Quat::IDENTITY; skeleton.len()];
        let mut frame_translations: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
        // Legs swing in opposition about X; knees bend on the back swing only.
        frame_rotations[l_up] = Quat::from_rotation_x(-swing);
        frame_rotations[r_up] = Quat::from_rotation_x(swing);
        frame_rotations[l_knee] = Quat::from_rotation_x(0.6 * (-phase.cos()).max(0.0));
        frame_rotations[r_knee] = Quat::from_rotation_x(0.6 * phase.cos().max(0.0));
        // Arms counter-swing, hanging slightly away from the body; elbows stay bent.
        frame_rotations[l_arm] = Quat::from_rotation_z(0.15) * Quat::from_rotation_x(0.6 * swing);
        frame_rotations[r_arm] = Quat::from_rotation_z(-0.15) * Quat::from_rotation_x(-0.6 * swing);
        frame_rotations[l_elbow] = Quat::from_rotation_x(-0.3);
        frame_rotations[r_elbow] = Quat::from_rotation_x(-0.3);
        // The hips bob twice per cycle and travel forward.
        frame_translations[0] = Vec3::new(0.0, 0.95 + 0.02 * (2.0 * phase).cos(), speed_m_per_s * t_secs);
        rotations.extend(frame_rotations);
        translations.extend(frame_translations);
    }
    Clip::new(skeleton, fps, rotations, translations, ImportScale::METRES)
}

/// A box of half-width `radius` (metres) around every bone (joint to child), each rigidly
/// skinned to its joint, in the rest pose.
pub fn mannequin_mesh(skeleton: Arc<Skeleton>, radius: f32) -> Mesh {
    let rest = skeleton.rest_positions();
    let mut mesh = Mesh { name: "mannequin".into(), uvs: Some(Vec::new()), ..Mesh::default() };
    let mut joints = Vec::new();
    for (child, joint) in skeleton.joints().iter().enumerate() {
        let Some(parent) = joint.parent else { continue };
        let (a, b) = (rest[parent], rest[child]);
        let Some(axis) = (b - a).try_normalize() else { continue };
        let side = axis.any_orthonormal_vector() * radius;
        let up = axis.cross(side);
        // Eight corners, then four vertices per face so each face has its own normal.
        let corner = |i: usize| {
            let end = if i & 4 == 0 { a } else { b };
            end + if i & 1 == 0 { -side } else { side } + if i & 2 == 0 { -up } else { up }
        };
        mesh.push_box(corner);
        joints.extend([[parent as u16, 0, 0, 0]; 24]);
    }
    let inverse_bind_matrices = rest.iter().map(|p| Mat4::from_translation(-*p)).collect();
    let weights = vec![[1.0, 0.0, 0.0, 0.0]; joints.len()];
    mesh.skin = Some(Skin { skeleton, joints, weights, inverse_bind_matrices });
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::forward_kinematics;

    #[test]
    fn rest_pose_is_human_sized_and_feet_touch_the_ground() {
        let s = mannequin_skeleton().unwrap();
        let rest = s.rest_positions();
        let head_top = rest[s.index_of("HeadTop").unwrap()].y;
        assert!((head_top - 1.77).abs() < 1e-5, "{head_top}");
        let foot = rest[s.index_of("LeftFoot").unwrap()].y;
        assert!(foot.abs() < 0.07);
    }

    #[test]
    fn the_clip_travels_at_the_given_speed_and_legs_alternate() {
        let clip = mannequin_clip(48, 24.0, 1.0, 1.2).unwrap();
        let roots: Vec<Vec3> = clip.root_translations().collect();
        assert!((roots[47].z - 1.2 * 47.0 / 24.0).abs() < 1e-5);
        let poses = forward_kinematics(&clip);
        let (l, r) = (clip.skeleton().index_of("LeftFoot").unwrap(), clip.skeleton().index_of("RightFoot").unwrap());
        // A quarter cycle in, the feet are on opposite sides of the hips.
        let f = 12;
        let hips = poses.position(f, 0).z;
        assert!((poses.position(f, l).z - hips) * (poses.position(f, r).z - hips) < 0.0);
    }

    #[test]
    fn mesh_is_rigidly_skinned_and_bind_pose_skinning_is_identity() {
        let s = Arc::new(mannequin_skeleton().unwrap());
        let mesh = mannequin_mesh(s.clone(), 0.04);
        assert_eq!(mesh.positions.len(), 19 * 24);
        assert_eq!(mesh.triangles.len(), 19 * 12);
        let skin = mesh.skin.as_ref().unwrap();
        let rest = Clip::rest_pose(s, 24.0, 1).unwrap();
        let world = forward_kinematics(&rest);
        for (v, p) in mesh.positions.iter().enumerate() {
            let j = skin.joints[v][0] as usize;
            let skinned = world.frame(0)[j].to_mat4() * skin.inverse_bind_matrices[j] * p.extend(1.0);
            assert!((skinned.truncate() - *p).length() < 1e-6);
        }
        assert!(mesh.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
    }
}
