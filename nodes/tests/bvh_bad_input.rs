//! Broken and unusual BVH input: every problem is a located, typed error, never a panic;
//! every legal oddity real files carry is accepted.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh, write_bvh};
use kinegraph_nodes::formats::{FormatErrorKind, Location};
use kinegraph_nodes::model::forward_kinematics;

const GOOD: &str = "HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 10 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 90 0 0 0 0 0 0 0
1 90 0 0 0 90 0 0 0
";

fn read(text: &[u8]) -> Result<kinegraph_nodes::model::Clip, kinegraph_nodes::formats::FormatError> {
    read_bvh(text, Path::new("bad.bvh"), BvhReadOptions { metres_per_unit: Some(0.01) }).map(|l| l.value.0)
}

#[test]
fn the_reference_document_reads_and_has_hand_checked_positions() {
    let clip = read(GOOD.as_bytes()).unwrap();
    let poses = forward_kinematics(&clip);
    // Frame 1: root at (1, 90, 0) cm, Spine rotated 90° about Y (no effect on a +Y bone),
    // so the end site sits 20 cm straight up.
    let tip = poses.position(1, 2);
    assert!((tip - glam::Vec3::new(0.01, 1.1, 0.0)).length() < 1e-6, "{tip}");
    assert!((clip.fps() - 30.00003).abs() < 1e-3);
}

/// Each case: what to break, the expected kind and line.
#[test]
fn broken_documents_give_located_typed_errors() {
    let cases: Vec<(&str, String, FormatErrorKind, Option<usize>)> = vec![
        ("truncated in hierarchy", GOOD[..60].to_string(), FormatErrorKind::Truncated, None),
        ("truncated in motion", GOOD[..GOOD.len() - 10].to_string(), FormatErrorKind::Structure, Some(20)),
        (
            "wrong channel count in a row",
            GOOD.replace("1 90 0 0 0 90 0 0 0", "1 90 0 0 0 90 0 0"),
            FormatErrorKind::Structure,
            Some(20),
        ),
        ("non-numeric value", GOOD.replace("1 90 0 0 0 90", "1 90 zero 0 0 90"), FormatErrorKind::Value, Some(20)),
        ("NaN value", GOOD.replace("1 90 0 0 0 90", "1 90 NaN 0 0 90"), FormatErrorKind::Value, Some(20)),
        ("infinite value", GOOD.replace("1 90 0 0 0 90", "1 inf 0 0 0 90"), FormatErrorKind::Value, Some(20)),
        (
            "NaN offset",
            GOOD.replace("OFFSET 0 10 0\n    CHANNELS", "OFFSET 0 nan 0\n    CHANNELS"),
            FormatErrorKind::Value,
            Some(8),
        ),
        ("zero frame time", GOOD.replace("0.0333333", "0"), FormatErrorKind::Value, Some(18)),
        ("negative frame time", GOOD.replace("0.0333333", "-0.03"), FormatErrorKind::Value, Some(18)),
        (
            "frames claim beyond the data",
            GOOD.replace("Frames: 2", "Frames: 4000000000"),
            FormatErrorKind::Truncated,
            Some(17),
        ),
        ("missing MOTION", GOOD[..GOOD.find("MOTION").unwrap()].to_string(), FormatErrorKind::Truncated, None),
        ("no joints", "HIERARCHY\nMOTION\nFrames: 0\nFrame Time: 0.1\n".to_string(), FormatErrorKind::Structure, None),
        ("duplicate joint names", GOOD.replace("JOINT Spine", "JOINT Hips"), FormatErrorKind::Structure, Some(6)),
        (
            "bad channel name",
            GOOD.replace("Zrotation Xrotation Yrotation\n    End", "Zrotation Xrotation Wrotation\n    End"),
            FormatErrorKind::Syntax,
            Some(9),
        ),
        ("channel count too small", GOOD.replace("CHANNELS 3", "CHANNELS 2"), FormatErrorKind::Syntax, Some(9)),
        ("non-UTF-8 bytes", GOOD.replace("Spine", "Sp\u{FFFD}ine"), FormatErrorKind::Syntax, Some(6)),
        (
            "non-UTF-8 bytes in a row",
            GOOD.replace("1 90 0 0 0 90", "1 9\u{FFFD}0 0 0 0 90"),
            FormatErrorKind::Value,
            Some(20),
        ),
        ("unbalanced braces", GOOD.replacen("}\n", "", 1), FormatErrorKind::Syntax, Some(15)),
        ("not a BVH at all", "hello world".to_string(), FormatErrorKind::Syntax, None),
        ("empty", String::new(), FormatErrorKind::Syntax, None),
    ];
    for (what, text, kind, line) in cases {
        let mut bytes = text.into_bytes();
        if what.starts_with("non-UTF-8 bytes") {
            // Replace the UTF-8 replacement character with a lone invalid byte.
            let pos = bytes.windows(3).position(|w| w == "\u{FFFD}".as_bytes()).unwrap();
            bytes.splice(pos..pos + 3, [0xFFu8]);
        }
        let err = read(&bytes).err().unwrap_or_else(|| panic!("{what}: accepted"));
        assert_eq!(err.kind, kind, "{what}: {err}");
        assert_eq!(err.file, Path::new("bad.bvh"), "{what}");
        if let Some(line) = line {
            assert_eq!(err.location, Location::Line { line, column: None }, "{what}: {err}");
        }
        assert!(err.to_string().starts_with("bad.bvh"), "{what}: {err}");
    }
}

