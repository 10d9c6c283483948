//! Online motion retargeting by inverse rate control (Choi & Ko 2000).
//!
//! Per frame `n`, with the end-effector goals `x₁ᵈ(n)` (primary task) and the source's joint
//! angles `θ_src(n)` (secondary task):
//!
//! `Δθ = J⁺ K₁ (x₁ᵈ(n) − x₁(θ(n−1))) + (I − J⁺J) K₂ (θ_src(n) − θ(n−1))`
//!
//! 1. The closed-loop primary error is clamped to `max_task_step_m` per effector (update
//!    clamping: a goal that jumps does not throw the body).
//! 2. `J⁺` is the weighted damped pseudo-inverse of [`IkSolver`]; the damping grows where
//!    the dexterity `σ / σ_max` of a direction falls below `dexterity` (the gains are
//!    lowered in the near-singular directions only).
//! 3. The secondary task moves only in the primary task's null space, so the source's
//!    style is kept wherever the goals leave freedom.
//! 4. `Δθ` is clamped to `max_angle_step_rad` per DOF, then to the joint limits.
//! 5. While an effector is further than `tolerance_m` from its goal, up to
//!    `max_corrections` primary-only updates follow with the same `J⁺` (chord steps): the
//!    paper's single update linearises at the last frame's pose, so a foot swinging fast
//!    at 120 fps ends millimetres off, and a planted foot creeps.
//!
//! The goals `x₁ᵈ(n)` are the source's tips laid out for the character's size ([`GoalMap`]):
//! the paper's walk fed the source's toe paths unmodified, so a 60 % character took the
//! source's steps and its pelvis surged and stalled; scaled by the leg-length ratio, the
//! steps keep the source's length in leg lengths and the pelvis its speed in proportion.
//!
//! The kernel holds one pose and fixed buffers: it consumes a stream one frame at a time in
//! constant memory.

use std::sync::Arc;

use glam::{DVec3, Quat, Vec3};
use nalgebra::DVector;

use std::f64::consts::PI;

use crate::kernels::body::{find_landmarks, limb_tip};
use crate::kernels::ik::foot_lock::Plants;
use crate::kernels::ik::{DofKind, IkPose, IkRig, IkSolver, Weighting};
use crate::kernels::stride::rest_leg_length_m;
use crate::model::choice::choices;
use crate::model::fk::pose_world;
use crate::model::{Clip, Contacts, FootContacts, Skeleton, Transform};
use crate::node::into_report;
use crate::node::{ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Report};
use serde_json::json;

/// Gains and clamps of the online retargeting filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RetargetParams {
    /// Primary gain `K₁` (1 = the paper's `I`, best tracking).
    pub primary_gain: f64,
    /// Secondary gain `K₂` (1 = the paper's `I`).
    pub secondary_gain: f64,
    /// Directions whose singular value is below this fraction of the largest are damped.
    pub dexterity: f64,
    /// Damping at an exact singularity (metres per radian).
    pub max_damping_m: f64,
    /// Largest primary error fed back in one frame, per effector (metres).
    pub max_task_step_m: f64,
    /// Largest change of one DOF in one frame (radians, or metres for the root).
    pub max_angle_step_rad: f64,
    /// Primary-only corrections after the paper's update, at most, per frame (0 = the
    /// paper's single update alone, which linearises at the last frame's pose and leaves a
    /// second-order remainder: millimetres where a foot swings fast).
    pub max_corrections: usize,
    /// A frame whose effectors are all within this distance of their goals after an
    /// update takes no further correction (metres).
    pub tolerance_m: f64,
    /// Time over which a planted foot's goal blends in and out at contact edges (seconds).
    pub plant_blend_secs: f64,
    /// Updates run on the first frame before the stream starts, so it begins on its goals.
    pub settle_iterations: usize,
    /// Whether the pelvis's horizontal path is a primary task or only imitated.
    pub pelvis: PelvisTask,
    /// Whose size the effector goals are laid out for.
    pub goals: GoalFrame,
}

