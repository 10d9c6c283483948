//! The Motion-Graphs join the paper compares against (Kovar et al. 2002, as described by
//! Shum et al. 2009): cut where the poses of the two clips are most alike, align the second
//! clip's heading and position to the first there, and crossfade briefly. Poses are
//! compared as joint positions in each body's own heading frame (invariant to where the
//! character stands and which way it faces) at the start, middle and end of the crossfade.
//!
//! A kernel: the `motion.concat_baseline` node runs it, and the transitions compare their
//! smoothness against it.

use std::sync::Arc;

use glam::Vec3;
use serde_json::json;

use super::align::{place, torso_facing};
use super::analysis::{Analysis, AnalysisOptions};
use super::join::{ConcatError, Concatenated, foot_skate_m, same_skeleton, splice};
use crate::model::{ClipPoses, FrameRange, into_report};

/// Settings of the baseline join.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaselineParams {
    /// The cut is searched in the last this share of the first clip and the first this
    /// share of the second (0..=1).
    pub search_share: f64,
    /// Crossfade length, seconds.
    pub crossfade_secs: f64,
}

impl Default for BaselineParams {
    fn default() -> Self {
        BaselineParams { search_share: 0.25, crossfade_secs: 0.25 }
    }
}

/// Yaw of the torso facing at `frame` (radians about +Y from +Z), 0 when degenerate.
fn facing_yaw(analysis: &Analysis, frame: usize) -> f64 {
    torso_facing(&analysis.poses, frame, &analysis.landmarks).map_or(0.0, |v| f64::from(v.x.atan2(v.z)))
}

/// Joint positions at `frame` relative to the root's ground point, turned so the torso
/// faces +Z.
fn body_frame_pose(analysis: &Analysis, poses: &ClipPoses, frame: usize) -> Vec<Vec3> {
    let root = poses.position(frame, 0);
    let turn = glam::Quat::from_rotation_y(-facing_yaw(analysis, frame) as f32);
    poses.frame(frame).iter().map(|t| turn * (t.translation - Vec3::new(root.x, 0.0, root.z))).collect()
}

/// Joins `a` and `b` at their most similar poses with a crossfade.
pub fn concatenate_baseline(
    a: &Analysis,
    b: &Analysis,
    params: &BaselineParams,
    options: &AnalysisOptions,
) -> Result<Concatenated, ConcatError> {
    same_skeleton(&a.clip, &b.clip)?;
    let fps = a.clip.fps();
    let (n1, n2) = (a.clip.frame_count(), b.clip.frame_count());
    let fade = ((params.crossfade_secs * fps).round() as usize).clamp(1, n1.min(n2).saturating_sub(1).max(1));
    let share = params.search_share.clamp(0.0, 1.0);
    let first_from = ((n1 as f64 * (1.0 - share)) as usize).min(n1.saturating_sub(fade + 1));
    let first_to = n1.saturating_sub(fade);
    let second_to = ((n2 as f64 * share).ceil() as usize).clamp(1, n2.saturating_sub(fade).max(1));
    let pose_a: Vec<Vec<Vec3>> = (0..n1).map(|f| body_frame_pose(a, &a.poses, f)).collect();
    let pose_b: Vec<Vec<Vec3>> = (0..n2).map(|f| body_frame_pose(b, &b.poses, f)).collect();
    let distance = |i: usize, j: usize| -> f64 {
        [0, (fade - 1) / 2, fade - 1]
            .iter()
            .map(|&k| {
                let (p, q) = (&pose_a[(i + k).min(n1 - 1)], &pose_b[(j + k).min(n2 - 1)]);
                p.iter().zip(q).map(|(x, y)| f64::from(x.distance_squared(*y))).sum::<f64>()
            })
            .sum()
    };
    let mut best = (first_from, 0, f64::INFINITY);
    for i in first_from..first_to.max(first_from + 1) {
        for j in 0..second_to {
            let d = distance(i, j);
            if d < best.2 {
                best = (i, j, d);
            }
        }
    }
    let (i, j, d) = best;
    // Align heading and ground position of the second clip to the first at the cut.
    let yaw = facing_yaw(a, i) - facing_yaw(b, j);
    let turn = glam::Quat::from_rotation_y(yaw as f32);
    let (ra, rb) = (a.poses.position(i, 0), turn * b.poses.position(j, 0));
    let offset_m = Vec3::new(ra.x - rb.x, 0.0, ra.z - rb.z);
    let placed = place(&b.clip, yaw, offset_m)?;
    let offset = i as isize - j as isize;
    let (f0, ff) = (i, (i + fade - 1).min(n1 - 1));
    let out = Arc::new(splice(&a.clip, &placed, f0, ff, offset)?);
    let result = a.reanalysed(out.clone(), options);
    let window = FrameRange::new(f0, ff + 1);
    let peak = (window.start..window.end).map(|f| result.smoothed[f].length()).fold(0.0, f64::max);
    let report = json!({
        "method": "motion graphs baseline (most similar poses, crossfade)",
        "cut_first_frame": i,
        "cut_second_frame": j,
        "cut_first_secs": i as f64 / fps,
        "cut_second_secs": j as f64 / fps,
        "pose_distance_m2": d,
        "window_frames": [f0, ff],
        "yaw_deg": yaw.to_degrees(),
        "duration_first_secs": a.clip.duration_secs(),
        "duration_second_secs": b.clip.duration_secs(),
        "duration_secs": out.duration_secs(),
        "peak_momentum_in_blend": peak,
        "foot_skate_in_blend_m": foot_skate_m(&result, window, options.contacts.enter_height_m),
    });
    Ok(Concatenated { clip: Arc::unwrap_or_clone(out), report: into_report(report) })
}