#[test]
fn real_world_oddities_are_accepted() {
    let variants = [
        ("CRLF", GOOD.replace('\n', "\r\n")),
        ("BOM and junk before HIERARCHY", format!("\u{FEFF}exported by SomeTool 1.0\n\n{GOOD}")),
        ("tabs and trailing spaces", GOOD.replace("  ", "\t").replace("Frames: 2", "Frames:\t2 ")),
        ("scientific notation", GOOD.replace("1 90 0 0 0 90", "1e0 9.0E1 0 0 0 9e+1")),
        (
            "numbers longer than 15 digits",
            GOOD.replace("1 90 0 0 0 90", "1.00000000000000000000 90 0 0 0 90.0000000000000000000000001"),
        ),
        ("brace on the joint line", GOOD.replace("JOINT Spine\n  {", "JOINT Spine {")),
    ];
    let reference = forward_kinematics(&read(GOOD.as_bytes()).unwrap());
    for (what, text) in variants {
        let clip = read(text.as_bytes()).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(forward_kinematics(&clip), reference, "{what}");
    }
}

#[test]
fn mixed_layouts_and_odd_rates_round_trip() {
    // Rotation-only root, a translation channel on a non-root, a one-channel hinge,
    // and a 29.97 fps NTSC frame time.
    let text = "HIERARCHY
ROOT root
{
\tOFFSET 0 100 0
\tCHANNELS 3 Yrotation Xrotation Zrotation
\tJOINT slider
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 4 Yposition Xrotation Yrotation Zrotation
\t\tJOINT hinge
\t\t{
\t\t\tOFFSET 0 0 5
\t\t\tCHANNELS 1 Xrotation
\t\t\tEnd Site
\t\t\t{
\t\t\t\tOFFSET 0 0 5
\t\t\t}
\t\t}
\t}
}
MOTION
Frames: 3
Frame Time: 0.0333667
10 20 30 12 1 2 3 45
-10 5 0 8 -1 -2 -3 -30
0 0 0 10 0 0 0 0
";
    let clip = read(text.as_bytes()).unwrap();
    assert!((clip.fps() - 29.97).abs() < 1e-2);
    // The slider's position channel replaces the offset's Y: 12 cm at frame 0.
    assert!((clip.frame_translations(0)[1].y - 0.12).abs() < 1e-6);
    let written = write_bvh(&clip);
    assert!(written.value.contains("CHANNELS 4 Yposition Xrotation Yrotation Zrotation"));
    assert!(written.value.contains("CHANNELS 1 Xrotation"));
    let back = read(written.value.as_bytes()).unwrap();
    let (a, b) = (forward_kinematics(&clip), forward_kinematics(&back));
    for f in 0..3 {
        for (x, y) in a.frame(f).iter().zip(b.frame(f)) {
            assert!((x.translation - y.translation).length() < 1e-6);
        }
    }
}
