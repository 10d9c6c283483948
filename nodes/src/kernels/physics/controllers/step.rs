//! Protective step: when a push moves the capture point out of the support polygon but
//! within a step's reach, swing a foot to it (the LIPM result: with its pivot at the
//! capture point the COM comes to rest above it), then close the trailing foot up beside it
//! so balance takes over on two feet side by side (holding the split stance, balance held
//! the figure after none of 30 pushes; 29 of them ended in a fall).
//!
//! The swing foot is the one on the capture point's side (no crossover steps). Its sole
//! follows a smoothstep from where it was to [`BEYOND_M`] past the capture point predicted
//! for its landing ([`step_target`]; re-aimed for most of the swing) over [`SWING_SECS`], lifted by
//! `LIFT_M·sin(π·s)`; the leg's hip and knee angles come from the two-link inverse
//! kinematics of the thigh and shank lengths, the knee pointing forward. The stance hip
//! keeps the pelvis upright over the stance thigh as it was at the start, yielding
//! ([`STANCE_HIP_GAIN`]); both feet are kept level. The step is planned in the frame the
//! figure faced when it started: the swing leg's reaction yaws a figure on one gripping foot
//! by 20–30°, and re-reading the facing every step swung the no-crossover line and the knee's
//! direction with it (the CMU foot landed 10 cm short of the capture point). Once the
//! catching foot lands, the trailing foot swings the same way to where the capture point
//! is midway between the soles ([`beside`]); meanwhile the catching leg is the stance, its
//! knee kept bent as it landed (bent further if the closing foot hovers), its hip yielding
//! ([`CLOSE_HIP_GAIN`]) and its ankle leaning the shank away from the capture point's
//! offset from the sole, as balance's ankles do.
//!
//! Pre-condition: a foot down, trunk within 35° of vertical, COM at least 75 % of its
//! standing height, capture point outside the support, and the capture point predicted for
//! the landing ([`predicted_capture`]) within [`REACH`] leg lengths of the stance sole (a
//! push that will carry it farther is a fall, not a step). Post-condition: both swings
//! done (each foot, once lifted, down again after half its swing, the closing one near its
//! target) with the capture point within [`LAND_MARGIN_M`] of the support. Expected
//! performance: the predicted capture point stays within reach while the target follows
//! it, each foot lands within [`TIMEOUT_SECS`] and the trunk stays within 50° of vertical.

use glam::{Quat, Vec2, Vec3};

use super::balance::{K_ANKLE, MAX_ANKLE_RAD, lean_away};
use super::{facing, leg, xz};
use crate::kernels::physics::controller::{BID_CAN_REACH, ControlContext, Controller, Status, Targets};
use crate::kernels::physics::state::FigureState;
use crate::math::smoothstep;

