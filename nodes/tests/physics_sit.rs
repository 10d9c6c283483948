//! Sit down on a seat and rise from it (kernels::physics::controllers::{sit, rise}) on a rig
//! we did not build (the Mixamo Xbot). Poses are judged from the simulated clip by forward
//! kinematics of the skeleton, not by the controllers' own senses: seated means the hips
//! rest just above the seat's top, over it, with the feet where they stood and the head up;
//! standing again means hips and head back at 90 % of their first height with the feet
//! where they stood, and (from the timeline) the rise succeeded and balance holds to the
//! end. Skips without `../shared/data` outside CI.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use kinegraph_nodes::cancel::Cancel;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf_file};
use kinegraph_nodes::kernels::body::find_landmarks;
use kinegraph_nodes::kernels::physics::controller::Outcome;
use kinegraph_nodes::kernels::physics::seat::Chair;
use kinegraph_nodes::kernels::physics::simulate::{Request, Script, SimParams, SimResult, simulate};
use kinegraph_nodes::model::Skeleton;
use kinegraph_nodes::model::fk::{Transform, pose_world};

fn xbot(data: &Path) -> Arc<Skeleton> {
    read_gltf_file(&data.join("gltf/Xbot.glb"), &GltfReadOptions::default()).unwrap().value.skeleton.unwrap()
}

