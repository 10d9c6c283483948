//! `motion.quality` against answers known in closed form: hand-built clips of the
//! mannequin (whose toes stand on y = 0 in the rest pose) with one fault of known size
//! each, degenerate clips that must become findings, and a CMU clip checked against the
//! corpus' independent forward kinematics and a fault of known size injected into it.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use glam::Vec3;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::kernels::load::{ClipLoadOptions, load_clip};
use kinegraph_nodes::kernels::mannequin::{mannequin_mesh, mannequin_skeleton};
use kinegraph_nodes::kernels::quality::{QualityGate, QualityOptions, QualityReport, measure_quality};
use kinegraph_nodes::model::{Clip, Contacts, FootContacts, FrameRange, ImportScale, Joint, Skeleton};

const FPS: f64 = 30.0;

/// The mannequin in its rest pose, its root moved by `path(frame)` (metres).
fn mannequin_moving(frames: usize, path: impl Fn(usize) -> Vec3) -> Clip {
    let skeleton = Arc::new(mannequin_skeleton().unwrap());
    let rotations = (0..frames).flat_map(|_| skeleton.joints().iter().map(|j| j.rest_rotation)).collect();
    let path = &path;
    let translations = (0..frames)
        .flat_map(|f| {
            skeleton
                .joints()
                .iter()
                .map(move |j| if j.parent.is_none() { j.rest_offset + path(f) } else { j.rest_offset })
        })
        .collect();
    Clip::new(skeleton.clone(), FPS, rotations, translations, ImportScale::METRES).unwrap()
}

/// Contacts of the left foot over `left`, the right foot never down.
fn left_foot_down(clip: &Clip, left: Vec<FrameRange>) -> Contacts {
    Contacts {
        fps: clip.fps(),
        frame_count: clip.frame_count(),
        feet: vec![
            FootContacts { foot: "LeftFoot".into(), intervals: left },
            FootContacts { foot: "RightFoot".into(), intervals: Vec::new() },
        ],
        double_support: Vec::new(),
        hands: Vec::new(),
    }
}

fn measure(clip: &Clip, contacts: Option<&Contacts>, sources: &[&Clip]) -> QualityReport {
    measure_quality(clip, contacts, sources, None, &QualityOptions::default())
}

fn close(got: Option<f64>, want: f64, tolerance: f64) -> bool {
    got.is_some_and(|g| (g - want).abs() <= tolerance)
}

#[test]
fn a_foot_sliding_one_centimetre_a_frame_while_planted_skates_one_centimetre_a_frame() {
    // The body glides forward 1 cm per frame; only the left foot is planted, frames 5..25
    // and 30..36: it slides 19 cm in the first plant and 5 cm in the second.
    let clip = mannequin_moving(40, |f| Vec3::new(0.0, 0.0, 0.01 * f as f32));
    let contacts = left_foot_down(&clip, vec![FrameRange::new(5, 25), FrameRange::new(30, 36)]);
    let r = measure(&clip, Some(&contacts), &[]);
    let left = &r.feet[0];
    assert_eq!((left.foot.as_str(), left.contacts, left.contact_frame_pairs), ("LeftFoot", 2, 24));
    assert!((left.skate_mean_cm_per_frame - 1.0).abs() < 1e-4, "{left:?}");
    assert!((left.skate_max_cm_per_frame - 1.0).abs() < 1e-4, "{left:?}");
    assert!((left.skate_total_cm - 24.0).abs() < 1e-3, "{left:?}");
    assert!((left.contact_slide_max_cm - 19.0).abs() < 1e-3, "{left:?}");
    assert_eq!(left.contact_slide_max_frames, Some((5, 25)));
    assert_eq!((r.feet[1].contact_frame_pairs, r.feet[1].skate_total_cm), (0, 0.0));
    assert!(r.feet[1].skate_total_cm.is_sign_positive(), "a report shows 0, not -0");
    assert!(close(r.summary.skate_max_cm_per_frame, 1.0, 1e-4), "{:?}", r.summary);
    assert!(close(r.summary.contact_slide_max_cm, 19.0, 1e-3), "{:?}", r.summary);
    assert_eq!(r.contacts, "connected");
    // At 0.3 m/s the detector plants both feet too; the skate it then measures is the same.
    let detected = measure(&clip, None, &[]);
    assert_eq!(detected.contacts, "detected");
    assert!(detected.feet.iter().all(|f| f.contact_frame_pairs > 0), "{:?}", detected.feet);
    assert!(close(detected.summary.skate_max_cm_per_frame, 1.0, 1e-4), "{:?}", detected.summary);
    // A foot standing still does not skate.
    let still = mannequin_moving(40, |_| Vec3::ZERO);
    assert!(close(measure(&still, Some(&contacts), &[]).summary.skate_max_cm_per_frame, 0.0, 1e-9));
}

