//! Rise from the seat to standing (the paper's "rise from a chair"), leaning first as most
//! people do.
//!
//! Seated, the hips are a thigh's length behind the feet, and the hips' flexion limit lets
//! the pelvis alone lean too little to bring the centre of mass over the feet. So the rise
//! has two phases. **Lean**: the trunk leans forward at [`RISE_PITCH_RATE_RAD_S`] to
//! [`RISE_LEAN_RAD`] (the pelvis up to the hips' limit, the spine for the rest; less if
//! they allow less) and the arms reach forward, with the hips on the seat; seat-off comes
//! once the lean is (nearly) complete, both feet are down and the capture point is
//! [`SEAT_OFF_MARGIN_M`] inside the feet's contact polygon (seated, the feet press only at
//! their heels: [`FigureState::contact`]). **Extend**: the hips leave the seat on a
//! straight line to standing over the ankles over [`EXTEND_SECS`], the shanks' lean capped
//! by the ankles; the lean keeps the COM over the feet where the legs put the hips (from the
//! figure's mass split), easing off while the capture point runs ahead of the contact's
//! centre; the extension waits whenever the capture point nears the heels. Balance takes
//! over from the post-condition.
//!
//! Pre-condition: sitting on the seat, both feet down, trunk within 40° of vertical.
//! Post-condition: the COM above 90 % of its standing height, the trunk within 15° of
//! vertical, the capture point [`SETTLED_INSIDE_M`] inside the contact polygon and the COM nearly
//! still. Expected performance: seat-off within [`LEAN_FAIL_SECS`], the trunk within 80° of
//! vertical, no foot off the ground for longer than [`FOOT_OFF_SECS`], and standing within
//! `2·EXTEND_SECS + 1` s of seat-off.

use glam::Vec2;

use super::facing;
use super::posture::{
    FeedForward, LegLengths, MassSplit, Room, com_target, heel_along, hip_from_ankle, reach_forward, set_leg,
    set_trunk, smooth,
};
use crate::kernels::physics::controller::{BID_CAN_REACH, ControlContext, Controller, Status, Targets};
use crate::kernels::physics::state::{FigureState, signed_distance};

/// The trunk leans forward at most this much to gather momentum, radians.
pub const RISE_LEAN_RAD: f32 = 1.2;
/// Seat-off: the capture point this far inside the feet's contact polygon, metres.
pub const SEAT_OFF_MARGIN_M: f32 = 0.03;
/// Standing is reached with the capture point this far inside the contact polygon, metres, and
/// the COM moving horizontally slower than [`SETTLED_SPEED_M_S`]: balance takes over then.
pub const SETTLED_INSIDE_M: f32 = 0.02;
/// See [`SETTLED_INSIDE_M`], m/s.
pub const SETTLED_SPEED_M_S: f32 = 0.1;
/// Trunk lean taken off per metre the capture point runs ahead of the contact polygon's centre
/// while extending, rad/m.
pub const K_LEAN: f32 = 3.0;
/// How fast the pelvis pitches forward to gather momentum, rad/s.
pub const RISE_PITCH_RATE_RAD_S: f32 = 1.0;
/// Time from activation by which the capture point must be over the feet, seconds.
pub const LEAN_FAIL_SECS: f32 = 1.5;
/// Time to extend from seated to standing, seconds.
pub const EXTEND_SECS: f32 = 1.5;
/// A foot may be off the ground this long before the rise fails, seconds.
pub const FOOT_OFF_SECS: f32 = 0.3;

/// The rise controller.
#[derive(Default)]
pub struct Rise {
    plan: Option<Plan>,
}

/// The rise, fixed at activation.
struct Plan {
    start_secs: f32,
    /// Per side: leg lengths and the hip from the ankle when seated, (forward, up).
    legs: [(LegLengths, Vec2); 2],
    split: MassSplit,
    /// Where the COM is kept, forward of the ankles, metres.
    com_target_m: f32,
    room: Room,
    base: Targets,
    /// The pelvis pitch target and when it was set, seconds.
    pitch: f32,
    pitch_at: f32,
    /// How far the trunk leans before seat-off: [`RISE_LEAN_RAD`], or less if hips and spine
    /// allow less, radians.
    lean_rad: f32,
    /// When the extension started, seconds, and the pitch then.
    extend_from: Option<(f32, f32)>,
    /// Progress of the extension in [0, 1] and when it was last advanced, seconds.
    progress: f32,
    progress_at: f32,
    foot_off_since: Option<f32>,
    feed_forward: FeedForward,
}

/// The rise planned from the seated state; `None` without two full legs.
fn plan(state: &FigureState, ctx: &ControlContext<'_>) -> Option<Plan> {
    let (forward, _) = facing(state, ctx);
    let leg = |side: usize| {
        // Aimed a little above the seat, the legs press the feet down; aimed where the hips
        // rest they would lift them.
        let seated = hip_from_ankle(state, ctx, side, forward)? + Vec2::Y * (2.0 * super::sit::HOVER_M);
        Some((LegLengths::of(ctx, side)?, seated))
    };
    Some(Plan {
        start_secs: state.time_secs,
        legs: [leg(0)?, leg(1)?],
        split: MassSplit::measure(state, ctx, forward)?,
        com_target_m: com_target(state, ctx, forward),
        room: Room::of(ctx),
        base: ctx.stand.clone(),
        pitch: super::posture::pelvis_pitch(state, forward),
        pitch_at: state.time_secs,
        lean_rad: RISE_LEAN_RAD,
        extend_from: None,
        progress: 0.0,
        progress_at: state.time_secs,
        foot_off_since: None,
        feed_forward: FeedForward::default(),
    })
}

