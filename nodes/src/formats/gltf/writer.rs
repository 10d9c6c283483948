//! GLB writer: a clip's skeleton as a node hierarchy, one or more named animations of it,
//! and optionally a skinned mesh bound to it, one primitive per material.
//!
//! Layout: node `j` is skeleton joint `j` (end sites included, harmless), with the joint's
//! rest offset and rest rotation as its TRS. A skeleton with several roots gets one extra
//! unanimated parent node so the skin's joints share a root. Each animation has one shared
//! time input (`frame / fps` seconds, with min/max), one LINEAR rotation channel per joint
//! and a LINEAR translation channel for every joint whose translation leaves its rest
//! offset in any animation. The mesh node (when given) is a scene root without a
//! transform, as the spec asks of skinned meshes. A mesh without materials is one
//! primitive over all its vertices; with materials, each material's triangles are one
//! primitive over the vertices they use, and images are embedded in the binary chunk.

use std::borrow::Cow;
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
use crate::model::{Clip, Material, Mesh, Skeleton, Skin};

use super::builder::{Bounds, GlbBuilder, GlbChunks};
use super::material::write_materials;

/// The stand-in file name in errors from [`write_glb`], which has no file.
const IN_MEMORY: &str = "<glb>";

/// Name of the animation [`write_glb`] and [`build_glb`] write.
pub const DEFAULT_ANIMATION_NAME: &str = "clip";

/// One animation of a GLB being written.
#[derive(Clone, Copy, Debug)]
pub struct GlbAnimation<'a> {
    /// The animation's name in the file.
    pub name: &'a str,
    /// Its clip; every animation of a file moves the same skeleton (joint names and
    /// parents), the first one's, whose rest pose the nodes get.
    pub clip: &'a Clip,
}

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
    build_glb_animations(&[GlbAnimation { name: DEFAULT_ANIMATION_NAME, clip }], mesh)
}

