//! Angular-momentum-guided concatenation (Shum, Komura & Yadav 2009) as nodes: the body
//! mass model, angular momentum curves, phase segmentation, alignment, the full
//! concatenation and the Motion-Graphs baseline it is compared with.

pub mod concat;
pub mod edit;
pub mod family;
pub mod splines;
pub mod stages;

use std::sync::Arc;

use glam::DVec3;
use serde_json::json;

use self::concat::{ConcatParams, Support, concatenate};
use crate::kernels::align::{Rule, facing_difference, feet_centre, place, yaw_rotation};
use crate::kernels::analysis::{Analysis, AnalysisOptions, analyse, kinematics};
use crate::kernels::angular::MomentumTrack;
use crate::kernels::baseline::{BaselineParams, concatenate_baseline};
use crate::kernels::body::{BodyModel, MassOverride, MassTable, body_model};
use crate::kernels::join::Concatenated;
use crate::kernels::phases::{PhaseOptions, segment_phases};
use crate::kernels::resample::resample;
use crate::model::choice::{Choice, OnOff};
use crate::model::{Clip, Contacts, Curves, Phases};
use crate::node::{
    ChoiceParam, FloatParam, Input, InputPathParam, Node, NodeContext, NodeError, NodeSchema, Output, ParamSpec,
    Registry, Report, report_of,
};

/// Registers the momentum nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(AngularMomentum));
    registry.add(Box::new(SegmentPhases));
    registry.add(Box::new(Align));
    registry.add(Box::new(Concat));
    registry.add(Box::new(ConcatBaseline));
    stages::register(registry);
    splines::register(registry);
    edit::register(registry);
    family::register(registry);
}

const TOTAL_MASS: FloatParam = FloatParam::new("total_mass_kg", "Body mass of the performer.", 70.0, 1.0, 500.0, "kg");
const MASS_TABLE: ChoiceParam<MassTable> = ChoiceParam::new(
    "mass_table",
    "How segment masses are set: de Leva's (1996) male or female table mapped from joint names \
     (unknown rigs fall back to bone length), or bone length for every rig.",
    "de_leva_male",
);
const MASS_OVERRIDE: InputPathParam = InputPathParam::optional(
    "mass_override",
    "A RON file listing segments (name, mass_fraction, from, to, com_fraction) that replaces the table.",
    &["ron"],
);
const SMOOTHING: FloatParam = FloatParam::new(
    "smoothing_secs",
    "Half-width of the moving average applied to the momentum before phases are read.",
    0.05,
    0.0,
    2.0,
    "s",
);
const MASS_PARAMS: [ParamSpec; 4] = [TOTAL_MASS.0, MASS_TABLE.0, MASS_OVERRIDE.0, SMOOTHING.0];

/// The analysis settings every momentum node shares.
fn analysis_options(ctx: &NodeContext<'_>) -> Result<AnalysisOptions, NodeError> {
    let (total_mass_kg, table, mass_override) = mass_params(ctx)?;
    Ok(AnalysisOptions {
        total_mass_kg,
        table,
        mass_override,
        smoothing_secs: ctx.float(&SMOOTHING)?,
        ..AnalysisOptions::default()
    })
}

/// The mass params: total mass (kg), table and override file.
fn mass_params(ctx: &NodeContext<'_>) -> Result<(f64, MassTable, Option<MassOverride>), NodeError> {
    let table = ctx.choice(&MASS_TABLE)?;
    let mass_override = match ctx.optional_input_path(&MASS_OVERRIDE)? {
        None => None,
        Some(path) => {
            let text = std::fs::read_to_string(&path)
                .map_err(|e| NodeError::param("mass_override", format!("cannot read {}: {e}", path.display())))?;
            Some(
                ron::from_str::<MassOverride>(&text)
                    .map_err(|e| NodeError::param("mass_override", format!("{}:{e}", path.display())))?,
            )
        }
    };
    Ok((ctx.float(&TOTAL_MASS)?, table, mass_override))
}

