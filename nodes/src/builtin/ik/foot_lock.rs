//! Foot locking: feet that should be planted stay where they were put down, by the
//! weighted IK of [`super::solve`].
//!
//! Per foot and contact (from `motion.contacts`):
//! 1. The planted place is where the toe tip is at the contact's lowest frame ([`Plants`]).
//! 2. Each frame of the contact, the foot's drift is the toe tip's horizontal distance from
//!    that place; its correction `c = w · (place − toe)` (horizontal only, so heel strike
//!    and toe-off keep their heights) ramps in and out with the plant weight `w` over
//!    `blend_secs` at the contact's edges.
//! 3. The ankle's goal is the clip's ankle plus `c`; the two joints above it (knee and hip)
//!    turn to reach it (one rig with both ankles as effectors; unplanted ankles keep their
//!    own position as goal, so that leg does not move).
//! 4. The ankle's local rotation is then reset so the foot keeps its world orientation from
//!    the clip: the whole foot, toes included, moves by exactly `c`.
//!
//! The root and every joint outside the legs are left untouched, so the body's path is the
//! clip's; a plant out of the leg's reach is met as closely as the leg allows and counted.

use std::sync::Arc;

use glam::{DVec3, Quat};
use serde_json::json;

use super::retarget::Plants;
use super::rig::{IkRig, RigError};
use super::solve::{IkSolver, SolveParams, SolveReport, parse_weights};
use crate::kernels::body::limb_tip;
use crate::model::fk::pose_world;
use crate::model::{Clip, ClipError, ClipPoses, Contacts, Transform, forward_kinematics};
use crate::node::into_report;
use crate::node::{FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Report, TextParam};

/// Controls of a foot lock.
#[derive(Clone, Debug, PartialEq)]
pub struct FootLockParams {
    /// Time over which a plant fades in and out at a contact's edges (seconds).
    pub blend_secs: f64,
    /// Stiffness per joint name (`W` in [0, 1]); legs' joints not named are free.
    pub weights: Vec<(String, f64)>,
    /// Tolerance and iteration limits of each frame's solve.
    pub solve: SolveParams,
    /// The toe joints held planted, per foot of the contacts (left, right), by name; `None`:
    /// the joint farthest below each ankle.
    pub toes: Option<[String; 2]>,
}

impl Default for FootLockParams {
    fn default() -> Self {
        FootLockParams { blend_secs: 0.05, weights: Vec::new(), solve: SolveParams::default(), toes: None }
    }
}

/// How one foot was locked.
#[derive(Clone, Debug, PartialEq)]
pub struct FootReport {
    /// The ankle joint's name.
    pub foot: String,
    /// Contacts (plants) of this foot.
    pub plants: usize,
    /// Horizontal toe-tip travel in the fully planted frames, before the lock (metres).
    pub skate_before_m: f64,
    /// The same after the lock (metres).
    pub skate_after_m: f64,
}

/// A locked clip and what the lock did.
#[derive(Clone, Debug)]
pub struct FootLocked {
    /// The clip with planted feet held in place.
    pub clip: Clip,
    /// Per foot, in the order of the contacts.
    pub feet: Vec<FootReport>,
    /// Each frame's solve.
    pub frames: Vec<SolveReport>,
}

