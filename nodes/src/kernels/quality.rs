//! Motion quality measured the way an animator checks a clip frame by frame: planted feet
//! that slide, feet under the floor or hovering over it while planted, joints that jerk, a
//! root that changes speed in one frame, bones that stretch, joints that pop.
//!
//! Units are in every field name: lengths in centimetres (`_cm`), speeds in m/s (`_mps`),
//! accelerations in m/s² (`_mps2`). "Per frame" means between consecutive frames at the
//! clip's own frame rate. The floor is the horizontal plane y = `floor_height_m` in the
//! clip's metres (0 by default: the ground of glTF and of the corpus clips). A foot is its
//! ankle (the joint the contacts name) with every joint below it (toes, toe tips) and,
//! when a skinned mesh is given, the vertices bound mostly to those joints (its sole).
//!
//! Measures:
//! 1. Skate: for two consecutive frames inside one contact of a foot, the horizontal
//!    distance moved by the foot's stillest point (the least of its joints' moves). A foot
//!    rolling from heel to toe keeps one point still and does not skate; a sliding foot
//!    moves every point. Summed over one contact, the slide of that plant.
//! 2. Penetration: how far the lowest point of a foot is below the floor; frames are
//!    counted when a foot is more than [`BELOW_FLOOR_SLACK_M`] under it.
//! 3. Float: per contact, the lowest the foot gets above the floor (a planted foot that
//!    never reaches the floor hovers); the largest over the contacts. Measured on joints it
//!    includes the rig's ankle or toe height above the sole: connect the skinned mesh for
//!    the sole itself.
//! 4. Acceleration: the second difference of every joint's world position times fps²;
//!    A(f) is the largest over the joints. The spike ratio at f is A(f) over the median of
//!    A in the frames 3 to w away (w = `neighbourhood_secs` · fps, at least 6), the median
//!    taken as at least [`QUIET_ACCELERATION_MPS2`] so a still clip has no spikes of
//!    noise; the report gives the largest ratio. With source clips, the clip's peak A over
//!    the largest peak of the sources, both over the body's joints ([`body_joints`]: all
//!    but the fingers, which a game rig has and a capture mostly lacks, and whose tips
//!    swing fastest), so a rig is compared with its source joint for joint.
//! 5. Root velocity change: |p(f+1) − 2 p(f) + p(f−1)| · fps of the root joint's world
//!    position (m/s): the one-frame change of the root's velocity; with source clips, over
//!    the sources' largest.
//! 6. Bone-length drift: per bone (joint and parent), longest minus shortest length over
//!    the clip; the largest.
//! 7. Pops: a joint that moves in one frame more than [`POP_RATIO`] times as far as in
//!    the frame before and the frame after, and faster than [`POP_MIN_SPEED_MPS`] (a
//!    teleporting root pops every joint). Only moves with a move before and after them
//!    are judged (not into the first two frames or the last).
//! 8. Stride ([`super::stride`]): step length ÷ leg length and the pelvis's horizontal
//!    speed range (5th–95th percentile), of the clip and of each source (contacts detected
//!    on it); how far the clip's step ÷ leg lies outside the sources' span of it, and how
//!    far its pelvis speed range reaches outside the span of the sources' ranges, each
//!    scaled by its leg-length ratio (a walk joined to a punch is measured against both,
//!    not against the walk alone).
//!
//! With a window (e.g. a transition's frames) only the frames inside it are looked at:
//! contacts are cut to it, while accelerations and pops still see the frames around it.
//!
//! Degenerate clips (no frames, one frame, no contacts, feet not found) are measured as far
//! as they go: what cannot be measured is `None` and said in the findings, never a panic.
//!
//! A kernel: the `motion.quality` node reports with it and `kg test` gates on its summary.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::contacts::{ContactThresholds, contacts_of};
use super::props::{PropsPenetration, props_penetration};
use super::roles::{BodyRoles, RolesError};
use super::skinning::SkinError;
use super::soles::{foot_joints, lowest_sole_heights};
use super::stride::{FootPlants, Stride, StrideComparison, compare_stride, measure_stride, rest_legs};
use crate::model::{Clip, ClipPoses, Contacts, FrameRange, Mesh, Skeleton, forward_kinematics};

/// A foot more than this far under the floor (metres) counts as below it: capture noise
/// of a millimetre is not a fault.
pub const BELOW_FLOOR_SLACK_M: f64 = 0.001;

/// The least neighbourhood acceleration a spike is divided by (m/s²): below it a joint is
/// as good as still, and a ratio to capture noise would mean nothing.
pub const QUIET_ACCELERATION_MPS2: f64 = 1.0;

/// A joint's one-frame move must exceed this many times its moves in the frames around it
/// to be a pop.
pub const POP_RATIO: f64 = 3.0;

/// …and be faster than this (m/s), so the jitter of a joint at rest is no pop.
pub const POP_MIN_SPEED_MPS: f64 = 1.0;

/// Frames nearer than this to a frame are not its neighbourhood: a single spike in a
/// position spreads over three second differences.
const SPIKE_EXCLUSION_FRAMES: usize = 3;

/// Findings listed one by one before the rest are counted.
const MAX_LISTED_FINDINGS: usize = 5;

