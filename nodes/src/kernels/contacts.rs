//! Foot contacts: when each foot rests on the ground, and when both do (double support).
//!
//! A foot is in contact while its ankle or its toe tip is near the height that point rests
//! at in the clip and moves slowly. Thresholds have hysteresis (stricter to enter than
//! to stay), so a foot that rests does not flicker in and out of contact on capture noise.
//! The rest height is taken per point from the clip itself: flat ground, any rig. The
//! thresholds are set for a leg of [`REFERENCE_LEG_M`] and scaled to the legs of the clip
//! watched ([`ContactThresholds::for_leg`]), so a child-sized character's lift-off is not
//! taken for a plant nor a giant's plant for a lift-off.
//!
//! A kernel: the `motion.contacts` node, the clip analysis, foot locking and the editor's
//! viewport all detect contacts with it.

use glam::DVec3;

use super::angular::central_difference;
use super::body::{Landmarks, limb_tip};
use super::roles::{RolesError, mean_limb_length_m, roles_of};
use crate::model::names::did_you_mean;
use crate::model::{
    Clip, ClipPoses, Contacts, FootContacts, FrameRange, Skeleton, intervals::intersect_all, intervals::union_all,
};

/// Foot joints named by the user where detection fails (an unusual rig): the ankles and the
/// toe points watched with them, left then right. `None`: the ankles come from the body
/// roles, the toes are the joints farthest below each ankle. Hands are watched only when
/// named.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NamedFeet {
    /// Ankle joints, left then right.
    pub ankles: Option<[usize; 2]>,
    /// Toe joints, left then right.
    pub toes: Option<[usize; 2]>,
    /// Hand (wrist) joints, left then right, for motions that put the hands down
    /// (cartwheels, crawls, push-ups): see [`hand_contacts`].
    pub hands: Option<[usize; 2]>,
}

/// Two joint names, `"Left, Right"` (comma separated, spaces trimmed), as joint indices;
/// empty text is `None`; an unknown name is refused with the nearest joint name.
pub fn joint_pair(skeleton: &Skeleton, text: &str) -> Result<Option<[usize; 2]>, String> {
    if text.trim().is_empty() {
        return Ok(None);
    }
    let names: Vec<&str> = text.split(',').map(str::trim).collect();
    let [left, right] = names[..] else {
        return Err(format!("expected two joint names, left then right, separated by a comma; got '{text}'"));
    };
    let find = |name: &str| {
        skeleton.index_of(name).ok_or_else(|| {
            format!("no joint named '{name}'{}", did_you_mean(name, skeleton.joints().iter().map(|j| j.name.as_str())))
        })
    };
    Ok(Some([find(left)?, find(right)?]))
}

/// Thresholds of contact detection (metres above the point's rest height, m/s), for legs
/// [`leg_m`](Self::leg_m) long.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactThresholds {
    /// A point enters contact below this height…
    pub enter_height_m: f64,
    /// …and moving slower than this.
    pub enter_speed_mps: f64,
    /// It leaves contact above this height…
    pub leave_height_m: f64,
    /// …or moving faster than this.
    pub leave_speed_mps: f64,
    /// Contacts shorter than this are dropped (seconds).
    pub min_duration_secs: f64,
    /// The leg length (hip to knee to ankle, metres) the heights and speeds are set for:
    /// detection scales them to the legs of the clip it watches. `None`: they are used as
    /// they are on any body.
    pub leg_m: Option<f64>,
}

impl Default for ContactThresholds {
    fn default() -> Self {
        ContactThresholds {
            enter_height_m: 0.05,
            enter_speed_mps: 0.5,
            leave_height_m: 0.08,
            leave_speed_mps: 0.9,
            min_duration_secs: 0.05,
            leg_m: Some(REFERENCE_LEG_M),
        }
    }
}

/// Leg length (hip to knee to ankle, metres) of the body the default thresholds were set
/// on: the subject of CMU 02_01, the corpus's reference walk.
pub const REFERENCE_LEG_M: f64 = 0.8377;

impl ContactThresholds {
    /// These thresholds for legs `leg_m` long rather than [`Self::leg_m`]: heights and
    /// speeds in proportion to the leg, the shortest contact unchanged; the result is for
    /// that leg. A motion carried onto another body keeps its timing, so its feet move in
    /// proportion to the body's size: scaled so, the thresholds find the plants the source
    /// had (speeds by the square root, as dynamic similarity would have for bodies moving
    /// alike at their own pace, missed a half-size copy's by 24 of 686 foot-frames on CMU
    /// 02_01). Thresholds for any body (`leg_m: None`) and a leg of no length keep them.
    pub fn for_leg(self, leg_m: f64) -> ContactThresholds {
        let Some(set_for) = self.leg_m else { return self };
        if !(leg_m > 0.0 && leg_m.is_finite() && set_for > 0.0) {
            return self;
        }
        let ratio = leg_m / set_for;
        ContactThresholds {
            enter_height_m: self.enter_height_m * ratio,
            enter_speed_mps: self.enter_speed_mps * ratio,
            leave_height_m: self.leave_height_m * ratio,
            leave_speed_mps: self.leave_speed_mps * ratio,
            min_duration_secs: self.min_duration_secs,
            leg_m: Some(leg_m),
        }
    }
}

