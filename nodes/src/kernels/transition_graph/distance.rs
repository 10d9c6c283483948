//! The pose distance of Lee et al. 2002, made invariant to where the character stands and
//! which way it faces:
//!
//! D(i, j) = (h_i − h_j)² + Σ_k w_k ‖log(q_j,k⁻¹ q_i,k)‖² + ν (‖v_i − v_j‖² + Σ_k w_k ‖ω_i,k − ω_j,k‖²)
//!
//! with h the root height (m), q_k the joint rotations (the root's with its heading taken
//! out, every other joint's local one), ‖log q‖ the half rotation angle (radians), v the root
//! velocity in the body's own heading frame (m/s) and ω_k the joints' angular velocities in
//! their own frames (rad/s). Expressing each frame in its own heading frame is what makes
//! the distance ignore a turn about the vertical axis or a walk across the floor.

use glam::{Quat, Vec3};

use crate::model::{Clip, Skeleton};

/// Settings of the pose distance.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DistanceParams {
    /// Weight per joint (skeleton order); joints at zero are skipped entirely.
    pub weights: Vec<f32>,
    /// ν: weight of the velocity term, s² (turns rad²/s² into rad²).
    pub velocity_weight: f32,
}

/// Why a joint-weight override (`"Name=w, Name=w"`) was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WeightError {
    /// An item is not `Name=weight`.
    #[error("'{0}' is not of the form JointName=weight")]
    Form(String),
    /// The skeleton has no joint of that name.
    #[error("no joint called '{0}'")]
    UnknownJoint(String),
    /// The weight does not parse.
    #[error("'{0}' is not a number")]
    NotANumber(String),
    /// The weight of the named joint is negative or not finite.
    #[error("weight of '{0}' must be a finite number ≥ 0")]
    Negative(String),
}

impl DistanceParams {
    /// Lee et al.'s choice: weight 1 for the pelvis, spine, hips, knees, shoulders and
    /// elbows, 0 elsewhere (head, neck, wrists, hands, ankles, toes, end sites), found by
    /// joint name so it fits CMU, DAZ, 3ds Max and HumanIK naming.
    pub fn lee_defaults(skeleton: &Skeleton, velocity_weight: f32) -> DistanceParams {
        const KEEP: [&str; 14] = [
            "hip", "pelvis", "spine", "back", "chest", "abdomen", "leg", "thigh", "knee", "shin", "arm", "shoulder",
            "shldr", "elbow",
        ];
        const SKIP: [&str; 11] =
            ["hand", "finger", "thumb", "index", "toe", "foot", "ankle", "wrist", "head", "neck", "end"];
        let weights = skeleton
            .joints()
            .iter()
            .enumerate()
            .map(|(i, j)| {
                let name = j.name.to_lowercase();
                let keep = i == 0 || (KEEP.iter().any(|k| name.contains(k)) && !SKIP.iter().any(|k| name.contains(k)));
                if keep && !j.end_site { 1.0 } else { 0.0 }
            })
            .collect();
        DistanceParams { weights, velocity_weight }
    }

    /// Overrides weights from `"Name=w, Name=w"`; an unknown joint name is an error naming it.
    pub fn with_overrides(mut self, skeleton: &Skeleton, text: &str) -> Result<DistanceParams, WeightError> {
        for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, value) = item.split_once('=').ok_or_else(|| WeightError::Form(item.to_owned()))?;
            let (name, value) = (name.trim(), value.trim());
            let index = skeleton.index_of(name).ok_or_else(|| WeightError::UnknownJoint(name.to_owned()))?;
            let w: f32 = value.parse().map_err(|_| WeightError::NotANumber(value.to_owned()))?;
            if !(w.is_finite() && w >= 0.0) {
                return Err(WeightError::Negative(name.to_owned()));
            }
            self.weights[index] = w;
        }
        Ok(self)
    }
}

