//! Phase segmentation by the sign of angular momentum (Shum et al. 2009): from a frame t_m
//! inside the main phase, the main phase runs back and forth until the first frames whose
//! momentum points against L(t_m), i.e. L(t)·L(t_m) < 0. The runs of opposing momentum
//! just before and after are the preparatory and posterior phases; either may be missing.
//!
//! A kernel: part of the clip analysis both concatenation joins and the transitions use.

use glam::DVec3;

use crate::model::{FrameRange, Phases};

/// Where the segmentation starts and which borders the user fixed by hand.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseOptions {
    /// The frame inside the main phase; `None` takes the frame of largest |L|.
    pub main_frame: Option<usize>,
    /// A hand-set first frame of the main phase.
    pub main_start: Option<usize>,
    /// A hand-set first frame after the main phase.
    pub main_end: Option<usize>,
}

/// Segments `momentum` (already smoothed) into phases. `fps` is recorded for consumers.
pub fn segment_phases(momentum: &[DVec3], fps: f64, options: PhaseOptions) -> Phases {
    let n = momentum.len();
    let last = n.saturating_sub(1);
    // The peak is searched inside hand-set borders, so they are kept as given.
    let lo = options.main_start.unwrap_or(0).min(last);
    let hi = options.main_end.unwrap_or(n).min(n).max((lo + 1).min(n));
    let tm = options.main_frame.map(|f| f.min(last)).unwrap_or_else(|| {
        (lo..hi).max_by(|&a, &b| momentum[a].length().total_cmp(&momentum[b].length())).unwrap_or(lo)
    });
    let reference = momentum.get(tm).copied().unwrap_or_default();
    let opposes = |f: usize| momentum[f].dot(reference) < 0.0;
    let main_start = options
        .main_start
        .map(|f| f.min(tm))
        .unwrap_or_else(|| (0..tm).rev().find(|&f| opposes(f)).map_or(0, |f| f + 1));
    let main_end = options
        .main_end
        .map(|f| f.clamp(tm + 1, n.max(tm + 1)))
        .unwrap_or_else(|| (tm + 1..n).find(|&f| opposes(f)).unwrap_or(n));
    // The opposing runs next to the main phase; hand-set borders keep what lies beyond.
    let preparatory_start = if options.main_start.is_some() {
        0
    } else {
        (0..main_start).rev().find(|&f| !opposes(f)).map_or(0, |f| f + 1)
    };
    let posterior_end = if options.main_end.is_some() { n } else { (main_end..n).find(|&f| !opposes(f)).unwrap_or(n) };
    let preparatory = Some(FrameRange::new(preparatory_start, main_start)).filter(|r| !r.is_empty());
    let posterior = Some(FrameRange::new(main_end, posterior_end)).filter(|r| !r.is_empty());
    Phases { fps, frame_count: n, main_frame: tm, preparatory, main: FrameRange::new(main_start, main_end), posterior }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// L_z = sin-like profile: negative, positive peak, negative, then zero.
    fn profile(values: &[f64]) -> Vec<DVec3> {
        values.iter().map(|z| DVec3::new(0.0, 0.0, *z)).collect()
    }

    #[test]
    fn finds_all_three_phases_around_the_peak() {
        let l = profile(&[0.0, -1.0, -2.0, -1.0, 1.0, 4.0, 6.0, 3.0, -1.0, -2.0, 0.5, 0.2]);
        let p = segment_phases(&l, 30.0, PhaseOptions::default());
        assert_eq!(p.main_frame, 6);
        assert_eq!(p.main, FrameRange::new(4, 8));
        assert_eq!(p.preparatory, Some(FrameRange::new(1, 4)));
        assert_eq!(p.posterior, Some(FrameRange::new(8, 10)));
    }

    #[test]
    fn missing_phases_are_allowed_and_borders_can_be_overridden() {
        let punch = profile(&[1.0, 3.0, 5.0, 2.0, -1.0, -1.0]);
        let p = segment_phases(&punch, 30.0, PhaseOptions::default());
        assert_eq!((p.preparatory, p.main, p.posterior), (None, FrameRange::new(0, 4), Some(FrameRange::new(4, 6))));
        let flip = profile(&[-1.0, 2.0, 5.0, 4.0]);
        let p = segment_phases(&flip, 30.0, PhaseOptions::default());
        assert_eq!((p.preparatory, p.posterior), (Some(FrameRange::new(0, 1)), None));
        let forced =
            segment_phases(&flip, 30.0, PhaseOptions { main_start: Some(2), main_end: Some(3), ..Default::default() });
        assert_eq!(forced.preparatory, Some(FrameRange::new(0, 2)));
        assert_eq!(forced.main, FrameRange::new(2, 3));
        assert_eq!(forced.posterior, Some(FrameRange::new(3, 4)));
        // Hand-set borders around the smaller of two peaks keep the peak search inside them.
        let two = profile(&[1.0, 3.0, 1.0, 2.0, 9.0, 2.0]);
        let kept =
            segment_phases(&two, 30.0, PhaseOptions { main_start: Some(0), main_end: Some(3), ..Default::default() });
        assert_eq!((kept.main_frame, kept.main), (1, FrameRange::new(0, 3)));
        let manual_peak = segment_phases(&flip, 30.0, PhaseOptions { main_frame: Some(1), ..Default::default() });
        assert_eq!(manual_peak.main_frame, 1);
    }

    #[test]
    fn empty_and_still_clips_do_not_panic() {
        let p = segment_phases(&[], 30.0, PhaseOptions::default());
        assert!(p.main.is_empty() && p.preparatory.is_none() && p.posterior.is_none());
        let still = segment_phases(&profile(&[0.0; 5]), 30.0, PhaseOptions::default());
        assert_eq!(still.main, FrameRange::new(0, 5));
    }
}
