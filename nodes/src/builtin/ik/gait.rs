//! Procedural walking (Meredith & Maddock): a walk planned from the paper's foot-height
//! curve and a few control parameters, with the legs placed by the weighted Jacobian IK, so
//! a stiffened joint or a shortened stride turns the walk into a limp.
//!
//! Conventions: metres, seconds, radians, Y up, right-handed. The walk is planned in a body
//! frame whose +Z is the walking direction and +X the character's left; a heading `ψ` turns
//! it about +Y (`ψ = 0` walks along +Z, `ψ = π/2` along +X).
//!
//! The algorithm:
//! 1. **Skeleton.** The legs (thigh, shank, foot) are found by name
//!    ([`find_legs`]); the toe tip is the foot's farthest descendant ([`limb_tip`]). The rest
//!    pose gives the facing (ankle → toe), the sole height (the toe tip's height) and a heel
//!    point on the sole under the ankle. The foot (ankle → toe tip) is one rigid piece.
//! 2. **Timing.** One cycle of the normal walk lasts `T = stride / speed`; each swing lasts
//!    `swing_fraction · T` divided by that leg's `swing_speed_scale`, and each double support
//!    `(1 − 2 swing_fraction) · T / 2`. The cycle is: left heel strike, double support, right
//!    swing, right heel strike, double support, left swing. A leg's step (how far its foot
//!    lands ahead of the other foot) is `stride / 2 · stride_scale`; both feet advance by the
//!    sum of the two steps per cycle (a sustained walk cannot have one foot travel less than
//!    the other, so an injured leg's shorter "stride" is its shorter step).
//! 3. **Path.** The feet land along a path of constant curvature `κ = turn_rate / v̄`
//!    (`v̄` the walk's mean speed), so the heading changes at `turn_rate` on average. The
//!    ground under a footfall follows a stair profile: `rise · (⌊(s − start) / run⌋ + 1)` for
//!    path distance `s ≥ start`, else 0 (at the foot's middle).
//! 4. **Foot roll (two stages).** In stance the foot turns about its heel from the heel-strike
//!    pitch to flat over the double support after it lands (loading), stays flat, then turns
//!    about its toe tip from the middle of the other foot's swing to toe-off. In the air the
//!    pitch goes from toe-off to flat over the first third of the swing and from flat to the
//!    heel-strike pitch over the last third.
//! 5. **Swing height (eq. 1.1).** With `x = 3π u` over the swing (`u` ∈ [0, 1]),
//!    `Y(x) = 1 − cos x` for `x ≤ π`, else `1 − cos((π + x) / 2)`: the foot's lowest point
//!    (the toe while the heel is up, the heel while the toes are up) rises from the ground
//!    under the take-off place to `step_height` above the higher of the two grounds at
//!    `x = π`, then comes down onto the landing place. Horizontally the foot eases from one
//!    place to the next (`½ − ½ cos πu`).
//! 6. **Pelvis.** At the middle of each double support the pelvis is between the two
//!    planted heels; between those keys its distance along the path is a monotone cubic
//!    (Hermite); `u` ∈ [0, 1] runs from one key to the next. It sways sideways toward the
//!    stance foot by `hip_sway_m · sin πu` and turns about the vertical by
//!    `hip_rotation_rad · cos πu` (the paper's hip swing: the leading leg's hip ahead at each
//!    double support; the spine turns back so the chest faces the path). Its height comes
//!    from the legs: the limit is, per frame, the highest root for which every planned ankle
//!    is within 99.9 % of its leg's length (never above the rest height over the ground),
//!    eroded and averaged over ±0.05 s; at each key the pelvis is at the lowest of that limit
//!    around the double support (legs nearly straight at heel strike), between keys it rises
//!    by `hip_bounce_m · sin² πu` (the paper's vertical travel; 2–5 cm in a human walk),
//!    never above the limit. The upper arms swing about the body's left-right axis by
//!    `arm_swing_rad · cos πu`, each against its own side's leg.
//! 7. **Legs by weighted IK.** Per leg, the hip joints turn about three axes with the hip
//!    weight, the knee about its hinge (the Euler axis nearest the body's left-right axis,
//!    bending backward only) with the knee weight, the ankle about three axes with the ankle
//!    weight. Every frame starts from the previous frame's pose. From heel strike to heel-off
//!    the ankle, heel and toe tip are driven to the planned foot, which fixes the leg. From
//!    heel-off to the next heel strike (push-off and swing) the toe tip follows its planned
//!    path exactly, while the foot's orientation is blended from what a toe-only weighted
//!    solve gives (free) to the planned one by `w = 1 − swing_freedom · s(v / 0.15) ·
//!    s((1 − v) / 0.3)` (`v` ∈ [0, 1] over that span, `s` the smoothstep): planned at
//!    heel-off and at landing, free in between, and pulled toward the plan just enough that
//!    the heel never goes below the ground. This is where the weights show: a stiff knee
//!    bends less at push-off and in the swing, and the hip and ankle take up the motion.
//!    With every foot point fixed (flat stance) the weights cannot change the leg.

use std::f64::consts::PI;
use std::sync::Arc;

use glam::{DQuat, DVec3, Quat, Vec3};
use serde_json::json;

use crate::kernels::body::{find_landmarks, find_legs, limb_tip};
use crate::kernels::ik::{DofKind, IkRig, IkSolver, RigError, SolveParams};
use crate::kernels::mannequin::mannequin_skeleton;
use crate::math::smoothstep;
use crate::model::choice::{Choice, choices};
use crate::model::fk::{forward_kinematics, rest_world};
use crate::model::intervals::intersect_all;
use crate::model::{
    Clip, ClipError, Contacts, FootContacts, FrameRange, ImportScale, Joint, Skeleton, SkeletonError, Transform,
};
use crate::node::into_report;
use crate::node::{
    ChoiceParam, FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Report, TextParam,
};

/// Planned ankles stay within this fraction of the leg's length (hip → knee → ankle).
const REACH: f64 = 0.999;

/// Length of one swing in the curve's parameter: `x ∈ [0, 3π]`.
pub const SWING_CYCLE: f64 = 3.0 * PI;

/// Meredith & Maddock's eq. 1.1: the foot's relative height over a swing, `x ∈ [0, 3π]`
/// (clamped). Rises from 0 to 2 at `x = π`, falls back to 0 at `x = 3π`.
pub fn foot_height_curve(x: f64) -> f64 {
    let x = x.clamp(0.0, SWING_CYCLE);
    if x <= PI { 1.0 - x.cos() } else { 1.0 - ((PI + x) / 2.0).cos() }
}

/// Per-leg control and stiffness. Presets are defaults of these.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegParams {
    /// Scales this leg's step (how far its foot lands ahead of the other foot). Default 1.
    pub stride_scale: f64,
    /// Scales this leg's swing height. Default 1.
    pub height_scale: f64,
    /// Scales the speed of this leg's swing (its duration is divided by it). Default 1.
    pub swing_speed_scale: f64,
    /// IK weight of the hip's three DOFs, [0, 1] (1 free, 0 locked). Default 1.
    pub hip_weight: f64,
    /// IK weight of the knee hinge, [0, 1]. Default 1.
    pub knee_weight: f64,
    /// IK weight of the ankle's three DOFs, [0, 1]. Default 1.
    pub ankle_weight: f64,
}

impl Default for LegParams {
    fn default() -> Self {
        LegParams {
            stride_scale: 1.0,
            height_scale: 1.0,
            swing_speed_scale: 1.0,
            hip_weight: 1.0,
            knee_weight: 1.0,
            ankle_weight: 1.0,
        }
    }
}

/// A named set of [`LegParams`] defaults (Meredith & Maddock, Figure 1.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GaitPreset {
    /// Every scale and weight 1.
    Normal,
    /// Both hips' weights 0.8 (−20 %): a subtly individual walk.
    Individual,
    /// Left leg: step height × 0.5, step length × 0.5, swing speed × 1.3, knee weight 0.1
    /// (−90 %).
    InjuredLeftLeg,
    /// The injured leg's control changes (left height × 0.5, length × 0.5, swing speed × 1.3)
    /// with a stiff left hip (weight 0.1) instead of the knee.
    HipInjury,
}

choices!(GaitPreset {
    Normal = "normal",
    Individual = "individual",
    InjuredLeftLeg = "injured_left_leg",
    HipInjury = "hip_injury",
});

impl GaitPreset {
    /// The left and right leg settings the preset stands for.
    pub fn legs(self) -> [LegParams; 2] {
        let normal = LegParams::default();
        let limp = LegParams { stride_scale: 0.5, height_scale: 0.5, swing_speed_scale: 1.3, ..normal };
        match self {
            GaitPreset::Normal => [normal; 2],
            GaitPreset::Individual => [LegParams { hip_weight: 0.8, ..normal }; 2],
            GaitPreset::InjuredLeftLeg => [LegParams { knee_weight: 0.1, ..limp }, normal],
            GaitPreset::HipInjury => [LegParams { hip_weight: 0.1, ..limp }, normal],
        }
    }
}

/// Control parameters of a procedural walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GaitParams {
    /// Frame rate of the clip (frames per second). Default 30.
    pub fps: f64,
    /// Length of the clip (seconds). Default 4.
    pub duration_secs: f64,
    /// Distance between successive footfalls of one foot in the normal walk (metres).
    /// Default 1.3.
    pub stride_length_m: f64,
    /// Walking speed of the normal walk (metres per second); with the stride it sets the
    /// cadence. Default 1.25.
    pub speed_m_per_s: f64,
    /// Heading at the start (radians about +Y; 0 walks along +Z). Default 0.
    pub direction_rad: f64,
    /// Turning rate (radians per second, positive turns toward +X from +Z, i.e. to the
    /// character's left). Default 0.
    pub turn_rate_rad_per_s: f64,
    /// Peak height of the swinging foot's lowest point above the ground (metres). Default 0.1.
    pub step_height_m: f64,
    /// Sideways pelvis swing toward the stance foot (metres, each way). Default 0.03.
    pub hip_sway_m: f64,
    /// Rise of the pelvis from the double supports, where the legs are nearly straight, to
    /// mid-stance (metres; a human's is 2–5 cm at a normal walk). Default 0.03.
    pub hip_bounce_m: f64,
    /// Turn of the pelvis about the vertical, each way (radians; the paper's hip swing): the
    /// leading leg's hip is ahead at each double support. Default 0.08.
    pub hip_rotation_rad: f64,
    /// Swing of each upper arm forward and back about the body's left-right axis, each
    /// way, against its own side's leg (radians; 0 = still arms). Default 0.2.
    pub arm_swing_rad: f64,
    /// Height of each stair (metres; 0 = flat ground, negative = going down). Default 0.
    pub stair_rise_m: f64,
    /// Depth of each stair along the path (metres). Default 0.3.
    pub stair_run_m: f64,
    /// Path distance of the first stair's edge from the start (metres). Default 1.
    pub stair_start_m: f64,
    /// Share of the normal cycle each foot spends in the air, in (0, 0.5). Default 0.4.
    pub swing_fraction: f64,
    /// Toes-up pitch of the foot at heel strike (radians). Default 0.25.
    pub heel_strike_rad: f64,
    /// Heel-up pitch of the foot at toe-off (radians). Default 0.5.
    pub toe_off_rad: f64,
    /// How free the foot's orientation is between heel-off and landing, [0, 1] (0 = exactly
    /// the planned orientation throughout, so the weights cannot change the leg). Default 1.
    pub swing_freedom: f64,
    /// Left, right leg settings.
    pub legs: [LegParams; 2],
    /// IK stopping controls per frame.
    pub solve: SolveParams,
}

