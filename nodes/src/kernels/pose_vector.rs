//! A pose as a vector of joint rotations, the coordinates pose-space deformation
//! interpolates in. A kernel: the pose-space deformer and the bar-net deformer's driver
//! angle both read poses this way.

use glam::Vec3;

use crate::model::Skeleton;

/// A pose as one rotation vector per joint (axis × angle, radians) of the joint's local
/// rotation relative to its rest rotation. Roots count as zero: turning the whole body
/// does not change its shape.
pub fn pose_vector(skeleton: &Skeleton, rotations: &[glam::Quat]) -> Vec<Vec3> {
    skeleton
        .joints()
        .iter()
        .zip(rotations)
        .map(|(joint, q)| {
            if joint.parent.is_none() {
                return Vec3::ZERO;
            }
            let relative = joint.rest_rotation.inverse() * *q;
            let relative = if relative.w < 0.0 { -relative } else { relative };
            let (axis, angle) = relative.to_axis_angle();
            if angle.is_finite() && axis.is_finite() { axis * angle } else { Vec3::ZERO }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::kernels::arm::arm_clip;
    use glam::Quat;

    #[test]
    fn pose_vectors_ignore_the_root_and_measure_bends_in_radians() {
        let clip = arm_clip(&[(0.3, 1.1, -0.2)], 24.0).unwrap();
        let mut rotations = clip.frame_rotations(0).to_vec();
        rotations[0] = Quat::from_rotation_y(2.0);
        let p = pose_vector(clip.skeleton(), &rotations);
        assert_eq!(p[0], Vec3::ZERO);
        assert!(
            (p[1].length() - 0.3).abs() < 1e-5
                && (p[2].length() - 1.1).abs() < 1e-5
                && (p[3].length() - 0.2).abs() < 1e-5
        );
    }
}
