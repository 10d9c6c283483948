//! BVH reader and writer on the real corpus: every file loads, FK matches an independent
//! implementation, and write → read reproduces every joint's world position.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use kinegraph_nodes::corpus::{files_with_extension, shared_data};
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh, read_bvh_file, write_bvh};
use kinegraph_nodes::model::{LengthUnit, forward_kinematics};

fn load(path: &Path) -> kinegraph_nodes::model::Clip {
    read_bvh_file(path, BvhReadOptions::default()).unwrap_or_else(|e| panic!("{e}")).value.0
}

#[test]
fn every_corpus_file_loads_with_its_declared_frames() {
    let Some(data) = shared_data() else { return };
    let files = files_with_extension(&data.join("bvh"), "bvh");
    assert_eq!(files.len(), 39, "the corpus README lists 39 BVH clips");
    for path in files {
        let text = std::fs::read_to_string(&path).unwrap();
        let claimed: usize =
            text.lines().find_map(|l| l.trim().strip_prefix("Frames:")).unwrap().trim().parse().unwrap();
        let joints_in_text = text.lines().filter(|l| {
            let t = l.trim_start();
            t.starts_with("ROOT ") || t.starts_with("JOINT ") || t.starts_with("End Site")
        });
        let clip = load(&path);
        assert_eq!(clip.frame_count(), claimed, "{}", path.display());
        assert_eq!(clip.joint_count(), joints_in_text.count(), "{}", path.display());
        assert!(clip.fps() > 20.0 && clip.fps() < 130.0, "{}: fps {}", path.display(), clip.fps());
        assert!(clip.rotations().iter().all(|q| q.is_finite() && (q.length() - 1.0).abs() < 1e-4));
    }
}

#[test]
fn detected_units_match_the_corpus_readme() {
    let Some(data) = shared_data() else { return };
    let expect = [
        ("bvh/cmu/02_02.bvh", LengthUnit::CmuUnit),
        ("bvh/cmu_daz/02_02.bvh", LengthUnit::Centimetre),
        ("bvh/mass_humanik/walk.bvh", LengthUnit::Centimetre),
        ("bvh/makehuman/10_01.bvh", LengthUnit::Inch),
        ("bvh/makehuman/tpose.bvh", LengthUnit::Decimetre),
        ("bvh/cmu_3dsmax/scaled_131_03.bvh", LengthUnit::Metre),
        ("bvh/cmu_3dsmax/131_03.bvh", LengthUnit::CmuUnit),
    ];
    for (file, unit) in expect {
        let clip = load(&data.join(file));
        assert_eq!(clip.import_scale.unit, Some(unit), "{file}");
        assert!(clip.import_scale.detected);
        // Whatever the source unit, a human comes out between 1.2 and 2 m.
        let extent = clip.skeleton().rest_extent().max_element();
        assert!((1.2..2.0).contains(&extent), "{file}: {extent} m");
    }
}

#[test]
fn scale_override_replaces_detection() {
    let Some(data) = shared_data() else { return };
    let path = data.join("bvh/cmu/02_02.bvh");
    let auto = load(&path);
    let cm = read_bvh_file(&path, BvhReadOptions { metres_per_unit: Some(0.01) }).unwrap().value.0;
    assert!(!cm.import_scale.detected);
    let ratio = auto.skeleton().rest_extent().max_element() / cm.skeleton().rest_extent().max_element();
    assert!((f64::from(ratio) - LengthUnit::CmuUnit.metres() / 0.01).abs() < 1e-3);
}

#[derive(serde::Deserialize)]
struct Reference {
    source: String,
    joints: Vec<String>,
    frames: Vec<usize>,
    positions: Vec<Vec<[f64; 3]>>,
}