/// Like [`build_glb`] with several named animations of one skeleton in one file. Each
/// animation is complete on its own: every joint gets a rotation channel, and a joint
/// whose translation moves in any of them gets a translation channel in all of them, so a
/// viewer switching animations never keeps a position left over from another.
///
/// Errors: no animations, two with one name, an animation on another skeleton, and
/// everything [`build_glb`] refuses.
pub fn build_glb_animations(
    animations: &[GlbAnimation<'_>],
    mesh: Option<&Mesh>,
) -> Result<Loaded<GlbChunks>, FormatError> {
    let path = Path::new(IN_MEMORY);
    let err = |kind: Kind, message: String| FormatError::file(path, kind, message);
    let Some(first) = animations.first() else {
        return Err(err(Kind::Structure, "no animation to write".into()));
    };
    let skeleton = first.clip.skeleton();
    let joints = skeleton.joints();
    for (k, a) in animations.iter().enumerate() {
        if animations[..k].iter().any(|b| b.name == a.name) {
            return Err(err(Kind::Value, format!("two animations are named '{}'", a.name)));
        }
        if !a.clip.skeleton().same_hierarchy(skeleton) {
            return Err(err(
                Kind::Structure,
                format!("animation '{}' moves another skeleton than animation '{}'", a.name, first.name),
            ));
        }
    }
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

    // Animations.
    let moved: Vec<bool> = (0..joints.len())
        .map(|j| animations.iter().any(|a| a.clip.translation_leaves(j, joints[j].rest_offset)))
        .collect();
    let mut animated = false;
    for a in animations {
        if a.clip.frame_count() == 0 {
            let which = if animations.len() == 1 { "the clip".to_owned() } else { format!("animation '{}'", a.name) };
            warnings.push(format!("{which} has no frames; no animation written"));
            continue;
        }
        animated |= a.clip.frame_count() > 1;
        write_animation(&mut b, a, &moved);
    }

    // Mesh.
    let mut skinned = false;
    if let Some(mesh) = mesh {
        match write_mesh(&mut b, skeleton, mesh, &mut warnings) {
            Ok(Some(node)) => {
                skinned = mesh.skin.is_some();
                if !skinned && animated {
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

/// Writes one animation: a shared time input (`frame / fps` seconds), a LINEAR rotation
/// channel per joint and a translation channel for each joint `moved` marks.
fn write_animation(b: &mut GlbBuilder, animation: &GlbAnimation<'_>, moved: &[bool]) {
    let clip = animation.clip;
    let frames = clip.frame_count();
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
    for (j, &moved) in moved.iter().enumerate().take(jc) {
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
        add_channel(b, j, Property::Rotation, rotations, Type::Vec4);
        if moved {
            let translations: Vec<f32> = (0..frames).flat_map(|f| clip.translations()[f * jc + j].to_array()).collect();
            add_channel(b, j, Property::Translation, translations, Type::Vec3);
        }
    }
    b.root.push(json::Animation {
        extensions: Default::default(),
        extras: Default::default(),
        channels,
        name: Some(animation.name.to_owned()),
        samplers,
    });
}

/// Writes `write_glb(clip, mesh)` to `path` atomically; returns the warnings.
pub fn write_glb_file(path: &Path, clip: &Clip, mesh: Option<&Mesh>) -> Result<Vec<String>, FormatError> {
    let built = build_glb(clip, mesh).map_err(|e| FormatError { file: path.to_path_buf(), ..e })?;
    write_atomic_with(path, |out| built.value.write_to(out))?;
    Ok(built.warnings)
}

/// One primitive to write: the vertices it uses (`None`: all, in order), its triangles
/// over those vertices, and its material index in the mesh.
struct Part {
    vertices: Option<Vec<u32>>,
    triangles: Vec<[u32; 3]>,
    material: Option<usize>,
}

/// Splits `mesh` into one part per material, in the order the materials first appear;
/// each part keeps the vertices its triangles use, in their original order. A mesh
/// without material ranges is one part over all its vertices.
fn parts_by_material(mesh: &Mesh) -> Vec<Part> {
    if mesh.material_ranges.is_empty() {
        return vec![Part { vertices: None, triangles: mesh.triangles.clone(), material: None }];
    }
    let mut order: Vec<Option<usize>> = Vec::new();
    for r in &mesh.material_ranges {
        if !order.contains(&r.material) {
            order.push(r.material);
        }
    }
    if order.len() == 1 {
        return vec![Part { vertices: None, triangles: mesh.triangles.clone(), material: order[0] }];
    }
    let n = mesh.positions.len();
    order
        .into_iter()
        .map(|material| {
            let triangles: Vec<[u32; 3]> = mesh
                .material_ranges
                .iter()
                .filter(|r| r.material == material)
                .flat_map(|r| &mesh.triangles[r.first_triangle..r.first_triangle + r.triangle_count])
                .copied()
                .collect();
            let mut used = vec![false; n];
            for &i in triangles.iter().flatten() {
                used[i as usize] = true;
            }
            let vertices: Vec<u32> = (0..n as u32).filter(|&v| used[v as usize]).collect();
            let mut local = vec![0u32; n];
            for (k, &v) in vertices.iter().enumerate() {
                local[v as usize] = k as u32;
            }
            let triangles = triangles.iter().map(|t| t.map(|i| local[i as usize])).collect();
            Part { vertices: Some(vertices), triangles, material }
        })
        .collect()
}

/// `values` (`width` numbers per vertex) of the vertices `part` uses.
fn gather<T: Copy>(values: &[T], width: usize, vertices: &Option<Vec<u32>>) -> Vec<T> {
    match vertices {
        None => values.to_vec(),
        Some(vs) => vs.iter().flat_map(|&v| &values[v as usize * width..(v as usize + 1) * width]).copied().collect(),
    }
}

/// Adds `mesh` (and its skin) to the document: one primitive per material, each with its
/// material; returns its node.
fn write_mesh(
    b: &mut GlbBuilder,
    skeleton: &Skeleton,
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
    mesh.check_material_ranges().map_err(|m| (Kind::Structure, format!("mesh '{}': {m}", mesh.name)))?;
    let positions: Vec<f32> = mesh.positions.iter().flat_map(|p| p.to_array()).collect();
    let normals_source = if mesh.normals.len() == n {
        mesh.normals.clone()
    } else {
        warnings.push(format!("mesh '{}': normals missing or miscounted; recomputed", mesh.name));
        Mesh::compute_normals(&mesh.positions, &mesh.triangles)
    };
    let normals: Vec<f32> =
        normals_source.iter().flat_map(|v| v.try_normalize().unwrap_or(Vec3::Y).to_array()).collect();
    let uvs: Option<Vec<f32>> = match &mesh.uvs {
        Some(uvs) if uvs.len() == n && uvs.iter().all(|u| u.is_finite()) => {
            Some(uvs.iter().flat_map(|u| u.to_array()).collect())
        }
        Some(_) => {
            warnings.push(format!("mesh '{}': UVs miscounted or non-finite; not written", mesh.name));
            None
        }
        None => None,
    };
    let skin_data = match &mesh.skin {
        Some(skin) => Some(skin_rows(mesh, skin, skeleton)?),
        None => None,
    };

    let parts = parts_by_material(mesh);
    let mut attribute_sets = Vec::with_capacity(parts.len());
    for part in &parts {
        let mut attributes = BTreeMap::new();
        attributes.insert(
            Valid(Semantic::Positions),
            b.accessor_f32(
                &gather(&positions, 3, &part.vertices),
                Type::Vec3,
                Some(Target::ArrayBuffer),
                Bounds::Record,
            ),
        );
        attributes.insert(
            Valid(Semantic::Normals),
            b.accessor_f32(&gather(&normals, 3, &part.vertices), Type::Vec3, Some(Target::ArrayBuffer), Bounds::Omit),
        );
        if let Some(uv) = &uvs {
            attributes.insert(
                Valid(Semantic::TexCoords(0)),
                b.accessor_f32(&gather(uv, 2, &part.vertices), Type::Vec2, Some(Target::ArrayBuffer), Bounds::Omit),
            );
        }
        if let Some(rows) = &skin_data {
            attributes.insert(
                Valid(Semantic::Joints(0)),
                b.accessor_u16(&gather(&rows.joints, 4, &part.vertices), Type::Vec4, Some(Target::ArrayBuffer)),
            );
            attributes.insert(
                Valid(Semantic::Weights(0)),
                b.accessor_f32(
                    &gather(&rows.weights, 4, &part.vertices),
                    Type::Vec4,
                    Some(Target::ArrayBuffer),
                    Bounds::Omit,
                ),
            );
        }
        attribute_sets.push(attributes);
    }

    let mut skin_index = None;
    if let Some(rows) = &skin_data {
        let ibm_accessor = b.accessor_f32(&rows.inverse_bind_matrices, Type::Mat4, None, Bounds::Omit);
        skin_index = Some(b.root.push(json::Skin {
            extensions: Default::default(),
            extras: Default::default(),
            inverse_bind_matrices: Some(ibm_accessor),
            joints: (0..skeleton.len() as u32).map(json::Index::new).collect(),
            name: None,
            skeleton: None,
        }));
    }

    let materials: Cow<'_, [Material]> =
        if uvs.is_none() && mesh.materials.iter().any(|m| m.textures().next().is_some()) {
            // A texture needs TEXCOORD_0: without UVs the materials go out with their factors only.
            warnings.push(format!("mesh '{}' has no UVs; its materials are written without their textures", mesh.name));
            Cow::Owned(mesh.materials.iter().map(Material::without_textures).collect())
        } else {
            Cow::Borrowed(&mesh.materials)
        };
    let materials = write_materials(b, &materials);
    let primitives = parts
        .iter()
        .zip(attribute_sets)
        .map(|(part, attributes)| {
            let vertices = part.vertices.as_ref().map_or(n, Vec::len);
            let material = part.material.and_then(|m| materials.get(m).copied());
            b.triangle_primitive(attributes, &part.triangles, vertices, material, None)
        })
        .collect();
    let gmesh = b.mesh(&mesh.name, primitives, None);
    let node = b.root.push(json::Node {
        name: Some(mesh.name.clone()),
        mesh: Some(gmesh),
        skin: skin_index,
        ..Default::default()
    });
    Ok(Some(node))
}

/// A skin's attribute and matrix data as written, flattened.
struct SkinRows {
    /// Four joints per vertex.
    joints: Vec<u16>,
    /// Four weights per vertex, summing to one.
    weights: Vec<f32>,
    /// Sixteen numbers (column-major) per joint.
    inverse_bind_matrices: Vec<f32>,
}

/// Per vertex joints and weights (repeated joints merged, zero weights dropped, rows
/// summing to one) and the inverse bind matrices with glTF's exact affine last row,
/// checked against `skeleton`.
fn skin_rows(mesh: &Mesh, skin: &Skin, skeleton: &Skeleton) -> Result<SkinRows, (Kind, String)> {
    let n = mesh.positions.len();
    if !skin.skeleton.same_hierarchy(skeleton) {
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
    Ok(SkinRows { joints: joint_data, weights: weight_data, inverse_bind_matrices: ibm })
}
