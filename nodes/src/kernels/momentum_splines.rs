//! Pre-fit of the whole-body momentum curves (momentum-based dynamic motion editing): the
//! six channels p.x, p.y, p.z (linear momentum, kg·m/s) and L.x, L.y, L.z (angular
//! momentum about the centre of mass, kg·m²/s) as one piece per stage.
//!
//! 1. Stage i with frames s..e covers the times [(s − ½)/fps, (e − ½)/fps] (the clip's
//!    ends at its first and last frame): neighbouring pieces meet half way between frames.
//! 2. Flight stages: a line of fixed slope (−m·g for p.y, zero for every other channel:
//!    gravity is the only force, and it exerts no torque about the centre of mass); its
//!    value is the least-squares fit to the measured samples.
//! 3. Ground stages: a cubic B-spline on [t_a, t_b] with end knots of multiplicity 4 and
//!    interior knots spaced evenly about `knot_spacing_secs` apart, fitted by least squares.
//!    Next to a flight stage the spline takes the flight line's value and slope at the
//!    border (C1): c₀ = v, c₁ = c₀ + v′ (u₄ − t_a)/3 at the start, and symmetrically at the end.
//!    The vertical linear momentum only takes the flight's value at a landing (flight →
//!    ground), not its slope: the impact's force sets in at once (not C1), but the momentum
//!    does not jump. The paper frees the value too (an impulse); on a capture the impact
//!    takes ~5 frames at 120 fps (CMU 16_01: the root's vertical velocity changes at most
//!    0.47 m/s a frame), and a free value put all of it into one frame of the edit (1.2 m/s).

use glam::DVec3;
use nalgebra::{DMatrix, DVector};

use crate::model::{StageKind, Stages};

/// Channel names, in the order of [`MomentumFit::channels`].
pub const CHANNELS: [&str; 6] = ["p.x", "p.y", "p.z", "L.x", "L.y", "L.z"];

/// Units of [`CHANNELS`].
pub const UNITS: [&str; 6] = ["kg·m/s", "kg·m/s", "kg·m/s", "kg·m²/s", "kg·m²/s", "kg·m²/s"];

/// Why the momentum could not be fitted.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SplineError {
    /// The curves and the stages disagree in length.
    #[error("the stages describe {stages} frames, the momentum has {samples}")]
    Length {
        /// Frames of the stages.
        stages: usize,
        /// Samples of the momentum.
        samples: usize,
    },
    /// The stages do not tile the frames.
    #[error("the stages do not tile the clip's frames (gap or overlap at frame {0})")]
    NotTiled(usize),
    /// A bad knot spacing.
    #[error("knot spacing {0} s must be positive")]
    KnotSpacing(f64),
}

/// A cubic B-spline with clamped ends (first and last knot of multiplicity 4).
#[derive(Clone, Debug, PartialEq)]
pub struct CubicBSpline {
    /// Knots, non-decreasing, n + 4 of them.
    pub knots: Vec<f64>,
    /// Control points, n of them.
    pub control: Vec<f64>,
}

impl CubicBSpline {
    /// The clamped knot vector on [a, b] with `segments` equal spans.
    pub fn clamped_knots(a: f64, b: f64, segments: usize) -> Vec<f64> {
        let segments = segments.max(1);
        let mut k = vec![a; 4];
        k.extend((1..segments).map(|i| a + (b - a) * i as f64 / segments as f64));
        k.extend([b; 4]);
        k
    }

    /// The value at `t` (clamped to the knot range).
    pub fn value(&self, t: f64) -> f64 {
        basis(&self.knots, t).iter().zip(&self.control).map(|(n, c)| n * c).sum()
    }
}

/// Every cubic basis function N_i(t), i = 0..n, of the clamped `knots` (Cox–de Boor); `t`
/// is clamped to the knot range, and the last knot belongs to the last span.
pub fn basis(knots: &[f64], t: f64) -> Vec<f64> {
    let m = knots.len();
    if m < 5 {
        return Vec::new();
    }
    let (first, last) = (knots[0], knots[m - 1]);
    let t = t.clamp(first, last);
    let span = if t >= last {
        (0..m - 1).rev().find(|&i| knots[i] < knots[i + 1]).unwrap_or(0)
    } else {
        (0..m - 1).find(|&i| knots[i] <= t && t < knots[i + 1]).unwrap_or(0)
    };
    let mut nb = vec![0.0; m - 1];
    nb[span] = 1.0;
    for p in 1..=3 {
        for i in 0..m - 1 - p {
            let mut v = 0.0;
            let d1 = knots[i + p] - knots[i];
            if d1 > 0.0 {
                v += (t - knots[i]) / d1 * nb[i];
            }
            let d2 = knots[i + p + 1] - knots[i + 1];
            if d2 > 0.0 {
                v += (knots[i + p + 1] - t) / d2 * nb[i + 1];
            }
            nb[i] = v;
        }
    }
    nb.truncate(m - 4);
    nb
}

