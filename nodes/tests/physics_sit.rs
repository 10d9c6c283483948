//! Sit down on a seat and rise from it (kernels::physics::controllers::{sit, rise}) on a rig
//! we did not build (the Mixamo Xbot). Poses are judged from the simulated clip by forward
//! kinematics of the skeleton, not by the controllers' own senses: seated means the hips
//! rest just above the seat's top, over it, with the feet where they stood and the head up;
//! standing again means hips and head back at 90 % of their first height with the feet
//! where they stood, and (from the timeline) the rise succeeded and balance holds to the
//! end. Skips without `../shared/data` outside CI.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod node_eval;

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use kinegraph_nodes::cancel::Cancel;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf_file};
use kinegraph_nodes::kernels::body::find_landmarks;
use kinegraph_nodes::kernels::load::load_character;
use kinegraph_nodes::kernels::physics::controller::Outcome;
use kinegraph_nodes::kernels::physics::figure::{BodyRole, Figure, FigureParams, build_figure};
use kinegraph_nodes::kernels::physics::seat::Chair;
use kinegraph_nodes::kernels::physics::simulate::{Request, Script, SimParams, SimResult, simulate};
use kinegraph_nodes::kernels::props::props_penetration;
use kinegraph_nodes::model::fk::{Transform, pose_world};
use kinegraph_nodes::model::{Clip, FrameRange, Mesh, Skeleton, Skin};
use kinegraph_nodes::node::{NodeError, ParamValue, Value};
use node_eval::eval_node;

fn xbot(data: &Path) -> Arc<Skeleton> {
    read_gltf_file(&data.join("gltf/Xbot.glb"), &GltfReadOptions::default()).unwrap().value.skeleton.unwrap()
}

/// The Xbot as `character.load` gives it: skeleton and every mesh merged, skinned to it.
fn xbot_with_mesh(data: &Path) -> (Arc<Skeleton>, Arc<Mesh>) {
    let character = load_character(&data.join("gltf/Xbot.glb"), 0).unwrap().value;
    (character.clip.skeleton().clone(), Arc::new(character.mesh))
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
    /// Per measured mesh: how deep that skin went into the stool over the last second
    /// before the rise request (seated), cm, by [`props_penetration`].
    sunk_cm: Vec<f64>,
    min_head_m: f32,
    timeline: String,
}

fn judge(r: &SimResult, measured: &[&Mesh], chair: &Chair, rise_at: f32, secs: f32) -> Verdict {
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
    // Seated: the hip joints the seated body's depth above the seat (a thigh's radius, 7 cm
    // on the skeleton-sized Xbot; the seat pad's, 11.5 cm, sized from its mesh) and at most
    // SEATED_SLACK_M more, past its front edge (the hips started over the feet, `behind_m`
    // in front of the edge, within 5 cm), not off its back nor its sides.
    let thigh = r.figure.bodies.iter().position(|b| b.role == BodyRole::Thigh).expect("the figure has thighs");
    let on_seat = 0.0..r.figure.seated_depth_m(thigh) + SEATED_SLACK_M;
    let sat = on_seat.contains(&above_seat)
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
        on_seat.contains(&(last.hips.y - chair.seat_height_m))
            && last.head.y - last.hips.y > 0.4
            && r.timeline.last().is_some_and(|a| a.controller == "sit" && a.outcome == Outcome::Active)
    });
    let timeline = r
        .timeline
        .iter()
        .map(|a| format!("{} {:.2}–{:.2} {:?}", a.controller, a.start_secs, a.end_secs, a.outcome))
        .collect::<Vec<_>>()
        .join(" | ");
    let seated_frames = FrameRange {
        start: ((rise_at - 1.0) as f64 * r.clip.fps()) as usize,
        end: (rise_at as f64 * r.clip.fps()) as usize,
    };
    let stool = r.seat.expect("the script has a chair").mesh();
    let sunk_cm =
        measured.iter().map(|mesh| props_penetration(&r.clip, mesh, &stool, seated_frames).unwrap().max_cm).collect();
    Verdict {
        sat,
        stood,
        kept_seated,
        seated_hips: (above_seat, moved_back),
        feet_drift_m: drift(&last),
        sunk_cm,
        min_head_m: r.min_head_clearance_m,
        timeline,
    }
}