/// Settings of [`measure_quality`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QualityOptions {
    /// Height of the floor plane in the clip's metres. Default 0.
    pub floor_height_m: f64,
    /// Half-width of the neighbourhood a spike is compared with, seconds. Default 0.25.
    pub neighbourhood_secs: f64,
    /// Thresholds used when contacts must be detected (scaled to the clip's legs when set
    /// for a leg). Default: the detector's defaults.
    pub contacts: ContactThresholds,
    /// The seconds looked at, first and last included (rounded to frames); `None` (the
    /// default) looks at the whole clip.
    pub window_secs: Option<(f64, f64)>,
}

impl Default for QualityOptions {
    fn default() -> Self {
        QualityOptions {
            floor_height_m: 0.0,
            neighbourhood_secs: 0.25,
            contacts: ContactThresholds::default(),
            window_secs: None,
        }
    }
}

/// The measures a quality gate reads: the worst value of each over the clip, `None` when
/// it could not be measured (see the findings).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct QualitySummary {
    /// Largest skate of any foot in one frame of contact, cm per frame.
    pub skate_max_cm_per_frame: Option<f64>,
    /// Mean skate over every frame of contact of both feet, cm per frame.
    pub skate_mean_cm_per_frame: Option<f64>,
    /// Longest slide of one foot over one contact (the skate summed over the plant), cm.
    pub contact_slide_max_cm: Option<f64>,
    /// Deepest any foot goes under the floor, cm (0 when never below).
    pub penetration_max_cm: Option<f64>,
    /// Frames in which a foot is more than 1 mm under the floor.
    pub frames_below_floor: Option<usize>,
    /// Highest a planted foot stays above the floor through a whole contact, cm.
    pub float_in_contact_max_cm: Option<f64>,
    /// Largest joint acceleration, m/s².
    pub acceleration_peak_mps2: Option<f64>,
    /// Largest acceleration spike over its neighbourhood (dimensionless).
    pub acceleration_spike_ratio: Option<f64>,
    /// Peak acceleration of the body's joints (fingers excluded) over the sources' peak of
    /// theirs (dimensionless).
    pub acceleration_over_sources: Option<f64>,
    /// Largest one-frame change of the root's velocity, m/s.
    pub root_velocity_change_max_mps: Option<f64>,
    /// That over the sources' largest (dimensionless).
    pub root_velocity_change_over_sources: Option<f64>,
    /// Largest change of a bone's length over the clip, cm.
    pub bone_length_drift_max_cm: Option<f64>,
    /// Frames in which some joint pops.
    pub pop_frames: Option<usize>,
    /// Mean step length over leg length (dimensionless).
    #[serde(default)]
    pub step_over_leg: Option<f64>,
    /// How far that lies outside the sources' span of it, percent of the nearer end (with
    /// one source: the change against it, percent of the source's).
    #[serde(default)]
    pub step_over_leg_change_pct: Option<f64>,
    /// How far the pelvis's horizontal speed range (5th–95th percentile) reaches outside
    /// the span of the sources' ranges, each scaled by its leg-length ratio, percent of the
    /// span's top.
    #[serde(default)]
    pub pelvis_speed_outside_source_pct: Option<f64>,
    /// Deepest the skinned mesh goes into the scene's props, cm ([`super::props`]); `None`
    /// without props (and then left out of the report).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub props_penetration_max_cm: Option<f64>,
}

/// One foot's measures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FootQuality {
    /// The ankle joint's name.
    pub foot: String,
    /// Contacts (plants) of the foot.
    pub contacts: usize,
    /// Pairs of consecutive frames inside a contact, over which skate is measured.
    pub contact_frame_pairs: usize,
    /// Mean skate in contact, cm per frame (0 without contacts).
    pub skate_mean_cm_per_frame: f64,
    /// Largest skate in contact, cm per frame.
    pub skate_max_cm_per_frame: f64,
    /// The frame ending the largest skate.
    pub skate_max_frame: Option<usize>,
    /// Total skate over all contacts, cm.
    pub skate_total_cm: f64,
    /// The longest slide over one contact, cm.
    pub contact_slide_max_cm: f64,
    /// That contact's frames `[start, end)`.
    pub contact_slide_max_frames: Option<(usize, usize)>,
    /// Deepest under the floor, cm.
    pub penetration_max_cm: f64,
    /// Frames more than 1 mm under the floor.
    pub frames_below_floor: usize,
    /// Highest it stays above the floor through a whole contact, cm (0 without contacts).
    pub float_in_contact_max_cm: f64,
    /// Whether the lowest point includes the skinned mesh's sole.
    pub sole_from_mesh: bool,
}

/// Everything measured, with where the worst values happen.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct QualityReport {
    /// How to read the numbers.
    pub units: &'static str,
    /// Frames measured.
    pub frames: usize,
    /// The clip's frame rate: every "per frame" is at this rate.
    pub fps: f64,
    /// The floor plane's height, metres.
    pub floor_height_m: f64,
    /// The frames looked at, `[start, end)`.
    pub window_frames: (usize, usize),
    /// `"connected"`, `"detected"` or `"none"` (feet not found).
    pub contacts: &'static str,
    /// The gated measures.
    #[serde(flatten)]
    pub summary: QualitySummary,
    /// Per foot.
    pub feet: Vec<FootQuality>,
    /// Longest stretch with a foot under the floor, seconds.
    pub longest_below_floor_secs: f64,
    /// Frame and joint of the peak acceleration.
    pub acceleration_peak_at: Option<(usize, String)>,
    /// Frame of the largest spike ratio.
    pub acceleration_spike_frame: Option<usize>,
    /// Frame and joint of the peak acceleration of the body's joints, the one compared
    /// with the sources.
    pub body_acceleration_peak_at: Option<(usize, String)>,
    /// The sources' largest acceleration of their body's joints, m/s².
    pub sources_acceleration_peak_mps2: Option<f64>,
    /// Frame of the largest root velocity change.
    pub root_velocity_change_frame: Option<usize>,
    /// The sources' largest one-frame root velocity change, m/s.
    pub sources_root_velocity_change_max_mps: Option<f64>,
    /// The joint whose bone drifts most.
    pub bone_length_drift_joint: Option<String>,
    /// The clip's stride (step length, leg length, pelvis speed range).
    pub stride: Option<Stride>,
    /// Each source's stride, its contacts detected (a source whose stride cannot be
    /// measured is left out, with a finding).
    pub source_strides: Vec<Stride>,
    /// The clip's stride against the sources', scaled by leg length.
    pub stride_against_source: Option<StrideComparison>,
    /// How deep the skinned mesh goes into the props, when props were given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub props: Option<PropsPenetration>,
    /// What an animator would be told, one line each.
    pub findings: Vec<String>,
}