/// Whose size the goals (toe tips, hands, pelvis track) are laid out for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GoalFrame {
    /// The character's: the source's goals and root path mapped by [`GoalMap::character`]
    /// (horizontally scaled by the leg-length ratio about the start, heights by the ratio
    /// of root heights), so the character takes steps of its own size, in the source's
    /// number of leg lengths, and plants its feet where its own steps land.
    Character,
    /// The source's, unmodified (Choi & Ko's walking experiment): a smaller character takes
    /// the source's steps, big for its body, and its pelvis is dragged along by them.
    Source,
}

/// How the pelvis follows the source's pelvis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PelvisTask {
    /// In the null space of the tips, like the joint angles (its path mapped as the tips'
    /// are, [`GoalFrame`]): the tips win, and on a character of other proportions the
    /// pelvis speeds up and slows down within a stride where the source's does not.
    Imitate,
    /// Its horizontal position is an extra end-effector task beside the tips (Choi & Ko's
    /// pelvis task, which they found necessary; the default): on the source pelvis's
    /// ground track mapped as the tips' are; its height stays free for the legs.
    Track,
}

impl Default for RetargetParams {
    fn default() -> Self {
        RetargetParams {
            primary_gain: 1.0,
            secondary_gain: 1.0,
            dexterity: 0.02,
            max_damping_m: 0.02,
            max_task_step_m: 0.25,
            max_angle_step_rad: 0.2,
            max_corrections: 2,
            tolerance_m: 1e-4,
            settle_iterations: 100,
            pelvis: PelvisTask::Track,
            plant_blend_secs: 0.15,
            goals: GoalFrame::Character,
        }
    }
}

/// What one frame's update did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameReport {
    /// Largest effector error after the update (metres).
    pub error_m: f64,
    /// Dexterity `σ_min / σ_max` of the weighted Jacobian at the frame.
    pub dexterity: f64,
}

/// The streaming retargeting filter: feed it frames with [`OnlineRetargeter::step`].
#[derive(Clone, Debug)]
pub struct OnlineRetargeter {
    solver: IkSolver,
    params: RetargetParams,
    pose: IkPose,
    primary: DVector<f64>,
    secondary: DVector<f64>,
    projected: DVector<f64>,
    j_secondary: DVector<f64>,
    goals: Vec<DVec3>,
}

impl OnlineRetargeter {
    /// A filter over `rig` starting from `initial` (the target's first pose).
    pub fn new(rig: IkRig, initial: IkPose, params: RetargetParams) -> Self {
        let n = rig.dofs().len();
        let m = 3 * rig.effectors().len();
        OnlineRetargeter {
            goals: vec![DVec3::ZERO; rig.effectors().len()],
            solver: IkSolver::new(rig),
            params,
            pose: initial,
            primary: DVector::zeros(n),
            secondary: DVector::zeros(n),
            projected: DVector::zeros(n),
            j_secondary: DVector::zeros(m),
        }
    }

    /// The current (last output) pose.
    pub fn pose(&self) -> &IkPose {
        &self.pose
    }

    /// The rig.
    pub fn rig(&self) -> &IkRig {
        self.solver.rig()
    }

    /// Heap bytes held by the filter's buffers: constant over a stream.
    pub fn buffer_bytes(&self) -> usize {
        let f = std::mem::size_of::<f64>();
        (self.primary.len() + self.secondary.len() + self.projected.len() + self.j_secondary.len()) * f
            + self.goals.capacity() * std::mem::size_of::<DVec3>()
            + self.pose.rotations.capacity() * std::mem::size_of::<glam::DQuat>()
            + self.pose.translations.capacity() * std::mem::size_of::<DVec3>()
            + self.pose.euler.capacity() * 3 * f
    }

