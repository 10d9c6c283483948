//! Clip editing: trimming and resampling.

use std::sync::Arc;

use crate::kernels::resample::resample;
use crate::model::Clip;
use crate::node::{FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Registry};

/// Registers the clip editing nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Trim));
    registry.add(Box::new(Resample));
}

/// Why a trim range keeps no frame.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TrimError {
    /// The range ends before it starts (seconds).
    #[error("end {end_secs} s comes before start {start_secs} s")]
    EndBeforeStart {
        /// Start, seconds.
        start_secs: f64,
        /// End, seconds.
        end_secs: f64,
    },
    /// The range starts after the clip's last frame (seconds).
    #[error("the range starts at {start_secs} s, after the clip ends ({duration_secs:.3} s)")]
    AfterTheEnd {
        /// Start, seconds.
        start_secs: f64,
        /// The clip's duration, seconds.
        duration_secs: f64,
    },
}

/// Frames from `start_secs` to `end_secs` (inclusive, rounded to the nearest frame;
/// `end_secs = None` keeps the rest). Fails when the range is empty.
pub fn trim(clip: &Clip, start_secs: f64, end_secs: Option<f64>) -> Result<Clip, TrimError> {
    let last = clip.frame_count().saturating_sub(1) as f64;
    let first = (start_secs * clip.fps()).round().clamp(0.0, last.max(0.0)) as usize;
    let end = match end_secs {
        Some(end_secs) if end_secs < start_secs => return Err(TrimError::EndBeforeStart { start_secs, end_secs }),
        Some(e) => (e * clip.fps()).round().clamp(0.0, last) as usize + 1,
        None => clip.frame_count(),
    };
    if clip.frame_count() == 0 || first >= end || start_secs > clip.duration_secs() + 0.5 / clip.fps() {
        return Err(TrimError::AfterTheEnd { start_secs, duration_secs: clip.duration_secs() });
    }
    Ok(clip.slice(first, end))
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The clip to edit.");
const OUT: Output<Arc<Clip>> = Output::new("clip", "The edited clip.");
const START: FloatParam =
    FloatParam::new("start_secs", "First kept moment, seconds from the clip's start.", 0.0, 0.0, 1e6, "s");
const END: FloatParam = FloatParam::optional(
    "end_secs",
    "Last kept moment, seconds from the clip's start; unset keeps the rest.",
    0.0,
    1e6,
    "s",
);

/// `clip.trim`.
pub struct Trim;

static TRIM: NodeSchema = NodeSchema {
    kind: "clip.trim",
    category: "clip",
    doc: "Keeps the frames between a start and an end time.",
    inputs: &[CLIP.spec()],
    outputs: &[OUT.spec()],
    params: &[START.0, END.0],
    writes_files: false,
    version: 1,
};

impl Node for Trim {
    fn schema(&self) -> &'static NodeSchema {
        &TRIM
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let out = trim(&clip, ctx.float(&START)?, ctx.optional_float(&END)?).map_err(NodeError::kernel)?;
        ctx.set_output(&OUT, Arc::new(out));
        Ok(())
    }
}

const FPS: FloatParam = FloatParam::new("fps", "New frame rate, frames per second.", 30.0, 1.0, 1000.0, "fps");

/// `clip.resample`.
pub struct Resample;

static RESAMPLE: NodeSchema = NodeSchema {
    kind: "clip.resample",
    category: "clip",
    doc: "Changes the frame rate, interpolating rotations along the shortest arc.",
    inputs: &[CLIP.spec()],
    outputs: &[OUT.spec()],
    params: &[FPS.0],
    writes_files: false,
    version: 1,
};

impl Node for Resample {
    fn schema(&self) -> &'static NodeSchema {
        &RESAMPLE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let fps = ctx.float(&FPS)?;
        let frames = (clip.duration_secs() * fps).ceil() as usize + 1;
        ctx.reserve_memory(Clip::estimated_bytes(frames, clip.joint_count()), FPS.0.name)?;
        let out = resample(&clip, fps).map_err(NodeError::kernel)?;
        ctx.set_output(&OUT, Arc::new(out));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ImportScale, Joint, Skeleton};
    use glam::{Quat, Vec3};

    /// One joint turning about Y at 1 rad/s and moving along X at 1 m/s, sampled at `fps`.
    fn turning(fps: f64, frames: usize) -> Clip {
        let skeleton = Arc::new(Skeleton::new(vec![Joint::new("root", None, Vec3::ZERO)]).unwrap());
        let t = |i: usize| i as f64 / fps;
        let rotations = (0..frames).map(|i| Quat::from_rotation_y(t(i) as f32)).collect();
        let translations = (0..frames).map(|i| Vec3::new(t(i) as f32, 0.0, 0.0)).collect();
        Clip::new(skeleton, fps, rotations, translations, ImportScale::METRES).unwrap()
    }

    /// Component-wise comparison (acos-based angles lose precision near zero in f32).
    fn same_rotation(a: Quat, b: Quat) -> bool {
        (a - b).length() < 1e-5 || (a + b).length() < 1e-5
    }

    #[test]
    fn resampling_a_constant_rate_turn_matches_the_analytic_motion() {
        let clip = turning(120.0, 121); // exactly 1 s
        let out = resample(&clip, 30.0).unwrap();
        assert_eq!(out.frame_count(), 31);
        for i in 0..out.frame_count() {
            let t = i as f32 / 30.0;
            assert!(same_rotation(out.frame_rotations(i)[0], Quat::from_rotation_y(t)));
            assert!((out.frame_translations(i)[0].x - t).abs() < 1e-5);
        }
        // Up-sampling between samples is exact for a constant-rate turn too.
        let up = resample(&turning(10.0, 11), 100.0).unwrap();
        assert_eq!(up.frame_count(), 101);
        assert!(same_rotation(up.frame_rotations(55)[0], Quat::from_rotation_y(0.55)));
    }

    #[test]
    fn resample_rejects_bad_rates_and_keeps_empty_clips_empty() {
        assert!(resample(&turning(30.0, 5), 0.0).is_err());
        assert_eq!(resample(&turning(30.0, 0), 60.0).unwrap().frame_count(), 0);
    }

    #[test]
    fn trim_keeps_the_inclusive_range_and_refuses_empty_ones() {
        let clip = turning(10.0, 21); // 2 s
        let out = trim(&clip, 0.5, Some(1.0)).unwrap();
        assert_eq!(out.frame_count(), 6);
        assert!((out.frame_translations(0)[0].x - 0.5).abs() < 1e-6);
        assert_eq!(trim(&clip, 1.5, None).unwrap().frame_count(), 6);
        assert!(trim(&clip, 1.0, Some(0.5)).is_err());
        assert!(trim(&clip, 5.0, None).is_err());
        assert!(trim(&turning(10.0, 0), 0.0, None).is_err());
    }
}
