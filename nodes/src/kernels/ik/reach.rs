//! Soft reach: a limb's goal eased towards full stretch, so the middle joint never snaps.
//!
//! A two-bone limb (thigh `a`, shin `b`) reaching a point at distance `d` from its root puts
//! its middle joint `h = √(a² − x²)` off the root–goal line (equal bones, `x = d/2`), and
//! `dh/dd = −x / (2h)` grows without bound as the limb straightens. A goal that crosses the
//! limb's length `L = a + b` (a plant coming into or going out of reach) therefore throws the
//! knee sideways in one frame: on a CMU walk carried onto Xbot, 4.6 cm in a frame at 120 fps
//! (a 618 m/s² spike) where the ankle moved 4 mm.
//!
//! The goal's distance is replaced by
//!
//! ```text
//! d' = d                              for d ≤ L − s
//! d' = L − s · exp(−(d − (L − s)) / s)  beyond,
//! ```
//!
//! continuous with its first derivative at `L − s`, always below `L` (the limb never locks
//! straight) and approaching it as `d` grows. With `h ≈ √(a·(L − d'))` near the stretch, the
//! knee's speed per unit of goal speed stays below about `½·√(a / s)`: the softness `s` trades
//! how exactly a far goal is met (at most `s/e` short of `d = L`) for how calmly the knee moves.
//! This is the "soft IK" used by game engines' leg rigs.

use glam::DVec3;

/// `distance` eased towards `length` beyond `eased_from` (module doc, with `s = length −
/// eased_from`); `eased_from` ≥ `length` keeps the distance as it is (a hard reach).
pub fn soft_reach(distance: f64, eased_from: f64, length: f64) -> f64 {
    let softness = length - eased_from;
    if softness <= 0.0 || distance <= eased_from {
        return distance;
    }
    length - softness * (-(distance - eased_from) / softness).exp()
}

/// `goal` moved so that its distance from `root` is [`soft_reach`]'s: along `up` (a unit
/// vector; a planted foot rises a little rather than sliding), or, when no point along `up`
/// is at that distance, along the line from `root`.
pub fn soft_goal(root: DVec3, goal: DVec3, eased_from: f64, length: f64, up: DVec3) -> DVec3 {
    let to_goal = goal - root;
    let distance = to_goal.length();
    let eased = soft_reach(distance, eased_from, length);
    if distance <= f64::EPSILON || eased >= distance {
        return goal;
    }
    // |to_goal + t·up| = eased, the root of t² + 2t(to_goal·up) + |to_goal|² − eased² = 0
    // nearest zero (the goal moves as little as it can).
    let along = to_goal.dot(up);
    let discriminant = along * along - (distance * distance - eased * eased);
    if discriminant >= 0.0 {
        let t = -along - discriminant.sqrt();
        if t.is_finite() && t >= 0.0 {
            return goal + up * t;
        }
    }
    root + to_goal * (eased / distance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_eased_distance_is_c1_below_the_length_and_meets_the_hand_solved_values() {
        let (length, softness) = (0.9, 0.02);
        let knee = length - softness;
        let soft_reach = |d: f64, length: f64, softness: f64| soft_reach(d, length - softness, length);
        // Inside: unchanged. At d = L: L − s/e. Far out: within s·e⁻¹⁰ of L.
        assert_eq!(soft_reach(0.5, length, softness), 0.5);
        assert_eq!(soft_reach(knee, length, softness), knee);
        assert!((soft_reach(length, length, softness) - (length - softness / std::f64::consts::E)).abs() < 1e-15);
        let far = knee + 10.0 * softness;
        assert!((soft_reach(far, length, softness) - (length - softness * (-10.0f64).exp())).abs() < 1e-15);
        // Slope 1 on both sides of the knee point, by finite differences.
        let h = 1e-7;
        let below = (soft_reach(knee, length, softness) - soft_reach(knee - h, length, softness)) / h;
        let above = (soft_reach(knee + h, length, softness) - soft_reach(knee, length, softness)) / h;
        assert!((below - 1.0).abs() < 1e-6 && (above - 1.0).abs() < 1e-5, "{below} {above}");
        // Strictly increasing and below the length beyond (over 15 softness widths: further
        // out the gap to L falls under the doubles' resolution).
        let mut last = knee;
        for k in 1..300 {
            let d = soft_reach(knee + f64::from(k) * 1e-3, length, softness);
            assert!(d > last && d < length, "{d} at step {k}");
            last = d;
        }
        assert_eq!(soft_reach(2.0, length, 0.0), 2.0, "no softness: a hard reach");
    }

    #[test]
    fn a_goal_rises_or_else_is_pulled_along_its_line_from_the_root() {
        let root = DVec3::new(1.0, 2.0, 3.0);
        let goal = root + DVec3::new(0.0, -0.6, 0.8); // 1.0 away
        let want = 1.0 - 0.1 / std::f64::consts::E;
        // Straight up from a goal below and beside the root: x and z kept, y raised until
        // (0.6 − t)² + 0.8² = want², i.e. t = 0.6 − √(want² − 0.64).
        let raised = soft_goal(root, goal, 0.9, 1.0, DVec3::Y);
        assert!(((raised - root).length() - want).abs() < 1e-12);
        assert!((raised.y - (goal.y + 0.6 - (want * want - 0.64).sqrt())).abs() < 1e-12, "{raised}");
        assert_eq!((raised.x, raised.z), (goal.x, goal.z));
        // Sideways from the root (nothing along up reaches): along the line instead.
        let level = root + DVec3::new(1.0, 0.0, 0.0);
        let pulled = soft_goal(root, level, 0.9, 1.0, DVec3::NEG_Z);
        assert!((pulled - (root + DVec3::new(want, 0.0, 0.0))).length() < 1e-12, "{pulled}");
        assert_eq!(soft_goal(root, root, 0.9, 1.0, DVec3::Y), root);
        assert_eq!(soft_goal(root, goal, 1.0, 1.0, DVec3::Y), goal, "a hard reach leaves the goal");
    }

    /// A straight two-bone leg (0.45 + 0.45 m) whose ankle goal sweeps outwards through full
    /// stretch at 1 m/s, sampled at 120 fps, the knee placed in closed form: with a hard reach
    /// the knee's peak acceleration is the snap; eased over 2 cm it falls by more than 10×.
    #[test]
    fn easing_calms_the_knee_of_a_leg_swept_through_full_stretch() {
        let (bone, fps) = (0.45, 120.0);
        let knee_offset = |d: f64| (bone * bone - (d / 2.0) * (d / 2.0)).max(0.0).sqrt();
        let peak = |softness: f64| {
            let track: Vec<f64> = (0..120)
                .map(|f| {
                    let d = soft_reach(0.80 + f64::from(f) / fps, 2.0 * bone - softness, 2.0 * bone);
                    knee_offset(d.min(2.0 * bone))
                })
                .collect();
            track.windows(3).map(|w| ((w[0] - 2.0 * w[1] + w[2]) * fps * fps).abs()).fold(0.0, f64::max)
        };
        let (hard, soft) = (peak(0.0), peak(0.02));
        assert!(hard > 10.0 * soft, "hard reach {hard:.1} m/s², soft {soft:.1} m/s²");
    }
}