/// The mass model, angular momentum and smoothed momentum of `clip` under the node's mass
/// params: what the single-clip nodes need, without the landmarks and contacts of a full
/// analysis (so any rig works, through the bone-length fallback).
fn momentum_of(
    ctx: &mut NodeContext<'_>,
    clip: &Clip,
) -> Result<(BodyModel, MomentumTrack, Vec<glam::DVec3>), NodeError> {
    let model = mass_model_of(ctx, clip)?;
    let (_, track, smoothed) = kinematics(clip, &model, ctx.float(&SMOOTHING)?);
    Ok((model, track, smoothed))
}

/// Refuses stages read from another clip (the `stages` input must describe `clip`'s frames).
fn check_stages_fit(clip: &Clip, stages: &crate::model::Stages) -> Result<(), NodeError> {
    if stages.frame_count != clip.frame_count() {
        return Err(NodeError::input(
            "stages",
            format!("describe {} frames, the clip has {}", stages.frame_count, clip.frame_count()),
        ));
    }
    Ok(())
}

/// The body mass model of `clip` under the node's mass params (total mass, table,
/// override; a warning when the names were not recognised).
fn mass_model_of(ctx: &mut NodeContext<'_>, clip: &Clip) -> Result<BodyModel, NodeError> {
    let (total_mass_kg, table, mass_override) = mass_params(ctx)?;
    let model = body_model(clip.skeleton(), total_mass_kg, table, mass_override.as_ref()).map_err(NodeError::kernel)?;
    if model.method.starts_with("bone_length (") {
        ctx.warn(format!("mass model: {}", model.method));
    }
    Ok(model)
}

/// Both clips of a two-clip node, the second at the first's rate, analysed with the node's
/// settings.
fn analysed_pair(ctx: &mut NodeContext<'_>) -> Result<(Analysis, Analysis, AnalysisOptions), NodeError> {
    let first = ctx.input(&FIRST)?;
    let second = at_rate_of(ctx, &first, ctx.input(&SECOND)?)?;
    let options = analysis_options(ctx)?;
    let a = analysed(first, "first", &options, None, None)?;
    let b = analysed(second, "second", &options, None, None)?;
    Ok((a, b, options))
}

fn analysed(
    clip: Arc<Clip>,
    port: &'static str,
    options: &AnalysisOptions,
    phases: Option<Arc<Phases>>,
    contacts: Option<Arc<Contacts>>,
) -> Result<Analysis, NodeError> {
    let frames = clip.frame_count();
    let fits = |what: &str, n: usize| {
        if n == frames {
            Ok(())
        } else {
            Err(NodeError::input(port, format!("has {frames} frames but the {what} wired with it describe {n}")))
        }
    };
    if let Some(p) = &phases {
        fits("phases", p.frame_count)?;
    }
    if let Some(c) = &contacts {
        fits("contacts", c.frame_count)?;
    }
    analyse(clip, options, phases.map(Arc::unwrap_or_clone), contacts.map(Arc::unwrap_or_clone))
        .map_err(|e| NodeError::input(port, e.to_string()))
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The motion to analyse.");
const REPORT: Output<Arc<Report>> = Output::new("report", "What the node decided and measured.");

const CURVES: Output<Arc<Curves>> = Output::new(
    "curves",
    "Angular momentum about the centre of mass (L.x, L.y, L.z, |L|, kg·m²/s; smoothed |L|) and the centre of \
     mass (com.x/y/z, m; com_speed, m/s), one sample per frame.",
);

/// `motion.angular_momentum`.
pub struct AngularMomentum;

static ANGULAR_MOMENTUM: NodeSchema = NodeSchema {
    kind: "motion.angular_momentum",
    category: "motion",
    doc: "Whole-body angular momentum about the centre of mass, and the centre of mass itself, from a mass \
          model mapped onto the skeleton.",
    inputs: &[CLIP.spec()],
    outputs: &[CURVES.spec(), REPORT.spec()],
    params: &MASS_PARAMS,
    writes_files: false,
    version: 1,
};

impl Node for AngularMomentum {
    fn schema(&self) -> &'static NodeSchema {
        &ANGULAR_MOMENTUM
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let (table, track, smoothed) = momentum_of(ctx, &clip)?;
        let mut curves = track.curves().map_err(NodeError::kernel)?;
        curves
            .push("|L| smoothed", "kg·m²/s", smoothed.iter().map(|l| l.length()).collect())
            .map_err(NodeError::kernel)?;
        let peak_frame = (0..smoothed.len()).max_by(|&a, &b| smoothed[a].length().total_cmp(&smoothed[b].length()));
        ctx.set_output(&CURVES, Arc::new(curves));
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "mass_model": table.method,
                "total_mass_kg": table.total_mass_kg,
                "segments": table.segments.iter().map(|s| json!({
                    "name": s.name, "mass_kg": s.mass_kg, "joints": s.joints, "rule": s.rule,
                })).collect::<Vec<_>>(),
                "peak_momentum": track.peak(),
                "peak_momentum_smoothed": peak_frame.map(|f| smoothed[f].length()),
                "peak_frame": peak_frame,
            })),
        );
        Ok(())
    }
}

