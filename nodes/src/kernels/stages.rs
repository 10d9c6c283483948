//! Ground and flight stages of a dynamic motion, and the gravity that makes its flights
//! ballistic (momentum-based dynamic motion editing, "motion pre-fitting").
//!
//! 1. A frame is *ground* when a foot (or a hand the contacts watch) is in contact (from
//!    the contact kernel or the user's contacts), *flight* otherwise; runs of equal frames
//!    form alternating stages. The user may instead give the borders (seconds), which
//!    replace the detected ones; kinds still alternate, starting with the kind of the first
//!    frame.
//! 2. Gravity: over every flight stage of at least [`MIN_FIT_FRAMES`] frames, the centre of
//!    mass height is fitted by least squares with y(t) = a_k + b_k (t − t_k) − ½ g (t − t_k)²,
//!    one (a_k, b_k) per stage and one g for all; the horizontal components with a line per
//!    stage. The RMS of the 3-D residual is the parabola residual.
//! 3. Angular momentum in flight should be constant: per flight stage, over its interior
//!    frames (the central differences at its first and last frame reach into the ground
//!    stages), the variation is max_t |L(t) − L̄| / max_t |L(t)|, in per cent.
//!
//! Hands are not watched: a stage is flight when no *foot* touches the ground.

use glam::DVec3;
use nalgebra::{DMatrix, DVector};

use super::angular::{MomentumTrack, momentum_of_poses};
use super::body::BodyModel;
use super::contacts::{ContactThresholds, contacts_of};
use super::roles::RolesError;
use crate::model::{
    Clip, ClipPoses, Contacts, FrameRange, Stage, StageKind, Stages, forward_kinematics, stages::stages_from_flags,
};

/// Fewest frames a flight stage needs to take part in the gravity fit.
pub const MIN_FIT_FRAMES: usize = 4;

/// Why stages or the ballistic fit could not be found.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StagesError {
    /// Too few frames.
    #[error("the clip has {0} frames; at least {MIN_FIT_FRAMES} are needed")]
    TooShort(usize),
    /// No flight stage long enough to fit a parabola.
    #[error(
        "no flight stage of at least {MIN_FIT_FRAMES} frames (the body never leaves the ground long enough); \
         set the stage borders by hand if the contacts missed it"
    )]
    NoFlight,
    /// A manual border lies outside the clip.
    #[error("border {secs} s lies outside the clip (0 – {duration_secs} s)")]
    BorderOutside {
        /// The border given.
        secs: f64,
        /// The clip's length.
        duration_secs: f64,
    },
    /// Manual borders must increase.
    #[error("borders must increase strictly and fall on different frames ({0})")]
    BordersNotIncreasing(String),
    /// The feet could not be found to detect contacts.
    #[error("the feet could not be found: {0}")]
    Feet(#[source] RolesError),
    /// The contacts describe another clip.
    #[error("the contacts describe {contacts} frames, the clip has {clip}")]
    ContactsMismatch {
        /// Frames in the contacts.
        contacts: usize,
        /// Frames in the clip.
        clip: usize,
    },
}

/// The contact thresholds used to find stages when no contacts are given: the default
/// heights, but a foot counts as touching however fast it moves (landings slide, and a
/// foot pushing off is still on the ground).
pub fn stage_thresholds() -> ContactThresholds {
    ContactThresholds { enter_speed_mps: 5.0, leave_speed_mps: 8.0, ..ContactThresholds::default() }
}

/// Stages from contacts: ground wherever any foot (or watched hand) is in contact. A flight
/// must lie between a take-off and a landing and last `min_flight_frames`: runs without
/// contact at the clip's ends, or shorter, count as ground.
pub fn stages_from_contacts(contacts: &Contacts, min_flight_frames: usize) -> Vec<Stage> {
    let n = contacts.frame_count;
    let mut grounded = vec![false; n];
    for foot in contacts.limbs() {
        for r in &foot.intervals {
            for g in grounded.iter_mut().take(r.end).skip(r.start) {
                *g = true;
            }
        }
    }
    for s in stages_from_flags(&grounded) {
        let bounded = s.frames.start > 0 && s.frames.end < n;
        if s.kind == StageKind::Flight && (!bounded || s.frames.len() < min_flight_frames) {
            for g in grounded.iter_mut().take(s.frames.end).skip(s.frames.start) {
                *g = true;
            }
        }
    }
    stages_from_flags(&grounded)
}

