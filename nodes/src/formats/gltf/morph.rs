//! GLB writer for baked mesh sequences (PSD, WPSD, bar-net output): one mesh whose frames
//! are morph targets, animated by a weights channel.
//!
//! Why morph targets: a baked sequence has no joints that could reproduce it, and glTF has
//! no per-frame vertex streams; morph targets are the standard way every viewer and DCC
//! (Blender, three.js, Unity) plays per-vertex animation from one self-contained file.
//! Layout: the mesh's base is frame 0; target `f` holds frame `f` minus frame 0 (positions
//! and normals); the animation keys weight `f` to one at frame `f`'s time and the others
//! to zero, with LINEAR interpolation, so playback between frames blends neighbouring
//! frames linearly. The weights output is frames × frames floats, fine for the clips this
//! is meant for (a few hundred frames); longer ones get a warning.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use gltf_json as json;
use json::accessor::Type;
use json::animation::{Interpolation, Property};
use json::buffer::Target;
use json::mesh::{Mode, MorphTarget, Semantic};
use json::validation::Checked::Valid;

use super::builder::{Bounds, GlbBuilder};
use crate::formats::error::{FormatError, FormatErrorKind as Kind, Loaded};
use crate::model::MeshSequence;

/// Above this many frames the quadratic weights table gets a warning.
const LARGE_FRAME_COUNT: usize = 600;

/// Serialises `sequence` as GLB bytes (see the module docs for the layout).
pub fn write_sequence_glb(sequence: &MeshSequence) -> Result<Loaded<Vec<u8>>, FormatError> {
    let err = |kind: Kind, message: String| FormatError::file(Path::new("<glb>"), kind, message);
    let frames = sequence.frame_count();
    let n = sequence.vertex_count();
    let rest = &sequence.rest;
    if frames == 0 || n == 0 || rest.triangles.is_empty() {
        return Err(err(Kind::Value, "the mesh sequence has no frames or no triangles to write".into()));
    }
    if let Some(t) = rest.triangles.iter().position(|t| t.iter().any(|&i| i as usize >= n)) {
        return Err(err(Kind::Structure, format!("triangle {t} indexes past the {n} vertices")));
    }
    let mut warnings = Vec::new();
    if frames > LARGE_FRAME_COUNT {
        warnings.push(format!("{frames} frames: the morph weights table has {} entries", frames * frames));
    }
    let mut b = GlbBuilder::new(concat!("kinegraph ", env!("CARGO_PKG_VERSION")));
    let flat = |v: &[Vec3]| -> Vec<f32> { v.iter().flat_map(|p| p.to_array()).collect() };
    let (base_p, base_n) = (sequence.frame_positions(0), sequence.frame_normals(0));
    let mut attributes = BTreeMap::new();
    attributes.insert(
        Valid(Semantic::Positions),
        b.accessor_f32(&flat(base_p), Type::Vec3, Some(Target::ArrayBuffer), Bounds::Record),
    );
    attributes.insert(
        Valid(Semantic::Normals),
        b.accessor_f32(&flat(base_n), Type::Vec3, Some(Target::ArrayBuffer), Bounds::Omit),
    );
    if let Some(uvs) = rest.uvs.as_ref().filter(|u| u.len() == n && u.iter().all(|x| x.is_finite())) {
        let uv: Vec<f32> = uvs.iter().flat_map(|u| u.to_array()).collect();
        attributes.insert(
            Valid(Semantic::TexCoords(0)),
            b.accessor_f32(&uv, Type::Vec2, Some(Target::ArrayBuffer), Bounds::Omit),
        );
    }
    let mut targets = Vec::with_capacity(frames);
    for f in 0..frames {
        let dp: Vec<Vec3> = sequence.frame_positions(f).iter().zip(base_p).map(|(p, q)| *p - *q).collect();
        let dn: Vec<Vec3> = sequence.frame_normals(f).iter().zip(base_n).map(|(p, q)| *p - *q).collect();
        targets.push(MorphTarget {
            positions: Some(b.accessor_f32(&flat(&dp), Type::Vec3, Some(Target::ArrayBuffer), Bounds::Record)),
            normals: Some(b.accessor_f32(&flat(&dn), Type::Vec3, Some(Target::ArrayBuffer), Bounds::Omit)),
            tangents: None,
        });
    }
    let indices: Vec<u32> = rest.triangles.iter().flatten().copied().collect();
    let indices = b.accessor_u32(&indices, Some(Target::ElementArrayBuffer));
    let mesh = b.root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some(rest.name.clone()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(indices),
            material: None,
            mode: Valid(Mode::Triangles),
            targets: Some(targets),
        }],
        weights: Some(vec![0.0; frames]),
    });
    let node = b.root.push(json::Node { name: Some(rest.name.clone()), mesh: Some(mesh), ..Default::default() });

    let fps = sequence.clip.fps();
    let times: Vec<f32> = (0..frames).map(|f| (f as f64 / fps) as f32).collect();
    let input = b.accessor_f32(&times, Type::Scalar, None, Bounds::Record);
    let weights: Vec<f32> = (0..frames * frames).map(|e| if e / frames == e % frames { 1.0 } else { 0.0 }).collect();
    let output = b.accessor_f32(&weights, Type::Scalar, None, Bounds::Omit);
    b.root.push(json::Animation {
        extensions: Default::default(),
        extras: Default::default(),
        channels: vec![json::animation::Channel {
            sampler: json::Index::new(0),
            target: json::animation::Target {
                extensions: Default::default(),
                extras: Default::default(),
                node,
                path: Valid(Property::MorphTargetWeights),
            },
            extensions: Default::default(),
            extras: Default::default(),
        }],
        name: Some("sequence".into()),
        samplers: vec![json::animation::Sampler {
            extensions: Default::default(),
            extras: Default::default(),
            input,
            interpolation: Valid(Interpolation::Linear),
            output,
        }],
    });
    let scene = b.root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: vec![node],
    });
    b.root.scene = Some(scene);
    let bytes = b.finish().map_err(|m| err(Kind::Unsupported, m))?;
    Ok(Loaded { value: bytes, warnings })
}
