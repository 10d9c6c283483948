//! Protective fall: when balance and stepping cannot help, reach with both arms towards
//! the fall, elbows a little bent to absorb the impact with the hands, tuck the head away
//! from the fall and bend the knees and hips to lower the centre of mass (the paper's fall
//! controller: "absorb the shock of the impact using mostly the hands", in any direction).
//!
//! The fall direction is fixed at activation: from the support centre towards the capture
//! point (the way the COM is heading), or the horizontal COM velocity without support.
//! Each upper arm aims [`REACH_DOWN_RAD`] below the horizontal in that direction, spread
//! sideways by [`ARM_SPREAD`]; the neck and spine tilt the head away from the fall.
//!
//! Pre-condition: the figure is falling (no foot down, or the capture point outside the
//! support) and the head is still above [`MIN_HEAD_M`]. Post-condition: at rest on the
//! ground (COM slower than [`REST_SPEED`] for [`REST_SECS`]). Expected performance: the
//! head never touches the ground.

use glam::Vec3;

use super::{facing, tilt_towards, xz};
use crate::kernels::physics::controller::{BID_SENSIBLE, ControlContext, Controller, Status, Targets};
use crate::kernels::physics::figure::BodyRole;
use crate::kernels::physics::state::FigureState;

/// How far below the horizontal the arms reach, radians.
pub const REACH_DOWN_RAD: f32 = 0.6;
/// Sideways share of each arm's aim (0 = both arms parallel).
pub const ARM_SPREAD: f32 = 0.35;
/// Elbow flexion while reaching, radians.
pub const ELBOW_RAD: f32 = 0.35;
/// Head and spine tilt away from the fall, radians (split over neck and spine).
pub const TUCK_RAD: f32 = 0.6;
/// Knee flexion while falling, radians.
pub const KNEE_RAD: f32 = 0.8;
/// The head is "on the ground" below this clearance, metres.
pub const HEAD_CONTACT_M: f32 = 0.01;
/// The fall controller does not take over below this head clearance, metres.
pub const MIN_HEAD_M: f32 = 0.2;
/// At rest below this COM speed, m/s ...
pub const REST_SPEED: f32 = 0.15;
/// ... held this long, seconds.
pub const REST_SECS: f32 = 0.3;

/// The protective fall controller.
#[derive(Default)]
pub struct Fall {
    dir: Vec3,
    still_since: Option<f32>,
}

impl Controller for Fall {
    fn name(&self) -> &'static str {
        "fall"
    }
    fn preference(&self) -> u32 {
        10
    }
    fn bid(&self, state: &FigureState, _: &ControlContext<'_>) -> u32 {
        let falling = !(state.foot_down[0] || state.foot_down[1]) || state.capture_distance_m > 0.0;
        if falling && state.head_clearance_m > MIN_HEAD_M { BID_SENSIBLE } else { 0 }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        let towards = if state.support.is_empty() {
            state.com_vel.with_y(0.0)
        } else {
            xz(state.capture_point - state.support_centre())
        };
        self.dir = towards.try_normalize().unwrap_or(facing(state, ctx).0);
        self.still_since = None;
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        if state.head_clearance_m < HEAD_CONTACT_M {
            return Status::Failed(format!("the head touched the ground at {:.2} s", state.time_secs));
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
        let (_, left) = facing(state, ctx);
        for (i, body) in fig.bodies.iter().enumerate() {
            let parent_rot = body.parent.map_or(glam::Quat::IDENTITY, |p| state.body_rot[p]);
            match body.role {
                BodyRole::UpperArm => {
                    // Each arm spreads to its own side of the fall direction.
                    let spread = left * if body.side == Some(0) { ARM_SPREAD } else { -ARM_SPREAD };
                    let aim = dir * REACH_DOWN_RAD.cos() - Vec3::Y * REACH_DOWN_RAD.sin() + spread;
                    targets.aim(fig, i, parent_rot, aim);
                }
                BodyRole::Forearm => targets.angles[i] = [ELBOW_RAD, 0.0, 0.0],
                BodyRole::Head | BodyRole::Chest | BodyRole::Abdomen => {
                    let share = if body.role == BodyRole::Head { 0.5 } else { 0.25 };
                    targets.set_relative(fig, i, tilt_towards(parent_rot.inverse() * dir, -TUCK_RAD * share));
                }
                BodyRole::Shank => targets.angles[i] = [KNEE_RAD, 0.0, 0.0],
                BodyRole::Thigh => {
                    // Hips flex by half the knee angle so the shank stays near vertical.
                    targets.set_relative(fig, i, glam::Quat::from_axis_angle(fig.left, -0.5 * KNEE_RAD));
                }
                _ => {}
            }
        }
        Status::Running
    }
}