#[test]
fn a_foot_rolling_over_its_toe_keeps_one_point_still_and_does_not_skate() {
    // The left leg turns about the toe tip: the ankle travels, the toe stays put.
    let skeleton = Arc::new(mannequin_skeleton().unwrap());
    let hips = skeleton.joints()[0].rest_offset;
    let frames = 20;
    let mut rotations = Vec::new();
    let mut translations = Vec::new();
    for f in 0..frames {
        // Whole body turned about the X axis through the left toe tip (rest (0.09, 0, 0.14)).
        let turn = glam::Quat::from_rotation_x(0.05 * f as f32);
        let pivot = Vec3::new(0.09, 0.0, 0.14);
        for j in skeleton.joints() {
            rotations.push(if j.parent.is_none() { turn } else { j.rest_rotation });
            translations.push(if j.parent.is_none() { pivot + turn * (hips - pivot) } else { j.rest_offset });
        }
    }
    let clip = Clip::new(skeleton, FPS, rotations, translations, ImportScale::METRES).unwrap();
    let r = measure(&clip, Some(&left_foot_down(&clip, vec![FrameRange::new(0, frames)])), &[]);
    assert!(r.feet[0].skate_max_cm_per_frame < 1e-4, "{:?}", r.feet[0]);
}

#[test]
fn a_foot_three_centimetres_under_the_floor_penetrates_three_centimetres() {
    // Frames 10..20 the whole body is 3 cm low: the toe tips (at the floor in the rest pose)
    // are 3 cm under it.
    let clip = mannequin_moving(30, |f| if (10..20).contains(&f) { Vec3::new(0.0, -0.03, 0.0) } else { Vec3::ZERO });
    let r = measure(&clip, Some(&left_foot_down(&clip, vec![FrameRange::new(0, 30)])), &[]);
    assert!(close(r.summary.penetration_max_cm, 3.0, 1e-4), "{:?}", r.summary);
    assert_eq!(r.summary.frames_below_floor, Some(10));
    assert!((r.longest_below_floor_secs - 10.0 / FPS).abs() < 1e-9);
    assert!(r.feet.iter().all(|f| (f.penetration_max_cm - 3.0).abs() < 1e-4 && f.frames_below_floor == 10));
    assert!(r.findings.iter().any(|f| f.contains("under the floor by up to 3.0 cm")), "{:?}", r.findings);
    // The same clip over a floor 3 cm lower stands on it.
    let lower = QualityOptions { floor_height_m: -0.03, ..QualityOptions::default() };
    let r = measure_quality(&clip, None, &[], None, &lower);
    assert!(close(r.summary.penetration_max_cm, 0.0, 1e-4), "{:?}", r.summary);
    assert_eq!(r.summary.frames_below_floor, Some(0));
}

#[test]
fn a_skinned_mesh_puts_the_soles_where_its_lowest_vertices_are() {
    // The mannequin's box mesh is bound in the rest pose, where its lowest vertices (the
    // boxes round the toes) hang below the toe joints on the floor: the soles are under the
    // floor by exactly the mesh's lowest point, and 1 cm more with the body 1 cm lower.
    let clip = mannequin_moving(10, |f| if f >= 5 { Vec3::new(0.0, -0.01, 0.0) } else { Vec3::ZERO });
    let mesh = mannequin_mesh(clip.skeleton().clone(), 0.04);
    let (lowest, _) = mesh.bounds().unwrap();
    assert!(lowest.y < 0.0);
    let r = measure_quality(&clip, None, &[], Some(&mesh), &QualityOptions::default());
    let want = -f64::from(lowest.y) * 100.0 + 1.0;
    assert!(close(r.summary.penetration_max_cm, want, 1e-3), "{:?} vs {want}", r.summary);
    assert_eq!(r.summary.frames_below_floor, Some(10));
    assert!(r.feet.iter().all(|f| f.sole_from_mesh && (f.penetration_max_cm - want).abs() < 1e-3), "{:?}", r.feet);
    // Joints alone stand 1 cm under the floor in the lowered frames only.
    let joints = measure(&clip, None, &[]);
    assert!(close(joints.summary.penetration_max_cm, 1.0, 1e-4), "{:?}", joints.summary);
    assert_eq!(joints.summary.frames_below_floor, Some(5));
    // A mesh on another skeleton is a finding, and the joints are measured.
    let other = mannequin_mesh(Arc::new(Skeleton::new(vec![Joint::new("a", None, Vec3::ZERO)]).unwrap()), 0.04);
    let r = measure_quality(&clip, None, &[], Some(&other), &QualityOptions::default());
    assert!(r.findings.iter().any(|f| f.contains("soles are not measured")), "{:?}", r.findings);
    assert!(close(r.summary.penetration_max_cm, 1.0, 1e-4), "{:?}", r.summary);
}

