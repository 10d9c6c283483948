//! Angular-momentum-guided concatenation (Shum, Komura & Yadav 2009).
//!
//! Steps, with the paper's equations:
//! 1. Turn the second clip about the vertical so its mean main-phase momentum agrees
//!    (forward rule) or opposes (reverse rule) the first's (eq. 2).
//! 2. Blendable periods per rule: forward — the second half of the first clip's main phase
//!    and the first half of the second's; reverse — either the second half of the first's
//!    main phase with the second half of the second's preparatory phase, or the first half
//!    of the first's posterior phase with the first half of the second's main phase (both
//!    are tried when both exist; the cheaper wins). Frames outside double support are
//!    dropped (see [`Support`]).
//! 3. For every offset T (the second clip starts T frames after the first):
//!    f_T = argmin_f ‖L1(f) − L2(f−T)‖² (eq. 5), and
//!    F = F_dm + F_inertia + F_time (eqs. 3, 4, 6, 7); keep the T of least F and refuse
//!    when F, relative to the clips' squared peak momenta, is above a threshold.
//! 4. Grow the blend window from f_T both ways while ‖L1 − L2‖² stays under a threshold
//!    and both clips stay inside their blendable periods; move the second clip so the
//!    centres of the feet coincide at the window's start; refuse if the torsos then face
//!    more than a limit apart.
//! 5. Blend linearly (eq. 8; slerp for rotations), then rescale time over the window by s
//!    (eq. 9), read here as the mean of the end magnitudes over the window's mean |L| —
//!    the norm of the sum the paper prints vanishes under the reverse rule.
//! 6. The paper's clean-up: blending two clips' legs makes planted feet slide, so the feet
//!    in contact (detected on the result) during every plant that touches the window are
//!    held where they were put down by the foot lock ([`crate::kernels::ik::foot_lock`]):
//!    the whole plant, so a foot is never released mid-plant; a planted foot the blend puts
//!    under the floor (y = 0) is lifted onto it. Frames outside those plants are the clips'
//!    own ([`ConcatParams::foot_lock`] turns it off).

use std::sync::Arc;

use glam::{DVec3, Quat, Vec3};
use serde_json::json;

use crate::kernels::align::{Rule, alignment_yaw, facing_difference, place, torso_facing, yaw_rotation};
use crate::kernels::analysis::{Analysis, AnalysisOptions, analyse};
use crate::kernels::ik::foot_lock::hold_detected_plants;
use crate::kernels::join::{ConcatError, Concatenated, foot_skate_m, same_skeleton, splice};
use crate::kernels::resample::push_sample;
use crate::model::choice::{Choice, choices};
use crate::model::{Clip, ClipError, Contacts, FootContacts, FrameRange, into_report};

/// Which frames of the blendable periods may be blended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Support {
    /// Double support where the periods have at least `min_blend_secs` of it; all frames
    /// otherwise (an airborne flip), with a note in the report.
    Auto,
    /// Only double-support frames (the paper's rule); refuses when the periods have less
    /// than `min_blend_secs` of it.
    Double,
    /// Every frame.
    Any,
}

choices!(Support { Auto = "auto", Double = "double", Any = "any" });

/// Settings of the concatenation.
#[derive(Clone, Debug, PartialEq)]
pub struct ConcatParams {
    /// Forward or reverse rule.
    pub rule: Rule,
    /// Double-support truncation.
    pub support: Support,
    /// Weights of F_dm, F_inertia and F_time (the paper: all 1).
    pub weights: [f64; 3],
    /// Refuse when F / (½(peak|L1|² + peak|L2|²)) exceeds this.
    pub max_relative_cost: f64,
    /// The window grows while ‖L1 − L2‖² / (½(peak|L1|² + peak|L2|²)) stays below this.
    pub window_threshold: f64,
    /// The window is at least this long where both clips have frames, seconds.
    pub min_blend_secs: f64,
    /// Refuse when, where the blend starts and after alignment, the torsos face further
    /// apart than this (or, for a body far from upright, are turned further apart), radians.
    pub max_facing_rad: f64,
    /// Bounds on the time scale s of eq. 9 (1..1 turns scaling off).
    pub time_scale_range: (f64, f64),
    /// The second clip's main-phase peak plays at least this long after the first's,
    /// seconds, before the blend's time scaling (which can shorten the window by up to
    /// 1 − 1/s). The paper's cost favours the earliest blend, which for two similar motions
    /// overlaps their main phases into one; a gap keeps both (a double flip stays double),
    /// and then the blend also stays clear of each action's effector apex (a kick's toe at
    /// its highest), running on into the first clip's posterior phase if it must.
    pub min_peak_gap_secs: f64,
    /// Hold the feet planted through the plants that touch the blend window (step 6).
    pub foot_lock: bool,
}

