//! `motion.foot_lock`: the node over [`crate::kernels::ik::foot_lock`].

use std::sync::Arc;

use serde_json::json;

use super::solve::parse_weights;
use crate::kernels::ik::foot_lock::{DEFAULT_SOFT_REACH, FootLockError, FootLockParams, Ground, foot_lock};
use crate::kernels::ik::{RigError, SolveParams};
use crate::model::choice::choices;
use crate::model::{Clip, Contacts, Mesh};
use crate::node::into_report;
use crate::node::{
    ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Report, TextParam,
};

/// `"ToeL, ToeR"` as two names; empty text is `None`.
fn parse_toes(text: &str) -> Result<Option<[String; 2]>, String> {
    if text.trim().is_empty() {
        return Ok(None);
    }
    match text.split(',').map(|s| s.trim().to_owned()).collect::<Vec<_>>()[..] {
        [ref left, ref right] if !left.is_empty() && !right.is_empty() => Ok(Some([left.clone(), right.clone()])),
        _ => Err(format!("expected two toe joint names, left then right, separated by a comma; got '{text}'")),
    }
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The motion whose feet slide.");
const CONTACTS: Input<Arc<Contacts>> =
    Input::required("contacts", "When each foot is down (motion.contacts on the same clip).");
const MESH: Input<Arc<Mesh>> = Input::optional(
    "mesh",
    "The character's mesh skinned to the clip's skeleton: with ground 'soles', its skinned soles are put on the floor.",
);
const LOCKED: Output<Arc<Clip>> = Output::new("clip", "The motion with planted feet held still.");
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Per foot: plants and how far the toe slid while planted, before and after; per-frame IK residuals.",
);
const BLEND: FloatParam = FloatParam::new(
    "blend_secs",
    "Time over which a plant fades in before the foot lands and out after it lifts (every frame of a contact is held whole), so the foot never jumps.",
    0.15,
    0.0,
    2.0,
    "s",
);
const WEIGHTS: TextParam = TextParam::new(
    "weights",
    "Stiffness of the leg joints that turn (knees and hips), `JOINT=W` with W in [0, 1]; unnamed joints are free.",
    "",
);
const TOLERANCE: FloatParam = FloatParam::new(
    "tolerance_m",
    "A frame is solved when each ankle is this close to its goal.",
    1e-4,
    1e-7,
    1.0,
    "m",
);
const TOES: TextParam = TextParam::new(
    "toes",
    "The toe joints held in place, left then right, comma separated (e.g. 'ToeL, ToeR'). Empty: the joint farthest below each ankle.",
    "",
);
choices! {
    /// The `ground` choice: [`Ground`] without its mesh.
    enum GroundChoice { Clip = "clip", Soles = "soles" }
}
const GROUND: ChoiceParam<GroundChoice> = ChoiceParam::new(
    "ground",
    "Where planted feet stand: at the clip's heights ('clip'), or with the lowest vertex of each foot's skinned sole on the floor through every contact ('soles', needs the mesh input; the swing between two plants eases from one plant's height offset to the next's).",
    "clip",
);
const FLOOR: FloatParam = FloatParam::new(
    "floor_height_m",
    "Height of the floor the soles are put on (ground 'soles'), in the clip's metres.",
    0.0,
    -100.0,
    100.0,
    "m",
);
const SOFT_REACH: FloatParam = FloatParam::new(
    "soft_reach",
    "The last part of each leg's reach, as a fraction of its length, over which the ankle's goal eases towards full stretch (soft IK): a plant coming into or going out of reach bends the knee smoothly instead of snapping it straight, and is held that much short. 0: a hard reach.",
    DEFAULT_SOFT_REACH,
    0.0,
    0.2,
    "",
);
const ITERATIONS: IntParam = IntParam::new("max_iterations", "IK iterations allowed per frame.", 50, 1, 10_000);

/// `motion.foot_lock`.
pub struct FootLock;

