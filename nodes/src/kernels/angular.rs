//! Whole-body angular momentum about the centre of mass (Shum et al. 2009, eq. 1):
//! L(t) = Σ_j m_j r_j(t) × v_j(t), with r_j from the body's centre of mass to segment j's,
//! and v_j segment j's velocity by central differences at the clip's frame rate.
//! Segments' spin about their own centres is left out, as in the paper.
//!
//! A kernel: the clip analysis uses it, and foot contacts share its central difference.

use glam::{DVec3, Vec3};

use super::body::BodyModel;
use crate::model::{ClipPoses, Curves, CurvesError};

/// Angular momentum and centre-of-mass trajectories of one clip.
#[derive(Clone, Debug, PartialEq)]
pub struct MomentumTrack {
    /// Frames per second of the clip.
    pub fps: f64,
    /// Body centre of mass per frame, metres, world space.
    pub com_m: Vec<DVec3>,
    /// Velocity of the body centre of mass per frame, m/s.
    pub com_velocity_mps: Vec<DVec3>,
    /// Angular momentum about the centre of mass per frame, kg·m²/s.
    pub momentum: Vec<DVec3>,
    /// Moment arms r_j (segment centre minus body centre), frame-major, metres.
    pub arms_m: Vec<Vec3>,
    /// Segment masses, kilograms, in the order of `arms_m` within a frame.
    pub masses_kg: Vec<f64>,
}

impl MomentumTrack {
    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.momentum.len()
    }

    /// The moment arms of every segment at `frame`.
    pub fn arms(&self, frame: usize) -> &[Vec3] {
        let n = self.masses_kg.len();
        &self.arms_m[frame * n..(frame + 1) * n]
    }

    /// The largest |L| over the frames, kg·m²/s.
    pub fn peak(&self) -> f64 {
        self.momentum.iter().map(|l| l.length()).fold(0.0, f64::max)
    }

    /// The curves a plot or a test reads: L (x, y, z, magnitude) and the centre of mass.
    pub fn curves(&self) -> Result<Curves, CurvesError> {
        let mut c = Curves::new(self.fps, self.frame_count());
        let unit_l = "kg·m²/s";
        c.push("L.x", unit_l, self.momentum.iter().map(|l| l.x).collect())?;
        c.push("L.y", unit_l, self.momentum.iter().map(|l| l.y).collect())?;
        c.push("L.z", unit_l, self.momentum.iter().map(|l| l.z).collect())?;
        c.push("|L|", unit_l, self.momentum.iter().map(|l| l.length()).collect())?;
        c.push("com.x", "m", self.com_m.iter().map(|p| p.x).collect())?;
        c.push("com.y", "m", self.com_m.iter().map(|p| p.y).collect())?;
        c.push("com.z", "m", self.com_m.iter().map(|p| p.z).collect())?;
        c.push("com_speed", "m/s", self.com_velocity_mps.iter().map(|v| v.length()).collect())?;
        Ok(c)
    }
}

/// Central difference of `samples` at frame `i` (one-sided at the ends), per second.
pub fn central_difference<T>(samples: &[T], i: usize, fps: f64) -> T
where
    T: Copy + std::ops::Sub<Output = T> + std::ops::Mul<f64, Output = T> + Default,
{
    let n = samples.len();
    if n < 2 {
        return T::default();
    }
    let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
    (samples[b] - samples[a]) * (fps / (b - a) as f64)
}

/// Angular momentum under `model` of a clip's world poses (from
/// [`forward_kinematics`](crate::model::forward_kinematics)) at `fps` frames per second.
pub fn momentum_of_poses(poses: &ClipPoses, fps: f64, model: &BodyModel) -> MomentumTrack {
    let frames = poses.frame_count();
    let segments = model.segments.len();
    let masses_kg: Vec<f64> = model.segments.iter().map(|s| s.mass_kg).collect();
    let total_kg: f64 = masses_kg.iter().sum::<f64>().max(f64::MIN_POSITIVE);
    let mut segment_com: Vec<DVec3> = Vec::with_capacity(frames * segments);
    let mut positions: Vec<Vec3> = Vec::new();
    for f in 0..frames {
        positions.clear();
        positions.extend(poses.frame(f).iter().map(|t| t.translation));
        segment_com.extend(model.segments.iter().map(|s| model.segment_com(s, &positions).as_dvec3()));
    }
    let com_m: Vec<DVec3> = segment_com
        .chunks_exact(segments.max(1))
        .map(|c| c.iter().zip(&masses_kg).map(|(p, m)| *p * *m).sum::<DVec3>() / total_kg)
        .take(frames)
        .collect();
    let com_velocity_mps: Vec<DVec3> = (0..frames).map(|f| central_difference(&com_m, f, fps)).collect();
    let mut momentum = Vec::with_capacity(frames);
    let mut arms_m = Vec::with_capacity(frames * segments);
    let mut column: Vec<DVec3> = vec![DVec3::ZERO; frames];
    let mut velocities: Vec<DVec3> = vec![DVec3::ZERO; frames * segments];
    for s in 0..segments {
        for (f, c) in column.iter_mut().enumerate() {
            *c = segment_com[f * segments + s];
        }
        for f in 0..frames {
            velocities[f * segments + s] = central_difference(&column, f, fps);
        }
    }
    for f in 0..frames {
        let mut l = DVec3::ZERO;
        for s in 0..segments {
            let arm = segment_com[f * segments + s] - com_m[f];
            // Relative to the centre's velocity: identical in exact arithmetic (Σ m r = 0),
            // smaller round-off when the body travels fast.
            l += masses_kg[s] * arm.cross(velocities[f * segments + s] - com_velocity_mps[f]);
            arms_m.push(arm.as_vec3());
        }
        momentum.push(l);
    }
    MomentumTrack { fps, com_m, com_velocity_mps, momentum, arms_m, masses_kg }
}