impl Default for ConcatParams {
    fn default() -> Self {
        ConcatParams {
            rule: Rule::Forward,
            support: Support::Auto,
            weights: [1.0, 1.0, 1.0],
            max_relative_cost: 1.0,
            window_threshold: 0.25,
            min_blend_secs: 0.25,
            max_facing_rad: std::f64::consts::FRAC_PI_4,
            time_scale_range: (0.5, 2.0),
            min_peak_gap_secs: 0.0,
            foot_lock: true,
        }
    }
}

/// The contacts of `contacts` that overlap `window`, whole; the others dropped.
fn plants_touching(contacts: &Contacts, window: FrameRange) -> Contacts {
    let feet = contacts
        .feet
        .iter()
        .map(|c| FootContacts {
            foot: c.foot.clone(),
            intervals: c.intervals.iter().filter(|r| r.intersect(&window).is_some()).copied().collect(),
        })
        .collect();
    Contacts { feet, double_support: Vec::new(), ..contacts.clone() }
}

/// One way to pair the clips' blendable periods.
#[derive(Clone, Debug, PartialEq)]
struct Case {
    name: &'static str,
    first: FrameRange,
    second: FrameRange,
}

/// An end effector (foot or hand) must rise at least this far during the main phase for
/// its apex to count as the action's (a kick's toe, an uppercut's fist), metres.
const MIN_APEX_RISE_M: f32 = 0.1;

/// The frame where the action's effector peaks: of the feet and hands, the one that rises
/// most during the main phase (above its height at the phase's start), at its highest
/// frame there. `None` when none rises by [`MIN_APEX_RISE_M`] (a walk, a twist).
fn effector_apex(a: &Analysis) -> Option<usize> {
    let main = a.phases.main;
    if main.is_empty() {
        return None;
    }
    let ends = a.landmarks.limbs.iter().flat_map(|limb| [limb[2], limb[5]]);
    let height = |f: usize, j: usize| a.poses.frame(f)[j].translation.y;
    ends.filter_map(|j| {
        let top = (main.start..main.end).max_by(|&x, &y| height(x, j).total_cmp(&height(y, j)))?;
        let rise = height(top, j) - height(main.start, j);
        (rise >= MIN_APEX_RISE_M).then_some((rise, top))
    })
    .max_by(|x, y| x.0.total_cmp(&y.0))
    .map(|(_, top)| top)
}

/// The frames of a clip's action that a blend must not reach: its momentum peak t_m and,
/// with `apex`, its effector apex, as the last protected frame of the first clip
/// (`Side::First`: the blend starts after it) or the first of the second (`Side::Second`:
/// the blend ends before it). Blending across an apex replaces the kick by a mix of two
/// poses; a clip joined to itself at its peak (no gap asked) blends equal poses there and
/// keeps it anyway, so the apex is protected only when two distinct actions are asked for.
fn protected_frame(a: &Analysis, side: Side, apex: bool) -> usize {
    let peak = a.phases.main_frame;
    match (side, if apex { effector_apex(a) } else { None }) {
        (Side::First, Some(apex)) => peak.max(apex),
        (Side::Second, Some(apex)) => peak.min(apex),
        (_, None) => peak,
    }
}

/// Which clip of a join.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    First,
    Second,
}

/// The latter half of the main phase: from its peak frame t_m on (the halves meet at the
/// peak, so a clip concatenated with itself under the forward rule joins at its peak), or
/// from after the effector apex when that comes later. When the apex leaves fewer than
/// `min_frames` of the phase, the period runs on into the posterior phase.
fn main_after_peak(a: &Analysis, keep: usize, min_frames: usize) -> FrameRange {
    let p = &a.phases;
    let start = if keep == p.main_frame { keep.max(p.main.start) } else { keep + 1 };
    let end = p.main.end.max(start + min_frames).min(p.frame_count);
    FrameRange::new(start.min(end), end)
}

/// The initial half of the main phase: up to and including its peak frame t_m, or up to
/// just before the effector apex when that comes earlier.
fn main_before_peak(a: &Analysis, keep: usize) -> FrameRange {
    let p = &a.phases;
    let end = if keep == p.main_frame { keep + 1 } else { keep };
    FrameRange::new(p.main.start, end.min(p.main.end).max(p.main.start))
}

/// The blendable periods per rule; `keep` holds each clip's protected frame
/// ([`protected_frame`]: first clip, second clip).
fn cases(
    rule: Rule,
    a: &Analysis,
    b: &Analysis,
    keep: (usize, usize),
    min_frames: usize,
) -> Result<Vec<Case>, ConcatError> {
    let (pa, pb) = (&a.phases, &b.phases);
    let out = match rule {
        Rule::Forward => {
            vec![Case {
                name: "main -> main",
                first: main_after_peak(a, keep.0, min_frames),
                second: main_before_peak(b, keep.1),
            }]
        }
        Rule::Reverse => {
            let mut v = Vec::new();
            if let Some(prep) = pb.preparatory {
                v.push(Case {
                    name: "main -> preparatory",
                    first: main_after_peak(a, keep.0, min_frames),
                    second: prep.second_half(),
                });
            }
            if let Some(post) = pa.posterior {
                v.push(Case {
                    name: "posterior -> main",
                    first: post.first_half(),
                    second: main_before_peak(b, keep.1),
                });
            }
            v
        }
    };
    let out: Vec<Case> = out.into_iter().filter(|c| !c.first.is_empty() && !c.second.is_empty()).collect();
    if out.is_empty() {
        let why = match rule {
            Rule::Forward => "a main phase is too short".to_string(),
            Rule::Reverse => "the second clip has no preparatory phase and the first no posterior phase".to_string(),
        };
        return Err(ConcatError::NoBlendablePeriod { rule: rule.name(), why });
    }
    Ok(out)
}