    /// One frame: `source` is the source pose on the target rig (its DOF values are the
    /// secondary task, its non-rig joints are copied), `goals` the effector positions.
    pub fn step(&mut self, source: &IkPose, goals: &[DVec3]) -> FrameReport {
        let p = self.params;
        // Joints outside the rig follow the source directly.
        self.pose.rotations.clone_from_slice(&source.rotations);
        for (g, goal) in self.goals.iter_mut().zip(goals) {
            *g = *goal;
        }
        // The paper's update: linearised at the last frame's pose.
        self.solver.linearise(&self.pose, &self.goals);
        self.clamp_task_error();
        let dexterity = self.solver.decompose(p.dexterity, p.max_damping_m, true, Weighting::InsideInverse);
        self.solver.apply_pinv_to_task(&mut self.primary);
        // Secondary task projected on the null space: z − J⁺ (J z).
        for d in 0..self.solver.rig().dofs().len() {
            let rig = self.solver.rig();
            let diff = rig.dof_value(source, d) - rig.dof_value(&self.pose, d);
            // Angles the shorter way round (Euler angles wrap at ±π).
            let diff = match rig.dofs()[d].kind {
                DofKind::Rotation { .. } => (diff + PI).rem_euclid(2.0 * PI) - PI,
                DofKind::Translation { .. } => diff,
            };
            self.secondary[d] = p.secondary_gain * diff;
        }
        self.j_secondary.gemv_tr(1.0, self.solver.jacobian_transposed(), &self.secondary, 0.0);
        self.solver.apply_pinv(&self.j_secondary, &mut self.projected);
        self.primary += &self.secondary;
        self.primary -= &self.projected;
        self.apply_primary();
        // Corrections on the error left, with the same J⁺ (a chord step: the Jacobian moves
        // little within one frame's update, and its decomposition is most of the cost).
        let mut error_m = self.solver.task_offsets(&self.pose, &self.goals);
        for _ in 0..p.max_corrections {
            if error_m <= p.tolerance_m {
                break;
            }
            self.clamp_task_error();
            self.solver.apply_pinv_to_task(&mut self.primary);
            self.apply_primary();
            error_m = self.solver.task_offsets(&self.pose, &self.goals);
        }
        FrameReport { error_m, dexterity }
    }

    /// Update clamping and `K₁` on the solver's task error.
    fn clamp_task_error(&mut self) {
        let p = self.params;
        for e in 0..self.goals.len() {
            let mut d = DVec3::new(self.solver.dx[3 * e], self.solver.dx[3 * e + 1], self.solver.dx[3 * e + 2]);
            let len = d.length();
            if len > p.max_task_step_m {
                d *= p.max_task_step_m / len;
            }
            for k in 0..3 {
                self.solver.dx[3 * e + k] = p.primary_gain * d[k];
            }
        }
    }

    /// Adds `primary` to the pose's DOFs, each clamped to `max_angle_step_rad`.
    fn apply_primary(&mut self) {
        let step = self.params.max_angle_step_rad;
        for d in 0..self.solver.rig().dofs().len() {
            let delta = self.primary[d].clamp(-step, step);
            let value = self.solver.rig().dof_value(&self.pose, d) + delta;
            self.solver.rig().set_dof(&mut self.pose, d, value);
        }
    }
}

/// Where a point of the source is wanted on the target (metres to metres): on the ground
/// plane `to + horizontal · (p − from)`, a similarity that maps the source's start onto
/// the target's and keeps the shape of every path; in height `vertical · y`, scaled about
/// the floor (height 0) so planted feet stay on it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GoalMap {
    /// The source's ground-plane point that maps onto `to` (its height is ignored).
    pub from: DVec3,
    /// Where `from` lands on the target's ground plane (its height is ignored).
    pub to: DVec3,
    /// Scale of ground-plane offsets from `from`.
    pub horizontal: f64,
    /// Scale of heights.
    pub vertical: f64,
}

impl GoalMap {
    /// Every point where it is.
    pub const IDENTITY: GoalMap = GoalMap::scale(1.0);

    /// Scaling about the world origin by `factor` on every axis.
    pub const fn scale(factor: f64) -> Self {
        GoalMap { from: DVec3::ZERO, to: DVec3::ZERO, horizontal: factor, vertical: factor }
    }

    /// Goals laid out for the target's size: ground-plane offsets from the source root's
    /// first-frame place scaled by the ratio of rest-pose leg lengths, hip to knee to ankle
    /// (the measure step lengths are compared in, [`rest_leg_length_m`]; the ratio of root
    /// heights when a skeleton's legs cannot be read), starting from the target root's
    /// first-frame place; heights by the ratio of root heights (hip over the lowest joint,
    /// as the root path of `skeleton.scale`'s copy).
    pub fn character(source: &Clip, target: &Clip) -> Self {
        let vertical = f64::from(source.skeleton().root_height_ratio(target.skeleton()).unwrap_or(1.0));
        let legs = rest_leg_length_m(source.skeleton()).and_then(|s| Ok((s, rest_leg_length_m(target.skeleton())?)));
        let horizontal = match legs {
            Ok((s, t)) if s > 1e-6 && t > 1e-6 => t / s,
            _ => vertical,
        };
        let root = |c: &Clip| c.frame_translations(0).first().map_or(DVec3::ZERO, |t| t.as_dvec3());
        GoalMap { from: root(source), to: root(target), horizontal, vertical }
    }