impl Default for GaitParams {
    fn default() -> Self {
        GaitParams {
            fps: 30.0,
            duration_secs: 4.0,
            stride_length_m: 1.3,
            speed_m_per_s: 1.25,
            direction_rad: 0.0,
            turn_rate_rad_per_s: 0.0,
            step_height_m: 0.1,
            hip_sway_m: 0.03,
            hip_bounce_m: 0.03,
            hip_rotation_rad: 0.08,
            arm_swing_rad: 0.2,
            stair_rise_m: 0.0,
            stair_run_m: 0.3,
            stair_start_m: 1.0,
            swing_fraction: 0.4,
            heel_strike_rad: 0.25,
            toe_off_rad: 0.5,
            swing_freedom: 1.0,
            legs: [LegParams::default(); 2],
            solve: SolveParams { max_iterations: 100, ..SolveParams::default() },
        }
    }
}

/// Why a walk cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GaitError {
    /// The skeleton lacks leg joints (names the missing roles).
    #[error("the skeleton has no two legs to walk on (missing: {0})")]
    MissingLegs(String),
    /// A foot has no joint below it to serve as the toe.
    #[error("the foot `{0}` has no toe joint below it")]
    NoToe(String),
    /// A parameter out of its range.
    #[error("{name}: {reason}")]
    Param {
        /// Parameter name.
        name: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// Building the IK rig failed.
    #[error(transparent)]
    Rig(#[from] RigError),
    /// The helper skeleton with heel points failed.
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    /// Building the clip failed.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// The joints of one leg and the rest geometry of its foot.
#[derive(Clone, Debug, PartialEq)]
pub struct LegJoints {
    /// Top of the thigh.
    pub hip: usize,
    /// Knee (top of the shank).
    pub knee: usize,
    /// Ankle (the foot joint).
    pub ankle: usize,
    /// Toe tip (the foot's farthest descendant).
    pub toe: usize,
    /// The heel point on the sole under the ankle, in the ankle joint's frame (metres).
    pub heel_in_ankle: Vec3,
}

/// Measured facts of one leg's walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegReport {
    /// Mean distance between successive footfalls of this foot, measured on the clip (m).
    pub stride_length_m: f64,
    /// Mean distance this foot lands ahead of the other foot, along its heading (m).
    pub step_length_m: f64,
    /// Time this foot spends in the air per swing (s).
    pub swing_secs: f64,
    /// Footfalls inside the clip.
    pub footfalls: usize,
    /// Largest knee bend over the clip: change of the thigh–shank angle from rest (rad).
    pub max_knee_flexion_rad: f64,
    /// How far the knee bends and straightens within a swing: range of the thigh–shank
    /// angle over the swing, mean over the swings in the clip (rad).
    pub swing_knee_range_rad: f64,
    /// The settings this leg walked with.
    pub params: LegParams,
}

/// What a walk measured.
#[derive(Clone, Debug, PartialEq)]
pub struct GaitReport {
    /// Left, right.
    pub legs: [LegReport; 2],
    /// Footfalls per minute (both feet), over whole strides.
    pub cadence_steps_per_min: f64,
    /// Distance the feet advance per second, measured from the footfalls (m/s).
    pub speed_m_per_s: f64,
    /// Largest IK residual over all frames and legs (m).
    pub max_residual_m: f64,
    /// Frames where a leg did not reach its goals within the tolerance.
    pub unconverged_frames: usize,
    /// Mean pelvis (root) height above the ground (m).
    pub pelvis_height_m: f64,
    /// Pelvis rise from its lowest to its highest above the ground (m).
    pub pelvis_rise_m: f64,
}

/// One planned footfall of one foot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Footfall {
    /// Heel strike (s).
    pub strike_secs: f64,
    /// The foot is flat from here (s).
    pub flat_secs: f64,
    /// The heel starts to rise (s).
    pub heel_off_secs: f64,
    /// Toe-off (s).
    pub lift_secs: f64,
    /// The heel point while flat, world metres (its height is the ground's).
    pub heel: DVec3,
    /// The foot's heading (rad).
    pub heading_rad: f64,
}

/// A walk: the clip, its planned contacts and footfalls, and what was measured on it.
#[derive(Clone, Debug)]
pub struct Gait {
    /// The walking motion.
    pub clip: Clip,
    /// The planned foot contacts (frames from heel strike to toe-off, per foot, left first).
    pub contacts: Contacts,
    /// Planned footfalls per leg (left, right), including ones just outside the clip.
    pub footfalls: [Vec<Footfall>; 2],
    /// The leg joints (left, right).
    pub legs: [LegJoints; 2],
    /// Measurements on the clip.
    pub report: GaitReport,
    /// Oddities that did not stop the walk.
    pub warnings: Vec<String>,
}

/// Where one foot is planned to be at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FootPlan {
    /// Ankle, heel, toe tip (world metres).
    points: [DVec3; 3],
    /// Rotation from the rest pose's foot to the planned foot.
    rotation: DQuat,
    /// Position in the swing, if the foot is in the air.
    swing_u: Option<f64>,
    /// Position from heel-off to the next heel strike (the toe leads), if there.
    toe_phase: Option<f64>,
    /// The heel may not go below this height (m): the ground it stands on or will land on,
    /// whichever is lower.
    heel_floor_m: f64,
}

/// The path the walk follows: constant curvature from the origin.
#[derive(Clone, Copy, Debug)]
struct Path {
    heading0: f64,
    curvature: f64,
}

impl Path {
    fn heading(&self, s: f64) -> f64 {
        self.heading0 + self.curvature * s
    }

    /// Point at path distance `s` (Y = 0).
    fn point(&self, s: f64) -> DVec3 {
        let (a, k) = (self.heading0, self.curvature);
        if (k * s).abs() < 1e-9 {
            DVec3::new(a.sin() * s, 0.0, a.cos() * s)
        } else {
            let b = a + k * s;
            DVec3::new((a.cos() - b.cos()) / k, 0.0, (b.sin() - a.sin()) / k)
        }
    }
}

/// Walking direction for heading `ψ`.
fn forward(psi: f64) -> DVec3 {
    DVec3::new(psi.sin(), 0.0, psi.cos())
}

/// The character's left for heading `ψ`.
fn left(psi: f64) -> DVec3 {
    DVec3::new(psi.cos(), 0.0, -psi.sin())
}

/// A pelvis key: the middle of a double support.
#[derive(Clone, Copy, Debug)]
struct Key {
    secs: f64,
    progress_m: f64,
    ground_m: f64,
    /// +1 when the left foot is the stance foot until the next key, −1 for the right.
    side: f64,
}

/// The rest geometry a plan needs.
struct Body {
    legs: [LegJoints; 2],
    /// Rotation taking the rest facing to +Z.
    face: DQuat,
    root_rest_rotation: DQuat,
    /// Root height above the sole at rest.
    root_height_m: f64,
    /// Hip positions relative to the root in the body frame.
    hips: [DVec3; 2],
    /// Leg length hip → knee → ankle.
    leg_length_m: [f64; 2],
    /// Ankle, heel, toe relative to the heel, body frame (heel and toe on the sole, y = 0).
    foot: [[DVec3; 3]; 2],
    /// Ankle, heel, toe in the rest pose, world.
    foot_rest: [[DVec3; 3]; 2],
    foot_length_m: [f64; 2],
    /// World transforms of every joint in the rest pose.
    rest: Vec<Transform>,
}

fn body_of(skeleton: &Skeleton) -> Result<Body, GaitError> {
    let found = find_legs(skeleton).map_err(|m| GaitError::MissingLegs(m.join(", ")))?;
    let rest = rest_world(skeleton);
    let pos = |j: usize| rest[j].translation.as_dvec3();
    let mut toes = [0usize; 2];
    for (side, leg) in found.iter().enumerate() {
        toes[side] = limb_tip(skeleton, leg[2]);
        if toes[side] == leg[2] || pos(toes[side]).distance(pos(leg[2])) < 1e-4 {
            return Err(GaitError::NoToe(skeleton.joints()[leg[2]].name.clone()));
        }
    }
    let sole_y = pos(toes[0]).y.min(pos(toes[1]).y);
    // Facing: the feet's ankle → toe directions; the hips' left-right line if they cancel.
    let toe_dir = (0..2).map(|s| (pos(toes[s]) - pos(found[s][2])).with_y(0.0)).sum::<DVec3>();
    let hips_left = (pos(found[0][0]) - pos(found[1][0])).with_y(0.0);
    let facing = toe_dir.try_normalize().or_else(|| hips_left.cross(DVec3::Y).try_normalize()).unwrap_or(DVec3::Z);
    let face = DQuat::from_rotation_y(-facing.x.atan2(facing.z));
    let root = pos(0);
    let mut feet = [[DVec3::ZERO; 3]; 2];
    let mut feet_rest = [[DVec3::ZERO; 3]; 2];
    let mut legs = Vec::new();
    let mut leg_length = [0.0; 2];
    let mut hips = [DVec3::ZERO; 2];
    for side in 0..2 {
        let [hip, knee, ankle] = found[side];
        let toe = toes[side];
        let heel = pos(ankle).with_y(pos(toe).y);
        feet_rest[side] = [pos(ankle), heel, pos(toe)];
        feet[side] = [face * (pos(ankle) - heel), DVec3::ZERO, face * (pos(toe) - heel)];
        feet[side][2].y = 0.0;
        hips[side] = face * (pos(hip) - root);
        leg_length[side] = pos(hip).distance(pos(knee)) + pos(knee).distance(pos(ankle));
        let heel_in_ankle = rest[ankle].rotation.inverse() * (heel - pos(ankle)).as_vec3();
        legs.push(LegJoints { hip, knee, ankle, toe, heel_in_ankle });
    }
    let foot_length_m = [feet[0][2].length(), feet[1][2].length()];
    let [l, r] = <[LegJoints; 2]>::try_from(legs).map_err(|_| GaitError::MissingLegs("legs".into()))?;
    Ok(Body {
        legs: [l, r],
        face,
        root_rest_rotation: rest[0].rotation.as_dquat(),
        root_height_m: root.y - sole_y,
        hips,
        leg_length_m: leg_length,
        foot: feet,
        foot_rest: feet_rest,
        foot_length_m,
        rest,
    })
}

/// The timed plan of a walk.
struct Plan {
    path: Path,
    footfalls: [Vec<Footfall>; 2],
    keys: Vec<Key>,
    /// Key slopes of the path distance (m/s).
    slopes: Vec<f64>,
    sway_m: f64,
    bounce_m: f64,
    rotation_rad: f64,
    /// Swing height per leg (m).
    heights: [f64; 2],
    heel_strike_rad: f64,
    toe_off_rad: f64,
}

impl Plan {
    fn ground(p: &GaitParams, s: f64) -> f64 {
        if p.stair_rise_m == 0.0 || s < p.stair_start_m {
            0.0
        } else {
            p.stair_rise_m * (((s - p.stair_start_m) / p.stair_run_m).floor() + 1.0)
        }
    }

