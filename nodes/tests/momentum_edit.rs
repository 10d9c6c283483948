//! Momentum-based editing, step 3 so far: the naive kinematic edit (the paper's initial
//! guess) on a real jump, measured the way the optimiser will be judged. The figures are
//! the baseline an optimised edit must beat. Needs `../shared/data` (skips without it
//! outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{Jump, jump, jump_16_01};
use glam::{DVec3, Quat};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::kernels::angular::momentum_of_poses;
use kinegraph_nodes::kernels::body::{BodyModel, MassTable, body_model, find_landmarks};
use kinegraph_nodes::kernels::load::{ClipLoadOptions, load_clip};
use kinegraph_nodes::kernels::momentum_edit::{GroundEdit, measure_edit, naive_edit};
use kinegraph_nodes::kernels::momentum_solve::{EditSetup, LIMIT_MARGIN_RAD, SolveError, SolveOptions, momentum_edit};
use kinegraph_nodes::kernels::stages::{fit_ballistic, stage_clip};
use kinegraph_nodes::math::quat_normalize_or_identity;
use kinegraph_nodes::model::{Clip, FrameRange, Stage, StageKind, Stages, forward_kinematics};

#[test]
fn naive_landing_shift_keeps_feet_planted_but_needs_an_impulse_at_take_off() {
    let Some(Jump { clip, model, staged, forward, planted, .. }) = jump_16_01() else { return };
    let stages = &staged.stages;
    let kinds: Vec<StageKind> = stages.stages.iter().map(|s| s.kind).collect();
    assert_eq!(kinds, vec![StageKind::Ground, StageKind::Flight, StageKind::Ground]);
    // Land 0.5 m further along the jump's direction.
    let shift = 0.5 * forward;
    let edits = [GroundEdit::default(), GroundEdit { offset_m: shift, turn_rad: 0.0 }];
    let edited = naive_edit(&clip, stages, &model, &edits).unwrap();
    let feet = find_landmarks(clip.skeleton()).unwrap().feet();
    let g = stages.gravity_mps2;
    let naive = measure_edit(&clip, &edited, stages, &model, &edits, &feet, &planted, g).unwrap();
    let unedited = measure_edit(&clip, &clip, stages, &model, &[GroundEdit::default(); 2], &feet, &planted, g).unwrap();
    eprintln!("16_01 unedited: {unedited:?}");
    eprintln!("16_01 naive +0.5 m: {naive:?}");
    // The naive edit lands exactly where asked, except where the capture has the foot below
    // the floor (the asked place is on it), and moves planted feet no more than the capture
    // does (it moves ground stages rigidly).
    assert!(naive.placement_error_m.iter().all(|e| *e < naive.below_floor_m + 1e-4), "{:?}", naive.placement_error_m);
    assert!((naive.planted_drift_m - unedited.planted_drift_m).abs() < 1e-4);
    // A horizontal shift spread linearly over the flight adds a constant velocity: the
    // parabola under the same gravity fits as well as before…
    for (a, b) in naive.parabola_rms_m.iter().zip(&unedited.parabola_rms_m) {
        assert!((a - b).abs() < 1e-4, "{a} vs {b}");
    }
    // …but the take-off and the landing each need an impulse m·|Δ|·fps/(frames between the
    // last ground frame before and the first after), which no force in the ground stage
    // supplies: what the spacetime optimisation must remove.
    let flight = stages.stages[1].frames;
    let frames_between = (flight.end - (flight.start - 1)) as f64;
    let want = 70.0 * shift.length() * clip.fps() / frames_between;
    for jump in &naive.border_momentum_jump {
        assert!((jump - want).abs() < 0.01 * want, "{jump} vs {want}");
    }
    assert!(unedited.border_momentum_jump.iter().all(|j| *j < 1e-9));
}

/// Angular momentum variation (max |L − L̄| / max |L|, %) of each flight of `clip`, read by FK
/// and the momentum kernel, independently of the optimiser's residuals.
fn flight_spin_variation_pct(clip: &Clip, stages: &Stages, model: &BodyModel) -> Vec<f64> {
    let track = momentum_of_poses(&forward_kinematics(clip), clip.fps(), model);
    let fit = fit_ballistic(&stages.stages, &track.com_m, &track.momentum, clip.fps()).unwrap();
    fit.flights.iter().map(|f| f.momentum_variation_pct).collect()
}

