//! GLB writer: a clip's skeleton as a node hierarchy, one or more named animations of it,
//! and optionally a skinned mesh bound to it, one glTF mesh per part, one primitive per material.
//!
//! Layout: node `j` is skeleton joint `j` (end sites included, harmless), with the joint's
//! rest offset and rest rotation as its TRS. A skeleton with several roots gets one extra
//! unanimated parent node so the skin's joints share a root. Each animation has one shared
//! time input (`frame / fps` seconds, with min/max), one LINEAR rotation channel per joint
//! and a LINEAR translation channel for every joint whose translation leaves its rest
//! offset in any animation. The mesh (when given) is written as the objects it was merged
//! from (its parts, e.g. a character's body and joints; itself when it has none), each
//! its own named glTF mesh on its own node, a scene root without a transform as the spec
//! asks of skinned meshes, all bound to one skin. An object drawn with one material is one
//! primitive over all its vertices; with several, each material's triangles are one
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
use crate::model::{Clip, Material, Mesh, MeshPart, Skeleton, Skin};

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
    build_glb_animations(&[GlbAnimation { name: DEFAULT_ANIMATION_NAME, clip }], mesh, None)
}

/// Like [`build_glb`] with several named animations of one skeleton in one file. Each
/// animation is complete on its own: every joint gets a rotation channel, and a joint
/// whose translation moves in any of them gets a translation channel in all of them, so a
/// viewer switching animations never keeps a position left over from another.
///
/// `props` are the scene's fixed objects (a stool the character sits on), written as they
/// stand, each part its own object; an empty one writes nothing.
///
/// Errors: no animations, two with one name, an animation on another skeleton, and
/// everything [`build_glb`] refuses, for the props as for the mesh.
pub fn build_glb_animations(
    animations: &[GlbAnimation<'_>],
    mesh: Option<&Mesh>,
    props: Option<&Mesh>,
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
            Ok(nodes) if !nodes.is_empty() => {
                skinned = mesh.skin.is_some();
                if !skinned && animated {
                    warnings.push(format!(
                        "mesh '{}' has no skin: it is written standing still at the origin and will not follow the animated skeleton (load a skinned mesh, or bind it with skin.bind)",
                        mesh.name
                    ));
                }
                scene_nodes.extend(nodes);
            }
            Ok(_) => {}
            Err((kind, message)) => return Err(err(kind, message)),
        }
    }
    if let Some(props) = props.filter(|p| !p.triangles.is_empty()) {
        scene_nodes.extend(write_mesh(&mut b, skeleton, props, &mut warnings).map_err(|(kind, m)| err(kind, m))?);
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

/// One primitive to write: the vertices of its object it uses (`None`: all, in order, else
/// indices local to the object), its triangles over those vertices, and its material
/// index in the mesh.
struct Primitive {
    vertices: Option<Vec<u32>>,
    triangles: Vec<[u32; 3]>,
    material: Option<usize>,
}

/// Splits `object` of `mesh` (checked with [`Mesh::check_parts`]) into one primitive per
/// material, in the order the materials first appear; each keeps the vertices its
/// triangles use, in their original order. An object drawn with one material (or none)
/// is one primitive over all its vertices.
fn primitives_of(mesh: &Mesh, object: &MeshPart) -> Vec<Primitive> {
    let triangles = object.first_triangle..object.first_triangle + object.triangle_count;
    let base = object.first_vertex as u32;
    let local = |t: &[u32; 3]| t.map(|i| i - base);
    // The material runs, clipped to the object's triangles.
    let runs: Vec<(std::ops::Range<usize>, Option<usize>)> = if mesh.material_ranges.is_empty() {
        vec![(triangles.clone(), None)]
    } else {
        mesh.material_ranges
            .iter()
            .map(|r| {
                (
                    r.first_triangle.max(triangles.start)..(r.first_triangle + r.triangle_count).min(triangles.end),
                    r.material,
                )
            })
            .filter(|(range, _)| !range.is_empty())
            .collect()
    };
    let mut order: Vec<Option<usize>> = Vec::new();
    for (_, material) in &runs {
        if !order.contains(material) {
            order.push(*material);
        }
    }
    if order.len() <= 1 {
        let triangles = mesh.triangles[triangles].iter().map(local).collect();
        return vec![Primitive { vertices: None, triangles, material: order.first().copied().flatten() }];
    }
    let n = object.vertex_count;
    order
        .into_iter()
        .map(|material| {
            let triangles: Vec<[u32; 3]> = runs
                .iter()
                .filter(|(_, m)| *m == material)
                .flat_map(|(range, _)| &mesh.triangles[range.clone()])
                .map(local)
                .collect();
            let mut used = vec![false; n];
            for &i in triangles.iter().flatten() {
                used[i as usize] = true;
            }
            let vertices: Vec<u32> = (0..n as u32).filter(|&v| used[v as usize]).collect();
            let mut renumbered = vec![0u32; n];
            for (k, &v) in vertices.iter().enumerate() {
                renumbered[v as usize] = k as u32;
            }
            let triangles = triangles.iter().map(|t| t.map(|i| renumbered[i as usize])).collect();
            Primitive { vertices: Some(vertices), triangles, material }
        })
        .collect()
}

/// `values` (`width` numbers per vertex of the whole mesh) of the vertices `primitive`
/// uses in `object`.
fn gather<T: Copy>(values: &[T], width: usize, object: &MeshPart, primitive: &Primitive) -> Vec<T> {
    let first = object.first_vertex;
    match &primitive.vertices {
        None => values[first * width..(first + object.vertex_count) * width].to_vec(),
        Some(vs) => vs
            .iter()
            .flat_map(|&v| {
                let v = first + v as usize;
                &values[v * width..(v + 1) * width]
            })
            .copied()
            .collect(),
    }
}

/// Adds `mesh` (and its skin) to the document: each of its parts (see [`Mesh::objects`]) as
/// its own glTF mesh named like the part on its own node named like the part's object,
/// all bound to one skin, one primitive per material; returns the nodes.
fn write_mesh(
    b: &mut GlbBuilder,
    skeleton: &Skeleton,
    mesh: &Mesh,
    warnings: &mut Vec<String>,
) -> Result<Vec<json::Index<json::Node>>, (Kind, String)> {
    let n = mesh.positions.len();
    if n == 0 || mesh.triangles.is_empty() {
        warnings.push(format!("mesh '{}' has no triangles; not written", mesh.name));
        return Ok(Vec::new());
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err((Kind::Value, format!("mesh '{}' has a non-finite position", mesh.name)));
    }
    if let Some(t) = mesh.triangles.iter().position(|t| t.iter().any(|&i| i as usize >= n)) {
        return Err((Kind::Structure, format!("mesh '{}' triangle {t} indexes past its {n} vertices", mesh.name)));
    }
    mesh.check_material_ranges().map_err(|m| (Kind::Structure, format!("mesh '{}': {m}", mesh.name)))?;
    mesh.check_parts().map_err(|m| (Kind::Structure, format!("mesh '{}': {m}", mesh.name)))?;
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

    // Attribute accessors of every primitive first, then the skin, the materials and the
    // index accessors: the layout a single-object mesh has always had.
    let objects: Vec<MeshPart> = mesh.objects();
    let mut written = Vec::with_capacity(objects.len());
    for object in &objects {
        if object.triangle_count == 0 {
            warnings.push(format!("mesh '{}': part '{}' has no triangles; not written", mesh.name, object.name));
            continue;
        }
        let mut primitives = Vec::new();
        for primitive in primitives_of(mesh, object) {
            let mut attributes = BTreeMap::new();
            let vec3 = |b: &mut GlbBuilder, values: &[f32], bounds| {
                b.accessor_f32(&gather(values, 3, object, &primitive), Type::Vec3, Some(Target::ArrayBuffer), bounds)
            };
            attributes.insert(Valid(Semantic::Positions), vec3(b, &positions, Bounds::Record));
            attributes.insert(Valid(Semantic::Normals), vec3(b, &normals, Bounds::Omit));
            if let Some(uv) = &uvs {
                attributes.insert(
                    Valid(Semantic::TexCoords(0)),
                    b.accessor_f32(
                        &gather(uv, 2, object, &primitive),
                        Type::Vec2,
                        Some(Target::ArrayBuffer),
                        Bounds::Omit,
                    ),
                );
            }
            if let Some(rows) = &skin_data {
                attributes.insert(
                    Valid(Semantic::Joints(0)),
                    b.accessor_u16(&gather(&rows.joints, 4, object, &primitive), Type::Vec4, Some(Target::ArrayBuffer)),
                );
                attributes.insert(
                    Valid(Semantic::Weights(0)),
                    b.accessor_f32(
                        &gather(&rows.weights, 4, object, &primitive),
                        Type::Vec4,
                        Some(Target::ArrayBuffer),
                        Bounds::Omit,
                    ),
                );
            }
            primitives.push((primitive, attributes));
        }
        written.push((object, primitives));
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

    let mut nodes = Vec::with_capacity(written.len());
    for (object, primitives) in written {
        let primitives = primitives
            .into_iter()
            .map(|(primitive, attributes)| {
                let vertices = primitive.vertices.as_ref().map_or(object.vertex_count, Vec::len);
                let material = primitive.material.and_then(|m| materials.get(m).copied());
                b.triangle_primitive(attributes, &primitive.triangles, vertices, material, None)
            })
            .collect();
        let gmesh = b.mesh(&object.name, primitives, None);
        nodes.push(b.root.push(json::Node {
            name: Some(object.object.clone().unwrap_or_else(|| object.name.clone())),
            mesh: Some(gmesh),
            skin: skin_index,
            ..Default::default()
        }));
    }
    Ok(nodes)
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
