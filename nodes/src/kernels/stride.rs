//! Stride: how far a walk or run steps and how fast its pelvis travels, the figures an
//! animator compares between a source motion and the same motion on a character of another
//! size (a longer-legged character should step further and travel faster in proportion).
//!
//! - Leg length: hip to knee to ankle in the skeleton's rest pose, the mean of both legs
//!   (metres), the legs read by [`rest_roles`].
//! - Plant: one contact of a foot; its position is the ankle's horizontal position at the
//!   contact's middle frame (a rolling foot's ankle moves a little along a plant; the middle
//!   is its typical place).
//! - Step: from one plant to the next one to start, when they are of different feet; its
//!   length is the horizontal distance between their positions (metres). The step length
//!   is the mean over the steps, and ÷ leg length it is comparable across characters.
//! - Pelvis speed: the pelvis joint's horizontal speed over a centred difference of
//!   [`SPEED_SPAN_SECS`] (m/s), which smooths capture jitter that one-frame differences
//!   turn into speed noise; its range is the [`SPEED_LOW_PERCENTILE`]th to
//!   [`SPEED_HIGH_PERCENTILE`]th percentile over the frames, so a single noisy frame at
//!   either end does not set it.
//!
//! A kernel: `motion.quality` reports it for a clip and its source.

use glam::DVec3;
use serde::Serialize;

use super::roles::{BodyRoles, RolesError, rest_roles};
use crate::model::fk::rest_world;
use crate::model::{FrameRange, Skeleton};

/// Time over which the pelvis speed is taken (seconds): a tenth of a second, well under a
/// walking step (about half a second), over several frames of any capture.
pub const SPEED_SPAN_SECS: f64 = 0.1;

/// Lower percentile of the pelvis speed range.
pub const SPEED_LOW_PERCENTILE: f64 = 5.0;

/// Upper percentile of the pelvis speed range.
pub const SPEED_HIGH_PERCENTILE: f64 = 95.0;

/// A clip's stride (see the module doc).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stride {
    /// Mean rest-pose leg length, hip to knee to ankle, metres.
    pub leg_length_m: f64,
    /// Steps measured (successive plants of different feet).
    pub steps: usize,
    /// Mean step length, metres (`None` without steps).
    pub step_length_m: Option<f64>,
    /// The step length over the leg length (dimensionless).
    pub step_over_leg: Option<f64>,
    /// The pelvis's horizontal speed at the low percentile, m/s (`None` when the clip is
    /// shorter than the speed span).
    pub pelvis_speed_low_mps: Option<f64>,
    /// …and at the high percentile, m/s.
    pub pelvis_speed_high_mps: Option<f64>,
}

/// One foot's ankle joint and its contacts.
pub struct FootPlants<'a> {
    /// The ankle joint.
    pub ankle: usize,
    /// Its contacts, frames `[start, end)`.
    pub contacts: &'a [FrameRange],
}