#[test]
fn a_planted_foot_hovering_two_centimetres_floats_two_centimetres() {
    let clip = mannequin_moving(30, |f| if f < 15 { Vec3::new(0.0, 0.02, 0.0) } else { Vec3::ZERO });
    // One contact fully in the air, one through the landing: only the first floats.
    let contacts = left_foot_down(&clip, vec![FrameRange::new(2, 12), FrameRange::new(12, 25)]);
    let r = measure(&clip, Some(&contacts), &[]);
    assert!((r.feet[0].float_in_contact_max_cm - 2.0).abs() < 1e-4, "{:?}", r.feet[0]);
    assert_eq!(r.feet[1].float_in_contact_max_cm, 0.0);
}

/// The root accelerating at `a` m/s² along X (p = ½ a t²), its velocity stepping up by
/// `kick` m/s at frame `at`.
fn accelerating(frames: usize, a: f64, kick: f64, at: usize) -> Clip {
    mannequin_moving(frames, move |f| {
        let t = f as f64 / FPS;
        let after = f.saturating_sub(at) as f64 / FPS;
        Vec3::new((0.5 * a * t * t + kick * after) as f32, 0.0, 0.0)
    })
}

#[test]
fn a_single_acceleration_spike_is_its_size_over_the_steady_acceleration_around_it() {
    // Second differences: a everywhere, a + kick·fps at the kick; the root's velocity
    // changes by a/fps per frame, by a/fps + kick at the kick.
    let (a, kick, at) = (2.0, 0.1, 20);
    let clip = accelerating(41, a, kick, at);
    let source = accelerating(41, a, 0.0, at);
    let r = measure(&clip, None, &[&source]);
    let spike = a + kick * FPS;
    let s = &r.summary;
    assert!(close(s.acceleration_peak_mps2, spike, 0.02 * spike), "{s:?}");
    assert_eq!(r.acceleration_peak_at.as_ref().map(|p| p.0), Some(at));
    assert!(close(s.acceleration_spike_ratio, spike / a, 0.02 * spike / a), "{s:?}");
    assert_eq!(r.acceleration_spike_frame, Some(at));
    assert!(close(r.sources_acceleration_peak_mps2, a, 0.02 * a), "{r:?}");
    assert!(close(s.acceleration_over_sources, spike / a, 0.03 * spike / a), "{s:?}");
    let step = a / FPS + kick;
    assert!(close(s.root_velocity_change_max_mps, step, 0.02 * step), "{s:?}");
    assert_eq!(r.root_velocity_change_frame, Some(at));
    assert!(close(s.root_velocity_change_over_sources, step / (a / FPS), 0.03 * step / (a / FPS)), "{s:?}");
    // No spike, no pop and no drift in the smooth source.
    let smooth = measure(&source, None, &[]);
    assert!(close(smooth.summary.acceleration_spike_ratio, 1.0, 0.02), "{:?}", smooth.summary);
    assert_eq!(smooth.summary.pop_frames, Some(0));
    assert!(close(smooth.summary.bone_length_drift_max_cm, 0.0, 1e-3), "{:?}", smooth.summary);
}

#[test]
fn a_window_looks_only_at_its_frames_and_still_sees_around_them() {
    let (a, kick, at) = (2.0, 0.1, 20);
    let clip = accelerating(41, a, kick, at);
    let within = |first: usize, last: usize| QualityOptions {
        window_secs: Some((first as f64 / FPS, last as f64 / FPS)),
        ..QualityOptions::default()
    };
    // Frames 0..=15 miss the kick: the steady acceleration alone.
    let before = measure_quality(&clip, None, &[], None, &within(0, 15));
    assert_eq!(before.window_frames, (0, 16));
    assert!(close(before.summary.acceleration_peak_mps2, a, 0.02 * a), "{:?}", before.summary);
    assert!(close(before.summary.acceleration_spike_ratio, 1.0, 0.02), "{:?}", before.summary);
    assert!(close(before.summary.root_velocity_change_max_mps, a / FPS, 0.02 * a / FPS), "{:?}", before.summary);
    // Frames 19..=21 hold it, and its neighbourhood still reaches outside the window.
    let around = measure_quality(&clip, None, &[], None, &within(19, 21));
    assert_eq!(around.acceleration_spike_frame, Some(at));
    assert!(close(around.summary.acceleration_spike_ratio, (a + kick * FPS) / a, 0.05), "{:?}", around.summary);
    // Contacts are cut to the window: 1 cm a frame over frames 10..=14 is a 4 cm slide.
    let gliding = mannequin_moving(40, |f| Vec3::new(0.0, 0.0, 0.01 * f as f32));
    let contacts = left_foot_down(&gliding, vec![FrameRange::new(5, 25)]);
    let r = measure_quality(&gliding, Some(&contacts), &[], None, &within(10, 14));
    assert!((r.feet[0].contact_slide_max_cm - 4.0).abs() < 1e-3, "{:?}", r.feet[0]);
    assert_eq!(r.feet[0].contact_slide_max_frames, Some((10, 15)));
    // A window past the clip's end looks at nothing, and says so.
    let past = measure_quality(&gliding, None, &[], None, &within(50, 60));
    assert_eq!((past.window_frames, past.summary.acceleration_peak_mps2), ((40, 40), None));
    assert!(past.findings.iter().any(|f| f.contains("window holds no frame")), "{:?}", past.findings);
}