impl Controller for Rise {
    fn name(&self) -> &'static str {
        "rise"
    }
    fn preference(&self) -> u32 {
        20
    }
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32 {
        let Some(seat) = ctx.seat else { return 0 };
        let ready = state.foot_down[0] && state.foot_down[1] && state.trunk_upright > 40f32.to_radians().cos();
        if ready && seat.sitting(ctx.figure, state) { BID_CAN_REACH } else { 0 }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        self.plan = plan(state, ctx);
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        let Some(plan) = &mut self.plan else { return Status::Failed("the figure lacks a full pair of legs".into()) };
        let t = state.time_secs - plan.start_secs;
        if state.trunk_upright < 80f32.to_radians().cos() {
            return Status::Failed("the trunk tilted past 80°".into());
        }
        if state.foot_down[0] && state.foot_down[1] {
            plan.foot_off_since = None;
        } else if state.time_secs - *plan.foot_off_since.get_or_insert(state.time_secs) > FOOT_OFF_SECS {
            return Status::Failed("a foot left the ground".into());
        }
        let (forward, _) = facing(state, ctx);
        let f2 = Vec2::new(forward.x, forward.z);
        let heel_f = heel_along(state, forward);
        let capture_f = state.capture_point.dot(f2);
        // Seated and rising, the feet press where they touch (tipped onto the heels): the
        // capture point is judged against the contact polygon.
        let capture_inside = -signed_distance(&state.contact, state.capture_point);
        let extend = match plan.extend_from {
            None if plan.pitch >= 0.95 * plan.lean_rad
                && capture_inside > SEAT_OFF_MARGIN_M
                && state.foot_down == [true, true] =>
            {
                plan.extend_from = Some((state.time_secs, plan.pitch));
                plan.progress_at = state.time_secs;
                0.0
            }
            None if t > LEAN_FAIL_SECS => {
                return Status::Failed(format!(
                    "the capture point stayed {:.3} m behind where the feet press",
                    -capture_inside
                ));
            }
            None => 0.0,
            Some((t0, _)) => {
                let done = state.com.y > 0.9 * ctx.standing_com_height_m
                    && state.trunk_upright > 15f32.to_radians().cos()
                    && capture_inside > SETTLED_INSIDE_M
                    && state.com_vel.with_y(0.0).length() < SETTLED_SPEED_M_S;
                if plan.progress >= 1.0 && done {
                    return Status::Succeeded;
                }
                if state.time_secs - t0 > 2.0 * EXTEND_SECS + 1.0 {
                    return Status::Failed("did not reach standing".into());
                }
                // The extension waits while the capture point nears the heels.
                let inside = ((capture_f - heel_f) / SEAT_OFF_MARGIN_M).clamp(0.0, 1.0);
                plan.progress = (plan.progress + inside * (state.time_secs - plan.progress_at) / EXTEND_SECS).min(1.0);
                plan.progress_at = state.time_secs;
                smooth(plan.progress)
            }
        };
        // Each hip on its line from seated to standing over its ankle, the shank's lean capped.
        let planned: [(LegLengths, (f32, f32)); 2] = plan.legs.map(|(lengths, seated)| {
            let hip = seated.lerp(Vec2::new(0.0, 0.995 * (lengths.thigh_m + lengths.shank_m)), extend);
            (lengths, lengths.angles_within(hip, plan.room.shank_rad))
        });
        let (lengths, (thigh, shank)) = planned[0];
        let most = thigh + plan.room.hip_flexion_rad;
        // The whole trunk's lean: the pelvis up to the hips' limit, the spine for the rest.
        let spine = plan.room.spine_rad;
        let dt = (state.time_secs - plan.pitch_at).max(0.0);
        plan.pitch_at = state.time_secs;
        plan.pitch = match plan.extend_from {
            // Lean: towards RISE_LEAN_RAD, at the lean's rate.
            None => {
                plan.lean_rad = RISE_LEAN_RAD.min(most + spine);
                plan.pitch + (plan.lean_rad - plan.pitch).clamp(0.0, RISE_PITCH_RATE_RAD_S * dt)
            }
            // Extend: the lean that keeps the COM over the feet where the capped legs put the
            // hips, no more than at seat-off; less while the capture point runs ahead of the
            // contact polygon's centre, more while it lags.
            Some((_, lifted)) => {
                let most_now = (most + spine).min(lifted);
                let hip = lengths.hip_at((thigh, shank));
                let balanced = plan.split.pitch_for(hip, lengths.knee_at(shank), plan.com_target_m, most_now);
                let ahead = capture_f - state.contact_centre().dot(f2);
                (balanced - K_LEAN * ahead).clamp(0.0, most_now)
            }
        };
        targets.clone_from(&plan.base);
        let pelvis = set_trunk(targets, &plan.base, ctx, plan.pitch, most);
        reach_forward(targets, ctx, state, forward, (plan.pitch / RISE_LEAN_RAD).clamp(0.0, 1.0));
        for (side, (_, angles)) in planned.into_iter().enumerate() {
            set_leg(targets, &plan.base, ctx, side, angles, pelvis);
        }
        plan.feed_forward.apply(targets, state.time_secs);
        Status::Running
    }
}
