//! Spatial alignment of a second motion to a first (Shum et al. 2009, eq. 2): turn it about
//! the vertical axis so the mean angular momenta agree (forward rule) or oppose (reverse
//! rule), then slide it so the centres of the feet coincide where the blend starts.
//!
//! A kernel: both joins (the momentum method and the baseline crossfade) align with it.

use glam::{DVec3, Quat, Vec3};

use super::body::Landmarks;
use crate::model::choice::choices;
use crate::model::{Clip, ClipError, ClipPoses};

/// Which of the paper's two transition rules applies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rule {
    /// Same direction of rotation: the second motion keeps the first one's momentum going.
    Forward,
    /// Opposite directions: the end of the first motion winds up the second.
    Reverse,
}

choices!(Rule { Forward = "forward", Reverse = "reverse" });

/// The yaw θ (radians about +Y) that maximises (forward) or minimises (reverse)
/// `l1 · R_y(θ) l2`. In closed form: with horizontal parts a = l1, b = l2,
/// a·R_y(θ)b = cos θ (a·b) + sin θ (a_x b_z − a_z b_x) + a_y b_y, whose maximum sits at
/// θ = atan2(a_x b_z − a_z b_x, a·b); the minimum half a turn away.
pub fn alignment_yaw(l1: DVec3, l2: DVec3, rule: Rule) -> f64 {
    let sin_part = l1.x * l2.z - l1.z * l2.x;
    let cos_part = l1.x * l2.x + l1.z * l2.z;
    let best = sin_part.atan2(cos_part);
    match rule {
        Rule::Forward => best,
        Rule::Reverse => wrap_angle(best + std::f64::consts::PI),
    }
}

/// `angle` wrapped into (−π, π].
pub fn wrap_angle(angle: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let a = angle.rem_euclid(tau);
    if a > std::f64::consts::PI { a - tau } else { a }
}

/// The rotation about +Y by `yaw` radians.
pub fn yaw_rotation(yaw: f64) -> Quat {
    Quat::from_rotation_y(yaw as f32)
}

/// Horizontal facing of the torso at `frame` (unit, y = 0): perpendicular to the line from
/// the right to the left hip and shoulder, pointing forward. `None` when degenerate.
pub fn torso_facing(poses: &ClipPoses, frame: usize, landmarks: &Landmarks) -> Option<Vec3> {
    let [lh, rh] = landmarks.hips();
    let [ls, rs] = landmarks.shoulders();
    let p = |j| poses.position(frame, j);
    let across = (p(lh) - p(rh)) + (p(ls) - p(rs));
    // Left × up = forward for a right-handed, Y-up character facing +Z with left at +X.
    Vec3::new(across.x, 0.0, across.z).cross(Vec3::Y).try_normalize()
}

/// Whether the torso (mid-hip to neck) is within 60° of upright at `frame`, so that its
/// facing on the ground means something.
pub fn torso_upright(poses: &ClipPoses, frame: usize, landmarks: &Landmarks) -> bool {
    let [lh, rh] = landmarks.hips();
    let mid_hip = (poses.position(frame, lh) + poses.position(frame, rh)) * 0.5;
    (poses.position(frame, landmarks.neck) - mid_hip).try_normalize().is_some_and(|up| up.y > 0.5)
}

/// Orientation of the torso at `frame`: x from the right to the left hip and shoulder, y
/// from the middle of the hips to the neck (made perpendicular), z = x × y (forward).
/// `None` when degenerate.
pub fn torso_orientation(poses: &ClipPoses, frame: usize, landmarks: &Landmarks) -> Option<Quat> {
    let [lh, rh] = landmarks.hips();
    let [ls, rs] = landmarks.shoulders();
    let p = |j| poses.position(frame, j);
    let left = ((p(lh) - p(rh)) + (p(ls) - p(rs))).try_normalize()?;
    let up = (p(landmarks.neck) - (p(lh) + p(rh)) * 0.5).reject_from_normalized(left).try_normalize()?;
    let forward = left.cross(up);
    Some(crate::math::quat_normalize_or_identity(Quat::from_mat3(&glam::Mat3::from_cols(left, up, forward))))
}

