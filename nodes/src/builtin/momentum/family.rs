//! `motion.family`, `motion.family_blend` and `motion.family_reach`: a family of momentum
//! edits of one clip ([`crate::kernels::family`]) and real-time motion inside it
//! ([`crate::kernels::family_blend`]).

use std::sync::Arc;

use glam::DVec3;
use serde_json::json;

use super::edit::{GRAVITY_SCALE, KNOT_SPACING, MAX_STEPS, SOLVED_FRAMES, solve_inputs, solve_options};
use super::{MASS_OVERRIDE, MASS_TABLE, TOTAL_MASS, check_stages_fit};
use crate::kernels::family::{AxisSweep, FamilyError, FamilySpec, MAX_SAMPLES, populate};
use crate::kernels::family_blend::{BlendError, ReachTarget, blend_family, blend_shares, reach};
use crate::kernels::momentum_edit::GroundEdit;
use crate::kernels::momentum_solve::EditSetup;
use crate::model::choice::Choice;
use crate::model::{Clip, Family, FamilyKind, SampleOutcome, StageKind, Stages};
use crate::node::{
    ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry, Report,
    TextParam, report_of,
};

/// Registers the family nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(MotionFamily));
    registry.add(Box::new(FamilyBlend));
    registry.add(Box::new(FamilyReach));
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The captured jump, hop or flip the family is made from.");
const STAGES: Input<Arc<Stages>> =
    Input::required("stages", "Its ground and flight stages and fitted gravity (from motion.stages).");
const FAMILY_OUT: Output<Arc<Family>> = Output::new(
    "family",
    "Every sample's parameters, placement and edited clip (or why its optimisation failed), for motion.family_blend.",
);
const FAMILY_REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "The jump's direction, then per sample: parameters, offset (m) and turn (rad) of the swept stage, solver steps \
     and the worst constraint left (or the failure).",
);
const KIND: ChoiceParam<FamilyKind> = ChoiceParam::new(
    "kind",
    "line: the stage moves u metres along the jump; grid: u metres along it and v metres to its left; semicircle: \
     the stage turns u radians about the other stage of the jump (same length, new direction, body facing along \
     the radius).",
    "grid",
);
const STAGE: IntParam = IntParam::optional(
    "stage",
    "The swept ground stage, 0-based in time order (0: the take-off). Unset: the last one (the landing).",
    0,
    1000,
);
const U_FROM: FloatParam =
    FloatParam::new("u_from", "First value of u (metres; radians for a semicircle).", -0.3, -10.0, 10.0, "");
const U_TO: FloatParam = FloatParam::new("u_to", "Last value of u (ignored when u_count is 1).", 0.3, -10.0, 10.0, "");
const U_COUNT: IntParam = IntParam::new(
    "u_count",
    "Samples along u, evenly spaced (1: u_from alone; a farm task computing one sample).",
    3,
    1,
    MAX_SAMPLES as i64,
);
const V_FROM: FloatParam = FloatParam::new("v_from", "First value of v, metres (grid only).", -0.3, -10.0, 10.0, "m");
const V_TO: FloatParam =
    FloatParam::new("v_to", "Last value of v, metres (grid only; ignored when v_count is 1).", 0.3, -10.0, 10.0, "m");
const V_COUNT: IntParam = IntParam::new("v_count", "Samples along v (grid only).", 3, 1, MAX_SAMPLES as i64);

/// `motion.family`.
pub struct MotionFamily;

static MOTION_FAMILY: NodeSchema = NodeSchema {
    kind: "motion.family",
    category: "motion",
    doc: "Makes a family of physically plausible variants of one captured jump: one ground stage (by default the \
          landing) is moved along a line, over a grid, or turned along a semicircle, and every sample is re-solved \
          by momentum-based editing, in parallel. Samples that do not converge are kept, marked failed, and warned \
          about. Blend the family with motion.family_blend.",
    inputs: &[CLIP.spec(), STAGES.spec()],
    outputs: &[FAMILY_OUT.spec(), FAMILY_REPORT.spec()],
    params: &[
        KIND.0,
        STAGE.0,
        U_FROM.0,
        U_TO.0,
        U_COUNT.0,
        V_FROM.0,
        V_TO.0,
        V_COUNT.0,
        TOTAL_MASS.0,
        MASS_TABLE.0,
        MASS_OVERRIDE.0,
        GRAVITY_SCALE.0,
        KNOT_SPACING.0,
        MAX_STEPS.0,
        SOLVED_FRAMES.0,
    ],
    writes_files: false,
    version: 1,
};

/// The kernel's error, located on the node's param or port.
fn family_located(e: FamilyError) -> NodeError {
    let text = e.to_string();
    match e {
        FamilyError::Stage { .. } => NodeError::param("stage", text),
        FamilyError::OneGround { .. } | FamilyError::EditCount { .. } => NodeError::input("stages", text),
        FamilyError::Axis { axis: 1, .. } => NodeError::param("v_count", text),
        FamilyError::Axis { .. } | FamilyError::Axes { .. } => NodeError::param("u_count", text),
        FamilyError::TooMany { .. } => NodeError::param("u_count", text),
    }
}

