//! GLB writer: a clip's skeleton as a node hierarchy, the clip as one animation, and
//! optionally a skinned mesh bound to it.
//!
//! Layout: node `j` is skeleton joint `j` (end sites included, harmless), with the joint's
//! rest offset and rest rotation as its TRS. A skeleton with several roots gets one extra
//! unanimated parent node so the skin's joints share a root. The animation has one shared
//! time input (`frame / fps` seconds, with min/max), one LINEAR rotation channel per joint
//! and a LINEAR translation channel for every joint whose translation leaves its rest
//! offset. The mesh node (when given) is a scene root without a transform, as the spec asks
//! of skinned meshes.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{Mat4, Vec3, Vec4};
use gltf_json as json;
use json::accessor::Type;
use json::animation::{Interpolation, Property};
use json::buffer::Target;
use json::mesh::Semantic;
use json::validation::Checked::Valid;

use crate::formats::atomic::write_atomic_with;
use crate::formats::error::{FormatError, FormatErrorKind as Kind, Loaded};
use crate::math::quat_normalize_or_identity;
use crate::model::fk::rest_world;
use crate::model::{Clip, Mesh};

use super::builder::{Bounds, GlbBuilder, GlbChunks};

/// The stand-in file name in errors from [`write_glb`], which has no file.
const IN_MEMORY: &str = "<glb>";

/// Serialises `clip` (and `mesh`, skinned or not) as GLB bytes, with warnings for
/// anything left out (an empty clip writes no animation).
///
/// Errors: a mesh whose skin is bound to a different skeleton, non-finite mesh data, or a
/// file too large for GLB.
pub fn write_glb(clip: &Clip, mesh: Option<&Mesh>) -> Result<Loaded<Vec<u8>>, FormatError> {
    let built = build_glb(clip, mesh)?;
    Ok(Loaded { value: built.value.into_bytes(), warnings: built.warnings })
}

/// [`write_glb`]'s document, finished but not yet serialised: stream it into a file with
/// [`GlbChunks::write_to`].
pub fn build_glb(clip: &Clip, mesh: Option<&Mesh>) -> Result<Loaded<GlbChunks>, FormatError> {
    let path = Path::new(IN_MEMORY);
    let err = |kind: Kind, message: String| FormatError::file(path, kind, message);
    let skeleton = clip.skeleton();
    let joints = skeleton.joints();
    let mut warnings = Vec::new();
    let mut b = GlbBuilder::new(concat!("kinegraph ", env!("CARGO_PKG_VERSION")));

    // Nodes: one per joint.
    let mut children: Vec<Vec<json::Index<json::Node>>> = vec![Vec::new(); joints.len()];
    for (j, joint) in joints.iter().enumerate() {
        if let Some(p) = joint.parent {
            children[p].push(json::Index::new(j as u32));
        }
    }
    for (j, joint) in joints.iter().enumerate() {
        let rotation = quat_normalize_or_identity(joint.rest_rotation);
        b.root.push(json::Node {
            name: Some(joint.name.clone()),
            translation: Some(joint.rest_offset.to_array()),
            rotation: Some(json::scene::UnitQuaternion(rotation.to_array())),
            children: (!children[j].is_empty()).then(|| std::mem::take(&mut children[j])),
            ..Default::default()
        });
    }
    let roots: Vec<json::Index<json::Node>> = joints
        .iter()
        .enumerate()
        .filter(|(_, j)| j.parent.is_none())
        .map(|(i, _)| json::Index::new(i as u32))
        .collect();
    let mut scene_nodes = if roots.len() > 1 {
        vec![b.root.push(json::Node {
            name: Some("kinegraph_skeleton".into()),
            children: Some(roots),
            ..Default::default()
        })]
    } else {
        roots
    };

    // Animation.
    let frames = clip.frame_count();
    if frames == 0 {
        warnings.push("the clip has no frames; no animation written".to_string());
    } else {
        let times: Vec<f32> = (0..frames).map(|f| (f as f64 / clip.fps()) as f32).collect();
        let input = b.accessor_f32(&times, Type::Scalar, None, Bounds::Record);
        let mut samplers = Vec::new();
        let mut channels = Vec::new();
        let jc = clip.joint_count();
        let mut add_channel = |b: &mut GlbBuilder, j: usize, property: Property, values: Vec<f32>, type_: Type| {
            let output = b.accessor_f32(&values, type_, None, Bounds::Omit);
            let sampler = json::Index::new(samplers.len() as u32);
            samplers.push(json::animation::Sampler {
                extensions: Default::default(),
                extras: Default::default(),
                input,
                interpolation: Valid(Interpolation::Linear),
                output,
            });
            channels.push(json::animation::Channel {
                sampler,
                target: json::animation::Target {
                    extensions: Default::default(),
                    extras: Default::default(),
                    node: json::Index::new(j as u32),
                    path: Valid(property),
                },
                extensions: Default::default(),
                extras: Default::default(),
            });
        };
        for j in 0..joints.len() {
            let mut rotations = Vec::with_capacity(frames * 4);
            let mut previous: Option<glam::Quat> = None;
            for f in 0..frames {
                let mut q = quat_normalize_or_identity(clip.rotations()[f * jc + j]);
                // Keep consecutive keys in one hemisphere so LINEAR takes the short arc.
                if let Some(p) = previous
                    && p.dot(q) < 0.0
                {
                    q = -q;
                }
                previous = Some(q);
                rotations.extend_from_slice(&q.to_array());
            }
            add_channel(&mut b, j, Property::Rotation, rotations, Type::Vec4);
            if clip.translation_is_animated(j) {
                let translations: Vec<f32> =
                    (0..frames).flat_map(|f| clip.translations()[f * jc + j].to_array()).collect();
                add_channel(&mut b, j, Property::Translation, translations, Type::Vec3);
            }
        }
        b.root.push(json::Animation {
            extensions: Default::default(),
            extras: Default::default(),
            channels,
            name: Some("clip".into()),
            samplers,
        });
    }

    // Mesh.
    let mut skinned = false;
    if let Some(mesh) = mesh {
        match write_mesh(&mut b, clip, mesh, &mut warnings) {
            Ok(Some(node)) => {
                skinned = mesh.skin.is_some();
                if !skinned && frames > 1 {
                    warnings.push(format!(
                        "mesh '{}' has no skin: it is written standing still at the origin and will not follow the animated skeleton (load a skinned mesh, or bind it with skin.bind)",
                        mesh.name
                    ));
                }
                scene_nodes.push(node);
            }
            Ok(None) => {}
            Err((kind, message)) => return Err(err(kind, message)),
        }
    }
    if !skinned {
        // A skin with no mesh marks the joints as a skeleton, so DCCs (Blender) import an
        // armature rather than a tree of empties.
        let ibm: Vec<f32> = rest_world(skeleton).iter().flat_map(|t| t.inverse_to_mat4().to_cols_array()).collect();
        let inverse_bind_matrices = Some(b.accessor_f32(&ibm, Type::Mat4, None, Bounds::Omit));
        b.root.push(json::Skin {
            extensions: Default::default(),
            extras: Default::default(),
            inverse_bind_matrices,
            joints: (0..joints.len() as u32).map(json::Index::new).collect(),
            name: Some("skeleton".into()),
            skeleton: None,
        });
    }

    let scene = b.root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: scene_nodes,
    });
    b.root.scene = Some(scene);
    let chunks = b.finish().map_err(|m| err(Kind::Unsupported, m))?;
    Ok(Loaded { value: chunks, warnings })
}

