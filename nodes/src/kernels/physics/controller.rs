//! The controller contract of Faloutsos et al. (2001) and the supervisor that composes
//! controllers.
//!
//! A controller is a black box that answers two questions: "can you take the figure from
//! this state towards your goal?" (its **pre-condition**, given as an integer bid) and,
//! while active, "are you operating nominally, have you succeeded (**post-condition**), or
//! have you failed (**expected performance**)?". The supervisor polls the pool only when no
//! controller is active and activates the best bid times the controller's preference
//! weight. Transitions are implicit: nothing says "after balance comes step"; the state
//! moves out of one controller's region and into another's.
//!
//! Bids follow the paper: 0 = unsuited; [`BID_SENSIBLE`] = can do something sensible here;
//! [`BID_CAN_REACH`] = can take the figure to its post-condition. A user request (a
//! script's `request`) deactivates the active controller and multiplies the requested one's
//! bid by [`REQUEST_BOOST`], if it bids at all: a request cannot override a pre-condition.

use glam::{Quat, Vec3};
use rapier3d::prelude::*;

use super::World;
use super::figure::{BodyRole, Figure, JointKind, Spawned};
use super::seat::Seat;
use super::state::FigureState;

/// Bid of a controller that can act sensibly in this state but not promise success.
pub const BID_SENSIBLE: u32 = 1;
/// Bid of a controller that can reach its post-condition from this state.
pub const BID_CAN_REACH: u32 = 2;
/// How much a user request multiplies the requested controller's score.
pub const REQUEST_BOOST: u32 = 1000;
/// Angle of the upper arms from vertical in the standing pose, radians (hanging at the
/// sides, clear of the trunk's capsules).
pub const ARM_DOWN_RAD: f32 = 0.25;

/// What an active controller reports after a control step.
#[derive(Clone, Debug, PartialEq)]
pub enum Status {
    /// Operating nominally.
    Running,
    /// Post-condition reached; the controller relinquishes control.
    Succeeded,
    /// Expected performance violated (e.g. the capture point left the support polygon).
    Failed(String),
}

/// Joint targets a controller sets: per figure body, the motor positions of the joint to
/// its parent (joint coordinates about the joint frame's X, Y, Z; a hinge uses X) and a
/// gain multiplier on the figure's PD gains.
#[derive(Clone, Debug, PartialEq)]
pub struct Targets {
    /// Motor positions, radians, per body (ignored for the root).
    pub angles: Vec<[f32; 3]>,
    /// Gain multiplier per body (1 = the figure's gains).
    pub gain: Vec<f32>,
    /// Motor target velocities, rad/s, per body, in the units of `angles` (zero holds
    /// still). A moving target with zero velocity is tracked a damping time behind.
    pub velocity: Vec<[f32; 3]>,
}

impl Targets {
    /// The rest pose at the figure's gains.
    pub fn rest(figure: &Figure) -> Targets {
        let n = figure.bodies.len();
        Targets { angles: vec![[0.0; 3]; n], gain: vec![1.0; n], velocity: vec![[0.0; 3]; n] }
    }

    /// The standing pose a figure takes when no initial pose is given: each leg turned so
    /// that its ankle is straight below its hip, foot flat, and arms lowered to
    /// [`ARM_DOWN_RAD`] from vertical, out to their own side; everything else at rest.
    /// Rest poses are made for skinning, not standing: CMU's has the legs splayed 20° (soles
    /// 0.77 m apart) and most rigs hold the arms out in a T.
    pub fn standing(figure: &Figure) -> Targets {
        let mut t = Targets::rest(figure);
        let child = |b: usize, role: BodyRole| figure.bodies.iter().position(|c| c.parent == Some(b) && c.role == role);
        for (i, body) in figure.bodies.iter().enumerate() {
            match body.role {
                BodyRole::Thigh => {
                    let Some(shank) = child(i, BodyRole::Shank) else { continue };
                    let Some(foot) = child(shank, BodyRole::Foot) else { continue };
                    let hip_to_ankle = figure.bodies[shank].anchor_in_parent + figure.bodies[foot].anchor_in_parent;
                    let Some(dir) = hip_to_ankle.try_normalize() else { continue };
                    let turn = Quat::from_rotation_arc(dir, Vec3::NEG_Y);
                    t.set_relative(figure, i, turn);
                    // The foot keeps its rest orientation in the world.
                    t.set_relative(figure, foot, turn.inverse());
                }
                BodyRole::UpperArm => {
                    let rest = figure.bone_direction(i);
                    let Some(out) = rest.with_y(0.0).try_normalize() else { continue };
                    let want = Vec3::NEG_Y * ARM_DOWN_RAD.cos() + out * ARM_DOWN_RAD.sin();
                    if rest.angle_between(Vec3::NEG_Y) > ARM_DOWN_RAD {
                        t.set_relative(figure, i, Quat::from_rotation_arc(rest, want));
                    }
                }
                _ => {}
            }
        }
        t
    }