/// Why feet cannot be locked.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FootLockError {
    /// The contacts were detected on another clip.
    #[error("the contacts cover {contacts} frames but the clip has {clip}")]
    FrameCount {
        /// Frames the contacts refer to.
        contacts: usize,
        /// Frames of the clip.
        clip: usize,
    },
    /// A contact names a foot the skeleton lacks.
    #[error("the skeleton has no foot joint `{0}` named by the contacts")]
    UnknownFoot(String),
    /// A foot without two joints above it to turn.
    #[error("foot `{0}` has no knee and hip above it to turn")]
    ShortLeg(String),
    /// A toe named by the toes param is not in the skeleton.
    #[error("the clip's skeleton has no toe joint named '{0}'")]
    UnknownToe(String),
    /// The rig could not be built.
    #[error(transparent)]
    Rig(#[from] RigError),
    /// The clip could not be built.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// Holds the feet of `clip` planted during `contacts` (see the module doc).
pub fn foot_lock(clip: &Clip, contacts: &Contacts, params: &FootLockParams) -> Result<FootLocked, FootLockError> {
    if contacts.frame_count != clip.frame_count() {
        return Err(FootLockError::FrameCount { contacts: contacts.frame_count, clip: clip.frame_count() });
    }
    let skeleton = clip.skeleton();
    let joints = skeleton.joints();
    let mut rig = IkRig::new(skeleton.clone());
    let mut ankles = Vec::new();
    for foot in &contacts.feet {
        let ankle = skeleton.index_of(&foot.foot).ok_or_else(|| FootLockError::UnknownFoot(foot.foot.clone()))?;
        let knee = joints[ankle].parent.ok_or_else(|| FootLockError::ShortLeg(foot.foot.clone()))?;
        let hip = joints[knee].parent.ok_or_else(|| FootLockError::ShortLeg(foot.foot.clone()))?;
        for j in [hip, knee] {
            let w = params.weights.iter().find(|(n, _)| *n == joints[j].name).map_or(1.0, |(_, w)| *w);
            rig.add_joint(j, [true; 3], w);
        }
        rig.add_effector(ankle);
        ankles.push(ankle);
    }
    for (name, _) in &params.weights {
        rig.joint(name)?;
    }
    let rig = rig.finish()?;
    let blend = (params.blend_secs * clip.fps()).round().max(1.0) as usize;
    let tips: Vec<usize> = match &params.toes {
        Some(names) => names
            .iter()
            .take(ankles.len())
            .map(|name| skeleton.index_of(name).ok_or_else(|| FootLockError::UnknownToe(name.clone())))
            .collect::<Result<_, _>>()?,
        None => ankles.iter().map(|&a| limb_tip(skeleton, a)).collect(),
    };
    let plants: Vec<Plants> =
        contacts.feet.iter().zip(&tips).map(|(foot, &tip)| Plants::new(clip, tip, &foot.intervals, blend)).collect();

    let n = skeleton.len();
    let before = forward_kinematics(clip);
    let mut solver = IkSolver::new(rig);
    let mut world = vec![Transform::IDENTITY; n];
    let mut goals = vec![DVec3::ZERO; ankles.len()];
    let mut foot_in_world = vec![Quat::IDENTITY; ankles.len()];
    let mut rotations = clip.rotations().to_vec();
    let mut frames = Vec::with_capacity(clip.frame_count());
    let mut pose = solver.rig().pose_from(clip.frame_rotations(0), clip.frame_translations(0));
    for f in 0..clip.frame_count() {
        let original = before.frame(f);
        for (k, &ankle) in ankles.iter().enumerate() {
            let toe = original[tips[k]].translation.as_dvec3();
            let correction = match plants[k].at(f) {
                Some((place, w)) => w * (place - toe).with_y(0.0),
                None => DVec3::ZERO,
            };
            goals[k] = original[ankle].translation.as_dvec3() + correction;
            foot_in_world[k] = original[ankle].rotation;
        }
        solver.rig().fill_pose(clip.frame_rotations(f), clip.frame_translations(f), &mut pose);
        frames.push(solver.solve(&mut pose, &goals, &params.solve));
        let out = &mut rotations[f * n..(f + 1) * n];
        solver.rig().rotations_of(&pose, out);
        // Feet keep their world orientation: the ankle undoes what the leg above it turned.
        pose_world(skeleton, out, clip.frame_translations(f), &mut world);
        for (k, &ankle) in ankles.iter().enumerate() {
            if let Some(parent) = joints[ankle].parent {
                out[ankle] = world[parent].rotation.inverse() * foot_in_world[k];
            }
        }
    }
    let locked = Clip::new(skeleton.clone(), clip.fps(), rotations, clip.translations().to_vec(), clip.import_scale)?;
    let after = forward_kinematics(&locked);
    let feet = contacts
        .feet
        .iter()
        .zip(&plants)
        .zip(&tips)
        .map(|((foot, plant), &tip)| FootReport {
            foot: foot.foot.clone(),
            plants: foot.intervals.iter().filter(|r| !r.is_empty()).count(),
            skate_before_m: planted_travel_m(&before, tip, plant),
            skate_after_m: planted_travel_m(&after, tip, plant),
        })
        .collect();
    Ok(FootLocked { clip: locked, feet, frames })
}

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

/// Horizontal travel of joint `point` between consecutive frames that are both fully
/// planted (weight 1) in `poses`, in metres: how far a foot slides where it should stand still.
pub fn planted_travel_m(poses: &ClipPoses, point: usize, plants: &Plants) -> f64 {
    let planted = |f: usize| plants.at(f).is_some_and(|(_, w)| w >= 1.0);
    (1..poses.frame_count())
        .filter(|&f| planted(f) && planted(f - 1))
        .map(|f| f64::from((poses.position(f, point) - poses.position(f - 1, point)).with_y(0.0).length()))
        .sum()
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The motion whose feet slide.");
const CONTACTS: Input<Arc<Contacts>> =
    Input::required("contacts", "When each foot is down (motion.contacts on the same clip).");
const LOCKED: Output<Arc<Clip>> = Output::new("clip", "The motion with planted feet held still.");
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Per foot: plants and how far the toe slid while planted, before and after; per-frame IK residuals.",
);
const BLEND: FloatParam = FloatParam::new(
    "blend_secs",
    "Time over which a plant fades in after the foot lands and out before it lifts, so the foot never jumps.",
    0.05,
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
const ITERATIONS: IntParam = IntParam::new("max_iterations", "IK iterations allowed per frame.", 50, 1, 10_000);

/// `motion.foot_lock`.
pub struct FootLock;

static FOOT_LOCK: NodeSchema = NodeSchema {
    kind: "motion.foot_lock",
    category: "ik",
    doc: "Removes foot sliding: while a foot is in contact it stays where it was put down. The knee and hip turn (weighted IK), the foot keeps its angle, the body keeps its path.",
    inputs: &[CLIP.spec(), CONTACTS.spec()],
    outputs: &[LOCKED.spec(), REPORT.spec(), super::RESIDUAL_CURVES.spec()],
    params: &[BLEND.0, WEIGHTS.0, TOLERANCE.0, ITERATIONS.0, TOES.0],
    writes_files: false,
    version: 1,
};

impl Node for FootLock {
    fn schema(&self) -> &'static NodeSchema {
        &FOOT_LOCK
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let contacts = ctx.input(&CONTACTS)?;
        let params = FootLockParams {
            blend_secs: ctx.float(&BLEND)?,
            weights: parse_weights(ctx.text_param(&WEIGHTS)?).map_err(|e| NodeError::param("weights", e))?,
            solve: SolveParams {
                tolerance_m: ctx.float(&TOLERANCE)?,
                max_iterations: usize::try_from(ctx.int(&ITERATIONS)?).unwrap_or(1),
                ..SolveParams::default()
            },
            toes: parse_toes(ctx.text_param(&TOES)?).map_err(|e| NodeError::param("toes", e))?,
        };
        let locked = foot_lock(&clip, &contacts, &params).map_err(|e| match e {
            FootLockError::Rig(RigError::UnknownJoint(_)) => NodeError::param("weights", e.to_string()),
            FootLockError::UnknownToe(_) => NodeError::param("toes", e.to_string()),
            e => NodeError::input("contacts", e.to_string()),
        })?;
        let residuals: Vec<f64> = locked.frames.iter().map(|r| r.residual_m).collect();
        let unconverged = locked.frames.iter().filter(|r| !r.converged).count();
        if unconverged > 0 {
            ctx.warn(format!(
                "{unconverged} of {} frames could not hold the feet exactly (a plant out of the leg's reach)",
                residuals.len()
            ));
        }
        let feet: Vec<_> = locked
            .feet
            .iter()
            .map(|f| {
                json!({
                    "foot": f.foot,
                    "plants": f.plants,
                    "skate_before_m": f.skate_before_m,
                    "skate_after_m": f.skate_after_m,
                })
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

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::kernels::mannequin::mannequin_skeleton;
    use crate::model::{FootContacts, FrameRange, forward_kinematics};

    /// The mannequin gliding forward at `speed` m/s with its legs frozen: both feet slide.
    fn gliding(frames: usize, speed: f32) -> Clip {
        let skeleton = Arc::new(mannequin_skeleton().unwrap());
        let n = skeleton.len();
        let fps = 30.0;
        let mut rotations = vec![Quat::IDENTITY; frames * n];
        let mut translations = Vec::with_capacity(frames * n);
        let knee_bend = [("LeftLeg", 0.3f32), ("RightLeg", 0.2), ("LeftUpLeg", -0.25), ("RightUpLeg", -0.15)];
        for f in 0..frames {
            for (j, joint) in skeleton.joints().iter().enumerate() {
                let mut t = joint.rest_offset;
                if j == 0 {
                    t += Vec3::new(0.0, -0.05, speed * f as f32 / fps as f32);
                }
                translations.push(t);
                if let Some((_, a)) = knee_bend.iter().find(|(name, _)| *name == joint.name) {
                    rotations[f * n + j] = Quat::from_rotation_x(*a);
                }
            }
        }
        Clip::new(skeleton, fps, rotations, translations, crate::model::ImportScale::METRES).unwrap()
    }

    fn contacts_over(clip: &Clip, left: FrameRange, right: FrameRange) -> Contacts {
        let feet = [("LeftFoot", left), ("RightFoot", right)]
            .into_iter()
            .map(|(foot, r)| FootContacts { foot: foot.into(), intervals: vec![r] })
            .collect();
        Contacts { fps: clip.fps(), frame_count: clip.frame_count(), feet, double_support: Vec::new() }
    }

    #[test]
    fn a_gliding_foot_stays_on_its_plant_with_its_angle_and_the_body_keeps_its_path() {
        // 0.3 m/s for 20 frames at 30 fps: the frozen feet slide 0.19 m.
        let clip = gliding(20, 0.3);
        let contacts = contacts_over(&clip, FrameRange::new(0, 20), FrameRange::new(5, 15));
        let params = FootLockParams { blend_secs: 2.0 / 30.0, ..FootLockParams::default() };
        let locked = foot_lock(&clip, &contacts, &params).unwrap();
        let sk = clip.skeleton();
        let (before, after) = (forward_kinematics(&clip), forward_kinematics(&locked.clip));
        let toe = sk.index_of("LeftToe").unwrap();
        let ankle = sk.index_of("LeftFoot").unwrap();
        // The toes are level in every frame, so the lowest frame is the first: the plant is
        // the toe's place at frame 0. With a 2-frame blend, frames 1..=18 are fully planted.
        let place = before.position(0, toe);
        for f in 1..19 {
            let d = (after.position(f, toe) - place).with_y(0.0).length();
            assert!(d < 2e-4, "frame {f}: toe {d} m off its plant");
            // Heights are the clip's, the foot's world angle is the clip's.
            assert!((after.position(f, toe).y - before.position(f, toe).y).abs() < 2e-4);
            let (qa, qb) = (after.frame(f)[ankle].rotation, before.frame(f)[ankle].rotation);
            assert!(qa.angle_between(qb) < 1e-3, "frame {f}: foot turned {}", qa.angle_between(qb));
        }
        // Root and upper body untouched, bit for bit.
        let spine = sk.index_of("Spine").unwrap();
        for f in 0..20 {
            assert_eq!(locked.clip.frame_translations(f), clip.frame_translations(f));
            assert_eq!(locked.clip.frame_rotations(f)[spine], clip.frame_rotations(f)[spine]);
        }
        // The right foot moves only inside its contact: before it, nothing changes.
        let right_toe = sk.index_of("RightToe").unwrap();
        for f in 0..5 {
            assert!((after.position(f, right_toe) - before.position(f, right_toe)).length() < 1e-5);
        }
        let left = &locked.feet[0];
        // Independent figure: 17 planted steps of 0.01 m each (0.3 m/s at 30 fps).
        assert!((left.skate_before_m - 0.17).abs() < 1e-4, "{left:?}");
        assert!(left.skate_after_m < 1e-3, "{left:?}");
        assert!(locked.frames.iter().all(|r| r.converged));
    }

    #[test]
    fn a_plant_out_of_reach_is_met_as_closely_as_the_leg_allows() {
        // 3 m/s for 20 frames: the body leaves the planted foot 1.9 m behind.
        let clip = gliding(20, 3.0);
        let contacts = contacts_over(&clip, FrameRange::new(0, 20), FrameRange::new(0, 0));
        let locked = foot_lock(&clip, &contacts, &FootLockParams::default()).unwrap();
        assert!(locked.clip.rotations().iter().all(|q| q.is_finite()));
        assert!(locked.frames.iter().any(|r| !r.converged));
        assert!(locked.frames.iter().all(|r| r.residual_m.is_finite()));
        // The 0.84 m leg holds the foot while the body is within reach of the plant, then
        // drags it: still much less sliding than the 1.7 m before (measured: 0.97 m).
        assert!(locked.feet[0].skate_after_m < 0.7 * locked.feet[0].skate_before_m, "{:?}", locked.feet[0]);
    }

    #[test]
    fn contacts_of_another_clip_or_skeleton_are_refused() {
        let clip = gliding(10, 0.3);
        let mut contacts = contacts_over(&clip, FrameRange::new(0, 5), FrameRange::new(0, 5));
        contacts.frame_count = 11;
        assert!(matches!(
            foot_lock(&clip, &contacts, &FootLockParams::default()),
            Err(FootLockError::FrameCount { .. })
        ));
        contacts.frame_count = 10;
        contacts.feet[0].foot = "lFoot".into();
        assert_eq!(
            foot_lock(&clip, &contacts, &FootLockParams::default()).unwrap_err(),
            FootLockError::UnknownFoot("lFoot".into())
        );
        contacts.feet[0].foot = "Hips".into();
        assert_eq!(
            foot_lock(&clip, &contacts, &FootLockParams::default()).unwrap_err(),
            FootLockError::ShortLeg("Hips".into())
        );
    }
}