    /// Builds the footfalls and pelvis keys; without `walking`, a standing plan.
    fn new(p: &GaitParams, body: &Body, walking: bool) -> Plan {
        let mut footfalls: [Vec<Footfall>; 2] = [Vec::new(), Vec::new()];
        let mut keys = Vec::new();
        let lateral = [body.hips[0].x, body.hips[1].x];
        let place = |path: &Path, side: usize, s: f64| {
            let ground = Plan::ground(p, s + 0.5 * body.foot_length_m[side]);
            let psi = path.heading(s);
            let heel = path.point(s) + left(psi) * lateral[side] + DVec3::Y * ground;
            (heel, psi)
        };
        let heights = [0, 1].map(|s| p.step_height_m * p.legs[s].height_scale);
        if !walking {
            let path = Path { heading0: p.direction_rad, curvature: 0.0 };
            for (side, list) in footfalls.iter_mut().enumerate() {
                let (heel, heading_rad) = place(&path, side, 0.0);
                list.push(Footfall {
                    strike_secs: f64::NEG_INFINITY,
                    flat_secs: f64::NEG_INFINITY,
                    heel_off_secs: f64::INFINITY,
                    lift_secs: f64::INFINITY,
                    heel,
                    heading_rad,
                });
            }
            let ground = (footfalls[0][0].heel.y + footfalls[1][0].heel.y) / 2.0;
            for secs in [-1.0, p.duration_secs + 1.0] {
                keys.push(Key { secs, progress_m: 0.0, ground_m: ground, side: 0.0 });
            }
            return Plan {
                path,
                footfalls,
                slopes: vec![0.0; keys.len()],
                keys,
                sway_m: 0.0,
                bounce_m: 0.0,
                rotation_rad: 0.0,
                heights,
                heel_strike_rad: p.heel_strike_rad,
                toe_off_rad: p.toe_off_rad,
            };
        }
        let normal_cycle = p.stride_length_m / p.speed_m_per_s;
        let swing = [0, 1].map(|s| p.swing_fraction * normal_cycle / p.legs[s].swing_speed_scale);
        let double = (1.0 - 2.0 * p.swing_fraction) * normal_cycle / 2.0;
        let steps = [0, 1].map(|s| p.stride_length_m / 2.0 * p.legs[s].stride_scale);
        let cycle = 2.0 * double + swing[0] + swing[1];
        let travel = steps[0] + steps[1];
        let path = Path { heading0: p.direction_rad, curvature: p.turn_rate_rad_per_s * cycle / travel };
        let cycles = (p.duration_secs / cycle).ceil() as i64 + 2;
        let mut previous_right: Option<(f64, f64)> = None; // (progress, ground)
        for n in -2..=cycles {
            let t = n as f64 * cycle;
            let a = steps[0] / 2.0 + n as f64 * travel;
            let b = a + steps[1];
            let (left_heel, left_psi) = place(&path, 0, a);
            let (right_heel, right_psi) = place(&path, 1, b);
            footfalls[0].push(Footfall {
                strike_secs: t,
                flat_secs: t + double,
                heel_off_secs: t + double + swing[1] / 2.0,
                lift_secs: t + 2.0 * double + swing[1],
                heel: left_heel,
                heading_rad: left_psi,
            });
            let right_strike = t + double + swing[1];
            footfalls[1].push(Footfall {
                strike_secs: right_strike,
                flat_secs: right_strike + double,
                heel_off_secs: right_strike + double + swing[0] / 2.0,
                lift_secs: t + cycle + double,
                heel: right_heel,
                heading_rad: right_psi,
            });
            let (b_prev, g_prev) = previous_right.unwrap_or((a - steps[0], Plan::ground(p, a - steps[0])));
            keys.push(Key {
                secs: t + double / 2.0,
                progress_m: (a + b_prev) / 2.0,
                ground_m: (left_heel.y + g_prev) / 2.0,
                side: 1.0,
            });
            keys.push(Key {
                secs: right_strike + double / 2.0,
                progress_m: (a + b) / 2.0,
                ground_m: (left_heel.y + right_heel.y) / 2.0,
                side: -1.0,
            });
            previous_right = Some((b, right_heel.y));
        }
        // Monotone Hermite slopes (Fritsch–Carlson limit: at most 3× either neighbour secant).
        let secant =
            |k: usize| (keys[k + 1].progress_m - keys[k].progress_m) / (keys[k + 1].secs - keys[k].secs).max(1e-12);
        let last = keys.len() - 1;
        let slopes = (0..keys.len())
            .map(|k| {
                if k == 0 {
                    secant(0)
                } else if k == last {
                    secant(last - 1)
                } else {
                    let (d0, d1) = (secant(k - 1), secant(k));
                    let m = (keys[k + 1].progress_m - keys[k - 1].progress_m) / (keys[k + 1].secs - keys[k - 1].secs);
                    m.min(3.0 * d0.min(d1)).max(0.0)
                }
            })
            .collect();
        Plan {
            path,
            footfalls,
            keys,
            slopes,
            sway_m: p.hip_sway_m,
            bounce_m: p.hip_bounce_m,
            rotation_rad: p.hip_rotation_rad,
            heights,
            heel_strike_rad: p.heel_strike_rad,
            toe_off_rad: p.toe_off_rad,
        }
    }

    /// The pelvis at `t` (see [`Pelvis`]).
    fn pelvis(&self, t: f64) -> Pelvis {
        let k = self.keys.partition_point(|key| key.secs <= t).clamp(1, self.keys.len() - 1) - 1;
        let (a, b) = (self.keys[k], self.keys[k + 1]);
        let h = b.secs - a.secs;
        let u = ((t - a.secs) / h).clamp(0.0, 1.0);
        let (u2, u3) = (u * u, u * u * u);
        let s = (2.0 * u3 - 3.0 * u2 + 1.0) * a.progress_m
            + (u3 - 2.0 * u2 + u) * h * self.slopes[k]
            + (-2.0 * u3 + 3.0 * u2) * b.progress_m
            + (u3 - u2) * h * self.slopes[k + 1];
        let ground = a.ground_m + (b.ground_m - a.ground_m) * smoothstep(u);
        let wave = (PI * u).sin();
        let swing = a.side * (PI * u).cos();
        let psi = self.path.heading(s);
        Pelvis {
            position: self.path.point(s) + left(psi) * (self.sway_m * wave * a.side),
            heading: DQuat::from_rotation_y(psi),
            turn: DQuat::from_rotation_y(-self.rotation_rad * swing),
            ground_m: ground,
            rise_m: self.bounce_m * wave * wave,
            swing,
            key: k,
            u,
        }
    }

    /// The planned foot of leg `side` at `t`.
    fn foot(&self, body: &Body, side: usize, t: f64) -> FootPlan {
        let list = &self.footfalls[side];
        let k = list.partition_point(|f| f.strike_secs <= t).clamp(1, list.len()) - 1;
        let f = list[k];
        let toe_phase = list
            .get(k + 1)
            .filter(|_| t >= f.heel_off_secs)
            .map(|next| ((t - f.heel_off_secs) / (next.strike_secs - f.heel_off_secs)).clamp(0.0, 1.0));
        let (heel, heading, pitch, swing_u) = if t < f.lift_secs || k + 1 >= list.len() {
            let pitch = if t < f.flat_secs {
                -self.heel_strike_rad * (1.0 - smoothstep((t - f.strike_secs) / (f.flat_secs - f.strike_secs)))
            } else if t < f.heel_off_secs {
                0.0
            } else {
                self.toe_off_rad * smoothstep((t - f.heel_off_secs) / (f.lift_secs - f.heel_off_secs))
            };
            (f.heel, f.heading_rad, pitch, None)
        } else {
            let next = list[k + 1];
            let u = ((t - f.lift_secs) / (next.strike_secs - f.lift_secs)).clamp(0.0, 1.0);
            let ease = 0.5 - 0.5 * (PI * u).cos();
            let x = SWING_CYCLE * u;
            let (from, to) = (f.heel.y, next.heel.y);
            let top = from.max(to);
            let rise = foot_height_curve(x) / 2.0;
            let y = if x <= PI {
                from + (top - from + self.heights[side]) * rise
            } else {
                to + (top - to + self.heights[side]) * rise
            };
            let heel = f.heel.lerp(next.heel, ease).with_y(y);
            let heading = f.heading_rad + (next.heading_rad - f.heading_rad) * ease;
            let pitch = if x <= PI {
                self.toe_off_rad * (1.0 - smoothstep(x / PI))
            } else if x < 2.0 * PI {
                0.0
            } else {
                -self.heel_strike_rad * smoothstep(x / PI - 2.0)
            };
            (heel, heading, pitch, Some(u))
        };
        let yaw = DQuat::from_rotation_y(heading);
        let geometry = &body.foot[side];
        let pivot = if pitch > 0.0 { geometry[2] } else { DVec3::ZERO };
        let roll = DQuat::from_rotation_x(pitch);
        let points = geometry.map(|r| heel + yaw * (pivot + roll * (r - pivot)));
        let heel_floor_m = list.get(k + 1).map_or(f.heel.y, |next| f.heel.y.min(next.heel.y));
        FootPlan { points, rotation: yaw * roll * body.face, swing_u, toe_phase, heel_floor_m }
    }
}

/// Where the plan puts the pelvis at one time.
#[derive(Clone, Copy, Debug)]
struct Pelvis {
    /// Horizontal position (Y = 0), swayed toward the stance foot.
    position: DVec3,
    /// The path's heading.
    heading: DQuat,
    /// The hip swing about the vertical on top of the heading (the paper's hip rotation):
    /// the leading leg's hip ahead at each double support.
    turn: DQuat,
    /// Ground height under the pelvis (m).
    ground_m: f64,
    /// Rise above the double supports' height, `hip_bounce_m · sin² πu` (m).
    rise_m: f64,
    /// `±cos πu`: +1 at a double support with the left foot ahead, −1 with the right;
    /// the arms swing with it, each against its own side's leg.
    swing: f64,
    /// The key before `t` and the phase `u` ∈ [0, 1] from it to the next.
    key: usize,
    u: f64,
}

/// The joints a walk turns above the legs: the spine's first joints, which undo the
/// pelvis's hip swing so the chest keeps facing the path, and the upper arms, which swing.
struct UpperBody {
    /// Children of the root that do not lead to a leg.
    spine: Vec<usize>,
    /// The upper arms, left then right, when the skeleton's arms are found.
    arms: Option<[usize; 2]>,
}

impl UpperBody {
    fn of(skeleton: &Skeleton, legs: &[LegJoints; 2]) -> UpperBody {
        let leads_to = |from: usize, to: usize| {
            let mut j = Some(to);
            while let Some(k) = j {
                if k == from {
                    return true;
                }
                j = skeleton.joints()[k].parent;
            }
            false
        };
        let spine = skeleton.children(0).filter(|&c| !legs.iter().any(|l| leads_to(c, l.hip))).collect();
        UpperBody { spine, arms: find_landmarks(skeleton).ok().map(|l| l.shoulders()) }
    }

    /// Turns one frame's local `rotations` (the root's already set for `pelvis`).
    fn pose(&self, pelvis: &Pelvis, params: &GaitParams, skeleton: &Skeleton, rotations: &mut [Quat]) {
        // root = turn · rest of the root's rotation; the spine's world rotations must not
        // see the turn: each spine child gets root⁻¹ · turn⁻¹ · root in front.
        let root = rotations[0].as_dquat();
        let undo = (root.inverse() * pelvis.turn.inverse() * root).as_quat();
        for &j in &self.spine {
            rotations[j] = undo * rotations[j];
        }
        let Some(arms) = self.arms else { return };
        let axis = pelvis.heading * DVec3::X;
        for (side, &arm) in arms.iter().enumerate() {
            // About the left axis a positive angle takes a hanging hand back: the left arm
            // is back when the left foot is ahead (swing +1), the right arm forward.
            let sign = if side == 0 { 1.0 } else { -1.0 };
            let swing = DQuat::from_axis_angle(axis, sign * params.arm_swing_rad * pelvis.swing);
            let mut parent = DQuat::IDENTITY;
            let mut j = skeleton.joints()[arm].parent;
            while let Some(k) = j {
                parent = rotations[k].as_dquat() * parent;
                j = skeleton.joints()[k].parent;
            }
            rotations[arm] = (parent.inverse() * swing * parent).as_quat() * rotations[arm];
        }
    }
}