fn cmu(data: &Path) -> Arc<Skeleton> {
    let (clip, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    clip.skeleton().clone()
}

/// Request "sit" at 0.5 s and "rise" at `rise_at`, run to `secs`.
fn sit_and_rise(chair: Chair, rise_at: f32, secs: f32) -> Script {
    Script {
        duration_secs: secs,
        controllers: None,
        requests: vec![
            Request { controller: "sit".into(), at_secs: 0.5 },
            Request { controller: "rise".into(), at_secs: rise_at },
        ],
        pushes: vec![],
        chair: Some(chair),
    }
}

/// Where hips (midpoint), ankles and head are in a frame of the simulated clip.
struct Pose {
    hips: Vec3,
    ankles: [Vec3; 2],
    head: Vec3,
}

fn pose_at(r: &SimResult, time_secs: f32) -> Pose {
    let clip = &r.clip;
    let skeleton = clip.skeleton();
    let lm = find_landmarks(skeleton).unwrap();
    let frame = ((f64::from(time_secs) * clip.fps()).round() as usize).min(clip.frame_count() - 1);
    let mut world = vec![Transform::IDENTITY; skeleton.len()];
    pose_world(skeleton, clip.frame_rotations(frame), clip.frame_translations(frame), &mut world);
    let at = |j: usize| world[j].translation;
    Pose {
        hips: (at(lm.limbs[0][0]) + at(lm.limbs[1][0])) * 0.5,
        ankles: [at(lm.limbs[0][2]), at(lm.limbs[1][2])],
        head: at(lm.head),
    }
}

/// What a run did, read from its clip and timeline.
#[derive(Debug)]
struct Verdict {
    /// Just before the rise request: hips over the seat, just above its top; feet where they
    /// stood; head well above the hips.
    sat: bool,
    /// At the end: hips and head at 90 % of their first height, feet where they stood, the
    /// rise succeeded and balance holds.
    stood: bool,
    /// The rise never lifted the hips 10 cm off the seat, and at the end the figure still
    /// sits there (hips just above the seat, head up) with sit holding it.
    kept_seated: Option<bool>,
    /// Hips' height above the seat's top when seated, and how far they moved back, metres.
    seated_hips: (f32, f32),
    /// Largest horizontal drift of an ankle at the run's end from where it stood, metres.
    feet_drift_m: f32,
    min_head_m: f32,
    timeline: String,
}

fn judge(r: &SimResult, chair: &Chair, rise_at: f32, secs: f32) -> Verdict {
    let first = pose_at(r, 0.0);
    let seated = pose_at(r, rise_at - 0.1);
    let last = pose_at(r, secs);
    let back = -r.figure.forward;
    let moved = (seated.hips - first.hips).with_y(0.0);
    let moved_back = moved.dot(back);
    let moved_aside = moved.dot(Vec3::Y.cross(back)).abs();
    let above_seat = seated.hips.y - chair.seat_height_m;
    let drift = |p: &Pose| (0..2).map(|s| (p.ankles[s] - first.ankles[s]).with_y(0.0).length()).fold(0.0f32, f32::max);
    let feet_still =
        |p: &Pose| drift(p) < FEET_SLIDE_M && (0..2).all(|s| (p.ankles[s].y - first.ankles[s].y).abs() < ANKLE_RISE_M);
    // Seated: the hip joints a thigh's radius (7 cm on the Xbot) and a little above the seat,
    // past its front edge (the hips started over the feet, `behind_m` in front of the edge,
    // within 5 cm), not off its back nor its sides.
    let sat = (0.0..0.12).contains(&above_seat)
        && moved_back > chair.behind_m - 0.05
        && moved_back < chair.behind_m + chair.size_m[1]
        && moved_aside < 0.5 * chair.size_m[0]
        && feet_still(&seated)
        && seated.head.y - seated.hips.y > 0.4;
    let rise = r.timeline.iter().position(|a| a.controller == "rise");
    let balance_after = rise.is_some_and(|i| {
        r.timeline[i].outcome == Outcome::Succeeded
            && r.timeline[i + 1..].iter().all(|a| a.controller == "balance")
            && r.timeline.last().is_some_and(|a| a.controller == "balance" && a.outcome == Outcome::Active)
    });
    let stood =
        balance_after && last.hips.y > 0.9 * first.hips.y && last.head.y > 0.9 * first.head.y && feet_still(&last);
    // Hips never 10 cm above where they sat, sampled every 0.1 s after the rise request.
    let steps = ((secs - rise_at) * 10.0) as usize;
    let stayed_down = (0..=steps).all(|k| pose_at(r, rise_at + k as f32 * 0.1).hips.y < seated.hips.y + 0.1);
    let kept_seated = stayed_down.then(|| {
        (0.0..0.12).contains(&(last.hips.y - chair.seat_height_m))
            && last.head.y - last.hips.y > 0.4
            && r.timeline.last().is_some_and(|a| a.controller == "sit" && a.outcome == Outcome::Active)
    });
    let timeline = r
        .timeline
        .iter()
        .map(|a| format!("{} {:.2}–{:.2} {:?}", a.controller, a.start_secs, a.end_secs, a.outcome))
        .collect::<Vec<_>>()
        .join(" | ");
    Verdict {
        sat,
        stood,
        kept_seated,
        seated_hips: (above_seat, moved_back),
        feet_drift_m: drift(&last),
        min_head_m: r.min_head_clearance_m,
        timeline,
    }
}

/// How far an ankle may slide over the ground, metres. Not planted: measured, the feet slide
/// 3–9 cm while the Xbot sits (about 2 cm during the descent, 3–4 cm when the seat takes
/// the weight) and up to 11 cm over a sit and a rise.
const FEET_SLIDE_M: f32 = 0.12;
/// How far an ankle may rise, metres (seated, the feet tip onto their heels by 1–5 cm).
const ANKLE_RISE_M: f32 = 0.06;

const RISE_AT: f32 = 4.5;
const RUN_SECS: f32 = 10.0;

fn run(skeleton: &Arc<Skeleton>, chair: Chair) -> Verdict {
    let r = simulate(skeleton, None, &sit_and_rise(chair, RISE_AT, RUN_SECS), &SimParams::default(), Cancel::NEVER)
        .unwrap();
    judge(&r, &chair, RISE_AT, RUN_SECS)
}

/// The Mixamo Xbot on stools 0.40, 0.45 and 0.50 m high, their front edges 0.10, 0.15 and
/// 0.20 m behind where it stands: it sits on every one, and from the 0.40 and 0.45 m seats
/// placed 0.15 m behind it stands up again with its feet within 12 cm of where they stood and
/// keeps its balance. Where the rise does not bid or does not get the hips off the seat, the
/// figure stays seated (sit holds it; the fall controller once threw it off the stool). The
/// rest of the table is printed: what the rise does not yet manage (from the other seats it
/// runs out of time, or stands with its feet slid 14–31 cm, or stands and topples forward).
#[test]
fn xbot_sits_on_stools_of_three_heights_and_stands_up_from_two() {
    let Some(data) = shared_data() else { return };
    let skeleton = xbot(&data);
    let (mut failures, mut held_runs) = (Vec::new(), 0);
    for seat_height_m in [0.40f32, 0.45, 0.50] {
        for behind_m in [0.10f32, 0.15, 0.20] {
            let chair = Chair { seat_height_m, behind_m, ..Chair::default() };
            let v = run(&skeleton, chair);
            println!(
                "seat {seat_height_m:.2} m, edge {behind_m:.2} m behind: sat {} (hips {:.3} m above the seat, {:.3} m back), stood {}, kept seated {:?}, feet drift {:.3} m, lowest head {:.2} m: {}",
                v.sat,
                v.seated_hips.0,
                v.seated_hips.1,
                v.stood,
                v.kept_seated,
                v.feet_drift_m,
                v.min_head_m,
                v.timeline
            );
            held_runs += usize::from(v.kept_seated.is_some());
            let must_stand = seat_height_m <= 0.45 && behind_m == 0.15;
            if !v.sat || (must_stand && !v.stood) || v.kept_seated == Some(false) {
                failures.push(format!("seat {seat_height_m} behind {behind_m}: {v:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    // The hold is exercised: four rises leave the hips on the seat (three stall, one is refused).
    assert!(held_runs >= 1, "no rise left the hips on the seat, so the hold was not tested");
}

/// The same script run twice gives the same clip bit for bit.
#[test]
fn sit_and_rise_is_deterministic() {
    let Some(data) = shared_data() else { return };
    let skeleton = xbot(&data);
    let script = sit_and_rise(Chair::default(), RISE_AT, 6.0);
    let a = simulate(&skeleton, None, &script, &SimParams::default(), Cancel::NEVER).unwrap();
    let b = simulate(&skeleton, None, &script, &SimParams::default(), Cancel::NEVER).unwrap();
    assert_eq!(a.clip.frame_count(), b.clip.frame_count());
    for f in 0..a.clip.frame_count() {
        assert_eq!(a.clip.frame_rotations(f), b.clip.frame_rotations(f), "frame {f}");
        assert_eq!(a.clip.frame_translations(f), b.clip.frame_translations(f), "frame {f}");
    }
}

/// Without a chair neither controller bids: a request for "sit" on open ground leaves the
/// figure standing in balance.
#[test]
fn no_seat_no_sitting() {
    let Some(data) = shared_data() else { return };
    let skeleton = xbot(&data);
    let script = Script { chair: None, ..sit_and_rise(Chair::default(), 2.0, 3.0) };
    let r = simulate(&skeleton, None, &script, &SimParams::default(), Cancel::NEVER).unwrap();
    assert!(!r.timeline.is_empty() && r.timeline.iter().all(|a| a.controller == "balance"), "{:?}", r.timeline);
    let (first, last) = (pose_at(&r, 0.0), pose_at(&r, 3.0));
    assert!(last.hips.y > 0.97 * first.hips.y, "{} -> {}", first.hips.y, last.hips.y);
}

/// CMU 02_01's figure does not sit: its rest pose splays the legs 20°, so standing holds each
/// ankle turned 0.35 rad about the forward axis, and dorsiflexing it further twists the foot
/// (rapier's ball-joint coordinates are integrated rates, not a rotation vector, so the three
/// axis motors no longer act about the anatomical axes); the shanks lose their forward lean,
/// the hips drift back and the capture point passes the heels half way down.
#[test]
#[ignore = "the CMU figure tips backward on the way down (its splayed rest pose twists the ankles)"]
fn cmu_sits_on_a_standard_stool() {
    let Some(data) = shared_data() else { return };
    let v = run(&cmu(&data), Chair::default());
    assert!(v.sat, "{v:?}");
}

/// A chair with impossible numbers is a typed script error naming the number, not a run.
#[test]
fn a_bad_chair_is_a_script_error() {
    use kinegraph_nodes::kernels::physics::simulate::{ScriptError, SimError};
    let Some(data) = shared_data() else { return };
    let skeleton = xbot(&data);
    for (chair, says) in [
        (Chair { seat_height_m: 0.0, ..Chair::default() }, "seat_height_m 0"),
        (Chair { behind_m: f32::NAN, ..Chair::default() }, "behind_m NaN"),
        (Chair { size_m: [0.5, -1.0], ..Chair::default() }, "size_m [0.5, -1.0]"),
        (Chair { behind_m: -0.2, ..Chair::default() }, "puts the seat under the feet"),
    ] {
        let script = sit_and_rise(chair, 1.0, 2.0);
        match simulate(&skeleton, None, &script, &SimParams::default(), Cancel::NEVER) {
            Err(SimError::Script(ScriptError::BadChair(message))) => assert!(message.contains(says), "{message}"),
            other => panic!("{chair:?}: {:?}", other.map(|r| r.timeline)),
        }
    }
}