/// The height a point rests at: the 10th percentile of its heights over the clip, so that
/// a few frames of capture noise or a foot poking through the floor do not set it.
pub fn ground_height(track: &[DVec3]) -> f64 {
    height_quantile(track, 10)
}

/// The height below which `percent` % of a track's frames lie (0 for an empty track).
fn height_quantile(track: &[DVec3], percent: usize) -> f64 {
    let mut heights: Vec<f64> = track.iter().map(|p| p.y).collect();
    heights.sort_by(f64::total_cmp);
    heights.get(heights.len() * percent / 100).copied().unwrap_or(0.0)
}

/// How far above the floor a hand may rest and still be taken as put down, in lift-off
/// heights ([`ContactThresholds::leave_height_m`]): capture skeletons often model the hand
/// coarsely (CMU's fingertip stays 14-15 cm up with the palm on the floor in 90_02).
const HAND_REACH_LIFTS: f64 = 3.0;

/// Joint `joint`'s world position in every frame of `poses`.
fn track(poses: &ClipPoses, joint: usize) -> Vec<DVec3> {
    (0..poses.frame_count()).map(|f| poses.position(f, joint).as_dvec3()).collect()
}

/// The fewest frames a contact lasts at `fps`.
fn min_frames(t: &ContactThresholds, fps: f64) -> usize {
    (t.min_duration_secs * fps).ceil() as usize
}

/// `intervals` (sorted, disjoint) with every gap no longer than `max_gap` frames filled: a
/// foot off the ground for less than the shortest contact did not lift (a flicker at a
/// threshold, e.g. a stance foot sliding through a blended transition), and held as two
/// plants it would jump from one's place to the other's in that gap.
fn close_short_gaps(intervals: Vec<FrameRange>, max_gap: usize) -> Vec<FrameRange> {
    let mut out: Vec<FrameRange> = Vec::with_capacity(intervals.len());
    for r in intervals {
        match out.last_mut() {
            Some(last) if r.start.saturating_sub(last.end) <= max_gap => last.end = last.end.max(r.end),
            _ => out.push(r),
        }
    }
    out
}

/// Contact intervals of one point's track (world positions per frame), heights taken
/// from the height the point rests at.
fn point_contacts(track: &[DVec3], fps: f64, t: &ContactThresholds) -> Vec<FrameRange> {
    contacts_above(track, ground_height(track), fps, t)
}