/// The best timing found for one case.
#[derive(Clone, Debug, PartialEq)]
pub struct Timing {
    /// Offset of the second clip, frames (its frame g plays at the first clip's g + T).
    pub offset: isize,
    /// Blend centre f_T, in the first clip's frames.
    pub centre: usize,
    /// F_dm, F_inertia, F_time (weighted).
    pub terms: [f64; 3],
}

impl Timing {
    /// F.
    pub fn cost(&self) -> f64 {
        self.terms.iter().sum()
    }
}

/// Which frames each clip may blend at: the blendable period, truncated by support.
struct Allowed {
    first: Vec<bool>,
    second: Vec<bool>,
    first_range: FrameRange,
    second_range: FrameRange,
    support_used: &'static str,
}

fn allowed(case: &Case, a: &Analysis, b: &Analysis, support: Support, min_frames: usize) -> Option<Allowed> {
    let mask = |an: &Analysis, r: FrameRange, double: bool| {
        (0..an.clip.frame_count()).map(|f| r.contains(f) && (!double || an.in_double_support(f))).collect::<Vec<_>>()
    };
    let make = |double: bool, label| Allowed {
        first: mask(a, case.first, double),
        second: mask(b, case.second, double),
        first_range: case.first,
        second_range: case.second,
        support_used: label,
    };
    let enough = |m: &Allowed| {
        m.first.iter().filter(|x| **x).count() >= min_frames.min(case.first.len())
            && m.second.iter().filter(|x| **x).count() >= min_frames.min(case.second.len())
    };
    match support {
        Support::Any => Some(make(false, "any")),
        Support::Double => Some(make(true, "double")).filter(|m| enough(m) && m.first.contains(&true)),
        Support::Auto => {
            let d = make(true, "double");
            if enough(&d) && d.first.contains(&true) && d.second.contains(&true) {
                Some(d)
            } else {
                Some(make(false, "any (the blendable periods have too little double support)"))
            }
        }
    }
}

/// One side of the timing search: a clip's (already aligned) curves and where it may blend.
#[derive(Clone, Copy, Debug)]
pub struct TimingSide<'a> {
    /// Smoothed angular momentum per frame, kg·m²/s.
    pub momentum: &'a [DVec3],
    /// Moment arms, frame-major, one per segment (metres).
    pub arms_m: &'a [Vec3],
    /// Whether each frame lies in the (truncated) blendable period.
    pub allowed: &'a [bool],
}

/// The optimal-timing search (eqs. 3–7): every offset T, its blend centre f_T and cost F.
#[derive(Clone, Copy, Debug)]
pub struct TimingSearch<'a> {
    /// The first clip.
    pub first: TimingSide<'a>,
    /// The second clip.
    pub second: TimingSide<'a>,
    /// Segment masses (kg), the same segments as the arms.
    pub masses_kg: &'a [f64],
    /// f_start of eq. 7: the first frame of the first clip's blendable period.
    pub first_start: usize,
    /// Weights of F_dm, F_inertia, F_time.
    pub weights: [f64; 3],
    /// Smallest offset considered, frames (the paper: none).
    pub min_offset: isize,
}