#[test]
fn optimised_landing_shift_is_ballistic_with_feet_planted_where_asked() {
    let Some(Jump { clip, model, staged, forward, planted, .. }) = jump_16_01() else { return };
    let stages = &staged.stages;
    // 0.5 m further along the jump and 0.3 m to its left.
    let side = DVec3::Y.cross(forward);
    let edits = [GroundEdit::default(), GroundEdit { offset_m: 0.5 * forward + 0.3 * side, turn_rad: 0.0 }];
    let feet = find_landmarks(clip.skeleton()).unwrap().feet();
    let setup = EditSetup { clip: &clip, stages, model: &model, feet, planted: &planted, edits: &edits };
    let (edited, report) = momentum_edit(setup, &SolveOptions::default()).unwrap();
    eprintln!("16_01 optimised: {report:#?}");
    let naive = naive_edit(&clip, stages, &model, &edits).unwrap();
    let g = stages.gravity_mps2;
    let ours = measure_edit(&clip, &edited, stages, &model, &edits, &feet, &planted, g).unwrap();
    let base = measure_edit(&clip, &naive, stages, &model, &edits, &feet, &planted, g).unwrap();
    let (spin_ours, spin_naive) =
        (flight_spin_variation_pct(&edited, stages, &model), flight_spin_variation_pct(&naive, stages, &model));
    eprintln!("16_01 naive     : {base:?}, flight L variation {spin_naive:?} %");
    eprintln!("16_01 optimised : {ours:?}, flight L variation {spin_ours:?} %");
    assert!(ours.placement_error_m.iter().all(|e| *e < 1e-3), "landing {:?}", ours.placement_error_m);
    assert!(ours.planted_drift_m < 5e-3, "planted feet drift {} m", ours.planted_drift_m);
    assert!(ours.below_floor_m < 1e-3, "below floor {} m", ours.below_floor_m);
    assert!(ours.parabola_rms_m.iter().all(|r| *r < 0.01), "parabola {:?}", ours.parabola_rms_m);
    assert!(spin_ours.iter().all(|v| *v < 5.0), "flight L variation {spin_ours:?} %");
    // Joint limits: every joint but the root stays within the angle from its mean rotation
    // that the capture itself reaches, plus the margin (read from the clips' local rotations).
    let excess = joint_range_excess_rad(&clip, &edited);
    eprintln!(
        "16_01 optimised : joint range excess {excess:.4} rad (naive {:.4})",
        joint_range_excess_rad(&clip, &naive)
    );
    // Soft in the solver: the report says how far past the range + margin the edit goes (on
    // this edit 0 since the planted feet roll as captured; with the ankles held still the
    // take-off needed 0.025 rad more than the margin).
    let reported = report.violations.iter().find(|v| v.constraint == "joint limits").unwrap().max;
    assert!(
        ((excess - LIMIT_MARGIN_RAD).max(0.0) - reported).abs() < 1e-3,
        "measured {excess} rad, reported {reported} + margin"
    );
    // The root's velocity changes in one frame no more than half again the capture's largest
    // change: no zigzag beside the pins, the landing's impact spread over frames as captured.
    let (root_ours, root_capture) = (largest_root_velocity_change(&edited), largest_root_velocity_change(&clip));
    eprintln!("16_01 root velocity change in a frame: optimised {root_ours:.3} m/s, capture {root_capture:.3} m/s");
    assert!(root_ours < 1.5 * root_capture, "root velocity change {root_ours} m/s vs the capture's {root_capture}");
    // The impulse the naive edit needs at the take-off is almost gone (the landing is an
    // impact: its vertical momentum may jump, so it is only printed above).
    let (ours_takeoff, naive_takeoff) = (ours.border_momentum_jump[0], base.border_momentum_jump[0]);
    assert!(ours_takeoff < 0.05 * naive_takeoff, "take-off impulse {ours_takeoff} vs naive {naive_takeoff}");
}