/// Stages cut at `borders_secs` (each border starts a new stage at the frame nearest to it),
/// alternating from `first` kind.
pub fn stages_from_borders(
    frame_count: usize,
    fps: f64,
    borders_secs: &[f64],
    first: StageKind,
) -> Result<Vec<Stage>, StagesError> {
    let duration_secs = frame_count.saturating_sub(1) as f64 / fps;
    let mut cuts = vec![0usize];
    for &secs in borders_secs {
        if !(secs.is_finite() && secs > 0.0 && secs < duration_secs) {
            return Err(StagesError::BorderOutside { secs, duration_secs });
        }
        let frame = (secs * fps).round() as usize;
        if frame <= *cuts.last().unwrap_or(&0) || frame >= frame_count {
            return Err(StagesError::BordersNotIncreasing(format!("{secs} s is frame {frame}")));
        }
        cuts.push(frame);
    }
    cuts.push(frame_count);
    let mut kind = first;
    let mut out = Vec::new();
    for w in cuts.windows(2) {
        out.push(Stage { kind, frames: FrameRange::new(w[0], w[1]) });
        kind = match kind {
            StageKind::Ground => StageKind::Flight,
            StageKind::Flight => StageKind::Ground,
        };
    }
    Ok(out)
}

/// What the ballistic fit found in one flight stage.
#[derive(Clone, Debug, PartialEq)]
pub struct FlightFit {
    /// The stage's frames.
    pub frames: FrameRange,
    /// Whether it took part in the gravity fit (long enough).
    pub fitted: bool,
    /// RMS distance of the centre of mass from its fitted parabola, metres.
    pub rms_residual_m: f64,
    /// Highest fitted centre-of-mass height above its take-off height, metres.
    pub rise_m: f64,
    /// Mean angular momentum over the interior frames, kg·m²/s.
    pub mean_momentum: DVec3,
    /// max |L − L̄| / max |L| over the interior frames, per cent.
    pub momentum_variation_pct: f64,
}

/// The ballistic fit of every flight stage.
#[derive(Clone, Debug, PartialEq)]
pub struct BallisticFit {
    /// Gravity, m/s² (positive: pointing down).
    pub gravity_mps2: f64,
    /// RMS of the 3-D residual over every fitted flight frame, metres.
    pub rms_residual_m: f64,
    /// Per flight stage, in time order.
    pub flights: Vec<FlightFit>,
    /// The fitted centre of mass per frame (parabola in flight stages, measured elsewhere).
    pub com_fitted_m: Vec<DVec3>,
}

impl BallisticFit {
    /// The largest angular-momentum variation of the fitted flight stages, per cent.
    pub fn max_momentum_variation_pct(&self) -> f64 {
        self.flights.iter().filter(|f| f.fitted).map(|f| f.momentum_variation_pct).fold(0.0, f64::max)
    }
}

/// Fits gravity to the centre of mass `com_m` (per frame, metres) in the flight `stages`, and
/// measures the angular momentum `momentum` (per frame) there.
pub fn fit_ballistic(
    stages: &[Stage],
    com_m: &[DVec3],
    momentum: &[DVec3],
    fps: f64,
) -> Result<BallisticFit, StagesError> {
    let n = com_m.len();
    if n < MIN_FIT_FRAMES {
        return Err(StagesError::TooShort(n));
    }
    let fitted: Vec<&Stage> = stages
        .iter()
        .filter(|s| s.kind == StageKind::Flight && s.frames.len() >= MIN_FIT_FRAMES && s.frames.end <= n)
        .collect();
    if fitted.is_empty() {
        return Err(StagesError::NoFlight);
    }
    // Heights: unknowns [g, a_0, b_0, a_1, b_1, ...]; rows y = a + b τ − ½ g τ².
    let rows: usize = fitted.iter().map(|s| s.frames.len()).sum();
    let cols = 1 + 2 * fitted.len();
    let mut a = DMatrix::<f64>::zeros(rows, cols);
    let mut y = DVector::<f64>::zeros(rows);
    let mut r = 0;
    for (k, s) in fitted.iter().enumerate() {
        for (i, p) in com_m[s.frames.start..s.frames.end].iter().enumerate() {
            let tau = i as f64 / fps;
            a[(r, 0)] = -0.5 * tau * tau;
            a[(r, 1 + 2 * k)] = 1.0;
            a[(r, 2 + 2 * k)] = tau;
            y[r] = p.y;
            r += 1;
        }
    }
    let solution = a.clone().svd(true, true).solve(&y, 1e-12).unwrap_or_else(|_| DVector::zeros(cols));
    let gravity_mps2 = solution[0];
    let mut com_fitted_m = com_m.to_vec();
    let mut flights = Vec::new();
    let (mut sum_sq, mut count) = (0.0, 0usize);
    let mut k = 0;
    for s in stages.iter().filter(|s| s.kind == StageKind::Flight && s.frames.end <= n) {
        let is_fitted = s.frames.len() >= MIN_FIT_FRAMES;
        let (mut stage_sq, mut rise_m) = (0.0, 0.0f64);
        if is_fitted {
            let (a0, b0) = (solution[1 + 2 * k], solution[2 + 2 * k]);
            k += 1;
            let (lx, lz) = (line_fit(s.frames, com_m, fps, |p| p.x), line_fit(s.frames, com_m, fps, |p| p.z));
            for f in s.frames.start..s.frames.end {
                let tau = (f - s.frames.start) as f64 / fps;
                let p =
                    DVec3::new(lx.0 + lx.1 * tau, a0 + b0 * tau - 0.5 * gravity_mps2 * tau * tau, lz.0 + lz.1 * tau);
                stage_sq += (p - com_m[f]).length_squared();
                rise_m = rise_m.max(p.y - a0);
                com_fitted_m[f] = p;
            }
            sum_sq += stage_sq;
            count += s.frames.len();
        }
        let interior =
            if s.frames.len() > 2 { FrameRange::new(s.frames.start + 1, s.frames.end - 1) } else { s.frames };
        let ls = &momentum[interior.start..interior.end.min(momentum.len())];
        let mean_momentum = ls.iter().sum::<DVec3>() / ls.len().max(1) as f64;
        let peak = ls.iter().map(|l| l.length()).fold(0.0, f64::max);
        let spread = ls.iter().map(|l| (*l - mean_momentum).length()).fold(0.0, f64::max);
        flights.push(FlightFit {
            frames: s.frames,
            fitted: is_fitted,
            rms_residual_m: if is_fitted { (stage_sq / s.frames.len() as f64).sqrt() } else { 0.0 },
            rise_m,
            mean_momentum,
            momentum_variation_pct: if peak > 0.0 { 100.0 * spread / peak } else { 0.0 },
        });
    }
    Ok(BallisticFit { gravity_mps2, rms_residual_m: (sum_sq / count.max(1) as f64).sqrt(), flights, com_fitted_m })
}