    /// Where source point `p` is wanted on the target.
    pub fn apply(&self, p: DVec3) -> DVec3 {
        let ground = self.to + self.horizontal * (p - self.from);
        DVec3::new(ground.x, self.vertical * p.y, ground.z)
    }
}

/// Which effectors a clip retarget tracks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effectors {
    /// Both toe tips (Choi & Ko's walking experiment).
    Feet,
    /// Both toe tips and both hands.
    FeetAndHands,
}

/// A clip retargeted onto another skeleton, with one report per frame.
#[derive(Clone, Debug)]
pub struct Retargeted {
    /// The target clip.
    pub clip: Clip,
    /// Per-frame error and dexterity.
    pub frames: Vec<FrameReport>,
    /// The effector joints of the target, in task order.
    pub effectors: Vec<usize>,
    /// How the source's tips were mapped to their goals.
    pub goal_map: GoalMap,
}

/// Why a clip cannot be retargeted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RetargetError {
    /// The target skeleton lacks a joint of the source.
    #[error("the target skeleton has no joint `{0}` (the source and target must share joint names)")]
    MissingJoint(String),
    /// Feet or hands not found by name.
    #[error("could not find the limbs by joint name (missing: {0})")]
    Landmarks(String),
    /// Building the rig failed.
    #[error(transparent)]
    Rig(#[from] crate::kernels::ik::RigError),
    /// Building the clip failed.
    #[error(transparent)]
    Clip(#[from] crate::model::ClipError),
}

/// The retargeting rig over a target skeleton: the root translates, every joint between the
/// root and the chosen tips turns about three axes, the tips are the effectors.
pub fn retarget_rig(
    skeleton: &Arc<Skeleton>,
    effectors: Effectors,
    pelvis: PelvisTask,
) -> Result<IkRig, RetargetError> {
    let landmarks = find_landmarks(skeleton).map_err(|m| RetargetError::Landmarks(m.join(", ")))?;
    let mut tips: Vec<usize> = landmarks.feet().iter().map(|&f| limb_tip(skeleton, f)).collect();
    if effectors == Effectors::FeetAndHands {
        tips.extend(landmarks.limbs.iter().map(|side| limb_tip(skeleton, side[5])));
    }
    let mut rig = IkRig::new(skeleton.clone());
    rig.add_root_translation(1.0);
    let root = skeleton.joints()[0].name.clone();
    for &tip in &tips {
        // The root's orientation follows the source (heading is free in a walk, and an
        // Euler root would meet gimbal lock at ±90° of heading); the joints below it turn.
        let path = rig.chain_joints(&root, &skeleton.joints()[tip].name)?;
        for &j in path.iter().take(path.len() - 1).skip(1) {
            rig.add_joint(j, [true; 3], 1.0);
        }
        rig.add_effector(tip);
    }
    if pelvis == PelvisTask::Track {
        // The root's ground-plane position (its goal, as the tips', is the source's).
        rig.add_effector_on_axes(0, [true, false, true]);
    }
    Ok(rig.finish()?)
}

/// Retargets `source` onto the skeleton of `target` (a clip whose joints have the source's
/// names, e.g. from `skeleton.scale`; its first frame is the start pose, settled on the
/// first goals). The effectors follow the source's tips mapped by `params.goals`
/// ([`GoalFrame`]); while a foot is in contact (`contacts`, from the source) its goal is
/// held at one horizontal place (see [`Plants`]; the source's place, mapped), so the stance
/// foot is the fixed base the body moves about, and base and swing foot switch at contact
/// boundaries. The root's secondary task (and the pelvis track's goal) is the source root
/// path mapped the same way: with [`GoalFrame::Source`], scaled by the ratio of root
/// heights about the origin.
pub fn retarget_clip(
    source: &Clip,
    target: &Clip,
    contacts: Option<&Contacts>,
    effectors: Effectors,
    params: RetargetParams,
) -> Result<Retargeted, RetargetError> {
    let blend_frames = (params.plant_blend_secs * source.fps()).round().max(1.0) as usize;
    let skeleton = target.skeleton();
    let map: Vec<usize> = skeleton
        .joints()
        .iter()
        .map(|j| source.skeleton().index_of(&j.name).ok_or_else(|| RetargetError::MissingJoint(j.name.clone())))
        .collect::<Result<_, _>>()?;
    let rig = retarget_rig(skeleton, effectors, params.pelvis)?;
    let tips: Vec<usize> = rig.effectors().iter().map(|&e| map[e]).collect();
    let effector_joints = rig.effectors().to_vec();
    let (tip_map, root_map) = match params.goals {
        GoalFrame::Character => {
            let map = GoalMap::character(source, target);
            (map, map)
        }
        GoalFrame::Source => {
            (GoalMap::IDENTITY, GoalMap::scale(f64::from(source.skeleton().root_height_ratio(skeleton).unwrap_or(1.0))))
        }
    };
    let rest: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
    let frames = source.frame_count();
    // Per-frame scratch, allocated once.
    let mut rotations = vec![Quat::IDENTITY; skeleton.len()];
    let mut translations = rest.clone();
    let mut source_world = vec![Transform::IDENTITY; source.joint_count()];
    let mut goals = vec![DVec3::ZERO; tips.len()];
    let initial = rig.pose_from(target.frame_rotations(0), target.frame_translations(0));
    let mut source_pose = initial.clone();
    let mut filter = OnlineRetargeter::new(rig, initial, params);
    let mut out_rot = Vec::with_capacity(frames * skeleton.len());
    let mut out_tr = Vec::with_capacity(frames * skeleton.len());
    let mut reports = Vec::with_capacity(frames);
    // Each toe tip (the first two effectors) takes the contacts of the foot it lies under,
    // matched by the foot's joint name, whatever order the contacts list the feet in.
    let plants: Vec<Plants> = match contacts {
        Some(c) => tips
            .iter()
            .take(2)
            .map(|&tip| {
                let under = |f: &&FootContacts| {
                    source
                        .skeleton()
                        .index_of(&f.foot)
                        .is_some_and(|a| a == tip || source.skeleton().is_ancestor(a, tip))
                };
                let intervals = c.feet.iter().find(under).map_or(&[][..], |f| f.intervals.as_slice());
                Plants::new(source, tip, intervals, blend_frames)
            })
            .collect(),
        None => Vec::new(),
    };
    for f in 0..frames {
        pose_world(source.skeleton(), source.frame_rotations(f), source.frame_translations(f), &mut source_world);
        for (t, &s) in map.iter().enumerate() {
            rotations[t] = source.frame_rotations(f)[s];
        }
        translations[0] = root_map.apply(source.frame_translations(f)[map[0]].as_dvec3()).as_vec3();
        filter.rig().fill_pose(&rotations, &translations, &mut source_pose);
        for (k, &tip) in tips.iter().enumerate() {
            let here = source_world[tip].translation.as_dvec3();
            goals[k] = if effector_joints[k] == 0 {
                root_map.apply(here)
            } else {
                // Planted: the toe is drawn to its planted place, its height follows the
                // source's; then the whole goal is laid out for the character.
                tip_map.apply(here + plants.get(k).map_or(DVec3::ZERO, |p| p.shift(f, here)))
            };
        }

        if f == 0 {
            // Start on the first frame's goals: the stream's first pose is solved fully.
            for _ in 0..params.settle_iterations {
                filter.step(&source_pose, &goals);
            }
        }
        reports.push(filter.step(&source_pose, &goals));
        let pose = filter.pose();
        let start = out_rot.len();
        out_rot.resize(start + skeleton.len(), Quat::IDENTITY);
        filter.rig().rotations_of(pose, &mut out_rot[start..]);
        out_tr.extend(rest.iter().enumerate().map(|(j, r)| if j == 0 { pose.translations[0].as_vec3() } else { *r }));
    }
    let clip = Clip::new(skeleton.clone(), source.fps(), out_rot, out_tr, target.import_scale)?;
    Ok(Retargeted { clip, frames: reports, effectors: effector_joints, goal_map: tip_map })
}

const SOURCE: Input<Arc<Clip>> = Input::required("source", "The captured motion to carry over.");
const TARGET: Input<Arc<Clip>> = Input::required(
    "target",
    "A clip on the character to animate (joint names as in the source, e.g. from skeleton.scale); its first frame is the start pose.",
);
const CONTACTS: Input<Arc<Contacts>> = Input::optional(
    "contacts",
    "Foot contacts of the source (motion.contacts): planted feet stay put and serve as the base the body moves about.",
);
const RETARGETED: Output<Arc<Clip>> = Output::new("clip", "The motion on the target character.");
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Effector tracking error per frame (m), the smallest dexterity met, and the scales the goals were laid out with (ground plane, height).",
);
choices!(Effectors { Feet = "feet", FeetAndHands = "feet_and_hands" });
const TRACK: ChoiceParam<Effectors> = ChoiceParam::new(
    "effectors",
    "Which tips follow the source's paths as tasks: the toe tips, or the toe tips and the hands.",
    "feet",
);
const GAIN: FloatParam = FloatParam::new(
    "imitation_gain",
    "How strongly the joints are pulled toward the source's angles where the tips leave freedom (K₂; 1 = fully each frame).",
    1.0,
    0.0,
    1.0,
    "",
);
const DEXTERITY: FloatParam = FloatParam::new(
    "dexterity",
    "Near-straight limbs are eased (damped) when a direction's dexterity σ/σ_max falls below this.",
    0.02,
    0.0,
    1.0,
    "",
);
choices!(PelvisTask { Imitate = "imitate", Track = "track" });
const PELVIS: ChoiceParam<PelvisTask> = ChoiceParam::new(
    "pelvis",
    "How the pelvis follows the source's: kept on the source pelvis's ground track (laid out as the tips' goals are) as a task of its own beside the tips, its height free; or only imitated where the tips leave freedom (it then surges and stalls within a stride on a character of other proportions).",
    "track",
);
choices!(GoalFrame { Character = "character", Source = "source" });
const GOALS: ChoiceParam<GoalFrame> = ChoiceParam::new(
    "goals",
    "Whose size the tips' goals and the pelvis path are laid out for: the character's (the source's paths scaled by the leg-length ratio from the start, so it takes steps of its own size and plants its feet where its own steps land), or the source's unmodified (Choi & Ko's walking experiment: a smaller character takes the source's steps).",
    "character",
);
const MAX_ANGLE_STEP: FloatParam = FloatParam::new(
    "max_angle_step_rad",
    "Largest change of one joint angle in one frame (update clamp).",
    0.2,
    0.001,
    3.2,
    "rad",
);

