//! Real-time motion anywhere inside a [`Family`]: the 2^n samples at the corners of the
//! grid cell holding the parameters are blended per frame (the paper's simple weighted
//! average): along each axis, rotations by short-arc slerp and translations linearly, with
//! the cell's linear weights, the last axis first. At a grid point the weights are 0 or 1,
//! so the blend returns that sample.
//!
//! Inverse control ([`reach`]): the parameters that put one joint at a target point at one
//! frame, by Levenberg–Marquardt on the 3-D miss with finite-difference derivatives over
//! the 1–2 parameters, kept inside the family's box.

use glam::{DMat2, DVec2, DVec3, Quat, Vec3};

use crate::math::slerp_short;
use crate::model::{Clip, ClipError, Family, SampleOutcome, Transform, fk::pose_world};

/// Parameters within this of an axis's single value, or of its ends, count as on it
/// (metres or radians: far below anything an animator types).
pub const ON_AXIS_TOL: f64 = 1e-9;

/// Why a blend or a reach could not be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BlendError {
    /// One parameter per axis is needed.
    #[error("the family has {want} parameter(s), {got} given")]
    Dimensions {
        /// Parameters given.
        got: usize,
        /// Axes of the family.
        want: usize,
    },
    /// A parameter lies outside the sampled range.
    #[error("parameter {axis} = {value} lies outside the family's range [{from}, {to}]")]
    Outside {
        /// 0 for u, 1 for v.
        axis: usize,
        /// The value asked.
        value: f64,
        /// First sampled value.
        from: f64,
        /// Last sampled value.
        to: f64,
    },
    /// A corner of the cell is a sample whose optimisation failed.
    #[error("the sample at {params:?} is needed but its optimisation failed: {reason}")]
    FailedSample {
        /// The failed sample's parameters.
        params: Vec<f64>,
        /// The solver's error.
        reason: String,
    },
    /// The family holds no sample at a grid index (a malformed family).
    #[error("the family has no sample at grid index {0:?}")]
    Missing(Vec<usize>),
    /// Corner samples differ in frames or skeleton.
    #[error("the samples differ in frame count or skeleton")]
    Mismatch,
    /// The joint to reach is not in the skeleton.
    #[error("joint {joint} does not exist: the skeleton has {joints} joints")]
    Joint {
        /// The joint asked.
        joint: usize,
        /// Joints in the skeleton.
        joints: usize,
    },
    /// The frame to reach at is not in the clips.
    #[error("frame {frame} does not exist: the samples have {frames} frames")]
    Frame {
        /// The frame asked.
        frame: usize,
        /// Frames in the samples.
        frames: usize,
    },
    /// The target is not a finite point.
    #[error("the target {0} is not a finite point")]
    Target(DVec3),
    /// The blended clip is unusable.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// The corners of the cell holding `params`, blend-ready: 2^n clips (corner bit n−1−k set
/// when it takes the upper value on axis k, so corners paired along the last axis are
/// adjacent) and the weight of the upper value on each axis.
struct Cell<'a> {
    corners: Vec<&'a Clip>,
    /// Each corner's parameters and share of the blend (the product of its axis weights).
    shares: Vec<(Vec<f64>, f64)>,
    weights: Vec<f32>,
}