/// Swing duration, seconds.
pub const SWING_SECS: f32 = 0.35;
/// Swing foot clearance at mid-swing, metres.
pub const LIFT_M: f32 = 0.15;
/// Farthest step, in leg lengths from the stance sole to the capture point.
pub const REACH: f32 = 0.9;
/// Capture point tolerance outside the new support at landing, metres: balance's entry
/// margin, so the step's post-condition is inside balance's pre-condition.
pub const LAND_MARGIN_M: f32 = crate::kernels::physics::controllers::balance::ENTER_OUTSIDE_M;
/// The step fails when the foot is not down after this long, seconds.
pub const TIMEOUT_SECS: f32 = 0.8;
/// When the swing foot lands after the step starts, seconds: its path ends at
/// `SWING_SECS`, read [`LEAD_SECS`] ahead.
pub const LAND_SECS: f32 = SWING_SECS - LEAD_SECS;
/// Closest the swing sole may land to the stance sole, sideways, metres.
pub const MIN_WIDTH_M: f32 = 0.12;
/// Gain multiplier on the swing leg's joints, so the foot tracks its path in time.
pub const SWING_GAIN: f32 = 3.0;
/// Gain multiplier on the stance hip. At full stiffness the hip fought the trunk's pitch
/// after a chest push, and its reaction slid the gripping stance foot 11 cm back and out
/// within 0.1 s; yielding, it slides 3 cm (CMU, 45 N·s forward, 4 contact passes).
pub const STANCE_HIP_GAIN: f32 = 0.25;
/// The swing path is read this far ahead, seconds: the PD motors follow their targets
/// with a lag of about kd/kp (≈ 0.07 s for the leg gains), which this compensates.
pub const LEAD_SECS: f32 = 0.1;
/// The target follows the capture point during this share of the swing.
pub const RETARGET_UNTIL: f32 = 0.7;
/// The swing foot counts as lifted once its sole centre is this high, metres.
pub const LIFTED_M: f32 = 0.025;
/// The catching foot is aimed this far beyond the predicted capture point, away from the
/// stance sole, metres. When it lands the trailing foot still carries weight, so the centre
/// of pressure lies between the feet, behind the catching sole; a capture point under that
/// sole ran on past it and the figure had to step again. Landing beyond it leaves the
/// capture point between the feet, where the closing swing can keep it (physics_controllers'
/// stand-again test, 30 pushes with 4 contact passes: aimed 3 cm beyond, 5 figures stand
/// again; 9 cm, 10).
pub const BEYOND_M: f32 = 0.09;
/// Stance hip gain multiplier while the trailing foot closes up: the pelvis is held over
/// the catching thigh as it landed, softly enough to roll over it.
pub const CLOSE_HIP_GAIN: f32 = 0.5;
/// Once its path has ended, the closing foot is let down by bending the catching knee this
/// much per metre the closing sole still hovers, rad/m (up to [`MAX_KNEE_LOWER_RAD`]): with
/// the pelvis tilted up on the swing side a straight swing leg stops 2–4 cm short of the
/// ground, on its toes.
pub const KNEE_LOWER_RAD_PER_M: f32 = 15.0;
/// Most the catching knee bends to let the closing foot down, radians.
pub const MAX_KNEE_LOWER_RAD: f32 = 0.4;
/// The closing foot has landed once its sole centre is within this of its target
/// horizontally (or its path has ended), metres.
pub const CLOSE_LANDED_M: f32 = 0.04;
/// The closing foot goes at most this much wider than the feet stood, metres.
pub const MAX_WIDEN_M: f32 = 0.1;

/// The protective step controller.
#[derive(Default)]
pub struct Step {
    plan: Option<Plan>,
}

#[derive(Clone, Copy, Debug)]
struct Plan {
    start_secs: f32,
    swing: usize,
    from: Vec3,
    to: Vec3,
    /// The swing foot has left the ground.
    lifted: bool,
    /// The stance thigh's world rotation (relative to rest) when this swing started: the
    /// stance hip holds the pelvis upright above it.
    stance_thigh: Quat,
    /// The figure's facing (forward, left) when the step started: the frame the step is
    /// planned in (see the module's doc).
    frame: (Vec3, Vec3),
    /// How far apart sideways the soles stood when the step started, metres: the width the
    /// closing swing restores.
    width_m: f32,
    /// Set once the catching foot has landed and the trailing foot swings up beside it.
    closing: Option<Closing>,
}

/// The catching leg when the closing swing started: its knee's joint angles, and its
/// shank's and foot's world rotations (relative to rest).
#[derive(Clone, Copy, Debug)]
struct Closing {
    knee: [f32; 3],
    shank: Quat,
    foot: Quat,
}

/// The stance foot a step would pivot on, given the capture point: the foot away from ξ's
/// side, and the swing foot towards it. Returns (swing, stance).
pub fn choose_feet(state: &FigureState, ctx: &ControlContext<'_>) -> (usize, usize) {
    let (_, left) = facing(state, ctx);
    let mid = (state.sole_centre[0] + state.sole_centre[1]) * 0.5;
    let side = xz(state.capture_point).dot(left) - mid.with_y(0.0).dot(left);
    // Which sole is on the figure's left right now (side 0 is the left leg).
    let zero_is_left = (state.sole_centre[0] - state.sole_centre[1]).dot(left) >= 0.0;
    let swing = if (side >= 0.0) == zero_is_left { 0 } else { 1 };
    (swing, 1 - swing)
}