const PHASES: Output<Arc<Phases>> =
    Output::new("phases", "Preparatory, main and posterior frame ranges (missing phases left out).");
const PHASE_CURVES: Output<Arc<Curves>> = Output::new(
    "curves",
    "What the phases were cut from, one sample per frame: smoothed |L| and the smoothed momentum along its \
     direction at the main-phase moment (kg·m²/s; negative where the body turns the other way).",
);
const MAIN_SECS: FloatParam = FloatParam::optional(
    "main_secs",
    "A moment inside the main phase; unset takes the moment of largest angular momentum.",
    0.0,
    1e6,
    "s",
);
const MAIN_START: FloatParam =
    FloatParam::optional("main_start_secs", "Hand-set start of the main phase; unset finds it.", 0.0, 1e6, "s");
const MAIN_END: FloatParam =
    FloatParam::optional("main_end_secs", "Hand-set end of the main phase; unset finds it.", 0.0, 1e6, "s");

/// `motion.segment_phases`.
pub struct SegmentPhases;

static SEGMENT_PHASES: NodeSchema = NodeSchema {
    kind: "motion.segment_phases",
    category: "motion",
    doc: "Splits a dynamic motion into preparatory, main and posterior phases by the direction of its angular \
          momentum; borders can be set by hand.",
    inputs: &[CLIP.spec()],
    outputs: &[PHASES.spec(), PHASE_CURVES.spec(), REPORT.spec()],
    params: &[TOTAL_MASS.0, MASS_TABLE.0, MASS_OVERRIDE.0, SMOOTHING.0, MAIN_SECS.0, MAIN_START.0, MAIN_END.0],
    writes_files: false,
    version: 1,
};

impl Node for SegmentPhases {
    fn schema(&self) -> &'static NodeSchema {
        &SEGMENT_PHASES
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let frame = |secs: Option<f64>| secs.map(|s| (s * clip.fps()).round() as usize);
        let phase_options = PhaseOptions {
            main_frame: frame(ctx.optional_float(&MAIN_SECS)?),
            main_start: frame(ctx.optional_float(&MAIN_START)?),
            main_end: frame(ctx.optional_float(&MAIN_END)?),
        };
        if let (Some(a), Some(b)) = (phase_options.main_start, phase_options.main_end)
            && b <= a
        {
            return Err(NodeError::param("main_end_secs", "must come after main_start_secs"));
        }
        let (_, _, smoothed) = momentum_of(ctx, &clip)?;
        let phases = segment_phases(&smoothed, clip.fps(), phase_options);
        let main_direction = smoothed.get(phases.main_frame).map_or(DVec3::ZERO, |l| l.normalize_or_zero());
        let mut curves = Curves::new(clip.fps(), smoothed.len());
        let pushed =
            curves.push("|L| smoothed", "kg·m²/s", smoothed.iter().map(|l| l.length()).collect()).and_then(|()| {
                curves.push("L along main", "kg·m²/s", smoothed.iter().map(|l| l.dot(main_direction)).collect())
            });
        pushed.map_err(NodeError::kernel)?;
        ctx.set_output(&PHASE_CURVES, Arc::new(curves));
        let secs =
            |r: Option<crate::model::FrameRange>| r.map(|r| [r.start as f64 / clip.fps(), r.end as f64 / clip.fps()]);
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "main_frame": phases.main_frame,
                "preparatory_secs": secs(phases.preparatory),
                "main_secs": secs(Some(phases.main)),
                "posterior_secs": secs(phases.posterior),
            })),
        );
        ctx.set_output(&PHASES, Arc::new(phases));
        Ok(())
    }
}