#[test]
fn a_teleporting_root_is_a_finding_with_its_size_and_frame() {
    // The root stands, then is 0.5 m further along X from frame 12 on.
    let (jump, at) = (0.5, 12);
    let clip = mannequin_moving(30, |f| if f >= at { Vec3::new(jump as f32, 0.0, 0.0) } else { Vec3::ZERO });
    let r = measure(&clip, None, &[]);
    let s = &r.summary;
    assert!(close(s.root_velocity_change_max_mps, jump * FPS, 1e-3 * jump * FPS), "{s:?}");
    assert_eq!(r.root_velocity_change_frame, Some(at - 1));
    assert!(close(s.acceleration_peak_mps2, jump * FPS * FPS, 1e-3 * jump * FPS * FPS), "{s:?}");
    assert_eq!(s.pop_frames, Some(1));
    let pop = r.findings.iter().find(|f| f.contains("pop")).unwrap_or_else(|| panic!("{:?}", r.findings));
    assert!(pop.contains("50.0 cm into frame 12"), "{pop}");
    let gate: QualityGate = ron::from_str("(max_pop_frames: 0, max_root_velocity_change_mps: 2.0)").unwrap();
    let broken = gate.violations(s);
    assert_eq!(broken.len(), 2, "{broken:?}");
    assert!(broken[0].starts_with("root_velocity_change_max_mps = 15 m/s, above max_root_velocity_change_mps 2"));
    assert!(broken[1].starts_with("pop_frames = 1, above max_pop_frames 0"), "{broken:?}");
}

/// A body that stands and starts moving in the clip's last frame (a toe-off cut there) has
/// no move after it to compare with: not a pop. The same start followed by a stop one frame
/// later, inside the clip, is one.
#[test]
fn a_start_in_the_last_frame_is_not_a_pop_and_the_same_move_inside_is() {
    let step = |frames: usize, at: usize| {
        mannequin_moving(frames, move |f| Vec3::new(if f >= at { 0.05 } else { 0.0 }, 0.0, 0.0))
    };
    let at_end = measure(&step(20, 19), None, &[]);
    assert_eq!(at_end.summary.pop_frames, Some(0), "{:?}", at_end.findings);
    let inside = measure(&step(21, 19), None, &[]);
    assert_eq!(inside.summary.pop_frames, Some(1), "{:?}", inside.findings);
    assert!(inside.findings.iter().any(|f| f.contains("5.0 cm into frame 19")), "{:?}", inside.findings);
}

#[test]
fn a_stretching_bone_drifts_by_its_stretch() {
    let mut clip = mannequin_moving(10, |_| Vec3::ZERO);
    let skeleton = clip.skeleton().clone();
    let shin = skeleton.index_of("LeftFoot").unwrap();
    let mut translations = clip.translations().to_vec();
    // Frame 6 the shin is 4 cm longer.
    translations[6 * skeleton.len() + shin] += Vec3::new(0.0, -0.04, 0.0);
    clip = Clip::new(skeleton, FPS, clip.rotations().to_vec(), translations, ImportScale::METRES).unwrap();
    let r = measure(&clip, None, &[]);
    assert!(close(r.summary.bone_length_drift_max_cm, 4.0, 1e-4), "{:?}", r.summary);
    assert_eq!(r.bone_length_drift_joint.as_deref(), Some("LeftFoot"));
}