/// World positions of every joint of a clip, frame-major, in f64.
struct Tracks {
    fps: f64,
    joints: usize,
    frames: usize,
    pos_m: Vec<DVec3>,
}

impl Tracks {
    /// The joints' world positions of `clip`, from its forward kinematics `poses` (computed
    /// once by the caller, which also detects contacts on them).
    fn of(clip: &Clip, poses: &ClipPoses) -> Tracks {
        let pos_m = (0..clip.frame_count())
            .flat_map(|f| poses.frame(f).iter().map(|t| t.translation.as_dvec3()))
            .collect::<Vec<_>>();
        Tracks { fps: clip.fps(), joints: clip.joint_count(), frames: clip.frame_count(), pos_m }
    }

    fn at(&self, frame: usize, joint: usize) -> DVec3 {
        self.pos_m[frame * self.joints + joint]
    }

    /// `p(f+1) − 2 p(f) + p(f−1)` of `joint`, metres; `frame` must have both neighbours.
    fn second_difference(&self, frame: usize, joint: usize) -> DVec3 {
        self.at(frame + 1, joint) - 2.0 * self.at(frame, joint) + self.at(frame - 1, joint)
    }

    /// The frames with both neighbours.
    fn interior(&self) -> std::ops::Range<usize> {
        1..self.frames.saturating_sub(1)
    }

    /// Per interior frame, the largest joint acceleration (m/s²) and its joint, over every
    /// joint and over those `body` lets in (all when it is shorter), in one pass.
    fn peak_accelerations(&self, body: &[bool]) -> Vec<[(f64, usize); 2]> {
        let fps2 = self.fps * self.fps;
        let larger = |best: (f64, usize), x: (f64, usize)| if x.0 > best.0 { x } else { best };
        self.interior()
            .map(|f| {
                (0..self.joints).fold([(0.0, 0); 2], |[all, in_body], j| {
                    let x = (self.second_difference(f, j).length() * fps2, j);
                    [larger(all, x), if body.get(j).copied().unwrap_or(true) { larger(in_body, x) } else { in_body }]
                })
            })
            .collect()
    }

    /// Per interior frame, the one-frame change of the root's velocity, m/s.
    fn root_velocity_changes(&self) -> Vec<f64> {
        if self.joints == 0 {
            return Vec::new();
        }
        self.interior().map(|f| self.second_difference(f, 0).length() * self.fps).collect()
    }
}

/// The stride of `clip` (with its `feet`, over `window`) and of each of `sources` (with
/// their forward kinematics and tracks, contacts detected with `options.contacts` for their
/// legs, whole): `None` for the clip, and a source left out, with a finding saying why when
/// it cannot be measured.
fn strides(
    clip: &Clip,
    tracks: &Tracks,
    feet: &[Foot],
    window: FrameRange,
    sources: &[(&Clip, &ClipPoses, &Tracks)],
    options: &QualityOptions,
    findings: &mut Vec<String>,
) -> (Option<Stride>, Vec<Stride>) {
    let mut note = |what: &str, result: Result<Stride, RolesError>| {
        result.map_err(|why| findings.push(format!("the {what}'s stride is not measured: {why}"))).ok()
    };
    let plants: Vec<FootPlants<'_>> =
        feet.iter().map(|f| FootPlants { ankle: f.ankle, contacts: &f.intervals }).collect();
    let stride = (!feet.is_empty()).then(|| {
        let measured =
            measure_stride(clip.skeleton(), clip.fps(), clip.frame_count(), window, |f, j| tracks.at(f, j), &plants);
        note("clip", measured)
    });
    let several = sources.len() > 1;
    let source_strides = sources
        .iter()
        .enumerate()
        .filter_map(|(i, &(source, poses, t))| {
            let measured = contacts_of(source, poses, &options.contacts).and_then(|(contacts, _)| {
                let ankles: Vec<(usize, &[FrameRange])> = contacts
                    .feet
                    .iter()
                    .filter_map(|c| Some((source.skeleton().index_of(&c.foot)?, c.intervals.as_slice())))
                    .collect();
                let plants: Vec<FootPlants<'_>> =
                    ankles.iter().map(|&(ankle, contacts)| FootPlants { ankle, contacts }).collect();
                let whole = FrameRange::new(0, source.frame_count());
                measure_stride(source.skeleton(), source.fps(), source.frame_count(), whole, |f, j| t.at(f, j), &plants)
            });
            // Numbered in the node's order: source, other_source, then the set's clips.
            let what = if several { format!("source {} of {}", i + 1, sources.len()) } else { "source".into() };
            note(&what, measured)
        })
        .collect();
    (stride.flatten(), source_strides)
}

