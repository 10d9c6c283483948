//! The glTF reader on small hand-made documents: interpolation modes against hand-computed
//! values, sparse accessors, integer skin attributes, external buffers, and a table of
//! broken documents that must each give a located error (never a panic).

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed unwrap is a failed test

use std::f32::consts::FRAC_PI_2;
use std::path::Path;

use base64::Engine as _;
use glam::{Quat, Vec3};
use kinegraph_nodes::formats::gltf::{GltfAsset, GltfReadOptions, read_gltf, read_gltf_file, write_glb};
use kinegraph_nodes::formats::{FormatError, FormatErrorKind, Location};
use serde_json::{Value, json};

/// Accumulates buffer views and accessors for a document with one embedded buffer.
#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Doc {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.views.push(json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()}));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn accessor(&mut self, a: Value) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn floats(&mut self, data: &[f32], type_: &str) -> usize {
        let n = match type_ {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            _ => 16,
        };
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let mut a = json!({"bufferView": view, "componentType": 5126, "count": data.len() / n, "type": type_});
        if type_ == "SCALAR" {
            let lo = data.iter().copied().fold(f32::INFINITY, f32::min);
            let hi = data.iter().copied().fold(f32::NEG_INFINITY, f32::max);
            a["min"] = json!([lo]);
            a["max"] = json!([hi]);
        }
        self.accessor(a)
    }

    /// The whole document as JSON bytes; `rest` supplies nodes, skins, animations, ….
    fn finish(&self, mut rest: Value) -> Vec<u8> {
        let uri = format!(
            "data:application/octet-stream;base64,{}",
            base64::engine::general_purpose::STANDARD.encode(&self.bin)
        );
        rest["asset"] = json!({"version": "2.0"});
        rest["buffers"] = json!([{"byteLength": self.bin.len(), "uri": uri}]);
        rest["bufferViews"] = json!(self.views);
        rest["accessors"] = json!(self.accessors);
        serde_json::to_vec(&rest).unwrap()
    }
}

/// Two joints, `root` at the origin and `tip` 1 m up, with one animation channel.
fn two_joint_doc(doc: &mut Doc, path: &str, interpolation: &str, times: &[f32], values: &[f32]) -> Vec<u8> {
    let input = doc.floats(times, "SCALAR");
    let output = doc.floats(values, if path == "rotation" { "VEC4" } else { "VEC3" });
    doc.finish(json!({
        "nodes": [{"name": "root", "children": [1]}, {"name": "tip", "translation": [0.0, 1.0, 0.0]}],
        "skins": [{"joints": [0, 1]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": path}}],
                        "samplers": [{"input": input, "output": output, "interpolation": interpolation}]}],
        "scenes": [{"nodes": [0]}],
    }))
}

fn read(bytes: &[u8], fps: f64) -> GltfAsset {
    let options = GltfReadOptions { sample_fps: Some(fps), ..Default::default() };
    read_gltf(bytes, Path::new("test.gltf"), &options).unwrap_or_else(|e| panic!("{e}")).value
}

fn tip_translations(asset: &GltfAsset) -> Vec<Vec3> {
    let c = &asset.clips[0].clip;
    (0..c.frame_count()).map(|f| c.frame_translations(f)[1]).collect()
}

/// Same rotation within 1e-5 (component-wise, either sign; `angle_between` is too
/// imprecise near zero for this).
fn quat_close(a: Quat, b: Quat) -> bool {
    (a - b).length() < 1e-5 || (a + b).length() < 1e-5
}

fn assert_vec3s(got: &[Vec3], want: &[Vec3]) {
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (g, w) in got.iter().zip(want) {
        assert!((*g - *w).length() < 1e-5, "{got:?} vs {want:?}");
    }
}

#[test]
fn step_holds_each_key_until_the_next() {
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "STEP", &[0.0, 1.0, 2.0], &[0., 0., 0., 1., 0., 0., 3., 0., 0.]);
    let asset = read(&bytes, 2.0);
    let x = |v: f32| Vec3::new(v, 0.0, 0.0);
    assert_vec3s(&tip_translations(&asset), &[x(0.0), x(0.0), x(1.0), x(1.0), x(3.0)]);
}

