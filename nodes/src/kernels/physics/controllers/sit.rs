//! Sit down on the seat behind (the paper's "sit" controller), and stay seated.
//!
//! The hips move on a straight line from where they stand to just behind the seat's front
//! edge, resting on its top, over [`SIT_SECS`], with the feet where they are and the shanks
//! leaning forward no more than the ankles allow. The pelvis leans forward as far as keeps
//! the whole-body centre of mass over the feet (predicted from the figure's
//! [`MassSplit`]), and the descent waits while the lean lags or the capture point nears the
//! heels. Once no lean within the hips' flexion limit can hold the COM over the feet (the
//! last few centimetres, as for a person), the figure lets itself down onto the seat, and
//! it comes upright as the seat takes the weight. Seated, the controller holds the posture
//! until a request (rise) takes over: it has no post-condition, like balance.
//!
//! Pre-condition: a seat facing the figure's way, its front edge at least 2 cm behind both
//! soles' centres, the seated hips within the legs' reach, both feet down and standing
//! balanced ([`BID_CAN_REACH`]); or already sitting on the seat with the trunk within 70° ([`BID_SENSIBLE`]: the
//! descent is then the few centimetres to the seated posture, which it holds, so a figure a
//! rise left on the seat stays seated instead of going to the fall controller). Expected performance: the trunk within 75° of vertical, seated within
//! [`MISS_SECS`] of the descent's end and within [`MAX_SIT_SECS`] of starting.

use glam::Vec2;

use super::posture::{
    FeedForward, LegLengths, MassSplit, Room, com_target, heel_along, hip_from_ankle, pelvis_pitch, set_leg, smooth,
};
use super::{facing, leg};
use crate::kernels::physics::controller::{BID_CAN_REACH, BID_SENSIBLE, ControlContext, Controller, Status, Targets};
use crate::kernels::physics::seat::Seat;
use crate::kernels::physics::state::FigureState;

/// Length of the descent, seconds.
pub const SIT_SECS: f32 = 3.0;
/// Largest forward lean of the pelvis on the way down, radians.
pub const SIT_PITCH_RAD: f32 = 1.1;
/// The hips end this far behind the seat's front edge, metres.
pub const HIP_BEHIND_EDGE_M: f32 = 0.12;
/// The hips are aimed this far above resting on the seat: the legs then press the feet
/// down (aimed below it, they lift the feet off the ground, the seat stopping the hips).
pub const HOVER_M: f32 = 0.01;
/// The capture point is kept this far ahead of the heels on the way down, metres.
pub const HEEL_MARGIN_M: f32 = 0.04;
/// Time for the trunk to come upright once the seat carries the figure, seconds.
pub const UPRIGHT_SECS: f32 = 0.6;
/// Fastest change of the pelvis pitch target, rad/s.
pub const PITCH_RATE_RAD_S: f32 = 0.6;
/// The descent stops while the pitch lags the balanced pitch by this much, radians.
pub const MAX_PITCH_LAG_RAD: f32 = 0.1;
/// Lean of the legs at the ankles per metre the hips lag behind their path, rad/m.
pub const K_TRACK: f32 = 3.0;
/// The balance feedback fades out over the last this much of the hips' descent, metres:
/// to sit, the COM must go behind the heels.
pub const FADE_M: f32 = 0.12;
/// Time after the descent's end within which the figure must sit, seconds.
pub const MISS_SECS: f32 = 0.5;
/// Sit fails when the trunk tilts further than this from vertical, radians (75°).
pub const FAIL_TRUNK_RAD: f32 = 1.309;
/// A seated figure is held when its trunk is within this of vertical, radians: 5° inside
/// [`FAIL_TRUNK_RAD`], so holding it does not fail at once (which would make sit bid and
/// fail at every step); a rise's lean ([`super::rise::RISE_LEAN_RAD`], 69°) stays within it.
pub const HOLD_TRUNK_RAD: f32 = FAIL_TRUNK_RAD - 0.087;

/// Whether the figure sits on the seat with its trunk within [`HOLD_TRUNK_RAD`]: what sit
/// holds, and what the fall controller leaves alone.
pub fn held_on_seat(state: &FigureState, ctx: &ControlContext<'_>) -> bool {
    state.trunk_upright > HOLD_TRUNK_RAD.cos() && ctx.seat.is_some_and(|seat| seat.sitting(ctx.figure, state))
}

/// The descent may wait; seated the figure must be within this long of starting, seconds.
pub const MAX_SIT_SECS: f32 = 3.0 * SIT_SECS;

