//! The glTF and OBJ files of the shared corpus: counts checked against the files' own
//! JSON (parsed here independently with serde_json), keyframes, bind pose and round trips.

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed unwrap is a failed test

use std::path::{Path, PathBuf};

use glam::{Mat4, Quat, Vec3, Vec4};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::gltf::{GltfAsset, GltfReadOptions, read_gltf, read_gltf_file, write_glb};
use kinegraph_nodes::formats::obj::read_obj_file;
use kinegraph_nodes::math::quat_normalize_or_identity;
use kinegraph_nodes::model::{Clip, Mesh, forward_kinematics};
use serde_json::Value;

const SAMPLES: [&str; 4] = ["CesiumMan.glb", "Fox.glb", "RiggedSimple.glb", "SimpleSkin.gltf"];

/// The JSON document and binary buffers of a sample, decoded without the crate under test.
struct RawGltf {
    json: Value,
    buffers: Vec<Vec<u8>>,
}

fn raw(path: &Path) -> RawGltf {
    let bytes = std::fs::read(path).unwrap();
    let (json, bin): (Value, Option<Vec<u8>>) = if bytes.starts_with(b"glTF") {
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let json = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
        let bin_start = 20 + json_len;
        let bin = (bin_start + 8 <= bytes.len()).then(|| {
            let len = u32::from_le_bytes(bytes[bin_start..bin_start + 4].try_into().unwrap()) as usize;
            bytes[bin_start + 8..bin_start + 8 + len].to_vec()
        });
        (json, bin)
    } else {
        (serde_json::from_slice(&bytes).unwrap(), None)
    };
    use base64::Engine as _;
    let buffers = json["buffers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| match b["uri"].as_str() {
            Some(uri) => base64::engine::general_purpose::STANDARD.decode(uri.split_once(',').unwrap().1).unwrap(),
            None => bin.clone().unwrap(),
        })
        .collect();
    RawGltf { json, buffers }
}