#[test]
fn linear_translation_and_rotation_interpolate() {
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0, 1.0, 2.0], &[0., 0., 0., 1., 0., 0., 3., 0., 0.]);
    let x = |v: f32| Vec3::new(v, 0.0, 0.0);
    assert_vec3s(&tip_translations(&read(&bytes, 2.0)), &[x(0.0), x(0.5), x(1.0), x(2.0), x(3.0)]);

    let keys: Vec<f32> = [0.0f32, 1.0, 2.0].iter().flat_map(|a| Quat::from_rotation_z(*a).to_array()).collect();
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "rotation", "LINEAR", &[0.0, 1.0, 2.0], &keys);
    let asset = read(&bytes, 4.0);
    let c = &asset.clips[0].clip;
    assert_eq!(c.frame_count(), 9);
    for f in 0..9 {
        let want = Quat::from_rotation_z(f as f32 * 0.25);
        assert!(quat_close(c.frame_rotations(f)[1], want), "frame {f}");
    }
    // The untouched tip translation is the node's rest translation.
    assert_vec3s(&tip_translations(&asset)[..1], &[Vec3::Y]);
}

#[test]
fn cubic_spline_uses_hermite_tangents() {
    // Keys x(0) = 0, x(1) = 1; out-tangent at key 0 is 2, in-tangent at key 1 is 0.
    // p(s) = (s³ − 2s² + s)·2 + (−2s³ + 3s²)  ⇒  p(0.5) = 0.25 + 0.5 = 0.75.
    let values = [
        /* key 0: in, value, out */ 0., 0., 0., 0., 0., 0., 2., 0., 0., /* key 1 */ 0., 0., 0., 1., 0., 0.,
        0., 0., 0.,
    ];
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "CUBICSPLINE", &[0.0, 1.0], &values);
    let x = |v: f32| Vec3::new(v, 0.0, 0.0);
    assert_vec3s(&tip_translations(&read(&bytes, 2.0)), &[x(0.0), x(0.75), x(1.0)]);

    // Rotations with zero tangents: h00·q0 + h01·q1 at s = ½ is the normalised midpoint,
    // i.e. the half-angle rotation.
    let (q0, q1) = (Quat::IDENTITY.to_array(), Quat::from_rotation_z(FRAC_PI_2).to_array());
    let zero = [0.0f32; 4];
    let keys: Vec<f32> = [zero, q0, zero, zero, q1, zero].concat();
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "rotation", "CUBICSPLINE", &[0.0, 1.0], &keys);
    let asset = read(&bytes, 2.0);
    let got = asset.clips[0].clip.frame_rotations(1)[1];
    assert!(quat_close(got, Quat::from_rotation_z(FRAC_PI_2 / 2.0)), "{got}");
    assert!((got.length() - 1.0).abs() < 1e-6);
}

#[test]
fn frame_rate_is_inferred_from_key_spacing() {
    let times: Vec<f32> = (0..25).map(|i| i as f32 / 24.0).collect();
    let values: Vec<f32> = times.iter().flat_map(|t| [*t, 0.0, 0.0]).collect();
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "LINEAR", &times, &values);
    let asset = read_gltf(&bytes, Path::new("t.gltf"), &GltfReadOptions::default()).unwrap().value;
    let c = &asset.clips[0].clip;
    assert_eq!(c.fps(), 24.0);
    assert_eq!(c.frame_count(), 25);
    // A single key gives no spacing: the documented 30 fps fallback.
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0], &[1.0, 0.0, 0.0]);
    let asset = read_gltf(&bytes, Path::new("t.gltf"), &GltfReadOptions::default()).unwrap().value;
    assert_eq!(asset.clips[0].clip.fps(), 30.0);
    assert_eq!(asset.clips[0].clip.frame_count(), 1);
}

