//! `motion.momentum_edit`: the node over the spacetime optimisation
//! ([`crate::kernels::momentum_solve`]) of momentum-based editing.

use std::sync::Arc;

use glam::DVec3;
use serde_json::json;

use super::{MASS_OVERRIDE, MASS_TABLE, TOTAL_MASS, check_stages_fit, mass_model_of};
use crate::kernels::body::BodyModel;
use crate::kernels::contacts::{ContactThresholds, contacts_of};
use crate::kernels::momentum_edit::{EditError, GroundEdit, measure_edit, naive_edit};
use crate::kernels::momentum_solve::{EditSetup, SolveError, SolveOptions, SolvedFrames, momentum_edit};
use crate::model::choice::choices;
use crate::model::{Clip, FrameRange, StageKind, Stages, forward_kinematics};
use crate::node::{
    ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry, Report,
    TextParam, report_of,
};

/// Registers the momentum edit node.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(MomentumEdit));
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The captured jump, hop or flip to edit.");
const STAGES: Input<Arc<Stages>> =
    Input::required("stages", "Its ground and flight stages and fitted gravity (from motion.stages).");
const EDITED: Output<Arc<Clip>> =
    Output::new("clip", "The edited motion: ground stages where asked, momentum physically plausible.");
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Solver: steps, unknowns, the frames solved (the others are the capture moved rigidly with their ground \
     stages), each objective term, every constraint's final violation and tolerance. Measures of \
     the result next to the naive kinematic edit's: landing error, planted-foot drift, depth below the floor (m), \
     flight parabola RMS under the (scaled) gravity (m), unsupplied momentum change at each border (kg·m/s).",
);
const OFFSETS: TextParam = TextParam::new(
    "offsets_m",
    "Horizontal offset of each ground stage, metres, as 'x z' pairs separated by ';' in time order (e.g. \
     \"0 0; 0.5 0.3\" moves the landing 0.5 m along X and 0.3 m along Z). Empty: no offsets.",
    "",
);
const TURNS: TextParam = TextParam::new(
    "turns_rad",
    "Turn of each ground stage about the vertical through its centre of mass, radians, comma separated in time \
     order. Empty: no turns.",
    "",
);
pub(super) const GRAVITY_SCALE: FloatParam = FloatParam::new(
    "gravity_scale",
    "Gravity in flight as a multiple of the gravity fitted to the capture (0.5: a moon-like, floatier jump).",
    1.0,
    0.1,
    5.0,
    "",
);
pub(super) const KNOT_SPACING: FloatParam = FloatParam::new(
    "knot_spacing_secs",
    "Spacing of the momentum spline knots in ground stages: smaller lets the momentum change faster.",
    0.1,
    0.02,
    1.0,
    "s",
);
choices!(SolvedFrames { Auto = "auto", Whole = "whole_clip", AroundEdit = "around_edit" });
pub(super) const SOLVED_FRAMES: ChoiceParam<SolvedFrames> = ChoiceParam::new(
    "solved_frames",
    "Which frames are re-solved: \"whole_clip\" cleans the whole capture as it edits (every contact held, every \
     flight ballistic); \"around_edit\" solves from the middle of the ground stage before the first changed flight \
     to the middle of the one after the last, and moves the rest of the capture rigidly, as captured; \"auto\": \
     around the edit for clips longer than 10 s (a long capture as a whole converges slowly or not at all).",
    "auto",
);
pub(super) const MAX_STEPS: IntParam =
    IntParam::new("max_iterations", "Most Gauss–Newton steps before the edit is declared not converged.", 120, 1, 1000);

/// `motion.momentum_edit`.
pub struct MomentumEdit;

static MOMENTUM_EDIT: NodeSchema = NodeSchema {
    kind: "motion.momentum_edit",
    category: "motion",
    doc: "Moves or turns the ground stages of a captured jump (where it takes off, where it lands) and changes \
          gravity, then re-solves every frame so the feet stay planted where asked and above the floor, the \
          flights stay ballistic and spin at constant angular momentum, and the momentum on the ground changes \
          smoothly: momentum-based dynamic motion editing, as a spacetime optimisation.",
    inputs: &[CLIP.spec(), STAGES.spec()],
    outputs: &[EDITED.spec(), REPORT.spec()],
    params: &[
        TOTAL_MASS.0,
        MASS_TABLE.0,
        MASS_OVERRIDE.0,
        OFFSETS.0,
        TURNS.0,
        GRAVITY_SCALE.0,
        KNOT_SPACING.0,
        MAX_STEPS.0,
        SOLVED_FRAMES.0,
    ],
    writes_files: false,
    version: 1,
};