impl TimingSearch<'_> {
    /// The offset of least F. Brute force over every offset, as in the paper:
    /// O(|B1|·|B2|) momentum differences plus one inertia term per offset.
    pub fn run(&self) -> Option<Timing> {
        let (l1, l2) = (self.first.momentum, self.second.momentum);
        let segments = self.masses_kg.len();
        let first_frames: Vec<usize> = (0..l1.len()).filter(|&f| self.first.allowed[f]).collect();
        let second_frames: Vec<usize> = (0..l2.len()).filter(|&g| self.second.allowed[g]).collect();
        let (&f_lo, &f_hi) = (first_frames.first()?, first_frames.last()?);
        let (&g_lo, &g_hi) = (second_frames.first()?, second_frames.last()?);
        let l_start = l1[self.first_start.min(l1.len() - 1)];
        let lowest = (f_lo as isize - g_hi as isize).max(self.min_offset);
        let mut best: Option<Timing> = None;
        for offset in lowest..=(f_hi as isize - g_lo as isize) {
            let mut centre: Option<(usize, f64)> = None;
            for &f in &first_frames {
                let g = f as isize - offset;
                if g < 0 || g as usize >= l2.len() || !self.second.allowed[g as usize] {
                    continue;
                }
                let d = (l1[f] - l2[g as usize]).length_squared();
                if centre.is_none_or(|(_, best_d)| d < best_d) {
                    centre = Some((f, d));
                }
            }
            let Some((f, f_dm)) = centre else { continue };
            let g = (f as isize - offset) as usize;
            let r1 = &self.first.arms_m[f * segments..(f + 1) * segments];
            let r2 = &self.second.arms_m[g * segments..(g + 1) * segments];
            let f_inertia: f64 = (0..segments)
                .map(|j| {
                    let dot = f64::from(r1[j].dot(r2[j] - r1[j]));
                    self.masses_kg[j] * dot * dot
                })
                .sum();
            let f_time = (l1[f] - l_start).length_squared();
            let w = self.weights;
            let t = Timing { offset, centre: f, terms: [w[0] * f_dm, w[1] * f_inertia, w[2] * f_time] };
            if best.as_ref().is_none_or(|b| t.cost() < b.cost()) {
                best = Some(t);
            }
        }
        best
    }
}

/// The smallest offset T considered: the second motion never starts before the first, and
/// its main-phase peak (at frame `peak2 + T` of the result) plays at least
/// `min_peak_gap_secs` after the first's.
fn min_offset(params: &ConcatParams, a: &Analysis, b: &Analysis) -> isize {
    let gap = (params.min_peak_gap_secs * a.clip.fps()).round() as isize;
    (a.phases.main_frame as isize - b.phases.main_frame as isize + gap).max(0)
}

/// Share of the rescaled window, at each end, over which playback eases between normal
/// speed and the scaled speed.
const EASE_SHARE: f64 = 0.25;

/// Source frames (after the window's start) played by output frame `u` of a window of
/// `span` source frames stretched over `n` output frames. Speed is one source frame per
/// frame at both ends and eases by a smoothstep S over `ramp` frames to the constant speed
/// v = (span − ramp) / (n − ramp) in the middle (so the total is `span`): the integral of
/// 1 + (v − 1)·S(u/ramp), with ∫₀ˣ S = x³ − x⁴/2, mirrored at the end.
fn eased_time(u: f64, n: f64, span: f64, ramp: f64) -> f64 {
    let v = (span - ramp) / (n - ramp);
    let ramp_part = |w: f64| {
        let x = w / ramp;
        w + (v - 1.0) * ramp * (x * x * x - 0.5 * x * x * x * x)
    };
    if u <= ramp {
        ramp_part(u)
    } else if u >= n - ramp {
        span - ramp_part(n - u)
    } else {
        ramp_part(ramp) + v * (u - ramp)
    }
}

/// Replaces frames `f0..=ff` of `clip` by the same stretch played over `new_len` frame
/// intervals: the time scaling of eq. 9. Playback speed eases from normal speed into the
/// scaled speed and back out over the first and last quarter of the window
/// (`eased_time`) instead of switching in one frame: a jump in speed is a jump in every
/// joint's velocity, an acceleration spike at both window edges. With the scale
/// s = (ff − f0) / new_len in [1/2, 2] the speed stays positive (the window never plays
/// backwards).
pub fn rescale_window(clip: &Clip, f0: usize, ff: usize, new_len: usize) -> Result<Clip, ClipError> {
    if ff <= f0 || new_len == 0 {
        return Ok(clip.clone());
    }
    let joints = clip.joint_count();
    let (span, n) = ((ff - f0) as f64, new_len as f64);
    let ramp = EASE_SHARE * n;
    let mut rotations = clip.rotations()[..f0 * joints].to_vec();
    let mut translations = clip.translations()[..f0 * joints].to_vec();
    for i in 0..=new_len {
        push_sample(clip, f0 as f64 + eased_time(i as f64, n, span, ramp), &mut rotations, &mut translations);
    }
    rotations.extend_from_slice(&clip.rotations()[(ff + 1) * joints..]);
    translations.extend_from_slice(&clip.translations()[(ff + 1) * joints..]);
    Clip::new(clip.skeleton().clone(), clip.fps(), rotations, translations, clip.import_scale)
}

/// Peak of the smoothed |L| inside `frames`.
fn peak_in(analysis: &Analysis, frames: FrameRange) -> f64 {
    (frames.start..frames.end.min(analysis.smoothed.len())).map(|f| analysis.smoothed[f].length()).fold(0.0, f64::max)
}