#[test]
fn sparse_accessors_substitute_values() {
    let mut d = Doc::default();
    let input = d.floats(&[0.0, 1.0, 2.0], "SCALAR");
    // No base view: zeros, with element 2 replaced by (3, 0, 0) ...
    let idx = d.view(&2u16.to_le_bytes());
    let vals: Vec<u8> = [3.0f32, 0.0, 0.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let val = d.view(&vals);
    let output = d.accessor(json!({"componentType": 5126, "count": 3, "type": "VEC3",
        "sparse": {"count": 1, "indices": {"bufferView": idx, "componentType": 5123}, "values": {"bufferView": val}}}));
    // ... and a based accessor: (5,5,5) × 3 with element 0 replaced by (1, 2, 3).
    let base: Vec<u8> = [5.0f32; 9].iter().flat_map(|v| v.to_le_bytes()).collect();
    let base_view = d.view(&base);
    let idx0 = d.view(&[0u8]);
    let vals0: Vec<u8> = [1.0f32, 2.0, 3.0].iter().flat_map(|v| v.to_le_bytes()).collect();
    let val0 = d.view(&vals0);
    let output_root = d.accessor(json!({"bufferView": base_view, "componentType": 5126, "count": 3, "type": "VEC3",
        "sparse": {"count": 1, "indices": {"bufferView": idx0, "componentType": 5121}, "values": {"bufferView": val0}}}));
    let bytes = d.finish(json!({
        "nodes": [{"name": "root", "children": [1]}, {"name": "tip"}],
        "skins": [{"joints": [0, 1]}],
        "animations": [{"channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}},
                                     {"sampler": 1, "target": {"node": 0, "path": "translation"}}],
                        "samplers": [{"input": input, "output": output}, {"input": input, "output": output_root}]}],
    }));
    let asset = read(&bytes, 1.0);
    let x = |v: f32| Vec3::new(v, 0.0, 0.0);
    assert_vec3s(&tip_translations(&asset), &[x(0.0), x(0.0), x(3.0)]);
    let c = &asset.clips[0].clip;
    assert_vec3s(
        &c.root_translations().collect::<Vec<_>>(),
        &[Vec3::new(1.0, 2.0, 3.0), Vec3::splat(5.0), Vec3::splat(5.0)],
    );
}

/// A skinned triangle with u8 joints and normalised u8 weights (the first row sums to
/// 254/255, so it is renormalised with a warning); `weights` overrides the weight bytes.
fn skinned_triangle(weights: [[u8; 4]; 3]) -> (Vec<u8>, usize) {
    let mut d = Doc::default();
    let pos = d.floats(&[0., 0., 0., 1., 0., 0., 0., 1., 0.], "VEC3");
    let jv = d.view(&[0, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0]);
    let joints = d.accessor(json!({"bufferView": jv, "componentType": 5121, "count": 3, "type": "VEC4"}));
    let wv = d.view(&weights.concat());
    let w =
        d.accessor(json!({"bufferView": wv, "componentType": 5121, "normalized": true, "count": 3, "type": "VEC4"}));
    // Inverse bind matrices: joint 1 sits 1 m up the Y axis.
    let ibm: Vec<f32> =
        [glam::Mat4::IDENTITY, glam::Mat4::from_translation(-Vec3::Y)].iter().flat_map(|m| m.to_cols_array()).collect();
    let ibm = d.floats(&ibm, "MAT4");
    let bytes = d.finish(json!({
        "nodes": [{"name": "root", "children": [1]}, {"name": "tip", "translation": [0.0, 1.0, 0.0]},
                  {"name": "tri", "mesh": 0, "skin": 0}],
        "skins": [{"joints": [1, 0], "inverseBindMatrices": ibm}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": pos, "JOINTS_0": joints, "WEIGHTS_0": w}}]}],
    }));
    (bytes, w)
}

#[test]
fn integer_skin_attributes_map_to_skeleton_joints() {
    let (bytes, _) = skinned_triangle([[254, 0, 0, 0], [128, 127, 0, 0], [255, 0, 0, 0]]);
    let loaded = read_gltf(&bytes, Path::new("tri.gltf"), &GltfReadOptions::default()).unwrap();
    assert!(loaded.warnings.iter().any(|w| w.contains("renormalised")), "{:?}", loaded.warnings);
    let mesh = &loaded.value.meshes[0];
    let skin = mesh.skin.as_ref().unwrap();
    // Skin joint 0 is node 1 = skeleton joint 1 ("tip"), skin joint 1 is the root.
    assert_eq!(skin.joints[0][0], 1);
    assert_eq!(&skin.joints[1][..2], &[0, 1]);
    assert!((skin.weights[0][0] - 1.0).abs() < 1e-6);
    assert!((skin.weights[1][0] - 128.0 / 255.0).abs() < 1e-6);
    assert!(mesh.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6), "computed normals");
}