/// The larger of `best` and `candidate` by value, the earlier on a tie (for folds).
fn larger(best: Option<(f64, usize)>, candidate: (f64, usize)) -> Option<(f64, usize)> {
    match best {
        Some((b, _)) if b >= candidate.0 => best,
        _ => Some(candidate),
    }
}

/// The largest value and its index.
fn max_at(values: impl IntoIterator<Item = f64>) -> Option<(f64, usize)> {
    values.into_iter().enumerate().map(|(i, v)| (v, i)).fold(None, larger)
}

/// The largest of per-interior-frame `values` (index `i` is frame `i + 1`) inside
/// `window`, and its frame.
fn max_in_window(values: &[f64], window: FrameRange) -> Option<(f64, usize)> {
    let inside = values.iter().enumerate().map(|(i, &v)| (v, i + 1)).filter(|(_, f)| window.contains(*f));
    inside.fold(None, larger)
}

/// The spike ratio (see the module doc) of each of `peaks` (one per interior frame),
/// comparing with the values `SPIKE_EXCLUSION_FRAMES..=half_width` indices away.
fn spike_ratios(peaks: &[f64], half_width: usize) -> Vec<f64> {
    let ratios = (0..peaks.len()).map(|i| {
        let mut around: Vec<f64> = (i.saturating_sub(half_width)..=(i + half_width).min(peaks.len() - 1))
            .filter(|&k| k.abs_diff(i) >= SPIKE_EXCLUSION_FRAMES)
            .map(|k| peaks[k])
            .collect();
        if around.is_empty() {
            return 0.0;
        }
        around.sort_by(f64::total_cmp);
        peaks[i] / around[(around.len() - 1) / 2].max(QUIET_ACCELERATION_MPS2)
    });
    ratios.collect()
}

/// A foot of the clip: its joints, its sole's vertices and its contacts.
struct Foot {
    name: String,
    ankle: usize,
    joints: Vec<usize>,
    intervals: Vec<FrameRange>,
}

/// The feet named by `contacts`, their contacts cut to `window`; findings say why a foot
/// is not.
fn feet_of(clip: &Clip, contacts: &Contacts, window: FrameRange, findings: &mut Vec<String>) -> Vec<Foot> {
    let skeleton = clip.skeleton();
    contacts
        .feet
        .iter()
        .filter_map(|c| {
            let Some(ankle) = skeleton.index_of(&c.foot) else {
                findings.push(format!("the contacts name a foot '{}' the clip's skeleton lacks", c.foot));
                return None;
            };
            let joints = foot_joints(skeleton, ankle);
            let intervals = c.intervals.iter().filter_map(|r| r.intersect(&window)).collect();
            Some(Foot { name: c.foot.clone(), ankle, joints, intervals })
        })
        .collect()
}

/// Per foot and frame, the lowest height of its joints and, with a usable skinned `mesh`,
/// of the vertices bound mostly to them; and per foot whether it has such a sole.
fn lowest_heights(
    clip: &Clip,
    tracks: &Tracks,
    feet: &[Foot],
    mesh: Option<&Mesh>,
    findings: &mut Vec<String>,
) -> (Vec<Vec<f64>>, Vec<bool>) {
    let mut lowest: Vec<Vec<f64>> = feet
        .iter()
        .map(|foot| {
            (0..tracks.frames)
                .map(|f| foot.joints.iter().map(|&j| tracks.at(f, j).y).fold(f64::INFINITY, f64::min))
                .collect()
        })
        .collect();
    let joints_only = vec![false; feet.len()];
    let Some(mesh) = mesh else { return (lowest, joints_only) };
    let joint_sets: Vec<Vec<usize>> = feet.iter().map(|f| f.joints.clone()).collect();
    let soles = match lowest_sole_heights(clip, mesh, &joint_sets) {
        Ok(soles) => soles,
        Err(SkinError::NotSkinned) => {
            findings.push("the mesh is not skinned, so its soles are not measured".into());
            return (lowest, joints_only);
        }
        Err(why) => {
            findings.push(format!("the mesh's soles are not measured: {why}"));
            return (lowest, joints_only);
        }
    };
    for (per_frame, sole) in lowest.iter_mut().zip(&soles) {
        for (low, sole_low) in per_frame.iter_mut().zip(sole.iter().flatten()) {
            *low = low.min(*sole_low);
        }
    }
    (lowest, soles.iter().map(Option::is_some).collect())
}

/// The sum of the skates (cm), 0 for none (an empty float sum is −0).
fn sum_cm(skates: &[(f64, usize)]) -> f64 {
    skates.iter().fold(0.0, |total, s| total + s.0)
}

