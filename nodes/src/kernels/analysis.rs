//! Everything the concatenation methods need to know about one clip, computed once:
//! world poses, landmarks, the body mass model, angular momentum, phases and contacts.
//!
//! A kernel: the momentum nodes and the transitions' crossfade comparison both analyse clips.

use std::sync::Arc;

use glam::DVec3;

use super::angular::{MomentumTrack, momentum_of_poses, smooth};
use super::body::{BodyError, BodyModel, Landmarks, MassOverride, MassTable, body_model, find_landmarks};
use super::contacts::{ContactThresholds, detect_contacts};
use super::phases::{PhaseOptions, segment_phases};
use crate::model::{Clip, ClipPoses, Contacts, FrameRange, Phases, forward_kinematics};

/// How to analyse a clip.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalysisOptions {
    /// Body mass, kilograms.
    pub total_mass_kg: f64,
    /// Anthropometric table.
    pub table: MassTable,
    /// A mapping that replaces the table, if given.
    pub mass_override: Option<MassOverride>,
    /// Half-width of the moving average applied to L before its sign is read, seconds.
    pub smoothing_secs: f64,
    /// Contact detection thresholds.
    pub contacts: ContactThresholds,
}

impl Default for AnalysisOptions {
    fn default() -> Self {
        AnalysisOptions {
            total_mass_kg: 70.0,
            table: MassTable::DeLevaMale,
            mass_override: None,
            smoothing_secs: 0.05,
            contacts: ContactThresholds::default(),
        }
    }
}

/// One analysed clip.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// The clip.
    pub clip: Arc<Clip>,
    /// World transforms of every joint at every frame.
    pub poses: ClipPoses,
    /// Named landmarks (feet, hips, shoulders).
    pub landmarks: Landmarks,
    /// Segment masses and centres.
    pub model: BodyModel,
    /// Raw angular momentum and moment arms.
    pub track: MomentumTrack,
    /// L after the moving average, kg·m²/s.
    pub smoothed: Vec<DVec3>,
    /// Phases (computed, or given by the user).
    pub phases: Phases,
    /// Foot contacts (computed, or given by the user).
    pub contacts: Contacts,
}

/// Why a clip could not be analysed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    /// The feet, hips or shoulders could not be found by joint name.
    #[error("the body landmarks could not be found by joint name (missing: {})", .0.join(", "))]
    Landmarks(Vec<String>),
    /// The mass model failed.
    #[error(transparent)]
    Body(#[from] BodyError),
    /// Too short to differentiate.
    #[error("the clip has {0} frames; at least 3 are needed")]
    TooShort(usize),
}

/// Analyses `clip`; `phases` and `contacts` replace the computed ones when given.
pub fn analyse(
    clip: Arc<Clip>,
    options: &AnalysisOptions,
    phases: Option<Phases>,
    contacts: Option<Contacts>,
) -> Result<Analysis, AnalysisError> {
    if clip.frame_count() < 3 {
        return Err(AnalysisError::TooShort(clip.frame_count()));
    }
    let landmarks = find_landmarks(clip.skeleton()).map_err(AnalysisError::Landmarks)?;
    let model = body_model(clip.skeleton(), options.total_mass_kg, options.table, options.mass_override.as_ref())?;
    let (poses, track, smoothed) = kinematics(&clip, &model, options.smoothing_secs);
    let phases = phases.unwrap_or_else(|| segment_phases(&smoothed, clip.fps(), PhaseOptions::default()));
    let contacts = contacts.unwrap_or_else(|| detect_contacts(&clip, &poses, &landmarks, &options.contacts));
    Ok(Analysis { clip, poses, landmarks, model, track, smoothed, phases, contacts })
}

/// World poses, angular momentum and its smoothed version for `clip` under `model`.
pub fn kinematics(clip: &Clip, model: &BodyModel, smoothing_secs: f64) -> (ClipPoses, MomentumTrack, Vec<DVec3>) {
    let poses = forward_kinematics(clip);
    let track = momentum_of_poses(&poses, clip.fps(), model);
    let half_width = (smoothing_secs * clip.fps()).round() as usize;
    let smoothed = smooth(&track.momentum, half_width);
    (poses, track, smoothed)
}

impl Analysis {
    /// Analyses `clip`, which must share this analysis' skeleton, reusing the landmarks and
    /// mass model (so it cannot fail); phases and contacts are carried over unchanged.
    pub fn reanalysed(&self, clip: Arc<Clip>, options: &AnalysisOptions) -> Analysis {
        let (poses, track, smoothed) = kinematics(&clip, &self.model, options.smoothing_secs);
        Analysis {
            clip,
            poses,
            landmarks: self.landmarks.clone(),
            model: self.model.clone(),
            track,
            smoothed,
            phases: self.phases.clone(),
            contacts: self.contacts.clone(),
        }
    }

    /// Peak of the smoothed |L|, kg·m²/s.
    pub fn smoothed_peak(&self) -> f64 {
        self.smoothed.iter().map(|l| l.length()).fold(0.0, f64::max)
    }

    /// Mean smoothed L over `frames` (the whole clip when they are empty).
    pub fn mean_momentum(&self, frames: FrameRange) -> DVec3 {
        let end = frames.end.min(self.smoothed.len());
        let samples = if frames.start >= end { &self.smoothed[..] } else { &self.smoothed[frames.start..end] };
        samples.iter().sum::<DVec3>() / samples.len().max(1) as f64
    }

    /// Whether `frame` lies in double support.
    pub fn in_double_support(&self, frame: usize) -> bool {
        self.contacts.double_support.iter().any(|r| r.contains(frame))
    }
}
