//! Sagittal leg postures for the sit and rise controllers: where each hip should be
//! relative to its ankle (forward and up in the figure's facing) and how far the pelvis
//! leans, turned into hip, knee and ankle targets with the foot kept as it stands.
//!
//! Angles are rotations about the figure's left (rest-pose axes), positive tilting "up"
//! forward: a bone hanging down at angle φ points along (forward, up) = (−sin φ, −cos φ), so
//! a thigh with the knee ahead of the hip has φ < 0 and a shank with the ankle behind the
//! knee φ > 0; a pelvis pitch p > 0 leans the trunk forward.

use glam::{Quat, Vec2, Vec3};

use super::leg;
use crate::kernels::physics::controller::{ControlContext, Targets};
use crate::kernels::physics::figure::{BodyRole, JointKind, MIN_BONE_M};
use crate::kernels::physics::state::FigureState;
use crate::math::smoothstep;

/// The shank leans forward by at most this much when sitting or rising, radians (the
/// ankle's dorsiflexion limit is 0.35 from standing; [`Room`] lowers it for a figure that
/// stands with its ankles already bent).
pub const MAX_SHANK_RAD: f32 = 0.3;

/// A leg's lengths: hip to knee and knee to ankle, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LegLengths {
    /// Hip to knee, metres.
    pub thigh_m: f32,
    /// Knee to ankle, metres.
    pub shank_m: f32,
}

impl LegLengths {
    /// The lengths of `side`'s leg at rest, `None` without a full leg or with a bone shorter
    /// than [`MIN_BONE_M`].
    pub fn of(ctx: &ControlContext<'_>, side: usize) -> Option<LegLengths> {
        let (_, shank, foot) = leg(ctx, side)?;
        let bodies = &ctx.figure.bodies;
        let (thigh_m, shank_m) = (bodies[shank].anchor_in_parent.length(), bodies[foot].anchor_in_parent.length());
        // Bones too short to bend about would make the knee's cosine rule divide by zero.
        (thigh_m >= MIN_BONE_M && shank_m >= MIN_BONE_M).then_some(LegLengths { thigh_m, shank_m })
    }

    /// The world angles (thigh φ₁, shank φ₂) that put the hip at `hip` = (forward, up)
    /// from the ankle with the knee bending forward, as a person's does. A hip out of reach
    /// is brought within it along the same direction (leg straight, or folded to the
    /// shortest the two bones allow).
    pub fn angles(&self, hip: Vec2) -> (f32, f32) {
        let (l1, l2) = (self.thigh_m, self.shank_m);
        let d = hip.length().clamp((l1 - l2).abs() + 1e-3, (l1 + l2) * 0.9999);
        let u = hip.try_normalize().unwrap_or(Vec2::Y);
        // Angle at the ankle between the ankle–hip line and the shank (cosine rule).
        let alpha = ((l2 * l2 + d * d - l1 * l1) / (2.0 * l2 * d)).clamp(-1.0, 1.0).acos();
        // The shank turned from the ankle–hip line towards forward: the knee ahead.
        let (s, c) = alpha.sin_cos();
        let knee = Vec2::new(u.x * c + u.y * s, -u.x * s + u.y * c) * l2;
        let hip = u * d;
        let thigh = (hip.x - knee.x).atan2(hip.y - knee.y);
        let shank = knee.x.atan2(knee.y);
        (thigh, shank)
    }

    /// Where the hip is from the ankle, (forward, up), for thigh and shank world angles
    /// (forward kinematics of [`angles`](Self::angles)).
    pub fn hip_at(&self, (thigh_rad, shank_rad): (f32, f32)) -> Vec2 {
        // Up the shank to the knee, then up the thigh: a bone at angle φ points down along
        // (−sin φ, −cos φ).
        self.knee_at(shank_rad) + Vec2::new(thigh_rad.sin(), thigh_rad.cos()) * self.thigh_m
    }

    /// The knee from the ankle, (forward, up) metres, with the shank leaning forward by
    /// `shank_rad`.
    pub fn knee_at(&self, shank_rad: f32) -> Vec2 {
        Vec2::new(shank_rad.sin(), shank_rad.cos()) * self.shank_m
    }