/// Skate, penetration and float of one foot (see the module doc) over the frames of
/// `window`, `lowest_m` its lowest height per frame.
fn foot_quality(
    tracks: &Tracks,
    foot: &Foot,
    lowest_m: &[f64],
    floor_m: f64,
    window: FrameRange,
    sole_from_mesh: bool,
) -> FootQuality {
    let mut skates: Vec<(f64, usize)> = Vec::new();
    let mut slides: Vec<(f64, (usize, usize))> = Vec::new();
    for r in &foot.intervals {
        let before = skates.len();
        for f in r.start + 1..r.end {
            let moved = foot
                .joints
                .iter()
                .map(|&j| (tracks.at(f, j) - tracks.at(f - 1, j)).with_y(0.0).length())
                .fold(f64::INFINITY, f64::min);
            skates.push((moved * 100.0, f));
        }
        slides.push((sum_cm(&skates[before..]), (r.start, r.end)));
    }
    let worst_slide = max_at(slides.iter().map(|s| s.0));
    let total = sum_cm(&skates);
    let worst = max_at(skates.iter().map(|s| s.0));
    let depth_m = |f: usize| floor_m - lowest_m[f];
    let float_cm = foot
        .intervals
        .iter()
        .filter(|r| !r.is_empty())
        .map(|r| (r.start..r.end).map(|f| -depth_m(f)).fold(f64::INFINITY, f64::min))
        .fold(0.0, f64::max)
        * 100.0;
    FootQuality {
        foot: foot.name.clone(),
        contacts: foot.intervals.iter().filter(|r| !r.is_empty()).count(),
        contact_frame_pairs: skates.len(),
        skate_mean_cm_per_frame: if skates.is_empty() { 0.0 } else { total / skates.len() as f64 },
        skate_max_cm_per_frame: worst.map_or(0.0, |w| w.0),
        skate_max_frame: worst.map(|w| skates[w.1].1),
        skate_total_cm: total,
        contact_slide_max_cm: worst_slide.map_or(0.0, |w| w.0),
        contact_slide_max_frames: worst_slide.map(|w| slides[w.1].1),
        penetration_max_cm: (window.start..window.end).map(depth_m).fold(0.0, f64::max) * 100.0,
        frames_below_floor: (window.start..window.end).filter(|&f| depth_m(f) > BELOW_FLOOR_SLACK_M).count(),
        float_in_contact_max_cm: float_cm,
        sole_from_mesh,
    }
}

/// Frames of `window` in which some joint pops (see the module doc), with the largest pop:
/// (frame, joint, move in metres).
fn pops(tracks: &Tracks, window: FrameRange) -> (usize, Option<(usize, usize, f64)>) {
    let moved = |f: usize, j: usize| (tracks.at(f, j) - tracks.at(f - 1, j)).length();
    let min_move_m = POP_MIN_SPEED_MPS / tracks.fps;
    let (mut frames, mut largest): (usize, Option<(usize, usize, f64)>) = (0, None);
    // A move needs a frame before and after it to be judged: at the clip's edges a foot
    // speeding up from rest (a toe-off in the last frame) would count as a pop.
    for f in window.start.max(2)..window.end.min(tracks.frames.saturating_sub(1)) {
        let mut popped = false;
        for j in 0..tracks.joints {
            let here = moved(f, j);
            let neighbour = moved(f - 1, j).max(moved(f + 1, j));
            if here > min_move_m && here > POP_RATIO * neighbour {
                popped = true;
                if largest.is_none_or(|l| here > l.2) {
                    largest = Some((f, j, here));
                }
            }
        }
        frames += usize::from(popped);
    }
    (frames, largest)
}

/// The largest change of a bone's length over the frames of `window` (metres) and its joint.
fn bone_length_drift(clip: &Clip, tracks: &Tracks, window: FrameRange) -> Option<(f64, usize)> {
    let joints = clip.skeleton().joints();
    let drift = |j: usize| {
        let parent = joints[j].parent?;
        let lengths = (window.start..window.end).map(|f| tracks.at(f, j).distance(tracks.at(f, parent)));
        let (lo, hi) = lengths.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), l| (lo.min(l), hi.max(l)));
        (hi >= lo).then_some((hi - lo, j))
    };
    (0..joints.len()).filter_map(drift).fold(None, |best, x| match best {
        Some(b) if b.0 >= x.0 => Some(b),
        _ => Some(x),
    })
}

/// The frames of `clip` from the first to the last second of `window_secs` (both
/// included, rounded to frames), or all of them.
fn window_frames(clip: &Clip, window_secs: Option<(f64, f64)>) -> FrameRange {
    let n = clip.frame_count();
    match window_secs {
        None => FrameRange::new(0, n),
        // Negative or NaN seconds become frame 0 (`as` saturates and maps NaN to 0).
        Some((first, last)) if last >= first => FrameRange::new(
            ((first * clip.fps()).round() as usize).min(n),
            ((last * clip.fps()).round() as usize).saturating_add(1).min(n),
        ),
        Some(_) => FrameRange::new(0, 0),
    }
}

/// `value / reference`, when the reference is above round-off.
fn ratio(value: Option<f64>, reference: Option<f64>) -> Option<f64> {
    match (value, reference) {
        (Some(v), Some(r)) if r > 1e-9 => Some(v / r),
        _ => None,
    }
}

/// The longest run of consecutive `true`s.
fn longest_run(flags: impl Iterator<Item = bool>) -> usize {
    flags.fold((0, 0), |(run, best), x| if x { (run + 1, best.max(run + 1)) } else { (0, best) }).1
}

/// Per joint of `skeleton` (whose body `roles` are), whether it belongs to the body every
/// humanoid rig shares: all joints but those below the wrists (the arms' end joints).
pub fn body_joints(skeleton: &Skeleton, roles: &BodyRoles) -> Vec<bool> {
    let wrists = roles.arms.each_ref().map(|arm| arm.joints()[2]);
    (0..skeleton.len()).map(|j| !wrists.iter().any(|&w| skeleton.is_ancestor(w, j))).collect()
}