/// How far apart two torsos face, radians, and what was compared: `b` at frame `g` is
/// turned by `turn` first. The paper compares torso facings projected on the ground; a body
/// far from upright (on its hands in a cartwheel) has no such facing, so there the whole
/// torso orientations are compared instead.
pub fn facing_difference(
    (poses_a, landmarks_a, f): (&ClipPoses, &Landmarks, usize),
    (poses_b, landmarks_b, g): (&ClipPoses, &Landmarks, usize),
    turn: Quat,
) -> (f64, &'static str) {
    if torso_upright(poses_a, f, landmarks_a) && torso_upright(poses_b, g, landmarks_b) {
        let angle = match (torso_facing(poses_a, f, landmarks_a), torso_facing(poses_b, g, landmarks_b)) {
            (Some(x), Some(y)) => angle_between(x, turn * y),
            _ => 0.0,
        };
        (angle, "ground facing")
    } else {
        let angle = match (torso_orientation(poses_a, f, landmarks_a), torso_orientation(poses_b, g, landmarks_b)) {
            (Some(x), Some(y)) => f64::from(x.angle_between(turn * y)),
            _ => 0.0,
        };
        (angle, "torso orientation (not upright)")
    }
}

/// The point between the two ankles at `frame`, on the ground plane (y = 0).
pub fn feet_centre(poses: &ClipPoses, frame: usize, landmarks: &Landmarks) -> Vec3 {
    let [l, r] = landmarks.feet();
    let c = (poses.position(frame, l) + poses.position(frame, r)) * 0.5;
    Vec3::new(c.x, 0.0, c.z)
}

/// Unsigned angle between two horizontal unit vectors, radians.
pub fn angle_between(a: Vec3, b: Vec3) -> f64 {
    f64::from(a.dot(b).clamp(-1.0, 1.0)).acos()
}

/// The clip with its root motion turned by `yaw` about the world's vertical axis through
/// the origin and then moved by `offset_m`. The skeleton is untouched, so the result still
/// blends with clips on the same skeleton.
pub fn place(clip: &Clip, yaw: f64, offset_m: Vec3) -> Result<Clip, ClipError> {
    let r = yaw_rotation(yaw);
    let n = clip.joint_count();
    let roots: Vec<bool> = clip.skeleton().joints().iter().map(|j| j.parent.is_none()).collect();
    let rotations = clip.rotations().iter().enumerate().map(|(i, q)| if roots[i % n] { r * *q } else { *q }).collect();
    let translations = clip
        .translations()
        .iter()
        .enumerate()
        .map(|(i, t)| if roots[i % n] { r * *t + offset_m } else { *t })
        .collect();
    Clip::new(clip.skeleton().clone(), clip.fps(), rotations, translations, clip.import_scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over a fine grid of angles agrees with the closed form.
    #[test]
    fn closed_form_yaw_matches_a_scan() {
        let cases = [
            (DVec3::new(1.0, 0.3, 0.0), DVec3::new(0.0, -0.2, 2.0)),
            (DVec3::new(-0.4, 1.0, 0.9), DVec3::new(0.7, 0.5, -0.1)),
        ];
        for (l1, l2) in cases {
            let score = |t: f64| l1.dot(yaw_rotation(t).as_dquat() * l2);
            let scan: Vec<f64> = (0..36000).map(|i| i as f64 / 36000.0 * std::f64::consts::TAU).collect();
            let best = scan.iter().copied().max_by(|a, b| score(*a).total_cmp(&score(*b))).unwrap();
            let worst = scan.iter().copied().min_by(|a, b| score(*a).total_cmp(&score(*b))).unwrap();
            assert!(wrap_angle(alignment_yaw(l1, l2, Rule::Forward) - best).abs() < 1e-3);
            assert!(wrap_angle(alignment_yaw(l1, l2, Rule::Reverse) - worst).abs() < 1e-3);
        }
    }

    #[test]
    fn wrap_angle_stays_in_range() {
        for a in [-10.0, -std::f64::consts::PI, 0.0, 3.0, 7.0] {
            let w = wrap_angle(a);
            assert!(w > -std::f64::consts::PI - 1e-12 && w <= std::f64::consts::PI);
            assert!(((w - a) / std::f64::consts::TAU).round() * std::f64::consts::TAU - (w - a) < 1e-9);
        }
    }
}