/// The leg rig: hip joints 3 DOFs, knee hinge, ankle 3 DOFs; effectors ankle, heel, toe
/// (`full`) or the toe alone. Returns the rig and the knee's DOF index.
fn leg_rig(
    skeleton: &Arc<Skeleton>,
    leg: &LegJoints,
    heel_joint: usize,
    weights: &LegParams,
    hinge: (usize, f64),
    full: bool,
) -> Result<(IkRig, usize), GaitError> {
    let mut rig = IkRig::new(skeleton.clone());
    let names = skeleton.joints();
    let path = rig.chain_joints(&names[leg.hip].name, &names[leg.ankle].name)?;
    let mut knee_dof = 0;
    for &j in &path {
        if j == leg.ankle {
            rig.add_joint(j, [true; 3], weights.ankle_weight);
        } else if j == leg.knee {
            let mut free = [false; 3];
            free[hinge.0] = true;
            rig.add_joint(j, free, weights.knee_weight);
            knee_dof = rig.dofs().len() - 1;
            let (a, b, c) = names[j].rest_rotation.as_dquat().to_euler(glam::EulerRot::XYZ);
            let straight = [a, b, c][hinge.0];
            let dof = &mut rig.dofs_mut()[knee_dof];
            // Bend backward only, up to 2.6 rad from straight (the rest pose).
            (dof.min, dof.max) = if hinge.1 > 0.0 { (straight, straight + 2.6) } else { (straight - 2.6, straight) };
        } else if !path_below(&path, leg.knee, j) {
            rig.add_joint(j, [true; 3], weights.hip_weight);
        }
    }
    if full {
        rig.add_effector(leg.ankle);
        rig.add_effector(heel_joint);
    }
    rig.add_effector(leg.toe);
    Ok((rig.finish()?, knee_dof))
}

/// True when `joint` comes after `knee` in the root-first `path`.
fn path_below(path: &[usize], knee: usize, joint: usize) -> bool {
    let at = |j: usize| path.iter().position(|&p| p == j);
    matches!((at(knee), at(joint)), (Some(k), Some(j)) if j > k)
}

/// The knee's hinge: the Euler axis (0 X, 1 Y, 2 Z) of its rest frame nearest the body's
/// left-right axis, and the sign of the angle that bends the shank backward.
fn knee_hinge(body: &Body, leg: &LegJoints) -> (usize, f64) {
    let rest = &body.rest;
    let knee_frame = rest[leg.knee].rotation.as_dquat();
    let lateral = body.face.inverse() * DVec3::X;
    let facing = body.face.inverse() * DVec3::Z;
    let axes = [DVec3::X, DVec3::Y, DVec3::Z].map(|a| knee_frame * a);
    let axis = (0..3).max_by(|&a, &b| axes[a].dot(lateral).abs().total_cmp(&axes[b].dot(lateral).abs())).unwrap_or(0);
    let shank = rest[leg.ankle].translation.as_dvec3() - rest[leg.knee].translation.as_dvec3();
    let backward = -axes[axis].cross(shank).dot(facing);
    (axis, if backward >= 0.0 { 1.0 } else { -1.0 })
}

fn check(name: &'static str, ok: bool, reason: &str) -> Result<(), GaitError> {
    if ok { Ok(()) } else { Err(GaitError::Param { name, reason: reason.to_owned() }) }
}

fn validate(p: &GaitParams) -> Result<(), GaitError> {
    let finite_nonneg = |v: f64| v.is_finite() && v >= 0.0;
    check("fps", p.fps.is_finite() && p.fps > 0.0, "the frame rate must be positive")?;
    check("duration_secs", finite_nonneg(p.duration_secs) && p.duration_secs * p.fps <= 1e6, "0 to 10⁶ frames")?;
    check("stride_length_m", finite_nonneg(p.stride_length_m), "must be 0 or more")?;
    check("speed_m_per_s", finite_nonneg(p.speed_m_per_s), "must be 0 or more")?;
    check("direction_rad", p.direction_rad.is_finite(), "must be a number")?;
    check("turn_rate_rad_per_s", p.turn_rate_rad_per_s.is_finite(), "must be a number")?;
    check("step_height_m", finite_nonneg(p.step_height_m), "must be 0 or more")?;
    check("hip_sway_m", finite_nonneg(p.hip_sway_m), "must be 0 or more")?;
    check("hip_bounce_m", finite_nonneg(p.hip_bounce_m), "must be 0 or more")?;
    check("hip_rotation_rad", finite_nonneg(p.hip_rotation_rad), "must be 0 or more")?;
    check("arm_swing_rad", finite_nonneg(p.arm_swing_rad), "must be 0 or more")?;
    check("stair_rise_m", p.stair_rise_m.is_finite(), "must be a number")?;
    check("stair_run_m", p.stair_run_m.is_finite() && p.stair_run_m > 0.0, "must be positive")?;
    check("stair_start_m", p.stair_start_m.is_finite(), "must be a number")?;
    check("swing_fraction", p.swing_fraction > 0.0 && p.swing_fraction < 0.5, "lies in (0, 0.5)")?;
    check("heel_strike_rad", finite_nonneg(p.heel_strike_rad) && p.heel_strike_rad < 1.5, "lies in [0, 1.5)")?;
    check("toe_off_rad", finite_nonneg(p.toe_off_rad) && p.toe_off_rad < 1.5, "lies in [0, 1.5)")?;
    check("swing_freedom", (0.0..=1.0).contains(&p.swing_freedom), "lies in [0, 1]")?;
    for leg in &p.legs {
        check("legs", finite_nonneg(leg.stride_scale), "stride scales must be 0 or more")?;
        check("legs", finite_nonneg(leg.height_scale), "height scales must be 0 or more")?;
        check(
            "legs",
            leg.swing_speed_scale.is_finite() && leg.swing_speed_scale > 0.0,
            "swing speed scales must be positive",
        )?;
        for w in [leg.hip_weight, leg.knee_weight, leg.ankle_weight] {
            check("legs", (0.0..=1.0).contains(&w), "IK weights lie in [0, 1]")?;
        }
    }
    Ok(())
}

/// Makes a walk for `skeleton` (see the module doc for the steps). A zero speed or zero
/// stride gives a standing clip (both feet planted) with a warning.
pub fn procedural_gait(skeleton: &Arc<Skeleton>, params: &GaitParams) -> Result<Gait, GaitError> {
    validate(params)?;
    let body = body_of(skeleton)?;
    let mut warnings = Vec::new();
    let travel = params.stride_length_m / 2.0 * (params.legs[0].stride_scale + params.legs[1].stride_scale);
    let walking = params.speed_m_per_s > 0.0 && travel > 0.0;
    if walking {
        let steps = params.duration_secs * params.speed_m_per_s / travel;
        check("stride_length_m", steps <= 1e5, "the walk would take more than 100 000 steps: lengthen the stride")?;
    }
    if !walking {
        warnings.push("speed or stride is 0: the character stands with both feet planted".to_owned());
    }
    let plan = Plan::new(params, &body, walking);
    let frames = (params.duration_secs * params.fps).round() as usize + 1;
    let time = |f: usize| f as f64 / params.fps;

    // Pelvis height. The limit: as high as the legs allow (every planned ankle within
    // `REACH` of its leg's length, at most the rest height), eroded and averaged over
    // ±0.05 s so it is smooth and stays under itself. At each double support (a key) the
    // pelvis is at the limit, legs nearly straight; between keys it rises by the bounce
    // and comes down again, never above the limit. Worked out up to 2 s past the clip's
    // end, so the last steps know where the legs stretch next.
    let window = ((0.05 * params.fps).round() as usize).max(1);
    let last_key = plan.keys.last().map_or(0.0, |k| k.secs);
    let span_frames =
        frames.max(((last_key.min(params.duration_secs + 2.0)) * params.fps).ceil() as usize + window + 1);
    let pelvises: Vec<Pelvis> = (0..span_frames).map(|f| plan.pelvis(time(f))).collect();
    let allowed: Vec<f64> = (0..span_frames)
        .map(|f| {
            let (t, pelvis) = (time(f), &pelvises[f]);
            let turn = pelvis.turn * pelvis.heading;
            let mut top = pelvis.ground_m + body.root_height_m;
            for side in 0..2 {
                let ankle = plan.foot(&body, side, t).points[0];
                let hip = pelvis.position + turn * body.hips[side];
                let horizontal = (ankle - hip).with_y(0.0).length();
                let limit = REACH * body.leg_length_m[side];
                let vertical = (limit * limit - horizontal * horizontal).max(0.0).sqrt();
                top = top.min(ankle.y + vertical - body.hips[side].y);
            }
            top
        })
        .collect();
    let around = |f: usize| f.saturating_sub(window)..(f + window + 1).min(span_frames);
    let smooth = |values: &[f64]| -> Vec<f64> {
        (0..span_frames).map(|f| values[around(f)].iter().sum::<f64>() / around(f).len() as f64).collect()
    };
    let eroded: Vec<f64> =
        (0..span_frames).map(|f| allowed[around(f)].iter().copied().fold(f64::INFINITY, f64::min)).collect();
    let limit = smooth(&eroded);
    // A key's height: the lowest of the limit within a quarter step of it (the legs are
    // longest-stretched around the double support, not always at its middle).
    let frame_of = |secs: f64| ((secs * params.fps).round().max(0.0) as usize).min(span_frames - 1);
    let keys = &plan.keys;
    let troughs: Vec<f64> = (0..keys.len())
        .map(|k| {
            let before = if k > 0 { (keys[k].secs - keys[k - 1].secs) / 4.0 } else { 0.0 };
            let after = if k + 1 < keys.len() { (keys[k + 1].secs - keys[k].secs) / 4.0 } else { 0.0 };
            let span = frame_of(keys[k].secs - before)..=frame_of(keys[k].secs + after);
            limit[span].iter().copied().fold(f64::INFINITY, f64::min)
        })
        .collect();
    let wanted: Vec<f64> = pelvises
        .iter()
        .zip(&limit)
        .map(|(p, &top)| {
            let trough = troughs[p.key] + (troughs[p.key + 1] - troughs[p.key]) * smoothstep(p.u);
            (trough + p.rise_m).min(top)
        })
        .collect();
    let root_y: Vec<f64> = smooth(&wanted).iter().zip(&limit).take(frames).map(|(y, top)| y.min(*top)).collect();

    // The IK skeleton: the character plus a heel point under each ankle.
    let mut joints = skeleton.joints().to_vec();
    for leg in &body.legs {
        let mut heel = Joint::new(format!("{}.gait_heel", joints[leg.ankle].name), Some(leg.ankle), leg.heel_in_ankle);
        heel.end_site = true;
        joints.push(heel);
    }
    let ik_skeleton = Arc::new(Skeleton::new(joints)?);
    let n = skeleton.len();
    let mut planted = Vec::new();
    let mut free = Vec::new();
    let mut poses = Vec::new();
    let mut leg_joints: Vec<Vec<usize>> = Vec::new();
    let rest_rotations: Vec<Quat> = ik_skeleton.joints().iter().map(|j| j.rest_rotation).collect();
    let rest_offsets: Vec<Vec3> = ik_skeleton.joints().iter().map(|j| j.rest_offset).collect();
    for side in 0..2 {
        let leg = &body.legs[side];
        let hinge = knee_hinge(&body, leg);
        let (rig, knee_dof) = leg_rig(&ik_skeleton, leg, n + side, &params.legs[side], hinge, true)?;
        let (toe_rig, _) = leg_rig(&ik_skeleton, leg, n + side, &params.legs[side], hinge, false)?;
        let mut pose = rig.pose_from(&rest_rotations, &rest_offsets);
        // Start with the knee a little bent, so the solve keeps the natural branch.
        let bent = rig.dof_value(&pose, knee_dof) + 0.3 * hinge.1;
        rig.set_dof(&mut pose, knee_dof, bent);
        leg_joints.push(
            rig.dofs()
                .iter()
                .filter_map(|d| match d.kind {
                    DofKind::Rotation { joint, .. } => Some(joint),
                    DofKind::Translation { .. } => None,
                })
                .collect(),
        );
        planted.push(IkSolver::new(rig));
        free.push(IkSolver::new(toe_rig));
        poses.push(pose);
    }
    let foot_rest = body.foot_rest;
    let upper_body = UpperBody::of(skeleton, &body.legs);
    let ankle_rest_rotation: Vec<DQuat> = body.legs.iter().map(|l| body.rest[l.ankle].rotation.as_dquat()).collect();

    let mut rotations = Vec::with_capacity(frames * n);
    let mut translations = Vec::with_capacity(frames * n);
    let mut scratch = vec![Quat::IDENTITY; ik_skeleton.len()];
    let mut max_residual = 0.0f64;
    let mut unconverged = 0;
    let mut positions = [DVec3::ZERO; 3];
    for (f, &height_m) in root_y.iter().enumerate() {
        let t = time(f);
        let pelvis = &pelvises[f];
        let root = pelvis.position.with_y(height_m);
        let root_rotation = pelvis.turn * pelvis.heading * body.face * body.root_rest_rotation;
        let mut frame_rotations = rest_rotations[..n].to_vec();
        let mut frame_converged = true;
        frame_rotations[0] = root_rotation.as_quat();
        for side in 0..2 {
            let pose = &mut poses[side];
            pose.translations[0] = root;
            pose.rotations[0] = root_rotation;
            let target = plan.foot(&body, side, t);
            let solve = if f == 0 {
                SolveParams { max_iterations: params.solve.max_iterations * 10, ..params.solve }
            } else {
                params.solve
            };
            let goals = match target.toe_phase {
                Some(v) if params.swing_freedom > 0.0 => {
                    let toe = target.points[2];
                    free[side].solve(pose, &[toe], &solve);
                    planted[side].effector_positions(pose, &mut positions);
                    let ankle_now = planted[side].world()[body.legs[side].ankle].0;
                    let free_rotation = ankle_now * ankle_rest_rotation[side].inverse();
                    let rest = foot_rest[side];
                    let heel_y = |w: f64| toe.y + (free_rotation.slerp(target.rotation, w) * (rest[1] - rest[2])).y;
                    // Free in the middle, planned at heel-off and landing; never heel below
                    // the floor (the plan's heel is above it, so bisect toward the plan).
                    let mut w = 1.0 - params.swing_freedom * smoothstep(v / 0.15) * smoothstep((1.0 - v) / 0.3);
                    if heel_y(w) < target.heel_floor_m {
                        let (mut lo, mut hi) = (w, 1.0);
                        for _ in 0..30 {
                            let mid = 0.5 * (lo + hi);
                            if heel_y(mid) < target.heel_floor_m { lo = mid } else { hi = mid }
                        }
                        w = hi;
                    }
                    let rotation = free_rotation.slerp(target.rotation, w);
                    [toe + rotation * (rest[0] - rest[2]), toe + rotation * (rest[1] - rest[2]), toe]
                }
                _ => target.points,
            };
            let report = planted[side].solve(pose, &goals, &solve);
            max_residual = max_residual.max(report.residual_m);
            frame_converged &= report.converged;
            planted[side].rig().rotations_of(pose, &mut scratch);
            for &j in &leg_joints[side] {
                frame_rotations[j] = scratch[j];
            }
        }
        unconverged += usize::from(!frame_converged);
        upper_body.pose(pelvis, params, skeleton, &mut frame_rotations);
        let mut frame_translations = rest_offsets[..n].to_vec();
        frame_translations[0] = root.as_vec3();
        rotations.extend(frame_rotations);
        translations.extend(frame_translations);
    }
    let clip = Clip::new(skeleton.clone(), params.fps, rotations, translations, ImportScale::METRES)?;

    // Planned contacts: frames from heel strike to toe-off.
    let feet: Vec<FootContacts> = (0..2)
        .map(|side| {
            let mut intervals = Vec::new();
            let mut start = None;
            for f in 0..=frames {
                let on = f < frames && plan.foot(&body, side, time(f)).swing_u.is_none();
                match (on, start) {
                    (true, None) => start = Some(f),
                    (false, Some(s)) => {
                        intervals.push(FrameRange::new(s, f));
                        start = None;
                    }
                    _ => {}
                }
            }
            FootContacts { foot: skeleton.joints()[body.legs[side].ankle].name.clone(), intervals }
        })
        .collect();
    let double_support = intersect_all(&feet[0].intervals, &feet[1].intervals);
    let contacts = Contacts { fps: params.fps, frame_count: frames, feet, double_support, hands: Vec::new() };

    let lift: Vec<f64> = root_y.iter().zip(&pelvises).map(|(y, p)| y - p.ground_m).collect();
    let (legs, cadence_steps_per_min, speed_m_per_s) = measure(&clip, &body, &plan, params, walking);
    let report = GaitReport {
        legs,
        cadence_steps_per_min,
        speed_m_per_s,
        max_residual_m: max_residual,
        unconverged_frames: unconverged,
        pelvis_height_m: lift.iter().sum::<f64>() / frames as f64,
        pelvis_rise_m: lift.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            - lift.iter().copied().fold(f64::INFINITY, f64::min),
    };
    Ok(Gait { clip, contacts, footfalls: plan.footfalls.clone(), legs: body.legs.clone(), report, warnings })
}