/// Measures `clip` (see the module doc). `contacts` are used when they describe this clip,
/// else contacts are detected with `options.contacts`; `sources` are the clips it was made
/// from (any skeleton, any rate); `mesh`, skinned to the clip's skeleton, adds its soles.
pub fn measure_quality(
    clip: &Clip,
    contacts: Option<&Contacts>,
    sources: &[&Clip],
    mesh: Option<&Mesh>,
    options: &QualityOptions,
) -> QualityReport {
    let poses = forward_kinematics(clip);
    let tracks = Tracks::of(clip, &poses);
    let mut findings = Vec::new();
    match clip.frame_count() {
        0 => findings.push("the clip has no frames: nothing is measured".into()),
        1 => {
            findings.push("the clip has a single frame: nothing moves, so only the floor and bones are measured".into())
        }
        2 => findings.push("the clip has two frames: accelerations need three, so they are not measured".into()),
        _ => {}
    }
    let window = window_frames(clip, options.window_secs);
    if window.is_empty() && clip.frame_count() > 0 {
        findings.push(format!(
            "the window holds no frame of the clip ({:.3} s long): nothing is measured",
            clip.duration_secs()
        ));
    }

    // Feet: the connected contacts when they describe this clip, else detected ones.
    let given = contacts.filter(|c| {
        let fits = c.frame_count == clip.frame_count();
        if !fits {
            findings.push(format!(
                "the connected contacts cover {} frames but the clip has {}: contacts were detected instead",
                c.frame_count,
                clip.frame_count()
            ));
        }
        fits
    });
    // The rest legs and body roles, read once: for the contact thresholds and the joints
    // compared with the sources.
    let rest = rest_legs(clip.skeleton());
    let leg_ratio = match (options.contacts.leg_m, &rest) {
        (Some(set_for), Ok((leg_m, _))) => leg_m / set_for,
        _ => 1.0,
    };
    if given.is_none() && (leg_ratio - 1.0).abs() > 0.05 {
        findings.push(format!(
            "contacts detected for legs {leg_ratio:.2} × the reference's: heights and speeds × {leg_ratio:.2} of the \
             defaults"
        ));
    }
    let (contacts_from, feet) = match given {
        Some(c) => ("connected", feet_of(clip, c, window, &mut findings)),
        None => match contacts_of(clip, &poses, &options.contacts) {
            Ok((c, _)) => ("detected", feet_of(clip, &c, window, &mut findings)),
            Err(why) => {
                findings.push(format!("the feet could not be found, so they are not measured: {why}"));
                ("none", Vec::new())
            }
        },
    };
    // Only the positions (`tracks`) are needed from here: the clip's world transforms go.
    drop(poses);
    let (lowest, soles) = lowest_heights(clip, &tracks, &feet, mesh, &mut findings);
    let floor = options.floor_height_m;
    let feet_quality: Vec<FootQuality> = feet
        .iter()
        .zip(&lowest)
        .zip(soles)
        .map(|((foot, low), sole)| foot_quality(&tracks, foot, low, floor, window, sole))
        .collect();
    let measured_feet = !feet_quality.is_empty();
    if measured_feet && feet_quality.iter().all(|f| f.contacts == 0) && clip.frame_count() > 1 {
        findings.push("no foot contacts: the feet never plant, so there is no skate or float to measure".into());
    }
    let below = |f: usize| lowest.iter().any(|l| floor - l[f] > BELOW_FLOOR_SLACK_M);
    let frames_below = (window.start..window.end).filter(|&f| below(f)).count();
    let longest_below_secs = longest_run((window.start..window.end).map(below)) as f64 / clip.fps();
    let pairs: usize = feet_quality.iter().map(|f| f.contact_frame_pairs).sum();
    let worst_foot =
        |value: fn(&FootQuality) -> f64| measured_feet.then(|| feet_quality.iter().map(value).fold(0.0, f64::max));
    let penetration_max_cm = worst_foot(|f| f.penetration_max_cm);
    if let Some(depth) = penetration_max_cm.filter(|_| frames_below > 0) {
        findings.push(format!(
            "feet under the floor by up to {depth:.1} cm in {frames_below} frames (longest {longest_below_secs:.2} s)"
        ));
    }

    // Accelerations and the root, against the sources' own.
    let mut body = |skeleton: &Skeleton, rest: Result<(f64, BodyRoles), RolesError>| match rest {
        Ok((_, roles)) => body_joints(skeleton, &roles),
        Err(why) => {
            if !sources.is_empty() {
                findings
                    .push(format!("the fingers could not be told from the body, so all joints are compared: {why}"));
            }
            Vec::new()
        }
    };
    let peaks = tracks.peak_accelerations(&body(clip.skeleton(), rest));
    let peak_values: Vec<f64> = peaks.iter().map(|p| p[0].0).collect();
    let peak = max_in_window(&peak_values, window);
    let half_width = ((options.neighbourhood_secs * clip.fps()).round() as usize).max(2 * SPIKE_EXCLUSION_FRAMES);
    let spike = max_in_window(&spike_ratios(&peak_values, half_width), window);
    let root = max_in_window(&tracks.root_velocity_changes(), window);
    let source_poses: Vec<ClipPoses> = sources.iter().map(|s| forward_kinematics(s)).collect();
    let source_tracks: Vec<Tracks> = sources.iter().zip(&source_poses).map(|(s, p)| Tracks::of(s, p)).collect();
    let body_values: Vec<f64> = peaks.iter().map(|p| p[1].0).collect();
    let body_peak = max_in_window(&body_values, window).filter(|_| !sources.is_empty());
    let sources_peak = sources
        .iter()
        .zip(&source_tracks)
        .flat_map(|(s, t)| {
            let in_body = body(s.skeleton(), rest_legs(s.skeleton()));
            t.peak_accelerations(&in_body).into_iter().map(|p| p[1].0)
        })
        .reduce(f64::max);
    let sources_root = source_tracks.iter().flat_map(|t| t.root_velocity_changes()).reduce(f64::max);
    if !sources.is_empty() && sources_peak.is_none() {
        findings.push("the source clips have fewer than three frames: nothing to compare with".into());
    }
    let (pop_frames, largest_pop) = pops(&tracks, window);
    if let Some((f, j, moved_m)) = largest_pop {
        findings.push(format!(
            "{pop_frames} frame(s) with a pop; the largest: '{}' jumps {:.1} cm into frame {f} ({:.1} m/s)",
            clip.skeleton().joints()[j].name,
            moved_m * 100.0,
            moved_m * clip.fps()
        ));
    }
    let drift = bone_length_drift(clip, &tracks, window);
    let measured_sources: Vec<(&Clip, &ClipPoses, &Tracks)> =
        sources.iter().zip(&source_poses).zip(&source_tracks).map(|((s, p), t)| (*s, p, t)).collect();
    let (stride, source_strides) = strides(clip, &tracks, &feet, window, &measured_sources, options, &mut findings);
    let stride_against_source = stride.as_ref().and_then(|c| compare_stride(c, &source_strides));
    let joint_name = |j: usize| clip.skeleton().joints()[j].name.clone();
    if findings.len() > MAX_LISTED_FINDINGS {
        let more = findings.len() - MAX_LISTED_FINDINGS;
        findings.truncate(MAX_LISTED_FINDINGS);
        findings.push(format!("… and {more} more"));
    }

    let summary = QualitySummary {
        skate_max_cm_per_frame: worst_foot(|f| f.skate_max_cm_per_frame),
        skate_mean_cm_per_frame: measured_feet.then(|| {
            let total: f64 =
                feet_quality.iter().map(|f| f.skate_mean_cm_per_frame * f.contact_frame_pairs as f64).sum();
            if pairs == 0 { 0.0 } else { total / pairs as f64 }
        }),
        contact_slide_max_cm: worst_foot(|f| f.contact_slide_max_cm),
        penetration_max_cm,
        frames_below_floor: measured_feet.then_some(frames_below),
        float_in_contact_max_cm: worst_foot(|f| f.float_in_contact_max_cm),
        acceleration_peak_mps2: peak.map(|p| p.0),
        acceleration_spike_ratio: spike.map(|s| s.0),
        acceleration_over_sources: ratio(body_peak.map(|p| p.0), sources_peak),
        root_velocity_change_max_mps: root.map(|r| r.0),
        root_velocity_change_over_sources: ratio(root.map(|r| r.0), sources_root),
        bone_length_drift_max_cm: drift.map(|d| d.0 * 100.0),
        pop_frames: (clip.frame_count() > 1).then_some(pop_frames),
        step_over_leg: stride.as_ref().and_then(|s| s.step_over_leg),
        step_over_leg_change_pct: stride_against_source.as_ref().and_then(|c| c.step_over_leg_change_pct),
        pelvis_speed_outside_source_pct: stride_against_source.as_ref().and_then(|c| c.pelvis_speed_outside_source_pct),
        props_penetration_max_cm: None,
    };
    QualityReport {
        units: "lengths cm, speeds m/s, accelerations m/s²; per frame = between consecutive frames at fps",
        frames: clip.frame_count(),
        fps: clip.fps(),
        floor_height_m: floor,
        window_frames: (window.start, window.end),
        contacts: contacts_from,
        summary,
        feet: feet_quality,
        longest_below_floor_secs: longest_below_secs,
        acceleration_peak_at: peak.map(|(_, f)| (f, joint_name(peaks[f - 1][0].1))),
        body_acceleration_peak_at: body_peak.map(|(_, f)| (f, joint_name(peaks[f - 1][1].1))),
        acceleration_spike_frame: spike.map(|s| s.1),
        sources_acceleration_peak_mps2: sources_peak,
        root_velocity_change_frame: root.map(|r| r.1),
        sources_root_velocity_change_max_mps: sources_root,
        bone_length_drift_joint: drift.map(|d| joint_name(d.1)),
        stride,
        source_strides,
        stride_against_source,
        props: None,
        findings,
    }
}

