//! Animation clips: per-frame local joint transforms on a shared skeleton.

use std::sync::Arc;

use glam::{Quat, Vec3};

use super::skeleton::Skeleton;
use super::units::{ImportScale, memory_size};

/// Translations further than this (metres) from the rest offset count as animated.
pub const ANIMATED_TRANSLATION_M: f32 = 1e-7;

/// Why clip data is inconsistent.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClipError {
    /// Frame rate is not a positive finite number.
    #[error("frame rate must be positive and finite, got {fps}")]
    BadFrameRate {
        /// The rejected rate (frames per second).
        fps: f64,
    },
    /// Buffers do not hold `frames × joints` entries.
    #[error("clip data has {got} entries, expected {frames} frames × {joints} joints")]
    BadLength {
        /// Entries given.
        got: usize,
        /// Frame count.
        frames: usize,
        /// Joint count.
        joints: usize,
    },
    /// The skeleton the clip would need is invalid.
    #[error(transparent)]
    Skeleton(#[from] super::SkeletonError),
    /// A rotation is NaN, infinite or zero, or a translation is not finite or beyond
    /// ±[`super::MAX_COORDINATE_M`].
    #[error(
        "non-finite or out-of-range value at frame {frame}, joint '{joint}' (translations must stay within ±1e6 m)"
    )]
    NonFinite {
        /// Frame index.
        frame: usize,
        /// Joint name.
        joint: String,
    },
}

/// An animation: for every frame and joint, the joint's local rotation and translation
/// relative to its parent.
///
/// Storage is frame-major (`[frame * joints + joint]`) because blending, FK and export all
/// walk a frame at a time. Translations are metres and include the rest offset, so joints
/// without animated translation simply repeat it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Clip {
    skeleton: Arc<Skeleton>,
    fps: f64,
    frames: usize,
    rotations: Vec<Quat>,
    translations: Vec<Vec3>,
    /// How the source file's lengths were converted to metres.
    pub import_scale: ImportScale,
}

/// Largest clip a file reader samples when not given the run's memory limit: 1.4 GB of
/// rotations and translations (5e7 samples, an 855 s clip of 58 joints at 1,000 fps). A
/// few kilobytes of keys claiming hours must not make a reader ask for gigabytes.
pub const DEFAULT_MAX_SAMPLED_BYTES: u64 = 50_000_000 * SAMPLE_BYTES;

/// Bytes of one joint's local transform in one frame: a rotation and a translation.
const SAMPLE_BYTES: u64 = 16 + 12;

/// Bytes of `frames` frames of `joints` local transforms (a clip's own arrays).
pub fn sampled_bytes(frames: f64, joints: usize) -> f64 {
    frames * (joints as u64 * SAMPLE_BYTES) as f64
}

/// Why a reader must not sample `frames` frames (as computed from the file, possibly huge
/// or not finite) of `joints` joints within `max_bytes` (default
/// [`DEFAULT_MAX_SAMPLED_BYTES`]), or `None` when it may; `rate_param` names the param that
/// sets the sampling rate, for the way out.
pub fn sampling_refusal(frames: f64, joints: usize, max_bytes: Option<u64>, rate_param: &str) -> Option<String> {
    let limit = max_bytes.unwrap_or(DEFAULT_MAX_SAMPLED_BYTES);
    let bytes = sampled_bytes(frames, joints);
    if frames.is_finite() && bytes <= limit as f64 {
        return None;
    }
    Some(format!(
        "{frames:.0} frames of {joints} joints need about {}, more than the limit of {} (kg --max-memory, or a lower {rate_param})",
        memory_size(bytes),
        memory_size(limit as f64)
    ))
}

impl Clip {
    /// Bytes of the rotations and translations of `frames` frames of `joints` joints: the
    /// estimate nodes check before making a clip whose length comes from their params.
    pub fn estimated_bytes(frames: usize, joints: usize) -> u64 {
        (frames as u64).saturating_mul(joints as u64).saturating_mul(SAMPLE_BYTES)
    }