/// A heel this close to its planted height has struck (metres).
const STRIKE_HEIGHT_M: f64 = 1e-3;

/// Measures the walk on the clip at the plan's footfalls: footfalls (the heel at the middle
/// of each flat stance, the strike where the heel came down), strides, steps and knee bends
/// per leg, cadence (steps/min) and speed (m/s).
fn measure(clip: &Clip, body: &Body, plan: &Plan, params: &GaitParams, walking: bool) -> ([LegReport; 2], f64, f64) {
    let poses = forward_kinematics(clip);
    let last = clip.frame_count().saturating_sub(1);
    let frame_at = |t: f64| (t * clip.fps()).round();
    let heel_at = |side: usize, frame: usize| -> DVec3 {
        let leg = &body.legs[side];
        let ankle: Transform = poses.frame(frame)[leg.ankle];
        ankle.transform_point(leg.heel_in_ankle).as_dvec3()
    };
    // (strike time, heel position, heading) of footfalls whose flat middle is in the clip.
    // The strike is measured on the clip, not read from the plan: the first frame of the
    // run, back from the middle, in which the heel is within 1 mm of its planted height.
    let falls: [Vec<(f64, DVec3, f64)>; 2] = [0, 1].map(|side| {
        plan.footfalls[side]
            .iter()
            .filter(|f| walking && f.strike_secs >= 0.0)
            .filter_map(|f| {
                let middle = frame_at((f.flat_secs + f.heel_off_secs) / 2.0);
                if middle > last as f64 {
                    return None;
                }
                let planted = heel_at(side, middle as usize);
                let mut strike = middle as usize;
                while strike > 0 && heel_at(side, strike - 1).y <= planted.y + STRIKE_HEIGHT_M {
                    strike -= 1;
                }
                Some((strike as f64 / clip.fps(), planted, f.heading_rad))
            })
            .collect()
    });
    let mean = |v: &[f64]| if v.is_empty() { 0.0 } else { v.iter().sum::<f64>() / v.len() as f64 };
    let mut stride_sum = (0.0, 0.0);
    let legs = [0, 1].map(|side| {
        let own = &falls[side];
        let other = &falls[1 - side];
        let strides: Vec<f64> = own.windows(2).map(|w| (w[1].1 - w[0].1).with_y(0.0).length()).collect();
        stride_sum.0 += strides.iter().sum::<f64>();
        stride_sum.1 += own.windows(2).map(|w| w[1].0 - w[0].0).sum::<f64>();
        let steps: Vec<f64> = own
            .iter()
            .filter_map(|(t, heel, psi)| {
                let before = other.iter().rev().find(|o| o.0 < *t)?;
                Some((*heel - before.1).dot(forward(*psi)))
            })
            .collect();
        let leg = &body.legs[side];
        let rest_angle = knee_angle(&body.rest, leg);
        let bend = |f: usize| knee_angle(poses.frame(f), leg) - rest_angle;
        let flexion = (0..clip.frame_count()).map(bend).fold(0.0f64, f64::max);
        let ranges: Vec<f64> = plan.footfalls[side]
            .windows(2)
            .filter(|w| walking && w[0].lift_secs >= 0.0 && frame_at(w[1].strike_secs) <= last as f64)
            .map(|w| {
                let frames = frame_at(w[0].lift_secs) as usize..=frame_at(w[1].strike_secs) as usize;
                let (lo, hi) =
                    frames.map(bend).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), b| (lo.min(b), hi.max(b)));
                hi - lo
            })
            .collect();
        let swing = plan.footfalls[side].windows(2).next().map_or(0.0, |w| w[1].strike_secs - w[0].lift_secs);
        LegReport {
            stride_length_m: mean(&strides),
            step_length_m: mean(&steps),
            swing_secs: if walking { swing } else { 0.0 },
            footfalls: own.len(),
            max_knee_flexion_rad: flexion,
            swing_knee_range_rad: mean(&ranges),
            params: params.legs[side],
        }
    });
    // Two footfalls per stride: 120 per minute per stride-second, over whole strides.
    let strides = falls.iter().map(|f| f.len().saturating_sub(1)).sum::<usize>();
    let cadence = if stride_sum.1 > 0.0 { 120.0 * strides as f64 / stride_sum.1 } else { 0.0 };
    (legs, cadence, if stride_sum.1 > 0.0 { stride_sum.0 / stride_sum.1 } else { 0.0 })
}

/// The bend between thigh and shank (radians, 0 = straight) in world transforms `world`.
fn knee_angle(world: &[Transform], leg: &LegJoints) -> f64 {
    let p = |j: usize| world[j].translation.as_dvec3();
    let (thigh, shank) = (p(leg.knee) - p(leg.hip), p(leg.ankle) - p(leg.knee));
    thigh.angle_between(shank)
}

/// Parses per-leg overrides `left.knee=0.1, right.stride=0.8` onto `legs`. Keys: `stride`,
/// `height`, `swing_speed` (scales), `hip`, `knee`, `ankle` (IK weights).
pub fn parse_leg_overrides(text: &str, legs: &mut [LegParams; 2]) -> Result<(), String> {
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (key, value) = item.split_once('=').ok_or_else(|| format!("`{item}` is not SIDE.KEY=VALUE"))?;
        let (side, what) = key.trim().split_once('.').ok_or_else(|| format!("`{key}` is not SIDE.KEY"))?;
        let leg = match side.trim() {
            "left" => &mut legs[0],
            "right" => &mut legs[1],
            other => return Err(format!("`{other}`: the side is `left` or `right`")),
        };
        let value: f64 = value.trim().parse().map_err(|_| format!("`{item}` has no number"))?;
        let slot = match what.trim() {
            "stride" => &mut leg.stride_scale,
            "height" => &mut leg.height_scale,
            "swing_speed" => &mut leg.swing_speed_scale,
            "hip" => &mut leg.hip_weight,
            "knee" => &mut leg.knee_weight,
            "ankle" => &mut leg.ankle_weight,
            other => {
                return Err(format!("`{other}`: keys are stride, height, swing_speed, hip, knee, ankle"));
            }
        };
        *slot = value;
    }
    Ok(())
}

const SKELETON_CLIP: Input<Arc<Clip>> = Input::optional(
    "clip",
    "A clip whose skeleton walks (e.g. from clip.load or skeleton.scale; only its skeleton and file unit are used, its motion is not). Without one the built-in 1.7 m mannequin walks.",
);
const CLIP_OUT: Output<Arc<Clip>> = Output::new("clip", "The walk.");
const CONTACTS_OUT: Output<Arc<Contacts>> =
    Output::new("contacts", "The planned foot contacts, heel strike to toe-off, per foot.");
