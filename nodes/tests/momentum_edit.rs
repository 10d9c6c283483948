//! Momentum-based editing, step 3 so far: the naive kinematic edit (the paper's initial
//! guess) on a real jump, measured the way the optimiser will be judged. The figures are
//! the baseline an optimised edit must beat. Needs `../shared/data` (skips without it
//! outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use glam::DVec3;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::kernels::body::{MassTable, body_model, find_landmarks};
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::kernels::load::{ClipLoadOptions, load_clip};
use kinegraph_nodes::kernels::momentum_edit::{GroundEdit, measure_edit, naive_edit};
use kinegraph_nodes::kernels::stages::stage_clip;
use kinegraph_nodes::model::{FrameRange, StageKind, forward_kinematics};

#[test]
fn naive_landing_shift_keeps_feet_planted_but_needs_an_impulse_at_take_off() {
    let Some(data) = shared_data() else { return };
    let clip = load_clip(&data.join("bvh/cmu/16_01.bvh"), ClipLoadOptions::default()).unwrap().value;
    let model = body_model(clip.skeleton(), 70.0, MassTable::DeLevaMale, None).unwrap();
    let staged = stage_clip(&clip, &model, None, None).unwrap();
    let stages = &staged.stages;
    let kinds: Vec<StageKind> = stages.stages.iter().map(|s| s.kind).collect();
    assert_eq!(kinds, vec![StageKind::Ground, StageKind::Flight, StageKind::Ground]);
    // Land 0.5 m further along the jump's direction (the centre of mass travel in flight).
    let flight = stages.stages[1].frames;
    let travel = staged.track.com_m[flight.end - 1] - staged.track.com_m[flight.start];
    let forward = DVec3::new(travel.x, 0.0, travel.z).normalize_or_zero();
    let shift = 0.5 * forward;
    let edits = [GroundEdit::default(), GroundEdit { offset_m: shift, turn_rad: 0.0 }];
    let edited = naive_edit(&clip, stages, &model, &edits).unwrap();
    let feet = find_landmarks(clip.skeleton()).unwrap().feet();
    let (contacts, ankles) = contacts_of(&clip, &forward_kinematics(&clip), &ContactThresholds::default()).unwrap();
    let planted: Vec<(usize, FrameRange)> =
        contacts.feet.iter().zip(ankles).flat_map(|(c, j)| c.intervals.iter().map(move |r| (j, *r))).collect();
    let g = stages.gravity_mps2;
    let naive = measure_edit(&clip, &edited, stages, &model, &edits, &feet, &planted, g).unwrap();
    let unedited = measure_edit(&clip, &clip, stages, &model, &[GroundEdit::default(); 2], &feet, &planted, g).unwrap();
    eprintln!("16_01 unedited: {unedited:?}");
    eprintln!("16_01 naive +0.5 m: {naive:?}");
    // The naive edit lands exactly where asked and moves planted feet no more than the
    // capture does (it moves ground stages rigidly).
    assert!(naive.placement_error_m.iter().all(|e| *e < 1e-4), "{:?}", naive.placement_error_m);
    assert!((naive.planted_drift_m - unedited.planted_drift_m).abs() < 1e-4);
    // A horizontal shift spread linearly over the flight adds a constant velocity: the
    // parabola under the same gravity fits as well as before…
    for (a, b) in naive.parabola_rms_m.iter().zip(&unedited.parabola_rms_m) {
        assert!((a - b).abs() < 1e-4, "{a} vs {b}");
    }
    // …but the take-off and the landing each need an impulse m·|Δ|·fps/(frames between the
    // last ground frame before and the first after), which no force in the ground stage
    // supplies: what the spacetime optimisation must remove.
    let frames_between = (flight.end - (flight.start - 1)) as f64;
    let want = 70.0 * shift.length() * clip.fps() / frames_between;
    for jump in &naive.border_momentum_jump {
        assert!((jump - want).abs() < 0.01 * want, "{jump} vs {want}");
    }
    assert!(unedited.border_momentum_jump.iter().all(|j| *j < 1e-9));
}