const FIRST: Input<Arc<Clip>> = Input::required("first", "The motion that plays first.");
const SECOND: Input<Arc<Clip>> =
    Input::required("second", "The motion that follows (same skeleton; resampled to the first's frame rate).");
const RULE: ChoiceParam<Rule> = ChoiceParam::new(
    "rule",
    "forward: the second motion turns the same way and keeps the first one's momentum going (double flip); \
     reverse: it turns the other way and the end of the first winds it up (one-two punch).",
    "forward",
);
const MAX_FACING: FloatParam = FloatParam::new(
    "max_facing_deg",
    "Refuse when the torsos face further apart than this after alignment.",
    45.0,
    0.0,
    180.0,
    "°",
);
const ALIGNED: Output<Arc<Clip>> = Output::new("clip", "The second motion, turned and moved onto the first.");

/// The second clip at the first clip's frame rate (with a warning when resampled).
fn at_rate_of(ctx: &mut NodeContext<'_>, first: &Clip, second: Arc<Clip>) -> Result<Arc<Clip>, NodeError> {
    if (second.fps() - first.fps()).abs() < 1e-9 {
        return Ok(second);
    }
    ctx.warn(format!("the second clip was resampled from {} to {} fps to match the first", second.fps(), first.fps()));
    resample(&second, first.fps()).map(Arc::new).map_err(|e| NodeError::input("second", e.to_string()))
}

fn rule_of(ctx: &NodeContext<'_>) -> Result<Rule, NodeError> {
    ctx.choice(&RULE)
}

/// `motion.align`.
pub struct Align;

static ALIGN: NodeSchema = NodeSchema {
    kind: "motion.align",
    category: "motion",
    doc: "Turns the second motion about the vertical so its angular momentum agrees (forward) or opposes \
          (reverse) the first's, and moves it so the feet meet where the first motion's main phase ends.",
    inputs: &[FIRST.spec(), SECOND.spec()],
    outputs: &[ALIGNED.spec(), REPORT.spec()],
    params: &[RULE.0, MAX_FACING.0, TOTAL_MASS.0, MASS_TABLE.0, MASS_OVERRIDE.0, SMOOTHING.0],
    writes_files: false,
    version: 1,
};

impl Node for Align {
    fn schema(&self) -> &'static NodeSchema {
        &ALIGN
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let rule = rule_of(ctx)?;
        let (a, b, _) = analysed_pair(ctx)?;
        let (yaw, yaw_from) = concat::alignment(&a, &b, (a.phases.main, b.phases.main), rule);
        let turn = yaw_rotation(yaw);
        // Where the blend would start: the end of the first main phase, and the start of
        // the second's main phase (forward) or of its preparatory phase's second half.
        let f = a.phases.main.end.saturating_sub(1);
        let g = match (rule, b.phases.preparatory) {
            (Rule::Reverse, Some(prep)) => prep.second_half().start,
            _ => b.phases.main.start,
        };
        let (facing, facing_compared) =
            facing_difference((&a.poses, &a.landmarks, f), (&b.poses, &b.landmarks, g), turn);
        let max = ctx.float(&MAX_FACING)?;
        if facing.to_degrees() > max {
            let refusal = crate::kernels::join::ConcatError::Facing { angle_deg: facing.to_degrees(), max_deg: max };
            return Err(NodeError::kernel(refusal));
        }
        let offset = feet_centre(&a.poses, f, &a.landmarks) - turn * feet_centre(&b.poses, g, &b.landmarks);
        let placed = place(&b.clip, yaw, offset).map_err(NodeError::kernel)?;
        ctx.set_output(&ALIGNED, Arc::new(placed));
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "rule": rule.name(),
                "yaw_deg": yaw.to_degrees(),
                "yaw_from": yaw_from,
                "feet_offset_m": [offset.x, offset.z],
                "facing_deg": facing.to_degrees(),
                "facing_compared": facing_compared,
                "first_frame": f,
                "second_frame": g,
            })),
        );
        Ok(())
    }
}

const PHASES_FIRST: Input<Arc<Phases>> =
    Input::optional("phases_first", "Phases of the first motion (e.g. hand-tuned); computed when unconnected.");