/// How far above resting on the seat the hips of a seated figure may be, metres (measured
/// on the Xbot, skeleton- or mesh-sized: −0.1 to 1.4 cm above the seated body's depth).
const SEATED_SLACK_M: f32 = 0.05;

/// How far an ankle may slide over the ground, metres. Not planted: measured, the feet slide
/// 3–10 cm while the Xbot sits, 2.5–9 cm of it in the first 2.5 s of the descent (the
/// contact solver's creep: physics_controllers' `a_balanced_figure_keeps_its_feet_where_they_stand`),
/// the rest as the seat takes the weight and the toes lift, and up to 11 cm over a sit and
/// a rise.
const FEET_SLIDE_M: f32 = 0.12;
/// How far an ankle may rise, metres (seated, the feet tip onto their heels by 1–5 cm).
const ANKLE_RISE_M: f32 = 0.06;

const RISE_AT: f32 = 4.5;
const RUN_SECS: f32 = 10.0;

/// Sits and rises on `chair`, the figure's shapes sized from `sized_from` if given, and
/// measures how deep each of the `measured` meshes (skinned to the skeleton) goes into the
/// stool.
fn run(skeleton: &Arc<Skeleton>, chair: Chair, sized_from: Option<&Arc<Mesh>>, measured: &[&Mesh]) -> Verdict {
    let params = SimParams { mesh: sized_from.cloned(), ..SimParams::default() };
    let r = simulate(skeleton, None, &sit_and_rise(chair, RISE_AT, RUN_SECS), &params, Cancel::NEVER).unwrap();
    judge(&r, measured, &chair, RISE_AT, RUN_SECS)
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
            let v = run(&skeleton, chair, None, &[]);
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

/// The skin of `mesh` whose heaviest joint rides on a body of `figure` with the given
/// `role` (no triangles: the props measure needs only vertices).
fn skin_of(mesh: &Mesh, figure: &Figure, role: BodyRole) -> Mesh {
    let skin = mesh.skin.as_ref().unwrap();
    let keep: Vec<usize> = (0..mesh.positions.len())
        .filter(|&v| figure.bodies[figure.owner[skin.heaviest_joint(v).0]].role == role)
        .collect();
    Mesh {
        positions: keep.iter().map(|&v| mesh.positions[v]).collect(),
        normals: keep.iter().map(|&v| mesh.normals[v]).collect(),
        skin: Some(Skin {
            skeleton: skin.skeleton.clone(),
            joints: keep.iter().map(|&v| skin.joints[v]).collect(),
            weights: keep.iter().map(|&v| skin.weights[v]).collect(),
            inverse_bind_matrices: skin.inverse_bind_matrices.clone(),
        }),
        ..Mesh::default()
    }
}

/// Given its mesh, the figure's shapes are sized from the skin, and the Xbot's seated body
/// (the skin on its pelvis and thighs, posed by linear blend skinning from the simulated
/// clip) rests on the stool instead of sinking into it; the figure sized from the skeleton
/// alone sinks several centimetres on the same stools, by the same measure. The buttocks
/// (the pelvis's skin, on the seat pad) go less than 1 cm into the seat. The thighs are
/// capsules holding half their skin (the median radius): level on the lower stools their
/// skin goes less than 1 cm in too, but on the 0.50 m stool, higher than the knees, the
/// thighs slope down over its front edge and their underside goes 1.37 cm into it (0.61 cm
/// while the feet's boxes came from the skeleton and held the shoes 1.5 cm above the floor,
/// the knees that much higher): there the 1.5 cm bound is a regression bound on a known
/// defect. What happens after the rise request is printed, not asserted (see the README).
#[test]
fn sized_from_its_mesh_the_seated_xbot_rests_on_the_stool() {
    let Some(data) = shared_data() else { return };
    let (skeleton, mesh) = xbot_with_mesh(&data);
    let figure = build_figure(&skeleton, &FigureParams::default(), Some(&mesh)).unwrap();
    let (buttocks, thighs) = (skin_of(&mesh, &figure, BodyRole::Pelvis), skin_of(&mesh, &figure, BodyRole::Thigh));
    for seat_height_m in [0.40f32, 0.45, 0.50] {
        let chair = Chair { seat_height_m, ..Chair::default() };
        let sized = run(&skeleton, chair, Some(&mesh), &[&buttocks, &thighs]);
        let from_skeleton = run(&skeleton, chair, None, &[&buttocks, &thighs]);
        println!("seat {seat_height_m:.2} m: sized {sized:?}\n  from the skeleton {from_skeleton:?}");
        let (above, back) = sized.seated_hips;
        // Seated over the seat: the hips a buttock's depth above its top (11–13 cm on the
        // Xbot's mesh), moved back past its front edge.
        assert!((0.0..0.15).contains(&above) && back > chair.behind_m - 0.05, "{sized:?}");
        let [buttocks_cm, thighs_cm] = sized.sunk_cm[..] else { unreachable!() };
        assert!(buttocks_cm < 1.0, "sized from the mesh, the buttocks go {buttocks_cm:.2} cm into the stool");
        let thighs_bound_cm = if seat_height_m < 0.5 { 1.0 } else { 1.5 };
        assert!(thighs_cm < thighs_bound_cm, "sized from the mesh, the thighs go {thighs_cm:.2} cm into the stool");
        // The measure sees the defect the sizing removes (5.0–5.2 cm on the 0.40 and 0.45 m
        // stools, 3.5 cm on the 0.50 m one).
        let skeleton_cm = from_skeleton.sunk_cm.iter().copied().fold(0.0, f64::max);
        assert!(skeleton_cm > 3.0, "sized from the skeleton, the skin goes only {skeleton_cm:.2} cm in");
    }
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
    let v = run(&cmu(&data), Chair::default(), None, &[]);
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

/// Runs `physics.simulate` on `clip` with `mesh` on its mesh input and a one-second script.
fn run_simulate_node(clip: Arc<Clip>, mesh: Mesh) -> Result<(), NodeError> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("script.ron"), "(duration_secs: 1.0)").unwrap();
    let inputs = vec![Some(Value::Clip(clip)), Some(Value::Mesh(Arc::new(mesh)))];
    eval_node("physics.simulate", inputs, &[("script", ParamValue::Text("script.ron".into()))], dir.path()).map(drop)
}

/// A mesh that cannot size the figure is an error on the node's mesh input, saying why.
#[test]
fn a_mesh_that_cannot_size_the_figure_names_the_mesh_input() {
    let Some(data) = shared_data() else { return };
    let character = load_character(&data.join("gltf/Xbot.glb"), 0).unwrap().value;
    let xbot_clip = Arc::new(character.clip.clone());
    let unskinned = Mesh { skin: None, ..character.mesh.clone() };
    let err = run_simulate_node(xbot_clip.clone(), unskinned).unwrap_err();
    assert!(matches!(&err, NodeError::Input { port: "mesh", message } if message.contains("not skinned")), "{err:?}");
    let (cmu_clip, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    let err = run_simulate_node(Arc::new(cmu_clip), character.mesh.clone()).unwrap_err();
    assert!(
        matches!(&err, NodeError::Input { port: "mesh", message } if message.contains("different skeleton")),
        "{err:?}"
    );
    // The Xbot's own mesh sizes its figure.
    run_simulate_node(xbot_clip, character.mesh).unwrap();
}