/// The other short jumps of the corpus (16_01 is the test above, 01_01's hops the test
/// below; the MASS backflip, whose flight is not ballistic under this body model, is not
/// handled yet): every ground stage after the first moved 0.3 m further along the first
/// flight, the landings held together (88_01's second "flight" is a 0.1 s rebound, so
/// moving the stage after it alone is refused as unreachable). Each is held to the issue's
/// bars, read by FK and the momentum kernel independently of the solver's residuals, and
/// compared with the naive edit on the same measures.
#[test]
fn other_corpus_jumps_land_where_asked_ballistic_and_planted() {
    for path in ["bvh/cmu_daz/13_32.bvh", "bvh/cmu/90_05.bvh", "bvh/cmu/88_01.bvh"] {
        let Some(Jump { clip, model, staged, forward, planted, .. }) = jump(path) else { return };
        let stages = &staged.stages;
        let grounds = stages.stages.iter().filter(|s| s.kind == StageKind::Ground).count();
        let mut edits = vec![GroundEdit { offset_m: 0.3 * forward, turn_rad: 0.0 }; grounds];
        edits[0] = GroundEdit::default();
        let feet = find_landmarks(clip.skeleton()).unwrap().feet();
        let setup = EditSetup { clip: &clip, stages, model: &model, feet, planted: &planted, edits: &edits };
        let (edited, report) = momentum_edit(setup, &SolveOptions::default()).unwrap();
        let naive = naive_edit(&clip, stages, &model, &edits).unwrap();
        let g = stages.gravity_mps2;
        let ours = measure_edit(&clip, &edited, stages, &model, &edits, &feet, &planted, g).unwrap();
        let base = measure_edit(&clip, &naive, stages, &model, &edits, &feet, &planted, g).unwrap();
        let unedited = vec![GroundEdit::default(); grounds];
        let capture = measure_edit(&clip, &clip, stages, &model, &unedited, &feet, &planted, g).unwrap();
        let spin = flight_spin_variation_pct(&edited, stages, &model);
        eprintln!("{path}: {} iterations, {:.2} s", report.iterations, report.seconds);
        eprintln!("{path} naive     : {base:?}");
        eprintln!("{path} optimised : {ours:?}, flight L variation {spin:?} %");
        eprintln!("{path} capture   : below the floor {:.4} m", capture.below_floor_m);
        assert!(ours.placement_error_m.iter().all(|e| *e < 1e-3), "{path}: landing {:?}", ours.placement_error_m);
        assert!(ours.planted_drift_m < 5e-3, "{path}: planted feet drift {} m", ours.planted_drift_m);
        assert!(ours.parabola_rms_m.iter().all(|r| *r < 0.01), "{path}: parabola {:?}", ours.parabola_rms_m);
        assert!(spin.iter().all(|v| *v < 5.0), "{path}: flight L variation {spin:?} %");
        // The floor: no deeper than the capture's own feet go (90_05's left toe is 6.8 cm
        // under its resting height in the capture), and never deeper than the naive edit.
        assert!(
            ours.below_floor_m <= capture.below_floor_m + 1e-3 && ours.below_floor_m <= base.below_floor_m + 1e-3,
            "{path}: below the floor {} m (capture {}, naive {})",
            ours.below_floor_m,
            capture.below_floor_m,
            base.below_floor_m
        );
        // Better than the naive edit where it fails: its planted feet slide with the
        // stage's shift spread over the flight, and its take-off needs an impulse (the
        // landings are impacts; the stages moved together need none from the naive edit,
        // which the optimised one re-solves: printed above).
        assert!(
            ours.planted_drift_m < base.planted_drift_m,
            "{path}: drift {} vs naive {}",
            ours.planted_drift_m,
            base.planted_drift_m
        );
        let take_off = stages.stages.iter().position(|s| s.kind == StageKind::Flight).unwrap() - 1;
        assert!(
            ours.border_momentum_jump[take_off] < 0.7 * base.border_momentum_jump[take_off],
            "{path}: take-off impulse {} vs naive {}",
            ours.border_momentum_jump[take_off],
            base.border_momentum_jump[take_off]
        );
        // Joint limits are soft (see the 16_01 test): the report says how far past the
        // capture's range + margin the edit goes, as measured here from the clips. The toes
        // go furthest (90_05's left toe 0.26 rad past the margin: the capture has that toe
        // 6.8 cm under the floor, and the edit bends it up onto the floor).
        let excess = joint_range_excess_rad(&clip, &edited);
        let reported = report.violations.iter().find(|v| v.constraint == "joint limits").unwrap().max;
        eprintln!("{path} joint range excess {excess:.4} rad, reported past the margin {reported:.4}");
        assert!(
            ((excess - LIMIT_MARGIN_RAD).max(0.0) - reported).abs() < 1e-3,
            "{path}: measured {excess}, reported {reported}"
        );
    }
}