/// Writes `write_glb(clip, mesh)` to `path` atomically; returns the warnings.
pub fn write_glb_file(path: &Path, clip: &Clip, mesh: Option<&Mesh>) -> Result<Vec<String>, FormatError> {
    let built = build_glb(clip, mesh).map_err(|e| FormatError { file: path.to_path_buf(), ..e })?;
    write_atomic_with(path, |out| built.value.write_to(out))?;
    Ok(built.warnings)
}

/// Adds `mesh` (and its skin) to the document; returns its node.
fn write_mesh(
    b: &mut GlbBuilder,
    clip: &Clip,
    mesh: &Mesh,
    warnings: &mut Vec<String>,
) -> Result<Option<json::Index<json::Node>>, (Kind, String)> {
    let n = mesh.positions.len();
    if n == 0 || mesh.triangles.is_empty() {
        warnings.push(format!("mesh '{}' has no triangles; not written", mesh.name));
        return Ok(None);
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err((Kind::Value, format!("mesh '{}' has a non-finite position", mesh.name)));
    }
    if let Some(t) = mesh.triangles.iter().position(|t| t.iter().any(|&i| i as usize >= n)) {
        return Err((Kind::Structure, format!("mesh '{}' triangle {t} indexes past its {n} vertices", mesh.name)));
    }
    let mut attributes = BTreeMap::new();
    let positions: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    attributes.insert(
        Valid(Semantic::Positions),
        b.accessor_f32(&positions, Type::Vec3, Some(Target::ArrayBuffer), Bounds::Record),
    );
    let normals_source = if mesh.normals.len() == n {
        mesh.normals.clone()
    } else {
        warnings.push(format!("mesh '{}': normals missing or miscounted; recomputed", mesh.name));
        Mesh::compute_normals(&mesh.positions, &mesh.triangles)
    };
    let normals: Vec<f32> =
        normals_source.iter().flat_map(|v| v.try_normalize().unwrap_or(Vec3::Y).to_array()).collect();
    attributes.insert(
        Valid(Semantic::Normals),
        b.accessor_f32(&normals, Type::Vec3, Some(Target::ArrayBuffer), Bounds::Omit),
    );
    if let Some(uvs) = &mesh.uvs {
        if uvs.len() == n && uvs.iter().all(|u| u.is_finite()) {
            let uv: Vec<f32> = uvs.iter().flat_map(|u| u.to_array()).collect();
            attributes.insert(
                Valid(Semantic::TexCoords(0)),
                b.accessor_f32(&uv, Type::Vec2, Some(Target::ArrayBuffer), Bounds::Omit),
            );
        } else {
            warnings.push(format!("mesh '{}': UVs miscounted or non-finite; not written", mesh.name));
        }
    }

    let mut skin_index = None;
    if let Some(skin) = &mesh.skin {
        let skeleton = clip.skeleton();
        let same = skin.skeleton.len() == skeleton.len()
            && skin
                .skeleton
                .joints()
                .iter()
                .zip(skeleton.joints())
                .all(|(a, b)| a.name == b.name && a.parent == b.parent);
        if !same {
            return Err((
                Kind::Structure,
                format!("mesh '{}' is skinned to a different skeleton than the clip's", mesh.name),
            ));
        }
        if skin.joints.len() != n || skin.weights.len() != n || skin.inverse_bind_matrices.len() != skeleton.len() {
            return Err((
                Kind::Structure,
                format!("mesh '{}': skin arrays do not match the vertex and joint counts", mesh.name),
            ));
        }
        let mut joint_data = Vec::with_capacity(n * 4);
        let mut weight_data = Vec::with_capacity(n * 4);
        for (v, (js, ws)) in skin.joints.iter().zip(&skin.weights).enumerate() {
            // Merge repeated joints, drop zero weights, renormalise.
            let mut row: Vec<(u16, f32)> = Vec::with_capacity(4);
            for (&j, &w) in js.iter().zip(ws) {
                if !(w.is_finite() && w > 0.0) {
                    continue;
                }
                if j as usize >= skeleton.len() {
                    return Err((
                        Kind::Structure,
                        format!("mesh '{}' vertex {v}: joint {j} outside the skeleton", mesh.name),
                    ));
                }
                match row.iter_mut().find(|(k, _)| *k == j) {
                    Some(e) => e.1 += w,
                    None => row.push((j, w)),
                }
            }
            let sum: f32 = row.iter().map(|e| e.1).sum();
            if row.is_empty() || sum <= 0.0 {
                return Err((Kind::Value, format!("mesh '{}' vertex {v} has no positive weight", mesh.name)));
            }
            let mut jrow = [0u16; 4];
            let mut wrow = [0f32; 4];
            for (k, (j, w)) in row.iter().enumerate() {
                jrow[k] = *j;
                wrow[k] = *w / sum;
            }
            // Put f32 rounding into the largest weight so the row sums to one.
            let rest: f32 = wrow[1..].iter().sum();
            wrow[0] = 1.0 - rest;
            joint_data.extend_from_slice(&jrow);
            weight_data.extend_from_slice(&wrow);
        }
        attributes
            .insert(Valid(Semantic::Joints(0)), b.accessor_u16(&joint_data, Type::Vec4, Some(Target::ArrayBuffer)));
        attributes.insert(
            Valid(Semantic::Weights(0)),
            b.accessor_f32(&weight_data, Type::Vec4, Some(Target::ArrayBuffer), Bounds::Omit),
        );
        let mut ibm = Vec::with_capacity(skeleton.len() * 16);
        for m in &skin.inverse_bind_matrices {
            if !m.is_finite() {
                return Err((Kind::Value, format!("mesh '{}' has a non-finite inverse bind matrix", mesh.name)));
            }
            // An affine matrix's last row is exactly (0, 0, 0, 1) in glTF.
            let mut m: Mat4 = *m;
            m.x_axis = Vec4::new(m.x_axis.x, m.x_axis.y, m.x_axis.z, 0.0);
            m.y_axis = Vec4::new(m.y_axis.x, m.y_axis.y, m.y_axis.z, 0.0);
            m.z_axis = Vec4::new(m.z_axis.x, m.z_axis.y, m.z_axis.z, 0.0);
            m.w_axis.w = 1.0;
            ibm.extend_from_slice(&m.to_cols_array());
        }
        let ibm_accessor = b.accessor_f32(&ibm, Type::Mat4, None, Bounds::Omit);
        skin_index = Some(b.root.push(json::Skin {
            extensions: Default::default(),
            extras: Default::default(),
            inverse_bind_matrices: Some(ibm_accessor),
            joints: (0..skeleton.len() as u32).map(json::Index::new).collect(),
            name: None,
            skeleton: None,
        }));
    }

    let gmesh = b.triangle_mesh(&mesh.name, attributes, &mesh.triangles, n, None, None);
    let node = b.root.push(json::Node {
        name: Some(mesh.name.clone()),
        mesh: Some(gmesh),
        skin: skin_index,
        ..Default::default()
    });
    Ok(Some(node))
}