impl RawGltf {
    /// A float accessor's values (these samples use plain float accessors for keys).
    fn floats(&self, index: usize) -> Vec<f32> {
        let a = &self.json["accessors"][index];
        assert_eq!(a["componentType"], 5126);
        let n = match a["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT4" => 16,
            t => panic!("{t}"),
        };
        let view = &self.json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let buf = &self.buffers[view["buffer"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let stride = view["byteStride"].as_u64().map(|s| s as usize).unwrap_or(4 * n);
        let count = a["count"].as_u64().unwrap() as usize;
        let mut out = Vec::new();
        for i in 0..count {
            for c in 0..n {
                let o = start + i * stride + 4 * c;
                out.push(f32::from_le_bytes(buf[o..o + 4].try_into().unwrap()));
            }
        }
        out
    }
}

fn samples() -> Option<Vec<PathBuf>> {
    let dir = shared_data()?.join("gltf");
    Some(SAMPLES.iter().map(|f| dir.join(f)).collect())
}

fn load(path: &Path) -> GltfAsset {
    let loaded = read_gltf_file(path, &GltfReadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{}: warnings {:?}", path.display(), loaded.warnings);
    loaded.value
}

#[test]
fn every_sample_loads_with_the_counts_its_json_states() {
    let Some(paths) = samples() else { return };
    for path in paths {
        let asset = load(&path);
        let r = raw(&path);
        let j = &r.json;
        let skin_joints = j["skins"][0]["joints"].as_array().unwrap().len();
        let skeleton = asset.skeleton.as_ref().unwrap();
        assert_eq!(skeleton.len(), skin_joints, "{}", path.display());
        let animations = j["animations"].as_array().unwrap();
        assert_eq!(asset.clips.len(), animations.len(), "{}", path.display());
        for (a, clip) in animations.iter().zip(&asset.clips) {
            if let Some(name) = a["name"].as_str() {
                assert_eq!(clip.name, name);
            }
            // Duration: from the earliest to the latest key of any input accessor.
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for s in a["samplers"].as_array().unwrap() {
                let times = r.floats(s["input"].as_u64().unwrap() as usize);
                lo = lo.min(times[0] as f64);
                hi = hi.max(*times.last().unwrap() as f64);
            }
            let c = &clip.clip;
            assert!(
                (c.duration_secs() - (hi - lo)).abs() <= 0.5 / c.fps() + 1e-6,
                "{}: {} vs {}",
                path.display(),
                c.duration_secs(),
                hi - lo
            );
            assert!((clip.start_secs - lo).abs() < 1e-6);
        }
        // Vertices: every node mesh's primitives' POSITION counts.
        let mut expected_vertices = Vec::new();
        for node in j["nodes"].as_array().unwrap() {
            if let Some(m) = node["mesh"].as_u64() {
                let count: u64 = j["meshes"][m as usize]["primitives"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| {
                        j["accessors"][p["attributes"]["POSITION"].as_u64().unwrap() as usize]["count"]
                            .as_u64()
                            .unwrap()
                    })
                    .sum();
                expected_vertices.push(count as usize);
            }
        }
        let got: Vec<usize> = asset.meshes.iter().map(|m| m.positions.len()).collect();
        assert_eq!(got, expected_vertices, "{}", path.display());
        for mesh in &asset.meshes {
            assert!(mesh.skin.is_some(), "{}: every sample mesh is skinned", path.display());
            assert_eq!(mesh.normals.len(), mesh.positions.len());
        }
    }
}

/// Frames that land on a key reproduce the key's raw value (non-root joints, whose local
/// transforms are the node's own; roots have their ancestors baked in).
#[test]
fn sampled_clips_equal_raw_keyframes_at_key_times() {
    let Some(paths) = samples() else { return };
    for path in paths {
        let asset = load(&path);
        let r = raw(&path);
        let mut checked = 0;
        for (a, clip) in r.json["animations"].as_array().unwrap().iter().zip(&asset.clips) {
            let c = &clip.clip;
            for ch in a["channels"].as_array().unwrap() {
                let node = ch["target"]["node"].as_u64().unwrap() as usize;
                let Some(joint) = asset.joint_nodes.iter().position(|&n| n == node) else {
                    continue;
                };
                if c.skeleton().joints()[joint].parent.is_none() {
                    continue;
                }
                let sampler = &a["samplers"][ch["sampler"].as_u64().unwrap() as usize];
                let times = r.floats(sampler["input"].as_u64().unwrap() as usize);
                let values = r.floats(sampler["output"].as_u64().unwrap() as usize);
                for (k, &t) in times.iter().enumerate() {
                    let f = (t as f64 - clip.start_secs) * c.fps();
                    if (f - f.round()).abs() > 1e-3 || f.round() as usize >= c.frame_count() {
                        continue;
                    }
                    let f = f.round() as usize;
                    match ch["target"]["path"].as_str().unwrap() {
                        "rotation" => {
                            // Files may store keys slightly off unit length; the clip holds unit quaternions.
                            let q = quat_normalize_or_identity(Quat::from_slice(&values[4 * k..4 * k + 4]));
                            let got = c.frame_rotations(f)[joint];
                            assert!(
                                got.dot(q).abs() > 1.0 - 1e-5,
                                "{} node {node} key {k}: {got} vs {q}",
                                path.display()
                            );
                            checked += 1;
                        }
                        "translation" => {
                            let t = Vec3::from_slice(&values[3 * k..3 * k + 3]);
                            let got = c.frame_translations(f)[joint];
                            assert!(
                                (got - t).length() < 1e-4 * t.length().max(1.0),
                                "{} node {node} key {k}: {got} vs {t}",
                                path.display()
                            );
                            checked += 1;
                        }
                        _ => {}
                    }
                }
            }
        }
        assert!(checked > 0, "{}: no key landed on a frame", path.display());
    }
}

/// Linear blend skinning with the rest pose's FK world matrices and the mesh's inverse
/// bind matrices reproduces the mesh's own positions.
#[test]
fn bind_pose_skinning_reproduces_mesh_positions() {
    let Some(paths) = samples() else { return };
    for path in paths {
        let asset = load(&path);
        let skeleton = asset.skeleton.clone().unwrap();
        let rest = Clip::rest_pose(skeleton.clone(), 30.0, 1).unwrap();
        let world: Vec<Mat4> = forward_kinematics(&rest).frame(0).iter().map(|t| t.to_mat4()).collect();
        for mesh in &asset.meshes {
            let skinned = skin_positions(mesh, &world);
            let (lo, hi) = mesh.bounds().unwrap();
            let tol = 1e-4 * (hi - lo).length();
            for (v, (p, s)) in mesh.positions.iter().zip(&skinned).enumerate() {
                assert!((*p - *s).length() < tol, "{} vertex {v}: {p} vs {s}", path.display());
            }
        }
    }
}

fn skin_positions(mesh: &Mesh, world_from_joint: &[Mat4]) -> Vec<Vec3> {
    let skin = mesh.skin.as_ref().unwrap();
    mesh.positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            let mut out = Vec4::ZERO;
            for k in 0..4 {
                let j = skin.joints[v][k] as usize;
                out += skin.weights[v][k] * (world_from_joint[j] * skin.inverse_bind_matrices[j] * p.extend(1.0));
            }
            out.truncate()
        })
        .collect()
}

/// Baking the `Z_UP`/`Armature` ancestors gives a character standing along +Y.
#[test]
fn cesium_man_stands_up_along_y() {
    let Some(dir) = shared_data() else { return };
    let asset = load(&dir.join("gltf/CesiumMan.glb"));
    let (lo, hi) = asset.meshes[0].bounds().unwrap();
    let size = hi - lo;
    assert!(size.y > 1.2 && size.y < 2.0 && size.y > size.x && size.y > size.z, "{size}");
    assert!(lo.y.abs() < 0.1, "feet at y = {}", lo.y);
}

/// Writing each sample's clips as GLB and reading them back reproduces every joint's FK
/// world position on every frame (within 1e-5 m, relative for models larger than a
/// metre), and the mesh.
#[test]
fn glb_round_trip_reproduces_world_positions() {
    let Some(paths) = samples() else { return };
    for path in paths {
        let asset = load(&path);
        for clip in &asset.clips {
            let glb = write_glb(&clip.clip, asset.meshes.first()).unwrap();
            let options = GltfReadOptions { sample_fps: Some(clip.clip.fps()), ..Default::default() };
            let back = read_gltf(&glb.value, Path::new("roundtrip.glb"), &options).unwrap().value;
            let c2 = &back.clips[0].clip;
            assert_eq!(c2.frame_count(), clip.clip.frame_count(), "{}", path.display());
            let (p1, p2) = (forward_kinematics(&clip.clip), forward_kinematics(c2));
            for f in 0..c2.frame_count() {
                for j in 0..c2.joint_count() {
                    // 1e-5 m, or f32 resolution for models far larger than a metre (Fox is
                    // ~100 units across: one f32 ulp at 64 is 7.6e-6).
                    let d = (p1.position(f, j) - p2.position(f, j)).length();
                    let tol = 1e-5 * p1.position(f, j).length().max(1.0);
                    assert!(d < tol, "{} '{}' frame {f} joint {j}: {d} m", path.display(), clip.name);
                }
            }
            let (m1, m2) = (&asset.meshes[0], &back.meshes[0]);
            assert_eq!(m1.triangles, m2.triangles);
            for (a, b) in m1.positions.iter().zip(&m2.positions) {
                assert!((*a - *b).length() < 1e-5);
            }
        }
    }
}

#[test]
fn every_obj_loads() {
    let Some(dir) = shared_data() else { return };
    let obj_dir = dir.join("obj");
    let mut files = Vec::new();
    for sub in std::fs::read_dir(&obj_dir).unwrap() {
        for f in std::fs::read_dir(sub.unwrap().path()).unwrap() {
            let p = f.unwrap().path();
            if p.extension().is_some_and(|e| e == "obj") {
                files.push(p);
            }
        }
    }
    files.sort();
    assert_eq!(files.len(), 4, "{files:?}");
    for path in files {
        let loaded = read_obj_file(&path, None).unwrap_or_else(|e| panic!("{e}"));
        // Independent count: a polygon of n corners is n - 2 triangles.
        let text = std::fs::read_to_string(&path).unwrap();
        let expected: usize =
            text.lines().filter(|l| l.starts_with("f ")).map(|l| l.split_whitespace().count() - 3).sum();
        let got: usize = loaded.value.iter().map(|m| m.triangles.len()).sum();
        assert_eq!(got, expected, "{}", path.display());
        for m in &loaded.value {
            assert_eq!(m.normals.len(), m.positions.len());
            assert!(m.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
        }
        eprintln!("{}: {} meshes, warnings {:?}", path.display(), loaded.value.len(), loaded.warnings.first());
        if path.ends_with("base.obj") {
            assert!(loaded.warnings.iter().any(|w| w.contains("dm")), "{:?}", loaded.warnings);
        }
    }
}