/// The capture point `remaining_secs` from now while the figure pivots on the stance
/// sole's centre `p`: `ξ(t) = p + (ξ₀ − p)·e^{ω t}`, `ω = √(g/h)` at the COM height `h`.
pub fn predicted_capture(state: &FigureState, ctx: &ControlContext<'_>, stance: usize, remaining_secs: f32) -> Vec2 {
    let stance_xz = state.sole_xz(stance);
    let omega = (ctx.gravity_m_s2 / state.com.y.max(0.1)).sqrt();
    stance_xz + (state.capture_point - stance_xz) * (omega * remaining_secs.max(0.0)).exp()
}

/// Where the swing sole is put: on `landing`, the capture point the figure will have when
/// the foot lands ([`predicted_capture`]; while it swings the figure is a linear inverted
/// pendulum pivoting on the stance sole). A sole centred there holds the capture point under
/// the foot when it lands, so the COM comes to rest over the new support (the capture
/// point's defining property). Never closer than [`MIN_WIDTH_M`] sideways to the stance sole
/// (no crossover) along `left`, and within [`REACH`] leg lengths of it.
pub fn step_target(
    state: &FigureState,
    ctx: &ControlContext<'_>,
    left: Vec3,
    (swing, stance): (usize, usize),
    landing: Vec2,
) -> Vec2 {
    let stance_xz = state.sole_xz(stance);
    let mut t = landing;
    let l = Vec2::new(left.x, left.z);
    let sign = side_of(state, left, (swing, stance));
    let width = (t - stance_xz).dot(l) * sign;
    if width < MIN_WIDTH_M {
        t += l * sign * (MIN_WIDTH_M - width);
    }
    let reach = REACH * ctx.leg_length_m;
    let d = t - stance_xz;
    if d.length() > reach { stance_xz + d * (reach / d.length()) } else { t }
}

/// +1 when the `swing` sole is on the `left` side of the `stance` sole, −1 otherwise.
fn side_of(state: &FigureState, left: Vec3, (swing, stance): (usize, usize)) -> f32 {
    if (state.sole_centre[swing] - state.sole_centre[stance]).dot(left) >= 0.0 { 1.0 } else { -1.0 }
}

/// Where the swing sole goes, given the capture point predicted for its landing: the
/// catching foot [`BEYOND_M`] past it, away from the stance sole; the closing foot
/// [`beside`] the catching one; both within [`step_target`]'s limits. At the stance sole's
/// height.
fn swing_target(state: &FigureState, ctx: &ControlContext<'_>, plan: &Plan, landing: Vec2) -> Vec3 {
    let stance = 1 - plan.swing;
    let aim = if plan.closing.is_some() {
        beside(state, plan, landing)
    } else {
        landing + (landing - state.sole_xz(stance)).normalize_or_zero() * BEYOND_M
    };
    let to = step_target(state, ctx, plan.frame.1, (plan.swing, stance), aim);
    Vec3::new(to.x, plan.from.y, to.y)
}

/// Where the closing swing puts the trailing sole: so that the capture point predicted for
/// its landing (`landing`) is midway between the two soles, but no narrower than the feet
/// stood and at most [`MAX_WIDEN_M`] wider (the no-crossover and reach limits of
/// [`step_target`] follow).
fn beside(state: &FigureState, plan: &Plan, landing: Vec2) -> Vec2 {
    let caught = state.sole_xz(1 - plan.swing);
    let (f, l) = (Vec2::new(plan.frame.0.x, plan.frame.0.z), Vec2::new(plan.frame.1.x, plan.frame.1.z));
    let sign = side_of(state, plan.frame.1, (plan.swing, 1 - plan.swing));
    let d = landing - caught;
    let width = (2.0 * d.dot(l) * sign).clamp(plan.width_m, plan.width_m + MAX_WIDEN_M);
    caught + l * (sign * width) + f * (2.0 * d.dot(f))
}