#[test]
fn clips_without_contacts_frames_or_feet_are_findings_not_panics() {
    // Running at 3 m/s: the feet move too fast to ever plant.
    let running = mannequin_moving(30, |f| Vec3::new(0.0, 0.0, 0.1 * f as f32));
    let r = measure(&running, None, &[]);
    assert!(r.feet.iter().all(|f| f.contacts == 0), "{:?}", r.feet);
    assert_eq!(r.summary.skate_max_cm_per_frame, Some(0.0));
    assert!(r.findings.iter().any(|f| f.contains("no foot contacts")), "{:?}", r.findings);

    let single = mannequin_moving(1, |_| Vec3::new(0.0, -0.05, 0.0));
    let r = measure(&single, None, &[&running]);
    assert!(close(r.summary.penetration_max_cm, 5.0, 1e-4), "{:?}", r.summary);
    assert_eq!(
        (r.summary.acceleration_peak_mps2, r.summary.pop_frames, r.summary.acceleration_over_sources),
        (None, None, None)
    );
    assert!(r.findings.iter().any(|f| f.contains("single frame")), "{:?}", r.findings);

    let empty = mannequin_moving(0, |_| Vec3::ZERO);
    let r = measure(&empty, None, &[&empty]);
    assert_eq!(r.summary.bone_length_drift_max_cm, None);
    assert!(r.findings.iter().any(|f| f.contains("no frames")), "{:?}", r.findings);
    assert!(serde_json::to_value(&r).is_ok());

    // A rod has no feet: the feet's measures are missing and a gate on them fails.
    let rod =
        Arc::new(Skeleton::new(vec![Joint::new("a", None, Vec3::ZERO), Joint::new("b", Some(0), Vec3::Y)]).unwrap());
    let r = measure(&Clip::rest_pose(rod, FPS, 5).unwrap(), None, &[]);
    assert_eq!((r.contacts, r.summary.skate_max_cm_per_frame), ("none", None));
    assert!(r.findings.iter().any(|f| f.contains("feet could not be found")), "{:?}", r.findings);
    let gate: QualityGate = ron::from_str("(max_skate_cm: 0.5)").unwrap();
    assert!(gate.violations(&r.summary)[0].contains("not measured"));

    // Contacts of another clip are not trusted.
    let other = left_foot_down(&running.slice(0, 10), vec![FrameRange::new(0, 10)]);
    let r = measure(&running, Some(&other), &[]);
    assert_eq!(r.contacts, "detected");
    assert!(r.findings.iter().any(|f| f.contains("cover 10 frames but the clip has 30")), "{:?}", r.findings);
}

#[test]
fn gates_parse_bare_numbers_refuse_unknown_limits_and_pass_within_them() {
    let gate: QualityGate = ron::from_str("(max_skate_cm: 0.5, max_penetration_cm: 1)").unwrap();
    assert_eq!((gate.max_skate_cm, gate.max_penetration_cm, gate.max_float_cm), (Some(0.5), Some(1.0), None));
    assert!(ron::from_str::<QualityGate>("(max_skate: 0.5)").is_err());
    let clip = mannequin_moving(40, |f| Vec3::new(0.0, 0.0, 0.004 * f as f32));
    let r = measure(&clip, Some(&left_foot_down(&clip, vec![FrameRange::new(0, 40)])), &[]);
    assert!(gate.violations(&r.summary).is_empty(), "{:?}", r.summary);
    let strict: QualityGate = ron::from_str("(max_skate_cm: 0.3)").unwrap();
    assert_eq!(strict.violations(&r.summary), vec!["skate_max_cm_per_frame = 0.4 cm/frame, above max_skate_cm 0.3"]);
    // Written back, a gate keeps its bare numbers.
    assert_eq!(ron::to_string(&strict).unwrap(), "(max_skate_cm:0.3)");
}