/// Asserts `result` failed with `kind` at JSON path `path`.
fn assert_error(
    name: &str,
    result: Result<impl std::fmt::Debug, FormatError>,
    path: Option<&str>,
    kind: FormatErrorKind,
) {
    let err = match result {
        Ok(v) => panic!("{name}: expected an error, got {v:?}"),
        Err(e) => e,
    };
    let want = match path {
        Some(p) => Location::JsonPath(p.to_string()),
        None => Location::File,
    };
    assert_eq!(err.location, want, "{name}: {err}");
    assert_eq!(err.kind, kind, "{name}: {err}");
    assert!(err.to_string().contains("bad.gltf"), "{name}: the message names the file: {err}");
}

#[test]
fn broken_documents_give_located_errors() {
    let mut d = Doc::default();
    let input = d.floats(&[0.0, 1.0], "SCALAR");
    let output = d.floats(&[0., 0., 0., 1., 0., 0.], "VEC3");
    let nan = d.floats(&[0., 0., 0., f32::NAN, 0., 0.], "VEC3");
    let falling = d.floats(&[1.0, 0.0], "SCALAR");
    // Claims 1000 elements of 12 bytes in a 24-byte view.
    let long = d.accessor(json!({"bufferView": 1, "componentType": 5126, "count": 1000, "type": "VEC3"}));
    let anim = |input: usize, output: usize| {
        json!([{"channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
                "samplers": [{"input": input, "output": output}]}])
    };
    let nodes = json!([{"name": "root", "children": [1]}, {"name": "tip"}]);
    let skins = json!([{"joints": [0, 1]}]);
    let cases: Vec<(&str, Value, &str, FormatErrorKind)> = vec![
        ("skin joint out of range", json!({"nodes": nodes, "skins": [{"joints": [0, 7]}]}), "/skins/0/joints/1", FormatErrorKind::Structure),
        (
            "channel node out of range",
            json!({"nodes": nodes, "skins": skins, "animations": [{"channels": [{"sampler": 0, "target": {"node": 9, "path": "rotation"}}],
                   "samplers": [{"input": input, "output": output}]}]}),
            "/animations/0/channels/0/target/node",
            FormatErrorKind::Structure,
        ),
        ("accessor out of range", json!({"nodes": nodes, "skins": skins, "animations": anim(input, 99)}), "/animations/0/samplers/0/output", FormatErrorKind::Structure),
        ("cyclic hierarchy", json!({"nodes": [{"children": [1]}, {"children": [0]}], "skins": [{"joints": [0, 1]}]}), "/nodes/0", FormatErrorKind::Structure),
        ("node with two parents", json!({"nodes": [{"children": [2]}, {"children": [2]}, {}], "skins": [{"joints": [0, 2]}]}), "/nodes/1/children/0", FormatErrorKind::Structure),
        ("accessor past buffer end", json!({"nodes": nodes, "skins": skins, "animations": anim(input, long)}), &*format!("/accessors/{long}"), FormatErrorKind::Truncated),
        ("NaN in accessor", json!({"nodes": nodes, "skins": skins, "animations": anim(input, nan)}), &*format!("/accessors/{nan}"), FormatErrorKind::Value),
        ("decreasing key times", json!({"nodes": nodes, "skins": skins, "animations": anim(falling, output)}), &*format!("/accessors/{falling}"), FormatErrorKind::Value),
        ("output count mismatch", json!({"nodes": nodes, "skins": skins, "animations": anim(input, nan + 100)}), "/animations/0/samplers/0/output", FormatErrorKind::Structure),
    ]
    .into_iter()
    .map(|(n, v, p, k)| (n, v, Box::leak(p.to_string().into_boxed_str()) as &str, k))
    .collect();
    for (name, rest, path, kind) in cases {
        let bytes = d.finish(rest);
        assert_error(name, read_gltf(&bytes, Path::new("bad.gltf"), &GltfReadOptions::default()), Some(path), kind);
    }

    // A buffer view running past its buffer.
    let mut d2 = Doc::default();
    let input = d2.floats(&[0.0, 1.0], "SCALAR");
    let output = d2.floats(&[0., 0., 0., 1., 0., 0.], "VEC3");
    d2.views[output]["byteLength"] = json!(4096);
    let bytes = d2.finish(json!({"nodes": nodes, "skins": skins, "animations": anim(input, output)}));
    assert_error(
        "view past buffer",
        read_gltf(&bytes, Path::new("bad.gltf"), &GltfReadOptions::default()),
        Some("/bufferViews/1"),
        FormatErrorKind::Truncated,
    );

    // Weights summing to zero.
    let (bytes, w) = skinned_triangle([[255, 0, 0, 0], [0, 0, 0, 0], [255, 0, 0, 0]]);
    let result = read_gltf(&bytes, Path::new("bad.gltf"), &GltfReadOptions::default());
    assert_error("zero weights", result, Some(&format!("/accessors/{w}")), FormatErrorKind::Value);

    // Not JSON at all, and a truncated JSON document.
    assert_error(
        "garbage",
        read_gltf(b"\x00\x01 nonsense", Path::new("bad.gltf"), &GltfReadOptions::default()),
        None,
        FormatErrorKind::Syntax,
    );
    assert_error(
        "cut JSON",
        read_gltf(b"{\"asset\": {\"vers", Path::new("bad.gltf"), &GltfReadOptions::default()),
        None,
        FormatErrorKind::Truncated,
    );
}

