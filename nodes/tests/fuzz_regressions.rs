//! Inputs the fuzz targets once broke the readers with (`fuzz/regressions/`): each must now
//! load or fail with a located error, and what loads must have finite forward kinematics.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh};
use kinegraph_nodes::formats::error::Location;
use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf};
use kinegraph_nodes::formats::obj::read_obj;
use kinegraph_nodes::model::forward_kinematics;

#[test]
fn bvh_reader_regressions_never_panic_and_stay_finite() {
    let files = regression_inputs("bvh_reader");
    assert!(files.len() >= 2, "the bvh_reader regression inputs are incomplete: {files:?}");
    let overflow = files.iter().find(|p| p.ends_with("fk_offsets_overflow.bvh")).cloned().unwrap();
    for path in files {
        let bytes = std::fs::read(&path).unwrap();
        match read_bvh(&bytes, &path, BvhReadOptions::default()) {
            Ok(loaded) => {
                let clip = &loaded.value.0;
                let poses = forward_kinematics(clip);
                for f in 0..clip.frame_count() {
                    assert!(
                        poses.frame(f).iter().all(|t| t.translation.is_finite() && t.rotation.is_finite()),
                        "{}",
                        path.display()
                    );
                }
            }
            Err(e) => assert!(e.to_string().contains(path.file_name().unwrap().to_str().unwrap()), "{e}"),
        }
    }
    // The huge-offset case is refused, naming the joint.
    let err = read_bvh(&std::fs::read(overflow).unwrap(), Path::new("x.bvh"), BvhReadOptions::default()).unwrap_err();
    assert!(err.message.contains("joint 'b'"), "{err}");
}

/// The kept inputs of fuzz target `target` (`fuzz/regressions/<target>/`), sorted; fails when
/// there are none, so a lost folder is not a silent pass.
fn regression_inputs(target: &str) -> Vec<std::path::PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/regressions").join(target);
    let mut files: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    assert!(!files.is_empty(), "the regression inputs are missing from {}", dir.display());
    files
}

/// The `obj_reader` target's inputs (their first byte picks the unit; the rest is the file):
/// each is refused with an error located at a line of the file, never a panic.
#[test]
fn obj_reader_regressions_are_located_errors() {
    for path in regression_inputs("obj_reader") {
        let bytes = std::fs::read(&path).unwrap();
        let err = read_obj(&bytes[1..], &path, None).expect_err("a face index before the first record");
        assert!(matches!(err.location, Location::Line { .. }), "{}: {err}", path.display());
    }
}

/// The `gltf_loader` target's finds: a primitive whose POSITION names an accessor that does
/// not exist made gltf-json's own validation index past the accessor list (a panic); a
/// node's transform that overflows left a mesh with infinite positions; keys claiming hours
/// of animation asked for 3.2 GB, and later (`timeout-…`: 5.5e6 s of keys) for the whole
/// default limit, seconds of sampling. Kept inputs (as given, and the JSON before a NUL as
/// the target wraps it in a GLB), read under the target's memory limit, load with finite
/// meshes or fail without panicking; the long one is refused naming the limit; a hand-made
/// file fails naming the attribute.
#[test]
fn gltf_loader_regressions_never_panic_and_out_of_range_attributes_are_named() {
    let options = GltfReadOptions { max_clip_bytes: Some(64 << 20), materials: true, ..Default::default() };
    for path in regression_inputs("gltf_loader") {
        let bytes = std::fs::read(&path).unwrap();
        let json = bytes.split(|&b| b == 0).next().unwrap_or(&bytes);
        let result = read_gltf(&bytes, &path, &options);
        if path.file_name().unwrap().to_string_lossy().starts_with("timeout-") {
            let err = result.as_ref().unwrap_err().to_string();
            assert!(err.contains("/animations/0") && err.contains("--max-memory"), "{err}");
        }
        for input in [&bytes[..], json] {
            if let Ok(loaded) = read_gltf(input, &path, &options) {
                for mesh in &loaded.value.meshes {
                    assert!(mesh.positions.iter().all(|p| p.is_finite()), "{}: mesh '{}'", path.display(), mesh.name);
                }
            }
        }
    }
    let text = br#"{"asset": {"version": "2.0"}, "meshes": [{"primitives": [{"attributes": {"POSITION": 5}}]}]}"#;
    let err = read_gltf(text, Path::new("bad.gltf"), &GltfReadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("/meshes/0/primitives/0/attributes/POSITION"), "{err}");
    assert!(err.to_string().contains("index out of range"), "{err}");
}