#[test]
fn on_a_cmu_walk_the_floor_matches_independent_kinematics_and_an_injected_kink_is_found() {
    let Some(data) = shared_data() else { return };
    // World positions of every joint at a few frames from an independent implementation
    // (shared/data/reference/README.md), in file units.
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("reference/cmu_02_02.fk.json")).unwrap()).unwrap();
    let clip = load_clip(&data.join(r["source"].as_str().unwrap()), ClipLoadOptions::default()).unwrap().value;
    let joints: Vec<&str> = r["joints"].as_array().unwrap().iter().map(|j| j.as_str().unwrap()).collect();
    let scale = clip.import_scale.metres_per_unit;
    // A floor 20 cm up puts every foot under it: each foot's depth is 20 cm minus its
    // lowest joint (ankle, toe, toe tip) in the independent implementation's positions.
    let floor = QualityOptions { floor_height_m: 0.2, ..QualityOptions::default() };
    for (fi, frame) in r["frames"].as_array().unwrap().iter().enumerate() {
        let frame = frame.as_u64().unwrap() as usize;
        let single = clip.slice(frame, frame + 1);
        let got = measure_quality(&single, None, &[], None, &floor);
        for (k, side) in ["Left", "Right"].iter().enumerate() {
            let lowest = ["Foot", "ToeBase", "ToeBase_EndSite"]
                .iter()
                .map(|part| {
                    let j = joints.iter().position(|n| *n == format!("{side}{part}")).unwrap();
                    r["positions"][fi][j][1].as_f64().unwrap() * scale
                })
                .fold(f64::INFINITY, f64::min);
            let want_cm = (0.2 - lowest) * 100.0;
            let foot = &got.feet[k];
            assert_eq!(foot.foot, format!("{side}Foot"));
            assert!((foot.penetration_max_cm - want_cm).abs() < 0.05, "frame {frame} {side}: {foot:?} vs {want_cm}");
        }
    }

    // A 10 m/s push of the root at frame 150 of the walk (frames 1.. skip the T-pose): the
    // root's one-frame velocity change there is 10 m/s give or take the walk's own largest
    // (1.46 m/s: the capture has a glitch near its end), and it is the clip's worst spike.
    let walk = clip.slice(1, clip.frame_count());
    let own = measure(&walk, None, &[]);
    let own_largest = own.summary.root_velocity_change_max_mps.unwrap();
    assert!(own_largest < 2.0, "{:?}", own.summary);
    let (kick, at) = (10.0f32, 150usize);
    let n = walk.joint_count();
    let mut translations = walk.translations().to_vec();
    for f in at + 1..walk.frame_count() {
        translations[f * n].x += kick * (f - at) as f32 / walk.fps() as f32;
    }
    let pushed =
        Clip::new(walk.skeleton().clone(), walk.fps(), walk.rotations().to_vec(), translations, walk.import_scale)
            .unwrap();
    let got = measure(&pushed, None, &[&walk]);
    let change = got.summary.root_velocity_change_max_mps.unwrap();
    assert!((change - f64::from(kick)).abs() <= own_largest, "{change} vs {kick} ± {own_largest}");
    assert_eq!(got.root_velocity_change_frame, Some(at));
    let over = got.summary.root_velocity_change_over_sources.unwrap();
    assert!((over - change / own_largest).abs() < 1e-9, "{over}");
    assert_eq!(got.acceleration_spike_frame, Some(at));
    assert!(got.summary.acceleration_over_sources.unwrap() > 1.0, "{:?}", got.summary);
}

/// A walk built by hand on the mannequin (legs 0.42 + 0.42 m, hips 0.09 m either side) at
/// 60 fps: nine plants alternating left, right, … 0.7 m apart along Z, plant `i` centred
/// on frame 30 i + 15 (25 frames, contacts connected), so each step spans 0.7 m forward
/// and 0.18 m across: √(0.7² + 0.18²) = 0.7228 m, 0.8604 legs. The hips travel
/// z(t) = 1.4 t + 0.02 sin(4π t): speed 1.4 + 0.02·4π cos(4π t) m/s. Over a centred
/// 0.1 s difference (±3 frames) a cosine of angular rate ω keeps its phase and shrinks by
/// sin(0.05 ω)/(0.05 ω); the 270 frames measured (3..273, nine periods of 30 frames) hold
/// each of the 30 phases 2πk/30 nine times, so sorted ascending the lowest phase (k = 15,
/// cos −1) fills ranks 0–8 and the next (k = 14, 16, cos −cos(π/15)) ranks 9–26: the 5th
/// percentile (rank 13.45) is 1.4 − A cos(π/15), and likewise the 95th (rank 255.55)
/// 1.4 + A cos(π/15), with A = 0.02·4π · sin(0.2π)/(0.2π).
#[test]
fn a_hand_built_walk_has_its_step_length_and_pelvis_speed_range() {
    use std::f64::consts::PI;
    let skeleton = Arc::new(mannequin_skeleton().unwrap());
    let (fps, frames, step_m, speed) = (60.0, 276usize, 0.7f64, 1.4f64);
    let index = |n: &str| skeleton.index_of(n).unwrap();
    let (left, right) = (index("LeftFoot"), index("RightFoot"));
    let hips_z = |f: usize| {
        let t = f as f64 / fps;
        speed * t + 0.02 * (4.0 * PI * t).sin()
    };
    let plants: Vec<(usize, usize, f64)> = (0..9).map(|i| (i % 2, 30 * i + 15, step_m * i as f64)).collect();
    let mut translations = Vec::new();
    for f in 0..frames {
        for (j, joint) in skeleton.joints().iter().enumerate() {
            let mut t = joint.rest_offset;
            if j == 0 {
                t.z += hips_z(f) as f32;
            }
            for (side, ankle) in [left, right].into_iter().enumerate() {
                if j == ankle {
                    // The foot stands at its nearest plant, whatever the hips do.
                    let (_, _, z) = *plants.iter().filter(|p| p.0 == side).min_by_key(|p| p.1.abs_diff(f)).unwrap();
                    t.z = (z - hips_z(f)) as f32;
                }
            }
            translations.push(t);
        }
    }
    let rotations = vec![glam::Quat::IDENTITY; frames * skeleton.len()];
    let clip = Clip::new(skeleton.clone(), fps, rotations, translations, ImportScale::METRES).unwrap();
    let intervals = |side: usize| {
        plants.iter().filter(|p| p.0 == side).map(|p| FrameRange::new(p.1 - 12, p.1 + 13)).collect::<Vec<_>>()
    };
    let contacts = Contacts {
        fps,
        frame_count: frames,
        feet: vec![
            FootContacts { foot: "LeftFoot".into(), intervals: intervals(0) },
            FootContacts { foot: "RightFoot".into(), intervals: intervals(1) },
        ],
        double_support: Vec::new(),
        hands: Vec::new(),
    };
    let r = measure_quality(&clip, Some(&contacts), &[], None, &QualityOptions::default());
    let stride = r.stride.as_ref().unwrap();
    let step = (step_m * step_m + 0.18 * 0.18).sqrt();
    let amplitude = 0.02 * 4.0 * PI * (0.2 * PI).sin() / (0.2 * PI) * (PI / 15.0).cos();
    println!("{stride:?}; want step {step:.4} m, pelvis {:.4}–{:.4} m/s", speed - amplitude, speed + amplitude);
    assert!((stride.leg_length_m - 0.84).abs() < 1e-6, "{stride:?}");
    assert_eq!(stride.steps, 8);
    assert!(close(stride.step_length_m, step, 1e-5), "{stride:?}");
    assert!(close(stride.step_over_leg, step / 0.84, 1e-5), "{stride:?}");
    assert!(close(r.summary.step_over_leg, step / 0.84, 1e-5), "{:?}", r.summary);
    assert!(close(stride.pelvis_speed_low_mps, speed - amplitude, 1e-4), "{stride:?}");
    assert!(close(stride.pelvis_speed_high_mps, speed + amplitude, 1e-4), "{stride:?}");
    // Without a source there is nothing to compare with, and a gate on it fails.
    assert!(r.stride_against_source.is_none() && r.summary.step_over_leg_change_pct.is_none());
    let gate: QualityGate = ron::from_str("(max_step_ratio_change_pct: 10)").unwrap();
    assert_eq!(
        gate.violations(&r.summary),
        vec![
            "step_over_leg_change_pct was not measured (see the report's findings), so max_step_ratio_change_pct fails"
        ]
    );
}