/// Parses `offsets_m` into `count` horizontal offsets (missing trailing stages: zero).
fn parse_offsets(text: &str, count: usize) -> Result<Vec<DVec3>, NodeError> {
    let bad = |m: String| NodeError::param("offsets_m", m);
    let mut out = vec![DVec3::ZERO; count];
    if text.trim().is_empty() {
        return Ok(out);
    }
    let pairs: Vec<&str> = text.split(';').collect();
    if pairs.len() > count {
        return Err(bad(format!("{} offsets given, the clip has {count} ground stages", pairs.len())));
    }
    for (slot, pair) in out.iter_mut().zip(pairs) {
        let v: Vec<f64> = pair
            .split_whitespace()
            .map(|x| x.parse::<f64>().ok().filter(|v| v.is_finite()))
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| bad(format!("'{}' is not an 'x z' pair of metres", pair.trim())))?;
        match v[..] {
            [x, z] => *slot = DVec3::new(x, 0.0, z),
            _ => return Err(bad(format!("'{}' is not an 'x z' pair of metres", pair.trim()))),
        }
    }
    Ok(out)
}

/// Parses `turns_rad` into `count` turns (missing trailing stages: zero).
fn parse_turns(text: &str, count: usize) -> Result<Vec<f64>, NodeError> {
    let mut out = vec![0.0; count];
    if text.trim().is_empty() {
        return Ok(out);
    }
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() > count {
        return Err(NodeError::param(
            "turns_rad",
            format!("{} turns given, the clip has {count} ground stages", parts.len()),
        ));
    }
    for (slot, part) in out.iter_mut().zip(parts) {
        *slot =
            part.trim().parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                NodeError::param("turns_rad", format!("'{}' is not a number of radians", part.trim()))
            })?;
    }
    Ok(out)
}

/// The kernel's error, located on the node's port or param.
pub(super) fn located(e: SolveError) -> NodeError {
    match e {
        SolveError::Unreachable { .. } => NodeError::param("offsets_m", e.to_string()),
        SolveError::GravityScale(_) => NodeError::param("gravity_scale", e.to_string()),
        SolveError::Splines(_) => NodeError::param("knot_spacing_secs", e.to_string()),
        SolveError::TooShort { .. } => NodeError::input("clip", e.to_string()),
        SolveError::NoFlight | SolveError::Edit(EditError::Frames { .. } | EditError::EditCount { .. }) => {
            NodeError::input("stages", e.to_string())
        }
        SolveError::NotConverged { .. } | SolveError::Factor(_) | SolveError::Clip(_) | SolveError::Edit(_) => {
            NodeError::kernel(e)
        }
    }
}

/// The solver settings of the node's params.
pub(super) fn solve_options(ctx: &NodeContext<'_>) -> Result<SolveOptions, NodeError> {
    Ok(SolveOptions {
        gravity_scale: ctx.float(&GRAVITY_SCALE)?,
        knot_spacing_secs: ctx.float(&KNOT_SPACING)?,
        max_iterations: usize::try_from(ctx.int(&MAX_STEPS)?).unwrap_or(1),
        frames: ctx.choice(&SOLVED_FRAMES)?,
    })
}

/// The original's foot contacts: (ankle joint, frames).
pub(super) type Planted = Vec<(usize, FrameRange)>;

/// What an edit of `clip` needs besides the clip and its stages: the body model (the
/// node's mass params), the ankle joints and the original's foot contacts.
pub(super) fn solve_inputs(
    ctx: &mut NodeContext<'_>,
    clip: &Clip,
) -> Result<(BodyModel, [usize; 2], Planted), NodeError> {
    let model = mass_model_of(ctx, clip)?;
    let (contacts, feet) = contacts_of(clip, &forward_kinematics(clip), &ContactThresholds::default())
        .map_err(|e| NodeError::input("clip", format!("the feet could not be found: {e}")))?;
    let planted = contacts.feet.iter().zip(feet).flat_map(|(c, j)| c.intervals.iter().map(move |r| (j, *r))).collect();
    Ok((model, feet, planted))
}