/// `shared/data/reference` holds world joint positions from an independent (float64,
/// cross-checked) implementation, in file units.
#[test]
fn forward_kinematics_matches_the_independent_reference() {
    let Some(data) = shared_data() else { return };
    let refs = files_with_extension(&data.join("reference"), "json");
    assert_eq!(refs.len(), 5);
    for ref_path in refs {
        let r: Reference = serde_json::from_str(&std::fs::read_to_string(&ref_path).unwrap()).unwrap();
        let clip = load(&data.join(&r.source));
        let poses = forward_kinematics(&clip);
        let scale = clip.import_scale.metres_per_unit;
        let height_m = clip.skeleton().rest_extent().max_element() as f64;
        let skeleton = clip.skeleton();
        let mut worst = 0.0f64;
        for (fi, &frame) in r.frames.iter().enumerate() {
            for (ji, name) in r.joints.iter().enumerate() {
                let j = skeleton.index_of(name).unwrap_or_else(|| panic!("{}: no joint {name}", r.source));
                let p = poses.position(frame, j);
                let expected = r.positions[fi][ji];
                let err = (0..3).map(|k| (f64::from(p[k]) / scale - expected[k]).powi(2)).sum::<f64>().sqrt() * scale;
                worst = worst.max(err);
            }
        }
        assert!(worst < 1e-4 * height_m, "{}: worst error {worst} m (height {height_m} m)", r.source);
    }
}

#[test]
fn write_then_read_reproduces_every_world_position_on_every_file() {
    let Some(data) = shared_data() else { return };
    for path in files_with_extension(&data.join("bvh"), "bvh") {
        let original = load(&path);
        let written = write_bvh(&original);
        assert!(written.warnings.is_empty(), "{}: {:?}", path.display(), written.warnings);
        let back = read_bvh(written.value.as_bytes(), &path, BvhReadOptions::default()).unwrap().value.0;
        assert_eq!(back.import_scale.metres_per_unit, original.import_scale.metres_per_unit);
        assert_eq!(back.frame_count(), original.frame_count());
        assert!((back.fps() - original.fps()).abs() < 1e-9 * original.fps());
        for (a, b) in original.skeleton().joints().iter().zip(back.skeleton().joints()) {
            assert_eq!((&a.name, a.parent, &a.channels, a.end_site), (&b.name, b.parent, &b.channels, b.end_site));
        }
        let (pa, pb) = (forward_kinematics(&original), forward_kinematics(&back));
        let mut worst = 0.0f32;
        for f in 0..original.frame_count() {
            for (ta, tb) in pa.frame(f).iter().zip(pb.frame(f)) {
                worst = worst.max((ta.translation - tb.translation).length());
            }
        }
        assert!(worst < 1e-5, "{}: worst round-trip error {worst} m", path.display());
    }
}

#[test]
fn z_up_files_are_flagged_and_converted_on_request() {
    use kinegraph_nodes::kernels::load::{ClipLoadOptions, UpAxis, load_clip};
    let Some(data) = shared_data() else { return };
    let path = data.join("bvh/makehuman/tpose.bvh");
    let as_is = load_clip(&path, ClipLoadOptions::default()).unwrap();
    assert!(as_is.warnings.iter().any(|w| w.contains("looks Z-up")), "{:?}", as_is.warnings);
    let converted = load_clip(&path, ClipLoadOptions { up_axis: UpAxis::Z, ..Default::default() }).unwrap();
    assert!(!converted.warnings.iter().any(|w| w.contains("looks Z-up")));
    let (before, after) = (as_is.value.skeleton().rest_extent(), converted.value.skeleton().rest_extent());
    // Height moves from Z to Y; the rest of the body keeps its size.
    assert!((after.y - before.z).abs() < 1e-4 && (after.x - before.x).abs() < 1e-4, "{before} → {after}");
    // Y-up files raise no such warning.
    let cmu = load_clip(&data.join("bvh/cmu/02_02.bvh"), ClipLoadOptions::default()).unwrap();
    assert!(!cmu.warnings.iter().any(|w| w.contains("Z-up")));
}

