//! Fuzz target `gltf_loader`: arbitrary bytes into the glTF reader, as JSON and as GLB.
//!
//! Each input is read twice:
//! 1. as given: bytes starting with the `glTF` magic are a GLB, anything else JSON text;
//! 2. wrapped in a well-formed GLB container: the bytes before the first NUL become the
//!    JSON chunk and the bytes after it the BIN chunk (JSON text never holds a raw NUL,
//!    so a seed is written as `{…json…}\0<binary buffer>`). Inputs that already are a
//!    GLB are not wrapped again.
//!
//! The reader must never panic. When it accepts a file, the clips it returns must hold
//! `frames × joints` samples on the asset's skeleton and every value must be finite.
//! The file path lies in a folder that does not exist, so external buffer URIs fail to
//! open instead of reading whatever happens to sit beside the fuzzer.

#![no_main]

use std::path::Path;

use kinegraph_nodes::formats::gltf::{GltfAsset, GltfReadOptions, read_gltf};
use libfuzzer_sys::fuzz_target;

/// Where the input pretends to live (the folder must not exist).
const FAKE_PATH: &str = "/nonexistent-kinegraph-fuzz/input.gltf";

/// GLB chunk type of the JSON chunk (`JSON` little-endian).
const CHUNK_JSON: u32 = 0x4E4F_534A;
/// GLB chunk type of the binary chunk (`BIN\0` little-endian).
const CHUNK_BIN: u32 = 0x004E_4942;

/// Builds a version-2 GLB around `json` and an optional `bin` chunk, padding each chunk
/// to four bytes (spaces for JSON, zeros for BIN) as the specification asks.
fn glb(json: &[u8], bin: Option<&[u8]>) -> Vec<u8> {
    let pad = |n: usize| (4 - n % 4) % 4;
    let json_len = json.len() + pad(json.len());
    let bin_len = bin.map(|b| b.len() + pad(b.len()));
    let total = 12 + 8 + json_len + bin_len.map_or(0, |n| 8 + n);
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_len as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(json);
    out.resize(out.len() + pad(json.len()), b' ');
    if let (Some(bin), Some(bin_len)) = (bin, bin_len) {
        out.extend_from_slice(&(bin_len as u32).to_le_bytes());
        out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
        out.extend_from_slice(bin);
        out.resize(out.len() + pad(bin.len()), 0);
    }
    out
}

/// Checks what an accepted file produced.
fn check(asset: &GltfAsset) {
    if let Some(skeleton) = &asset.skeleton {
        assert_eq!(asset.joint_nodes.len(), skeleton.len(), "one glTF node per skeleton joint");
        for (index, joint) in skeleton.joints().iter().enumerate() {
            assert!(joint.parent.is_none_or(|p| p < index), "joint {index} has its parent after it");
            assert!(joint.rest_offset.is_finite() && joint.rest_rotation.is_finite(), "joint {index} rest not finite");
        }
    }
    for clip in &asset.clips {
        let c = &clip.clip;
        assert!(c.fps().is_finite() && c.fps() > 0.0, "clip '{}' fps {}", clip.name, c.fps());
        assert!(clip.start_secs.is_finite(), "clip '{}' start {}", clip.name, clip.start_secs);
        assert_eq!(c.frame_count() * c.joint_count(), c.rotations().len(), "clip '{}' rotation count", clip.name);
        assert_eq!(c.rotations().len(), c.translations().len(), "clip '{}' translation count", clip.name);
        if let Some(skeleton) = &asset.skeleton {
            assert_eq!(c.joint_count(), skeleton.len(), "clip '{}' is on another skeleton", clip.name);
        }
        assert!(c.rotations().iter().all(|q| q.is_finite()), "clip '{}' has a non-finite rotation", clip.name);
        assert!(c.translations().iter().all(|t| t.is_finite()), "clip '{}' has a non-finite translation", clip.name);
    }
    for mesh in &asset.meshes {
        let vertices = mesh.positions.len();
        assert!(mesh.positions.iter().all(|p| p.is_finite()), "mesh '{}' has a non-finite position", mesh.name);
        assert_eq!(mesh.normals.len(), vertices, "mesh '{}' normal count", mesh.name);
        if let Err(e) = mesh.check_material_ranges() {
            panic!("mesh '{}': {e}", mesh.name);
        }
        if let Some(uvs) = &mesh.uvs {
            assert_eq!(uvs.len(), vertices, "mesh '{}' uv count", mesh.name);
        }
        for t in &mesh.triangles {
            assert!(t.iter().all(|&v| (v as usize) < vertices), "mesh '{}' triangle {t:?} out of range", mesh.name);
        }
        if let Some(skin) = &mesh.skin {
            assert_eq!(skin.joints.len(), vertices, "mesh '{}' skin joint count", mesh.name);
            assert_eq!(skin.weights.len(), vertices, "mesh '{}' skin weight count", mesh.name);
            let joints = skin.skeleton.len();
            for (v, idx) in skin.joints.iter().enumerate() {
                assert!(idx.iter().all(|&j| (j as usize) < joints), "mesh '{}' vertex {v} joint {idx:?}", mesh.name);
            }
        }
    }
}

/// The memory limit the reader is given, as `kg --max-memory` would: a few kilobytes of
/// keys may legitimately ask for the default limit (1.4 GB, seconds of sampling), which
/// would only slow the search; the refusal path is what is tested.
const MAX_CLIP_BYTES: u64 = 64 << 20;

fuzz_target!(|data: &[u8]| {
    // Materials on: their textures, samplers and images are user data too.
    let options = GltfReadOptions { max_clip_bytes: Some(MAX_CLIP_BYTES), materials: true, ..Default::default() };
    let path = Path::new(FAKE_PATH);
    if let Ok(loaded) = read_gltf(data, path, &options) {
        check(&loaded.value);
    }
    if !data.starts_with(b"glTF") {
        let (json, bin) = match data.iter().position(|&b| b == 0) {
            Some(nul) => (&data[..nul], Some(&data[nul + 1..])),
            None => (data, None),
        };
        if let Ok(loaded) = read_gltf(&glb(json, bin), path, &options) {
            check(&loaded.value);
        }
    }
});