const PHASES_SECOND: Input<Arc<Phases>> = Input::optional("phases_second", "Phases of the second motion.");
const CONTACTS_FIRST: Input<Arc<Contacts>> =
    Input::optional("contacts_first", "Foot contacts of the first motion; detected when unconnected.");
const CONTACTS_SECOND: Input<Arc<Contacts>> = Input::optional("contacts_second", "Foot contacts of the second motion.");
const JOINED: Output<Arc<Clip>> = Output::new("clip", "The two motions as one.");
const SUPPORT: ChoiceParam<Support> = ChoiceParam::new(
    "support",
    "Which frames may blend: double (both feet down, the paper's rule), any, or auto (double support where \
     the blendable periods have at least min_blend_secs of it, any frame otherwise, e.g. airborne flips).",
    "auto",
);
const MAX_COST: FloatParam = FloatParam::new(
    "max_relative_cost",
    "Refuse when the best cost F, divided by the mean squared peak momentum of the clips, is above this.",
    1.0,
    0.0,
    1e6,
    "",
);
const WINDOW_THRESHOLD: FloatParam = FloatParam::new(
    "window_threshold",
    "The blend window grows while the squared momentum difference, relative like the cost, stays below this.",
    0.25,
    0.0,
    1e6,
    "",
);
const MIN_BLEND: FloatParam = FloatParam::new(
    "min_blend_secs",
    "The blend lasts at least this long (growing past the blendable periods if it must).",
    0.25,
    0.0,
    10.0,
    "s",
);
const MIN_SCALE: FloatParam = FloatParam::new(
    "min_time_scale",
    "Lower bound of the time scale s (eq. 9); s < 1 slows the blend down.",
    0.5,
    0.05,
    1.0,
    "",
);
const MAX_SCALE: FloatParam =
    FloatParam::new("max_time_scale", "Upper bound of the time scale s; 1 and 1 turn scaling off.", 2.0, 1.0, 20.0, "");
const MIN_GAP: FloatParam = FloatParam::new(
    "min_peak_gap_secs",
    "The second motion's peak plays at least this long after the first's (before the blend's time scaling). \
     0 is the paper's method, which overlaps two similar motions into one; about one main phase keeps a \
     double flip double.",
    0.0,
    0.0,
    60.0,
    "s",
);
const FOOT_LOCK: ChoiceParam<OnOff> = ChoiceParam::new(
    "foot_lock",
    "The paper's clean-up after the blend: feet planted during the blend (whole plants touching the window) are \
     held where they were put down by the foot lock's IK, so the blended legs do not slide them ('off' keeps the raw blend).",
    "on",
);
const W_DM: FloatParam = FloatParam::new("weight_momentum", "Weight of F_dm (eq. 4).", 1.0, 0.0, 1e6, "");
const W_INERTIA: FloatParam = FloatParam::new("weight_inertia", "Weight of F_inertia (eq. 6).", 1.0, 0.0, 1e6, "");
const W_TIME: FloatParam = FloatParam::new("weight_time", "Weight of F_time (eq. 7).", 1.0, 0.0, 1e6, "");

/// `motion.concat`.
pub struct Concat;

static CONCAT: NodeSchema = NodeSchema {
    kind: "motion.concat",
    category: "motion",
    doc: "Joins two dynamic motions (punches, kicks, flips) the way a performer would chain them, guided by \
          angular momentum (Shum et al. 2009): aligns them, finds the best moment to blend, blends and smooths \
          the blend's timing. The report says what was chosen and why.",
    inputs: &[
        FIRST.spec(),
        SECOND.spec(),
        PHASES_FIRST.spec(),
        PHASES_SECOND.spec(),
        CONTACTS_FIRST.spec(),
        CONTACTS_SECOND.spec(),
    ],
    outputs: &[JOINED.spec(), REPORT.spec()],
    params: &[
        RULE.0,
        SUPPORT.0,
        MAX_COST.0,
        WINDOW_THRESHOLD.0,
        MIN_BLEND.0,
        MAX_FACING.0,
        MIN_SCALE.0,
        MAX_SCALE.0,
        MIN_GAP.0,
        FOOT_LOCK.0,
        W_DM.0,
        W_INERTIA.0,
        W_TIME.0,
        TOTAL_MASS.0,
        MASS_TABLE.0,
        MASS_OVERRIDE.0,
        SMOOTHING.0,
    ],
    writes_files: false,
    version: 4,
};