/// The sit controller.
#[derive(Default)]
pub struct Sit {
    plan: Option<Plan>,
}

/// The descent, fixed at activation.
struct Plan {
    start_secs: f32,
    /// Progress along the descent in [0, 1] and when it was last advanced, seconds: it
    /// advances more slowly while the capture point is near the heels.
    progress: f32,
    last_secs: f32,
    /// Per side: leg lengths, hip from ankle at the start and at the end, (forward, up).
    legs: [(LegLengths, Vec2, Vec2); 2],
    /// The figure's mass split and where its COM is kept, forward of the ankles, metres.
    split: MassSplit,
    /// The pelvis pitch target and when it was set, seconds.
    pitch: f32,
    pitch_at: f32,
    /// How far the pitch target lags the balanced pitch, radians.
    pitch_lag: f32,
    /// Whether the lean needed to keep the COM over the feet is past the hips' reach.
    out_of_lean: bool,
    room: Room,
    feed_forward: FeedForward,
    com_target_m: f32,
    base: Targets,
    /// When the seat first carried the figure, seconds.
    seated_at: Option<f32>,
    /// When the descent reached its end, seconds.
    descended_at: Option<f32>,
}

/// Each side's hip from its ankle at the end of the descent: over the seat, behind its front
/// edge, resting on it; `None` without a seat or a full leg.
fn seated_hips(state: &FigureState, ctx: &ControlContext<'_>, seat: &Seat) -> [Option<(LegLengths, Vec2)>; 2] {
    let (forward, _) = facing(state, ctx);
    std::array::from_fn(|side| {
        let lengths = LegLengths::of(ctx, side)?;
        let (thigh, _, foot) = leg(ctx, side)?;
        let ankle = state.body_pos[foot];
        let edge = (seat.front_edge() - ankle).dot(forward);
        let depth = ctx.figure.seated_depth_m(thigh);
        Some((lengths, Vec2::new(edge - HIP_BEHIND_EDGE_M, seat.top_centre.y + depth + HOVER_M - ankle.y)))
    })
}

/// The descent planned from the standing state; `None` without a seat or two full legs.
fn plan(state: &FigureState, ctx: &ControlContext<'_>) -> Option<Plan> {
    let (forward, _) = facing(state, ctx);
    let ends = seated_hips(state, ctx, &ctx.seat?);
    let leg = |side: usize| {
        let (lengths, end) = ends[side]?;
        Some((lengths, hip_from_ankle(state, ctx, side, forward)?, end))
    };
    Some(Plan {
        start_secs: state.time_secs,
        progress: 0.0,
        last_secs: state.time_secs,
        legs: [leg(0)?, leg(1)?],
        split: MassSplit::measure(state, ctx, forward)?,
        pitch: pelvis_pitch(state, forward),
        pitch_at: state.time_secs,
        pitch_lag: 0.0,
        out_of_lean: false,
        room: Room::of(ctx),
        feed_forward: FeedForward::default(),
        com_target_m: com_target(state, ctx, forward),
        base: ctx.stand.clone(),
        seated_at: None,
        descended_at: None,
    })
}