const REPORT_OUT: Output<Arc<Report>> = Output::new(
    "report",
    "Stride and step length per leg measured on the walk, cadence, speed, knee bend, IK residual and the preset.",
);
const PRESET: ChoiceParam<GaitPreset> = ChoiceParam::new(
    "preset",
    "Starting settings: `normal`; `individual` (both hips' IK weight 0.8); `injured_left_leg` (left step height and length ×0.5, left swing 30 % faster, left knee weight 0.1); `hip_injury` (the same left-leg changes with a stiff left hip, weight 0.1, instead of the knee).",
    "normal",
);
const LEGS: TextParam = TextParam::new(
    "legs",
    "Per-leg changes on top of the preset, `SIDE.KEY=VALUE` separated by commas, e.g. `left.knee=0.3, right.stride=0.9`. Keys: stride, height, swing_speed (scales, 1 = as the preset), hip, knee, ankle (IK weights in [0, 1]: 1 free, 0.1 stiff).",
    "",
);
const FPS: FloatParam = FloatParam::new("fps", "Frame rate of the walk.", 30.0, 1.0, 1000.0, "fps");
const DURATION: FloatParam = FloatParam::new("duration_secs", "Length of the walk.", 4.0, 0.0, 3600.0, "s");
const STRIDE: FloatParam = FloatParam::new(
    "stride_length_m",
    "Distance between successive footfalls of one foot in the normal walk (0 = stand).",
    1.3,
    0.0,
    5.0,
    "m",
);
const SPEED: FloatParam = FloatParam::new(
    "speed_m_per_s",
    "Walking speed of the normal walk; with the stride it sets the cadence (0 = stand).",
    1.25,
    0.0,
    10.0,
    "m/s",
);
const DIRECTION: FloatParam = FloatParam::new(
    "direction_rad",
    "Heading at the start, about the vertical (0 walks along +Z, π/2 along +X).",
    0.0,
    -7.0,
    7.0,
    "rad",
);
const TURN: FloatParam = FloatParam::new(
    "turn_rate_rad_per_s",
    "Turning rate; positive turns from +Z toward +X (to the character's left).",
    0.0,
    -3.0,
    3.0,
    "rad/s",
);
const STEP_HEIGHT: FloatParam = FloatParam::new(
    "step_height_m",
    "How high the swinging foot's lowest point rises above the ground (Meredith & Maddock eq. 1.1).",
    0.1,
    0.0,
    1.0,
    "m",
);
const SWAY: FloatParam =
    FloatParam::new("hip_sway_m", "Sideways pelvis swing toward the stance foot, each way.", 0.03, 0.0, 0.5, "m");
const BOUNCE: FloatParam = FloatParam::new(
    "hip_bounce_m",
    "Rise of the pelvis from the double supports (legs nearly straight) to mid-stance; a human's is 2–5 cm at a normal walk.",
    0.03,
    0.0,
    0.5,
    "m",
);
const ROTATION: FloatParam = FloatParam::new(
    "hip_rotation_rad",
    "Turn of the pelvis about the vertical, each way (the paper's hip swing): the leading leg's hip ahead at each double support; the chest keeps facing the path.",
    0.08,
    0.0,
    0.8,
    "rad",
);
const ARM_SWING: FloatParam = FloatParam::new(
    "arm_swing_rad",
    "Swing of each upper arm forward and back, each way, against its own side's leg (0: the arms hang still).",
    0.2,
    0.0,
    1.5,
    "rad",
);
const STAIR_RISE: FloatParam =
    FloatParam::new("stair_rise_m", "Height of each stair (0 = flat ground, negative = down).", 0.0, -0.5, 0.5, "m");
const STAIR_RUN: FloatParam =
    FloatParam::new("stair_run_m", "Depth of each stair along the path.", 0.3, 0.05, 5.0, "m");
const STAIR_START: FloatParam =
    FloatParam::new("stair_start_m", "Path distance of the first stair's edge.", 1.0, -100.0, 1000.0, "m");

/// `gait.procedural`.
pub struct ProceduralGait;

static PROCEDURAL_GAIT: NodeSchema = NodeSchema {
    kind: "gait.procedural",
    category: "ik",
    doc: "A procedural walk (Meredith & Maddock): feet follow the paper's foot-height curve with a heel-to-toe roll, the legs are placed by weighted IK; presets and per-leg settings make individual walks and limps (a stiff joint moves less, the others take up the motion).",
    inputs: &[SKELETON_CLIP.spec()],
    outputs: &[CLIP_OUT.spec(), CONTACTS_OUT.spec(), REPORT_OUT.spec()],
    params: &[
        PRESET.0,
        LEGS.0,
        FPS.0,
        DURATION.0,
        STRIDE.0,
        SPEED.0,
        DIRECTION.0,
        TURN.0,
        STEP_HEIGHT.0,
        SWAY.0,
        BOUNCE.0,
        ROTATION.0,
        ARM_SWING.0,
        super::WEIGHTING.0,
        STAIR_RISE.0,
        STAIR_RUN.0,
        STAIR_START.0,
    ],
    writes_files: false,
    version: 2,
};

fn leg_json(leg: &LegReport) -> serde_json::Value {
    json!({
        "stride_length_m": leg.stride_length_m,
        "step_length_m": leg.step_length_m,
        "swing_secs": leg.swing_secs,
        "footfalls": leg.footfalls,
        "max_knee_flexion_rad": leg.max_knee_flexion_rad,
        "swing_knee_range_rad": leg.swing_knee_range_rad,
        "stride_scale": leg.params.stride_scale,
        "height_scale": leg.params.height_scale,
        "swing_speed_scale": leg.params.swing_speed_scale,
        "hip_weight": leg.params.hip_weight,
        "knee_weight": leg.params.knee_weight,
        "ankle_weight": leg.params.ankle_weight,
    })
}

impl Node for ProceduralGait {
    fn schema(&self) -> &'static NodeSchema {
        &PROCEDURAL_GAIT
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let source = ctx.optional_input(&SKELETON_CLIP)?;
        let skeleton = match &source {
            Some(clip) => clip.skeleton().clone(),
            None => Arc::new(mannequin_skeleton().map_err(|e| NodeError::input("clip", e.to_string()))?),
        };
        let preset = ctx.choice(&PRESET)?;
        let mut legs = preset.legs();
        parse_leg_overrides(ctx.text_param(&LEGS)?, &mut legs).map_err(|e| NodeError::param("legs", e))?;
        let params = GaitParams {
            fps: ctx.float(&FPS)?,
            duration_secs: ctx.float(&DURATION)?,
            stride_length_m: ctx.float(&STRIDE)?,
            speed_m_per_s: ctx.float(&SPEED)?,
            direction_rad: ctx.float(&DIRECTION)?,
            turn_rate_rad_per_s: ctx.float(&TURN)?,
            step_height_m: ctx.float(&STEP_HEIGHT)?,
            hip_sway_m: ctx.float(&SWAY)?,
            hip_bounce_m: ctx.float(&BOUNCE)?,
            hip_rotation_rad: ctx.float(&ROTATION)?,
            arm_swing_rad: ctx.float(&ARM_SWING)?,
            stair_rise_m: ctx.float(&STAIR_RISE)?,
            stair_run_m: ctx.float(&STAIR_RUN)?,
            stair_start_m: ctx.float(&STAIR_START)?,
            legs,
            solve: SolveParams { weighting: ctx.choice(&super::WEIGHTING)?, ..GaitParams::default().solve },
            ..GaitParams::default()
        };
        let gait = procedural_gait(&skeleton, &params).map_err(|e| match e {
            GaitError::MissingLegs(_) | GaitError::NoToe(_) => NodeError::input("clip", e.to_string()),
            GaitError::Param { name, reason } => NodeError::param(name, reason),
            other => NodeError::input("clip", other.to_string()),
        })?;
        ctx.warn_all(gait.warnings.iter().cloned());
        if gait.report.unconverged_frames > 0 {
            ctx.warn(format!(
                "{} frames did not reach their foot goals (largest miss {:.4} m): the feet are out of reach or limited",
                gait.report.unconverged_frames, gait.report.max_residual_m
            ));
        }
        let r = &gait.report;
        ctx.set_output(
            &REPORT_OUT,
            Arc::new(into_report(json!({
                "preset": preset.name(),
                "left": leg_json(&r.legs[0]),
                "right": leg_json(&r.legs[1]),
                "cadence_steps_per_min": r.cadence_steps_per_min,
                "speed_m_per_s": r.speed_m_per_s,
                "pelvis_height_m": r.pelvis_height_m,
                "pelvis_rise_m": r.pelvis_rise_m,
                "max_residual_m": r.max_residual_m,
                "unconverged_frames": r.unconverged_frames,
            }))),
        );
        ctx.set_output(&CONTACTS_OUT, Arc::new(gait.contacts));
        let mut clip = gait.clip;
        if let Some(source) = &source {
            // Exports write in the connected clip's file unit.
            clip.import_scale = source.import_scale;
        }
        ctx.set_output(&CLIP_OUT, Arc::new(clip));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::ik::Weighting;
    use crate::model::ClipPoses;

    fn mannequin() -> Arc<Skeleton> {
        Arc::new(mannequin_skeleton().unwrap())
    }

    fn walk(skeleton: &Arc<Skeleton>, params: &GaitParams) -> Gait {
        procedural_gait(skeleton, params).unwrap()
    }

    /// Heel and toe tip of leg `side` at `frame`, from the clip's own forward kinematics.
    fn heel_toe(gait: &Gait, poses: &ClipPoses, side: usize, frame: usize) -> (DVec3, DVec3) {
        let leg = &gait.legs[side];
        let ankle = poses.frame(frame)[leg.ankle];
        (ankle.transform_point(leg.heel_in_ankle).as_dvec3(), poses.position(frame, leg.toe).as_dvec3())
    }

    /// Footfalls measured on the clip: (strike time, heel at the middle of the contact).
    fn footfalls(gait: &Gait, poses: &ClipPoses, side: usize) -> Vec<(f64, DVec3)> {
        let fps = gait.clip.fps();
        gait.contacts.feet[side]
            .intervals
            .iter()
            .filter(|r| r.start > 0 && r.end < gait.clip.frame_count())
            .map(|r| (r.start as f64 / fps, heel_toe(gait, poses, side, (r.start + r.end) / 2).0))
            .collect()
    }

    /// Times (s) at which leg `side`'s heel comes down to within 1 mm of its lowest height
    /// over the clip (flat ground) and stays there at least 0.1 s (a heel that grazes the
    /// floor mid-swing has not struck), read from the poses alone.
    fn heel_strikes(gait: &Gait, poses: &ClipPoses, side: usize) -> Vec<f64> {
        let heights: Vec<f64> = (0..gait.clip.frame_count()).map(|f| heel_toe(gait, poses, side, f).0.y).collect();
        let floor = heights.iter().copied().fold(f64::INFINITY, f64::min) + 1e-3;
        let stay = (0.1 * gait.clip.fps()).round() as usize;
        (1..heights.len().saturating_sub(stay))
            .filter(|&f| heights[f - 1] > floor && heights[f..f + stay].iter().all(|&h| h <= floor))
            .map(|f| f as f64 / gait.clip.fps())
            .collect()
    }