/// Measures the stride of a clip of `skeleton` at `fps` whose joint `j` is at `at(f, j)`
/// (world metres) in frame `f` of `frame_count`, over the frames of `window`, with the
/// feet's contacts `feet`. Errors: the legs or pelvis cannot be found (the message says
/// what was).
pub fn measure_stride(
    skeleton: &Skeleton,
    fps: f64,
    frame_count: usize,
    window: FrameRange,
    at: impl Fn(usize, usize) -> DVec3,
    feet: &[FootPlants<'_>],
) -> Result<Stride, RolesError> {
    let (leg_length_m, roles) = rest_legs(skeleton)?;
    let horizontal = |p: DVec3| glam::DVec2::new(p.x, p.z);

    // Plants in the order they start; a step joins successive plants of different feet.
    let mut plants: Vec<(usize, usize, glam::DVec2)> = feet
        .iter()
        .enumerate()
        .flat_map(|(k, foot)| {
            foot.contacts.iter().filter_map(|c| c.intersect(&window)).filter(|c| !c.is_empty()).map(move |c| {
                let middle = (c.start + c.end - 1) / 2;
                (c.start, k, foot.ankle, middle)
            })
        })
        .map(|(start, k, ankle, middle)| (start, k, horizontal(at(middle, ankle))))
        .collect();
    plants.sort_by_key(|p| (p.0, p.1));
    let steps: Vec<f64> = plants.windows(2).filter(|w| w[0].1 != w[1].1).map(|w| w[0].2.distance(w[1].2)).collect();
    let step_length_m = (!steps.is_empty()).then(|| steps.iter().sum::<f64>() / steps.len() as f64);

    // Pelvis speed over a centred span, at the frames whose span lies inside the clip.
    let half = ((0.5 * SPEED_SPAN_SECS * fps).round() as usize).max(1);
    let span_secs = 2.0 * half as f64 / fps;
    let mut speeds: Vec<f64> = (window.start.max(half)..window.end.min(frame_count.saturating_sub(half)))
        .map(|f| horizontal(at(f + half, roles.pelvis)).distance(horizontal(at(f - half, roles.pelvis))) / span_secs)
        .collect();
    speeds.sort_by(f64::total_cmp);
    Ok(Stride {
        leg_length_m,
        steps: steps.len(),
        step_length_m,
        step_over_leg: step_length_m.filter(|_| leg_length_m > 0.0).map(|s| s / leg_length_m),
        pelvis_speed_low_mps: percentile(&speeds, SPEED_LOW_PERCENTILE),
        pelvis_speed_high_mps: percentile(&speeds, SPEED_HIGH_PERCENTILE),
    })
}

/// The rest-pose leg length of `skeleton` (metres; see the module doc), or why its legs
/// cannot be found.
pub fn rest_leg_length_m(skeleton: &Skeleton) -> Result<f64, RolesError> {
    rest_legs(skeleton).map(|(leg, _)| leg)
}

/// The rest-pose leg length (metres) and the body roles it was read from.
pub fn rest_legs(skeleton: &Skeleton) -> Result<(f64, BodyRoles), RolesError> {
    let roles = rest_roles(skeleton)?;
    let rest = rest_world(skeleton);
    Ok((f64::from(roles.leg_length_m(|j| rest[j].translation)), roles))
}

/// The `p`th percentile (0–100) of ascending `sorted` values, linearly interpolated between
/// ranks; `None` when empty.
fn percentile(sorted: &[f64], p: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let rank = p / 100.0 * last as f64;
    let (below, above) = (rank.floor() as usize, (rank.ceil() as usize).min(last));
    Some(sorted[below] + (rank - below as f64) * (sorted[above] - sorted[below]))
}

/// How a clip's stride compares with its sources' (a clip joined or blended from several
/// takes may stride like any of them): each source's figures scaled by the leg-length ratio
/// (clip's over that source's), and the clip measured against the span they cover.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StrideComparison {
    /// The clip's leg length over the sources' mean.
    pub leg_length_ratio: f64,
    /// How far the clip's step ÷ leg lies outside the sources' span of step ÷ leg, over the
    /// nearer end of the span, percent; 0 inside it. With one source: |clip − source| over
    /// the source.
    pub step_over_leg_change_pct: Option<f64>,
    /// The span of the sources' pelvis speed ranges, each times its leg-length ratio, m/s.
    pub scaled_source_pelvis_speed_mps: Option<(f64, f64)>,
    /// How far the clip's pelvis speed range reaches outside that scaled span (below its
    /// low end or above its high end, whichever is further), percent of its high end; 0
    /// when inside.
    pub pelvis_speed_outside_source_pct: Option<f64>,
}

/// Compares `clip`'s stride with its `sources`' (see [`StrideComparison`]); `None` without
/// sources.
pub fn compare_stride(clip: &Stride, sources: &[Stride]) -> Option<StrideComparison> {
    if sources.is_empty() {
        return None;
    }
    let ratio_to = |source: &Stride| {
        if source.leg_length_m > 0.0 { clip.leg_length_m / source.leg_length_m } else { 1.0 }
    };
    let mean_leg = sources.iter().map(|s| s.leg_length_m).sum::<f64>() / sources.len() as f64;
    let leg_length_ratio = if mean_leg > 0.0 { clip.leg_length_m / mean_leg } else { 1.0 };
    let step_span = span(sources.iter().filter_map(|s| s.step_over_leg.filter(|&v| v > 0.0).map(|v| (v, v))));
    let step_over_leg_change_pct = match (clip.step_over_leg, step_span) {
        (Some(c), Some((lo, _))) if c < lo => Some((lo - c) / lo * 100.0),
        (Some(c), Some((_, hi))) if c > hi => Some((c - hi) / hi * 100.0),
        (Some(_), Some(_)) => Some(0.0),
        _ => None,
    };
    let scaled = span(sources.iter().filter_map(|s| {
        let r = ratio_to(s);
        Some((s.pelvis_speed_low_mps? * r, s.pelvis_speed_high_mps? * r))
    }));
    let outside = match (scaled, clip.pelvis_speed_low_mps, clip.pelvis_speed_high_mps) {
        (Some((lo, hi)), Some(c_lo), Some(c_hi)) if hi > 0.0 => Some((lo - c_lo).max(c_hi - hi).max(0.0) / hi * 100.0),
        _ => None,
    };
    Some(StrideComparison {
        leg_length_ratio,
        step_over_leg_change_pct,
        scaled_source_pelvis_speed_mps: scaled,
        pelvis_speed_outside_source_pct: outside,
    })
}