const CORRECTIONS: IntParam = IntParam::new(
    "corrections",
    "Extra tip corrections per frame, at most, while a tip is further than tolerance_m from its goal (0 = the paper's single update, which leaves millimetres where a foot moves fast and lets a planted foot creep).",
    2,
    0,
    20,
);
const TOLERANCE: FloatParam = FloatParam::new(
    "tolerance_m",
    "A frame whose tips are all this close to their goals takes no further correction.",
    1e-4,
    1e-7,
    1.0,
    "m",
);

/// `retarget.online`.
pub struct RetargetOnline;

static RETARGET_ONLINE: NodeSchema = NodeSchema {
    kind: "retarget.online",
    category: "retarget",
    doc: "Carries a captured motion onto a character of other proportions frame by frame (Choi & Ko's online retargeting): the toe tips follow the source's paths scaled to the character (steps of its own size), the joints imitate its angles, planted feet do not slide.",
    inputs: &[SOURCE.spec(), TARGET.spec(), CONTACTS.spec()],
    outputs: &[RETARGETED.spec(), REPORT.spec(), super::RESIDUAL_CURVES.spec()],
    params: &[TRACK.0, GOALS.0, PELVIS.0, GAIN.0, DEXTERITY.0, MAX_ANGLE_STEP.0, CORRECTIONS.0, TOLERANCE.0],
    writes_files: false,
    version: 4,
};

