//! Balance: the inverted-pendulum ankle strategy with a hip strategy on top (the paper's
//! balance controller, after Pai & Patton's region of balance without stepping).
//!
//! The hips, knees and ankles hold the posture they had when balance took over (so it
//! also balances after a protective step, feet apart); the ankles lean the body away from the capture point's
//! offset `u = ξ − c` (ξ the LIPM capture point, c the support centroid), proportionally:
//! `θ_ankle = k_ankle·u` (clamped), and the hips add `k_hip·u` once `|u|` exceeds what the
//! ankles can hold. Leaning the shanks by θ moves the COM by about `h·θ` and makes the
//! ankle motors push the centre of pressure towards ξ, which is what brings ξ (and the COM)
//! back over the support.
//!
//! Pre-condition: both feet down, trunk within 30° of vertical, COM at least 70 % of its
//! standing height (a knee may still be bent after a step), capture point within
//! [`ENTER_OUTSIDE_M`] of the support polygon. Expected performance: the
//! capture point stays within [`FAIL_OUTSIDE_M`] of the polygon, no foot is off the ground
//! for longer than [`FOOT_OFF_SECS`], the trunk stays within 40° and the COM above 60 %; no post-condition (balance holds until a request or a failure).

use glam::{Quat, Vec3};

use super::{facing, leg};
use crate::kernels::physics::controller::{BID_CAN_REACH, ControlContext, Controller, Status, Targets};
use crate::kernels::physics::figure::BodyRole;
use crate::kernels::physics::state::FigureState;

/// Ankle lean per metre of capture-point offset, rad/m.
pub const K_ANKLE: f32 = 2.0;
/// Hip lean per metre of offset beyond [`HIP_FROM_M`], rad/m.
pub const K_HIP: f32 = 3.0;
/// Offset where the hip strategy starts, metres.
pub const HIP_FROM_M: f32 = 0.03;
/// Largest ankle lean, radians.
pub const MAX_ANKLE_RAD: f32 = 0.25;
/// Balance takes over while the capture point is at most this far outside the support
/// polygon, metres (a protective step ends within it).
pub const ENTER_OUTSIDE_M: f32 = 0.01;
/// Balance fails when the capture point is this far outside the support polygon, metres.
pub const FAIL_OUTSIDE_M: f32 = 0.02;

/// The balance controller.
#[derive(Default)]
pub struct Balance {
    hold: Option<Targets>,
    /// The COM's ground projection (x, z, metres) and the time (seconds) when balance took
    /// over: see [`SETTLE_SECS`].
    start: Option<(glam::Vec2, f32)>,
    /// Since when a foot has been off the ground, seconds.
    foot_off_since: Option<f32>,
}

/// Balance drives the capture point towards a point that moves from the COM's ground
/// projection at activation to the support centroid over this long, seconds: a figure
/// standing still has its COM several centimetres behind the middle of its feet, and
/// pulling it there at once jerks it off its heels.
pub const SETTLE_SECS: f32 = 0.4;

/// A foot may be off the ground this long (a trailing heel after a step) before balance
/// declares failure, seconds.
pub const FOOT_OFF_SECS: f32 = 0.2;

/// Whether the state is inside balance's region: trunk within `acos(tilt_cos)` of vertical,
/// COM above `height` times its standing height, capture point inside the support (by
/// `margin_m`); the feet are checked by the caller.
pub fn balanced(state: &FigureState, ctx: &ControlContext<'_>, margin_m: f32, tilt_cos: f32, height: f32) -> bool {
    state.trunk_upright > tilt_cos
        && state.com.y > height * ctx.standing_com_height_m
        && state.capture_distance_m < margin_m
}