/// Contact intervals of one point's track, heights taken from `ground` (metres).
fn contacts_above(track: &[DVec3], ground: f64, fps: f64, t: &ContactThresholds) -> Vec<FrameRange> {
    let min_frames = min_frames(t, fps);
    let (mut out, mut start) = (Vec::new(), None);
    for f in 0..track.len() {
        let speed = central_difference(track, f, fps).length();
        let height = track[f].y - ground;
        match start {
            None if height < t.enter_height_m && speed < t.enter_speed_mps => start = Some(f),
            Some(s) if height > t.leave_height_m || speed > t.leave_speed_mps => {
                out.push(FrameRange::new(s, f));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push(FrameRange::new(s, track.len()));
    }
    out.retain(|r| r.len() >= min_frames.max(1));
    out
}

/// Contacts of both feet of `clip` from precomputed world `poses`.
pub fn detect_contacts(
    clip: &Clip,
    poses: &ClipPoses,
    landmarks: &Landmarks,
    thresholds: &ContactThresholds,
) -> Contacts {
    let legs = landmarks.limbs.map(|l| [l[0], l[1], l[2]]);
    feet_contacts(clip, poses, landmarks.feet(), None, &thresholds.for_leg(first_frame_leg_m(poses, legs)))
}

/// Mean leg length (m) of the body in the first of `poses`, hip, knee and ankle joints
/// given per leg; legs are rigid, so any frame gives it. 0 without frames.
fn first_frame_leg_m(poses: &ClipPoses, legs: [[usize; 3]; 2]) -> f64 {
    if poses.frame_count() == 0 {
        return 0.0;
    }
    f64::from(mean_limb_length_m(legs, |j| poses.position(0, j)))
}

/// Contacts of the two ankle joints `feet` (left, right) of `clip`, each watched with its
/// toe (`toes`, or the joint farthest below the ankle).
fn feet_contacts(
    clip: &Clip,
    poses: &ClipPoses,
    feet: [usize; 2],
    toes: Option<[usize; 2]>,
    thresholds: &ContactThresholds,
) -> Contacts {
    let skeleton = clip.skeleton();
    let feet: Vec<FootContacts> = feet
        .iter()
        .enumerate()
        .map(|(k, &ankle)| {
            let toe = toes.map_or_else(|| limb_tip(skeleton, ankle), |t| t[k]);
            let ankle_contacts = point_contacts(&track(poses, ankle), clip.fps(), thresholds);
            let intervals = if toe == ankle {
                ankle_contacts
            } else {
                union_all(&ankle_contacts, &point_contacts(&track(poses, toe), clip.fps(), thresholds))
            };
            let intervals = close_short_gaps(intervals, min_frames(thresholds, clip.fps()));
            FootContacts { foot: skeleton.joints()[ankle].name.clone(), intervals }
        })
        .collect();
    let double_support = match feet.as_slice() {
        [left, right] => intersect_all(&left.intervals, &right.intervals),
        _ => Vec::new(),
    };
    Contacts { fps: clip.fps(), frame_count: clip.frame_count(), feet, double_support, hands: Vec::new() }
}

/// Contacts of the two hand joints `hands` (left, right) of `clip`, for a clip whose feet
/// `feet` rest on the floor. A hand is watched at its palm (half way from the wrist to the
/// tip, the joint farthest below it) by height alone, with the feet's hysteresis, from the
/// height it rests at when down (the 2nd percentile of its heights: hands are down for
/// short spells), but only if that height is within [`HAND_REACH_LIFTS`] lift-off heights
/// of the floor (the lowest height the feet's ankles and toes rest at): an arm hanging
/// still is low and slow too, and must not count.
pub fn hand_contacts(
    clip: &Clip,
    poses: &ClipPoses,
    feet: [usize; 2],
    hands: [usize; 2],
    thresholds: &ContactThresholds,
) -> Vec<FootContacts> {
    let skeleton = clip.skeleton();
    let floor = feet
        .iter()
        .flat_map(|&ankle| [ankle, limb_tip(skeleton, ankle)])
        .map(|j| ground_height(&track(poses, j)))
        .fold(f64::INFINITY, f64::min);
    // Height alone: a planted hand's palm still slides and rolls on capture skeletons' coarse
    // hands (CMU 90_02's left palm moves at 0.4-0.8 m/s through its support, above any
    // foot's enter speed).
    let by_height = ContactThresholds { enter_speed_mps: f64::INFINITY, leave_speed_mps: f64::INFINITY, ..*thresholds };
    hands
        .iter()
        .map(|&hand| {
            // The palm, half way from the wrist to the fingertip: what a planted hand turns
            // about (the wrist circles it as the body goes over the hand).
            let (wrist, tip) = (track(poses, hand), track(poses, limb_tip(skeleton, hand)));
            let palm: Vec<DVec3> = wrist.iter().zip(&tip).map(|(w, t)| (*w + *t) * 0.5).collect();
            let down = height_quantile(&palm, 2);
            let reached = down - floor <= HAND_REACH_LIFTS * thresholds.leave_height_m;
            let intervals = if reached { contacts_above(&palm, down, clip.fps(), &by_height) } else { Vec::new() };
            let intervals = close_short_gaps(intervals, min_frames(thresholds, clip.fps()));
            FootContacts { foot: skeleton.joints()[hand].name.clone(), intervals }
        })
        .collect()
}

/// Contacts of both feet of `clip` with the feet's joint indices (left, right). The feet
/// are the body roles' ankles ([`roles_of`]: by joint name, or else from the body's shape
/// in the first frame, e.g. a glTF character with generic joint names); otherwise why they
/// could not be found. Thresholds set for a leg are scaled to the body's legs.
pub fn contacts_of(
    clip: &Clip,
    poses: &ClipPoses,
    thresholds: &ContactThresholds,
) -> Result<(Contacts, [usize; 2]), RolesError> {
    contacts_with(clip, poses, thresholds, &NamedFeet::default())
        .map(|found| (found.contacts, found.feet))
        .map_err(|UnnamedFeet(why)| why)
}

/// The body's feet could not be found and the user named none ([`contacts_with`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}; name them with the feet param (e.g. 'LeftFoot, RightFoot')")]
pub struct UnnamedFeet(#[source] pub RolesError);

/// Contacts found by [`contacts_with`].
#[derive(Clone, Debug, PartialEq)]
pub struct FoundContacts {
    /// The contacts of both feet.
    pub contacts: Contacts,
    /// The ankle joints watched, left then right.
    pub feet: [usize; 2],
    /// The legs' length the thresholds were scaled to (metres); `None` when the body's legs
    /// could not be read (named feet on an unusual rig) and the thresholds were used as set.
    pub scaled_to_leg_m: Option<f64>,
}

/// [`contacts_of`] with feet named by the user: named ankles replace the body's, named toes
/// the joints farthest below the ankles.
pub fn contacts_with(
    clip: &Clip,
    poses: &ClipPoses,
    thresholds: &ContactThresholds,
    named: &NamedFeet,
) -> Result<FoundContacts, UnnamedFeet> {
    let first: Vec<glam::Vec3> =
        if poses.frame_count() > 0 { poses.frame(0).iter().map(|t| t.translation).collect() } else { Vec::new() };
    let legs = roles_of(clip.skeleton(), &first).map(|roles| roles.legs.map(|l| l.joints()));
    let feet = match (named.ankles, &legs) {
        (Some(feet), _) => feet,
        (None, Ok(legs)) => legs.map(|l| l[2]),
        (None, Err(why)) => return Err(UnnamedFeet(why.clone())),
    };
    // Legs read from the body scale the thresholds; a rig whose body cannot be read keeps them.
    let leg_m = legs.ok().map(|legs| first_frame_leg_m(poses, legs));
    let scaled = leg_m.map_or(*thresholds, |leg_m| thresholds.for_leg(leg_m));
    let mut contacts = feet_contacts(clip, poses, feet, named.toes, &scaled);
    if let Some(hands) = named.hands {
        contacts.hands = hand_contacts(clip, poses, feet, hands, &scaled);
    }
    Ok(FoundContacts { contacts, feet, scaled_to_leg_m: leg_m.filter(|_| thresholds.leg_m.is_some()) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_scale_heights_and_speeds_with_the_leg() {
        let adult = ContactThresholds::default();
        // A leg a quarter of the reference: heights and speeds × 1/4.
        let small = adult.for_leg(REFERENCE_LEG_M / 4.0);
        assert!((small.enter_height_m - 0.0125).abs() < 1e-12 && (small.leave_height_m - 0.02).abs() < 1e-12);
        assert!((small.enter_speed_mps - 0.125).abs() < 1e-12 && (small.leave_speed_mps - 0.225).abs() < 1e-12);
        assert_eq!(small.min_duration_secs, adult.min_duration_secs);
        assert_eq!(adult.for_leg(REFERENCE_LEG_M), adult);
        assert_eq!(adult.for_leg(0.0), adult);
        assert_eq!(adult.for_leg(f64::NAN), adult);
        // The result is for the new leg: scaling on from it is scaling from the reference.
        assert_eq!(small.leg_m, Some(REFERENCE_LEG_M / 4.0));
        let twice = small.for_leg(REFERENCE_LEG_M);
        assert!((twice.enter_height_m - 0.05).abs() < 1e-12 && (twice.leave_speed_mps - 0.9).abs() < 1e-12);
        // Thresholds for any body are not scaled.
        let absolute = ContactThresholds { leg_m: None, ..adult };
        assert_eq!(absolute.for_leg(REFERENCE_LEG_M / 4.0), absolute);
    }

    #[test]
    fn gaps_shorter_than_a_contact_are_filled() {
        let r = |a, b| FrameRange::new(a, b);
        let got = close_short_gaps(vec![r(0, 10), r(12, 20), r(23, 30), r(40, 50)], 2);
        assert_eq!(got, vec![r(0, 20), r(23, 30), r(40, 50)]);
        assert_eq!(close_short_gaps(Vec::new(), 2), Vec::new());
    }

    #[test]
    fn hysteresis_keeps_a_noisy_rest_in_one_contact() {
        // Rest on the ground with ±1 cm noise, lift off to 30 cm, come back down.
        let fps = 100.0;
        let mut track = Vec::new();
        for f in 0..300 {
            let noise = if f % 2 == 0 { 0.01 } else { 0.0 };
            let lift = if (100..200).contains(&f) {
                0.3 * ((f - 100) as f32 / 100.0 * std::f32::consts::PI).sin()
            } else {
                0.0
            };
            track.push(DVec3::new(0.0, f64::from(noise + lift), 0.0));
        }
        let t = ContactThresholds { enter_speed_mps: 2.0, leave_speed_mps: 3.0, ..Default::default() };
        let got = point_contacts(&track, fps, &t);
        assert_eq!(got.len(), 2, "{got:?}");
        assert_eq!(got[0].start, 0);
        assert!((100..125).contains(&got[0].end), "{got:?}");
        assert!((175..200).contains(&got[1].start) && got[1].end == 300, "{got:?}");
    }
}