fn cell<'a>(family: &'a Family, params: &[f64]) -> Result<Cell<'a>, BlendError> {
    if params.len() != family.axes.len() || params.is_empty() {
        return Err(BlendError::Dimensions { got: params.len(), want: family.axes.len() });
    }
    let mut spans = Vec::with_capacity(params.len());
    for (axis, (values, &p)) in family.axes.iter().zip(params).enumerate() {
        let (Some(&from), Some(&to)) = (values.first(), values.last()) else {
            return Err(BlendError::Missing(vec![0; axis + 1]));
        };
        if !(p >= from - ON_AXIS_TOL && p <= to + ON_AXIS_TOL) {
            return Err(BlendError::Outside { axis, value: p, from, to });
        }
        let p = p.clamp(from, to);
        // The cell [lo, lo + 1] holding p (the last one for p at the end).
        let lo = values.windows(2).position(|w| p <= w[1]).unwrap_or(0);
        let hi = (lo + 1).min(values.len() - 1);
        let w = if hi == lo { 0.0 } else { (p - values[lo]) / (values[hi] - values[lo]) };
        spans.push((lo, hi, w as f32));
    }
    let n = spans.len();
    let mut corners = Vec::with_capacity(1 << n);
    let mut shares = Vec::with_capacity(1 << n);
    for c in 0..1usize << n {
        let index: Vec<usize> = spans
            .iter()
            .enumerate()
            .map(|(k, (lo, hi, _))| if c >> (n - 1 - k) & 1 == 1 { *hi } else { *lo })
            .collect();
        let sample = family.sample_at(&index).ok_or_else(|| BlendError::Missing(index.clone()))?;
        let share = spans
            .iter()
            .enumerate()
            .map(|(k, (_, _, w))| if c >> (n - 1 - k) & 1 == 1 { f64::from(*w) } else { 1.0 - f64::from(*w) })
            .product();
        shares.push((sample.params.clone(), share));
        match &sample.outcome {
            SampleOutcome::Solved(clip) => corners.push(clip.as_ref()),
            SampleOutcome::Failed(reason) => {
                return Err(BlendError::FailedSample { params: sample.params.clone(), reason: reason.clone() });
            }
        }
    }
    let first = corners[0];
    if corners.iter().any(|c| c.frame_count() != first.frame_count() || c.skeleton() != first.skeleton()) {
        return Err(BlendError::Mismatch);
    }
    Ok(Cell { corners, shares, weights: spans.iter().map(|s| s.2).collect() })
}

impl Cell<'_> {
    /// The blended local pose of `frame` into `rotations` and `translations` (one per joint).
    fn pose(&self, frame: usize, rotations: &mut [Quat], translations: &mut [Vec3]) {
        // At most 2 axes: 4 corners.
        let (mut q, mut t) = ([Quat::IDENTITY; 4], [Vec3::ZERO; 4]);
        for j in 0..rotations.len() {
            for (c, clip) in self.corners.iter().enumerate() {
                q[c] = clip.frame_rotations(frame)[j];
                t[c] = clip.frame_translations(frame)[j];
            }
            let mut len = self.corners.len();
            for &w in self.weights.iter().rev() {
                len /= 2;
                for i in 0..len {
                    q[i] = slerp_short(q[2 * i], q[2 * i + 1], w);
                    t[i] = t[2 * i].lerp(t[2 * i + 1], w);
                }
            }
            rotations[j] = q[0];
            translations[j] = t[0];
        }
    }
}

/// Most axes a family may have (a grid's 2).
const MAX_AXES: usize = 2;

/// The motion of `family` at `params` (one per axis, inside its range), blended from the
/// nearest 2^n samples.
pub fn blend_family(family: &Family, params: &[f64]) -> Result<Clip, BlendError> {
    if params.len() > MAX_AXES {
        return Err(BlendError::Dimensions { got: params.len(), want: family.axes.len() });
    }
    let cell = cell(family, params)?;
    let first = cell.corners[0];
    let (frames, joints) = (first.frame_count(), first.joint_count());
    let mut rotations = vec![Quat::IDENTITY; frames * joints];
    let mut translations = vec![Vec3::ZERO; frames * joints];
    for f in 0..frames {
        let range = f * joints..(f + 1) * joints;
        cell.pose(f, &mut rotations[range.clone()], &mut translations[range]);
    }
    Ok(Clip::new(first.skeleton().clone(), first.fps(), rotations, translations, first.import_scale)?)
}