/// One stage's piece of one channel, on [start_secs, end_secs].
#[derive(Clone, Debug, PartialEq)]
pub enum Piece {
    /// Flight: value + slope · (t − start_secs).
    Line {
        /// Start of the piece, seconds.
        start_secs: f64,
        /// End of the piece, seconds.
        end_secs: f64,
        /// Value at the start.
        value: f64,
        /// Slope per second (−m·g for p.y, else 0).
        slope: f64,
    },
    /// Ground: a clamped cubic B-spline on the piece's interval.
    Spline {
        /// Start of the piece, seconds.
        start_secs: f64,
        /// End of the piece, seconds.
        end_secs: f64,
        /// The spline.
        spline: CubicBSpline,
    },
}

impl Piece {
    /// The interval the piece covers, seconds.
    pub fn span_secs(&self) -> (f64, f64) {
        match self {
            Piece::Line { start_secs, end_secs, .. } | Piece::Spline { start_secs, end_secs, .. } => {
                (*start_secs, *end_secs)
            }
        }
    }

    /// The value at `t`.
    pub fn value(&self, t: f64) -> f64 {
        match self {
            Piece::Line { start_secs, value, slope, .. } => value + slope * (t - start_secs),
            Piece::Spline { spline, .. } => spline.value(t),
        }
    }
}

/// The fitted pieces of one channel, one per stage.
#[derive(Clone, Debug, PartialEq)]
pub struct ChannelFit {
    /// One of [`CHANNELS`].
    pub name: &'static str,
    /// One per stage, in time order.
    pub pieces: Vec<Piece>,
    /// RMS of fitted minus measured over every frame.
    pub rms_residual: f64,
}

impl ChannelFit {
    /// The fitted value at `t` seconds (the piece whose interval holds `t`; a border
    /// belongs to the later piece).
    pub fn value(&self, t: f64) -> f64 {
        self.piece_at(t).map_or(0.0, |i| self.pieces[i].value(t))
    }

    /// The index of the piece whose interval holds `t` (a border belongs to the later
    /// piece; times before the first piece belong to it).
    pub fn piece_at(&self, t: f64) -> Option<usize> {
        self.pieces.iter().rposition(|p| t >= p.span_secs().0).or((!self.pieces.is_empty()).then_some(0))
    }
}

/// The fitted momentum of a clip.
#[derive(Clone, Debug, PartialEq)]
pub struct MomentumFit {
    /// p.x, p.y, p.z, L.x, L.y, L.z.
    pub channels: Vec<ChannelFit>,
    /// Times where neighbouring stages meet, seconds.
    pub borders_secs: Vec<f64>,
    /// The fitted curves sampled at every frame, per channel.
    pub fitted: Vec<Vec<f64>>,
    /// The measured curves, per channel.
    pub measured: Vec<Vec<f64>>,
}

