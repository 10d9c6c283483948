//! Foot locking: feet that should be planted stay where they were put down, by the
//! weighted IK of [`super::solve`].
//!
//! Per foot and contact (from `motion.contacts`):
//! 1. The planted place is where the toe tip is at the contact's lowest frame ([`Plants`]).
//! 2. Each frame of the contact, the foot's drift is the toe tip's horizontal distance from
//!    that place; its correction `c = place − toe` (horizontal only, so heel strike and
//!    toe-off keep their heights). Outside the contact, the correction of its first (last)
//!    frame fades in before it (out after it) over `blend_secs` ([`Plants::shift`]).
//! 3. The ankle's goal is the clip's ankle plus `c`; the two joints above it (knee and hip)
//!    turn to reach it (one rig with both ankles as effectors; unplanted ankles keep their
//!    own position as goal, so that leg does not move).
//!    A goal near the edge of the leg's reach is eased towards full stretch ([`super::reach`],
//!    over the last `soft_reach` of the leg's length) by raising it, so a plant coming into or
//!    going out of reach (a heel strike the correction stretches) bends the knee smoothly
//!    instead of snapping it, and the foot lands a little high rather than sliding; the
//!    shortfall is reported.
//! 4. The ankle's local rotation is then reset so the foot keeps its world orientation from
//!    the clip: the whole foot, toes included, moves by exactly `c`.
//!
//! Hands in the contacts (`motion.contacts`' `hands`) are held the same way, the elbow and
//! shoulder turning for the knee and hip, the fingertip for the toe.
//!
//! A foot that does not hang below its knee (an IK-style game rig hangs the feet off the
//! root) has its hip and knee read from the body's roles; the effector is then the end of
//! the shin, the point where the clip puts the foot in the knee's frame, and after the solve
//! the foot is moved there (keeping its world orientation), so it follows the leg as a
//! foot below the knee would.
//!
//! The root and every joint outside the legs are left untouched (but for the root's height
//! on soles, below), so the body's path is the clip's; a plant out of the leg's reach is met as
//! closely as the leg allows (eased short with a soft reach, counted in the report).
//!
//! Ground ([`Ground`]): by default heights are the clip's. On the soles of a skinned mesh
//! ([`Ground::Soles`]) each foot also moves up or down by `d(f)` so that each plant stands
//! on the floor: through a contact `d = floor − min sole(f)`, the lowest its skinned sole
//! ([`crate::kernels::soles`]) gets in that contact, so the sole reaches the floor and never
//! goes under it while the clip's own heel strike, roll and toe-off are kept (pinning every
//! frame would drag a lifting foot back down: detected contacts run on into toe-off, where
//! the sole is up to 11 cm above the floor on a CMU walk carried onto Xbot, out of the
//! leg's reach). Between two contacts `d` eases from one plant's value to the next's (a
//! smoothstep); before the first and after the last it holds theirs, so a swinging foot
//! keeps the offset of the plants around it instead of dropping into place at touch-down.
//! [`Ground::AboveFloor`] does the same from the feet's joints, lifting only: a plant's
//! `d = max(0, floor − min lowest joint)`.
//! The ankle's goal becomes the clip's ankle plus `c + d·ŷ`; with the foot's world
//! orientation kept, the sole moves by the same vector. The root moves up or down by the
//! lower of the two feet's `d` in each frame (the part both share: a rig whose ankles sit
//! higher over its skin), so the legs only bend to take up the rest and never have to
//! stretch past their length. A rig whose ankles sit higher or
//! lower over its skin than the captured actor's no longer floats or sinks.

use std::sync::Arc;

use glam::{DVec3, Quat, Vec3};

use super::reach::soft_goal;
use super::rig::{IkRig, RigError};
use super::solve::{IkSolver, SolveParams, SolveReport};
use crate::kernels::body::limb_tip;
use crate::kernels::contacts::{ContactThresholds, contacts_of};
use crate::kernels::roles::{RolesError, roles_of};
use crate::kernels::skinning::SkinError;
use crate::kernels::soles::{foot_joints, lowest_sole_heights};
use crate::math::smoothstep;
use crate::model::fk::{pose_world, rest_world};
use crate::model::intervals::union_all;
use crate::model::{
    Clip, ClipError, ClipPoses, Contacts, FootContacts, FrameRange, Mesh, Skeleton, Transform, forward_kinematics,
};

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
    /// the joint farthest below each ankle. Hands in the contacts are held at their tips.
    pub toes: Option<[String; 2]>,
    /// Where planted feet stand vertically.
    pub ground: Ground,
    /// The last part of each leg's reach, as a fraction of its length (hip to knee to
    /// ankle), over which an ankle goal is eased towards full stretch ([`super::reach`]).
    /// 0: a hard reach, the knee snaps straight.
    pub soft_reach: f64,
}

