//! Populating a motion family (momentum-based editing, the paper's families): one ground
//! stage of a clip swept over a line, a grid or a semicircle of placements, each placement
//! optimised by [`momentum_edit`] in parallel (rayon). A sample that does not converge stays
//! in the family marked failed, with its typed error, so a blend can refuse it by name.
//!
//! Frame of reference: the jump's direction `forward` is the horizontal travel of the centre
//! of mass over the flight between the swept stage and its neighbouring ground stage (the
//! one before it, or after the first); `side` = Y × forward (the jump's left). Stages turn
//! about their pivots (mid-stage centre of mass on the floor, [`ground_pivots`]).
//! - line: offset = u · forward (u in metres);
//! - grid: offset = u · forward + v · side (metres);
//! - semicircle: the stage turns by u radians about the neighbouring stage's pivot C, so its
//!   offset is R_y(u)(c − C) − (c − C) and its turn u: same jump length, new direction, the
//!   body facing along the arc's normal.

use std::sync::Arc;

use glam::{DQuat, DVec3};
use rayon::prelude::*;

use super::angular::momentum_of_poses;
use super::momentum_edit::{GroundEdit, ground_pivots};
use super::momentum_solve::{EditSetup, SolveError, SolveOptions, SolveReport, momentum_edit};
use crate::model::choice::Choice;
use crate::model::{Family, FamilyKind, FamilySample, SampleOutcome, StageKind, forward_kinematics};

/// Most samples a family may hold (each is a full optimisation).
pub const MAX_SAMPLES: usize = 400;

/// One axis of the parameter grid: `count` evenly spaced values from `from` to `to`
/// (a single value `from` when `count` is 1; a farm task computes one sample that way).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisSweep {
    /// First value (metres, or radians for a semicircle).
    pub from: f64,
    /// Last value, above `from` when `count` > 1.
    pub to: f64,
    /// Number of values, at least 1.
    pub count: usize,
}

impl AxisSweep {
    /// The axis's values, increasing.
    pub fn values(&self) -> Vec<f64> {
        if self.count <= 1 {
            return vec![self.from];
        }
        let step = (self.to - self.from) / (self.count - 1) as f64;
        (0..self.count).map(|i| if i + 1 == self.count { self.to } else { self.from + step * i as f64 }).collect()
    }
}

/// What to sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct FamilySpec {
    /// Line, grid or semicircle.
    pub kind: FamilyKind,
    /// The swept ground stage, 0-based among ground stages.
    pub stage: usize,
    /// One axis per parameter of `kind` (u, then v for a grid).
    pub axes: Vec<AxisSweep>,
}

/// Why a family could not be set up (a sample that fails is not an error of the family).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FamilyError {
    /// The swept stage does not exist.
    #[error("ground stage {stage} does not exist: the clip has {grounds} ground stages (0..{grounds})")]
    Stage {
        /// The stage asked.
        stage: usize,
        /// Ground stages in the clip.
        grounds: usize,
    },
    /// A family needs a flight between the swept stage and another ground stage.
    #[error("the clip has {grounds} ground stage(s): a family needs two, with a flight between")]
    OneGround {
        /// Ground stages in the clip.
        grounds: usize,
    },
    /// The number of axes does not fit the kind.
    #[error("a {kind} family has {want} parameter(s), {got} axes given")]
    Axes {
        /// The kind's name.
        kind: &'static str,
        /// Axes given.
        got: usize,
        /// Axes the kind has.
        want: usize,
    },
    /// An axis is malformed.
    #[error("axis {axis}: {reason}")]
    Axis {
        /// 0 for u, 1 for v.
        axis: usize,
        /// What is wrong.
        reason: String,
    },
    /// Too many samples.
    #[error("{samples} samples asked; a family holds at most {MAX_SAMPLES}")]
    TooMany {
        /// Samples asked.
        samples: usize,
    },
    /// The base edits do not fit the clip.
    #[error("{got} base edits given, the clip has {want} ground stages")]
    EditCount {
        /// Edits given.
        got: usize,
        /// Ground stages.
        want: usize,
    },
}