impl Node for RetargetOnline {
    fn schema(&self) -> &'static NodeSchema {
        &RETARGET_ONLINE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let source = ctx.input(&SOURCE)?;
        let target = ctx.input(&TARGET)?;
        let contacts = ctx.optional_input(&CONTACTS)?;
        if let Some(c) = &contacts
            && c.frame_count != source.frame_count()
        {
            return Err(NodeError::input("contacts", "the contacts were found on another clip (frame counts differ)"));
        }
        let effectors = ctx.choice(&TRACK)?;
        let params = RetargetParams {
            secondary_gain: ctx.float(&GAIN)?,
            dexterity: ctx.float(&DEXTERITY)?,
            max_angle_step_rad: ctx.float(&MAX_ANGLE_STEP)?,
            max_corrections: ctx.int(&CORRECTIONS)? as usize,
            tolerance_m: ctx.float(&TOLERANCE)?,
            pelvis: ctx.choice(&PELVIS)?,
            goals: ctx.choice(&GOALS)?,
            ..RetargetParams::default()
        };
        let out = retarget_clip(&source, &target, contacts.as_deref(), effectors, params).map_err(|e| match e {
            RetargetError::MissingJoint(_) | RetargetError::Landmarks(_) => NodeError::input("target", e.to_string()),
            _ => NodeError::input("source", e.to_string()),
        })?;
        let errors: Vec<f64> = out.frames.iter().map(|r| r.error_m).collect();
        let max = errors.iter().copied().fold(0.0, f64::max);
        let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
        let dexterity = out.frames.iter().map(|r| r.dexterity).fold(f64::INFINITY, f64::min);
        ctx.set_output(
            &super::RESIDUAL_CURVES,
            super::residual_curves(
                source.fps(),
                vec![
                    ("residual", "m", errors.clone()),
                    ("dexterity", "", out.frames.iter().map(|r| r.dexterity).collect()),
                ],
            )?,
        );
        ctx.set_output(
            &REPORT,
            Arc::new(into_report(json!({
                "max_error_m": max,
                "mean_error_m": mean,
                "min_dexterity": if dexterity.is_finite() { dexterity } else { 0.0 },
                "goal_scale_horizontal": out.goal_map.horizontal,
                "goal_scale_vertical": out.goal_map.vertical,
                "error_m_per_frame": errors,
            }))),
        );
        ctx.set_output(&RETARGETED, Arc::new(out.clip));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Joint;