    /// [`angles`](Self::angles) with the shank leaning forward (the ankle dorsiflexed) by
    /// at most `max_shank_rad`: past it the hip goes back at the same height instead, as a
    /// person's does when the ankle is at its limit.
    pub fn angles_within(&self, hip: Vec2, max_shank_rad: f32) -> (f32, f32) {
        let (thigh, shank) = self.angles(hip);
        if shank <= max_shank_rad {
            return (thigh, shank);
        }
        let knee = self.knee_at(max_shank_rad);
        let rise = (hip.y - knee.y).clamp(-self.thigh_m, self.thigh_m);
        let back = (self.thigh_m * self.thigh_m - rise * rise).sqrt();
        // The thigh from the hip, `back` behind and `rise` above the knee, down to it.
        ((-back).atan2(rise), max_shank_rad)
    }
}

/// The figure's mass split at the hips, measured in a state: the legs' masses, and the
/// upper body's (pelvis, trunk, head and arms) mass and centre of mass seen from the hips'
/// midpoint in the sagittal plane, relative to the pelvis's pitch. It predicts where the
/// whole-body COM will be for a planned hip position and pelvis pitch, which is what a
/// sitting or rising figure must keep over its feet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassSplit {
    /// Upper body mass, kilograms.
    pub upper_kg: f32,
    /// Distance from the hips' midpoint to the upper body's COM (sagittal), metres.
    pub upper_reach_m: f32,
    /// Angle of that COM from the pelvis's up axis, forward positive, radians.
    pub upper_angle_rad: f32,
    /// Both thighs, both shanks and both feet, kilograms.
    pub leg_kg: [f32; 3],
    /// The feet's COM forward of the ankles, metres.
    pub feet_forward_m: f32,
}

impl MassSplit {
    /// Measures the split in `state`, facing `forward`; `None` without two full legs.
    pub fn measure(state: &FigureState, ctx: &ControlContext<'_>, forward: Vec3) -> Option<MassSplit> {
        let legs = [leg(ctx, 0)?, leg(ctx, 1)?];
        let hips = (state.body_pos[legs[0].0] + state.body_pos[legs[1].0]) * 0.5;
        let ankles = (state.body_pos[legs[0].2] + state.body_pos[legs[1].2]) * 0.5;
        let (mut upper_kg, mut upper_com, mut leg_kg, mut feet_com) = (0.0f32, Vec3::ZERO, [0.0f32; 3], Vec3::ZERO);
        for (i, body) in ctx.figure.bodies.iter().enumerate() {
            let com = state.body_pos[i] + state.body_rot[i] * body.com_local;
            let part = legs.iter().find_map(|&(t, s, f)| [t, s, f].iter().position(|&b| b == i));
            match part {
                Some(k) => {
                    leg_kg[k] += body.mass_kg;
                    if k == 2 {
                        feet_com += com * body.mass_kg;
                    }
                }
                None => {
                    upper_kg += body.mass_kg;
                    upper_com += com * body.mass_kg;
                }
            }
        }
        let r = upper_com / upper_kg.max(1e-6) - hips;
        let r = Vec2::new(r.dot(forward), r.y);
        Some(MassSplit {
            upper_kg,
            upper_reach_m: r.length(),
            upper_angle_rad: r.x.atan2(r.y) - pelvis_pitch(state, forward),
            leg_kg,
            feet_forward_m: (feet_com / leg_kg[2].max(1e-6) - ankles).dot(forward),
        })
    }

    /// The whole-body COM's forward distance from the ankles with the hips at `hip` and the
    /// knees at `knee` (forward, up from the ankles) and the pelvis pitched by `pitch_rad`.
    pub fn com_forward(&self, hip: Vec2, knee: Vec2, pitch_rad: f32) -> f32 {
        let upper = hip.x + self.upper_reach_m * (pitch_rad + self.upper_angle_rad).sin();
        let [thighs, shanks, feet] = self.leg_kg;
        let sum = self.upper_kg * upper
            + thighs * 0.5 * (hip.x + knee.x)
            + shanks * 0.5 * knee.x
            + feet * self.feet_forward_m;
        sum / (self.upper_kg + thighs + shanks + feet).max(1e-6)
    }