/// Contacts found in the test itself on a clip's joint positions: frames where the ankle
/// is within 5 cm of its lowest and moves slower than 0.4 m/s horizontally (one-frame
/// centred difference), in runs of at least 10 frames; each plant at the ankle's mean
/// horizontal position over its run. Returns (start frame, foot, x, z) per plant.
fn threshold_plants(clip: &Clip, ankles: [usize; 2]) -> Vec<(usize, usize, f64, f64)> {
    let poses = kinegraph_nodes::model::forward_kinematics(clip);
    let n = clip.frame_count();
    let mut plants = Vec::new();
    for (side, ankle) in ankles.into_iter().enumerate() {
        let p: Vec<glam::DVec3> = (0..n).map(|f| poses.position(f, ankle).as_dvec3()).collect();
        let lowest = p.iter().map(|q| q.y).fold(f64::INFINITY, f64::min);
        let planted = |f: usize| {
            let (a, b) = (p[f.saturating_sub(1)], p[(f + 1).min(n - 1)]);
            let span = ((f + 1).min(n - 1) - f.saturating_sub(1)) as f64 / clip.fps();
            let horizontal = glam::DVec2::new(b.x - a.x, b.z - a.z).length() / span;
            p[f].y < lowest + 0.05 && horizontal < 0.4
        };
        let mut f = 0;
        while f < n {
            let start = f;
            while f < n && planted(f) {
                f += 1;
            }
            if f - start >= 10 {
                let mean = p[start..f].iter().fold(glam::DVec3::ZERO, |s, q| s + *q) / (f - start) as f64;
                plants.push((start, side, mean.x, mean.z));
            }
            f += 1;
        }
    }
    plants.sort_by_key(|p| (p.0, p.1));
    plants
}

