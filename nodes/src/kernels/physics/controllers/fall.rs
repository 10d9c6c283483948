//! Protective fall: when balance and stepping cannot help, reach with both arms towards
//! the fall, elbows a little bent to absorb the impact with the hands, tuck the head away
//! from the fall and bend the knees and hips to lower the centre of mass (the paper's fall
//! controller: "absorb the shock of the impact using mostly the hands", in any direction).
//!
//! The fall direction is fixed at activation: from the support centre towards the capture
//! point (the way the COM is heading), or the horizontal COM velocity without support.
//! Each upper arm aims [`REACH_DOWN_RAD`] below the horizontal in that direction, spread
//! sideways by [`ARM_SPREAD`], stiffening to [`ARM_GAIN`] times the figure's gains (an
//! arm's own gains are sized for holding the arm, not for landing on it); the neck and spine
//! tilt the head away from the fall; the knees ([`KNEE_RAD`]) and hips ([`HIP_RAD`]) bend so
//! the figure drops towards its knees. The legs bend and the arms stiffen over
//! [`CROUCH_SECS`] (at once, the legs folded up and dropped the figure from standing height).
//!
//! Falling backwards, where the hands cannot catch the body, the figure curls as a person
//! does (chin to chest, back rounded, hips flexed): by the backward share `b` of the fall
//! direction (0 forwards or sideways, 1 straight back) the tuck grows by
//! [`BACK_TUCK_RAD`]·b, the knees by [`BACK_KNEE_RAD`]·b, the hips by [`BACK_HIP_RAD`]·b,
//! the arms reach [`BACK_REACH_DOWN_RAD`]·b lower, and the trunk and neck hold the curl at
//! `1 + BACK_TRUNK_GAIN·b` times their gains, so the body rolls on its rounded back with
//! the head off the ground.
//!
//! Whatever the direction, a head closing in on the ground (within [`HEAD_REFLEX_M`],
//! coming down faster than [`HEAD_REFLEX_SPEED`]) is lifted by the neck, as a falling person
//! does: the head aims straight up, as far as the neck's range allows, at (at least)
//! [`HEAD_REFLEX_GAIN`] times its gains. A posture chosen at the start of the fall cannot
//! know how the body will land; the reflex reads where the head is. Over the fall table's
//! 48 pushes it halved the falls whose head struck faster than 1 m/s (15 to 8).
//!
//! Pre-condition: the figure is falling (no foot down, or the capture point outside the
//! support), not sitting upright on a seat ([`super::sit::held_on_seat`]), not lying still
//! on the ground (COM slower than [`REST_SPEED`] and below [`LYING_COM_SHARE`] of its
//! standing height) and the head still above [`MIN_HEAD_M`].
//! Post-condition: at rest on the ground (COM slower than [`REST_SPEED`] for
//! [`REST_SECS`]). Expected performance: the head never hits the ground (touches it coming
//! down faster than [`HEAD_HIT_M_S`]); a head laid on the ground slower than that is not a
//! hit.

use glam::Vec3;

use super::{facing, tilt_towards, xz};
use crate::kernels::physics::controller::{BID_SENSIBLE, ControlContext, Controller, Status, Targets};
use crate::kernels::physics::figure::BodyRole;
use crate::kernels::physics::state::FigureState;
use crate::math::smoothstep;

/// How far below the horizontal the arms reach, radians.
pub const REACH_DOWN_RAD: f32 = 0.6;
/// Sideways share of each arm's aim (0 = both arms parallel).
pub const ARM_SPREAD: f32 = 0.35;
/// Elbow flexion while reaching, radians.
pub const ELBOW_RAD: f32 = 0.35;
/// Head and spine tilt away from the fall, radians (split over neck and spine).
pub const TUCK_RAD: f32 = 0.6;
/// Knee flexion while falling, radians: the figure drops towards its knees before its
/// hands and trunk reach the ground (0.8 rad let forward falls topple stiff-legged, the head
/// hitting at 5–8 m/s).
pub const KNEE_RAD: f32 = 1.2;
/// Hip flexion while falling, radians.
pub const HIP_RAD: f32 = 0.7;
/// A head that reaches the ground coming down faster than this hits it, m/s (the speed of
/// a 5 cm drop; over the fall table's 48 pushes a limp figure's head comes down at 2.7 m/s
/// median, up to 6.5).
pub const HEAD_HIT_M_S: f32 = 1.0;
/// Gain multiplier on the arms while reaching.
pub const ARM_GAIN: f32 = 5.0;
/// The knees and hips reach their crouch over this long, seconds.
pub const CROUCH_SECS: f32 = 0.3;
/// Extra head and spine tuck when falling straight back, radians.
pub const BACK_TUCK_RAD: f32 = 2.6;
/// Extra knee flexion when falling straight back, radians.
pub const BACK_KNEE_RAD: f32 = 0.4;
/// Extra hip flexion when falling straight back, radians (with the knees: sitting down
/// into the roll).
pub const BACK_HIP_RAD: f32 = 0.5;
/// How much lower the arms reach when falling straight back, radians.
pub const BACK_REACH_DOWN_RAD: f32 = 0.4;
/// Gain multiplier added to the trunk and neck when falling straight back.
pub const BACK_TRUNK_GAIN: f32 = 4.0;
/// The head reflex acts when the head is closer to the ground than this, metres ...
pub const HEAD_REFLEX_M: f32 = 0.3;
/// ... and coming down faster than this, m/s.
pub const HEAD_REFLEX_SPEED: f32 = 0.2;
/// Gain multiplier on the neck during the head reflex.
pub const HEAD_REFLEX_GAIN: f32 = 4.0;
/// The fall controller does not take over below this head clearance, metres.
pub const MIN_HEAD_M: f32 = 0.2;
/// A still figure whose COM is below this share of its standing height is lying down.
pub const LYING_COM_SHARE: f32 = 0.5;
/// At rest below this COM speed, m/s ...
pub const REST_SPEED: f32 = 0.15;
/// ... held this long, seconds.
pub const REST_SECS: f32 = 0.3;