    /// The pelvis pitch that puts the COM `com_forward_m` ahead of the ankles for that hip and
    /// knee, clamped to `[0, max_rad]` (a pitch that cannot get it there leans all the way;
    /// a negative `max_rad`, hips already past their limit, allows none).
    pub fn pitch_for(&self, hip: Vec2, knee: Vec2, com_forward_m: f32, max_rad: f32) -> f32 {
        // com_forward is affine in sin(pitch + angle): solve for it.
        let at = |p: f32| self.com_forward(hip, knee, p);
        let slope = at(std::f32::consts::FRAC_PI_2 - self.upper_angle_rad) - at(-self.upper_angle_rad);
        if slope <= 1e-6 {
            return 0.0;
        }
        let sin = ((com_forward_m - at(-self.upper_angle_rad)) / slope).clamp(-1.0, 1.0);
        (sin.asin() - self.upper_angle_rad).clamp(0.0, max_rad.max(0.0))
    }
}

/// Where `side`'s hip is relative to its ankle, (forward, up) metres, facing `forward`.
pub fn hip_from_ankle(state: &FigureState, ctx: &ControlContext<'_>, side: usize, forward: Vec3) -> Option<Vec2> {
    let (thigh, _, foot) = leg(ctx, side)?;
    let d = state.body_pos[thigh] - state.body_pos[foot];
    Some(Vec2::new(d.dot(forward), d.y))
}

/// The pelvis's forward lean from vertical, radians (positive forward), facing `forward`.
pub fn pelvis_pitch(state: &FigureState, forward: Vec3) -> f32 {
    let up = state.body_rot[0] * Vec3::Y;
    up.dot(forward).atan2(up.y)
}

/// Sets `side`'s hip, knee and ankle targets for thigh and shank world angles (φ₁, φ₂) and
/// pelvis pitch `pitch_rad`, bending the leg of `base` (its standing targets): the thigh,
/// shank and foot keep their standing twist and splay, the foot its standing orientation
/// in the world.
pub fn set_leg(
    targets: &mut Targets,
    base: &Targets,
    ctx: &ControlContext<'_>,
    side: usize,
    (thigh_rad, shank_rad): (f32, f32),
    pitch_rad: f32,
) {
    let Some((thigh, shank, foot)) = leg(ctx, side) else { return };
    let figure = ctx.figure;
    let rel = |b: usize| base.relative(figure, b);
    let turn = |a: f32| Quat::from_axis_angle(figure.left, a);
    let (st, ss, sf) = (rel(thigh), rel(shank), rel(foot));
    // World rotations: pelvis R(p), thigh R(φ₁)·St, shank R(φ₂)·St·Ss, foot St·Ss·Sf (as
    // standing), each relative to its parent.
    targets.set_relative(figure, thigh, turn(thigh_rad - pitch_rad) * st);
    targets.set_relative(figure, shank, st.inverse() * turn(shank_rad - thigh_rad) * st * ss);
    targets.set_relative(figure, foot, (st * ss).inverse() * turn(-shank_rad) * st * ss * sf);
}

/// The contact polygon's rearmost point along `forward` (a world position projected on it,
/// metres); `+∞` without contact.
pub fn heel_along(state: &FigureState, forward: Vec3) -> f32 {
    state.contact.iter().map(|v| v.dot(Vec2::new(forward.x, forward.z))).fold(f32::INFINITY, f32::min)
}

/// The contact polygon's centre forward of the ankles' midpoint, metres.
pub fn com_target(state: &FigureState, ctx: &ControlContext<'_>, forward: Vec3) -> f32 {
    let ankles: Vec3 = (0..2).filter_map(|side| Some(state.body_pos[leg(ctx, side)?.2])).sum::<Vec3>() * 0.5;
    state.contact_centre().dot(Vec2::new(forward.x, forward.z)) - ankles.dot(forward)
}

/// How far the body may bend from standing before a joint limit: the shank's forward lean
/// (ankle dorsiflexion) and the hip's flexion, radians, less a margin of 0.05; and how far
/// the spine bends forward at most.
#[derive(Clone, Copy, Debug)]
pub struct Room {
    /// Forward lean of the shank, radians.
    pub shank_rad: f32,
    /// Hip flexion, radians.
    pub hip_flexion_rad: f32,
    /// Forward bend of the whole spine, radians ([`MAX_SPINE_BEND_RAD`] per segment).
    pub spine_rad: f32,
}