/// CMU 02_01 (the walk graphs/walk_on_xbot.ron carries), its T-pose frame cut: the step
/// length `motion.quality` measures from its detected contacts matches the one found here
/// by another route (threshold contacts and mean plant positions, above) within 2 cm, a
/// thirtieth of a step; the leg length is the rest offsets' lengths (knee and ankle
/// offsets) to 1e-6 m; the pelvis speed range matches the root joint's own translations
/// differenced over ±6 frames (0.1 s at 120 fps) and ranked by nearest rank within 0.01
/// m/s. The same walk on a skeleton 1.2 times larger, against the original as its source,
/// keeps its step ÷ leg within 2 % and its pelvis speed inside the source's range scaled
/// by 1.2 within 1 %.
#[test]
fn on_a_cmu_walk_the_stride_matches_one_measured_another_way() {
    let Some(data) = shared_data() else { return };
    let clip = load_clip(&data.join("bvh/cmu/02_01.bvh"), ClipLoadOptions::default()).unwrap().value;
    let walk = clip.slice(1, clip.frame_count());
    let r = measure(&walk, None, &[]);
    let stride = r.stride.clone().unwrap();
    let skeleton = walk.skeleton();
    let joint = |n: &str| skeleton.index_of(n).unwrap();
    let offset = |n: &str| f64::from(skeleton.joints()[joint(n)].rest_offset.length());
    let leg = 0.5 * (offset("LeftLeg") + offset("LeftFoot") + offset("RightLeg") + offset("RightFoot"));
    let plants = threshold_plants(&walk, [joint("LeftFoot"), joint("RightFoot")]);
    let steps: Vec<f64> = plants
        .windows(2)
        .filter(|w| w[0].1 != w[1].1)
        .map(|w| ((w[0].2 - w[1].2).powi(2) + (w[0].3 - w[1].3).powi(2)).sqrt())
        .collect();
    let step = steps.iter().sum::<f64>() / steps.len() as f64;
    let n = walk.joint_count();
    let half = 6;
    let mut speeds: Vec<f64> = (half..walk.frame_count() - half)
        .map(|f| {
            let (a, b) = (walk.translations()[(f - half) * n], walk.translations()[(f + half) * n]);
            f64::from(glam::Vec2::new(b.x - a.x, b.z - a.z).length()) * walk.fps() / (2 * half) as f64
        })
        .collect();
    speeds.sort_by(f64::total_cmp);
    let rank = |p: f64| speeds[((p / 100.0 * speeds.len() as f64).ceil() as usize).saturating_sub(1)];
    println!(
        "kernel {stride:?}\nhere: leg {leg:.4} m, {} steps {step:.4} m ({steps:.3?}), pelvis {:.3}–{:.3} m/s",
        steps.len(),
        rank(5.0),
        rank(95.0)
    );
    assert!((stride.leg_length_m - leg).abs() < 1e-6, "{leg}");
    assert!(close(stride.step_length_m, step, 0.02), "{step}");
    assert!(close(stride.pelvis_speed_low_mps, rank(5.0), 0.01));
    assert!(close(stride.pelvis_speed_high_mps, rank(95.0), 0.01));

    let big = Arc::new(skeleton.scaled(1.2).unwrap());
    let translations = walk.translations().iter().map(|t| *t * 1.2).collect();
    let scaled = Clip::new(big, walk.fps(), walk.rotations().to_vec(), translations, walk.import_scale).unwrap();
    let r = measure(&scaled, None, &[&walk]);
    let against = r.stride_against_source.clone().unwrap();
    println!("scaled 1.2: {:?}\n{against:?}", r.stride);
    assert!((against.leg_length_ratio - 1.2).abs() < 1e-5, "{against:?}");
    assert!(r.summary.step_over_leg_change_pct.unwrap() < 2.0, "{against:?}");
    assert!(r.summary.pelvis_speed_outside_source_pct.unwrap() < 1.0, "{against:?}");
}

#[test]
fn a_rigs_fingers_are_left_out_when_it_is_compared_with_its_sources() {
    use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf_file};
    use kinegraph_nodes::kernels::quality::body_joints;
    use kinegraph_nodes::kernels::roles::rest_roles;
    let Some(data) = shared_data() else { return };
    // The body is read from the shape; checked here by the joints' names instead: Mixamo's
    // fingers are `mixamorig:{Left,Right}Hand{Thumb,Index,Middle,Ring,Pinky}{1..4}`, CMU's
    // `*FingerBase`, `*HandIndex1`, `LThumb`/`RThumb` and the end sites below them.
    let xbot = read_gltf_file(&data.join("gltf/Xbot.glb"), &GltfReadOptions::default()).unwrap().value;
    let cmu = load_clip(&data.join("bvh/cmu/02_01.bvh"), ClipLoadOptions::default()).unwrap().value;
    let finger_words = ["Thumb", "Index", "Middle", "Ring", "Pinky", "Finger"];
    for skeleton in [xbot.clips[0].clip.skeleton(), cmu.skeleton()] {
        let roles = rest_roles(skeleton);
        assert!(roles.is_ok(), "{roles:?}");
        let body = body_joints(skeleton, &roles.unwrap());
        let fingers = skeleton.joints().iter().filter(|j| finger_words.iter().any(|w| j.name.contains(w))).count();
        assert!(fingers >= 4, "{fingers}");
        for (joint, &in_body) in skeleton.joints().iter().zip(&body) {
            let finger = finger_words.iter().any(|w| joint.name.contains(w));
            assert_eq!(in_body, !finger, "{}", joint.name);
        }
    }
}