/// A populated family with each sample's solver report or error, in the family's order.
#[derive(Debug)]
pub struct FamilyRun {
    /// The family.
    pub family: Family,
    /// Per sample, the solver's report, or its error (the sample is then marked failed).
    pub reports: Vec<Result<SolveReport, SolveError>>,
}

/// The jump's frame of reference and the swept stage's pivot: (forward, side, centre C,
/// swept pivot c), metres.
fn frame_of_reference(setup: &EditSetup<'_>, stage: usize) -> Result<(DVec3, DVec3, DVec3, DVec3), FamilyError> {
    let track = momentum_of_poses(&forward_kinematics(setup.clip), setup.clip.fps(), setup.model);
    let grounds = ground_pivots(setup.stages, &track.com_m);
    if grounds.len() < 2 {
        return Err(FamilyError::OneGround { grounds: grounds.len() });
    }
    if stage >= grounds.len() {
        return Err(FamilyError::Stage { stage, grounds: grounds.len() });
    }
    let neighbour = if stage > 0 { stage - 1 } else { 1 };
    let (earlier, later) = (grounds[stage.min(neighbour)].0, grounds[stage.max(neighbour)].0);
    // The centre of mass's travel over the flight between them, on the floor plane; a hop
    // on the spot has no direction, and the default facing (+Z) stands in.
    let com = |f: usize| track.com_m.get(f).copied().unwrap_or(DVec3::ZERO);
    let travel = com(later.start.saturating_sub(1)) - com(earlier.end);
    let forward = DVec3::new(travel.x, 0.0, travel.z).normalize_or(DVec3::Z);
    Ok((forward, DVec3::Y.cross(forward), grounds[neighbour].1, grounds[stage].1))
}

/// The swept stage's edit for the parameters `p` (one per axis).
fn edit_for(kind: FamilyKind, p: &[f64], reference: (DVec3, DVec3, DVec3, DVec3)) -> GroundEdit {
    let (forward, side, centre, pivot) = reference;
    match kind {
        FamilyKind::Line => GroundEdit { offset_m: p[0] * forward, turn_rad: 0.0 },
        FamilyKind::Grid => GroundEdit { offset_m: p[0] * forward + p[1] * side, turn_rad: 0.0 },
        FamilyKind::Semicircle => {
            let arm = pivot - centre;
            GroundEdit { offset_m: DQuat::from_rotation_y(p[0]) * arm - arm, turn_rad: p[0] }
        }
    }
}

/// Checks the spec and returns each axis's values.
fn axis_values(spec: &FamilySpec) -> Result<Vec<Vec<f64>>, FamilyError> {
    let want = spec.kind.dimensions();
    if spec.axes.len() != want {
        return Err(FamilyError::Axes { kind: spec.kind.name(), got: spec.axes.len(), want });
    }
    let mut samples = 1usize;
    for (axis, a) in spec.axes.iter().enumerate() {
        let bad = |reason: String| FamilyError::Axis { axis, reason };
        if a.count == 0 {
            return Err(bad("needs at least one value".into()));
        }
        if !(a.from.is_finite() && a.to.is_finite()) {
            return Err(bad(format!("bounds {} and {} must be finite", a.from, a.to)));
        }
        if a.count > 1 && a.to <= a.from {
            return Err(bad(format!("runs from {} to {}: the end must lie above the start", a.from, a.to)));
        }
        if spec.kind == FamilyKind::Semicircle && a.from.abs().max(a.to.abs()) > std::f64::consts::PI {
            return Err(bad(format!("turns from {} to {} rad: a semicircle stays within ±π", a.from, a.to)));
        }
        samples = samples.saturating_mul(a.count);
    }
    if samples > MAX_SAMPLES {
        return Err(FamilyError::TooMany { samples });
    }
    Ok(spec.axes.iter().map(AxisSweep::values).collect())
}

