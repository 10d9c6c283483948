//! `motion.contacts`: the node over the foot-contact kernel ([`crate::kernels::contacts`]).

use std::sync::Arc;

use crate::kernels::contacts::{ContactThresholds, NamedFeet, REFERENCE_LEG_M, contacts_with, joint_pair};
use crate::model::{Clip, Contacts, forward_kinematics};
use crate::node::{
    ChoiceParam, FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, OnOff, Output, Registry, TextParam,
};

/// Registers the contact node.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(DetectContacts));
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The clip whose feet to watch.");
const CONTACTS: Output<Arc<Contacts>> =
    Output::new("contacts", "Frames where each foot is on the ground, and where both are.");
const ENTER_HEIGHT: FloatParam = FloatParam::new(
    "enter_height_m",
    "A foot touches down when its ankle or toe comes this close to the height it rests at in the clip.",
    0.05,
    0.0,
    1.0,
    "m",
);
const LEAVE_HEIGHT: FloatParam =
    FloatParam::new("leave_height_m", "It lifts off when both rise above this height.", 0.08, 0.0, 1.0, "m");
const ENTER_SPEED: FloatParam =
    FloatParam::new("enter_speed_mps", "…and touches down only while slower than this.", 0.5, 0.0, 20.0, "m/s");
const LEAVE_SPEED: FloatParam =
    FloatParam::new("leave_speed_mps", "It lifts off when faster than this.", 0.9, 0.0, 20.0, "m/s");
const MIN_DURATION: FloatParam =
    FloatParam::new("min_duration_secs", "Shorter contacts are ignored.", 0.05, 0.0, 10.0, "s");

const SCALE_TO_LEGS: ChoiceParam<OnOff> = ChoiceParam::new(
    "scale_to_legs",
    "The heights and speeds above are for a 0.84 m leg (hip to knee to ankle, an adult's) and are scaled to the clip's \
     legs, heights and speeds in proportion (a motion carried onto a smaller body keeps its timing, so its feet move \
     less far as fast). 'off' uses them as metres and m/s on any body. A rig whose legs cannot be read keeps them as \
     they are (with a warning).",
    "on",
);

const FEET: TextParam = TextParam::new(
    "feet",
    "The ankle joints, left then right, comma separated (e.g. 'FootL, FootR'), when the feet are not found by name or shape. Empty: found from the body.",
    "",
);
const TOES: TextParam = TextParam::new(
    "toes",
    "The toe joints watched with the ankles, left then right, comma separated (e.g. 'ToeL, ToeR'). Empty: the joint farthest below each ankle.",
    "",
);

const HANDS: TextParam = TextParam::new(
    "hands",
    "The hand joints, left then right, comma separated (e.g. 'LeftHand, RightHand'), for motions that put the hands down \
     (cartwheels, crawls, push-ups): each is watched at its palm (half way from the wrist to the fingertip), by height, \
     when it comes within reach of the floor the feet stand on. Stages and motion.foot_lock take hand contacts like the \
     feet's; gait measures do not. Empty: hands are not watched.",
    "",
);

/// Reads and checks the threshold params.
fn thresholds_from(ctx: &NodeContext<'_>) -> Result<ContactThresholds, NodeError> {
    let t = ContactThresholds {
        enter_height_m: ctx.float(&ENTER_HEIGHT)?,
        enter_speed_mps: ctx.float(&ENTER_SPEED)?,
        leave_height_m: ctx.float(&LEAVE_HEIGHT)?,
        leave_speed_mps: ctx.float(&LEAVE_SPEED)?,
        min_duration_secs: ctx.float(&MIN_DURATION)?,
        leg_m: (ctx.choice(&SCALE_TO_LEGS)? == OnOff::On).then_some(REFERENCE_LEG_M),
    };
    if t.leave_height_m < t.enter_height_m {
        return Err(NodeError::param("leave_height_m", "must not be below enter_height_m"));
    }
    if t.leave_speed_mps < t.enter_speed_mps {
        return Err(NodeError::param("leave_speed_mps", "must not be below enter_speed_mps"));
    }
    Ok(t)
}

/// `motion.contacts`.
pub struct DetectContacts;

static DETECT_CONTACTS: NodeSchema = NodeSchema {
    kind: "motion.contacts",
    category: "motion",
    doc: "Finds when each foot (and each named hand) is planted (low and slow, with hysteresis) and the double-support \
          frames.",
    inputs: &[CLIP.spec()],
    outputs: &[CONTACTS.spec()],
    params: &[
        ENTER_HEIGHT.0,
        LEAVE_HEIGHT.0,
        ENTER_SPEED.0,
        LEAVE_SPEED.0,
        MIN_DURATION.0,
        SCALE_TO_LEGS.0,
        FEET.0,
        TOES.0,
        HANDS.0,
    ],
    writes_files: false,
    version: 2,
};

impl Node for DetectContacts {
    fn schema(&self) -> &'static NodeSchema {
        &DETECT_CONTACTS
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let thresholds = thresholds_from(ctx)?;
        let skeleton = clip.skeleton();
        let named = NamedFeet {
            ankles: joint_pair(skeleton, ctx.text_param(&FEET)?).map_err(|e| NodeError::param("feet", e))?,
            toes: joint_pair(skeleton, ctx.text_param(&TOES)?).map_err(|e| NodeError::param("toes", e))?,
            hands: joint_pair(skeleton, ctx.text_param(&HANDS)?).map_err(|e| NodeError::param("hands", e))?,
        };
        let found = contacts_with(&clip, &forward_kinematics(&clip), &thresholds, &named)
            .map_err(|why| NodeError::input("clip", format!("the feet could not be found: {why}")))?;
        if thresholds.leg_m.is_some() && found.scaled_to_leg_m.is_none() {
            ctx.warn(
                "the legs could not be read from the body, so the thresholds are not scaled to them: they are used as \
                 metres and m/s (set for a 0.84 m leg)",
            );
        }
        ctx.set_output(&CONTACTS, Arc::new(found.contacts));
        Ok(())
    }
}
