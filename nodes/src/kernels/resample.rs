//! Resampling a clip to another frame rate. A kernel: `clip.resample`, the momentum nodes
//! (matching rates before a join), the join's time scaling and the clip-set loader use it.

use glam::{Quat, Vec3};

use crate::math::slerp_short;
use crate::model::{Clip, ClipError};

/// Appends the pose of `clip` at fractional frame `frame` (clamped to the clip; rotations
/// slerped on the short arc, translations lerped between the neighbouring frames). The
/// clip must have a frame.
pub fn push_sample(clip: &Clip, frame: f64, rotations: &mut Vec<Quat>, translations: &mut Vec<Vec3>) {
    let last = clip.frame_count().saturating_sub(1);
    let frame = frame.clamp(0.0, last as f64);
    let lo = frame.floor() as usize;
    let hi = (lo + 1).min(last);
    let t = (frame - lo as f64) as f32;
    let (ra, rb) = (clip.frame_rotations(lo), clip.frame_rotations(hi));
    let (ta, tb) = (clip.frame_translations(lo), clip.frame_translations(hi));
    rotations.extend(ra.iter().zip(rb).map(|(a, b): (&Quat, &Quat)| slerp_short(*a, *b, t)));
    translations.extend(ta.iter().zip(tb).map(|(a, b): (&Vec3, &Vec3)| a.lerp(*b, t)));
}

/// Resamples to `fps` frames per second over the same duration: rotations by spherical
/// interpolation (short arc), translations linearly. The last frame lands on the
/// original's last frame when the duration is a whole number of new frames, otherwise
/// just before it.
pub fn resample(clip: &Clip, fps: f64) -> Result<Clip, ClipError> {
    if !(fps.is_finite() && fps > 0.0) {
        return Err(ClipError::BadFrameRate { fps });
    }
    let joints = clip.joint_count();
    let frames = if clip.frame_count() == 0 { 0 } else { (clip.duration_secs() * fps + 1e-9).floor() as usize + 1 };
    let mut rotations = Vec::with_capacity(frames * joints);
    let mut translations = Vec::with_capacity(frames * joints);
    for i in 0..frames {
        let source = (i as f64 / fps * clip.fps()).min(clip.frame_count().saturating_sub(1) as f64);
        push_sample(clip, source, &mut rotations, &mut translations);
    }
    Clip::new(clip.skeleton().clone(), fps, rotations, translations, clip.import_scale)
}
