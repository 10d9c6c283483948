//! Motion families on a real jump (CMU 16_01): a two-sample line family of optimised
//! landings, blended between its samples and searched by inverse control; failed samples
//! stay in the family, marked. Needs `../shared/data` (skips without it outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{Jump, jump_16_01};
use glam::DVec3;
use kinegraph_nodes::kernels::family::{AxisSweep, FamilySpec, populate};
use kinegraph_nodes::kernels::family_blend::{BlendError, ReachTarget, blend_family, reach};
use kinegraph_nodes::kernels::momentum_edit::{EditMeasures, GroundEdit, measure_edit};
use kinegraph_nodes::kernels::momentum_solve::{EditSetup, SolveError, SolveOptions, momentum_edit};
use kinegraph_nodes::model::{Clip, FamilyKind, SampleOutcome, forward_kinematics};

/// The solver's tolerance on planted feet and on the floor, metres: below it a sample
/// counts as exact, so a blend is held to twice this rather than to twice round-off.
const FEET_TOL_M: f64 = 5e-4;

/// The solver's tolerance on the centre of mass's velocity (linear momentum per mass), m/s.
const LINEAR_TOL_MPS: f64 = 5e-3;

/// The measures of `edited` (16_01 with its landing moved `offset`) that the family blend is
/// judged by, from the momentum-edit tests' measure.
fn measures(jump: &Jump, edited: &Clip, offset: DVec3) -> EditMeasures {
    let edits = [GroundEdit::default(), GroundEdit { offset_m: offset, turn_rad: 0.0 }];
    let stages = &jump.staged.stages;
    measure_edit(&jump.clip, edited, stages, &jump.model, &edits, &jump.ankles, &jump.planted, stages.gravity_mps2)
        .unwrap()
}

