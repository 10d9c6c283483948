//! `motion.quality`: the node over the quality measures ([`crate::kernels::quality`]).

use std::sync::Arc;

use crate::kernels::quality::{QualityOptions, measure_quality};
use crate::model::{Clip, ClipSet, Contacts, Mesh};
use crate::node::{FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Registry, Report};

/// Registers the quality node.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(MeasureQuality));
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The motion to check.");
const SOURCE: Input<Arc<Clip>> = Input::optional(
    "source",
    "A clip the motion was made from (e.g. a join's first clip): spikes and root jumps are compared with its own, \
     and its stride (step ÷ leg length, pelvis speed scaled by the leg-length ratio) with the motion's; with \
     several sources the motion's stride is measured against the span of theirs.",
);
const OTHER_SOURCE: Input<Arc<Clip>> =
    Input::optional("other_source", "A second clip the motion was made from (e.g. a join's second clip).");
const SOURCE_SET: Input<Arc<ClipSet>> =
    Input::optional("source_set", "Clips the motion was made from (e.g. a transition graph's clip set).");
const CONTACTS: Input<Arc<Contacts>> = Input::optional(
    "contacts",
    "When each foot is down (motion.contacts on this clip); when unconnected, detected with motion.contacts' default \
     thresholds scaled to the clip's legs (heights and speeds in proportion; the defaults are for a 0.84 m \
     leg). Those end a plant when the foot moves faster than 0.9 m/s (scaled), so a planted foot gliding \
     faster counts as lifted: connect motion.contacts with a higher leave_speed_mps to catch fast glides.",
);
const MESH: Input<Arc<Mesh>> = Input::optional(
    "mesh",
    "A mesh skinned to the clip's skeleton: its soles are checked against the floor too (joints alone sit above the skin).",
);
const PROPS: Input<Arc<Mesh>> = Input::optional(
    crate::node::PROPS_PORT,
    "The scene's fixed objects as closed surfaces (physics.simulate's stool): how deep the skinned mesh goes into \
     them is measured too (needs mesh).",
);
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Foot skate (cm per frame), feet under or above the floor (cm), acceleration spikes (m/s², ratios), \
     one-frame root velocity changes (m/s), bone-length drift (cm), pops, stride (step length m and ÷ leg length, \
     pelvis horizontal speed 5th–95th percentile m/s; against the source's), how deep the skinned mesh goes into the \
     props (cm) and findings.",
);
const FLOOR: FloatParam = FloatParam::new(
    "floor_height_m",
    "Height of the floor in the clip's metres: feet below it penetrate, planted feet above it float.",
    0.0,
    -100.0,
    100.0,
    "m",
);
const NEIGHBOURHOOD: FloatParam = FloatParam::new(
    "neighbourhood_secs",
    "An acceleration spike is compared with the accelerations within this time on either side.",
    0.25,
    0.02,
    10.0,
    "s",
);
const WINDOW_START: FloatParam = FloatParam::new(
    "window_start_secs",
    "First moment looked at, seconds from the clip's start (e.g. where a transition begins).",
    0.0,
    0.0,
    1e6,
    "s",
);
const WINDOW_END: FloatParam = FloatParam::optional(
    "window_end_secs",
    "Last moment looked at, seconds from the clip's start; unset looks to the end.",
    0.0,
    1e6,
    "s",
);

/// `motion.quality`.
pub struct MeasureQuality;

static MEASURE_QUALITY: NodeSchema = NodeSchema {
    kind: "motion.quality",
    category: "motion",
    doc: "Checks a motion the way an animator does: planted feet that slide, feet through or above the floor, \
          jerky joints against the source clips, sudden root speed changes, stretching bones and pops, \
          a body sinking into the scene's props, over the whole clip or a window of it, and the stride (step length ÷ leg length, pelvis speed) \
          against the source's. Expectation files can gate on its report.",
    inputs: &[
        CLIP.spec(),
        SOURCE.spec(),
        OTHER_SOURCE.spec(),
        SOURCE_SET.spec(),
        CONTACTS.spec(),
        MESH.spec(),
        PROPS.spec(),
    ],
    outputs: &[REPORT.spec()],
    params: &[FLOOR.0, NEIGHBOURHOOD.0, WINDOW_START.0, WINDOW_END.0],
    writes_files: false,
    // 2: stride (step length ÷ leg length, pelvis speed range) and its comparison with the source.
    // 3: contacts detected for the clip's legs.
    // 4: the props input.
    version: 4,
};

impl Node for MeasureQuality {
    fn schema(&self) -> &'static NodeSchema {
        &MEASURE_QUALITY
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let mut sources: Vec<Arc<Clip>> =
            [ctx.optional_input(&SOURCE)?, ctx.optional_input(&OTHER_SOURCE)?].into_iter().flatten().collect();
        if let Some(set) = ctx.optional_input(&SOURCE_SET)? {
            sources.extend(set.clips().iter().map(|c| c.clip.clone()));
        }
        let contacts = ctx.optional_input(&CONTACTS)?;
        let mesh = ctx.optional_input(&MESH)?;
        let start = ctx.float(&WINDOW_START)?;
        let end = ctx.optional_float(&WINDOW_END)?;
        if end.is_some_and(|e| e < start) {
            return Err(NodeError::param("window_end_secs", "must not be before window_start_secs"));
        }
        let options = QualityOptions {
            floor_height_m: ctx.float(&FLOOR)?,
            neighbourhood_secs: ctx.float(&NEIGHBOURHOOD)?,
            window_secs: Some((start, end.unwrap_or(f64::INFINITY))),
            ..QualityOptions::default()
        };
        let sources: Vec<&Clip> = sources.iter().map(|c| c.as_ref()).collect();
        let mut report = measure_quality(&clip, contacts.as_deref(), &sources, mesh.as_deref(), &options);
        if let Some(props) = ctx.optional_input(&PROPS)? {
            report.measure_props(&clip, mesh.as_deref(), &props);
        }
        let json = serde_json::to_value(&report).map_err(|e| NodeError::Failed(e.to_string()))?;
        ctx.set_output(&REPORT, Arc::new(crate::model::into_report(json)));
        Ok(())
    }
}
