//! BVH export options (issue 18): unit, frame rate, End Sites and the zero root OFFSET,
//! checked by reading the written file back and by parsing its text independently, on a
//! real CMU walk and on the procedural gait.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use kinegraph_nodes::builtin::ik::gait::{GaitParams, procedural_gait};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{
    BvhReadOptions, BvhUnit, BvhWriteOptions, read_bvh, read_bvh_file, write_bvh_with,
};
use kinegraph_nodes::kernels::mannequin::mannequin_skeleton;
use kinegraph_nodes::kernels::resample::resample;
use kinegraph_nodes::model::{Clip, Skeleton, forward_kinematics};

fn cmu_walk() -> Option<(Clip, String)> {
    let data = shared_data()?;
    let path = data.join("bvh/cmu/02_01.bvh");
    let clip = read_bvh_file(&path, BvhReadOptions::default()).unwrap_or_else(|e| panic!("{e}")).value.0;
    Some((clip, std::fs::read_to_string(&path).unwrap()))
}

fn gait_clip() -> Clip {
    let skeleton = Arc::new(mannequin_skeleton().unwrap());
    procedural_gait(&skeleton, &GaitParams { duration_secs: 2.0, ..Default::default() }).unwrap().clip
}

fn write(clip: &Clip, unit: BvhUnit) -> String {
    write_bvh_with(clip, BvhWriteOptions { unit }).value
}

/// Reads `text` back with the unit given explicitly (no detection).
fn read_back(text: &str, metres_per_unit: f64) -> Clip {
    let options = BvhReadOptions { metres_per_unit: Some(metres_per_unit) };
    read_bvh(text.as_bytes(), Path::new("written.bvh"), options).unwrap_or_else(|e| panic!("{e}")).value.0
}

/// Largest distance (m) between the world positions of the same joints, frame `f` of `b`
/// against frame `map(f)` of `a`.
fn worst_fk_error(a: &Clip, b: &Clip, map: impl Fn(usize) -> usize) -> f32 {
    let (pa, pb) = (forward_kinematics(a), forward_kinematics(b));
    let mut worst = 0.0f32;
    for f in 0..b.frame_count() {
        for (ta, tb) in pa.frame(map(f)).iter().zip(pb.frame(f)) {
            worst = worst.max((ta.translation - tb.translation).length());
        }
    }
    worst
}

/// What a plain-text reader sees of the written file: the ROOT's OFFSET, its channel
/// names, and the first frame row (all in file units).
struct Text {
    root_offset: [f64; 3],
    root_channels: Vec<String>,
    first_row: Vec<f64>,
    frames: usize,
    frame_time: f64,
}

fn parse_text(text: &str) -> Text {
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let root = lines.iter().position(|l| l.starts_with("ROOT ")).expect("a ROOT line");
    let numbers = |l: &str| -> Vec<f64> { l.split_whitespace().filter_map(|w| w.parse().ok()).collect() };
    let offset_line = lines[root + 1..].iter().find(|l| l.starts_with("OFFSET")).unwrap();
    let o = numbers(offset_line);
    let channels_line = lines[root + 1..].iter().find(|l| l.starts_with("CHANNELS")).unwrap();
    let root_channels = channels_line.split_whitespace().skip(2).map(str::to_string).collect();
    let frames_at = lines.iter().position(|l| l.starts_with("Frames:")).unwrap();
    let frames = lines[frames_at].trim_start_matches("Frames:").trim().parse().unwrap();
    let frame_time = lines[frames_at + 1].trim_start_matches("Frame Time:").trim().parse().unwrap();
    Text {
        root_offset: [o[0], o[1], o[2]],
        root_channels,
        first_row: numbers(lines[frames_at + 2]),
        frames,
        frame_time,
    }
}

/// The text's root OFFSET is 0 0 0, and the first frame's root position channels are the
/// clip's root world position at frame 0 in the file's unit, so a reader adding the
/// OFFSET and one replacing it agree.
fn check_root_text(clip: &Clip, text: &str, metres_per_unit: f64, what: &str) {
    let t = parse_text(text);
    assert_eq!(t.root_offset, [0.0; 3], "{what}: root OFFSET");
    let root_world = forward_kinematics(clip).position(0, 0);
    let mut seen = 0;
    for (i, name) in t.root_channels.iter().enumerate() {
        let axis = match name.as_str() {
            "Xposition" => 0,
            "Yposition" => 1,
            "Zposition" => 2,
            _ => continue,
        };
        seen += 1;
        let in_metres = t.first_row[i] * metres_per_unit;
        let err = (in_metres - f64::from(root_world[axis])).abs();
        assert!(err < 1e-4, "{what}: root {name} {in_metres} m vs world {} m", root_world[axis]);
    }
    assert_eq!(seen, 3, "{what}: the root has three position channels");
}

#[test]
fn each_unit_round_trips_world_positions_and_writes_a_zero_root_offset() {
    let Some((clip, _)) = cmu_walk() else { return };
    let as_read = clip.import_scale.metres_per_unit;
    for (unit, metres_per_unit) in [(BvhUnit::AsRead, as_read), (BvhUnit::Centimetre, 0.01), (BvhUnit::Metre, 1.0)] {
        let text = write(&clip, unit);
        let back = read_back(&text, metres_per_unit);
        assert_eq!(back.frame_count(), clip.frame_count());
        let worst = worst_fk_error(&clip, &back, |f| f);
        assert!(worst < 1e-4, "{unit:?}: worst FK error {worst} m");
        check_root_text(&clip, &text, metres_per_unit, &format!("CMU 02_01 {unit:?}"));
    }
    // A reader that detects the unit gets the same sizes back from the metre file.
    let detected = read_bvh(write(&clip, BvhUnit::Metre).as_bytes(), Path::new("m.bvh"), BvhReadOptions::default())
        .unwrap()
        .value
        .0;
    assert_eq!(detected.import_scale.metres_per_unit, 1.0);
}