/// Heading (yaw about +Y, radians) of a root rotation: where its local +Z points on the
/// ground, or its local +X turned a quarter when +Z points straight up or down.
pub fn heading_yaw(root: Quat) -> f32 {
    let f = root * Vec3::Z;
    if f.x.hypot(f.z) > 1e-3 {
        f.x.atan2(f.z)
    } else {
        let s = root * Vec3::X;
        s.x.atan2(s.z) - std::f32::consts::FRAC_PI_2
    }
}

/// Rotation vector (axis × angle, radians) taking `a` to `b` in `a`'s own frame.
pub fn rotation_vector(a: Quat, b: Quat) -> Vec3 {
    let d = a.conjugate() * b;
    let d = if d.w < 0.0 { -d } else { d };
    let s = d.xyz().length();
    if s < 1e-7 { d.xyz() * 2.0 } else { d.xyz() * (2.0 * s.atan2(d.w) / s) }
}

/// acos(x) for x in [0, 1] (radians) by Abramowitz & Stegun 4.4.46: √(1 − x) times a
/// degree-7 polynomial, error below 2·10⁻⁸ rad before f32 rounding. Cheaper than the
/// library's `acos` call, which dominated the pose distance's cost.
#[inline]
fn acos_unit(x: f32) -> f32 {
    // The published coefficients (to f32 precision); a₀ = 1.5707963050 is not quite π/2.
    #[allow(clippy::approx_constant)]
    const A: [f32; 8] = [
        1.570_796_3,
        -0.214_598_8,
        0.088_978_99,
        -0.050_174_3,
        0.030_891_88,
        -0.017_088_126,
        0.006_670_09,
        -0.001_262_491_1,
    ];
    // Plain multiply-adds: `mul_add` is a library call on targets built without FMA.
    let p = A.iter().rev().fold(0.0f32, |acc, a| acc * x + a);
    (1.0 - x).max(0.0).sqrt() * p
}

/// The per-frame quantities the distance compares, for the joints of nonzero weight only,
/// stored flat (frame-major) so comparing two frames walks contiguous memory.
#[derive(Clone, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct PoseFeatures {
    /// Weighted joints' indices in the skeleton.
    joints: Vec<usize>,
    /// Their weights.
    weights: Vec<f32>,
    velocity_weight: f32,
    root_height_m: Vec<f32>,
    root_velocity_mps: Vec<Vec3>,
    rotations: Vec<Quat>,
    angular_velocity: Vec<Vec3>,
}

impl PoseFeatures {
    /// Features laid out for `params`, with no frames yet.
    pub fn empty(params: &DistanceParams) -> PoseFeatures {
        let joints: Vec<usize> = (0..params.weights.len()).filter(|&j| params.weights[j] > 0.0).collect();
        let weights = joints.iter().map(|&j| params.weights[j]).collect();
        PoseFeatures { joints, weights, velocity_weight: params.velocity_weight, ..Default::default() }
    }

    /// The same layout (joints, weights, ν) with no frames.
    pub fn clone_empty(&self) -> PoseFeatures {
        PoseFeatures {
            joints: self.joints.clone(),
            weights: self.weights.clone(),
            velocity_weight: self.velocity_weight,
            ..Default::default()
        }
    }