    /// A hip, a leg and a toe: hips at 0.9 m, thigh 0.45 m, shank 0.4 m.
    fn leg() -> Arc<Skeleton> {
        Arc::new(
            Skeleton::new(vec![
                Joint::new("Hips", None, Vec3::new(0.0, 0.9, 0.0)),
                Joint::new("LeftUpLeg", Some(0), Vec3::new(0.1, 0.0, 0.0)),
                Joint::new("LeftLeg", Some(1), Vec3::new(0.0, -0.45, 0.0)),
                Joint::new("LeftFoot", Some(2), Vec3::new(0.0, -0.4, 0.0)),
                Joint::new("LeftToe", Some(3), Vec3::new(0.0, -0.05, 0.12)),
            ])
            .unwrap(),
        )
    }

    /// Choi & Ko's secondary task moves the joints only in the null space of the primary
    /// one: with the tip on its goal, one update is `(I − J⁺J) K₂ (θ_src − θ)`. Checked
    /// against that formula evaluated another way: `J` by central differences of forward
    /// kinematics, `J⁺` by nalgebra's SVD pseudo-inverse (a bent leg, no damping, unit
    /// weights). The tip does not move to first order.
    #[test]
    fn the_imitation_moves_only_in_the_null_space_of_the_tips() {
        let skeleton = leg();
        let mut rig = IkRig::new(skeleton.clone());
        for j in 1..4 {
            rig.add_joint(j, [true; 3], 1.0);
        }
        rig.add_effector(4);
        let rig = rig.finish().unwrap();
        let rest: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
        let bent =
            [Quat::IDENTITY, Quat::from_rotation_x(-0.4), Quat::from_rotation_x(0.7), Quat::IDENTITY, Quat::IDENTITY];
        let initial = rig.pose_from(&bent, &rest);
        let n = rig.dofs().len();
        let mut fk = IkSolver::new(rig.clone());
        let mut tip = [DVec3::ZERO];
        fk.effector_positions(&initial, &mut tip);
        let goal = tip[0];
        // The source's angles a little away from the initial pose, every DOF.
        let mut source = initial.clone();
        let z: Vec<f64> = (0..n).map(|d| 0.01 * ((d as f64 * 1.7).sin() + 0.3)).collect();
        for (d, dz) in z.iter().enumerate() {
            rig.set_dof(&mut source, d, rig.dof_value(&initial, d) + dz);
        }
        let params = RetargetParams { max_corrections: 0, dexterity: 0.0, ..RetargetParams::default() };
        let mut filter = OnlineRetargeter::new(rig.clone(), initial.clone(), params);
        filter.step(&source, &[goal]);
        let moved: Vec<f64> = (0..n).map(|d| rig.dof_value(filter.pose(), d) - rig.dof_value(&initial, d)).collect();
        // J by central differences.
        let h = 1e-6;
        let mut j = nalgebra::DMatrix::<f64>::zeros(3, n);
        for d in 0..n {
            let mut at = |sign: f64| {
                let mut p = initial.clone();
                rig.set_dof(&mut p, d, rig.dof_value(&initial, d) + sign * h);
                fk.effector_positions(&p, &mut tip);
                tip[0]
            };
            let column = (at(1.0) - at(-1.0)) / (2.0 * h);
            for k in 0..3 {
                j[(k, d)] = column[k];
            }
        }
        let pinv = j.clone().pseudo_inverse(1e-12).unwrap();
        let projector = nalgebra::DMatrix::<f64>::identity(n, n) - &pinv * &j;
        let expected = projector * nalgebra::DVector::from_vec(z.clone());
        for d in 0..n {
            assert!(
                (moved[d] - expected[d]).abs() < 1e-6,
                "DOF {d}: moved {} expected {} ({moved:?})",
                moved[d],
                expected[d]
            );
        }
        // Something moved, and the tip stayed (second order in the step).
        let step = moved.iter().map(|v| v * v).sum::<f64>().sqrt();
        fk.effector_positions(filter.pose(), &mut tip);
        println!("null-space step {step:.4} rad, tip moved {:.2e} m", tip[0].distance(goal));
        assert!(step > 0.01, "{moved:?}");
        // Second order: at most ½ · reach · step², the leg reaching less than 1 m.
        assert!(tip[0].distance(goal) < 0.5 * step * step, "{}", tip[0].distance(goal));
    }

