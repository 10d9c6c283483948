//! Protective step: when a push moves the capture point out of the support polygon but
//! within a step's reach, swing a foot to it (the LIPM result: with its pivot at the
//! capture point the COM comes to rest above it).
//!
//! The swing foot is the one on the capture point's side (no crossover steps). Its sole
//! follows a smoothstep from where it was to the capture point predicted for its landing
//! ([`step_target`]; re-aimed for most of the swing) over [`SWING_SECS`], lifted by
//! `LIFT_M·sin(π·s)`; the leg's hip and knee angles come from the two-link inverse
//! kinematics of the thigh and shank lengths, the knee pointing forward. The stance hip
//! keeps the pelvis upright over the stance thigh as it was at the start, yielding
//! ([`STANCE_HIP_GAIN`]); both feet are kept level. The step is planned in the frame the
//! figure faced when it started: the swing leg's reaction yaws a figure on one gripping foot
//! by 20–30°, and re-reading the facing every step swung the no-crossover line and the knee's
//! direction with it (the CMU foot landed 10 cm short of the capture point).
//!
//! Pre-condition: a foot down, trunk within 35° of vertical, COM at least 75 % of its
//! standing height, capture point outside the support, and the capture point predicted for
//! the landing ([`predicted_capture`]) within [`REACH`] leg lengths of the stance sole (a
//! push that will carry it farther is a fall, not a step). Post-condition: the swing foot,
//! once lifted, is down again (after half the swing) with the capture point within
//! [`LAND_MARGIN_M`] of the new support. Expected performance: the predicted capture point
//! stays within reach while the target follows it, the foot lands within
//! [`TIMEOUT_SECS`] and the trunk stays within 50° of vertical.

use glam::{Quat, Vec2, Vec3};

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
    /// The stance thigh's world rotation (relative to rest) when the step started.
    stance_thigh: Quat,
    /// The figure's facing (forward, left) when the step started: the frame the step is
    /// planned in (see the module's doc).
    frame: (Vec3, Vec3),
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
    let stance_xz = Vec2::new(state.sole_centre[stance].x, state.sole_centre[stance].z);
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
    let stance_xz = Vec2::new(state.sole_centre[stance].x, state.sole_centre[stance].z);
    let mut t = landing;
    let l = Vec2::new(left.x, left.z);
    let sign = if (state.sole_centre[swing] - state.sole_centre[stance]).dot(left) >= 0.0 { 1.0 } else { -1.0 };
    let width = (t - stance_xz).dot(l) * sign;
    if width < MIN_WIDTH_M {
        t += l * sign * (MIN_WIDTH_M - width);
    }
    let reach = REACH * ctx.leg_length_m;
    let d = t - stance_xz;
    if d.length() > reach { stance_xz + d * (reach / d.length()) } else { t }
}

/// Whether a predicted capture point is farther than a step ([`REACH`] leg lengths) from
/// the `stance` sole.
fn out_of_reach(state: &FigureState, ctx: &ControlContext<'_>, stance: usize, capture: Vec2) -> bool {
    let s = state.sole_centre[stance];
    capture.distance(Vec2::new(s.x, s.z)) > REACH * ctx.leg_length_m
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
        let to = step_target(state, ctx, frame.1, (swing, stance), predicted_capture(state, ctx, stance, LAND_SECS));
        let stance_thigh = leg(ctx, stance).map_or(Quat::IDENTITY, |(t, _, _)| state.body_rot[t]);
        self.plan = Some(Plan {
            start_secs: state.time_secs,
            swing,
            from,
            to: Vec3::new(to.x, from.y, to.y),
            lifted: false,
            stance_thigh,
            frame,
        });
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        let Some(plan) = self.plan.as_mut() else { return Status::Failed("not activated".into()) };
        plan.lifted |= !state.foot_down[plan.swing] || state.sole_centre[plan.swing].y > LIFTED_M;
        // The capture point keeps moving while the figure pivots on one foot: follow it
        // until the last part of the swing.
        let tau = state.time_secs - plan.start_secs;
        if tau < RETARGET_UNTIL * SWING_SECS {
            let stance = 1 - plan.swing;
            let landing = predicted_capture(state, ctx, stance, LAND_SECS - tau);
            if out_of_reach(state, ctx, stance, landing) {
                return Status::Failed("the capture point ran out of a step's reach".into());
            }
            let to = step_target(state, ctx, plan.frame.1, (plan.swing, stance), landing);
            plan.to = Vec3::new(to.x, plan.from.y, to.y);
        }
        let plan = *plan;
        if state.trunk_upright < 50f32.to_radians().cos() {
            return Status::Failed("the trunk tilted past 50°".into());
        }
        let landed = state.foot_down[plan.swing] && state.sole_centre[plan.swing].y < 0.5 * LIFTED_M;
        if plan.lifted && tau > 0.6 * SWING_SECS && landed {
            return if state.capture_distance_m < LAND_MARGIN_M {
                Status::Succeeded
            } else {
                Status::Failed(format!(
                    "capture point {:.3} m outside the support after the step",
                    state.capture_distance_m
                ))
            };
        }
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
        Status::Running
    }
}
