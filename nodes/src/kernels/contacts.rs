//! Foot contacts: when each foot rests on the ground, and when both do (double support).
//!
//! A foot is in contact while its ankle or its toe tip is near the height that point rests
//! at in the clip and moves slowly. Thresholds have hysteresis (stricter to enter than
//! to stay), so a foot that rests does not flicker in and out of contact on capture noise.
//! The rest height is taken per point from the clip itself: flat ground, any rig.
//!
//! A kernel: the `motion.contacts` node, the clip analysis, foot locking and the editor's
//! viewport all detect contacts with it.

use glam::DVec3;

use super::angular::central_difference;
use super::body::{Landmarks, limb_tip};
use super::roles::{RolesError, roles_of};
use crate::model::names::did_you_mean;
use crate::model::{
    Clip, ClipPoses, Contacts, FootContacts, FrameRange, Skeleton, intervals::intersect_all, intervals::union_all,
};

/// Foot joints named by the user where detection fails (an unusual rig): the ankles and the
/// toe points watched with them, left then right. `None`: the ankles come from the body
/// roles, the toes are the joints farthest below each ankle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NamedFeet {
    /// Ankle joints, left then right.
    pub ankles: Option<[usize; 2]>,
    /// Toe joints, left then right.
    pub toes: Option<[usize; 2]>,
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

/// Thresholds of contact detection (metres above the point's rest height, m/s).
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
}

impl Default for ContactThresholds {
    fn default() -> Self {
        ContactThresholds {
            enter_height_m: 0.05,
            enter_speed_mps: 0.5,
            leave_height_m: 0.08,
            leave_speed_mps: 0.9,
            min_duration_secs: 0.05,
        }
    }
}

/// Leg length (hip to knee to ankle, metres) of the body the default thresholds were set
/// on: the subject of CMU 02_01, the corpus's reference walk.
pub const REFERENCE_LEG_M: f64 = 0.8377;

impl ContactThresholds {
    /// These thresholds for legs `leg_m` long rather than [`REFERENCE_LEG_M`]: heights in
    /// proportion to the leg, speeds in proportion to its square root (dynamic similarity:
    /// bodies moving alike, at one Froude number v²/(g·leg), have speeds that scale as
    /// √leg), the shortest contact unchanged. A leg of no length keeps them as they are.
    pub fn for_leg(self, leg_m: f64) -> ContactThresholds {
        if !(leg_m > 0.0 && leg_m.is_finite()) {
            return self;
        }
        let (height, speed) = (leg_m / REFERENCE_LEG_M, (leg_m / REFERENCE_LEG_M).sqrt());
        ContactThresholds {
            enter_height_m: self.enter_height_m * height,
            enter_speed_mps: self.enter_speed_mps * speed,
            leave_height_m: self.leave_height_m * height,
            leave_speed_mps: self.leave_speed_mps * speed,
            min_duration_secs: self.min_duration_secs,
        }
    }
}

/// The height a point rests at: the 10th percentile of its heights over the clip, so that
/// a few frames of capture noise or a foot poking through the floor do not set it.
pub fn ground_height(track: &[DVec3]) -> f64 {
    let mut heights: Vec<f64> = track.iter().map(|p| p.y).collect();
    heights.sort_by(f64::total_cmp);
    heights.get(heights.len() / 10).copied().unwrap_or(0.0)
}

/// Contact intervals of one point's track (world positions per frame).
fn point_contacts(track: &[DVec3], fps: f64, t: &ContactThresholds) -> Vec<FrameRange> {
    let ground = ground_height(track);
    let min_frames = (t.min_duration_secs * fps).ceil() as usize;
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
    feet_contacts(clip, poses, landmarks.feet(), None, thresholds)
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
    let track = |j: usize| (0..poses.frame_count()).map(|f| poses.position(f, j).as_dvec3()).collect::<Vec<DVec3>>();
    let feet: Vec<FootContacts> = feet
        .iter()
        .enumerate()
        .map(|(k, &ankle)| {
            let toe = toes.map_or_else(|| limb_tip(skeleton, ankle), |t| t[k]);
            let ankle_contacts = point_contacts(&track(ankle), clip.fps(), thresholds);
            let intervals = if toe == ankle {
                ankle_contacts
            } else {
                union_all(&ankle_contacts, &point_contacts(&track(toe), clip.fps(), thresholds))
            };
            FootContacts { foot: skeleton.joints()[ankle].name.clone(), intervals }
        })
        .collect();
    let double_support = match feet.as_slice() {
        [left, right] => intersect_all(&left.intervals, &right.intervals),
        _ => Vec::new(),
    };
    Contacts { fps: clip.fps(), frame_count: clip.frame_count(), feet, double_support }
}

/// Contacts of both feet of `clip` with the feet's joint indices (left, right). The feet
/// are the body roles' ankles ([`roles_of`]: by joint name, or else from the body's shape
/// in the first frame, e.g. a glTF character with generic joint names); otherwise why they
/// could not be found.
pub fn contacts_of(
    clip: &Clip,
    poses: &ClipPoses,
    thresholds: &ContactThresholds,
) -> Result<(Contacts, [usize; 2]), RolesError> {
    let first: Vec<glam::Vec3> =
        if poses.frame_count() > 0 { poses.frame(0).iter().map(|t| t.translation).collect() } else { Vec::new() };
    let feet = roles_of(clip.skeleton(), &first)?.legs.map(|l| l.joints()[2]);
    Ok((feet_contacts(clip, poses, feet, None, thresholds), feet))
}

/// The body's feet could not be found and the user named none ([`contacts_with`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}; name them with the feet param (e.g. 'LeftFoot, RightFoot')")]
pub struct UnnamedFeet(#[source] pub RolesError);

/// [`contacts_of`] with feet named by the user: named ankles replace the body's, named toes
/// the joints farthest below the ankles.
pub fn contacts_with(
    clip: &Clip,
    poses: &ClipPoses,
    thresholds: &ContactThresholds,
    named: &NamedFeet,
) -> Result<(Contacts, [usize; 2]), UnnamedFeet> {
    let feet = match named.ankles {
        Some(feet) => feet,
        None => {
            let first: Vec<glam::Vec3> = if poses.frame_count() > 0 {
                poses.frame(0).iter().map(|t| t.translation).collect()
            } else {
                Vec::new()
            };
            roles_of(clip.skeleton(), &first).map_err(UnnamedFeet)?.legs.map(|l| l.joints()[2])
        }
    };
    Ok((feet_contacts(clip, poses, feet, named.toes, thresholds), feet))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thresholds_scale_heights_with_the_leg_and_speeds_with_its_square_root() {
        let adult = ContactThresholds::default();
        // A leg a quarter of the reference: heights × 1/4, speeds × 1/2.
        let small = adult.for_leg(REFERENCE_LEG_M / 4.0);
        assert!((small.enter_height_m - 0.0125).abs() < 1e-12 && (small.leave_height_m - 0.02).abs() < 1e-12);
        assert!((small.enter_speed_mps - 0.25).abs() < 1e-12 && (small.leave_speed_mps - 0.45).abs() < 1e-12);
        assert_eq!(small.min_duration_secs, adult.min_duration_secs);
        assert_eq!(adult.for_leg(REFERENCE_LEG_M), adult);
        assert_eq!(adult.for_leg(0.0), adult);
        assert_eq!(adult.for_leg(f64::NAN), adult);
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