impl QualityReport {
    /// Adds how deep `mesh` (skinned to `clip`, the clip this report measured) goes into
    /// `props` over the report's window; without a usable mesh it says so in the findings.
    /// Props without triangles (a simulation without a stool) are no props: nothing is added.
    pub fn measure_props(&mut self, clip: &Clip, mesh: Option<&Mesh>, props: &Mesh) {
        if props.triangles.is_empty() {
            return;
        }
        let Some(mesh) = mesh else {
            self.findings.push("props need the skinned mesh: how deep the body goes into them is not measured".into());
            return;
        };
        let window = FrameRange { start: self.window_frames.0, end: self.window_frames.1 };
        match props_penetration(clip, mesh, props, window) {
            Ok(p) => {
                if p.frames_inside > 0 {
                    self.findings.push(format!(
                        "the body goes {:.1} cm into a prop (frame {}; {} frames inside)",
                        p.max_cm,
                        p.max_frame.unwrap_or(0),
                        p.frames_inside
                    ));
                }
                self.summary.props_penetration_max_cm = Some(p.max_cm);
                self.props = Some(p);
            }
            Err(why) => self.findings.push(format!("how deep the body goes into the props is not measured: {why}")),
        }
    }
}

/// Limits on a [`QualitySummary`]: what `kg test` holds a `motion.quality` node to. Unset
/// limits are not checked. In an expectation file: `(max_skate_cm: 0.5, max_penetration_cm: 0.5)`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QualityGate {
    /// Limit on `skate_max_cm_per_frame`, cm per frame.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_skate_cm: Option<f64>,
    /// Limit on `contact_slide_max_cm`, cm.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_contact_slide_cm: Option<f64>,
    /// Limit on `penetration_max_cm`, cm.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_penetration_cm: Option<f64>,
    /// Limit on `float_in_contact_max_cm`, cm.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_float_cm: Option<f64>,
    /// Limit on `acceleration_spike_ratio`.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_spike_ratio: Option<f64>,
    /// Limit on `acceleration_over_sources`.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_acceleration_over_sources: Option<f64>,
    /// Limit on `root_velocity_change_max_mps`, m/s.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_root_velocity_change_mps: Option<f64>,
    /// Limit on `root_velocity_change_over_sources`.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_root_velocity_change_over_sources: Option<f64>,
    /// Limit on `bone_length_drift_max_cm`, cm.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_bone_drift_cm: Option<f64>,
    /// Limit on `pop_frames`.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_pop_frames: Option<f64>,
    /// Limit on `step_over_leg_change_pct`, percent (issue 18 asks 10).
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_step_ratio_change_pct: Option<f64>,
    /// Limit on `pelvis_speed_outside_source_pct`, percent.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_pelvis_speed_outside_source_pct: Option<f64>,
    /// Limit on `props_penetration_max_cm`, cm.
    #[serde(default, skip_serializing_if = "Option::is_none", with = "bare_number")]
    pub max_props_penetration_cm: Option<f64>,
}