/// A sweep from the node's `from`, `to` and `count` params.
fn sweep(ctx: &NodeContext<'_>, from: &FloatParam, to: &FloatParam, count: &IntParam) -> Result<AxisSweep, NodeError> {
    Ok(AxisSweep { from: ctx.float(from)?, to: ctx.float(to)?, count: usize::try_from(ctx.int(count)?).unwrap_or(1) })
}

impl Node for MotionFamily {
    fn schema(&self) -> &'static NodeSchema {
        &MOTION_FAMILY
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let stages = ctx.input(&STAGES)?;
        check_stages_fit(&clip, &stages)?;
        let kind = ctx.choice(&KIND)?;
        let grounds = stages.stages.iter().filter(|s| s.kind == StageKind::Ground).count();
        let stage = match ctx.optional_int(&STAGE)? {
            Some(s) => usize::try_from(s).unwrap_or(0),
            None => grounds.saturating_sub(1),
        };
        let mut axes = vec![sweep(ctx, &U_FROM, &U_TO, &U_COUNT)?];
        if kind == FamilyKind::Grid {
            axes.push(sweep(ctx, &V_FROM, &V_TO, &V_COUNT)?);
        }
        let spec = FamilySpec { kind, stage, axes };
        let options = solve_options(ctx)?;
        let (model, feet, planted) = solve_inputs(ctx, &clip)?;
        let edits = vec![GroundEdit::default(); grounds];
        let setup = EditSetup { clip: &clip, stages: &stages, model: &model, feet, planted: &planted, edits: &edits };
        let run = populate(setup, &spec, &options).map_err(family_located)?;
        let mut failures = Vec::new();
        let samples: Vec<serde_json::Value> = run
            .family
            .samples
            .iter()
            .zip(&run.reports)
            .map(|(s, report)| {
                let solver = match report {
                    Ok(r) => {
                        let worst = r
                            .violations
                            .iter()
                            .max_by(|a, b| (a.max / a.tolerance).total_cmp(&(b.max / b.tolerance)))
                            .map(|v| json!({ "constraint": v.constraint, "max": v.max, "unit": v.unit }));
                        json!({ "iterations": r.iterations, "worst_constraint": worst })
                    }
                    Err(e) => {
                        failures.push(format!("sample at {:?} failed: {e}", s.params));
                        json!({ "failed": e.to_string() })
                    }
                };
                json!({
                    "params": s.params,
                    "offset_m": [s.offset_m.x, s.offset_m.z],
                    "turn_rad": s.turn_rad,
                    "solver": solver,
                })
            })
            .collect();
        ctx.warn_all(failures);
        let family = run.family;
        ctx.set_output(
            &FAMILY_REPORT,
            report_of(json!({
                "kind": family.kind.name(),
                "stage": family.stage,
                "forward": [family.forward.x, family.forward.z],
                "side": [family.side.x, family.side.z],
                "centre_m": [family.centre_m.x, family.centre_m.z],
                "solved": family.solved_count(),
                "samples": samples,
            })),
        );
        ctx.set_output(&FAMILY_OUT, Arc::new(family));
        Ok(())
    }
}

const FAMILY_IN: Input<Arc<Family>> = Input::required("family", "A motion family (from motion.family).");
const BLENDED: Output<Arc<Clip>> =
    Output::new("clip", "The motion at the asked parameters, blended from the nearest samples.");
const BLEND_REPORT: Output<Arc<Report>> =
    Output::new("report", "The parameters blended at, and the samples blended with their shares (summing to 1).");
const U: FloatParam = FloatParam::new(
    "u",
    "Where in the family: metres along the jump (line, grid) or radians (semicircle), inside the sampled range.",
    0.0,
    -10.0,
    10.0,
    "",
);
const V: FloatParam = FloatParam::new(
    "v",
    "Metres to the jump's left (grid families only), inside the sampled range.",
    0.0,
    -10.0,
    10.0,
    "m",
);

/// The parameters of `u` and `v` a family of `family`'s kind takes.
fn params_of(ctx: &NodeContext<'_>, family: &Family) -> Result<Vec<f64>, NodeError> {
    let mut params = vec![ctx.float(&U)?];
    if family.axes.len() == 2 {
        params.push(ctx.float(&V)?);
    }
    Ok(params)
}

/// The blend's error, located on the node's param or port.
fn blend_located(e: BlendError) -> NodeError {
    let text = e.to_string();
    match e {
        BlendError::Outside { axis: 1, .. } => NodeError::param("v", text),
        BlendError::Outside { .. } => NodeError::param("u", text),
        BlendError::Joint { .. } => NodeError::param("joint", text),
        BlendError::Frame { .. } => NodeError::param("time_secs", text),
        BlendError::Target(_) => NodeError::param("target_m", text),
        BlendError::FailedSample { .. }
        | BlendError::Dimensions { .. }
        | BlendError::Missing(_)
        | BlendError::Mismatch => NodeError::input("family", text),
        BlendError::Clip(_) => NodeError::kernel(e),
    }
}