/// Centred moving average over `half_width` frames either side (shorter at the ends):
/// takes the capture noise out of L before its sign is read.
pub fn smooth(samples: &[DVec3], half_width: usize) -> Vec<DVec3> {
    let n = samples.len();
    let mut prefix = Vec::with_capacity(n + 1);
    prefix.push(DVec3::ZERO);
    for s in samples {
        prefix.push(*prefix.last().unwrap_or(&DVec3::ZERO) + *s);
    }
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half_width), (i + half_width + 1).min(n));
            (prefix[b] - prefix[a]) / (b - a) as f64
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::Quat;

    use super::*;
    use crate::kernels::body::{MassOverride, MassTable, body_model};
    use crate::model::{Clip, ImportScale, Joint, Skeleton};

    /// Two point masses on a rigid rod spinning about Y at ω rad/s: L = I ω with
    /// I = Σ m r², an analytic case.
    #[test]
    fn spinning_dumbbell_has_the_analytic_momentum() {
        let joints = vec![
            Joint::new("centre", None, Vec3::ZERO),
            Joint::new("a", Some(0), Vec3::new(0.5, 0.0, 0.0)),
            Joint::new("b", Some(0), Vec3::new(-0.5, 0.0, 0.0)),
        ];
        let skeleton = Arc::new(Skeleton::new(joints).unwrap());
        let (fps, omega) = (240.0, 2.0);
        let frames = 100;
        let rotations: Vec<Quat> = (0..frames)
            .flat_map(|i| {
                let q = Quat::from_rotation_y((omega * i as f64 / fps) as f32);
                [q, Quat::IDENTITY, Quat::IDENTITY]
            })
            .collect();
        let translations: Vec<Vec3> = (0..frames)
            .flat_map(|_| [Vec3::new(3.0, 1.0, 0.0), Vec3::new(0.5, 0.0, 0.0), Vec3::new(-0.5, 0.0, 0.0)])
            .collect();
        let clip = Clip::new(skeleton.clone(), fps, rotations, translations, ImportScale::METRES).unwrap();
        // Each end carries 10 kg at the joint itself (com_fraction 1 from the centre).
        let o: MassOverride = ron::from_str(
            r#"(segments: [
                (name: "a", mass_fraction: 1.0, from: "centre", to: "a", com_fraction: 1.0),
                (name: "b", mass_fraction: 1.0, from: "centre", to: "b", com_fraction: 1.0),
            ])"#,
        )
        .unwrap();
        let model = body_model(&skeleton, 20.0, MassTable::DeLevaMale, Some(&o)).unwrap();
        let track = momentum_of_poses(&crate::model::forward_kinematics(&clip), clip.fps(), &model);
        let inertia = 2.0 * 10.0 * 0.5 * 0.5;
        // Central differences of a circle shrink the speed by sin(ωh)/(ωh).
        let h = 1.0 / fps;
        let chord = (omega * h).sin() / (omega * h);
        for f in 1..frames - 1 {
            let l = track.momentum[f];
            // f32 joint positions differenced over 1/240 s leave ~1e-5 relative noise.
            assert!((l.y - inertia * omega * chord).abs() < 1e-3, "frame {f}: {l}");
            assert!(l.x.abs() < 1e-4 && l.z.abs() < 1e-4);
            assert!((track.com_m[f] - DVec3::new(3.0, 1.0, 0.0)).length() < 1e-5);
        }
    }

    #[test]
    fn moving_average_is_exact_on_lines() {
        let line: Vec<DVec3> = (0..10).map(|i| DVec3::splat(i as f64)).collect();
        let s = smooth(&line, 2);
        for i in 2..8 {
            assert!((s[i] - line[i]).length() < 1e-12);
        }
        assert_eq!(s[0], DVec3::splat(1.0)); // mean of 0, 1, 2
    }

    #[test]
    fn central_difference_of_a_line_is_its_slope() {
        let xs: Vec<f64> = (0..5).map(|i| 2.0 * i as f64).collect();
        for i in 0..5 {
            assert!((central_difference(&xs, i, 10.0) - 20.0).abs() < 1e-12);
        }
        assert_eq!(central_difference(&[1.0], 0, 10.0), 0.0);
    }
}