/// Every frame value of every corpus file, parsed independently (rows split on whitespace,
/// each token by std's correctly rounded `str::parse::<f32>`, rotations composed by
/// `math::euler::compose` in written order), gives the reader's clip bit for bit: a faster
/// reader must not move a single value.
#[test]
fn every_frame_value_matches_an_independent_parse_bit_for_bit() {
    use kinegraph_nodes::math::euler::compose;
    use kinegraph_nodes::model::{Channel, Clip};
    let Some(data) = shared_data() else { return };
    for path in files_with_extension(&data.join("bvh"), "bvh") {
        let clip = load(&path);
        let text = String::from_utf8_lossy(&std::fs::read(&path).unwrap()).into_owned();
        let rows = text.lines().skip_while(|l| !l.trim_start().starts_with("Frame Time:")).skip(1);
        let skeleton = clip.skeleton().clone();
        let scale = clip.import_scale.metres_per_unit as f32;
        let (mut rotations, mut translations) = (Vec::new(), Vec::new());
        for row in rows.filter(|r| !r.trim().is_empty()).take(clip.frame_count()) {
            let values: Vec<f32> = row.split_whitespace().map(|t| t.parse().unwrap()).collect();
            let mut next = values.iter();
            for joint in skeleton.joints() {
                let (mut axes, mut angles, mut translation) = (Vec::new(), Vec::new(), joint.rest_offset);
                for (channel, &v) in joint.channels.iter().zip(next.by_ref()) {
                    match channel {
                        Channel::Position(axis) => translation[axis.index()] = v * scale,
                        Channel::Rotation(axis) => {
                            axes.push(*axis);
                            angles.push(v.to_radians());
                        }
                    }
                }
                rotations.push(compose(&axes, &angles));
                translations.push(translation);
            }
            assert!(next.next().is_none(), "{}: a row longer than the channels", path.display());
        }
        let expected = Clip::new(skeleton, clip.fps(), rotations, translations, clip.import_scale).unwrap();
        let bits = |c: &Clip| -> Vec<u32> {
            let r = c.rotations().iter().flat_map(|q| q.to_array());
            r.chain(c.translations().iter().flat_map(|t| t.to_array())).map(f32::to_bits).collect()
        };
        assert!(bits(&clip) == bits(&expected), "{}: a value differs from the independent parse", path.display());
    }
}

/// cgspeed's CMU conversions put a T-pose before the motion (the corpus README; its copy of
/// 144_05 had it removed upstream), and so does MakeHuman's conversion of CMU 10_01 (its
/// shoulders turn 86° into frame 1, then 0.1° a frame). The loader finds it in exactly those
/// files, by the pop alone, and drops only that frame when asked.
#[test]
fn cgspeed_t_pose_frames_are_found_in_exactly_the_cgspeed_files() {
    use kinegraph_nodes::kernels::load::{ClipLoadOptions, LeadingTPose, load_clip};
    let Some(data) = shared_data() else { return };
    let mut found = Vec::new();
    for path in files_with_extension(&data.join("bvh"), "bvh") {
        let name = path.strip_prefix(&data).unwrap().to_string_lossy().replace('\\', "/");
        let options = ClipLoadOptions { t_pose: LeadingTPose::Drop, ..Default::default() };
        let dropped = load_clip(&path, options).unwrap().value;
        let kept = load(&path);
        if dropped.frame_count() != kept.frame_count() {
            assert_eq!(dropped.frame_count() + 1, kept.frame_count(), "{name}");
            // The rest is the file's frames 1.., untouched.
            assert_eq!(dropped.rotations(), &kept.rotations()[kept.joint_count()..], "{name}");
            found.push(name);
        }
    }
    let cgspeed: Vec<String> = files_with_extension(&data.join("bvh/cmu"), "bvh")
        .iter()
        .map(|p| p.strip_prefix(&data).unwrap().to_string_lossy().replace('\\', "/"))
        .filter(|n| !n.ends_with("144_05.bvh"))
        .chain(["bvh/makehuman/10_01.bvh".to_owned()])
        .collect();
    assert_eq!(found, cgspeed);
}