/// The samples blended at `params` and their shares, for reports.
fn shares_json(family: &Family, params: &[f64]) -> Result<serde_json::Value, NodeError> {
    let shares = blend_shares(family, params).map_err(blend_located)?;
    Ok(shares.into_iter().filter(|(_, w)| *w > 0.0).map(|(p, w)| json!({ "params": p, "share": w })).collect())
}

/// `motion.family_blend`.
pub struct FamilyBlend;

static FAMILY_BLEND: NodeSchema = NodeSchema {
    kind: "motion.family_blend",
    category: "motion",
    doc: "The motion anywhere inside a family, in real time: the nearest 2 (line, semicircle) or 4 (grid) samples \
          are blended frame by frame (rotations by slerp, positions linearly). At a sample's own parameters the \
          result is that sample.",
    inputs: &[FAMILY_IN.spec()],
    outputs: &[BLENDED.spec(), BLEND_REPORT.spec()],
    params: &[U.0, V.0],
    writes_files: false,
    version: 1,
};

impl Node for FamilyBlend {
    fn schema(&self) -> &'static NodeSchema {
        &FAMILY_BLEND
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let family = ctx.input(&FAMILY_IN)?;
        let params = params_of(ctx, &family)?;
        let clip = blend_family(&family, &params).map_err(blend_located)?;
        let blended = shares_json(&family, &params)?;
        ctx.set_output(&BLEND_REPORT, report_of(json!({ "params": params, "blended": blended })));
        ctx.set_output(&BLENDED, Arc::new(clip));
        Ok(())
    }
}

const JOINT: TextParam = TextParam::new("joint", "The joint that must reach the target (e.g. RightHand).", "RightHand");
const TIME: FloatParam =
    FloatParam::new("time_secs", "When it must be there (rounded to the nearest frame).", 0.0, 0.0, 1e6, "s");
const TARGET: TextParam =
    TextParam::new("target_m", "Where it must be: 'x y z' in metres, world axes (e.g. a ball in the air).", "0 0 0");
const REACH_REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "The parameters found, the frame, and how far the joint is left from the target (m; above zero when the target \
     lies beyond what the family can reach).",
);

/// `motion.family_reach`.
pub struct FamilyReach;

static FAMILY_REACH: NodeSchema = NodeSchema {
    kind: "motion.family_reach",
    category: "motion",
    doc: "Inverse control over a family: finds where in the family one joint passes through a target point at a \
          given time (a hand hitting a ball, a head meeting a cross) and returns that blended motion.",
    inputs: &[FAMILY_IN.spec()],
    outputs: &[BLENDED.spec(), REACH_REPORT.spec()],
    params: &[JOINT.0, TIME.0, TARGET.0],
    writes_files: false,
    version: 1,
};

/// Parses 'x y z' metres.
fn parse_point(text: &str) -> Result<DVec3, NodeError> {
    let values: Option<Vec<f64>> =
        text.split_whitespace().map(|x| x.parse::<f64>().ok().filter(|v| v.is_finite())).collect();
    match values.as_deref() {
        Some([x, y, z]) => Ok(DVec3::new(*x, *y, *z)),
        _ => Err(NodeError::param("target_m", format!("'{}' is not an 'x y z' point in metres", text.trim()))),
    }
}

impl Node for FamilyReach {
    fn schema(&self) -> &'static NodeSchema {
        &FAMILY_REACH
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let family = ctx.input(&FAMILY_IN)?;
        let target_m = parse_point(ctx.text_param(&TARGET)?)?;
        let Some(sample) = family.samples.iter().find_map(|s| match &s.outcome {
            SampleOutcome::Solved(c) => Some(c.clone()),
            SampleOutcome::Failed(_) => None,
        }) else {
            return Err(NodeError::input("family", "holds no solved sample"));
        };
        let name = ctx.text_param(&JOINT)?;
        let joint = sample
            .skeleton()
            .index_of(name)
            .ok_or_else(|| NodeError::param("joint", format!("'{name}' is not a joint of the family's skeleton")))?;
        let secs = ctx.float(&TIME)?;
        let frame = (secs * sample.fps()).round() as usize;
        if frame >= sample.frame_count() {
            return Err(NodeError::param(
                "time_secs",
                format!("{secs} s lies after the clip's end ({} s)", sample.duration_secs()),
            ));
        }
        let found = reach(&family, &ReachTarget { joint, frame, target_m }).map_err(blend_located)?;
        let clip = blend_family(&family, &found.params).map_err(blend_located)?;
        ctx.set_output(
            &REACH_REPORT,
            report_of(json!({
                "params": found.params,
                "frame": frame,
                "miss_m": found.miss_m,
                "iterations": found.iterations,
                "blended": shares_json(&family, &found.params)?,
            })),
        );
        ctx.set_output(&BLENDED, Arc::new(clip));
        Ok(())
    }
}