    /// Weighted joints (skeleton indices) and their weights.
    pub fn weighted_joints(&self) -> impl Iterator<Item = (usize, f32)> + '_ {
        self.joints.iter().copied().zip(self.weights.iter().copied())
    }

    /// Features of every frame of `clip`.
    pub fn of_clip(clip: &Clip, params: &DistanceParams) -> PoseFeatures {
        let mut f = PoseFeatures::empty(params);
        f.push_frames(clip.rotations(), clip.translations(), clip.joint_count(), clip.fps(), 0..clip.frame_count());
        f
    }

    /// Appends the features of frames `range` of frame-major local transforms
    /// (`joints` per frame, `fps` frames per second). Velocities use central differences
    /// inside, one-sided ones at the ends of the whole buffer.
    pub fn push_frames(
        &mut self,
        rotations: &[Quat],
        translations: &[Vec3],
        joints: usize,
        fps: f64,
        range: std::ops::Range<usize>,
    ) {
        let frames = rotations.len() / joints.max(1);
        let fps = fps as f32;
        for f in range {
            let (prev, next) = (f.saturating_sub(1), (f + 1).min(frames.saturating_sub(1)));
            let dt = (next - prev).max(1) as f32 / fps;
            let root = rotations[f * joints];
            let heading_from_world = Quat::from_rotation_y(-heading_yaw(root));
            let root_pos = translations[f * joints];
            self.root_height_m.push(root_pos.y);
            let v = (translations[next * joints] - translations[prev * joints]) / dt;
            self.root_velocity_mps.push(heading_from_world * v);
            for &j in &self.joints {
                let q = rotations[f * joints + j];
                self.rotations.push(if j == 0 { heading_from_world * q } else { q });
                let w = rotation_vector(rotations[prev * joints + j], rotations[next * joints + j]) / dt;
                self.angular_velocity.push(w);
            }
        }
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.root_height_m.len()
    }

    /// Whether there are no frames.
    pub fn is_empty(&self) -> bool {
        self.root_height_m.is_empty()
    }

    /// D between frame `i` of `self` and frame `j` of `other` (same layout).
    #[inline]
    pub fn distance_to(&self, i: usize, other: &PoseFeatures, j: usize) -> f32 {
        self.distance_below(i, other, j, f32::INFINITY)
    }

    /// D between frame `i` of `self` and frame `j` of `other` when it is below `bound`;
    /// otherwise some value ≥ `bound` (the sum stops as soon as it reaches the bound, which
    /// is all a search for the nearest frame needs to know).
    #[inline]
    pub fn distance_below(&self, i: usize, other: &PoseFeatures, j: usize, bound: f32) -> f32 {
        let m = self.joints.len();
        let (a, b) = (&self.rotations[i * m..(i + 1) * m], &other.rotations[j * m..(j + 1) * m]);
        let (va, vb) = (&self.angular_velocity[i * m..(i + 1) * m], &other.angular_velocity[j * m..(j + 1) * m]);
        let dh = self.root_height_m[i] - other.root_height_m[j];
        let mut pose = dh * dh;
        let mut velocity = self.root_velocity_mps[i].distance_squared(other.root_velocity_mps[j]);
        for k in 0..m {
            let half_angle = acos_unit(a[k].dot(b[k]).abs().min(1.0));
            pose += self.weights[k] * half_angle * half_angle;
            velocity += self.weights[k] * va[k].distance_squared(vb[k]);
            let partial = pose + self.velocity_weight * velocity;
            if partial >= bound {
                return partial;
            }
        }
        pose + self.velocity_weight * velocity
    }

    /// D between frames `i` and `j` of `self`.
    #[inline]
    pub fn distance(&self, i: usize, j: usize) -> f32 {
        self.distance_to(i, self, j)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::model::{ImportScale, Joint};

    fn skeleton() -> Arc<Skeleton> {
        Arc::new(
            Skeleton::new(vec![
                Joint::new("Hips", None, Vec3::new(0.0, 1.0, 0.0)),
                Joint::new("LeftUpLeg", Some(0), Vec3::new(0.1, -0.1, 0.0)),
                Joint::new("LeftLeg", Some(1), Vec3::new(0.0, -0.45, 0.0)),
                Joint::new("LeftFoot", Some(2), Vec3::new(0.0, -0.45, 0.0)),
            ])
            .unwrap(),
        )
    }

    /// Three frames: the root walks along X, the knee bends at a constant rate.
    fn clip(turn: Quat, shift: Vec3) -> Clip {
        let s = skeleton();
        let mut rotations = Vec::new();
        let mut translations = Vec::new();
        for f in 0..3 {
            let t = f as f32;
            rotations.extend([
                turn * Quat::from_rotation_x(0.1),
                Quat::from_rotation_x(-0.3),
                Quat::from_rotation_x(0.4 + 0.1 * t),
                Quat::from_rotation_z(t),
            ]);
            let root = turn * Vec3::new(0.5 * t, 0.9 + 0.01 * t, 0.0) + shift;
            translations.extend([
                root,
                s.joints()[1].rest_offset,
                s.joints()[2].rest_offset,
                s.joints()[3].rest_offset,
            ]);
        }
        Clip::new(s, 10.0, rotations, translations, ImportScale::METRES).unwrap()
    }

    #[test]
    fn lee_weights_keep_the_body_and_drop_the_extremities() {
        let p = DistanceParams::lee_defaults(&skeleton(), 0.1);
        assert_eq!(p.weights, vec![1.0, 1.0, 1.0, 0.0]);
        let p = p.with_overrides(&skeleton(), "LeftFoot=0.5, LeftLeg = 2").unwrap();
        assert_eq!(p.weights, vec![1.0, 1.0, 2.0, 0.5]);
        let defaults = || DistanceParams::lee_defaults(&skeleton(), 0.1);
        assert_eq!(
            defaults().with_overrides(&skeleton(), "Nose=1").unwrap_err(),
            WeightError::UnknownJoint("Nose".into())
        );
        assert_eq!(
            defaults().with_overrides(&skeleton(), "LeftFoot").unwrap_err(),
            WeightError::Form("LeftFoot".into())
        );
        assert_eq!(
            defaults().with_overrides(&skeleton(), "LeftFoot=-1").unwrap_err().to_string(),
            "weight of 'LeftFoot' must be a finite number ≥ 0"
        );
    }

    #[test]
    fn distance_ignores_heading_and_floor_position() {
        let p = DistanceParams::lee_defaults(&skeleton(), 0.1);
        let base = PoseFeatures::of_clip(&clip(Quat::IDENTITY, Vec3::ZERO), &p);
        let moved = PoseFeatures::of_clip(&clip(Quat::from_rotation_y(2.0), Vec3::new(3.0, 0.0, -7.0)), &p);
        for i in 0..3 {
            for j in 0..3 {
                let (d0, d1) = (base.distance(i, j), base.distance_to(i, &moved, j));
                assert!((d0 - d1).abs() < 1e-4, "frames {i},{j}: {d0} vs {d1}");
            }
        }
        // A vertical shift is not ignored: only the height changes, by 0.2 m.
        let lifted = PoseFeatures::of_clip(&clip(Quat::IDENTITY, Vec3::new(0.0, 0.2, 0.0)), &p);
        assert!((base.distance_to(1, &lifted, 1) - 0.04).abs() < 1e-5);
    }

    #[test]
    fn distance_between_frames_matches_a_hand_computation() {
        // Frames 0 and 2: every rate is constant, so central and one-sided differences agree
        // and the velocity term is zero; only poses differ.
        // Root: heading removed, both tilt 0.1 about X → 0. Hip: same → 0.
        // Knee: 0.4 vs 0.6 rad about X → half-angle 0.1 → 0.01. Height: 0.02 m → 0.0004.
        let p = DistanceParams::lee_defaults(&skeleton(), 0.1);
        let f = PoseFeatures::of_clip(&clip(Quat::IDENTITY, Vec3::ZERO), &p);
        assert!((f.distance(0, 2) - 0.0104).abs() < 1e-5, "{}", f.distance(0, 2));
        assert_eq!(f.distance(1, 1), 0.0);
    }

    #[test]
    fn the_polynomial_acos_matches_the_library_one() {
        let worst = (0..=100_000)
            .map(|i| {
                let x = i as f32 / 100_000.0;
                (f64::from(acos_unit(x)) - f64::from(x).acos()).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 5e-7, "{worst}");
        assert_eq!(acos_unit(1.0), 0.0);
    }

    #[test]
    fn a_bounded_distance_is_exact_below_the_bound_and_at_least_the_bound_above() {
        let p = DistanceParams::lee_defaults(&skeleton(), 0.1);
        let f = PoseFeatures::of_clip(&clip(Quat::IDENTITY, Vec3::ZERO), &p);
        // 0.0104 from the hand computation above.
        assert_eq!(f.distance_below(0, &f, 2, 0.02), f.distance(0, 2));
        let stopped = f.distance_below(0, &f, 2, 0.001);
        assert!((0.001..=0.0104 + 1e-6).contains(&stopped), "{stopped}");
    }
}
