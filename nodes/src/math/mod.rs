//! Maths helpers shared by every kernel.
//!
//! # Conventions glossary
//! - **Handedness and axes**: right-handed, **Y up**, the character faces **+Z** by default
//!   (glTF's convention). Importers of other conventions convert on load.
//! - **Units**: lengths in **metres**, time in **seconds**, angles in **radians** inside the
//!   engine. BVH files store degrees; they are converted at the file boundary only.
//! - **Quaternions**: `glam::Quat` (x, y, z, w), unit length, rotating column vectors:
//!   `v' = q * v`. `a * b` applies `b` first, then `a`.
//! - **Euler orders**: named by the order the rotations are *written* in a BVH `CHANNELS`
//!   line; `Zrotation Xrotation Yrotation` means `R = Rz · Rx · Ry` (intrinsic, applied to
//!   column vectors), see [`euler`].
//! - **Spaces**: *local* = relative to the parent joint (what a clip stores), *model* =
//!   relative to the skeleton root's parent (what forward kinematics returns), *world* =
//!   model space placed in the scene; this crate keeps the skeleton at the world origin, so
//!   model and world coincide unless a node says otherwise. Names carry the space:
//!   `world_from_joint` maps joint-space points into world space.
//! - **Frames**: frame `i` of a clip sits at time `i / fps` seconds; frame rates are `f64`.

pub mod euler;
pub mod nnls;
pub mod solid;

use glam::Quat;

/// Tolerance for results that should agree to float round-off (unit-quaternion norms,
/// exact round trips of small values).
pub const EXACT_TOL: f32 = 1e-5;

/// Tolerance for results that agree up to accumulated f32 error over long joint chains
/// or numerical methods (metres or radians).
pub const APPROX_TOL: f32 = 1e-3;

/// Normalises `q`, falling back to the identity when it has (near) zero or non-finite
/// length, so a degenerate rotation never turns into NaN downstream.
pub fn quat_normalize_or_identity(q: Quat) -> Quat {
    let len_sq = q.length_squared();
    if len_sq.is_finite() && len_sq > 1e-20 { q * len_sq.sqrt().recip() } else { Quat::IDENTITY }
}

/// `3u² − 2u³` on `u` clamped to [0, 1]: a ramp from 0 to 1 with zero slope at both ends,
/// so a blend weight or a time warp built on it is C1 where it meets constant segments.
pub fn smoothstep(u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    u * u * (3.0 - 2.0 * u)
}

/// `6u⁵ − 15u⁴ + 10u³` on `u` clamped to [0, 1]: a ramp from 0 to 1 whose slope and
/// curvature vanish at both ends, so what moves along a blend built on it starts and stops
/// accelerating gradually (C2) instead of taking the whole acceleration in one frame.
pub fn smootherstep(u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    u * u * u * (u * (6.0 * u - 15.0) + 10.0)
}

/// Spherical interpolation that takes the short way round and never returns NaN.
pub fn slerp_short(a: Quat, b: Quat, t: f32) -> Quat {
    let b = if a.dot(b) < 0.0 { -b } else { b };
    quat_normalize_or_identity(a.slerp(b, t))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normalize_degenerate_quaternions_gives_identity() {
        assert_eq!(quat_normalize_or_identity(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)), Quat::IDENTITY);
        assert_eq!(quat_normalize_or_identity(Quat::from_xyzw(f32::NAN, 0.0, 0.0, 1.0)), Quat::IDENTITY);
        let q = quat_normalize_or_identity(Quat::from_xyzw(0.0, 0.0, 2.0, 0.0));
        assert!((q.z - 1.0).abs() < EXACT_TOL);
    }

    #[test]
    fn slerp_takes_the_short_arc() {
        let a = Quat::from_rotation_y(0.1);
        let b = -Quat::from_rotation_y(0.3); // same rotation, opposite hemisphere
        let mid = slerp_short(a, b, 0.5);
        assert!(mid.angle_between(Quat::from_rotation_y(0.2)) < EXACT_TOL * 10.0);
    }
}