/// A clip cut into stages, with the ballistic fit of its flights.
#[derive(Clone, Debug)]
pub struct StagedClip {
    /// The stages and the fitted gravity.
    pub stages: Stages,
    /// The fit of every flight stage.
    pub fit: BallisticFit,
    /// World poses of the clip.
    pub poses: ClipPoses,
    /// Centre of mass and angular momentum per frame under the body model.
    pub track: MomentumTrack,
}

/// Cuts `clip` into stages, from `borders_secs` when given, else from `contacts` (detected
/// with the default thresholds when `None`), and fits gravity to its flights under `model`.
pub fn stage_clip(
    clip: &Clip,
    model: &BodyModel,
    contacts: Option<&Contacts>,
    borders_secs: Option<&[f64]>,
) -> Result<StagedClip, StagesError> {
    stage_clip_with(clip, model, contacts, borders_secs, &stage_thresholds(), DEFAULT_MIN_FLIGHT_SECS)
}

/// Shortest flight by default, seconds: shorter gaps between contacts are capture noise.
pub const DEFAULT_MIN_FLIGHT_SECS: f64 = 0.1;

/// [`stage_clip`] with the contact thresholds used when no contacts are given and the
/// shortest flight, seconds.
pub fn stage_clip_with(
    clip: &Clip,
    model: &BodyModel,
    contacts: Option<&Contacts>,
    borders_secs: Option<&[f64]>,
    thresholds: &ContactThresholds,
    min_flight_secs: f64,
) -> Result<StagedClip, StagesError> {
    let min_flight = (min_flight_secs * clip.fps()).round().max(1.0) as usize;
    let n = clip.frame_count();
    if n < MIN_FIT_FRAMES {
        return Err(StagesError::TooShort(n));
    }
    let poses = forward_kinematics(clip);
    let detected = match contacts {
        Some(c) if c.frame_count != n => {
            return Err(StagesError::ContactsMismatch { contacts: c.frame_count, clip: n });
        }
        Some(c) => stages_from_contacts(c, min_flight),
        None => {
            let (c, _) = contacts_of(clip, &poses, thresholds).map_err(StagesError::Feet)?;
            stages_from_contacts(&c, min_flight)
        }
    };
    let stages = match borders_secs {
        Some(b) => {
            let first = detected.first().map(|s| s.kind).unwrap_or(StageKind::Ground);
            stages_from_borders(n, clip.fps(), b, first)?
        }
        None => detected,
    };
    let track = momentum_of_poses(&poses, clip.fps(), model);
    let fit = fit_ballistic(&stages, &track.com_m, &track.momentum, clip.fps())?;
    let stages = Stages { fps: clip.fps(), frame_count: n, stages, gravity_mps2: fit.gravity_mps2 };
    Ok(StagedClip { stages, fit, poses, track })
}