#[test]
fn truncated_or_corrupted_glb_never_panics() {
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0, 1.0], &[0., 0., 0., 1., 0., 0.]);
    let asset = read(&bytes, 10.0);
    let glb = write_glb(&asset.clips[0].clip, None).unwrap().value;
    let err = read_gltf(&glb[..glb.len() / 2], Path::new("bad.gltf"), &GltfReadOptions::default()).unwrap_err();
    assert_eq!((err.location.clone(), err.kind), (Location::File, FormatErrorKind::Truncated), "{err}");
    for len in 0..glb.len() {
        let _ = read_gltf(&glb[..len], Path::new("cut.glb"), &GltfReadOptions::default());
    }
    // Flip bytes everywhere (JSON and binary chunk alike).
    for i in (0..glb.len()).step_by(3) {
        let mut bad = glb.clone();
        bad[i] ^= 0x5a;
        let _ = read_gltf(&bad, Path::new("flip.glb"), &GltfReadOptions::default());
    }
}

/// Two keys far apart ask for a long clip: sampled when it fits the memory limit the
/// reader is given, refused with the estimate and the way out when it does not, before
/// anything is allocated (the `gltf_loader` fuzz find: 3 KB of JSON asking for 1.4 GB).
#[test]
fn long_sparse_animations_respect_the_memory_limit() {
    let limit = 1 << 20;
    let limited = GltfReadOptions { sample_fps: Some(30.0), max_clip_bytes: Some(limit), ..Default::default() };
    // 100 s at 30 fps: 3,001 frames of 2 joints, 28 bytes each = 168 KB.
    let mut d = Doc::default();
    let fits = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0, 100.0], &[0., 0., 0., 1., 0., 0.]);
    let asset = read_gltf(&fits, Path::new("long.gltf"), &limited).unwrap().value;
    assert_eq!(asset.clips[0].clip.frame_count(), 3_001);
    // 1,000 s: 30,001 frames, 1.6 MiB.
    let mut d = Doc::default();
    let too_long = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0, 1000.0], &[0., 0., 0., 1., 0., 0.]);
    let err = read_gltf(&too_long, Path::new("long.gltf"), &limited).unwrap_err();
    assert_eq!(err.location, Location::JsonPath("/animations/0".into()), "{err}");
    assert_eq!(err.kind, FormatErrorKind::Unsupported, "{err}");
    let message = err.to_string();
    assert!(message.contains("30001 frames of 2 joints") && message.contains("1.6 MiB"), "{message}");
    assert!(message.contains("1.0 MiB") && message.contains("--max-memory"), "{message}");
    // Without a limit the default (1.4 GB) applies: 1e6 s of keys is 3e7 frames, 1.6 GiB.
    let mut d = Doc::default();
    let absurd = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0, 1e6], &[0., 0., 0., 1., 0., 0.]);
    let options = GltfReadOptions { sample_fps: Some(30.0), ..Default::default() };
    let err = read_gltf(&absurd, Path::new("long.gltf"), &options).unwrap_err();
    assert!(err.to_string().contains("1.6 GiB"), "{err}");
}

