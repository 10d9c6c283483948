//! A motion family (momentum-based editing): one captured clip edited many times over a
//! grid of one ground stage's placements, so any placement inside the grid can be had by
//! blending the nearest samples.

use std::sync::Arc;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::choice::{Choice, choices};
use super::clip::Clip;

/// How the swept ground stage moves with the family's parameters (the paper's three kinds).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FamilyKind {
    /// One parameter u, metres along the jump's direction.
    Line,
    /// Two parameters: u metres along the jump's direction, v metres to its left.
    Grid,
    /// One parameter u, radians: the stage turns about the adjacent ground stage's centre,
    /// so the jump keeps its length, changes direction, and the body faces along the
    /// radius (the arc's normal).
    Semicircle,
}

choices!(FamilyKind { Line = "line", Grid = "grid", Semicircle = "semicircle" });

impl FamilyKind {
    /// How many parameters a family of this kind has.
    pub fn dimensions(self) -> usize {
        match self {
            FamilyKind::Grid => 2,
            FamilyKind::Line | FamilyKind::Semicircle => 1,
        }
    }
}

/// What became of one sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum SampleOutcome {
    /// Optimised: the edited clip.
    Solved(Arc<Clip>),
    /// The optimisation failed; why (the solver's error text).
    Failed(String),
}

/// One member of a family.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FamilySample {
    /// Its parameters, one per axis (metres, or radians for a semicircle).
    pub params: Vec<f64>,
    /// The horizontal offset of the swept ground stage, metres.
    pub offset_m: DVec3,
    /// The swept stage's turn about the vertical through its centre of mass, radians.
    pub turn_rad: f64,
    /// The edited clip, or why there is none.
    pub outcome: SampleOutcome,
}

/// Samples of one clip's edits on a regular grid of parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Family {
    /// How the parameters move the swept stage.
    pub kind: FamilyKind,
    /// The swept ground stage (0-based among ground stages).
    pub stage: usize,
    /// The parameter values of each axis, increasing (one axis, or two for a grid).
    pub axes: Vec<Vec<f64>>,
    /// The jump's horizontal direction (unit), the `u` axis of lines and grids.
    pub forward: DVec3,
    /// Its left (Y × forward), the `v` axis of grids.
    pub side: DVec3,
    /// Centre of the semicircle on the floor plane, metres (unused by the other kinds).
    pub centre_m: DVec3,
    /// The samples, row-major: sample (i, j) of a grid at `i · axes[1].len() + j`.
    pub samples: Vec<FamilySample>,
}

impl Family {
    /// The sample at grid index `index` (one entry per axis).
    pub fn sample_at(&self, index: &[usize]) -> Option<&FamilySample> {
        let mut flat = 0;
        for (axis, &i) in self.axes.iter().zip(index) {
            if i >= axis.len() {
                return None;
            }
            flat = flat * axis.len() + i;
        }
        self.samples.get(flat)
    }

    /// How many samples were solved.
    pub fn solved_count(&self) -> usize {
        self.samples.iter().filter(|s| matches!(s.outcome, SampleOutcome::Solved(_))).count()
    }

    /// Kind, axes and every sample's parameters and outcome, for reports and regression facts.
    pub fn summary(&self) -> serde_json::Value {
        let samples: Vec<serde_json::Value> = self
            .samples
            .iter()
            .map(|s| {
                let outcome = match &s.outcome {
                    SampleOutcome::Solved(clip) => serde_json::json!({ "frames": clip.frame_count() }),
                    SampleOutcome::Failed(why) => serde_json::json!({ "failed": why }),
                };
                serde_json::json!({
                    "params": s.params,
                    "offset_m": [s.offset_m.x, s.offset_m.z],
                    "turn_rad": s.turn_rad,
                    "outcome": outcome,
                })
            })
            .collect();
        serde_json::json!({
            "kind": self.kind.name(),
            "stage": self.stage,
            "axes": self.axes,
            "forward": [self.forward.x, self.forward.z],
            "solved": self.solved_count(),
            "samples": samples,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_samples_are_row_major() {
        let sample = |u: f64, v: f64| FamilySample {
            params: vec![u, v],
            offset_m: DVec3::ZERO,
            turn_rad: 0.0,
            outcome: SampleOutcome::Failed(String::new()),
        };
        let family = Family {
            kind: FamilyKind::Grid,
            stage: 1,
            axes: vec![vec![0.0, 1.0], vec![0.0, 2.0, 4.0]],
            forward: DVec3::X,
            side: DVec3::NEG_Z,
            centre_m: DVec3::ZERO,
            samples: [0.0, 1.0].iter().flat_map(|&u| [0.0, 2.0, 4.0].map(|v| sample(u, v))).collect(),
        };
        assert_eq!(family.sample_at(&[1, 2]).unwrap().params, vec![1.0, 4.0]);
        assert_eq!(family.sample_at(&[0, 1]).unwrap().params, vec![0.0, 2.0]);
        assert!(family.sample_at(&[2, 0]).is_none());
    }
}