impl QualityGate {
    /// One line per limit `summary` breaks: the measure, its value and unit, the limit's
    /// name and value. A limit on a measure that could not be taken breaks too: a gate
    /// never passes by not looking.
    pub fn violations(&self, summary: &QualitySummary) -> Vec<String> {
        let count = |n: Option<usize>| n.map(|n| n as f64);
        let checks = [
            ("max_skate_cm", self.max_skate_cm, "skate_max_cm_per_frame", summary.skate_max_cm_per_frame, " cm/frame"),
            (
                "max_contact_slide_cm",
                self.max_contact_slide_cm,
                "contact_slide_max_cm",
                summary.contact_slide_max_cm,
                " cm",
            ),
            ("max_penetration_cm", self.max_penetration_cm, "penetration_max_cm", summary.penetration_max_cm, " cm"),
            ("max_float_cm", self.max_float_cm, "float_in_contact_max_cm", summary.float_in_contact_max_cm, " cm"),
            (
                "max_spike_ratio",
                self.max_spike_ratio,
                "acceleration_spike_ratio",
                summary.acceleration_spike_ratio,
                "×",
            ),
            (
                "max_acceleration_over_sources",
                self.max_acceleration_over_sources,
                "acceleration_over_sources",
                summary.acceleration_over_sources,
                "×",
            ),
            (
                "max_root_velocity_change_mps",
                self.max_root_velocity_change_mps,
                "root_velocity_change_max_mps",
                summary.root_velocity_change_max_mps,
                " m/s",
            ),
            (
                "max_root_velocity_change_over_sources",
                self.max_root_velocity_change_over_sources,
                "root_velocity_change_over_sources",
                summary.root_velocity_change_over_sources,
                "×",
            ),
            (
                "max_bone_drift_cm",
                self.max_bone_drift_cm,
                "bone_length_drift_max_cm",
                summary.bone_length_drift_max_cm,
                " cm",
            ),
            ("max_pop_frames", self.max_pop_frames, "pop_frames", count(summary.pop_frames), ""),
            (
                "max_step_ratio_change_pct",
                self.max_step_ratio_change_pct,
                "step_over_leg_change_pct",
                summary.step_over_leg_change_pct,
                " %",
            ),
            (
                "max_pelvis_speed_outside_source_pct",
                self.max_pelvis_speed_outside_source_pct,
                "pelvis_speed_outside_source_pct",
                summary.pelvis_speed_outside_source_pct,
                " %",
            ),
            (
                "max_props_penetration_cm",
                self.max_props_penetration_cm,
                "props_penetration_max_cm",
                summary.props_penetration_max_cm,
                " cm",
            ),
        ];
        checks
            .into_iter()
            .filter_map(|(limit_name, limit, measure, value, unit)| {
                let limit = limit?;
                match value {
                    Some(v) if v <= limit => None,
                    Some(v) => {
                        let shown = (v * 1000.0).round() / 1000.0;
                        Some(format!("{measure} = {shown}{unit}, above {limit_name} {limit}"))
                    }
                    None => {
                        Some(format!("{measure} was not measured (see the report's findings), so {limit_name} fails"))
                    }
                }
            })
            .collect()
    }
}

/// Optional limits written as bare numbers (`0.5`, not `Some(0.5)`) in RON files.
mod bare_number {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(value: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        match value {
            Some(v) => s.serialize_f64(*v),
            None => s.serialize_none(),
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        f64::deserialize(d).map(Some)
    }
}