    /// The rotation body `b`'s motor angles stand for, relative to its parent (in world
    /// axes of the rest pose): what [`set_relative`](Self::set_relative) sets, read back.
    pub fn relative(&self, figure: &Figure, b: usize) -> Quat {
        Quat::from_scaled_axis(figure.bodies[b].joint_frame * Vec3::from_array(self.angles[b]))
    }

    /// Sets body `b`'s target so that it is rotated by `relative` (a rotation in world axes
    /// of the rest pose) with respect to its parent. Ball joints take the rotation vector in
    /// the joint frame (rapier's spherical multibody coordinates are the integrated joint
    /// angular velocity, which equals the rotation vector for a rotation about a fixed
    /// axis); hinges take its component about the hinge axis.
    pub fn set_relative(&mut self, figure: &Figure, b: usize, relative: Quat) {
        let body = &figure.bodies[b];
        let v = body.joint_frame.inverse() * shortest(relative).to_scaled_axis();
        self.angles[b] = match body.kind {
            JointKind::Hinge { limits_rad } => [v.x.clamp(limits_rad[0], limits_rad[1]), 0.0, 0.0],
            JointKind::Ball { limits_rad } => [
                v.x.clamp(limits_rad[0][0], limits_rad[0][1]),
                v.y.clamp(limits_rad[1][0], limits_rad[1][1]),
                v.z.clamp(limits_rad[2][0], limits_rad[2][1]),
            ],
            JointKind::Free => [0.0; 3],
        };
    }

    /// Aims body `b`'s bone (rest direction from its joint to the next) along `dir`, a
    /// world direction, given the parent's current world rotation `parent_rot`.
    pub fn aim(&mut self, figure: &Figure, b: usize, parent_rot: Quat, dir: Vec3) {
        let rest = figure.bone_direction(b);
        let Some(want) = (parent_rot.inverse() * dir).try_normalize() else { return };
        self.set_relative(figure, b, Quat::from_rotation_arc(rest, want));
    }

    /// Writes the targets into the figure's joint motors.
    pub fn apply(&self, figure: &Figure, world: &mut World, spawned: &Spawned) {
        for (i, body) in figure.bodies.iter().enumerate() {
            let Some(handle) = spawned.joints[i] else { continue };
            let Some((mb, link)) = world.inner.multibody_joints.get_mut(handle) else { continue };
            let Some(link) = mb.link_mut(link) else { continue };
            let (kp, kd) = (body.kp * self.gain[i], body.kd * self.gain[i]);
            let axes: &[JointAxis] = match body.kind {
                JointKind::Hinge { .. } => &[JointAxis::AngX],
                JointKind::Ball { .. } => &[JointAxis::AngX, JointAxis::AngY, JointAxis::AngZ],
                JointKind::Free => &[],
            };
            for (k, &axis) in axes.iter().enumerate() {
                link.joint.data.set_motor(axis, self.angles[i][k], self.velocity[i][k], kp, kd);
            }
        }
    }
}

/// The rotation with a non-negative real part (the same rotation, angle ≤ π).
fn shortest(q: Quat) -> Quat {
    if q.w < 0.0 { -q } else { q }
}

/// What the controllers may read besides the state: the figure and its reference values.
#[derive(Clone, Debug)]
pub struct ControlContext<'a> {
    /// The figure.
    pub figure: &'a Figure,
    /// Gravity, m/s².
    pub gravity_m_s2: f32,
    /// COM height standing in the initial pose, metres.
    pub standing_com_height_m: f32,
    /// Leg length (hip to sole), metres.
    pub leg_length_m: f32,
    /// Joint targets of the initial (standing) pose.
    pub stand: &'a Targets,
    /// The seat behind the figure, when the script has a chair.
    pub seat: Option<Seat>,
}

impl ControlContext<'_> {
    /// The body of `role` on `side` (None for trunk bodies).
    pub fn body(&self, role: BodyRole, side: Option<usize>) -> Option<usize> {
        self.figure.bodies.iter().position(|b| b.role == role && b.side == side)
    }
}

/// A composable controller.
pub trait Controller: Send {
    /// Stable name used in scripts and reports (`"balance"`).
    fn name(&self) -> &'static str;
    /// Preference weight multiplying the bid: the designer's ordering among controllers
    /// that can all handle a state.
    fn preference(&self) -> u32;
    /// Pre-condition: 0 when unsuited, [`BID_SENSIBLE`] or [`BID_CAN_REACH`] otherwise.
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32;
    /// Called when the supervisor activates the controller.
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>);
    /// One control step: sets `targets` and checks the post-condition and expected
    /// performance.
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status;
}