impl Room {
    /// The room of the figure's legs from its standing targets, the shank's capped at
    /// [`MAX_SHANK_RAD`].
    pub fn of(ctx: &ControlContext<'_>) -> Room {
        let room = |b: usize| match ctx.figure.bodies[b].kind {
            // Flexing the hip and dorsiflexing the ankle both turn the joint's X coordinate
            // down (a rotation about the figure's left).
            JointKind::Ball { limits_rad } => ctx.stand.angles[b][0] - limits_rad[0][0] - 0.05,
            _ => f32::INFINITY,
        };
        let (mut shank_rad, mut hip_flexion_rad) = (MAX_SHANK_RAD, f32::INFINITY);
        for side in 0..2 {
            if let Some((thigh, _, foot)) = leg(ctx, side) {
                shank_rad = shank_rad.min(room(foot));
                hip_flexion_rad = hip_flexion_rad.min(room(thigh));
            }
        }
        Room {
            shank_rad: shank_rad.max(0.0),
            hip_flexion_rad,
            spine_rad: spine(ctx).count() as f32 * MAX_SPINE_BEND_RAD,
        }
    }
}

/// Velocity feed-forward for a controller whose targets move: each motor is given its
/// target's rate of change, so the joints do not trail a moving target by a damping time.
#[derive(Default)]
pub struct FeedForward {
    last: Option<(Vec<[f32; 3]>, f32)>,
    rate: Vec<[f32; 3]>,
}

/// Time constant of the feed-forward's smoothing, seconds.
pub const FEED_FORWARD_SMOOTH_SECS: f32 = 0.05;
/// Largest feed-forward joint rate, rad/s.
pub const MAX_FEED_FORWARD_RAD_S: f32 = 3.0;

impl FeedForward {
    /// Sets `targets.velocity` from the change since the previous call, at `time_secs`.
    pub fn apply(&mut self, targets: &mut Targets, time_secs: f32) {
        if let Some((was, at)) = &self.last {
            let dt = time_secs - at;
            if dt > 0.0 {
                // Smoothed and bounded: a feedback term that jumps must not become a kick.
                let keep = (-dt / FEED_FORWARD_SMOOTH_SECS).exp();
                for (i, (now, was)) in targets.angles.iter().zip(was).enumerate() {
                    let rate: [f32; 3] = std::array::from_fn(|k| {
                        let raw = ((now[k] - was[k]) / dt).clamp(-MAX_FEED_FORWARD_RAD_S, MAX_FEED_FORWARD_RAD_S);
                        keep * self.rate.get(i).map_or(0.0, |r| r[k]) + (1.0 - keep) * raw
                    });
                    targets.velocity[i] = rate;
                }
                self.rate.clone_from(&targets.velocity);
            }
        }
        // The previous targets kept in place: no allocation per control step.
        match &mut self.last {
            Some((was, at)) => {
                was.clone_from(&targets.angles);
                *at = time_secs;
            }
            None => self.last = Some((targets.angles.clone(), time_secs)),
        }
    }
}

/// Forward bend of each spine segment at most, radians (its limit is 0.8).
pub const MAX_SPINE_BEND_RAD: f32 = 0.7;

/// The spine's segments (abdomen, chest), the bodies that bend the trunk above the pelvis.
fn spine<'a>(ctx: &'a ControlContext<'_>) -> impl Iterator<Item = usize> + 'a {
    ctx.figure
        .bodies
        .iter()
        .enumerate()
        .filter(|(_, b)| matches!(b.role, BodyRole::Abdomen | BodyRole::Chest))
        .map(|(i, _)| i)
}

/// Leans the trunk forward by `lean_rad` from `base`: the pelvis pitches by up to
/// `pelvis_most_rad` (what the hips' flexion allows), the spine segments bend evenly for
/// the rest, each by at most [`MAX_SPINE_BEND_RAD`]. Returns the pelvis pitch, for the legs.
pub fn set_trunk(
    targets: &mut Targets,
    base: &Targets,
    ctx: &ControlContext<'_>,
    lean_rad: f32,
    pelvis_most_rad: f32,
) -> f32 {
    let pelvis = lean_rad.min(pelvis_most_rad.max(0.0));
    let bend = ((lean_rad - pelvis) / spine(ctx).count().max(1) as f32).clamp(0.0, MAX_SPINE_BEND_RAD);
    for b in spine(ctx) {
        targets.set_relative(
            ctx.figure,
            b,
            Quat::from_axis_angle(ctx.figure.left, bend) * base.relative(ctx.figure, b),
        );
    }
    pelvis
}