    /// Builds a clip after checking the frame rate, buffer sizes and finiteness.
    /// Rotations are renormalised (files carry rounding).
    pub fn new(
        skeleton: Arc<Skeleton>,
        fps: f64,
        rotations: Vec<Quat>,
        translations: Vec<Vec3>,
        import_scale: ImportScale,
    ) -> Result<Self, ClipError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(ClipError::BadFrameRate { fps });
        }
        let joints = skeleton.len();
        if rotations.len() != translations.len() || !rotations.len().is_multiple_of(joints) {
            return Err(ClipError::BadLength {
                got: rotations.len().max(translations.len()),
                frames: rotations.len() / joints,
                joints,
            });
        }
        let frames = rotations.len() / joints;
        let mut rotations = rotations;
        for (i, (q, t)) in rotations.iter_mut().zip(&translations).enumerate() {
            let length_sq = q.length_squared();
            if !q.is_finite() || !super::coordinate_in_range(*t) || length_sq < 1e-12 {
                return Err(ClipError::NonFinite {
                    frame: i / joints,
                    joint: skeleton.joints()[i % joints].name.clone(),
                });
            }
            // Only rescale what is visibly off unit length (most sources are exact).
            if (length_sq - 1.0).abs() > 1e-6 {
                *q *= length_sq.sqrt().recip();
            }
        }
        Ok(Clip { skeleton, fps, frames, rotations, translations, import_scale })
    }

    /// A clip of `frames` frames holding the skeleton's rest pose.
    pub fn rest_pose(skeleton: Arc<Skeleton>, fps: f64, frames: usize) -> Result<Self, ClipError> {
        let rotations: Vec<Quat> =
            (0..frames).flat_map(|_| skeleton.joints().iter().map(|j| j.rest_rotation)).collect();
        let translations: Vec<Vec3> =
            (0..frames).flat_map(|_| skeleton.joints().iter().map(|j| j.rest_offset)).collect();
        Clip::new(skeleton, fps, rotations, translations, ImportScale::METRES)
    }

    /// The skeleton every frame animates.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// Frames per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames
    }

    /// Number of joints per frame.
    pub fn joint_count(&self) -> usize {
        self.skeleton.len()
    }

    /// Length in seconds from the first to the last frame.
    pub fn duration_secs(&self) -> f64 {
        self.frames.saturating_sub(1) as f64 / self.fps
    }

    /// Local rotations of every joint at `frame`.
    pub fn frame_rotations(&self, frame: usize) -> &[Quat] {
        let j = self.joint_count();
        &self.rotations[frame * j..(frame + 1) * j]
    }

    /// Local translations (metres) of every joint at `frame`.
    pub fn frame_translations(&self, frame: usize) -> &[Vec3] {
        let j = self.joint_count();
        &self.translations[frame * j..(frame + 1) * j]
    }

    /// All local rotations, frame-major.
    pub fn rotations(&self) -> &[Quat] {
        &self.rotations
    }

    /// All local translations (metres), frame-major.
    pub fn translations(&self) -> &[Vec3] {
        &self.translations
    }

    /// The root's translation (metres) at every frame.
    pub fn root_translations(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.translations.iter().step_by(self.joint_count()).copied()
    }

    /// The same motion with the whole scene rotated by `world_rotation` about the origin:
    /// every root joint's rest transform and per-frame transform is pre-multiplied, so
    /// world positions become `world_rotation * p`. Used for up-axis conversion and, later,
    /// facing alignment.
    pub fn rotated(&self, world_rotation: Quat) -> Result<Clip, ClipError> {
        let r = crate::math::quat_normalize_or_identity(world_rotation);
        let mut joints = self.skeleton.joints().to_vec();
        for joint in joints.iter_mut().filter(|j| j.parent.is_none()) {
            joint.rest_offset = r * joint.rest_offset;
            joint.rest_rotation = r * joint.rest_rotation;
        }
        let skeleton = Skeleton::new(joints)?;
        let roots: Vec<bool> = self.skeleton.joints().iter().map(|j| j.parent.is_none()).collect();
        let n = self.joint_count();
        let rotations =
            self.rotations.iter().enumerate().map(|(i, q)| if roots[i % n] { r * *q } else { *q }).collect();
        let translations =
            self.translations.iter().enumerate().map(|(i, t)| if roots[i % n] { r * *t } else { *t }).collect();
        Clip::new(Arc::new(skeleton), self.fps, rotations, translations, self.import_scale)
    }

    /// Whether joint `joint`'s translation leaves its rest offset by more than
    /// [`ANIMATED_TRANSLATION_M`] on some frame: exporters give such joints position
    /// channels.
    pub fn translation_is_animated(&self, joint: usize) -> bool {
        self.translation_leaves(joint, self.skeleton.joints()[joint].rest_offset)
    }

    /// Whether joint `joint`'s translation leaves `rest` (metres) by more than
    /// [`ANIMATED_TRANSLATION_M`] on some frame: a clip exported over another skeleton's
    /// rest offsets (several animations in one file) needs position channels there.
    pub fn translation_leaves(&self, joint: usize, rest: Vec3) -> bool {
        (0..self.frames)
            .any(|f| (self.frame_translations(f)[joint] - rest).abs().max_element() > ANIMATED_TRANSLATION_M)
    }

    /// Frames `start..end` (clamped to the clip) as a new clip at the same rate.
    pub fn slice(&self, start: usize, end: usize) -> Clip {
        let end = end.min(self.frames);
        let start = start.min(end);
        let j = self.joint_count();
        Clip {
            skeleton: self.skeleton.clone(),
            fps: self.fps,
            frames: end - start,
            rotations: self.rotations[start * j..end * j].to_vec(),
            translations: self.translations[start * j..end * j].to_vec(),
            import_scale: self.import_scale,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::skeleton::Joint;

    fn two_joint() -> Arc<Skeleton> {
        Arc::new(Skeleton::new(vec![Joint::new("a", None, Vec3::ZERO), Joint::new("b", Some(0), Vec3::Y)]).unwrap())
    }

    #[test]
    fn rejects_bad_rate_length_and_nan() {
        let s = two_joint();
        let q = vec![Quat::IDENTITY; 4];
        let t = vec![Vec3::ZERO; 4];
        assert!(matches!(
            Clip::new(s.clone(), 0.0, q.clone(), t.clone(), ImportScale::METRES),
            Err(ClipError::BadFrameRate { .. })
        ));
        assert!(matches!(
            Clip::new(s.clone(), -30.0, q.clone(), t.clone(), ImportScale::METRES),
            Err(ClipError::BadFrameRate { .. })
        ));
        assert!(matches!(
            Clip::new(s.clone(), 30.0, q[..3].to_vec(), t[..3].to_vec(), ImportScale::METRES),
            Err(ClipError::BadLength { .. })
        ));
        let mut tn = t.clone();
        tn[3] = Vec3::new(f32::NAN, 0.0, 0.0);
        assert!(matches!(Clip::new(s, 30.0, q, tn, ImportScale::METRES), Err(ClipError::NonFinite { frame: 1, .. })));
    }

    #[test]
    fn empty_clip_is_valid_and_has_zero_duration() {
        let c = Clip::rest_pose(two_joint(), 30.0, 0).unwrap();
        assert_eq!(c.frame_count(), 0);
        assert_eq!(c.duration_secs(), 0.0);
        assert_eq!(c.slice(0, 10).frame_count(), 0);
    }

    #[test]
    fn rotating_the_clip_rotates_every_world_position() {
        let skeleton = Arc::new(
            Skeleton::new(vec![Joint::new("a", None, Vec3::new(0.0, 0.0, 1.0)), Joint::new("b", Some(0), Vec3::X)])
                .unwrap(),
        );
        let rotations = vec![Quat::from_rotation_y(0.4), Quat::from_rotation_x(0.3), Quat::IDENTITY, Quat::IDENTITY];
        let translations = vec![Vec3::new(0.0, 0.0, 1.0), Vec3::X, Vec3::new(0.5, 0.2, 1.0), Vec3::X];
        let clip = Clip::new(skeleton, 30.0, rotations, translations, ImportScale::METRES).unwrap();
        let r = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
        let rotated = clip.rotated(r).unwrap();
        let (a, b) = (crate::model::forward_kinematics(&clip), crate::model::forward_kinematics(&rotated));
        for f in 0..2 {
            for j in 0..2 {
                assert!((b.position(f, j) - r * a.position(f, j)).length() < 1e-6);
            }
        }
        // Z up becomes Y up.
        assert!((b.position(0, 0) - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn slice_keeps_rate_and_frames() {
        let c = Clip::rest_pose(two_joint(), 120.0, 10).unwrap();
        let s = c.slice(2, 5);
        assert_eq!(s.frame_count(), 3);
        assert_eq!(s.fps(), 120.0);
        assert!((c.duration_secs() - 9.0 / 120.0).abs() < 1e-12);
    }
}