/// The gait's BVH: before the fix its ROOT OFFSET was the hips' rest height (0.95 m) with
/// the full position in the channels, so readers that add the two put the hips at 1.9 m.
#[test]
fn the_gait_file_puts_the_hips_at_the_same_height_in_adding_and_replacing_readers() {
    let clip = gait_clip();
    for (unit, metres_per_unit) in [(BvhUnit::AsRead, 1.0), (BvhUnit::Centimetre, 0.01)] {
        let text = write(&clip, unit);
        check_root_text(&clip, &text, metres_per_unit, &format!("gait {unit:?}"));
        let t = parse_text(&text);
        // An adding reader: OFFSET + channel. The hips of a walk are about 0.9 m up.
        let y = t.root_channels.iter().position(|c| c == "Yposition").unwrap();
        let adding = (t.root_offset[1] + t.first_row[y]) * metres_per_unit;
        assert!((0.8..1.0).contains(&adding), "adding reader's hips at {adding} m");
        let back = read_back(&text, metres_per_unit);
        let worst = worst_fk_error(&clip, &back, |f| f);
        assert!(worst < 1e-4, "gait {unit:?}: worst FK error {worst} m");
    }
}

#[test]
fn end_sites_are_written_as_end_site_blocks_also_when_only_their_name_says_so() {
    let Some((clip, source_text)) = cmu_walk() else { return };
    let count = |t: &str| t.lines().filter(|l| l.trim_start().starts_with("End Site")).count();
    let end_sites = clip.skeleton().joints().iter().filter(|j| j.end_site).count();
    assert_eq!(count(&source_text), end_sites);
    assert!(end_sites >= 5);
    // As read, and with the flag lost (a clip that went through glTF keeps only the
    // `_EndSite` names).
    let mut joints = clip.skeleton().joints().to_vec();
    for j in &mut joints {
        j.end_site = false;
    }
    let unflagged = Clip::new(
        Arc::new(Skeleton::new(joints).unwrap()),
        clip.fps(),
        clip.rotations().to_vec(),
        clip.translations().to_vec(),
        clip.import_scale,
    )
    .unwrap();
    for (what, c) in [("flagged", &clip), ("named", &unflagged)] {
        let text = write(c, BvhUnit::AsRead);
        assert_eq!(count(&text), end_sites, "{what}");
        assert!(!text.contains("_EndSite"), "{what}: an end site written as a JOINT");
        let back = read_back(&text, clip.import_scale.metres_per_unit);
        assert_eq!(back.joint_count(), clip.joint_count(), "{what}");
        assert_eq!(back.skeleton().joints().iter().filter(|j| j.end_site).count(), end_sites, "{what}");
        let worst = worst_fk_error(&clip, &back, |f| f);
        assert!(worst < 1e-4, "{what}: worst FK error {worst} m");
    }
}

/// `resample`'s rule (kernels/resample.rs): frames = floor(duration × fps + 1e-9) + 1,
/// frame i at source time i / fps. The file's frame time is .0083333 s (120.0005 fps), so
/// 120 → 30 fps samples source frame 4.00002 k: within 1e-4 m of frame 4k.
#[test]
fn a_frame_rate_resamples_by_the_kernels_rule() {
    let Some((clip, _)) = cmu_walk() else { return };
    assert!((clip.fps() - 120.0).abs() < 1e-3, "02_01 is a 120 fps file");
    // Hand case: 10 frames at 120 fps last 9/120 s = 0.075 s; × 30 = 2.25 → 2 + 1 = 3 frames.
    let short = clip.slice(0, 10);
    let text = write(&resample(&short, 30.0).unwrap(), BvhUnit::AsRead);
    let t = parse_text(&text);
    assert_eq!(t.frames, 3);
    assert!((t.frame_time - 1.0 / 30.0).abs() < 1e-9);
    let back = read_back(&text, clip.import_scale.metres_per_unit);
    assert_eq!(back.frame_count(), 3);
    let worst = worst_fk_error(&short, &back, |f| 4 * f);
    assert!(worst < 1e-4, "short: worst FK error {worst} m");

    // The whole clip at 30 fps: frame k is source frame 4k.
    let n = clip.frame_count();
    let text = write(&resample(&clip, 30.0).unwrap(), BvhUnit::Centimetre);
    let back = read_back(&text, 0.01);
    assert_eq!(back.frame_count(), (n - 1) / 4 + 1);
    let worst = worst_fk_error(&clip, &back, |f| 4 * f);
    assert!(worst < 1e-4, "30 fps: worst FK error {worst} m");

    // 50 fps: frame k sits at source frame ≈ 2.4 k, between two source frames; the root's
    // world position is their linear interpolation, computed here by hand.
    let text = write(&resample(&clip, 50.0).unwrap(), BvhUnit::Metre);
    let back = read_back(&text, 1.0);
    let duration = (n - 1) as f64 * 0.0083333;
    assert_eq!(back.frame_count(), (duration * 50.0 + 1e-9).floor() as usize + 1);
    let source = forward_kinematics(&clip);
    let written = forward_kinematics(&back);
    for k in 0..back.frame_count() {
        let s = k as f64 / 50.0 / 0.0083333;
        let lo = s.floor() as usize;
        let hi = (lo + 1).min(n - 1);
        let a = (s - lo as f64) as f32;
        let expected: Vec3 = source.position(lo, 0).lerp(source.position(hi, 0), a);
        let err = (written.position(k, 0) - expected).length();
        assert!(err < 1e-4, "50 fps frame {k}: root {err} m off");
    }
}