/// Raises both arms forward, `amount` of the way from hanging down (0) to level in front (1),
/// facing `forward`: reaching forward moves the COM forward by several centimetres, which is
/// what lets a seated figure bring it over its feet.
pub fn reach_forward(targets: &mut Targets, ctx: &ControlContext<'_>, state: &FigureState, forward: Vec3, amount: f32) {
    let dir = (Vec3::NEG_Y * (1.0 - amount) + forward * amount).normalize_or(Vec3::NEG_Y);
    for (i, body) in ctx.figure.bodies.iter().enumerate() {
        if let (BodyRole::UpperArm, Some(parent)) = (body.role, body.parent) {
            targets.aim(ctx.figure, i, state.body_rot[parent], dir);
        }
    }
}

/// Smooth step from 0 to 1 over `x` in [0, 1] ([`smoothstep`] in f32).
pub fn smooth(x: f32) -> f32 {
    smoothstep(f64::from(x)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Forward kinematics of the two angles, written out independently.
    fn hip_of(l: LegLengths, (t, s): (f32, f32)) -> Vec2 {
        // From the ankle up the shank to the knee, then up the thigh to the hip.
        let down = |phi: f32| Vec2::new(-phi.sin(), -phi.cos());
        -(down(s) * l.shank_m) - down(t) * l.thigh_m
    }

    #[test]
    fn leg_angles_put_the_hip_where_asked_with_the_knee_forward() {
        let l = LegLengths { thigh_m: 0.42, shank_m: 0.40 };
        for hip in [Vec2::new(0.0, 0.8), Vec2::new(-0.35, 0.4), Vec2::new(-0.1, 0.6), Vec2::new(0.1, 0.7)] {
            let (t, s) = l.angles(hip);
            assert!(hip_of(l, (t, s)).distance(hip) < 1e-5, "{hip}: {:?}", hip_of(l, (t, s)));
            assert!(l.hip_at((t, s)).distance(hip) < 1e-5, "{hip}: {:?}", l.hip_at((t, s)));
            // The knee is ahead of the ankle–hip line.
            let knee = Vec2::new(s.sin(), s.cos()) * l.shank_m;
            assert!(hip.perp_dot(knee) < 0.0, "{hip}: knee {knee}");
        }
        // Sitting with the thigh level and the shank vertical: hip 0.42 m behind, 0.40 up.
        let (t, s) = l.angles(Vec2::new(-0.42, 0.40));
        assert!((t + std::f32::consts::FRAC_PI_2).abs() < 1e-4 && s.abs() < 1e-4, "{t} {s}");
        // The ankle at its limit: the shank leans 0.3 rad and the hip goes back instead.
        let hip = Vec2::new(0.0, 0.6);
        let (t, s) = l.angles_within(hip, 0.3);
        let got = hip_of(l, (t, s));
        assert!((s - 0.3).abs() < 1e-6 && (got.y - 0.6).abs() < 1e-5 && got.x < -0.2, "{got}");
        assert_eq!(l.angles_within(Vec2::new(-0.42, 0.40), 0.3), l.angles(Vec2::new(-0.42, 0.40)));
        // The pitch that the mass split solves for puts the COM where asked.
        let split = MassSplit {
            upper_kg: 45.0,
            upper_reach_m: 0.33,
            upper_angle_rad: 0.05,
            leg_kg: [21.0, 6.5, 2.1],
            feet_forward_m: 0.05,
        };
        let (hip, knee) = (Vec2::new(-0.25, 0.6), l.knee_at(0.3));
        let p = split.pitch_for(hip, knee, 0.0, 1.5);
        assert!(split.com_forward(hip, knee, p).abs() < 1e-5 && p > 0.3, "{p}");
        // Written out by hand: 45·(−0.25 + 0.33·sin(p + 0.05)) + 21·(−0.25 + kx)/2 + 6.5·kx/2 + 2.1·0.05 = 0.
        let kx = knee.x;
        let by_hand =
            ((0.25 * 45.0 - 21.0 * (-0.25 + kx) / 2.0 - 6.5 * kx / 2.0 - 2.1 * 0.05) / (45.0 * 0.33)).asin() - 0.05;
        assert!((p - by_hand).abs() < 1e-5, "{p} vs {by_hand}");
        // Out of reach: the leg straight along the same line.
        let (t, s) = l.angles(Vec2::new(0.0, 2.0));
        assert!(t.abs() < 2e-2 && s.abs() < 2e-2, "{t} {s}");
    }
}