/// Why a controller was activated.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    /// Best score when the pool was polled (score = bid × preference).
    BestBid {
        /// The winning score.
        score: u32,
    },
    /// Requested by the user (script) and its pre-condition held.
    Requested,
}

/// How an activation ended.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Still active when the run ended.
    Active,
    /// Post-condition reached.
    Succeeded,
    /// Expected performance violated, with the controller's reason.
    Failed(String),
    /// A user request took over.
    Interrupted,
}

/// One entry of the controller timeline.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Activation {
    /// Controller name.
    pub controller: &'static str,
    /// Activation time, seconds.
    pub start_secs: f32,
    /// Deactivation time, seconds (the run's end while active).
    pub end_secs: f32,
    /// Why it was activated.
    pub reason: Reason,
    /// How it ended.
    pub outcome: Outcome,
}

/// Arbitrates a pool of controllers.
pub struct Supervisor {
    pool: Vec<Box<dyn Controller>>,
    active: Option<usize>,
    requested: Option<usize>,
    /// The activations so far, in time order.
    pub timeline: Vec<Activation>,
}

impl Supervisor {
    /// A supervisor over `pool` with nothing active.
    pub fn new(pool: Vec<Box<dyn Controller>>) -> Supervisor {
        Supervisor { pool, active: None, requested: None, timeline: Vec::new() }
    }

    /// Names of the pool's controllers.
    pub fn names(&self) -> Vec<&'static str> {
        self.pool.iter().map(|c| c.name()).collect()
    }

    /// The active controller's name.
    pub fn active(&self) -> Option<&'static str> {
        self.active.map(|i| self.pool[i].name())
    }

    /// A user request for `name` at `time_secs`: the active controller is interrupted and
    /// the requested one wins the next arbitration if its pre-condition holds. Returns false
    /// for a name not in the pool.
    pub fn request(&mut self, name: &str, time_secs: f32) -> bool {
        let Some(i) = self.pool.iter().position(|c| c.name() == name) else { return false };
        self.close(time_secs, Outcome::Interrupted);
        self.requested = Some(i);
        true
    }

    fn close(&mut self, time_secs: f32, outcome: Outcome) {
        if self.active.take().is_some()
            && let Some(last) = self.timeline.last_mut()
        {
            last.end_secs = time_secs;
            last.outcome = outcome;
        }
    }

    /// One control step: runs the active controller, and when none is active (or it just
    /// finished) polls the pool and activates the best score.
    pub fn step(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) {
        if let Some(i) = self.active {
            match self.pool[i].control(state, ctx, targets) {
                Status::Running => return,
                Status::Succeeded => self.close(state.time_secs, Outcome::Succeeded),
                Status::Failed(why) => self.close(state.time_secs, Outcome::Failed(why)),
            }
        }
        // No controller, or the active one just finished: its feed-forward rates end with
        // it (a newly activated controller sets its own below; with none, the motors hold
        // the last targets still).
        targets.velocity.fill([0.0; 3]);
        let requested = self.requested.take();
        let best = self
            .pool
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let bid = c.bid(state, ctx);
                let boost = if requested == Some(i) && bid > 0 { REQUEST_BOOST } else { 1 };
                (i, bid * c.preference() * boost)
            })
            .filter(|&(_, score)| score > 0)
            // Ties go to the first in the pool (deterministic).
            .fold(None, |best: Option<(usize, u32)>, (i, s)| match best {
                Some((_, bs)) if bs >= s => best,
                _ => Some((i, s)),
            });
        let Some((i, score)) = best else { return };
        let reason =
            if requested == Some(i) && score >= REQUEST_BOOST { Reason::Requested } else { Reason::BestBid { score } };
        self.pool[i].activate(state, ctx);
        self.active = Some(i);
        self.timeline.push(Activation {
            controller: self.pool[i].name(),
            start_secs: state.time_secs,
            end_secs: state.time_secs,
            reason,
            outcome: Outcome::Active,
        });
        // The new controller acts in this step already; a controller that finishes at once
        // is closed and the pool is polled again at the next step.
        match self.pool[i].control(state, ctx, targets) {
            Status::Running => {}
            Status::Succeeded => self.close(state.time_secs, Outcome::Succeeded),
            Status::Failed(why) => self.close(state.time_secs, Outcome::Failed(why)),
        }
    }

    /// Ends the run: the active controller's entry gets the end time.
    pub fn finish(&mut self, time_secs: f32) {
        if self.active.is_some()
            && let Some(last) = self.timeline.last_mut()
        {
            last.end_secs = time_secs;
        }
    }
}