/// The yaw that aligns `b` to `a` (eq. 2) and what it was read from; the mean momenta are
/// taken over `ranges` (the main phases: whole-clip means cancel out for motions with
/// strong preparatory or posterior phases). When the mean
/// momenta are nearly vertical (a punch twists the torso about the vertical axis), turning
/// barely changes their dot product and eq. 2 leaves the yaw to noise; the torso facings at
/// the main-phase peaks decide it instead.
pub fn alignment(a: &Analysis, b: &Analysis, ranges: (FrameRange, FrameRange), rule: Rule) -> (f64, &'static str) {
    let (la, lb) = (a.mean_momentum(ranges.0), b.mean_momentum(ranges.1));
    let horizontal = |l: DVec3| (l.x * l.x + l.z * l.z).sqrt();
    if horizontal(la) * horizontal(lb) >= 0.2 * la.length() * lb.length() {
        return (alignment_yaw(la, lb, rule), "momentum");
    }
    let facing = |an: &Analysis| torso_facing(&an.poses, an.phases.main_frame, &an.landmarks);
    match (facing(a), facing(b)) {
        (Some(fa), Some(fb)) => {
            let yaw = f64::from(fb.z * fa.x - fb.x * fa.z).atan2(f64::from(fb.dot(fa)));
            (yaw, "facing (the mean momenta are nearly vertical)")
        }
        _ => (alignment_yaw(la, lb, rule), "momentum"),
    }
}

/// Whether `foot` (a joint index) of `an` is in contact at `frame`.
fn planted(an: &Analysis, foot: usize, frame: usize) -> bool {
    let name = &an.clip.skeleton().joints()[foot].name;
    an.contacts.feet.iter().any(|c| &c.foot == name && c.intervals.iter().any(|r| r.contains(frame)))
}

/// The horizontal move of the (turned) second clip that lines it up with the first over the
/// window `f0..=ff` (second clip's frame g plays at g + `t`). The paper puts the feet
/// centres together where the blend starts, in double support. Here: the feet planted in
/// both clips at the same window frame are matched on average over those frames, so a
/// standing foot stays where it is through the blend; with no such frame (a flip, a leap)
/// the root paths are matched on average instead, since the blend interpolates root
/// positions and any disagreement between them becomes a glide of the whole body.
fn placement(a: &Analysis, b: &Analysis, (f0, ff): (usize, usize), t: isize, turn: Quat) -> Vec3 {
    let horizontal = |v: Vec3| Vec3::new(v.x, 0.0, v.z);
    let frames = || (f0..=ff).map(|f| (f, (f as isize - t) as usize));
    let (mut feet_sum, mut feet_n) = (Vec3::ZERO, 0usize);
    for foot in a.landmarks.feet() {
        for (f, g) in frames().filter(|&(f, g)| planted(a, foot, f) && planted(b, foot, g)) {
            feet_sum += horizontal(a.poses.position(f, foot) - turn * b.poses.position(g, foot));
            feet_n += 1;
        }
    }
    if feet_n > 0 {
        return feet_sum / feet_n as f32;
    }
    let roots: Vec3 = frames().map(|(f, g)| horizontal(a.poses.position(f, 0) - turn * b.poses.position(g, 0))).sum();
    roots / (ff - f0 + 1) as f32
}