fn set_joined(ctx: &mut NodeContext<'_>, joined: Concatenated) {
    ctx.set_output(&JOINED, Arc::new(joined.clip));
    ctx.set_output(&REPORT, Arc::new(joined.report));
}

impl Node for Concat {
    fn schema(&self) -> &'static NodeSchema {
        &CONCAT
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let first = ctx.input(&FIRST)?;
        let second_in = ctx.input(&SECOND)?;
        let resampled = (second_in.fps() - first.fps()).abs() > 1e-9;
        let second = at_rate_of(ctx, &first, second_in)?;
        let options = analysis_options(ctx)?;
        let (phases_second, contacts_second) =
            (ctx.optional_input(&PHASES_SECOND)?, ctx.optional_input(&CONTACTS_SECOND)?);
        if resampled && (phases_second.is_some() || contacts_second.is_some()) {
            return Err(NodeError::input(
                "phases_second",
                "phases and contacts of the second clip must be computed at the first clip's frame rate: resample it before",
            ));
        }
        let a = analysed(
            first,
            "first",
            &options,
            ctx.optional_input(&PHASES_FIRST)?,
            ctx.optional_input(&CONTACTS_FIRST)?,
        )?;
        let b = analysed(second, "second", &options, phases_second, contacts_second)?;
        let support = ctx.choice(&SUPPORT)?;
        let params = ConcatParams {
            rule: rule_of(ctx)?,
            support,
            weights: [ctx.float(&W_DM)?, ctx.float(&W_INERTIA)?, ctx.float(&W_TIME)?],
            max_relative_cost: ctx.float(&MAX_COST)?,
            window_threshold: ctx.float(&WINDOW_THRESHOLD)?,
            min_blend_secs: ctx.float(&MIN_BLEND)?,
            max_facing_rad: ctx.float(&MAX_FACING)?.to_radians(),
            time_scale_range: (ctx.float(&MIN_SCALE)?, ctx.float(&MAX_SCALE)?),
            min_peak_gap_secs: ctx.float(&MIN_GAP)?,
            foot_lock: ctx.choice(&FOOT_LOCK)? == OnOff::On,
        };
        ctx.check_cancelled()?;
        let joined = concatenate(&a, &b, &params, &options).map_err(NodeError::kernel)?;
        set_joined(ctx, joined);
        Ok(())
    }
}

const SEARCH_SHARE: FloatParam = FloatParam::new(
    "search_share",
    "The cut is searched in this last share of the first motion and this first share of the second.",
    0.25,
    0.01,
    1.0,
    "",
);
const CROSSFADE: FloatParam = FloatParam::new("crossfade_secs", "Length of the crossfade.", 0.25, 0.0, 10.0, "s");

/// `motion.concat_baseline`.
pub struct ConcatBaseline;

static CONCAT_BASELINE: NodeSchema = NodeSchema {
    kind: "motion.concat_baseline",
    category: "motion",
    doc: "Joins two motions where their poses are most alike, with a short crossfade (the Motion Graphs \
          criterion), for comparison with motion.concat.",
    inputs: &[FIRST.spec(), SECOND.spec()],
    outputs: &[JOINED.spec(), REPORT.spec()],
    params: &[SEARCH_SHARE.0, CROSSFADE.0, TOTAL_MASS.0, MASS_TABLE.0, MASS_OVERRIDE.0, SMOOTHING.0],
    writes_files: false,
    version: 1,
};

impl Node for ConcatBaseline {
    fn schema(&self) -> &'static NodeSchema {
        &CONCAT_BASELINE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let (a, b, options) = analysed_pair(ctx)?;
        let params = BaselineParams { search_share: ctx.float(&SEARCH_SHARE)?, crossfade_secs: ctx.float(&CROSSFADE)? };
        let joined = concatenate_baseline(&a, &b, &params, &options).map_err(NodeError::kernel)?;
        set_joined(ctx, joined);
        Ok(())
    }
}
