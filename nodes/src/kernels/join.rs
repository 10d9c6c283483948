//! Joining two clips: the blend-and-splice (Shum et al. 2009, eq. 8), the skeleton check,
//! the foot-skate measure and the result and error types. A kernel: the momentum-guided
//! join (`motion.concat`) and the Motion-Graphs crossfade baseline share them.

use glam::{DVec3, Quat, Vec3};

use super::analysis::Analysis;
use super::contacts::ground_height;
use super::ik::foot_lock::HoldError;
use crate::math::{slerp_short, smootherstep, smoothstep};
use crate::model::{Clip, ClipError, FrameRange, Report};

/// Why two clips were not concatenated.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConcatError {
    /// Blending needs one skeleton.
    #[error("the clips use different skeletons ({0}); retarget one onto the other first")]
    DifferentSkeletons(String),
    /// No blendable period under the rule.
    #[error("no blendable period under the {rule} rule: {why}")]
    NoBlendablePeriod {
        /// `"forward"` or `"reverse"`.
        rule: &'static str,
        /// What is missing.
        why: String,
    },
    /// The best timing still costs too much.
    #[error(
        "the motions are too different to blend: best relative cost {relative_cost:.3} exceeds {threshold} \
         (F_dm {f_dm:.3}, F_inertia {f_inertia:.3}, F_time {f_time:.3}); raise max_relative_cost or try the other rule"
    )]
    TooDifferent {
        /// F over the squared peak momenta.
        relative_cost: f64,
        /// The limit.
        threshold: f64,
        /// Momentum difference term.
        f_dm: f64,
        /// Inertia term.
        f_inertia: f64,
        /// Timing term.
        f_time: f64,
    },
    /// The torsos face too differently.
    #[error(
        "after alignment the torsos are turned {angle_deg:.1}° apart where the blend starts, more than {max_deg:.1}°: \
         these motions do not chain in this order"
    )]
    Facing {
        /// Angle found, degrees.
        angle_deg: f64,
        /// Limit, degrees.
        max_deg: f64,
    },
    /// Building a clip failed.
    #[error(transparent)]
    Clip(#[from] ClipError),
    /// The feet could not be held after the blend.
    #[error("the foot clean-up after the blend failed: {0} (set foot_lock off to skip it)")]
    FootLock(#[source] HoldError),
}

/// Concatenation result: the clip and the report of every decision.
#[derive(Clone, Debug)]
pub struct Concatenated {
    /// The joined clip, at the first clip's frame rate.
    pub clip: Clip,
    /// What was decided and measured.
    pub report: Report,
}

/// Blends `first` frames `f0..=ff` with `second` frames `f0−T..=ff−T` and splices. The
/// weight α of `first` falls from 1 to 0 over the window by a smooth ramp rather than eq.
/// 8's straight line, which switches the blend's velocity term on and off in one frame so
/// joint velocities jump at both window edges. Joint rotations take a smoothstep (C1). The
/// translations (the root's path) take a smootherstep (C2): with the two clips' roots apart
/// (a short window; a placement that matches feet, not roots) a smoothstep still switches
/// the root's acceleration on in one frame, a root-velocity jump of 2.3× the sources'
/// largest one-frame change on kick_kick, 1.5× with the smootherstep. The rotations keep the
/// smoothstep: the smootherstep's steeper middle turns a blend in the air faster, and
/// raised the double cartwheel's angular momentum in the blend above the clips' own peaks.
/// Frames: `first[..f0]`, the blend, `second[ff−T+1..]`. `second` must already be placed
/// and on the same skeleton and rate.
pub fn splice(first: &Clip, second: &Clip, f0: usize, ff: usize, offset: isize) -> Result<Clip, ClipError> {
    let joints = first.joint_count();
    let tail_start = (ff as isize - offset + 1).max(0) as usize;
    let frames = f0 + (ff - f0 + 1) + second.frame_count().saturating_sub(tail_start);
    let mut rotations: Vec<Quat> = Vec::with_capacity(frames * joints);
    let mut translations: Vec<Vec3> = Vec::with_capacity(frames * joints);
    for f in 0..f0 {
        rotations.extend_from_slice(first.frame_rotations(f));
        translations.extend_from_slice(first.frame_translations(f));
    }
    let last_second = second.frame_count().saturating_sub(1);
    for f in f0..=ff {
        let u = if ff > f0 { (f - f0) as f64 / (ff - f0) as f64 } else { 1.0 };
        let (alpha, alpha_path) = (1.0 - smoothstep(u) as f32, 1.0 - smootherstep(u) as f32);
        let g = ((f as isize - offset).max(0) as usize).min(last_second);
        let (ra, rb) = (first.frame_rotations(f), second.frame_rotations(g));
        let (ta, tb) = (first.frame_translations(f), second.frame_translations(g));
        rotations.extend(ra.iter().zip(rb).map(|(a, b)| slerp_short(*b, *a, alpha)));
        translations.extend(ta.iter().zip(tb).map(|(a, b)| b.lerp(*a, alpha_path)));
    }
    for g in tail_start..second.frame_count() {
        rotations.extend_from_slice(second.frame_rotations(g));
        translations.extend_from_slice(second.frame_translations(g));
    }
    Clip::new(first.skeleton().clone(), first.fps(), rotations, translations, first.import_scale)
}

/// Checks that two clips share a skeleton (names and hierarchy).
pub fn same_skeleton(a: &Clip, b: &Clip) -> Result<(), ConcatError> {
    let (ja, jb) = (a.skeleton().joints(), b.skeleton().joints());
    if ja.len() != jb.len() {
        return Err(ConcatError::DifferentSkeletons(format!("{} joints vs {}", ja.len(), jb.len())));
    }
    match ja.iter().zip(jb).find(|(x, y)| x.name != y.name || x.parent != y.parent) {
        Some((x, y)) => Err(ConcatError::DifferentSkeletons(format!("joint '{}' vs '{}'", x.name, y.name))),
        None => Ok(()),
    }
}

/// Horizontal sliding of planted feet over `frames` of `analysis`: for each ankle, the
/// horizontal distance travelled while it is within `height_m` of its rest height, metres
/// (summed over both feet).
pub fn foot_skate_m(analysis: &Analysis, frames: FrameRange, height_m: f64) -> f64 {
    let poses = &analysis.poses;
    let mut total = 0.0;
    for ankle in analysis.landmarks.feet() {
        let track: Vec<DVec3> = (0..poses.frame_count()).map(|f| poses.position(f, ankle).as_dvec3()).collect();
        let ground = ground_height(&track);
        for f in frames.start.max(1)..frames.end.min(track.len()) {
            if track[f].y - ground < height_m {
                let d = track[f] - track[f - 1];
                total += DVec3::new(d.x, 0.0, d.z).length();
            }
        }
    }
    total
}