#[test]
fn a_line_family_blends_exactly_at_its_samples_and_plausibly_between_them() {
    let Some(jump) = jump_16_01() else { return };
    let stages = &jump.staged.stages;
    let edits = [GroundEdit::default(); 2];
    let setup = EditSetup {
        clip: &jump.clip,
        stages,
        model: &jump.model,
        feet: jump.ankles,
        planted: &jump.planted,
        edits: &edits,
    };
    // Landing 0 and 0.3 m further along the jump.
    let spec = FamilySpec { kind: FamilyKind::Line, stage: 1, axes: vec![AxisSweep { from: 0.0, to: 0.3, count: 2 }] };
    let run = populate(setup, &spec, &SolveOptions::default()).unwrap();
    let family = &run.family;
    assert!(run.reports.iter().all(Result::is_ok), "{:?}", run.reports);
    // The family's direction is the centre of mass's travel in flight.
    let angle = family.forward.angle_between(jump.forward).to_degrees();
    assert!(angle < 0.01, "family forward {} vs COM travel {} ({angle}°)", family.forward, jump.forward);

    // At a grid point the blend is that sample: compared with the same edit optimised on its own.
    let offset = 0.3 * family.forward;
    let alone = momentum_edit(
        EditSetup { edits: &[GroundEdit::default(), GroundEdit { offset_m: offset, turn_rad: 0.0 }], ..setup },
        &SolveOptions::default(),
    )
    .unwrap()
    .0;
    let at = blend_family(family, &[0.3]).unwrap();
    let moved = at.translations().iter().zip(alone.translations()).map(|(a, b)| (*a - *b).length()).fold(0.0, f32::max);
    // Quaternions compared by components (same sign), which resolves round-off.
    let turned = at
        .rotations()
        .iter()
        .zip(alone.rotations())
        .map(|(a, b)| if a.dot(*b) < 0.0 { (*a + *b).length() } else { (*a - *b).length() })
        .fold(0.0, f32::max);
    eprintln!("blend at u = 0.3 vs the edit alone: {moved:e} m, {turned:e} (quaternion components)");
    assert!(moved < 1e-5 && turned < 1e-5, "{moved} m, {turned}");

    // Between the samples, the feet-on-ground and flight-parabola measures stay within twice
    // the samples' own (at least twice what the solver's tolerances allow, the samples being
    // exact there: the feet's, and for the parabola the velocity tolerance over the flight).
    let sample_measures: Vec<EditMeasures> = family
        .samples
        .iter()
        .map(|s| match &s.outcome {
            SampleOutcome::Solved(clip) => measures(&jump, clip, s.offset_m),
            SampleOutcome::Failed(e) => panic!("{e}"),
        })
        .collect();
    let worst = |f: &dyn Fn(&EditMeasures) -> f64| sample_measures.iter().map(f).fold(0.0, f64::max);
    let drift = worst(&|m| m.planted_drift_m);
    let below = worst(&|m| m.below_floor_m);
    let parabola = worst(&|m| m.parabola_rms_m.iter().copied().fold(0.0, f64::max));
    for u in [0.1, 0.15, 0.2] {
        let blended = blend_family(family, &[u]).unwrap();
        let m = measures(&jump, &blended, u * family.forward);
        eprintln!("u = {u}: {m:?} (samples: drift {drift:e}, below {below:e}, parabola {parabola:e})");
        assert!(m.planted_drift_m < 2.0 * drift.max(FEET_TOL_M), "drift {} m", m.planted_drift_m);
        assert!(m.below_floor_m < 2.0 * below.max(FEET_TOL_M), "below floor {} m", m.below_floor_m);
        let flight_secs = stages.stages[1].frames.len() as f64 / jump.clip.fps();
        let parabola_bar = 2.0 * parabola.max(LINEAR_TOL_MPS * flight_secs);
        assert!(m.parabola_rms_m.iter().all(|r| *r < parabola_bar), "parabola {:?}", m.parabola_rms_m);
        // The landing is where the blend's parameter puts it (within the feet tolerance).
        assert!(m.placement_error_m.iter().all(|e| *e < 2.0 * FEET_TOL_M), "landing {:?}", m.placement_error_m);
    }

    // Inverse control: the right hand's place at the top of the flight in the blend at
    // u = 0.12 (between the samples) is found again, and with it u.
    let hand = jump.clip.skeleton().index_of("RightHand").unwrap();
    let flight = stages.stages[1].frames;
    let frame = flight.start + flight.len() / 2;
    let known = 0.12;
    let target_m = forward_kinematics(&blend_family(family, &[known]).unwrap()).position(frame, hand).as_dvec3();
    let found = reach(family, &ReachTarget { joint: hand, frame, target_m }).unwrap();
    eprintln!("reach: {found:?} (known u = {known})");
    assert!(found.miss_m < 1e-3, "the hand misses by {} m", found.miss_m);
    assert!((found.params[0] - known).abs() < 5e-3, "u = {} vs {known}", found.params[0]);
}

#[test]
fn failed_samples_stay_in_the_family_with_their_errors() {
    let Some(jump) = jump_16_01() else { return };
    let edits = [GroundEdit::default(); 2];
    let setup = EditSetup {
        clip: &jump.clip,
        stages: &jump.staged.stages,
        model: &jump.model,
        feet: jump.ankles,
        planted: &jump.planted,
        edits: &edits,
    };
    // Two steps are too few to converge at all; 5 m further is beyond the legs.
    let spec = FamilySpec { kind: FamilyKind::Line, stage: 1, axes: vec![AxisSweep { from: 0.0, to: 5.0, count: 2 }] };
    let run = populate(setup, &spec, &SolveOptions { max_iterations: 2, ..SolveOptions::default() }).unwrap();
    assert!(matches!(run.reports[0], Err(SolveError::NotConverged { iterations: 2, .. })), "{:?}", run.reports[0]);
    assert!(matches!(run.reports[1], Err(SolveError::Unreachable { stage: 1, .. })), "{:?}", run.reports[1]);
    for (sample, report) in run.family.samples.iter().zip(&run.reports) {
        let SampleOutcome::Failed(why) = &sample.outcome else { panic!("{:?} marked solved", sample.params) };
        assert_eq!(why, &report.as_ref().unwrap_err().to_string());
    }
    let err = blend_family(&run.family, &[1.0]).unwrap_err();
    assert!(matches!(&err, BlendError::FailedSample { params, .. } if params == &vec![0.0]), "{err}");
}