/// The default [`FootLockParams::soft_reach`]: 5 % of the leg. At 2 % CesiumMan's straight
/// knee at a run's toe-off jumped (449 m/s² where the clip has 213); 3 % fixed that toe-off
/// but not the next one once CMU 09_01's T-pose frame was dropped (389 m/s², f70); at 5 % the
/// run's peak is 0.18 of the source's, and the walks and Xbot's run move by < 1 %.
pub const DEFAULT_SOFT_REACH: f64 = 0.05;

impl Default for FootLockParams {
    fn default() -> Self {
        FootLockParams {
            blend_secs: 0.15,
            weights: Vec::new(),
            solve: SolveParams::default(),
            toes: None,
            ground: Ground::Clip,
            soft_reach: DEFAULT_SOFT_REACH,
        }
    }
}

/// Where planted feet stand vertically (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub enum Ground {
    /// At the clip's heights: only horizontal drift is removed.
    Clip,
    /// At the clip's heights, but a plant whose lowest joint (ankle or below) goes under
    /// the floor is lifted by that much: what a blend of two clips' legs needs, where
    /// interpolated joint angles can shorten a standing leg. Floating plants stay.
    AboveFloor {
        /// The floor's height in the clip's metres.
        floor_height_m: f64,
    },
    /// With the lowest vertex of each foot's skinned sole on the floor through every contact.
    Soles {
        /// A mesh skinned to the clip's skeleton.
        mesh: Arc<Mesh>,
        /// The floor's height in the clip's metres.
        floor_height_m: f64,
    },
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
    /// On soles ([`Ground::Soles`]): the least and greatest vertical move given to the foot
    /// (metres), how far its sole sat above (negative) or below (positive) the floor.
    pub lift_range_m: Option<(f64, f64)>,
    /// Frames whose ankle goal was eased short of where the plant wanted it (the leg near
    /// full stretch), by more than the solve's tolerance.
    pub short_frames: usize,
    /// The most a goal was eased short (metres).
    pub shortfall_max_m: f64,
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