/// The smallest low end and the largest high end of `ranges`; `None` without any.
fn span(ranges: impl Iterator<Item = (f64, f64)>) -> Option<(f64, f64)> {
    ranges.reduce(|(a, b), (lo, hi)| (a.min(lo), b.max(hi)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Percentiles of 0..=10 fall on the values themselves; between ranks they interpolate.
    #[test]
    fn percentiles_interpolate_between_ranks() {
        let v: Vec<f64> = (0..=10).map(f64::from).collect();
        assert_eq!(percentile(&v, 0.0), Some(0.0));
        assert_eq!(percentile(&v, 50.0), Some(5.0));
        assert_eq!(percentile(&v, 95.0), Some(9.5));
        assert_eq!(percentile(&[], 50.0), None);
    }

    /// A stride of four steps of `ratio` leg lengths on legs of `leg` metres, the pelvis at
    /// `lo`–`hi` m/s.
    fn stride(leg: f64, ratio: f64, lo: f64, hi: f64) -> Stride {
        Stride {
            leg_length_m: leg,
            steps: 4,
            step_length_m: Some(ratio * leg),
            step_over_leg: Some(ratio),
            pelvis_speed_low_mps: Some(lo),
            pelvis_speed_high_mps: Some(hi),
        }
    }

    /// A clip whose leg is 1.2 times the source's, stepping 0.66 leg lengths against the
    /// source's 0.6 (10 % more), its pelvis at 1.3–1.9 m/s against the source's 1.0–1.5
    /// scaled to 1.2–1.8: 0.1 m/s over the scaled top, 5.6 % of it.
    #[test]
    fn comparison_scales_the_source_by_leg_length() {
        let c = compare_stride(&stride(1.2, 0.66, 1.3, 1.9), &[stride(1.0, 0.6, 1.0, 1.5)]).unwrap();
        assert!((c.leg_length_ratio - 1.2).abs() < 1e-12);
        assert!((c.step_over_leg_change_pct.unwrap() - 10.0).abs() < 1e-9);
        let (lo, hi) = c.scaled_source_pelvis_speed_mps.unwrap();
        assert!((lo - 1.2).abs() < 1e-12 && (hi - 1.8).abs() < 1e-12);
        assert!((c.pelvis_speed_outside_source_pct.unwrap() - 0.1 / 1.8 * 100.0).abs() < 1e-9);
        // Inside the scaled range: 0.
        let inside = compare_stride(&stride(1.2, 0.6, 1.25, 1.75), &[stride(1.0, 0.6, 1.0, 1.5)]).unwrap();
        assert_eq!(inside.pelvis_speed_outside_source_pct, Some(0.0));
        assert_eq!(compare_stride(&stride(1.2, 0.6, 1.25, 1.75), &[]), None);
    }

    /// Two sources, a walk (0.6 leg lengths, 1.0–1.5 m/s, legs 1.0 m) and a longer-legged
    /// run (1.1 leg lengths, 2.0–3.0 m/s, legs 1.2 m), against a clip with 1.2 m legs: the
    /// walk scales to 1.2–1.8 m/s and the run stays 2.0–3.0, so the span is 1.2–3.0 m/s
    /// and 0.6–1.1 leg lengths. A clip stepping 0.8 at 1.3–2.6 m/s is inside both; one
    /// stepping 1.32 (20 % past the run's 1.1) at 1.0–3.3 m/s reaches 0.3 m/s beyond the
    /// top, 10 % of it (the 0.2 m/s below the bottom is less).
    #[test]
    fn several_sources_are_compared_as_the_span_they_cover() {
        let sources = [stride(1.0, 0.6, 1.0, 1.5), stride(1.2, 1.1, 2.0, 3.0)];
        let inside = compare_stride(&stride(1.2, 0.8, 1.3, 2.6), &sources).unwrap();
        let (lo, hi) = inside.scaled_source_pelvis_speed_mps.unwrap();
        assert!((lo - 1.2).abs() < 1e-12 && (hi - 3.0).abs() < 1e-12, "{lo} {hi}");
        assert_eq!(inside.step_over_leg_change_pct, Some(0.0));
        assert_eq!(inside.pelvis_speed_outside_source_pct, Some(0.0));
        assert!((inside.leg_length_ratio - 1.2 / 1.1).abs() < 1e-12);
        let outside = compare_stride(&stride(1.2, 1.32, 1.0, 3.3), &sources).unwrap();
        assert!((outside.step_over_leg_change_pct.unwrap() - 20.0).abs() < 1e-9);
        assert!((outside.pelvis_speed_outside_source_pct.unwrap() - 10.0).abs() < 1e-9);
    }
}