/// Fits the momentum curves `linear` (kg·m/s) and `angular` (kg·m²/s), one sample per
/// frame, over `stages`, for a body of `mass_kg` under the stages' gravity.
pub fn fit_momentum(
    stages: &Stages,
    linear: &[DVec3],
    angular: &[DVec3],
    mass_kg: f64,
    knot_spacing_secs: f64,
) -> Result<MomentumFit, SplineError> {
    let n = stages.frame_count;
    if linear.len() != n || angular.len() != n {
        return Err(SplineError::Length { stages: n, samples: linear.len().min(angular.len()) });
    }
    if !(knot_spacing_secs.is_finite() && knot_spacing_secs > 0.0) {
        return Err(SplineError::KnotSpacing(knot_spacing_secs));
    }
    let mut next = 0;
    for s in &stages.stages {
        if s.frames.start != next || s.frames.is_empty() {
            return Err(SplineError::NotTiled(next));
        }
        next = s.frames.end;
    }
    if next != n {
        return Err(SplineError::NotTiled(next));
    }
    let fps = stages.fps;
    let last_secs = n.saturating_sub(1) as f64 / fps;
    let spans: Vec<(f64, f64)> = stages
        .stages
        .iter()
        .map(|s| {
            let a = if s.frames.start == 0 { 0.0 } else { (s.frames.start as f64 - 0.5) / fps };
            let b = if s.frames.end == n { last_secs } else { (s.frames.end as f64 - 0.5) / fps };
            (a, b)
        })
        .collect();
    let measured: Vec<Vec<f64>> = (0..6)
        .map(|c| {
            (0..n)
                .map(|f| {
                    let v = if c < 3 { linear[f] } else { angular[f] };
                    v[c % 3]
                })
                .collect()
        })
        .collect();
    let mut channels = Vec::new();
    for (c, samples) in measured.iter().enumerate() {
        let slope = if c == 1 { -mass_kg * stages.gravity_mps2 } else { 0.0 };
        // Flight lines first: the ground splines join them.
        let mut pieces: Vec<Option<Piece>> = stages
            .stages
            .iter()
            .zip(&spans)
            .map(|(s, &(a, b))| {
                (s.kind == StageKind::Flight).then(|| {
                    let k = s.frames.len() as f64;
                    let value =
                        (s.frames.start..s.frames.end).map(|f| samples[f] - slope * (f as f64 / fps - a)).sum::<f64>()
                            / k;
                    Piece::Line { start_secs: a, end_secs: b, value, slope }
                })
            })
            .collect();
        for i in 0..stages.stages.len() {
            if pieces[i].is_some() {
                continue;
            }
            let s = stages.stages[i];
            let (a, b) = spans[i];
            // Only C0 on the vertical linear momentum at a landing.
            let before = i
                .checked_sub(1)
                .and_then(|j| pieces[j].as_ref())
                .map(|p| (p.value(a), (c != 1).then(|| line_slope(p))));
            let after = pieces.get(i + 1).and_then(|p| p.as_ref()).map(|p| (p.value(b), Some(line_slope(p))));
            let spline =
                fit_ground(samples, s.frames.start..s.frames.end, fps, (a, b), knot_spacing_secs, before, after);
            pieces[i] = Some(Piece::Spline { start_secs: a, end_secs: b, spline });
        }
        let pieces: Vec<Piece> = pieces.into_iter().flatten().collect();
        let mut fit = ChannelFit { name: CHANNELS[c], pieces, rms_residual: 0.0 };
        let sq: f64 = (0..n).map(|f| (fit.value(f as f64 / fps) - samples[f]).powi(2)).sum();
        fit.rms_residual = (sq / n.max(1) as f64).sqrt();
        channels.push(fit);
    }
    let fitted = channels.iter().map(|ch| (0..n).map(|f| ch.value(f as f64 / fps)).collect()).collect();
    let borders_secs = spans.iter().skip(1).map(|s| s.0).collect();
    Ok(MomentumFit { channels, borders_secs, fitted, measured })
}

fn line_slope(p: &Piece) -> f64 {
    match p {
        Piece::Line { slope, .. } => *slope,
        Piece::Spline { .. } => 0.0,
    }
}