impl Controller for Sit {
    fn name(&self) -> &'static str {
        "sit"
    }
    fn preference(&self) -> u32 {
        20
    }
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32 {
        let Some(seat) = ctx.seat else { return 0 };
        // Already on the seat (a rise that was refused or gave up): hold the figure seated
        // if it has the legs a plan needs (else it would fail at once). Sitting tilted past
        // the hold, it is not standing balanced either, so it gets no bid below.
        let ends = seated_hips(state, ctx, &seat);
        if held_on_seat(state, ctx) {
            return if ends.iter().all(Option::is_some) { BID_SENSIBLE } else { 0 };
        }
        let (forward, _) = facing(state, ctx);
        let standing = state.foot_down[0]
            && state.foot_down[1]
            && super::balance::balanced(state, ctx, 0.02, 30f32.to_radians().cos(), 0.8);
        // Facing away from the seat, its front edge behind both soles' centres.
        let behind = seat.forward.dot(forward) > 0.7
            && (0..2).all(|s| (seat.front_edge() - state.sole_centre[s]).dot(forward) < -0.02);
        let reach =
            ends.iter().all(|h| h.is_some_and(|(l, hip)| hip.length() < 0.98 * (l.thigh_m + l.shank_m) && hip.y > 0.0));
        if standing && behind && reach { BID_CAN_REACH } else { 0 }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        self.plan = plan(state, ctx);
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        let (Some(plan), Some(seat)) = (&mut self.plan, ctx.seat) else {
            return Status::Failed("no seat, or the figure lacks a full pair of legs".into());
        };
        if state.trunk_upright < FAIL_TRUNK_RAD.cos() {
            return Status::Failed("the trunk tilted past 75°".into());
        }
        let t = state.time_secs - plan.start_secs;
        let sitting = seat.sitting(ctx.figure, state);
        let descended_for = if plan.progress >= 1.0 {
            state.time_secs - *plan.descended_at.get_or_insert(state.time_secs)
        } else {
            0.0
        };
        if !sitting && descended_for > MISS_SECS {
            return Status::Failed("missed the seat".into());
        }
        if !sitting && t > MAX_SIT_SECS {
            return Status::Failed(format!("not seated {MAX_SIT_SECS} s after starting to sit"));
        }
        let (forward, _) = facing(state, ctx);
        let f2 = Vec2::new(forward.x, forward.z);
        // How far the capture point is ahead of the heels, and how much of the way down the
        // hips still have to go (1 up to FADE_M above the end, 0 at it).
        let heel = heel_along(state, forward);
        let ahead = if heel.is_finite() { state.capture_point.dot(f2) - heel } else { 0.0 };
        let above = hip_from_ankle(state, ctx, 0, forward).map_or(0.0, |hip| hip.y - plan.legs[0].2.y);
        let fade = (above / FADE_M).clamp(0.0, 1.0);
        // The descent waits while the capture point nears the heels or the lean lags.
        // Once no lean can keep the COM over the feet (the hips at their flexion limit), the
        // figure lets itself down onto the seat without waiting.
        let keeping_up = (1.0 - plan.pitch_lag / MAX_PITCH_LAG_RAD).clamp(0.0, 1.0);
        let wait = fade * (ahead / HEEL_MARGIN_M).clamp(0.0, 1.0) * keeping_up + (1.0 - fade);
        let warp = if plan.out_of_lean { 1.0 } else { wait };
        plan.progress = (plan.progress + warp * (state.time_secs - plan.last_secs) / SIT_SECS).min(1.0);
        plan.last_secs = state.time_secs;
        let s = smooth(plan.progress);
        if sitting && plan.seated_at.is_none() {
            plan.seated_at = Some(state.time_secs);
        }
        // Lean as far as keeps the COM over the feet until the seat carries the figure,
        // then come upright.
        let upright = plan.seated_at.map_or(0.0, |t0| smooth((state.time_secs - t0) / UPRIGHT_SECS));
        let planned: [(LegLengths, Vec2); 2] = plan.legs.map(|(lengths, from, to)| (lengths, from.lerp(to, s)));
        // The lean for the planned hip, not where the capped angles put it: the legs' lean at
        // the ankles (below) holds the hips on their path.
        let (lengths, hip) = planned[0];
        let (thigh, shank) = lengths.angles_within(hip, plan.room.shank_rad);
        let most = SIT_PITCH_RAD.min(thigh + plan.room.hip_flexion_rad);
        let knee = lengths.knee_at(shank);
        plan.out_of_lean = plan.split.pitch_for(hip, knee, plan.com_target_m, std::f32::consts::PI) > most;
        let balanced = plan.split.pitch_for(hip, knee, plan.com_target_m, most);
        // Rate-limited: a sudden lean throws the COM forward onto the toes, and the ankles'
        // pull back then throws it behind the heels.
        let dt = (state.time_secs - plan.pitch_at).max(0.0);
        let step = PITCH_RATE_RAD_S * dt;
        plan.pitch = plan.pitch + (balanced * (1.0 - upright) - plan.pitch).clamp(-step, step);
        plan.pitch_at = state.time_secs;
        plan.pitch_lag = (balanced * (1.0 - upright) - plan.pitch).abs();
        let pitch = plan.pitch;
        targets.clone_from(&plan.base);
        for (side, (lengths, hip)) in planned.into_iter().enumerate() {
            // The hips held on their path by leaning the legs at the ankles.
            let now = hip_from_ankle(state, ctx, side, forward).unwrap_or(hip);
            let lean = fade * (K_TRACK * (hip.x - now.x)).clamp(-0.2, 0.2);
            let (thigh, shank) = lengths.angles_within(hip, plan.room.shank_rad - lean.max(0.0));
            set_leg(targets, &plan.base, ctx, side, (thigh + lean, shank + lean), pitch + lean);
        }
        plan.feed_forward.apply(targets, state.time_secs);
        Status::Running
    }
}