/// Why detected plants could not be held ([`hold_detected_plants`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HoldError {
    /// The feet could not be found to detect the plants.
    #[error(transparent)]
    Feet(#[from] RolesError),
    /// The plants could not be held.
    #[error(transparent)]
    Lock(#[from] FootLockError),
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
    /// A foot that does not hang below its knee, on a body whose legs cannot be read.
    #[error(
        "foot `{foot}` does not hang below its knee (an IK-style rig), and its leg cannot be read from the body: {why}"
    )]
    DetachedFoot {
        /// The foot joint.
        foot: String,
        /// Why the leg was not found.
        why: String,
    },
    /// A toe named by the toes param is not in the skeleton.
    #[error("the clip's skeleton has no toe joint named '{0}'")]
    UnknownToe(String),
    /// The rig could not be built.
    #[error(transparent)]
    Rig(#[from] RigError),
    /// The clip could not be built.
    #[error(transparent)]
    Clip(#[from] ClipError),
    /// The ground mesh cannot be skinned by the clip.
    #[error("the soles cannot be measured: {0}")]
    Soles(#[from] SkinError),
    /// No vertex of the ground mesh is bound to a foot.
    #[error("no vertex of the mesh is bound mostly to foot `{0}` or the joints below it, so it has no sole")]
    NoSole(String),
}

/// Per frame, the vertical move `d(f)` that stands each plant's sole on the floor (see the
/// module doc), from the sole's lowest height per frame and the foot's contacts.
/// With `lift_only` a plant is only ever moved up (never down onto the floor).
fn ground_offsets(sole_m: &[f64], floor_m: f64, intervals: &[FrameRange], lift_only: bool) -> Vec<f64> {
    let n = sole_m.len();
    let mut plants: Vec<(FrameRange, f64)> = intervals
        .iter()
        .filter(|r| r.end > r.start && r.end <= n)
        .map(|r| {
            let d = floor_m - sole_m[r.start..r.end].iter().copied().fold(f64::INFINITY, f64::min);
            (*r, if lift_only { d.max(0.0) } else { d })
        })
        .collect();
    plants.sort_by_key(|p| p.0.start);
    let (Some(&(first, d_first)), Some(&(last, d_last))) = (plants.first(), plants.last()) else {
        return vec![0.0; n];
    };
    let mut d = vec![0.0; n];
    d[..first.start].fill(d_first);
    d[last.end..].fill(d_last);
    for (r, v) in &plants {
        d[r.start..r.end].fill(*v);
    }
    for pair in plants.windows(2) {
        let ((from, a), (to, b)) = ((pair[0].0.end - 1, pair[0].1), (pair[1].0.start, pair[1].1));
        for (f, v) in d.iter_mut().enumerate().take(to).skip(from + 1) {
            *v = a + (b - a) * smoothstep((f - from) as f64 / (to - from) as f64);
        }
    }
    d
}

/// Where a leg of length `leg` (metres) starts easing its goal ([`super::reach`]): over its
/// last `soft_reach` fraction, or from the clip's own hip-to-ankle distance `clip_reach` if
/// the clip stretches the leg further, so that only the extension the lock adds is eased and
/// the clip's own straight leg at a heel strike is kept; the zone never narrows below a
/// quarter of the fraction, which bounds the knee's speed.
fn eased_from(leg: f64, soft_reach: f64, clip_reach: f32) -> f64 {
    let softness = soft_reach * leg;
    if softness <= 0.0 {
        return leg;
    }
    (leg - softness).max(f64::from(clip_reach)).min(leg - softness / 4.0)
}

/// The two joints a foot lock turns to move a foot, and how the foot hangs from them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Leg {
    hip: usize,
    knee: usize,
    /// The foot does not hang below its knee (an IK-style game rig parents the feet to the
    /// root): the knee carries the end of the shin, and the foot is placed there.
    detached: bool,
}

/// The limb above each of `ankles` (feet, then any hands): the hip and knee (shoulder and
/// elbow) the body's roles give it ([`roles_of`]: by name, else by shape, on the rest
/// pose), so a shin split into segments turns at the knee and a foot hung off the root
/// (an IK-style game rig) still has its leg; where the roles do not end a limb at that
/// joint (an unusual rig, a joint the user chose), the joint's parent and grandparent.
fn legs_above(skeleton: &Skeleton, ankles: &[usize]) -> Result<Vec<Leg>, FootLockError> {
    let joints = skeleton.joints();
    let name = |a: usize| joints[a].name.clone();
    let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
    let roles = roles_of(skeleton, &rest);
    let limbs: Vec<[usize; 3]> =
        roles.as_ref().map(|r| r.legs.iter().chain(&r.arms).map(|l| l.joints()).collect()).unwrap_or_default();
    ankles
        .iter()
        .map(|&ankle| {
            if let Some(&[hip, knee, _]) = limbs.iter().find(|l| l[2] == ankle) {
                return Ok(Leg { hip, knee, detached: !skeleton.is_ancestor(knee, ankle) });
            }
            let knee = joints[ankle].parent.ok_or_else(|| FootLockError::ShortLeg(name(ankle)))?;
            // A parent that also holds another of the limbs is the root of a rig that hangs
            // its feet there: the leg can only come from the body's roles.
            let holds_another = ankles.iter().any(|&o| o != ankle && (o == knee || skeleton.is_ancestor(knee, o)));
            if holds_another {
                let why = match &roles {
                    Ok(_) => "the legs read from the body end elsewhere".to_owned(),
                    Err(e) => e.to_string(),
                };
                return Err(FootLockError::DetachedFoot { foot: name(ankle), why });
            }
            let hip = joints[knee].parent.ok_or_else(|| FootLockError::ShortLeg(name(ankle)))?;
            Ok(Leg { hip, knee, detached: false })
        })
        .collect()
}

/// Holds the feet of `clip` planted during `contacts` (see the module doc).
pub fn foot_lock(clip: &Clip, contacts: &Contacts, params: &FootLockParams) -> Result<FootLocked, FootLockError> {
    if contacts.frame_count != clip.frame_count() {
        return Err(FootLockError::FrameCount { contacts: contacts.frame_count, clip: clip.frame_count() });
    }
    let skeleton = clip.skeleton();
    let joints = skeleton.joints();
    let mut rig = IkRig::new(skeleton.clone());
    let ankles: Vec<usize> = contacts
        .limbs()
        .map(|foot| skeleton.index_of(&foot.foot).ok_or_else(|| FootLockError::UnknownFoot(foot.foot.clone())))
        .collect::<Result<_, _>>()?;
    let legs = legs_above(skeleton, &ankles)?;
    let mut turned = Vec::new();
    for (&ankle, leg) in ankles.iter().zip(&legs) {
        for j in [leg.hip, leg.knee] {
            turned.push(j);
            let w = params.weights.iter().find(|(n, _)| *n == joints[j].name).map_or(1.0, |(_, w)| *w);
            rig.add_joint(j, [true; 3], w);
        }
        // A detached foot's effector is the end of its shin, a point the knee carries.
        rig.add_effector(if leg.detached { leg.knee } else { ankle });
    }
    for (name, _) in &params.weights {
        rig.joint(name)?;
    }
    let rig = rig.finish()?;
    let blend = (params.blend_secs * clip.fps()).round().max(1.0) as usize;
    // Named toes for the feet; any other limb (a hand) is held at its tip.
    let tips: Vec<usize> = ankles
        .iter()
        .enumerate()
        .map(|(k, &a)| match params.toes.as_ref().and_then(|names| names.get(k)) {
            Some(name) => skeleton.index_of(name).ok_or_else(|| FootLockError::UnknownToe(name.clone())),
            None => Ok(limb_tip(skeleton, a)),
        })
        .collect::<Result<_, _>>()?;
    let plants: Vec<Plants> =
        contacts.limbs().zip(&tips).map(|(foot, &tip)| Plants::new(clip, tip, &foot.intervals, blend)).collect();
    let lifts: Vec<Vec<f64>> = match &params.ground {
        Ground::Clip => vec![Vec::new(); ankles.len()],
        Ground::Soles { mesh, floor_height_m } => {
            let feet: Vec<Vec<usize>> = ankles.iter().map(|&a| foot_joints(skeleton, a)).collect();
            let soles = lowest_sole_heights(clip, mesh, &feet)?;
            soles
                .into_iter()
                .zip(contacts.limbs())
                .map(|(sole, foot)| {
                    let sole = sole.ok_or_else(|| FootLockError::NoSole(foot.foot.clone()))?;
                    Ok(ground_offsets(&sole, *floor_height_m, &foot.intervals, false))
                })
                .collect::<Result<_, FootLockError>>()?
        }
        Ground::AboveFloor { floor_height_m } => {
            let poses = forward_kinematics(clip);
            ankles
                .iter()
                .zip(contacts.limbs())
                .map(|(&a, foot)| {
                    let joints = foot_joints(skeleton, a);
                    let lowest: Vec<f64> = (0..clip.frame_count())
                        .map(|f| {
                            joints.iter().map(|&j| f64::from(poses.position(f, j).y)).fold(f64::INFINITY, f64::min)
                        })
                        .collect();
                    ground_offsets(&lowest, *floor_height_m, &foot.intervals, true)
                })
                .collect()
        }
    };

    let n = skeleton.len();
    // On soles the root carries the part of the feet's moves both share (the lower of the
    // two per frame), so the legs only ever shorten: a foot pulled down by a straight leg
    // would be out of reach.
    let mut translations = clip.translations().to_vec();
    let on_soles = !matches!(params.ground, Ground::Clip);
    let mut root_lift = vec![0.0f32; clip.frame_count()];
    if on_soles {
        let root = (0..n).find(|&j| joints[j].parent.is_none()).unwrap_or(0);
        for (f, frame) in translations.chunks_exact_mut(n).enumerate() {
            // The feet's: a hand that never comes down has no lift, and would keep the root low.
            let shared = lifts.iter().take(contacts.feet.len()).map(|l| l[f]).fold(f64::INFINITY, f64::min);
            if shared.is_finite() {
                root_lift[f] = shared as f32;
                frame[root].y += root_lift[f];
            }
        }
    }
    let before = forward_kinematics(clip);
    let mut solver = IkSolver::new(rig);
    let mut world = vec![Transform::IDENTITY; n];
    let mut goals = vec![DVec3::ZERO; ankles.len()];
    let mut foot_in_world = vec![Quat::IDENTITY; ankles.len()];
    // Per detached foot, where the clip puts it in its knee's frame this frame.
    let mut shin_ends = vec![Vec3::ZERO; ankles.len()];
    let mut shortfalls = vec![Vec::with_capacity(clip.frame_count()); ankles.len()];
    let mut rotations = clip.rotations().to_vec();
    let mut frames = Vec::with_capacity(clip.frame_count());
    let mut pose = solver.rig().pose_from(clip.frame_rotations(0), clip.frame_translations(0));
    for f in 0..clip.frame_count() {
        let original = before.frame(f);
        let frame_translations = &translations[f * n..(f + 1) * n];
        for (k, (&ankle, &Leg { hip, knee, detached })) in ankles.iter().zip(&legs).enumerate() {
            let toe = original[tips[k]].translation.as_dvec3();
            let correction = plants[k].shift(f, toe);
            let lift = lifts[k].get(f).copied().unwrap_or(0.0);
            let wanted = original[ankle].translation.as_dvec3() + correction + DVec3::Y * lift;
            // A detached foot's shin ends where the clip puts the foot, in the knee's frame.
            let shin = if detached {
                let knee_world = original[knee];
                shin_ends[k] = knee_world.rotation.inverse() * (original[ankle].translation - knee_world.translation);
                solver.set_effector_offset(k, shin_ends[k].as_dvec3());
                shin_ends[k].length()
            } else {
                original[knee].translation.distance(original[ankle].translation)
            };
            // Joint to joint (a rig may split the thigh or shin into segments).
            let leg = f64::from(original[hip].translation.distance(original[knee].translation) + shin);
            let (hip_before, ankle_before) = (original[hip].translation, original[ankle].translation);
            let eased_from = eased_from(leg, params.soft_reach, hip_before.distance(ankle_before));
            // The hip where this frame's solve finds it: the clip's, moved with the root.
            let hip_now = (hip_before + Vec3::Y * root_lift[f]).as_dvec3();
            goals[k] = soft_goal(hip_now, wanted, eased_from, leg, DVec3::Y);
            shortfalls[k].push(wanted.distance(goals[k]));
            foot_in_world[k] = original[ankle].rotation;
        }
        solver.rig().fill_pose(clip.frame_rotations(f), frame_translations, &mut pose);
        if on_soles && f > 0 {
            // Each solve starts from the last frame's correction carried onto this frame's
            // pose: a leg bent out of a straight knee then keeps bending the same way instead
            // of the solve picking a side afresh each frame (a pop at the knee).
            for &j in &turned {
                let (was, now) = (clip.frame_rotations(f - 1)[j], clip.frame_rotations(f)[j]);
                pose.rotations[j] = (rotations[(f - 1) * n + j] * was.inverse() * now).as_dquat();
            }
            solver.rig().set_euler_from_rotations(&mut pose);
        }
        frames.push(solver.solve(&mut pose, &goals, &params.solve));
        let out = &mut rotations[f * n..(f + 1) * n];
        solver.rig().rotations_of(&pose, out);
        // Feet keep their world orientation: the ankle undoes what the leg above it turned.
        pose_world(skeleton, out, &translations[f * n..(f + 1) * n], &mut world);
        for (k, (&ankle, leg)) in ankles.iter().zip(&legs).enumerate() {
            let parent = joints[ankle].parent.map_or(Transform::IDENTITY, |p| world[p]);
            out[ankle] = parent.rotation.inverse() * foot_in_world[k];
            if leg.detached {
                // The detached foot goes to the end of the shin the solve placed.
                let end = world[leg.knee].translation + world[leg.knee].rotation * shin_ends[k];
                translations[f * n + ankle] = parent.rotation.inverse() * (end - parent.translation);
            }
        }
    }
    let locked = Clip::new(skeleton.clone(), clip.fps(), rotations, translations, clip.import_scale)?;
    let after = forward_kinematics(&locked);
    let feet = contacts
        .limbs()
        .zip(&plants)
        .zip(&tips)
        .zip(&lifts)
        .zip(&shortfalls)
        .map(|((((foot, plant), &tip), lift), short)| FootReport {
            foot: foot.foot.clone(),
            plants: foot.intervals.iter().filter(|r| !r.is_empty()).count(),
            skate_before_m: planted_travel_m(&before, tip, plant),
            skate_after_m: planted_travel_m(&after, tip, plant),
            lift_range_m: lift.iter().fold(None, |range: Option<(f64, f64)>, &d| {
                Some(range.map_or((d, d), |(lo, hi)| (lo.min(d), hi.max(d))))
            }),
            short_frames: short.iter().filter(|&&s| s > params.solve.tolerance_m).count(),
            shortfall_max_m: short.iter().copied().fold(0.0, f64::max),
        })
        .collect();
    Ok(FootLocked { clip: locked, feet, frames })
}

/// The floor (metres) the clean-ups after a blend or a synthesised transition keep planted
/// feet above: the corpus's ground.
pub const CLEAN_UP_FLOOR_M: f64 = 0.0;

/// Most times the clean-up re-detects contacts on its own result ([`hold_detected_plants`]);
/// each pass can only widen plants, and one or two settle them on real clips.
const CLEAN_UP_PASSES: usize = 4;

/// The clean-up after a blend or a synthesised transition (Shum's foot-sliding fix after
/// the blend, feet held through Peng's joins): the plants detected on `clip` with
/// `thresholds`, narrowed by `select`, held where they were put down and lifted onto the
/// floor where the joined clips put them under ([`Ground::AboveFloor`]). Gives the held
/// clip and how many plants were held, or `None` when `select` leaves none (the clip needs
/// no change).
///
/// A plant's shift fading in before it slows a landing foot (and fading out after it, a
/// lifting one), so the same detection run on the held clip can find the plant starting
/// earlier or ending later, on frames that were only partly held and still slide. Those
/// frames join the plant and the clip is held again, until detection on the result finds
/// no planted frame next to a plant that is not held (at most four times, `CLEAN_UP_PASSES`).
pub fn hold_detected_plants(
    clip: &Clip,
    thresholds: &ContactThresholds,
    select: impl FnOnce(Contacts) -> Contacts,
) -> Result<Option<(Clip, usize)>, HoldError> {
    let (detected, _) = contacts_of(clip, &forward_kinematics(clip), thresholds)?;
    let mut plants = select(detected);
    let held: usize = plants.feet.iter().map(|c| c.intervals.len()).sum();
    if held == 0 {
        return Ok(None);
    }
    let params =
        FootLockParams { ground: Ground::AboveFloor { floor_height_m: CLEAN_UP_FLOOR_M }, ..FootLockParams::default() };
    let mut locked = foot_lock(clip, &plants, &params)?;
    for _ in 1..CLEAN_UP_PASSES {
        let (on_result, _) = contacts_of(&locked.clip, &forward_kinematics(&locked.clip), thresholds)?;
        let widened = widen_plants(&plants, &on_result);
        if widened == plants {
            break;
        }
        plants = widened;
        locked = foot_lock(clip, &plants, &params)?;
    }
    let held: usize = plants.feet.iter().map(|c| c.intervals.len()).sum();
    Ok(Some((locked.clip, held)))
}

/// `plants` with every contact of `found` that overlaps or touches one of a foot's plants
/// joined to it; contacts of `found` away from the plants are left out.
fn widen_plants(plants: &Contacts, found: &Contacts) -> Contacts {
    let feet = plants
        .feet
        .iter()
        .zip(&found.feet)
        .map(|(held, seen)| {
            let touching: Vec<FrameRange> = seen
                .intervals
                .iter()
                .filter(|r| held.intervals.iter().any(|h| r.start <= h.end && h.start <= r.end))
                .copied()
                .collect();
            FootContacts { foot: held.foot.clone(), intervals: union_all(&held.intervals, &touching) }
        })
        .collect();
    Contacts { feet, ..plants.clone() }
}

/// Horizontal travel of joint `point` between consecutive frames that are both fully
/// planted (weight 1) in `poses`, in metres: how far a foot slides where it should stand still.
pub fn planted_travel_m(poses: &ClipPoses, point: usize, plants: &Plants) -> f64 {
    let planted = |f: usize| plants.planted(f);
    (1..poses.frame_count())
        .filter(|&f| planted(f) && planted(f - 1))
        .map(|f| f64::from((poses.position(f, point) - poses.position(f - 1, point)).with_y(0.0).length()))
        .sum()
}

/// Where a point is planted during each contact of one foot, and how far it is moved at a
/// frame.
///
/// The place is the point's horizontal position at the frame of the interval where it is
/// lowest (the moment it is surely down: contacts begin at heel strike, while the toe may
/// still be moving). On every frame of the interval the point is moved onto its place, so
/// no frame that counts as planted slides. Outside, the shift the contact needs at its first
/// (last) frame fades in before it (out after it) by a smoothstep over up to `blend` frames:
/// the swing carries the difference, a constant offset faded, never a pull toward a place
/// the foot has not reached yet (which would yank a foot landing fast). A ramp takes at most
/// half the gap to the neighbouring contact, so two contacts' ramps never overlap. A contact
/// through the clip's first or last frame has no ramp there: the foot is down beyond the clip.
#[derive(Clone, Debug, PartialEq)]
pub struct Plants {
    spans: Vec<PlantSpan>,
}

/// One contact of [`Plants`]: its frames, place, and on each side the horizontal shift at
/// its edge frame and the length of the ramp.
#[derive(Clone, Debug, PartialEq)]
struct PlantSpan {
    frames: FrameRange,
    place: DVec3,
    shift_in: DVec3,
    ramp_in: usize,
    shift_out: DVec3,
    ramp_out: usize,
}

impl Plants {
    /// The planted places of joint `point` of `clip` over `intervals`.
    pub fn new(clip: &Clip, point: usize, intervals: &[FrameRange], blend: usize) -> Self {
        let mut world = vec![Transform::IDENTITY; clip.joint_count()];
        let at = |f: usize| {
            pose_world(clip.skeleton(), clip.frame_rotations(f), clip.frame_translations(f), &mut world);
            world[point].translation.as_dvec3()
        };
        Plants::along(at, clip.frame_count(), intervals, blend)
    }

    /// The planted places of a point at `at(frame)` (world position) in a clip of `frames`
    /// frames, over `intervals`: for callers that have the track already.
    pub fn along(mut at: impl FnMut(usize) -> DVec3, frames: usize, intervals: &[FrameRange], blend: usize) -> Self {
        let mut ranges: Vec<FrameRange> =
            intervals.iter().filter(|r| r.end > r.start && r.end <= frames).copied().collect();
        ranges.sort_by_key(|r| r.start);
        let blend = blend.max(1);
        // Half the gap to a neighbour, rounded up: two ramps sharing a gap then never
        // cover the same frame.
        let half_gap = |from: usize, to: usize| to.saturating_sub(from).div_ceil(2);
        let spans = ranges
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let track: Vec<DVec3> = (r.start..r.end).map(&mut at).collect();
                let place = track.iter().copied().min_by(|a, b| a.y.total_cmp(&b.y)).unwrap_or_default();
                let edge_shift = |p: Option<&DVec3>| (place - p.copied().unwrap_or(place)).with_y(0.0);
                let previous_end = i.checked_sub(1).map(|p| ranges[p].end);
                let next_start = ranges.get(i + 1).map(|n| n.start);
                PlantSpan {
                    frames: *r,
                    place,
                    shift_in: edge_shift(track.first()),
                    ramp_in: previous_end.map_or(blend, |e| blend.min(half_gap(e, r.start))),
                    shift_out: edge_shift(track.last()),
                    ramp_out: next_start.map_or(blend, |s| blend.min(half_gap(r.end, s))),
                }
            })
            .collect();
        Plants { spans }
    }

    /// The horizontal shift that puts the point, found at `here` in the clip at `frame`,
    /// where the plants want it: onto its place during a contact, the edge's shift faded
    /// around it, zero elsewhere.
    pub fn shift(&self, frame: usize, here: DVec3) -> DVec3 {
        self.spans
            .iter()
            .find_map(|span| {
                let r = span.frames;
                let (outside, ramp, shift) = if frame < r.start {
                    (r.start - frame, span.ramp_in, span.shift_in)
                } else if frame >= r.end {
                    (frame + 1 - r.end, span.ramp_out, span.shift_out)
                } else {
                    return Some((span.place - here).with_y(0.0));
                };
                let u = 1.0 - outside as f64 / ramp as f64;
                (outside < ramp).then(|| shift * (u * u * (3.0 - 2.0 * u)))
            })
            .unwrap_or(DVec3::ZERO)
    }

    /// Whether `frame` is inside a contact.
    pub fn planted(&self, frame: usize) -> bool {
        self.spans.iter().any(|span| span.frames.contains(frame))
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
        Contacts {
            fps: clip.fps(),
            frame_count: clip.frame_count(),
            feet,
            double_support: Vec::new(),
            hands: Vec::new(),
        }
    }

    #[test]
    fn ground_offsets_stand_each_plant_on_the_floor_and_ease_between_plants() {
        // Soles (m) over ten frames, plants at 1..4 and 7..9, the floor at 0. Hand-solved:
        // the first plant's lowest sole is 0.01 (d = −0.01), the second's −0.01 (d = 0.01);
        // before the first plant d holds −0.01, after the last 0.01; between frames 3 and 7
        // it eases from −0.01 to 0.01 by the smoothstep 3u² − 2u³ at u = 1/4, 1/2, 3/4
        // (0.15625, 0.5, 0.84375 of the 0.02 step).
        let sole = [0.03, 0.02, 0.01, 0.02, 0.05, 0.10, 0.05, 0.04, -0.01, -0.02];
        let d = ground_offsets(&sole, 0.0, &[FrameRange::new(7, 9), FrameRange::new(1, 4)], false);
        let want = [-0.01, -0.01, -0.01, -0.01, -0.006875, 0.0, 0.006875, 0.01, 0.01, 0.01];
        for (f, (got, want)) in d.iter().zip(want).enumerate() {
            assert!((got - want).abs() < 1e-12, "frame {f}: {got} vs {want}");
        }
        // A raised floor lifts every frame by its height; no plants, no move.
        let raised = ground_offsets(&sole, 0.5, &[FrameRange::new(7, 9), FrameRange::new(1, 4)], false);
        assert!(raised.iter().zip(&d).all(|(r, d)| (r - d - 0.5).abs() < 1e-12));
        assert_eq!(ground_offsets(&sole, 0.0, &[], false), vec![0.0; 10]);
        // Lifting only: the first plant floats 1 cm and stays; the second is 1 cm under.
        let lifted = ground_offsets(&sole, 0.0, &[FrameRange::new(7, 9), FrameRange::new(1, 4)], true);
        assert_eq!(lifted[2], 0.0);
        assert!((lifted[8] - 0.01).abs() < 1e-12 && (lifted[5] - 0.005).abs() < 1e-12);
    }

    /// A point moving 1 cm a frame along x, planted over frames 4..14 with 4-frame ramps.
    /// By hand: the place is x(4) = 0.04 (a level track: the first lowest frame); inside the
    /// contact the shift is place − x; the contact needs no shift at its first frame, so
    /// nothing moves before it, and −0.09 at its last (x(13) = 0.13), faded out after it by
    /// the smoothstep. With a second contact 2 frames later, each ramp gets (2 + 1) / 2 = 1
    /// frame, i.e. none: the gap is left free.
    #[test]
    fn plants_hold_every_contact_frame_and_fade_the_edge_shift_outside() {
        use glam::Vec3;
        let skeleton =
            Arc::new(crate::model::Skeleton::new(vec![crate::model::Joint::new("toe", None, Vec3::ZERO)]).unwrap());
        let x = |f: usize| f as f64 * 0.01;
        let translations = (0..30).map(|f| Vec3::new(x(f) as f32, 0.0, 0.0)).collect();
        let clip = Clip::new(skeleton, 30.0, vec![Quat::IDENTITY; 30], translations, crate::model::ImportScale::METRES)
            .unwrap();
        let here = |f: usize| DVec3::new(x(f), 0.0, 0.0);
        let shifts = |plants: &Plants| (0..30).map(|f| plants.shift(f, here(f)).x).collect::<Vec<_>>();

        let one = Plants::new(&clip, 0, &[FrameRange::new(4, 14)], 4);
        let s = shifts(&one);
        for (f, shift) in s.iter().enumerate().take(14).skip(4) {
            assert!((shift - (0.04 - x(f))).abs() < 1e-6, "frame {f}: {shift}");
            assert!(one.planted(f));
        }
        assert!(s[..4].iter().all(|v| v.abs() < 1e-12), "{:?}", &s[..4]);
        // After: −0.09 × smoothstep(3/4, 2/4, 1/4) = 27/32, 1/2, 5/32 of it, then nothing.
        for (f, fraction) in [(14, 27.0 / 32.0), (15, 0.5), (16, 5.0 / 32.0), (17, 0.0)] {
            assert!((s[f] + 0.09 * fraction).abs() < 1e-6, "frame {f}: {}", s[f]);
            assert!(!one.planted(f));
        }

        // Two contacts 2 frames apart: each ramp gets (2 + 1) / 2 = 1 frame, i.e. none.
        let two = Plants::new(&clip, 0, &[FrameRange::new(16, 20), FrameRange::new(4, 14)], 4);
        let s = shifts(&two);
        assert!(s[14].abs() < 1e-12 && s[15].abs() < 1e-12, "{:?}", &s[14..16]);
        for (f, shift) in s.iter().enumerate().take(20).skip(16) {
            assert!((shift - (0.16 - x(f))).abs() < 1e-6, "frame {f}: {shift}");
        }
    }

    #[test]
    fn a_gliding_foot_stays_on_its_plant_with_its_angle_and_the_body_keeps_its_path() {
        // 0.3 m/s for 20 frames at 30 fps: the frozen feet slide 0.19 m.
        let clip = gliding(20, 0.3);
        let contacts = contacts_over(&clip, FrameRange::new(0, 20), FrameRange::new(5, 15));
        // A hard reach: the frozen legs are straight, so a soft one would raise the planted
        // foot by design (tested in `reach` and on Xbot's walk).
        let params = FootLockParams { blend_secs: 2.0 / 30.0, soft_reach: 0.0, ..FootLockParams::default() };
        let locked = foot_lock(&clip, &contacts, &params).unwrap();
        let sk = clip.skeleton();
        let (before, after) = (forward_kinematics(&clip), forward_kinematics(&locked.clip));
        let toe = sk.index_of("LeftToe").unwrap();
        let ankle = sk.index_of("LeftFoot").unwrap();
        // The toes are level in every frame, so the lowest frame is the first: the plant is
        // the toe's place at frame 0. The contact spans the whole clip, so no edge ramps
        // (the foot is down beyond the clip): every frame is fully planted.
        let place = before.position(0, toe);
        for f in 0..20 {
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
        // The right foot is held on every frame of its contact (5..15) at its place, the
        // toe's at frame 5 (level toes: the first lowest frame). It needs no shift at that
        // first frame, so nothing moves before it; at the last (14) it is 0.09 m behind the
        // glide, and that shift fades out over the 2-frame ramp: half of it at frame 15
        // (smoothstep of 1/2), none from 16.
        let right_toe = sk.index_of("RightToe").unwrap();
        let moved = |f: usize| (after.position(f, right_toe) - before.position(f, right_toe)).with_y(0.0).length();
        for f in 0..5 {
            assert!(moved(f) < 1e-5, "frame {f} moved {} m", moved(f));
        }
        let right_place = before.position(5, right_toe);
        for f in 5..15 {
            assert!((after.position(f, right_toe) - right_place).with_y(0.0).length() < 2e-4, "frame {f}");
        }
        assert!((moved(15) - 0.045).abs() < 2e-4, "frame 15 moved {} m", moved(15));
        for f in 16..20 {
            assert!(moved(f) < 1e-5, "frame {f} moved {} m", moved(f));
        }
        let left = &locked.feet[0];
        // Independent figure: 19 planted steps of 0.01 m each (0.3 m/s at 30 fps).
        assert!((left.skate_before_m - 0.19).abs() < 1e-4, "{left:?}");
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
    fn plants_widen_by_the_contacts_found_next_to_them_and_only_those() {
        let contacts = |left: Vec<FrameRange>, right: Vec<FrameRange>| Contacts {
            fps: 30.0,
            frame_count: 40,
            feet: vec![
                FootContacts { foot: "LeftFoot".into(), intervals: left },
                FootContacts { foot: "RightFoot".into(), intervals: right },
            ],
            double_support: Vec::new(),
            hands: Vec::new(),
        };
        let r = FrameRange::new;
        let held = contacts(vec![r(5, 10)], vec![r(20, 25)]);
        // Found on the held clip: the left plant starting two frames earlier and a contact
        // touching its end (10..11), one away from it (12..15); the right plant running on
        // to 30, and one far before it (0..2).
        let found = contacts(vec![r(3, 10), r(10, 11), r(12, 15)], vec![r(0, 2), r(24, 30)]);
        let widened = widen_plants(&held, &found);
        assert_eq!(widened.feet[0].intervals, vec![r(3, 11)]);
        assert_eq!(widened.feet[1].intervals, vec![r(20, 30)]);
        // Found nothing new: unchanged, so the clean-up stops.
        assert_eq!(widen_plants(&held, &held), held);
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