#[test]
fn external_buffers_resolve_beside_the_file_and_refuse_escapes() {
    let mut d = Doc::default();
    let bytes = two_joint_doc(&mut d, "translation", "LINEAR", &[0.0, 1.0], &[0., 0., 0., 1., 0., 0.]);
    let mut v: Value = serde_json::from_slice(&bytes).unwrap();
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("data file.bin"), &d.bin).unwrap();
    v["buffers"][0]["uri"] = json!("data%20file.bin");
    let path = dir.path().join("model.gltf");
    std::fs::write(&path, serde_json::to_vec(&v).unwrap()).unwrap();
    let asset = read_gltf_file(&path, &GltfReadOptions { sample_fps: Some(2.0), ..Default::default() }).unwrap().value;
    assert_vec3s(&tip_translations(&asset), &[Vec3::ZERO, Vec3::new(0.5, 0.0, 0.0), Vec3::X]);

    v["buffers"][0]["uri"] = json!("../data file.bin");
    std::fs::write(&path, serde_json::to_vec(&v).unwrap()).unwrap();
    let err = read_gltf_file(&path, &GltfReadOptions::default()).unwrap_err();
    assert_eq!(err.location, Location::JsonPath("/buffers/0/uri".into()));
    assert!(err.message.contains("../data file.bin"), "{err}");
}

#[test]
fn ancestor_transforms_are_baked_into_the_root() {
    // An "Armature" rotating +90° about X and scaling ×2 above the skeleton root.
    let d = Doc::default();
    let bytes = d.finish(json!({
        "nodes": [{"name": "Armature", "rotation": Quat::from_rotation_x(FRAC_PI_2).to_array(), "scale": [2.0, 2.0, 2.0], "children": [1]},
                  {"name": "root", "translation": [0.0, 0.0, 1.0], "children": [2]},
                  {"name": "tip", "translation": [0.0, 0.0, 0.5]}],
        "skins": [{"joints": [1, 2]}],
    }));
    let loaded = read_gltf(&bytes, Path::new("a.gltf"), &GltfReadOptions::default()).unwrap();
    let skeleton = loaded.value.skeleton.unwrap();
    assert_eq!(skeleton.len(), 2);
    // Rotating +Z by +90° about X gives −Y; scaled ×2: root at (0, −2, 0), tip at (0, −3, 0).
    let p = skeleton.rest_positions();
    assert!((p[0] - Vec3::new(0.0, -2.0, 0.0)).length() < 1e-5, "{p:?}");
    assert!((p[1] - Vec3::new(0.0, -3.0, 0.0)).length() < 1e-5, "{p:?}");
}