/// The protective fall controller.
#[derive(Default)]
pub struct Fall {
    dir: Vec3,
    start_secs: f32,
    /// Joint coordinates when the fall began: the legs bend from there.
    start_coords: Vec<[f32; 3]>,
    still_since: Option<f32>,
}

impl Controller for Fall {
    fn name(&self) -> &'static str {
        "fall"
    }
    fn preference(&self) -> u32 {
        10
    }
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32 {
        let falling = !(state.foot_down[0] || state.foot_down[1]) || state.capture_distance_m > 0.0;
        // Lying still on the ground is where a fall ends, not where one starts.
        let lying = state.com_vel.length() < REST_SPEED && state.com.y < LYING_COM_SHARE * ctx.standing_com_height_m;
        // A figure upright on a seat is carried by it, wherever its capture point is.
        let seated = super::sit::held_on_seat(state, ctx);
        if falling && !lying && !seated && state.head_clearance_m > MIN_HEAD_M { BID_SENSIBLE } else { 0 }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        let towards = if state.support.is_empty() {
            state.com_vel.with_y(0.0)
        } else {
            xz(state.capture_point - state.support_centre())
        };
        self.dir = towards.try_normalize().unwrap_or(facing(state, ctx).0);
        self.still_since = None;
        self.start_secs = state.time_secs;
        self.start_coords.clone_from(&state.joint_coords);
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        if let Some(speed) = state.head_contact_speed().filter(|&v| v > HEAD_HIT_M_S) {
            return Status::Failed(format!("the head hit the ground at {speed:.2} m/s at {:.2} s", state.time_secs));
        }
        if state.com_vel.length() < REST_SPEED {
            let since = *self.still_since.get_or_insert(state.time_secs);
            if state.time_secs - since >= REST_SECS {
                return Status::Succeeded;
            }
        } else {
            self.still_since = None;
        }
        targets.clone_from(ctx.stand);
        let fig = ctx.figure;
        let dir = self.dir;
        let (forward, left) = facing(state, ctx);
        // Share of the fall that goes backwards (0 forwards or sideways, 1 straight back).
        let back = (-dir.dot(forward)).max(0.0);
        let tuck = TUCK_RAD + BACK_TUCK_RAD * back;
        let crouch = smoothstep(f64::from(((state.time_secs - self.start_secs) / CROUCH_SECS).clamp(0.0, 1.0))) as f32;
        let knee = KNEE_RAD + BACK_KNEE_RAD * back;
        let hip = HIP_RAD + BACK_HIP_RAD * back;
        let reach_down = REACH_DOWN_RAD + BACK_REACH_DOWN_RAD * back;
        let trunk_gain = 1.0 + BACK_TRUNK_GAIN * back;
        // The head reflex: closing in on the ground, the neck lifts the head.
        let head_reflex = state.head_clearance_m < HEAD_REFLEX_M && state.head_down_speed_m_s > HEAD_REFLEX_SPEED;
        // Stiffened over the crouch time: a fall from standing takes longer than that to
        // bring the hands to the ground.
        let arm_gain = 1.0 + (ARM_GAIN - 1.0) * crouch;
        for (i, body) in fig.bodies.iter().enumerate() {
            let parent_rot = body.parent.map_or(glam::Quat::IDENTITY, |p| state.body_rot[p]);
            match body.role {
                BodyRole::UpperArm => {
                    // Each arm spreads to its own side of the fall direction.
                    let spread = left * if body.side == Some(0) { ARM_SPREAD } else { -ARM_SPREAD };
                    let aim = dir * reach_down.cos() - Vec3::Y * reach_down.sin() + spread;
                    targets.aim(fig, i, parent_rot, aim);
                    targets.gain[i] = arm_gain;
                }
                BodyRole::Forearm => {
                    targets.angles[i] = [ELBOW_RAD, 0.0, 0.0];
                    targets.gain[i] = arm_gain;
                }
                BodyRole::Head if head_reflex => {
                    targets.aim(fig, i, parent_rot, Vec3::Y);
                    // At least: a backward fall's curl already stiffens the neck further.
                    targets.gain[i] = trunk_gain.max(HEAD_REFLEX_GAIN);
                }
                BodyRole::Head | BodyRole::Chest | BodyRole::Abdomen => {
                    let share = if body.role == BodyRole::Head { 0.5 } else { 0.25 };
                    targets.set_relative(fig, i, tilt_towards(parent_rot.inverse() * dir, -tuck * share));
                    targets.gain[i] = trunk_gain;
                }
                BodyRole::Shank => targets.angles[i] = [knee, 0.0, 0.0],
                BodyRole::Thigh => targets.set_relative(fig, i, glam::Quat::from_axis_angle(fig.left, -hip)),
                _ => {}
            }
            // The legs move from where they were (a step's bent swing knee snapped straight
            // when the crouch started from the rest pose, and bounced the body up at 1 m/s).
            if matches!(body.role, BodyRole::Shank | BodyRole::Thigh)
                && let Some(from) = self.start_coords.get(i)
            {
                for (k, a) in targets.angles[i].iter_mut().enumerate() {
                    *a = from[k] + (*a - from[k]) * crouch;
                }
            }
        }
        Status::Running
    }
}
