//! Forward kinematics: local joint transforms to world transforms for whole clips.

use glam::{Mat4, Quat, Vec3};

use super::clip::Clip;
use super::skeleton::Skeleton;

/// A rigid transform (rotation then translation), metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rotation part.
    pub rotation: Quat,
    /// Translation part (metres).
    pub translation: Vec3,
}

impl Transform {
    /// The identity transform.
    pub const IDENTITY: Transform = Transform { rotation: Quat::IDENTITY, translation: Vec3::ZERO };

    /// `self ∘ child`: applies `child` first, then `self`.
    #[inline]
    pub fn compose(&self, child_rotation: Quat, child_translation: Vec3) -> Transform {
        Transform {
            rotation: self.rotation * child_rotation,
            translation: self.translation + self.rotation * child_translation,
        }
    }

    /// Maps a point through this transform.
    #[inline]
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.translation + self.rotation * p
    }

    /// The equivalent 4×4 matrix.
    pub fn to_mat4(&self) -> Mat4 {
        Mat4::from_rotation_translation(self.rotation, self.translation)
    }

    /// The inverse transform as an exactly affine 4×4 matrix (last row exactly 0, 0, 0, 1):
    /// an inverse bind matrix as glTF requires it. Inverting the rigid transform first, not
    /// the general matrix, keeps rounding out of that row.
    pub fn inverse_to_mat4(&self) -> Mat4 {
        let inverse = self.rotation.inverse();
        Mat4::from_rotation_translation(inverse, -(inverse * self.translation))
    }
}

/// World transforms of every joint at every frame of a clip, frame-major.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipPoses {
    joints: usize,
    world_from_joint: Vec<Transform>,
}

impl ClipPoses {
    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.world_from_joint.len().checked_div(self.joints).unwrap_or(0)
    }

    /// World transforms of every joint at `frame`.
    pub fn frame(&self, frame: usize) -> &[Transform] {
        &self.world_from_joint[frame * self.joints..(frame + 1) * self.joints]
    }

    /// World position (metres) of `joint` at `frame`.
    pub fn position(&self, frame: usize, joint: usize) -> Vec3 {
        self.world_from_joint[frame * self.joints + joint].translation
    }
}

/// Computes world transforms for one frame's local transforms into `out`.
/// All three slices have one entry per joint, parents before children.
#[inline]
pub fn pose_world(skeleton: &Skeleton, rotations: &[Quat], translations: &[Vec3], out: &mut [Transform]) {
    for (j, joint) in skeleton.joints().iter().enumerate() {
        let parent = match joint.parent {
            Some(p) => out[p],
            None => Transform::IDENTITY,
        };
        out[j] = parent.compose(rotations[j], translations[j]);
    }
}

/// World transforms of every joint in the skeleton's rest pose (offsets and rest
/// rotations only).
pub fn rest_world(skeleton: &Skeleton) -> Vec<Transform> {
    let rotations: Vec<Quat> = skeleton.joints().iter().map(|j| j.rest_rotation).collect();
    let translations: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
    let mut out = vec![Transform::IDENTITY; skeleton.len()];
    pose_world(skeleton, &rotations, &translations, &mut out);
    out
}

/// Forward kinematics for the whole clip: world transform of every joint at every frame.
pub fn forward_kinematics(clip: &Clip) -> ClipPoses {
    let joints = clip.joint_count();
    let mut world_from_joint = vec![Transform::IDENTITY; joints * clip.frame_count()];
    for (frame, out) in world_from_joint.chunks_exact_mut(joints).enumerate() {
        pose_world(clip.skeleton(), clip.frame_rotations(frame), clip.frame_translations(frame), out);
    }
    ClipPoses { joints, world_from_joint }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::math::EXACT_TOL;
    use crate::model::skeleton::Joint;
    use crate::model::units::ImportScale;

    /// A planar two-link arm: the tip position has the closed form
    /// (l1 cos a + l2 cos(a+b), l1 sin a + l2 sin(a+b)).
    #[test]
    fn two_link_arm_matches_closed_form() {
        let (l1, l2) = (0.3f32, 0.25f32);
        let skeleton = Arc::new(
            Skeleton::new(vec![
                Joint::new("shoulder", None, Vec3::ZERO),
                Joint::new("elbow", Some(0), Vec3::new(l1, 0.0, 0.0)),
                Joint::new("hand", Some(1), Vec3::new(l2, 0.0, 0.0)),
            ])
            .unwrap(),
        );
        let angles = [(0.0f32, 0.0f32), (0.7, -1.2), (2.5, 0.4)];
        let mut rotations = Vec::new();
        let mut translations = Vec::new();
        for (a, b) in angles {
            rotations.extend([Quat::from_rotation_z(a), Quat::from_rotation_z(b), Quat::IDENTITY]);
            translations.extend(skeleton.joints().iter().map(|j| j.rest_offset));
        }
        let clip = Clip::new(skeleton, 30.0, rotations, translations, ImportScale::METRES).unwrap();
        let poses = forward_kinematics(&clip);
        for (f, (a, b)) in angles.iter().enumerate() {
            let expected = Vec3::new(l1 * a.cos() + l2 * (a + b).cos(), l1 * a.sin() + l2 * (a + b).sin(), 0.0);
            assert!((poses.position(f, 2) - expected).length() < EXACT_TOL, "frame {f}");
        }
        assert_eq!(poses.frame_count(), 3);
    }

    #[test]
    fn zero_length_bones_stay_finite() {
        let skeleton = Arc::new(
            Skeleton::new(vec![Joint::new("a", None, Vec3::ZERO), Joint::new("b", Some(0), Vec3::ZERO)]).unwrap(),
        );
        let clip = Clip::rest_pose(skeleton, 24.0, 2).unwrap();
        let poses = forward_kinematics(&clip);
        assert!(poses.frame(1).iter().all(|t| t.translation.is_finite() && t.rotation.is_finite()));
    }
}