impl Node for MomentumEdit {
    fn schema(&self) -> &'static NodeSchema {
        &MOMENTUM_EDIT
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let stages = ctx.input(&STAGES)?;
        check_stages_fit(&clip, &stages)?;
        let grounds = stages.stages.iter().filter(|s| s.kind == StageKind::Ground).count();
        let offsets = parse_offsets(ctx.text_param(&OFFSETS)?, grounds)?;
        let turns = parse_turns(ctx.text_param(&TURNS)?, grounds)?;
        let edits: Vec<GroundEdit> =
            offsets.iter().zip(&turns).map(|(o, t)| GroundEdit { offset_m: *o, turn_rad: *t }).collect();
        let options = solve_options(ctx)?;
        let (model, feet, planted) = solve_inputs(ctx, &clip)?;
        let setup = EditSetup { clip: &clip, stages: &stages, model: &model, feet, planted: &planted, edits: &edits };
        let (edited, report) = momentum_edit(setup, &options).map_err(located)?;
        let naive = naive_edit(&clip, &stages, &model, &edits).map_err(|e| located(e.into()))?;
        let g = stages.gravity_mps2 * options.gravity_scale;
        let measure = |c: &Clip| {
            measure_edit(&clip, c, &stages, &model, &edits, &feet, &planted, g).map(|m| {
                json!({
                    "landing_error_m": m.placement_error_m,
                    "planted_drift_m": m.planted_drift_m,
                    "below_floor_m": m.below_floor_m,
                    "flight_parabola_rms_m": m.parabola_rms_m,
                    "border_momentum_jump_kgmps": m.border_momentum_jump,
                })
            })
        };
        let optimised = measure(&edited).map_err(|e| located(e.into()))?;
        let kinematic = measure(&naive).map_err(|e| located(e.into()))?;
        let violations: Vec<serde_json::Value> = report
            .violations
            .iter()
            .map(|v| json!({ "constraint": v.constraint, "max": v.max, "tolerance": v.tolerance, "unit": v.unit }))
            .collect();
        // Wall-clock seconds stay out of the report (it must be reproducible); the
        // criterion bench `momentum_edit` times the edit.
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "iterations": report.iterations,
                "unknowns": report.unknowns,
                "active_joints": report.active_joints,
                "solved_frames": [report.solved_frames.start, report.solved_frames.end],
                "objective": { "similarity": report.similarity, "smoothness": report.smoothness, "balance": report.balance },
                "constraints": violations,
                "gravity_mps2": g,
                "optimised": optimised,
                "naive": kinematic,
            })),
        );
        ctx.set_output(&EDITED, Arc::new(edited));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_and_turns_parse_or_name_the_param() {
        assert_eq!(parse_offsets("", 2).unwrap(), vec![DVec3::ZERO; 2]);
        assert_eq!(parse_offsets("0 0; 0.5 -0.25", 2).unwrap(), vec![DVec3::ZERO, DVec3::new(0.5, 0.0, -0.25)]);
        for bad in ["0 0; 1", "0 0; a b", "0 0; 0 0; 0 0", "0 NaN"] {
            let err = parse_offsets(bad, 2).unwrap_err().to_string();
            assert!(err.contains("offsets_m"), "{bad}: {err}");
        }
        assert_eq!(parse_turns("0, 1.5", 2).unwrap(), vec![0.0, 1.5]);
        let err = parse_turns("0, x", 2).unwrap_err().to_string();
        assert!(err.contains("turns_rad") && err.contains("'x'"), "{err}");
    }

    /// The solved_frames doc states the length `auto` switches at, which a const string
    /// cannot take from the constant: this keeps the two together.
    #[test]
    fn the_solved_frames_doc_states_the_auto_window() {
        let window = crate::kernels::momentum_solve::AUTO_WINDOW_SECS;
        assert!(SOLVED_FRAMES.0.doc.contains(&format!("longer than {window} s")), "{}", SOLVED_FRAMES.0.doc);
    }
}