    /// Largest knee bend (thigh–shank angle) of leg `side` over the clip, radians.
    fn max_knee_bend(gait: &Gait, poses: &ClipPoses, side: usize) -> f64 {
        let leg = &gait.legs[side];
        (0..gait.clip.frame_count())
            .map(|f| {
                let p = |j: usize| poses.position(f, j).as_dvec3();
                (p(leg.knee) - p(leg.hip)).angle_between(p(leg.ankle) - p(leg.knee))
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn foot_height_curve_is_eq_1_1() {
        // Hand values: 1 − cos x below π, 1 − cos((π + x) / 2) above.
        for (x, want) in [
            (0.0, 0.0),
            (PI / 3.0, 0.5),
            (PI / 2.0, 1.0),
            (PI, 2.0),
            (5.0 * PI / 3.0, 1.5),
            (2.0 * PI, 1.0),
            (7.0 * PI / 3.0, 0.5),
            (3.0 * PI, 0.0),
        ] {
            assert!((foot_height_curve(x) - want).abs() < 1e-12, "Y({x}) = {} vs {want}", foot_height_curve(x));
        }
        // Continuous at π, and the peak is 2 there.
        let e = 1e-9;
        assert!((foot_height_curve(PI - e) - foot_height_curve(PI + e)).abs() < 1e-8);
        let (peak_x, peak) = (0..=30_000)
            .map(|i| SWING_CYCLE * i as f64 / 30_000.0)
            .map(|x| (x, foot_height_curve(x)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!((peak - 2.0).abs() < 1e-12 && (peak_x - PI).abs() < 1e-3, "peak {peak} at {peak_x}");
        assert!(foot_height_curve(SWING_CYCLE).abs() < 1e-12);
    }

    #[test]
    fn a_normal_walk_meets_its_parameters() {
        let params = GaitParams { fps: 60.0, duration_secs: 5.0, ..GaitParams::default() };
        let gait = walk(&mannequin(), &params);
        let poses = forward_kinematics(&gait.clip);
        let r = &gait.report;
        println!(
            "normal: residual {:.2e} m, unconverged {}, pelvis {:.3} m, cadence {:.1}/min, report strides {:.4} {:.4}",
            r.max_residual_m,
            r.unconverged_frames,
            r.pelvis_height_m,
            r.cadence_steps_per_min,
            r.legs[0].stride_length_m,
            r.legs[1].stride_length_m
        );
        assert!(r.max_residual_m < 1e-3, "{r:?}");
        // Two footfalls per stride time (stride / speed), measured on the clip: each heel's
        // strikes are the frames it comes down to within 1 mm of the floor it walks on.
        let cadence = 120.0 * params.speed_m_per_s / params.stride_length_m;
        let (mut strides, mut stride_secs) = (0, 0.0);
        for side in 0..2 {
            let strikes = heel_strikes(&gait, &poses, side);
            strides += strikes.len() - 1;
            stride_secs += strikes[strikes.len() - 1] - strikes[0];
        }
        let measured = 120.0 * strides as f64 / stride_secs;
        println!(
            "cadence: {measured:.2}/min measured, {cadence:.2} from stride and speed, report {:.2}",
            r.cadence_steps_per_min
        );
        // Strikes fall on frames: 1/60 s in a span of several strides.
        assert!((measured - cadence).abs() < 0.01 * cadence, "{measured} vs {cadence}");
        assert!(
            (r.cadence_steps_per_min - measured).abs() < 0.01 * cadence,
            "{} vs {measured}",
            r.cadence_steps_per_min
        );
        for side in 0..2 {
            let falls = footfalls(&gait, &poses, side);
            assert!(falls.len() >= 3, "{falls:?}");
            let strides: Vec<f64> = falls.windows(2).map(|w| (w[1].1 - w[0].1).with_y(0.0).length()).collect();
            let first = falls.first().unwrap();
            let last = falls.last().unwrap();
            let speed = (last.1 - first.1).with_y(0.0).length() / (last.0 - first.0);
            println!("side {side}: strides {strides:.4?} m, speed {speed:.4} m/s");
            for s in &strides {
                assert!((s - params.stride_length_m).abs() < 0.005, "stride {s}");
            }
            // Strike times are sampled to a frame: 1/60 s over the span.
            assert!((speed - params.speed_m_per_s).abs() < 0.02, "speed {speed}");
            // Planted points do not slide: while the heel (toe) is on the ground its
            // horizontal place does not change.
            let mut drift = 0.0f64;
            let mut peak_error = 0.0f64;
            for r in &gait.contacts.feet[side].intervals {
                let frames: Vec<(DVec3, DVec3)> = (r.start..r.end).map(|f| heel_toe(&gait, &poses, side, f)).collect();
                for pick in [0, 1] {
                    let point = |p: &(DVec3, DVec3)| if pick == 0 { p.0 } else { p.1 };
                    let ground = frames.iter().map(|p| point(p).y).fold(f64::INFINITY, f64::min);
                    let down: Vec<DVec3> = frames.iter().map(point).filter(|p| p.y < ground + 1e-3).collect();
                    for p in &down {
                        drift = drift.max((*p - down[0]).with_y(0.0).length());
                    }
                }
            }
            // Swing peaks: the toe tip's highest point between two contacts.
            for w in gait.contacts.feet[side].intervals.windows(2) {
                if w[0].end == 0 || w[1].start >= gait.clip.frame_count() {
                    continue;
                }
                let ground = heel_toe(&gait, &poses, side, w[0].end - 1).1.y;
                let top = (w[0].end..w[1].start).map(|f| heel_toe(&gait, &poses, side, f).1.y).fold(0.0, f64::max);
                peak_error = peak_error.max((top - ground - params.step_height_m).abs());
            }
            println!("side {side}: stance drift {:.3} mm, swing peak error {:.2} mm", drift * 1e3, peak_error * 1e3);
            assert!(drift < 1e-3, "drift {drift} m");
            assert!(peak_error < 2e-3, "peak error {peak_error} m");
        }
    }

    /// Step lengths measured on the clip: how far each footfall of `side` lands ahead of the
    /// other foot's previous footfall, along +Z (the walk goes straight along +Z).
    fn steps(gait: &Gait, poses: &ClipPoses, side: usize) -> Vec<f64> {
        let other = footfalls(gait, poses, 1 - side);
        footfalls(gait, poses, side)
            .iter()
            .filter_map(|(t, heel)| other.iter().rev().find(|o| o.0 < *t).map(|o| heel.z - o.1.z))
            .collect()
    }

    /// Air times of `side`: frames between successive contacts, in seconds.
    fn swing_secs(gait: &Gait, side: usize) -> Vec<f64> {
        let fps = gait.clip.fps();
        gait.contacts.feet[side].intervals.windows(2).map(|w| (w[1].start - w[0].end) as f64 / fps).collect()
    }

    #[test]
    fn the_injured_preset_limps_on_the_left() {
        let skeleton = mannequin();
        let base = GaitParams { fps: 60.0, duration_secs: 6.0, ..GaitParams::default() };
        let normal = walk(&skeleton, &base);
        let injured = walk(&skeleton, &GaitParams { legs: GaitPreset::InjuredLeftLeg.legs(), ..base });
        // The same control changes without the stiff knee: what the weight alone does.
        let limp_legs = [LegParams { knee_weight: 1.0, ..GaitPreset::InjuredLeftLeg.legs()[0] }, LegParams::default()];
        let limp = walk(&skeleton, &GaitParams { legs: limp_legs, ..base });
        let (pn, pi, pl) =
            (forward_kinematics(&normal.clip), forward_kinematics(&injured.clip), forward_kinematics(&limp.clip));
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (left_step, right_step) = (mean(&steps(&injured, &pi, 0)), mean(&steps(&injured, &pi, 1)));
        let (left_air, right_air) = (mean(&swing_secs(&injured, 0)), mean(&swing_secs(&injured, 1)));
        let bends = [
            (max_knee_bend(&normal, &pn, 0), max_knee_bend(&normal, &pn, 1)),
            (max_knee_bend(&limp, &pl, 0), max_knee_bend(&limp, &pl, 1)),
            (max_knee_bend(&injured, &pi, 0), max_knee_bend(&injured, &pi, 1)),
        ];
        println!(
            "injured: left step {left_step:.4} m, right step {right_step:.4} m (ratio {:.3}); air left {left_air:.3} s, right {right_air:.3} s (ratio {:.3})",
            left_step / right_step,
            left_air / right_air
        );
        println!(
            "max knee bend (left, right) rad: normal {:.3?}, limp with free knee {:.3?}, injured (knee weight 0.1) {:.3?}",
            bends[0], bends[1], bends[2]
        );
        println!(
            "residuals: normal {:.2e}, limp {:.2e}, injured {:.2e} m",
            normal.report.max_residual_m, limp.report.max_residual_m, injured.report.max_residual_m
        );
        // Left step half the right one (sampling: footfalls are measured exactly, not framed).
        assert!((left_step / right_step - 0.5).abs() < 0.02, "{left_step} / {right_step}");
        assert!((right_step - base.stride_length_m / 2.0).abs() < 0.005, "{right_step}");
        // Speed by hand: both steps per cycle of two double supports (0.2 · T / 2 each) and the
        // two swings (0.4 · T, the left one ÷ 1.3), T = stride / speed.
        let t = base.stride_length_m / base.speed_m_per_s;
        let speed = (0.5 + 1.0) * base.stride_length_m / 2.0 / (0.2 * t + 0.4 * t / 1.3 + 0.4 * t);
        // The report measures the strikes on the clip, to a frame: within 0.5 %.
        assert!(
            (injured.report.speed_m_per_s - speed).abs() < 5e-3 * speed,
            "{} vs {speed}",
            injured.report.speed_m_per_s
        );
        // The left swing 30 % faster: air time ÷ 1.3, to a frame.
        assert!((left_air - right_air / 1.3).abs() < 1.5 / base.fps, "{left_air} vs {right_air}");
        // The stiff knee bends measurably less than the free one with the same control, and
        // less than in the normal walk.
        assert!(bends[2].0 < bends[1].0 - 0.02, "{bends:?}");
        assert!(bends[2].0 < bends[0].0 - 0.1, "{bends:?}");
        assert!(injured.report.max_residual_m < 1e-3, "{:?}", injured.report);
    }

    /// The stiff knee of the limp (knee weight 0.1) bends less than the same limp's free
    /// knee under both weightings: inside the pseudo-inverse and the paper's eq. 1.6; and
    /// both walks hold their planted feet (the solves converge).
    #[test]
    fn the_stiff_knee_bends_less_under_both_weightings() {
        let skeleton = mannequin();
        for weighting in [Weighting::InsideInverse, Weighting::Paper] {
            let base = GaitParams {
                fps: 60.0,
                duration_secs: 4.0,
                solve: SolveParams { weighting, ..GaitParams::default().solve },
                ..GaitParams::default()
            };
            let stiff = walk(&skeleton, &GaitParams { legs: GaitPreset::InjuredLeftLeg.legs(), ..base });
            let free_legs =
                [LegParams { knee_weight: 1.0, ..GaitPreset::InjuredLeftLeg.legs()[0] }, LegParams::default()];
            let free = walk(&skeleton, &GaitParams { legs: free_legs, ..base });
            let (bend_stiff, bend_free) = (
                max_knee_bend(&stiff, &forward_kinematics(&stiff.clip), 0),
                max_knee_bend(&free, &forward_kinematics(&free.clip), 0),
            );
            println!(
                "{weighting:?}: left knee bends at most {bend_stiff:.3} rad stiff, {bend_free:.3} free; residual {:.2e} m, unconverged {}",
                stiff.report.max_residual_m, stiff.report.unconverged_frames
            );
            assert!(bend_stiff < bend_free - 0.02, "{weighting:?}: {bend_stiff} vs {bend_free}");
            assert!(stiff.report.max_residual_m < 1e-3, "{weighting:?}: {:?}", stiff.report);
        }
    }

    /// Meredith & Maddock's hip swing and a human walk's shape, read from the poses of the
    /// normal walk after its first step: the pelvis rises and falls by the bounce (2–5 cm,
    /// the default 3 cm), the knee is nearly straight at each heel strike (under 15°; the
    /// legs are stretched to `REACH` at the double supports), the pelvis turns about the
    /// vertical by the rotation each way while the chest keeps facing the path, and each hand
    /// swings forward and back, against its own side's leg.
    #[test]
    fn the_walk_bounces_straightens_its_knees_and_swings_hips_and_arms() {
        let params = GaitParams { fps: 60.0, duration_secs: 5.0, ..GaitParams::default() };
        let skeleton = mannequin();
        let gait = walk(&skeleton, &params);
        let poses = forward_kinematics(&gait.clip);
        let index = |name: &str| skeleton.index_of(name).unwrap();
        let settled = (params.fps * 1.0) as usize..gait.clip.frame_count();
        let hips: Vec<f64> = settled.clone().map(|f| f64::from(poses.position(f, 0).y)).collect();
        let bounce = hips.iter().copied().fold(f64::MIN, f64::max) - hips.iter().copied().fold(f64::MAX, f64::min);
        let mut knee_at_strikes = Vec::new();
        for side in 0..2 {
            let leg = &gait.legs[side];
            for t in heel_strikes(&gait, &poses, side) {
                let f = (t * params.fps).round() as usize;
                if settled.contains(&f) {
                    let p = |j: usize| poses.position(f, j).as_dvec3();
                    knee_at_strikes.push((p(leg.knee) - p(leg.hip)).angle_between(p(leg.ankle) - p(leg.knee)));
                }
            }
        }
        let yaw = |f: usize, j: usize| {
            let z = poses.frame(f)[j].rotation.as_dquat() * DVec3::Z;
            z.x.atan2(z.z)
        };
        let (root_turn, chest_turn) = settled
            .clone()
            .fold((0.0f64, 0.0f64), |(r, c), f| (r.max(yaw(f, 0).abs()), c.max(yaw(f, index("Spine")).abs())));
        // Hands forward of the pelvis along the walk (+Z), and the legs' ankles.
        let ahead = |f: usize, j: usize| f64::from(poses.position(f, j).z - poses.position(f, 0).z);
        let (left_hand, right_ankle) = (index("LeftHand"), gait.legs[1].ankle);
        let swing = settled.clone().map(|f| ahead(f, left_hand)).fold(f64::MIN, f64::max)
            - settled.clone().map(|f| ahead(f, left_hand)).fold(f64::MAX, f64::min);
        // The left hand is ahead when the right foot is ahead: their forward offsets correlate.
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (h, a): (Vec<f64>, Vec<f64>) =
            settled.clone().map(|f| (ahead(f, left_hand), ahead(f, right_ankle))).unzip();
        let (mh, ma) = (mean(&h), mean(&a));
        let covariance: f64 = h.iter().zip(&a).map(|(x, y)| (x - mh) * (y - ma)).sum();
        println!(
            "bounce {:.2} cm, knee at strikes {:?} deg, pelvis turn {root_turn:.3} rad, chest {chest_turn:.4} rad, left hand swing {:.1} cm",
            bounce * 100.0,
            knee_at_strikes.iter().map(|k| (k.to_degrees() * 10.0).round() / 10.0).collect::<Vec<_>>(),
            swing * 100.0
        );
        assert!((0.02..=0.05).contains(&bounce), "bounce {bounce} m");
        assert!(
            knee_at_strikes.len() >= 4 && knee_at_strikes.iter().all(|k| k.to_degrees() < 15.0),
            "{knee_at_strikes:?}"
        );
        assert!((root_turn - params.hip_rotation_rad).abs() < 0.01, "pelvis turns {root_turn}");
        assert!(chest_turn < 0.005, "the chest turns {chest_turn}");
        assert!(swing > 0.1, "the left hand swings {swing} m");
        assert!(covariance > 0.0, "the left hand moves with the left foot: {covariance}");
    }

    #[test]
    fn the_other_presets_change_what_they_name() {
        let skeleton = mannequin();
        let base = GaitParams { fps: 60.0, duration_secs: 4.0, ..GaitParams::default() };
        let normal = walk(&skeleton, &base);
        let individual = walk(&skeleton, &GaitParams { legs: GaitPreset::Individual.legs(), ..base });
        let hip = walk(&skeleton, &GaitParams { legs: GaitPreset::HipInjury.legs(), ..base });
        let limp_legs = [LegParams { hip_weight: 1.0, ..GaitPreset::HipInjury.legs()[0] }, LegParams::default()];
        let limp = walk(&skeleton, &GaitParams { legs: limp_legs, ..base });
        // Hip flexion (thigh from vertical) range of the left leg over the walk.
        let hip_swing = |g: &Gait| {
            let poses = forward_kinematics(&g.clip);
            let leg = &g.legs[0];
            let angles: Vec<f64> = (0..g.clip.frame_count())
                .map(|f| {
                    let thigh = poses.position(f, leg.knee).as_dvec3() - poses.position(f, leg.hip).as_dvec3();
                    thigh.z.atan2(-thigh.y)
                })
                .collect();
            angles.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - angles.iter().copied().fold(f64::INFINITY, f64::min)
        };
        let (n, i, l, h) = (hip_swing(&normal), hip_swing(&individual), hip_swing(&limp), hip_swing(&hip));
        println!("left hip swing range rad: normal {n:.4}, individual {i:.4}, limp free hip {l:.4}, hip injury {h:.4}");
        let knee = |g: &Gait| max_knee_bend(g, &forward_kinematics(&g.clip), 0);
        println!(
            "left knee max bend rad: normal {:.4}, individual {:.4}, limp {:.4}, hip injury {:.4}",
            knee(&normal),
            knee(&individual),
            knee(&limp),
            knee(&hip)
        );
        assert!(i < n, "individual {i} vs normal {n}");
        assert!(h < l, "hip injury {h} vs limp {l}");
        for g in [&individual, &hip] {
            assert!(g.report.max_residual_m < 1e-3, "{:?}", g.report);
        }
    }

    #[test]
    fn turning_changes_the_heading_by_rate_times_duration() {
        let params =
            GaitParams { turn_rate_rad_per_s: 0.3, direction_rad: 0.2, duration_secs: 4.0, ..GaitParams::default() };
        let gait = walk(&mannequin(), &params);
        let last = gait.clip.frame_count() - 1;
        // The mannequin faces +Z: the heading is the yaw of the spine's +Z axis (the pelvis
        // swings about it; the chest keeps facing the path).
        let poses = forward_kinematics(&gait.clip);
        let spine = gait.clip.skeleton().index_of("Spine").unwrap();
        let heading = |f: usize| {
            let z = poses.frame(f)[spine].rotation.as_dquat() * DVec3::Z;
            z.x.atan2(z.z)
        };
        let turned = heading(last) - heading(0);
        println!(
            "turned {turned:.4} rad in {} s (want {:.4}), start heading {:.4}",
            params.duration_secs,
            0.3 * params.duration_secs,
            heading(0)
        );
        assert!((turned - params.turn_rate_rad_per_s * params.duration_secs).abs() < 0.01, "{turned}");
        assert!(gait.report.max_residual_m < 1e-3, "{:?}", gait.report);
    }

    #[test]
    fn footfalls_land_on_the_stairs() {
        let skeleton = mannequin();
        // Foot length: heel (under the ankle) to toe tip along +Z in the rest pose.
        let rest = skeleton.rest_positions();
        for rise in [0.15, -0.15] {
            let params = GaitParams {
                stair_rise_m: rise,
                stair_run_m: 0.65,
                stair_start_m: 1.0,
                step_height_m: 0.12,
                duration_secs: 5.0,
                fps: 60.0,
                ..GaitParams::default()
            };
            let gait = walk(&skeleton, &params);
            let poses = forward_kinematics(&gait.clip);
            let mut checked = 0;
            for side in 0..2 {
                let foot_length = f64::from(rest[gait.legs[side].toe].z - rest[gait.legs[side].ankle].z);
                for (_, heel) in footfalls(&gait, &poses, side) {
                    // The stair under the middle of the foot, by hand: `rise` per 0.65 m from 1 m.
                    let s = heel.z + foot_length / 2.0;
                    let want = if s < 1.0 { 0.0 } else { rise * (((s - 1.0) / 0.65).floor() + 1.0) };
                    assert!(
                        (heel.y - want).abs() < 1e-3,
                        "heel at z {:.3}: height {:.4} vs stair {want}",
                        heel.z,
                        heel.y
                    );
                    checked += usize::from(want != 0.0);
                }
                // The foot never goes below the lower of the two treads it moves between: the
                // toe's height at toe-off and the heel's at the next heel strike.
                let last = gait.clip.frame_count() - 1;
                for r in gait.contacts.feet[side].intervals.windows(2).filter(|r| r[1].start <= last) {
                    let from = heel_toe(&gait, &poses, side, r[0].end - 1).1.y;
                    let floor = from.min(heel_toe(&gait, &poses, side, r[1].start).0.y);
                    for f in r[0].end..r[1].start {
                        let (heel, toe) = heel_toe(&gait, &poses, side, f);
                        assert!(heel.y > floor - 2e-3 && toe.y > floor - 2e-3, "frame {f}: {heel} {toe} floor {floor}");
                    }
                }
            }
            println!("stairs {rise:+} m: {checked} footfalls on stairs, residual {:.2e} m", gait.report.max_residual_m);
            assert!(checked >= 4);
            assert!(gait.report.max_residual_m < 1e-3, "{:?}", gait.report);
        }
    }

    #[test]
    fn standing_and_bad_input_give_a_still_clip_or_a_typed_error() {
        let skeleton = mannequin();
        for params in [
            GaitParams { speed_m_per_s: 0.0, ..GaitParams::default() },
            GaitParams { stride_length_m: 0.0, ..GaitParams::default() },
        ] {
            let gait = walk(&skeleton, &params);
            assert!(!gait.warnings.is_empty());
            let first = gait.clip.frame_translations(0)[0];
            for f in 0..gait.clip.frame_count() {
                assert!(gait.clip.frame_rotations(f).iter().all(|q| q.is_finite()));
                assert!((gait.clip.frame_translations(f)[0] - first).length() < 1e-6);
            }
            assert!(
                gait.contacts.feet.iter().all(|c| c.intervals == vec![FrameRange::new(0, gait.clip.frame_count())])
            );
            assert!(gait.report.max_residual_m < 1e-3 && gait.report.speed_m_per_s == 0.0, "{:?}", gait.report);
        }
        // No legs: an arm only.
        let arm = Arc::new(
            Skeleton::new(vec![
                Joint::new("Chest", None, Vec3::new(0.0, 1.4, 0.0)),
                Joint::new("LeftArm", Some(0), Vec3::new(0.2, 0.0, 0.0)),
                Joint::new("LeftHand", Some(1), Vec3::new(0.5, 0.0, 0.0)),
            ])
            .unwrap(),
        );
        match procedural_gait(&arm, &GaitParams::default()) {
            Err(GaitError::MissingLegs(m)) => assert!(m.contains("left thigh") && m.contains("right foot"), "{m}"),
            other => panic!("{other:?}"),
        }
        let bad = GaitParams { speed_m_per_s: f64::NAN, ..GaitParams::default() };
        assert!(matches!(procedural_gait(&skeleton, &bad), Err(GaitError::Param { name: "speed_m_per_s", .. })));
        let mut legs = [LegParams::default(); 2];
        assert!(parse_leg_overrides("left.knee=0.3, right.stride=0.8", &mut legs).is_ok());
        assert_eq!((legs[0].knee_weight, legs[1].stride_scale), (0.3, 0.8));
        assert!(parse_leg_overrides("middle.knee=1", &mut legs).is_err());
        let bad_weight =
            GaitParams { legs: [LegParams { knee_weight: 1.5, ..LegParams::default() }; 2], ..GaitParams::default() };
        assert!(matches!(procedural_gait(&skeleton, &bad_weight), Err(GaitError::Param { name: "legs", .. })));
    }

    #[test]
    fn a_cmu_skeleton_walks() {
        let Some(data) = crate::corpus::shared_data() else { return };
        let path = data.join("bvh/cmu/02_01.bvh");
        let loaded = crate::formats::bvh::read_bvh_file(&path, Default::default()).unwrap();
        let skeleton = loaded.value.0.skeleton().clone();
        let params = GaitParams { fps: 60.0, duration_secs: 4.0, ..GaitParams::default() };
        let gait = walk(&skeleton, &params);
        let poses = forward_kinematics(&gait.clip);
        let names: Vec<&str> = gait
            .legs
            .iter()
            .flat_map(|l| [l.hip, l.knee, l.ankle, l.toe])
            .map(|j| skeleton.joints()[j].name.as_str())
            .collect();
        println!("cmu legs {names:?}, report {:?}", gait.report);
        assert!(gait.report.max_residual_m < 1e-3, "{:?}", gait.report);
        for side in 0..2 {
            let falls = footfalls(&gait, &poses, side);
            for w in falls.windows(2) {
                let stride = (w[1].1 - w[0].1).with_y(0.0).length();
                assert!((stride - params.stride_length_m).abs() < 0.005, "stride {stride}");
            }
            assert!(falls.len() >= 2);
        }
        let knee = max_knee_bend(&gait, &poses, 0);
        assert!(knee > 0.3 && knee < 1.6, "knee bend {knee}");
    }
}