static FOOT_LOCK: NodeSchema = NodeSchema {
    kind: "motion.foot_lock",
    category: "ik",
    doc: "Removes foot sliding: while a foot is in contact it stays where it was put down. The knee and hip turn (weighted IK), the foot keeps its angle, the body keeps its path.",
    inputs: &[CLIP.spec(), CONTACTS.spec(), MESH.spec()],
    outputs: &[LOCKED.spec(), REPORT.spec(), super::RESIDUAL_CURVES.spec()],
    params: &[BLEND.0, WEIGHTS.0, TOLERANCE.0, ITERATIONS.0, TOES.0, GROUND.0, FLOOR.0, SOFT_REACH.0],
    writes_files: false,
    // 4: goals near full stretch eased (soft_reach), the shortfall reported per foot.
    // 5: soft_reach 0.02 -> 0.03 (a straight knee at toe-off no longer jumps on CesiumMan's run).
    // 6: soft_reach 0.03 -> 0.05 (the next toe-off of that run, with the T-pose frame dropped).
    version: 6,
};

impl Node for FootLock {
    fn schema(&self) -> &'static NodeSchema {
        &FOOT_LOCK
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let contacts = ctx.input(&CONTACTS)?;
        let ground = match (ctx.choice(&GROUND)?, ctx.optional_input(&MESH)?) {
            (GroundChoice::Soles, Some(mesh)) => Ground::Soles { mesh, floor_height_m: ctx.float(&FLOOR)? },
            (GroundChoice::Soles, None) => {
                return Err(NodeError::input("mesh", "ground 'soles' needs the character's skinned mesh connected"));
            }
            (GroundChoice::Clip, _) => Ground::Clip,
        };
        let params = FootLockParams {
            blend_secs: ctx.float(&BLEND)?,
            weights: parse_weights(ctx.text_param(&WEIGHTS)?).map_err(|e| NodeError::param("weights", e))?,
            solve: SolveParams {
                tolerance_m: ctx.float(&TOLERANCE)?,
                max_iterations: usize::try_from(ctx.int(&ITERATIONS)?).unwrap_or(1),
                ..SolveParams::default()
            },
            toes: parse_toes(ctx.text_param(&TOES)?).map_err(|e| NodeError::param("toes", e))?,
            ground,
            soft_reach: ctx.float(&SOFT_REACH)?,
        };
        let locked = foot_lock(&clip, &contacts, &params).map_err(|e| match e {
            FootLockError::Rig(RigError::UnknownJoint(_)) => NodeError::param("weights", e.to_string()),
            FootLockError::UnknownToe(_) => NodeError::param("toes", e.to_string()),
            FootLockError::Soles(_) | FootLockError::NoSole(_) => NodeError::input("mesh", e.to_string()),
            e => NodeError::input("contacts", e.to_string()),
        })?;
        let residuals: Vec<f64> = locked.frames.iter().map(|r| r.residual_m).collect();
        let unconverged = locked.frames.iter().filter(|r| !r.converged).count();
        if unconverged > 0 {
            // With a soft reach every goal is within the leg's reach (frames eased short are
            // in the report's short_frames), so what is left is the solve's own limit.
            let (worst_frame, worst_m) =
                residuals.iter().copied().enumerate().fold((0, 0.0), |w, (f, r)| if r > w.1 { (f, r) } else { w });
            let reach = if params.soft_reach > 0.0 {
                ""
            } else {
                "; with soft_reach 0 a plant out of the leg's reach does this"
            };
            ctx.warn(format!(
                "{unconverged} of {} frames did not hold the feet within the tolerance ({} m) in {} iterations; the \
                 worst is {worst_m:.5} m off at frame {worst_frame} (raise iterations or tolerance){reach}",
                residuals.len(),
                params.solve.tolerance_m,
                params.solve.max_iterations,
            ));
        }
        let feet: Vec<_> = locked
            .feet
            .iter()
            .map(|f| {
                let mut foot = json!({
                    "foot": f.foot,
                    "plants": f.plants,
                    "skate_before_m": f.skate_before_m,
                    "skate_after_m": f.skate_after_m,
                    "short_frames": f.short_frames,
                    "shortfall_max_m": f.shortfall_max_m,
                });
                if let Some((lo, hi)) = f.lift_range_m {
                    foot["lift_range_m"] = json!([lo, hi]);
                }
                foot
            })
            .collect();
        ctx.set_output(
            &super::RESIDUAL_CURVES,
            super::residual_curves(clip.fps(), vec![("residual", "m", residuals.clone())])?,
        );
        ctx.set_output(
            &REPORT,
            Arc::new(into_report(json!({
                "feet": feet,
                "max_residual_m": residuals.iter().copied().fold(0.0, f64::max),
                "unconverged_frames": unconverged,
                "residual_m_per_frame": residuals,
            }))),
        );
        ctx.set_output(&LOCKED, Arc::new(locked.clip));
        Ok(())
    }
}