/// CMU 01_01 (23 s, eleven hops): one hop's landing moved 0.2 m further, the hops after it
/// with it. As a whole the edit did not converge in 120 steps; solved around the hop (the
/// default for clips over 10 s) it converges, the rest of the capture is exactly the
/// capture moved with its ground stages, and the joins make no jump the capture does not.
#[test]
fn a_hop_of_a_long_capture_is_solved_around_the_edit() {
    let Some(Jump { clip, model, staged, planted, .. }) = jump("bvh/cmu/01_01.bvh") else { return };
    let stages = &staged.stages;
    let grounds = stages.ground_frames();
    assert!(grounds.len() >= 6, "{} ground stages", grounds.len());
    // The fifth hop: the flight between ground stages 3 and 4, along its own travel.
    let flight =
        stages.stages.iter().find(|s| s.kind == StageKind::Flight && s.frames.start == grounds[3].end).unwrap();
    let travel = staged.track.com_m[flight.frames.end - 1] - staged.track.com_m[flight.frames.start];
    let shift = 0.2 * DVec3::new(travel.x, 0.0, travel.z).normalize();
    let edits: Vec<GroundEdit> = (0..grounds.len())
        .map(|i| GroundEdit { offset_m: if i >= 4 { shift } else { DVec3::ZERO }, turn_rad: 0.0 })
        .collect();
    let feet = find_landmarks(clip.skeleton()).unwrap().feet();
    let setup = EditSetup { clip: &clip, stages, model: &model, feet, planted: &planted, edits: &edits };
    let (edited, report) = momentum_edit(setup, &SolveOptions::default()).unwrap();
    let window = report.solved_frames;
    eprintln!(
        "01_01: solved frames {window:?} of {}, {} iterations, {:.2} s",
        clip.frame_count(),
        report.iterations,
        report.seconds
    );
    assert!(window.start > grounds[3].start && window.end < grounds[4].end, "{window:?}");
    // Outside the window: the capture itself before, moved by the shift after.
    let joints = clip.joint_count();
    let root = clip.skeleton().joints().iter().position(|j| j.parent.is_none()).unwrap();
    for f in (0..window.start).chain(window.end..clip.frame_count()) {
        let moved = if f >= window.end { shift.as_vec3() } else { glam::Vec3::ZERO };
        let (a, b) = (f * joints, (f + 1) * joints);
        assert_eq!(edited.rotations()[a..b], clip.rotations()[a..b], "frame {f}");
        let want = clip.translations()[a + root] + moved;
        assert!((edited.translations()[a + root] - want).length() < 1e-5, "frame {f}");
    }
    // The edited hop: ballistic, its spin constant (FK and the momentum kernel).
    let index = stages.stages.iter().position(|s| s.frames == flight.frames).unwrap();
    let flights_before = stages.stages[..index].iter().filter(|s| s.kind == StageKind::Flight).count();
    let spin = flight_spin_variation_pct(&edited, stages, &model)[flights_before];
    let g = stages.gravity_mps2;
    let ours = measure_edit(&clip, &edited, stages, &model, &edits, &feet, &planted, g).unwrap();
    let naive = naive_edit(&clip, stages, &model, &edits).unwrap();
    let base = measure_edit(&clip, &naive, stages, &model, &edits, &feet, &planted, g).unwrap();
    eprintln!(
        "01_01 edited hop: parabola RMS {:.2e} m (naive {:.2e}), L variation {spin:.3} %",
        ours.parabola_rms_m[flights_before], base.parabola_rms_m[flights_before]
    );
    assert!(ours.parabola_rms_m[flights_before] < 0.01 && spin < 5.0);
    let take_off = index - 1;
    eprintln!(
        "01_01 take-off impulse {:.2} kg·m/s (naive {:.2})",
        ours.border_momentum_jump[take_off], base.border_momentum_jump[take_off]
    );
    assert!(ours.border_momentum_jump[take_off] < 0.2 * base.border_momentum_jump[take_off]);
    // The joins: no velocity jump of the root beyond half again the capture's largest.
    let (root_ours, root_capture) = (largest_root_velocity_change(&edited), largest_root_velocity_change(&clip));
    eprintln!("01_01 root velocity change in a frame: edited {root_ours:.3} m/s, capture {root_capture:.3} m/s");
    assert!(root_ours < 1.5 * root_capture, "{root_ours} vs {root_capture}");
}