/// Least-squares line (value at the stage start, slope per second) through one component.
fn line_fit(frames: FrameRange, com_m: &[DVec3], fps: f64, component: impl Fn(&DVec3) -> f64) -> (f64, f64) {
    let n = frames.len() as f64;
    let ts: Vec<f64> = (0..frames.len()).map(|i| i as f64 / fps).collect();
    let vs: Vec<f64> = (frames.start..frames.end).map(|f| component(&com_m[f])).collect();
    let (mt, mv) = (ts.iter().sum::<f64>() / n, vs.iter().sum::<f64>() / n);
    let stt: f64 = ts.iter().map(|t| (t - mt) * (t - mt)).sum();
    let stv: f64 = ts.iter().zip(&vs).map(|(t, v)| (t - mt) * (v - mv)).sum();
    let slope = if stt > 0.0 { stv / stt } else { 0.0 };
    (mv - slope * mt, slope)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::FootContacts;

    #[test]
    fn borders_cut_alternating_stages_and_are_checked() {
        let s = stages_from_borders(100, 100.0, &[0.3, 0.7], StageKind::Ground).unwrap();
        assert_eq!(s.len(), 3);
        assert_eq!((s[1].kind, s[1].frames), (StageKind::Flight, FrameRange::new(30, 70)));
        assert_eq!(s[2].frames, FrameRange::new(70, 100));
        assert!(matches!(
            stages_from_borders(100, 100.0, &[1.2], StageKind::Ground),
            Err(StagesError::BorderOutside { .. })
        ));
        assert!(matches!(
            stages_from_borders(100, 100.0, &[0.5, 0.4], StageKind::Ground),
            Err(StagesError::BordersNotIncreasing(_))
        ));
    }

    #[test]
    fn a_frame_is_ground_when_either_foot_touches() {
        let contacts = Contacts {
            fps: 10.0,
            frame_count: 10,
            feet: vec![
                FootContacts { foot: "l".into(), intervals: vec![FrameRange::new(0, 3)] },
                FootContacts { foot: "r".into(), intervals: vec![FrameRange::new(2, 4), FrameRange::new(8, 10)] },
            ],
            double_support: vec![],
            hands: vec![],
        };
        let s = stages_from_contacts(&contacts, 2);
        let got: Vec<(StageKind, usize, usize)> = s.iter().map(|s| (s.kind, s.frames.start, s.frames.end)).collect();
        assert_eq!(got, vec![(StageKind::Ground, 0, 4), (StageKind::Flight, 4, 8), (StageKind::Ground, 8, 10)]);
        // Too short a flight is ground; so is one that runs off the clip's end.
        assert_eq!(stages_from_contacts(&contacts, 5).len(), 1);
        let mut open = contacts.clone();
        open.feet[1].intervals.pop();
        let s = stages_from_contacts(&open, 2);
        assert_eq!(s.len(), 1, "{s:?}");
    }

    #[test]
    fn a_sampled_parabola_gives_back_its_gravity_and_no_residual() {
        // Two flights with different launch speeds, ground between; g = 3.7 (Mars).
        let fps = 60.0;
        let g = 3.7;
        let mut com = vec![DVec3::new(0.0, 1.0, 0.0); 100];
        let stages =
            stages_from_borders(100, fps, &[10.0 / fps, 80.0 / fps, 85.0 / fps, 95.0 / fps], StageKind::Ground)
                .unwrap();
        for (s, vy) in [(stages[1], 2.0), (stages[3], 1.5)] {
            for (i, c) in com[s.frames.start..s.frames.end].iter_mut().enumerate() {
                let t = i as f64 / fps;
                *c = DVec3::new(0.5 * t, 1.0 + vy * t - 0.5 * g * t * t, -0.2 * t);
            }
        }
        let fit = fit_ballistic(&stages, &com, &vec![DVec3::ZERO; 100], fps).unwrap();
        assert!((fit.gravity_mps2 - g).abs() < 1e-9, "{}", fit.gravity_mps2);
        assert!(fit.rms_residual_m < 1e-9);
        // Rise of the first flight: v²/2g, sampled (the apex falls between frames).
        assert!((fit.flights[0].rise_m - 2.0 * 2.0 / (2.0 * g)).abs() < 2e-3, "{}", fit.flights[0].rise_m);
        let none = stages_from_borders(100, fps, &[], StageKind::Ground).unwrap();
        assert_eq!(fit_ballistic(&none, &com, &com, fps), Err(StagesError::NoFlight));
    }
}