/// Populates the family `spec` from `setup` (whose `edits` hold every ground stage's base
/// edit; the swept stage's is replaced by each sample's), optimising the samples in
/// parallel with `options`.
pub fn populate(setup: EditSetup<'_>, spec: &FamilySpec, options: &SolveOptions) -> Result<FamilyRun, FamilyError> {
    let axes = axis_values(spec)?;
    let reference = frame_of_reference(&setup, spec.stage)?;
    let grounds = setup.stages.stages.iter().filter(|s| s.kind == StageKind::Ground).count();
    if setup.edits.len() != grounds {
        return Err(FamilyError::EditCount { got: setup.edits.len(), want: grounds });
    }
    // Row-major: the last axis varies fastest.
    let params: Vec<Vec<f64>> = match &axes[..] {
        [u] => u.iter().map(|&u| vec![u]).collect(),
        [u, v] => u.iter().flat_map(|&u| v.iter().map(move |&v| vec![u, v])).collect(),
        _ => return Err(FamilyError::Axes { kind: spec.kind.name(), got: axes.len(), want: spec.kind.dimensions() }),
    };
    let solved: Vec<(FamilySample, Result<SolveReport, SolveError>)> = params
        .into_par_iter()
        .map(|p| {
            let edit = edit_for(spec.kind, &p, reference);
            let mut edits = setup.edits.to_vec();
            edits[spec.stage] = edit;
            let result = momentum_edit(EditSetup { edits: &edits, ..setup }, options);
            let (outcome, report) = match result {
                Ok((clip, report)) => (SampleOutcome::Solved(Arc::new(clip)), Ok(report)),
                Err(e) => (SampleOutcome::Failed(e.to_string()), Err(e)),
            };
            (FamilySample { params: p, offset_m: edit.offset_m, turn_rad: edit.turn_rad, outcome }, report)
        })
        .collect();
    let (samples, reports) = solved.into_iter().unzip();
    let (forward, side, centre_m, _) = reference;
    Ok(FamilyRun {
        family: Family { kind: spec.kind, stage: spec.stage, axes, forward, side, centre_m, samples },
        reports,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_space_evenly_and_a_single_value_is_the_start() {
        assert_eq!(AxisSweep { from: -0.5, to: 0.5, count: 3 }.values(), vec![-0.5, 0.0, 0.5]);
        assert_eq!(AxisSweep { from: 0.25, to: -9.0, count: 1 }.values(), vec![0.25]);
        let spec = |axes: Vec<AxisSweep>| FamilySpec { kind: FamilyKind::Grid, stage: 1, axes };
        let ok = AxisSweep { from: 0.0, to: 1.0, count: 2 };
        assert!(matches!(axis_values(&spec(vec![ok])), Err(FamilyError::Axes { got: 1, want: 2, .. })));
        let flipped = AxisSweep { from: 1.0, to: 0.0, count: 2 };
        assert!(matches!(axis_values(&spec(vec![ok, flipped])), Err(FamilyError::Axis { axis: 1, .. })));
        let big = AxisSweep { from: 0.0, to: 1.0, count: 21 };
        assert_eq!(axis_values(&spec(vec![big, big])), Err(FamilyError::TooMany { samples: 441 }));
    }

    #[test]
    fn a_semicircle_sample_turns_the_stage_about_the_neighbouring_pivot() {
        // Take-off at the origin, landing pivot 1 m along +X: a quarter turn about the
        // take-off puts the landing 1 m along −Z (R_y(π/2) maps +X to −Z), facing turned alike.
        let (centre, pivot) = (DVec3::ZERO, DVec3::X);
        let quarter = std::f64::consts::FRAC_PI_2;
        let e = edit_for(FamilyKind::Semicircle, &[quarter], (DVec3::X, DVec3::NEG_Z, centre, pivot));
        assert!((pivot + e.offset_m - DVec3::NEG_Z).length() < 1e-12, "{}", e.offset_m);
        assert_eq!(e.turn_rad, quarter);
        let g = edit_for(FamilyKind::Grid, &[0.5, -0.25], (DVec3::X, DVec3::NEG_Z, centre, pivot));
        assert!((g.offset_m - DVec3::new(0.5, 0.0, 0.25)).length() < 1e-12);
    }
}