/// Concatenates two analysed clips (same skeleton, same frame rate) by the method above.
pub fn concatenate(
    a: &Analysis,
    b: &Analysis,
    params: &ConcatParams,
    options: &AnalysisOptions,
) -> Result<Concatenated, ConcatError> {
    same_skeleton(&a.clip, &b.clip)?;
    let fps = a.clip.fps();
    // 1. Alignment about the vertical axis (the main phases' mean momenta).
    let (yaw, yaw_from) = alignment(a, b, (a.phases.main, b.phases.main), params.rule);
    let turn_f = yaw_rotation(yaw);
    // F_inertia pairs the two clips' segments one to one: with rest offsets that differ, the
    // bone-length model can give the second clip other segments, so its momentum and arms
    // are then recomputed under the first clip's model.
    let same_model;
    let (b_momentum, b_arms) = if a.model == b.model {
        (&b.smoothed, &b.track.arms_m)
    } else {
        same_model = a.reanalysed(b.clip.clone(), options);
        (&same_model.smoothed, &same_model.track.arms_m)
    };
    let l2: Vec<DVec3> = b_momentum.iter().map(|l| turn_f.as_dquat() * *l).collect();
    let arms2: Vec<Vec3> = b_arms.iter().map(|r| turn_f * *r).collect();
    // 2–3. Blendable periods and the optimal timing per pairing of them.
    let scale = 0.5 * (a.smoothed_peak().powi(2) + b.smoothed_peak().powi(2)).max(f64::MIN_POSITIVE);
    let min_frames = ((params.min_blend_secs * fps).round() as usize).max(2);
    let mut best: Option<(Case, Allowed, Timing)> = None;
    // The frames the blend must stay clear of (the effector apexes only when two distinct
    // actions are asked for): found once, used by the periods and the window's growth.
    let apex = params.min_peak_gap_secs > 0.0;
    let keep = (protected_frame(a, Side::First, apex), protected_frame(b, Side::Second, apex));
    for case in cases(params.rule, a, b, keep, min_frames)? {
        let Some(mask) = allowed(&case, a, b, params.support, min_frames) else { continue };
        let timing = TimingSearch {
            first: TimingSide { momentum: &a.smoothed, arms_m: &a.track.arms_m, allowed: &mask.first },
            second: TimingSide { momentum: &l2, arms_m: &arms2, allowed: &mask.second },
            masses_kg: &a.track.masses_kg,
            first_start: case.first.start,
            weights: params.weights,
            min_offset: min_offset(params, a, b),
        }
        .run();
        if let Some(t) = timing
            && best.as_ref().is_none_or(|(_, _, b)| t.cost() < b.cost())
        {
            best = Some((case, mask, t));
        }
    }
    let Some((case, mask, timing)) = best else {
        let mut why = "the blendable periods never overlap".to_string();
        if params.support != Support::Any {
            why += " in double support (set support to \"any\" to blend in the air)";
        }
        if params.min_peak_gap_secs > 0.0 {
            why += &format!(" with the peaks {} s apart (lower min_peak_gap_secs)", params.min_peak_gap_secs);
        }
        return Err(ConcatError::NoBlendablePeriod { rule: params.rule.name(), why });
    };
    let relative_cost = timing.cost() / scale;
    if relative_cost > params.max_relative_cost {
        return Err(ConcatError::TooDifferent {
            relative_cost,
            threshold: params.max_relative_cost,
            f_dm: timing.terms[0],
            f_inertia: timing.terms[1],
            f_time: timing.terms[2],
        });
    }
    // 4. The blend window, grown from f_T.
    let t = timing.offset;
    let ok = |f: isize| {
        let g = f - t;
        f >= 0
            && (f as usize) < mask.first.len()
            && g >= 0
            && (g as usize) < mask.second.len()
            && mask.first[f as usize]
            && mask.second[g as usize]
    };
    let diff = |f: isize| (a.smoothed[f as usize] - l2[(f - t) as usize]).length_squared() / scale;
    let (mut f0, mut ff) = (timing.centre as isize, timing.centre as isize);
    while ok(f0 - 1) && diff(f0 - 1) <= params.window_threshold {
        f0 -= 1;
    }
    while ok(ff + 1) && diff(ff + 1) <= params.window_threshold {
        ff += 1;
    }
    let grown_by_threshold = (ff - f0) as usize;
    // A window of a few frames is a pop, not a blend: below the minimum length it grows on
    // beyond the blendable periods (anywhere both clips have frames), towards the side
    // whose momenta agree better.
    // It never reaches either clip's protected action frames (momentum peak, effector apex).
    let (keep_first, keep_second) = (keep.0 as isize, keep.1 as isize);
    let inside = |f: isize| {
        f >= 0
            && (f as usize) < mask.first.len()
            && f - t >= 0
            && ((f - t) as usize) < l2.len()
            && f > keep_first.min(timing.centre as isize - 1)
            && f - t < keep_second.max(timing.centre as isize - t + 1)
    };
    while ((ff - f0) as usize) < min_frames && (inside(f0 - 1) || inside(ff + 1)) {
        let back = if inside(f0 - 1) { diff(f0 - 1) } else { f64::INFINITY };
        let forth = if inside(ff + 1) { diff(ff + 1) } else { f64::INFINITY };
        if back <= forth { f0 -= 1 } else { ff += 1 }
    }
    let (f0, ff) = (f0 as usize, ff as usize);
    let g0 = (f0 as isize - t) as usize;
    // Facing check where the blend starts, then the sliding that puts the feet together.
    let centre = timing.centre;
    let (facing_angle, facing_compared) =
        facing_difference((&a.poses, &a.landmarks, f0), (&b.poses, &b.landmarks, g0), turn_f);
    if facing_angle > params.max_facing_rad {
        return Err(ConcatError::Facing {
            angle_deg: facing_angle.to_degrees(),
            max_deg: params.max_facing_rad.to_degrees(),
        });
    }
    let offset_m = placement(a, b, (f0, ff), t, turn_f);
    let placed = place(&b.clip, yaw, offset_m)?;
    // 5. Blend, then rescale time over the window (eq. 9).
    let blended = Arc::new(splice(&a.clip, &placed, f0, ff, t)?);
    let blended_analysis = a.reanalysed(blended.clone(), options);
    let mags: Vec<f64> = (f0..=ff).map(|f| blended_analysis.smoothed[f].length()).collect();
    let mean_window = mags.iter().sum::<f64>() / mags.len() as f64;
    let ends = 0.5 * (mags[0] + mags[mags.len() - 1]);
    let s_raw = if mean_window > 1e-9 { ends / mean_window } else { 1.0 };
    let (lo, hi) = params.time_scale_range;
    let s = s_raw.clamp(lo.min(hi), hi.max(lo));
    let new_len = (((ff - f0) as f64 / s).round() as usize).max(1);
    // Measurements on the result (analysed again only when the window was rescaled).
    let (out, result) = if ff > f0 && new_len != ff - f0 {
        let out = Arc::new(rescale_window(&blended, f0, ff, new_len)?);
        let result = a.reanalysed(out.clone(), options);
        (out, result)
    } else {
        (blended, blended_analysis)
    };
    let window_out = FrameRange::new(f0, f0 + new_len + 1);
    // 6. Feet held through the plants the blend touches.
    let held = if params.foot_lock {
        hold_detected_plants(&out, &options.contacts, |detected| plants_touching(&detected, window_out))
            .map_err(ConcatError::FootLock)?
    } else {
        None
    };
    let locked_plants = held.as_ref().map_or(0, |(_, count)| *count);
    let (out, result) = match held {
        Some((locked, _)) => {
            let out = Arc::new(locked);
            let result = a.reanalysed(out.clone(), options);
            (out, result)
        }
        None => (out, result),
    };
    let skate = foot_skate_m(&result, window_out, options.contacts.enter_height_m);
    let secs = |frames: f64| frames / fps;
    let report = json!({
        "method": "angular momentum (Shum et al. 2009)",
        "rule": params.rule.name(),
        "case": case.name,
        "support": mask.support_used,
        "yaw_deg": yaw.to_degrees(),
        "yaw_from": yaw_from,
        "blendable_first": [mask.first_range.start, mask.first_range.end],
        "blendable_second": [mask.second_range.start, mask.second_range.end],
        "offset_frames": t,
        "offset_secs": secs(t as f64),
        "blend_centre_frame": centre,
        "blend_centre_secs": secs(centre as f64),
        "cost": timing.cost(),
        "relative_cost": relative_cost,
        "f_dm": timing.terms[0],
        "f_inertia": timing.terms[1],
        "f_time": timing.terms[2],
        "window_frames": [f0, ff],
        "window_secs": [secs(f0 as f64), secs(ff as f64)],
        "window_grown_by_threshold_frames": grown_by_threshold,
        "facing_deg": facing_angle.to_degrees(),
        "facing_compared": facing_compared,
        "feet_offset_m": [offset_m.x, offset_m.z],
        "time_scale_raw": s_raw,
        "time_scale": s,
        "window_after_scaling_frames": [window_out.start, window_out.end - 1],
        "duration_first_secs": a.clip.duration_secs(),
        "duration_second_secs": b.clip.duration_secs(),
        "duration_secs": out.duration_secs(),
        "peak_momentum_first": a.smoothed_peak(),
        "peak_momentum_second": b.smoothed_peak(),
        "peak_momentum_in_blend": peak_in(&result, window_out),
        "foot_skate_in_blend_m": skate,
        "plants_locked": locked_plants,
    });
    Ok(Concatenated { clip: Arc::unwrap_or_clone(out), report: into_report(report) })
}