/// The samples a blend at `params` takes, with their shares (summing to 1): what the
/// paper shows as the samples' brightness on the floor.
pub fn blend_shares(family: &Family, params: &[f64]) -> Result<Vec<(Vec<f64>, f64)>, BlendError> {
    Ok(cell(family, params)?.shares)
}

/// Where a joint must be: `joint` at `target_m` (world, metres) at `frame`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReachTarget {
    /// The joint (index in the family's skeleton).
    pub joint: usize,
    /// The frame.
    pub frame: usize,
    /// The point, metres.
    pub target_m: DVec3,
}

/// The parameters found by [`reach`].
#[derive(Clone, Debug, PartialEq)]
pub struct Reached {
    /// One per axis, inside the family's range.
    pub params: Vec<f64>,
    /// Distance left between the joint and the target, metres (not zero when the target
    /// lies beyond what the family reaches).
    pub miss_m: f64,
    /// Levenberg–Marquardt steps taken.
    pub iterations: usize,
}

/// Steps of [`reach`] at most.
pub const REACH_STEPS: usize = 60;

/// A miss under this ends [`reach`] early, metres.
pub const REACH_TOL_M: f64 = 1e-5;

/// The family's parameters that put `target.joint` closest to `target.target_m` at
/// `target.frame`: started from the solved sample whose joint lies closest, improved by
/// damped Gauss–Newton on the miss vector with central-difference derivatives, each step
/// clamped to the family's box.
pub fn reach(family: &Family, target: &ReachTarget) -> Result<Reached, BlendError> {
    let dims = family.axes.len();
    if dims == 0 || dims > MAX_AXES {
        return Err(BlendError::Dimensions { got: dims, want: MAX_AXES });
    }
    if !target.target_m.is_finite() {
        return Err(BlendError::Target(target.target_m));
    }
    let end = |k: usize, last: bool| {
        family.axes.get(k).and_then(|a| if last { a.last() } else { a.first() }).copied().unwrap_or(0.0)
    };
    let (lower, upper) = (DVec2::new(end(0, false), end(1, false)), DVec2::new(end(0, true), end(1, true)));
    let mut scratch = Scratch::default();
    let mut position = |p: DVec2| -> Result<DVec3, BlendError> {
        let params = [p.x, p.y];
        let cell = cell(family, &params[..dims])?;
        scratch.position(&cell, target)
    };
    // Start from the closest solved sample.
    let mut best: Option<(DVec2, f64)> = None;
    for s in family.samples.iter().filter(|s| matches!(s.outcome, SampleOutcome::Solved(_))) {
        let p = DVec2::new(s.params[0], s.params.get(1).copied().unwrap_or(0.0));
        let miss = (position(p)? - target.target_m).length();
        if best.is_none_or(|(_, m)| miss < m) {
            best = Some((p, miss));
        }
    }
    let Some((mut p, _)) = best else {
        // No solved sample: the first one's failure says why.
        return Err(match family.samples.first() {
            Some(first) => BlendError::FailedSample {
                params: first.params.clone(),
                reason: match &first.outcome {
                    SampleOutcome::Failed(r) => r.clone(),
                    SampleOutcome::Solved(_) => String::new(),
                },
            },
            None => BlendError::Missing(vec![0; dims]),
        });
    };
    let span = (upper - lower).max(DVec2::splat(1e-12));
    let mut r = position(p)? - target.target_m;
    let mut damping = 1e-3;
    let mut iterations = 0;
    while iterations < REACH_STEPS && r.length() > REACH_TOL_M {
        iterations += 1;
        // Jacobian columns by central differences (one-sided at the box's walls).
        let mut columns = [DVec3::ZERO; 2];
        for (k, column) in columns.iter_mut().enumerate().take(dims) {
            let h = 1e-5 * span[k];
            let (mut a, mut b) = (p, p);
            a[k] = (p[k] - h).max(lower[k]);
            b[k] = (p[k] + h).min(upper[k]);
            *column = (position(b)? - position(a)?) / (b[k] - a[k]).max(f64::MIN_POSITIVE);
        }
        let jtj = DMat2::from_cols(
            DVec2::new(columns[0].dot(columns[0]), columns[1].dot(columns[0])),
            DVec2::new(columns[0].dot(columns[1]), columns[1].dot(columns[1])),
        );
        let jtr = DVec2::new(columns[0].dot(r), columns[1].dot(r));
        let mut accepted = false;
        while !accepted && damping < 1e12 {
            // Unused second axis: an identity row keeps the system regular.
            let pad = if dims == 1 { DVec2::new(0.0, 1.0) } else { DVec2::ZERO };
            let diag = DVec2::new(jtj.x_axis.x, jtj.y_axis.y) * damping + pad + DVec2::splat(1e-18);
            let system = jtj + DMat2::from_diagonal(diag);
            let step = -(system.inverse() * jtr);
            let next = (p + step).clamp(lower, upper);
            let r_next = position(next)? - target.target_m;
            if r_next.length() < r.length() {
                (p, r, accepted) = (next, r_next, true);
                damping = (damping / 3.0).max(1e-9);
            } else {
                damping *= 4.0;
            }
        }
        if !accepted {
            break;
        }
    }
    let params = [p.x, p.y][..dims].to_vec();
    Ok(Reached { params, miss_m: r.length(), iterations })
}