/// The rotation that leans a body away from the capture point's offset `(u_f, u_l)` (metres
/// ahead and to the left of where it should be), about the axes `(forward, left)`: back (by
/// −k·u_f about `left`, which tilts up backwards) when ξ is ahead, to the right (by k·u_l
/// about `forward`) when it is to the left. The gain `k` (rad/m) acts on the part of each
/// offset past `from_m`; each angle is clamped to `max_rad`.
pub fn lean_away((u_f, u_l): (f32, f32), (forward, left): (Vec3, Vec3), k: f32, from_m: f32, max_rad: f32) -> Quat {
    let shrink = |x: f32| x.signum() * (x.abs() - from_m).max(0.0);
    Quat::from_axis_angle(left, (-k * shrink(u_f)).clamp(-max_rad, max_rad))
        * Quat::from_axis_angle(forward, (k * shrink(u_l)).clamp(-max_rad, max_rad))
}

impl Controller for Balance {
    fn name(&self) -> &'static str {
        "balance"
    }
    fn preference(&self) -> u32 {
        30
    }
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32 {
        let feet = state.foot_down[0] && state.foot_down[1];
        if feet && balanced(state, ctx, ENTER_OUTSIDE_M, 30f32.to_radians().cos(), 0.7) { BID_CAN_REACH } else { 0 }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        // Hips, knees and ankles keep their current posture (feet where a step put them:
        // straightening a knee bent by the landing at full stiffness bounced the figure up at
        // 1 m/s); trunk, arms and head go back to standing.
        let mut hold = ctx.stand.clone();
        for (i, b) in ctx.figure.bodies.iter().enumerate() {
            if matches!(b.role, BodyRole::Thigh | BodyRole::Shank | BodyRole::Foot) {
                hold.angles[i] = state.joint_coords[i];
            }
        }
        self.hold = Some(hold);
        self.foot_off_since = None;
        self.start = Some((state.com_xz(), state.time_secs));
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        if state.foot_down[0] && state.foot_down[1] {
            self.foot_off_since = None;
        } else if state.time_secs - *self.foot_off_since.get_or_insert(state.time_secs) > FOOT_OFF_SECS {
            return Status::Failed("a foot left the ground".into());
        }
        if !balanced(state, ctx, FAIL_OUTSIDE_M, 40f32.to_radians().cos(), 0.6) {
            return Status::Failed(if state.capture_distance_m >= FAIL_OUTSIDE_M {
                format!("capture point {:.3} m outside the support", state.capture_distance_m)
            } else {
                "the trunk tilted or the body sank".into()
            });
        }
        let hold = self.hold.get_or_insert_with(|| ctx.stand.clone());
        targets.clone_from(hold);
        let (forward, left) = facing(state, ctx);
        let centre = match self.start {
            Some((com, t0)) => com.lerp(state.support_centre(), ((state.time_secs - t0) / SETTLE_SECS).clamp(0.0, 1.0)),
            None => state.support_centre(),
        };
        let u = super::xz(state.capture_point - centre);
        let (u_f, u_l) = (u.dot(forward), u.dot(left));
        // Relative rotations are in the rest pose's axes.
        let axes = (ctx.figure.forward, ctx.figure.left);
        let ankle = lean_away((u_f, u_l), axes, K_ANKLE, 0.0, MAX_ANKLE_RAD);
        // The hip strategy is sagittal only: rolling the pelvis sideways over two planted
        // feet would raise one hip and lift the other foot off the ground.
        let hip = lean_away((u_f, 0.0), axes, K_HIP, HIP_FROM_M, 0.4);
        for side in 0..2 {
            let Some((thigh, _, foot)) = leg(ctx, side) else { continue };
            // Foot flat, shank leant in world axes: the shank's world rotation becomes
            // `ankle · held⁻¹`, so the foot relative to it is `held · ankle⁻¹` (the other
            // order would lean each shank about its own turned axes, and two legs turned
            // apart would push against each other).
            targets.set_relative(ctx.figure, foot, hold.relative(ctx.figure, foot) * ankle.inverse());
            // Pelvis leant by the hip lean: the thigh relative to the pelvis is its inverse.
            targets.set_relative(ctx.figure, thigh, hip.inverse() * hold.relative(ctx.figure, thigh));
        }
        Status::Running
    }
}
