//! The controller family of the paper's 3-D figure that is implemented so far: balance
//! (ankle and hip strategy), protective step, protective fall, sit down on a seat and rise
//! from it, and the default controller that holds a relaxed pose when nothing else applies
//! (the paper's "default").
//!
//! | controller | pre-condition (bid) | post-condition | expected performance |
//! |---|---|---|---|
//! | [`balance`] | both feet down, trunk upright, capture point inside the support | none: holds until a request or failure | capture point stays inside the support, feet stay down |
//! | [`step`] | a foot down, trunk upright, capture point outside the support, and predicted at landing within a step | the catching foot down, then the trailing foot closed up beside it, with the capture point inside the support | predicted capture point within reach, each foot down within 0.8 s, trunk upright |
//! | [`fall`] | the figure is falling (capture point outside, or no foot down), not on a seat, and the head is up | at rest on the ground | the head never hits the ground (faster than 1 m/s) |
//! | [`sit`] | standing balanced, a seat's front edge 2 cm behind the soles' centres, the seated hips within reach; or sitting on the seat (holds it) | none: sits and stays seated until a request | trunk within 75°, seated within 0.5 s of the descent's end and 9 s of starting |
//! | [`rise`] | sitting on the seat, both feet down, trunk within 40° | COM at 90 % of standing, trunk within 15°, capture point 2 cm inside the support, COM nearly still | seat-off within 1.5 s, trunk within 80°, feet down, standing within 4 s of seat-off |
//! | [`Relax`] | always ([`BID_SENSIBLE`], lowest preference): holds the posture it found | none | none |
//!
//! [`posture`] holds what sit and rise share: leg and trunk postures in the sagittal plane,
//! the room the joint limits leave, the mass split that predicts the COM, and velocity
//! feed-forward for moving targets.

pub mod balance;
pub mod fall;
pub mod posture;
pub mod rise;
pub mod sit;
pub mod step;

use glam::{Quat, Vec2, Vec3};

use super::controller::{BID_SENSIBLE, ControlContext, Controller, Status, Targets};
use super::figure::BodyRole;
use super::state::FigureState;

/// Names of every controller [`pool`] can build, in pool order.
pub const NAMES: [&str; 6] = ["balance", "step", "fall", "sit", "rise", "relax"];

/// The full pool, in a fixed order (ties in the supervisor go to the first).
pub fn pool() -> Vec<Box<dyn Controller>> {
    vec![
        Box::new(balance::Balance::default()),
        Box::new(step::Step::default()),
        Box::new(fall::Fall::default()),
        Box::new(sit::Sit::default()),
        Box::new(rise::Rise::default()),
        Box::new(Relax::default()),
    ]
}

/// The pool restricted to `names` (unknown names are left out; check against [`NAMES`]).
pub fn pool_of(names: &[&str]) -> Vec<Box<dyn Controller>> {
    pool().into_iter().filter(|c| names.contains(&c.name())).collect()
}

/// The default controller: holds the posture it found when it took over, at a third of the
/// gains, so a figure on the ground lies limp but joints do not flop through their limits.
/// (Pulling towards the standing pose instead unrolled a figure lying curled after a
/// backward fall and struck its head on the ground at 2.4 m/s.)
#[derive(Default)]
pub struct Relax {
    hold: Option<Targets>,
}

/// Gain multiplier of the relaxed pose.
const RELAX_GAIN: f32 = 0.3;

/// The figure's current joint coordinates at [`RELAX_GAIN`].
fn relaxed(state: &FigureState) -> Targets {
    let n = state.joint_coords.len();
    Targets { angles: state.joint_coords.clone(), gain: vec![RELAX_GAIN; n], velocity: vec![[0.0; 3]; n] }
}

impl Controller for Relax {
    fn name(&self) -> &'static str {
        "relax"
    }
    fn preference(&self) -> u32 {
        1
    }
    fn bid(&self, _: &FigureState, _: &ControlContext<'_>) -> u32 {
        BID_SENSIBLE
    }
    fn activate(&mut self, state: &FigureState, _: &ControlContext<'_>) {
        self.hold = Some(relaxed(state));
    }
    fn control(&mut self, state: &FigureState, _: &ControlContext<'_>, targets: &mut Targets) -> Status {
        targets.clone_from(self.hold.get_or_insert_with(|| relaxed(state)));
        Status::Running
    }
}

/// The figure's current facing: (forward, left) horizontal unit vectors from the pelvis.
pub fn facing(state: &FigureState, ctx: &ControlContext<'_>) -> (Vec3, Vec3) {
    let q = state.body_rot[0];
    let f = (q * ctx.figure.forward).with_y(0.0).try_normalize().unwrap_or(ctx.figure.forward);
    (f, Vec3::Y.cross(f))
}

/// A horizontal `Vec2(x, z)` as a world vector at height 0.
pub fn xz(v: Vec2) -> Vec3 {
    Vec3::new(v.x, 0.0, v.y)
}

/// Rotation that tilts "up" by `angle_rad` towards the horizontal direction `dir`.
pub fn tilt_towards(dir: Vec3, angle_rad: f32) -> Quat {
    match Vec3::Y.cross(dir).try_normalize() {
        Some(axis) => Quat::from_axis_angle(axis, angle_rad),
        None => Quat::IDENTITY,
    }
}

/// Body indices of one side's leg: (thigh, shank, foot).
pub fn leg(ctx: &ControlContext<'_>, side: usize) -> Option<(usize, usize, usize)> {
    Some((
        ctx.body(BodyRole::Thigh, Some(side))?,
        ctx.body(BodyRole::Shank, Some(side))?,
        ctx.body(BodyRole::Foot, Some(side))?,
    ))
}