/// The closing swing that follows the catching foot's landing: the trailing foot swings,
/// the catching leg becomes the stance.
fn close(state: &FigureState, ctx: &ControlContext<'_>, plan: &Plan) -> Plan {
    let swing = 1 - plan.swing;
    let (thigh, shank, foot) = leg(ctx, plan.swing).unwrap_or_default();
    let from = state.sole_centre[swing];
    let mut next = Plan { swing, ..*plan };
    let to = beside(state, &next, state.capture_point);
    next.start_secs = state.time_secs;
    next.from = from;
    next.to = Vec3::new(to.x, from.y, to.y);
    next.lifted = false;
    next.stance_thigh = state.body_rot[thigh];
    next.closing =
        Some(Closing { knee: state.joint_coords[shank], shank: state.body_rot[shank], foot: state.body_rot[foot] });
    next
}

/// Whether a predicted capture point is farther than a step ([`REACH`] leg lengths) from
/// the `stance` sole.
fn out_of_reach(state: &FigureState, ctx: &ControlContext<'_>, stance: usize, capture: Vec2) -> bool {
    capture.distance(state.sole_xz(stance)) > REACH * ctx.leg_length_m
}

impl Controller for Step {
    fn name(&self) -> &'static str {
        "step"
    }
    fn preference(&self) -> u32 {
        20
    }
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32 {
        if !(state.foot_down[0] || state.foot_down[1])
            || state.trunk_upright < 35f32.to_radians().cos()
            || state.com.y < 0.75 * ctx.standing_com_height_m
            || state.capture_distance_m <= 0.0
        {
            return 0;
        }
        let (_, stance) = choose_feet(state, ctx);
        let landing = predicted_capture(state, ctx, stance, LAND_SECS);
        if out_of_reach(state, ctx, stance, landing) { 0 } else { BID_CAN_REACH }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        let (swing, stance) = choose_feet(state, ctx);
        let from = state.sole_centre[swing];
        let frame = facing(state, ctx);
        let stance_thigh = leg(ctx, stance).map_or(Quat::IDENTITY, |(t, _, _)| state.body_rot[t]);
        let mut plan = Plan {
            start_secs: state.time_secs,
            swing,
            from,
            to: from,
            lifted: false,
            stance_thigh,
            frame,
            width_m: (state.sole_centre[swing] - state.sole_centre[stance]).dot(frame.1).abs(),
            closing: None,
        };
        plan.to = swing_target(state, ctx, &plan, predicted_capture(state, ctx, stance, LAND_SECS));
        self.plan = Some(plan);
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        let Some(plan) = self.plan.as_mut() else { return Status::Failed("not activated".into()) };
        plan.lifted |= !state.foot_down[plan.swing] || state.sole_centre[plan.swing].y > LIFTED_M;
        // The capture point keeps moving while the figure pivots on one foot: follow it
        // until the last part of the swing.
        let tau = state.time_secs - plan.start_secs;
        let stance = 1 - plan.swing;
        if tau < RETARGET_UNTIL * SWING_SECS {
            let landing = predicted_capture(state, ctx, stance, LAND_SECS - tau);
            if out_of_reach(state, ctx, stance, landing) {
                return Status::Failed("the capture point ran out of a step's reach".into());
            }
            plan.to = swing_target(state, ctx, plan, landing);
        }
        if state.trunk_upright < 50f32.to_radians().cos() {
            return Status::Failed("the trunk tilted past 50°".into());
        }
        let on_target = plan.closing.is_none()
            || tau > SWING_SECS - LEAD_SECS
            || (state.sole_centre[plan.swing] - plan.to).with_y(0.0).length() < CLOSE_LANDED_M;
        let landed = state.foot_down[plan.swing] && state.sole_centre[plan.swing].y < 0.5 * LIFTED_M && on_target;
        if plan.lifted && tau > 0.6 * SWING_SECS && landed {
            if state.capture_distance_m >= LAND_MARGIN_M {
                return Status::Failed(format!(
                    "capture point {:.3} m outside the support after the {}",
                    state.capture_distance_m,
                    if plan.closing.is_some() { "closing swing" } else { "step" }
                ));
            }
            if plan.closing.is_some() {
                return Status::Succeeded;
            }
            *plan = close(state, ctx, plan);
        }
        let plan = *plan;
        let tau = state.time_secs - plan.start_secs;
        if tau > TIMEOUT_SECS {
            return Status::Failed("the swing foot did not land".into());
        }
        targets.clone_from(ctx.stand);
        let (Some((thigh, shank, foot)), Some((s_thigh, s_shank, s_foot))) =
            (leg(ctx, plan.swing), leg(ctx, 1 - plan.swing))
        else {
            return Status::Failed("the figure has no legs".into());
        };
        // Sole path: smoothstep in the plane, a sine arch up; aim past the end so the
        // foot is driven down onto the ground.
        let ahead = tau + LEAD_SECS;
        let s = smoothstep(f64::from((ahead / SWING_SECS).min(1.0))) as f32;
        let lift = if ahead < SWING_SECS { LIFT_M * (std::f32::consts::PI * s).sin() } else { -0.03 };
        let sole = plan.from.lerp(plan.to, s) + Vec3::Y * lift;
        // Two-link IK from the hip (the thigh body's origin) to the ankle (the foot's).
        let fig = ctx.figure;
        let rest_sole_to_ankle = state.body_pos[foot] - state.sole_centre[plan.swing];
        let ankle = sole + rest_sole_to_ankle.with_y(rest_sole_to_ankle.y.max(0.0));
        let hip = state.body_pos[thigh];
        let (l1, l2) = (fig.bone_length(thigh), fig.bone_length(shank));
        let d = ankle - hip;
        let reach = d.length().clamp(0.2 * (l1 + l2), 0.999 * (l1 + l2));
        let dir = d.try_normalize().unwrap_or(Vec3::NEG_Y);
        let forward = plan.frame.0;
        let bend = forward.reject_from(dir).try_normalize().unwrap_or(forward);
        let cos_hip = ((l1 * l1 + reach * reach - l2 * l2) / (2.0 * l1 * reach)).clamp(-1.0, 1.0);
        let knee = hip + (dir * cos_hip + bend * (1.0 - cos_hip * cos_hip).sqrt()) * l1;
        let cos_knee = ((l1 * l1 + l2 * l2 - reach * reach) / (2.0 * l1 * l2)).clamp(-1.0, 1.0);
        targets.aim(fig, thigh, state.body_rot[0], knee - hip);
        targets.angles[shank] = [std::f32::consts::PI - cos_knee.acos(), 0.0, 0.0];
        // Level foot: relative to the shank, the inverse of the shank's rotation.
        targets.set_relative(fig, foot, state.body_rot[shank].inverse());
        // Stance leg: the thigh stays where it was when the step started with the pelvis
        // upright above it (the thigh relative to the pelvis is then its world rotation), and
        // the foot stays flat (following the thigh's current rotation let the stance leg
        // splay and roll its foot onto the edge: the CMU stance sole slid 21 cm sideways).
        targets.set_relative(fig, s_thigh, plan.stance_thigh);
        targets.set_relative(fig, s_foot, state.body_rot[s_shank].inverse());
        targets.gain[s_thigh] = STANCE_HIP_GAIN;
        for b in [thigh, shank, foot] {
            targets.gain[b] = SWING_GAIN;
        }
        if let Some(c) = plan.closing {
            // The catching knee stays bent as it landed, and bends further to let the
            // closing foot down once its path has ended.
            targets.angles[s_shank] = c.knee;
            if ahead >= SWING_SECS {
                targets.angles[s_shank][0] +=
                    (KNEE_LOWER_RAD_PER_M * state.sole_centre[plan.swing].y).clamp(0.0, MAX_KNEE_LOWER_RAD);
            }
            targets.gain[s_thigh] = CLOSE_HIP_GAIN;
            // Ankle strategy on the one catching foot, as balance's on two: the shank leans
            // away from the capture point's offset from the sole centre, which moves the
            // centre of pressure towards it.
            let (forward, left) = plan.frame;
            let u = xz(state.capture_point) - state.sole_centre[1 - plan.swing].with_y(0.0);
            let lean = lean_away((u.dot(forward), u.dot(left)), plan.frame, K_ANKLE, 0.0, MAX_ANKLE_RAD);
            targets.set_relative(fig, s_foot, (lean * c.shank).inverse() * c.foot);
        }
        Status::Running
    }
}