    /// A long synthetic stream (a leg swinging for 100 000 frames): the filter's buffers do
    /// not grow, and it keeps tracking.
    #[test]
    fn a_long_stream_runs_in_constant_memory() {
        let skeleton = leg();
        let mut rig = IkRig::new(skeleton.clone());
        rig.add_root_translation(1.0);
        for j in 1..4 {
            rig.add_joint(j, [true; 3], 1.0);
        }
        rig.add_effector(4);
        let rig = rig.finish().unwrap();
        let rest: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
        let rotations = vec![Quat::IDENTITY; 5];
        let initial = rig.pose_from(&rotations, &rest);
        let mut source = initial.clone();
        let mut filter = OnlineRetargeter::new(rig, initial, RetargetParams::default());
        let bytes = filter.buffer_bytes();
        let mut worst = 0.0f64;
        for f in 0..100_000 {
            let t = f as f64 / 120.0;
            let goal = DVec3::new(0.1, 0.05 + 0.05 * (3.0 * t).sin().max(0.0), 0.12 + 0.2 * (3.0 * t).sin());
            source.euler[0][0] = 0.3 * (3.0 * t).sin();
            let report = filter.step(&source, &[goal]);
            if f > 10 {
                worst = worst.max(report.error_m);
            }
            assert_eq!(filter.buffer_bytes(), bytes, "frame {f}");
        }
        assert!(worst < 0.005, "worst tracking error {worst} m");
        assert!(filter.pose().euler.iter().flatten().all(|v| v.is_finite()));
    }
}