/// Convenience for tests and benches: analyse both clips with `options` and concatenate.
pub fn concatenate_clips(
    first: Arc<Clip>,
    second: Arc<Clip>,
    params: &ConcatParams,
    options: &AnalysisOptions,
) -> Result<Concatenated, String> {
    let a = analyse(first, options, None, None).map_err(|e| e.to_string())?;
    let b = analyse(second, options, None, None).map_err(|e| e.to_string())?;
    concatenate(&a, &b, params, options).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ImportScale, Joint, Skeleton};
    use glam::Quat;

    /// A triangle of momentum about Z peaking at frame 10 (height 10, slope 1).
    fn triangle() -> Vec<DVec3> {
        (0..21).map(|f| DVec3::new(0.0, 0.0, 10.0 - (f as f64 - 10.0).abs())).collect()
    }

    fn search<'a>(
        l: &'a [DVec3],
        arms: &'a [Vec3],
        after: &'a [bool],
        before: &'a [bool],
        min_offset: isize,
    ) -> TimingSearch<'a> {
        TimingSearch {
            first: TimingSide { momentum: l, arms_m: arms, allowed: after },
            second: TimingSide { momentum: l, arms_m: arms, allowed: before },
            masses_kg: &[1.0],
            first_start: 10,
            weights: [1.0; 3],
            min_offset,
        }
    }

    #[test]
    fn timing_of_a_motion_with_itself_is_solved_by_hand() {
        let l = triangle();
        let arms = vec![Vec3::ZERO; l.len()];
        let after: Vec<bool> = (0..21).map(|f| f >= 10).collect();
        let before: Vec<bool> = (0..21).map(|g| g <= 10).collect();
        // Peak on peak: no momentum difference, no delay after f_start.
        let t = search(&l, &arms, &after, &before, isize::MIN).run().unwrap();
        assert_eq!((t.offset, t.centre, t.cost()), (0, 10, 0.0));
        // Keeping the peaks 8 frames apart: the flanks meet at equal height at f = 14,
        // g = 6 (L = 6 on both) and F_time = (10 − 6)² = 16; odd offsets cost 1 more at
        // best (L 6 against 5), larger ones more F_time.
        let t = search(&l, &arms, &after, &before, 8).run().unwrap();
        assert_eq!((t.offset, t.centre), (8, 14));
        assert!((t.terms[0] - 0.0).abs() < 1e-12 && (t.terms[2] - 16.0).abs() < 1e-12, "{t:?}");
    }

    #[test]
    fn inertia_term_follows_eq_6() {
        // One 1 kg segment: r1 = (1, 0, 0) and r2 = (2, 0, 0) at every frame, so
        // r1 · (r2 − r1) = 1 and F_inertia = 1 at any centre.
        let l = triangle();
        let (arms1, arms2) = (vec![Vec3::X; 21], vec![Vec3::X * 2.0; 21]);
        let all = vec![true; 21];
        let s = TimingSearch {
            first: TimingSide { momentum: &l, arms_m: &arms1, allowed: &all },
            second: TimingSide { momentum: &l, arms_m: &arms2, allowed: &all },
            masses_kg: &[1.0],
            first_start: 10,
            weights: [1.0; 3],
            min_offset: isize::MIN,
        };
        let t = s.run().unwrap();
        assert!((t.terms[1] - 1.0).abs() < 1e-12, "{t:?}");
    }

    /// One joint turned `angle` radians about Y at every frame.
    fn constant(angle: f32, frames: usize) -> Clip {
        let skeleton = Arc::new(Skeleton::new(vec![Joint::new("root", None, Vec3::ZERO)]).unwrap());
        let rotations = vec![Quat::from_rotation_y(angle); frames];
        let translations = (0..frames).map(|_| Vec3::new(angle, 0.0, 0.0)).collect();
        Clip::new(skeleton, 30.0, rotations, translations, ImportScale::METRES).unwrap()
    }

    #[test]
    fn splice_blends_from_the_first_to_the_second_with_flat_ends() {
        let (first, second) = (constant(0.0, 10), constant(1.0, 10));
        // Blend first[4..=8] with second[2..=6] (T = 2), then second[7..].
        let out = splice(&first, &second, 4, 8, 2).unwrap();
        assert_eq!(out.frame_count(), 4 + 5 + 3);
        let yaw = |f: usize| out.frame_rotations(f)[0].to_scaled_axis().y;
        assert!(yaw(3).abs() < 1e-6 && (yaw(4) - 0.0).abs() < 1e-6);
        assert!((yaw(6) - 0.5).abs() < 1e-5, "{}", yaw(6));
        assert!((yaw(8) - 1.0).abs() < 1e-5 && (yaw(11) - 1.0).abs() < 1e-5);
        // u = 3/4: smootherstep 6u⁵ − 15u⁴ + 10u³ = 459/512 of the way to the second clip.
        assert!((out.frame_translations(7)[0].x - 459.0 / 512.0).abs() < 1e-6);
        // The weight's slope and curvature vanish at both ends: the first step is 53/512,
        // not a linear ramp's 1/4 (nor a smoothstep's 5/32).
        assert!((out.frame_translations(5)[0].x - 53.0 / 512.0).abs() < 1e-6);
    }

    #[test]
    fn rescaling_a_window_stretches_it_and_keeps_the_rest() {
        let mut rotations = Vec::new();
        for f in 0..11 {
            rotations.push(Quat::from_rotation_y(f as f32 * 0.1));
        }
        let skeleton = Arc::new(Skeleton::new(vec![Joint::new("root", None, Vec3::ZERO)]).unwrap());
        let clip = Clip::new(skeleton, 10.0, rotations, vec![Vec3::ZERO; 11], ImportScale::METRES).unwrap();
        // Frames 2..=6 (4 intervals) become 8 intervals: twice as slow.
        let out = rescale_window(&clip, 2, 6, 8).unwrap();
        assert_eq!(out.frame_count(), 11 + 4);
        let yaw = |f: usize| out.frame_rotations(f)[0].to_scaled_axis().y;
        // Window of 4 source frames over n = 8: ramps of 2 frames, middle speed
        // v = (4 − 2) / (8 − 2) = 1/3. By hand: after 1 frame (x = 1/2 of the ramp),
        // 1 + (1/3 − 1)·2·(1/8 − 1/32) = 1 − 1/8 = 0.875 source frames; after 2 (ramp end),
        // 2 − (2/3)·2·(1/2) = 4/3; the middle frame (4) plays 4/3 + 2/3 = 2, the window's middle.
        assert!((yaw(3) - (0.2 + 0.0875)).abs() < 1e-5, "{}", yaw(3));
        assert!((yaw(4) - (0.2 + 0.4 / 3.0)).abs() < 1e-5, "{}", yaw(4));
        assert!((yaw(6) - 0.4).abs() < 1e-5, "{}", yaw(6));
        assert!((yaw(10) - 0.6).abs() < 1e-5 && (yaw(11) - 0.7).abs() < 1e-5);
        // Monotonic: the stretched window never plays backwards.
        assert!((2..=10).all(|f| yaw(f + 1) >= yaw(f) - 1e-6));
    }
}
