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
use json::mesh::{MorphTarget, Semantic};
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
    let mesh = b.triangle_mesh(&rest.name, attributes, &rest.triangles, n, Some(targets), Some(vec![0.0; frames]));
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
    let bytes = b.finish().map_err(|m| err(Kind::Unsupported, m))?.into_bytes();
    Ok(Loaded { value: bytes, warnings })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use std::sync::Arc;

    use super::*;
    use crate::model::{Clip, Joint, Mesh, Skeleton};

    #[test]
    fn frames_become_morph_targets_played_by_a_weights_animation() {
        let skeleton = Arc::new(Skeleton::new(vec![Joint::new("root", None, Vec3::ZERO)]).unwrap());
        let clip = Arc::new(Clip::rest_pose(skeleton, 10.0, 3).unwrap());
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let rest = Arc::new(Mesh {
            name: "tri".into(),
            normals: vec![Vec3::Z; 3],
            positions: positions.clone(),
            triangles: vec![[0, 1, 2]],
            ..Mesh::default()
        });
        let frames: Vec<Vec3> = (0..3).flat_map(|f| positions.iter().map(move |p| *p + Vec3::Z * f as f32)).collect();
        let seq = MeshSequence::new(rest, clip, frames, vec![Vec3::Z; 9]).unwrap();
        let bytes = write_sequence_glb(&seq).unwrap().value;
        let (document, buffers, _) = gltf::import_slice(&bytes).unwrap();
        let primitive = document.meshes().next().unwrap().primitives().next().unwrap();
        assert_eq!(primitive.morph_targets().count(), 3);
        // Target 2 moves every vertex by +2 in z (frame 2 minus frame 0).
        let reader = primitive.reader(|b| Some(&buffers[b.index()]));
        let target = reader.read_morph_targets().nth(2).unwrap();
        assert!(target.0.unwrap().all(|d| d == [0.0, 0.0, 2.0]));
        let animation = document.animations().next().unwrap();
        let channel = animation.channels().next().unwrap();
        assert_eq!(channel.target().property(), gltf::animation::Property::MorphTargetWeights);
        let times: Vec<f32> = match channel.reader(|b| Some(&buffers[b.index()])).read_inputs() {
            Some(t) => t.collect(),
            None => Vec::new(),
        };
        assert_eq!(times, vec![0.0, 0.1, 0.2]);
    }
}