/// Least-squares clamped cubic B-spline on [a, b] through `samples[frames]`, with the value
/// (and the slope, when given) fixed at the start (`before`) and the end (`after`).
fn fit_ground(
    samples: &[f64],
    frames: std::ops::Range<usize>,
    fps: f64,
    (a, b): (f64, f64),
    knot_spacing_secs: f64,
    before: Option<(f64, Option<f64>)>,
    after: Option<(f64, Option<f64>)>,
) -> CubicBSpline {
    let segments = (((b - a) / knot_spacing_secs).round() as usize).max(1);
    let knots = CubicBSpline::clamped_knots(a, b, segments);
    let n = knots.len() - 4;
    let mut fixed: Vec<Option<f64>> = vec![None; n];
    if let Some((v, d)) = before {
        fixed[0] = Some(v);
        fixed[1] = d.map(|d| v + d * (knots[4] - a) / 3.0);
    }
    if let Some((v, d)) = after {
        fixed[n - 1] = Some(v);
        fixed[n - 2] = d.map(|d| v - d * (b - knots[n - 1]) / 3.0);
    }
    let free: Vec<usize> = (0..n).filter(|&i| fixed[i].is_none()).collect();
    let mut control: Vec<f64> = fixed.iter().map(|v| v.unwrap_or(0.0)).collect();
    if !free.is_empty() {
        let rows = frames.len();
        let mut m = DMatrix::<f64>::zeros(rows, free.len());
        let mut y = DVector::<f64>::zeros(rows);
        for (r, f) in frames.enumerate() {
            let nb = basis(&knots, f as f64 / fps);
            let known: f64 = (0..n).filter_map(|i| fixed[i].map(|v| v * nb[i])).sum();
            y[r] = samples[f] - known;
            for (k, &i) in free.iter().enumerate() {
                m[(r, k)] = nb[i];
            }
        }
        if let Ok(x) = m.svd(true, true).solve(&y, 1e-12) {
            for (k, &i) in free.iter().enumerate() {
                control[i] = x[k];
            }
        }
    }
    CubicBSpline { knots, control }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{FrameRange, Stage};

    #[test]
    fn basis_functions_partition_unity_and_match_a_bezier_on_one_span() {
        let knots = CubicBSpline::clamped_knots(0.0, 1.0, 1);
        for t in [0.0, 0.25, 0.5, 1.0] {
            let nb = basis(&knots, t);
            // One span, clamped: the Bernstein polynomials.
            let want = [(1.0 - t).powi(3), 3.0 * t * (1.0 - t).powi(2), 3.0 * t * t * (1.0 - t), t.powi(3)];
            for (a, b) in nb.iter().zip(want) {
                assert!((a - b).abs() < 1e-12, "t {t}: {nb:?}");
            }
        }
        let knots = CubicBSpline::clamped_knots(-1.0, 2.0, 5);
        for i in 0..=30 {
            let s: f64 = basis(&knots, -1.0 + 0.1 * i as f64).iter().sum();
            assert!((s - 1.0).abs() < 1e-12);
        }
    }

    /// Measured curves built from exact lines in flight and cubics on the ground that meet
    /// them C1 (p.y at the landing only C0: a kink, no jump): the fit must give them back.
    #[test]
    fn exact_piecewise_momentum_is_reproduced() {
        let fps = 100.0;
        let (m, g) = (70.0, 9.81);
        let stages = Stages {
            fps,
            frame_count: 100,
            stages: vec![
                Stage { kind: StageKind::Ground, frames: FrameRange::new(0, 30) },
                Stage { kind: StageKind::Flight, frames: FrameRange::new(30, 70) },
                Stage { kind: StageKind::Ground, frames: FrameRange::new(70, 100) },
            ],
            gravity_mps2: g,
        };
        let (b1, b2) = (29.5 / fps, 69.5 / fps);
        let py = |t: f64| {
            if t < b1 {
                300.0 - m * g * (t - b1) + 2000.0 * (t - b1).powi(2) + 1000.0 * (t - b1).powi(3)
            } else if t < b2 {
                300.0 - m * g * (t - b1)
            } else {
                300.0 - m * g * (b2 - b1) + 20.0 * (t - b2) - 300.0 * (t - b2).powi(2)
            }
        };
        let px = |t: f64| {
            if t < b1 {
                100.0 + 50.0 * (t - b1).powi(2) - 400.0 * (t - b1).powi(3)
            } else if t < b2 {
                100.0
            } else {
                100.0 - 80.0 * (t - b2).powi(2) + 10.0 * (t - b2).powi(3)
            }
        };
        let lx = |t: f64| {
            if t < b1 {
                5.0 + 30.0 * (t - b1).powi(2)
            } else if t < b2 {
                5.0
            } else {
                5.0 + 7.0 * (t - b2).powi(3)
            }
        };
        let linear: Vec<DVec3> = (0..100).map(|f| f as f64 / fps).map(|t| DVec3::new(px(t), py(t), 0.0)).collect();
        let angular: Vec<DVec3> = (0..100).map(|f| f as f64 / fps).map(|t| DVec3::new(lx(t), 0.0, -2.0)).collect();
        let fit = fit_momentum(&stages, &linear, &angular, m, 0.07).unwrap();
        for (c, ch) in fit.channels.iter().enumerate() {
            assert!(ch.rms_residual < 1e-8, "{}: {}", ch.name, ch.rms_residual);
            for f in 0..100 {
                assert!((fit.fitted[c][f] - fit.measured[c][f]).abs() < 1e-7, "{} frame {f}", ch.name);
            }
        }
        // Between frames too: the pieces are the curves themselves.
        for t in [0.123, 0.2951, 0.5, 0.6949, 0.6951, 0.9] {
            assert!((fit.channels[1].value(t) - py(t)).abs() < 1e-7, "p.y at {t}");
            assert!((fit.channels[0].value(t) - px(t)).abs() < 1e-7, "p.x at {t}");
        }
        assert_eq!(fit.borders_secs, vec![b1, b2]);
    }

    #[test]
    fn untiled_stages_and_bad_lengths_are_refused() {
        let mut stages = Stages {
            fps: 10.0,
            frame_count: 10,
            stages: vec![Stage { kind: StageKind::Ground, frames: FrameRange::new(0, 8) }],
            gravity_mps2: 9.8,
        };
        let z = vec![DVec3::ZERO; 10];
        assert_eq!(fit_momentum(&stages, &z, &z, 70.0, 0.1), Err(SplineError::NotTiled(8)));
        stages.stages[0].frames.end = 10;
        assert!(matches!(fit_momentum(&stages, &z[..5], &z, 70.0, 0.1), Err(SplineError::Length { .. })));
        assert_eq!(fit_momentum(&stages, &z, &z, 70.0, 0.0), Err(SplineError::KnotSpacing(0.0)));
    }
}