/// Largest change of the root's velocity from one frame to the next, m/s (read from the
/// root's world positions by forward kinematics).
fn largest_root_velocity_change(clip: &Clip) -> f64 {
    let poses = forward_kinematics(clip);
    let at = |f: usize| poses.position(f, 0).as_dvec3();
    (1..clip.frame_count() - 1)
        .map(|f| ((at(f + 1) - at(f)) - (at(f) - at(f - 1))).length() * clip.fps())
        .fold(0.0, f64::max)
}

/// Largest angle by which a non-root joint of `edited` leaves the range of `original`: the
/// largest angle of the original's local rotation from its (sign-aligned, normalised)
/// mean, by 2·acos|q·q̄|.
fn joint_range_excess_rad(original: &Clip, edited: &Clip) -> f64 {
    let joints = original.joint_count();
    let angle = |q: Quat, m: Quat| 2.0 * f64::from(q.dot(m).abs().min(1.0)).acos();
    let mut worst = f64::NEG_INFINITY;
    for j in (0..joints).filter(|&j| original.skeleton().joints()[j].parent.is_some()) {
        let of = |c: &Clip| (0..c.frame_count()).map(|f| c.rotations()[f * joints + j]).collect::<Vec<Quat>>();
        let (qo, qe) = (of(original), of(edited));
        let sum =
            qo.iter().fold(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0), |a, q| a + if q.dot(qo[0]) < 0.0 { -*q } else { *q });
        let mean = if sum.length() > 1e-6 { quat_normalize_or_identity(sum) } else { qo[0] };
        let spread = qo.iter().map(|q| angle(*q, mean)).fold(0.0, f64::max);
        worst = worst.max(qe.iter().map(|q| angle(*q, mean) - spread).fold(f64::NEG_INFINITY, f64::max));
    }
    worst.max(0.0)
}

#[test]
fn bad_edits_are_typed_errors() {
    let Some(data) = shared_data() else { return };
    let clip = load_clip(&data.join("bvh/cmu/16_01.bvh"), ClipLoadOptions::default()).unwrap().value;
    let model = body_model(clip.skeleton(), 70.0, MassTable::DeLevaMale, None).unwrap();
    let stages = stage_clip(&clip, &model, None, None).unwrap().stages;
    let feet = find_landmarks(clip.skeleton()).unwrap().feet();
    let edits = [GroundEdit::default(); 2];
    let run = |clip: &Clip, stages: &Stages, edits: &[GroundEdit], options: SolveOptions| {
        let setup = EditSetup { clip, stages, model: &model, feet, planted: &[], edits };
        momentum_edit(setup, &options).map(|_| ()).unwrap_err()
    };
    // 5 m further in a 0.3 s flight: 16 m/s more take-off speed.
    let far = [GroundEdit::default(), GroundEdit { offset_m: DVec3::new(5.0, 0.0, 0.0), turn_rad: 0.0 }];
    assert!(matches!(run(&clip, &stages, &far, SolveOptions::default()), SolveError::Unreachable { stage: 1, .. }));
    let ground_only = Stages {
        stages: vec![Stage { kind: StageKind::Ground, frames: FrameRange::new(0, clip.frame_count()) }],
        ..stages.clone()
    };
    assert_eq!(run(&clip, &ground_only, &edits[..1], SolveOptions::default()), SolveError::NoFlight);
    let low = SolveOptions { gravity_scale: -1.0, ..SolveOptions::default() };
    assert_eq!(run(&clip, &stages, &edits, low), SolveError::GravityScale(-1.0));
    let short = Clip::rest_pose(clip.skeleton().clone(), clip.fps(), 8).unwrap();
    let short_stages = Stages { frame_count: 8, ..stages.clone() };
    assert_eq!(run(&short, &short_stages, &edits, SolveOptions::default()), SolveError::TooShort { frames: 8 });
    let few = SolveOptions { max_iterations: 2, ..SolveOptions::default() };
    let half = [GroundEdit::default(), GroundEdit { offset_m: DVec3::new(0.5, 0.0, 0.0), turn_rad: 0.0 }];
    let err = run(&clip, &stages, &half, few);
    assert!(matches!(err, SolveError::NotConverged { iterations: 2, .. }), "{err}");
}