/// Buffers for one frame's blended pose and its forward kinematics.
#[derive(Default)]
struct Scratch {
    rotations: Vec<Quat>,
    translations: Vec<Vec3>,
    world: Vec<Transform>,
}

impl Scratch {
    /// World position of `target.joint` at `target.frame` in `cell`'s blend, metres.
    fn position(&mut self, cell: &Cell<'_>, target: &ReachTarget) -> Result<DVec3, BlendError> {
        let clip = cell.corners[0];
        let joints = clip.joint_count();
        if target.joint >= joints {
            return Err(BlendError::Joint { joint: target.joint, joints });
        }
        if target.frame >= clip.frame_count() {
            return Err(BlendError::Frame { frame: target.frame, frames: clip.frame_count() });
        }
        self.rotations.resize(joints, Quat::IDENTITY);
        self.translations.resize(joints, Vec3::ZERO);
        self.world.resize(joints, Transform::IDENTITY);
        cell.pose(target.frame, &mut self.rotations, &mut self.translations);
        pose_world(clip.skeleton(), &self.rotations, &self.translations, &mut self.world);
        Ok(self.world[target.joint].translation.as_dvec3())
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::model::{FamilyKind, FamilySample, ImportScale, Joint, Skeleton};

    /// A two-joint figure whose sample at (u, v) has its root at (u, 1, v) m, turned
    /// (0.5 u + 0.3 v) rad about Z, with its hand 1 m along the root's X, on each of 3 frames.
    fn sample(skeleton: &Arc<Skeleton>, u: f64, v: f64) -> FamilySample {
        let arm = Quat::from_rotation_z((0.5 * u + 0.3 * v) as f32);
        let root = Vec3::new(u as f32, 1.0, v as f32);
        let rotations = [arm, Quat::IDENTITY].repeat(3);
        let translations = [root, Vec3::X].repeat(3);
        let clip = Clip::new(skeleton.clone(), 30.0, rotations, translations, ImportScale::METRES).unwrap();
        FamilySample {
            params: vec![u, v],
            offset_m: DVec3::ZERO,
            turn_rad: 0.0,
            outcome: SampleOutcome::Solved(Arc::new(clip)),
        }
    }

    fn grid() -> Family {
        let skeleton = Arc::new(
            Skeleton::new(vec![Joint::new("Hips", None, Vec3::Y), Joint::new("Hand", Some(0), Vec3::X)]).unwrap(),
        );
        let axes = vec![vec![-0.5, 0.0, 0.5], vec![-0.4, 0.4]];
        let samples =
            axes[0].iter().flat_map(|&u| axes[1].iter().map(|&v| sample(&skeleton, u, v)).collect::<Vec<_>>());
        Family {
            kind: FamilyKind::Grid,
            stage: 1,
            forward: DVec3::X,
            side: DVec3::NEG_Z,
            centre_m: DVec3::ZERO,
            samples: samples.collect(),
            axes,
        }
    }

    /// The hand of the figure at (u, v), by hand: root + R_z(0.5 u + 0.3 v) · (1, 0, 0).
    fn hand(u: f64, v: f64) -> DVec3 {
        let a = 0.5 * u + 0.3 * v;
        DVec3::new(u + a.cos(), 1.0 + a.sin(), v)
    }

    #[test]
    fn a_blend_at_a_grid_point_is_that_sample_and_between_points_follows_the_cell() {
        let family = grid();
        let at = blend_family(&family, &[0.5, -0.4]).unwrap();
        let SampleOutcome::Solved(own) = &family.sample_at(&[2, 0]).unwrap().outcome else { panic!() };
        assert_eq!(at.translations(), own.translations());
        for (a, b) in at.rotations().iter().zip(own.rotations()) {
            assert!(a.angle_between(*b) < 1e-6);
        }
        // Inside a cell the root is interpolated bilinearly, and slerp about one axis turns
        // it by the interpolated angle: the hand lands where the figure at (u, v) has it.
        let (u, v) = (0.3, 0.1);
        let mid = blend_family(&family, &[u, v]).unwrap();
        let p = forward_kinematics_position(&mid, 1, 2);
        assert!((p - hand(u, v)).length() < 1e-6, "{p} vs {}", hand(u, v));
    }

    fn forward_kinematics_position(clip: &Clip, joint: usize, frame: usize) -> DVec3 {
        crate::model::forward_kinematics(clip).position(frame, joint).as_dvec3()
    }

    #[test]
    fn outside_the_range_and_failed_corners_are_refused_by_name() {
        let mut family = grid();
        assert_eq!(
            blend_family(&family, &[0.0, 0.5]).unwrap_err(),
            BlendError::Outside { axis: 1, value: 0.5, from: -0.4, to: 0.4 }
        );
        assert_eq!(blend_family(&family, &[0.0]).unwrap_err(), BlendError::Dimensions { got: 1, want: 2 });
        family.samples[0].outcome = SampleOutcome::Failed("did not converge".into());
        let err = blend_family(&family, &[-0.25, 0.0]).unwrap_err();
        assert_eq!(err, BlendError::FailedSample { params: vec![-0.5, -0.4], reason: "did not converge".into() });
        // The other cell does not need the failed sample.
        assert!(blend_family(&family, &[0.25, 0.0]).is_ok());
    }

    #[test]
    fn reach_finds_the_parameters_that_put_the_hand_on_a_known_point() {
        let family = grid();
        // Between grid points on both axes; the answer is known by construction.
        let (u, v) = (0.37, -0.21);
        let target = ReachTarget { joint: 1, frame: 1, target_m: hand(u, v) };
        let found = reach(&family, &target).unwrap();
        assert!(found.miss_m < 1e-4, "{found:?}");
        assert!((found.params[0] - u).abs() < 1e-3 && (found.params[1] - v).abs() < 1e-3, "{found:?}");
        // Out of reach: the closest point of the family's box, on its wall.
        let far = ReachTarget { target_m: hand(2.0, 0.0), ..target };
        let clamped = reach(&family, &far).unwrap();
        assert!((clamped.params[0] - 0.5).abs() < 1e-6 && clamped.miss_m > 1.0, "{clamped:?}");
        let bad = ReachTarget { joint: 7, ..target };
        assert_eq!(reach(&family, &bad).unwrap_err(), BlendError::Joint { joint: 7, joints: 2 });
    }
}
