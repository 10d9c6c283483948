//! FBX input through the ufbx loader: skeleton and the clips of the file's takes
//! (animation stacks), in kinegraph conventions (metres, Y up, right-handed).
//!
//! ufbx converts the scene itself (load options `target_axes` = right-handed Y up,
//! `target_unit_meters` = 1): every node's world matrix is then in metres, Y up. The
//! skeleton is the file's bone nodes (FBX `LimbNode`s) in depth-first order, parents first,
//! names exactly as in the file (Mixamo's `mixamorig:` prefix kept). Joint transforms are
//! derived from world matrices (scale dropped, so world positions are exact whatever
//! scale or non-bone ancestors such as Mixamo's `Armature` node carry): local rotation =
//! parent world rotation⁻¹ · world rotation, local offset = parent world rotation⁻¹ ·
//! (position − parent position). The rest pose is the file's static node transforms; each
//! take is sampled at a fixed rate (the file's frame rate unless one is given) from its
//! start to its end time.
//!
//! With meshes, each keeps the materials its faces use; `materials.rs` says how FBX
//! materials and their textures become metallic-roughness ones.

mod channels;
mod materials;

use std::path::Path;
use std::sync::Arc;

use glam::{DMat4, DQuat, DVec3, Mat4, Quat, Vec2, Vec3};

use crate::formats::error::{FormatError, FormatErrorKind as Kind, Loaded};
use crate::model::clip::sampling_refusal;
use crate::model::{Clip, ImportScale, Joint, LengthUnit, Mesh, Skeleton, Skin};
use materials::MaterialReader;

/// Frame rate used when the file states none.
pub const FALLBACK_FPS: f64 = 30.0;

/// Options for reading FBX.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FbxReadOptions {
    /// Read only this take (index into the file's animation stacks); `None` reads all.
    pub take: Option<usize>,
    /// Sampling rate (frames per second); `None` uses the file's frame rate.
    pub sample_fps: Option<f64>,
    /// Also read the meshes (skipped by default: clips do not need them).
    pub meshes: bool,
    /// Largest clip to sample, in bytes of rotations and translations (the run's memory
    /// limit); `None` uses [`crate::model::clip::DEFAULT_MAX_SAMPLED_BYTES`].
    pub max_clip_bytes: Option<u64>,
    /// Rest the skeleton in the skin's bind pose (where the skin clusters bound the bones)
    /// rather than in the node transforms; the meshes then rest as they were bound.
    pub bind_pose: bool,
}

/// What the file said about itself before conversion.
#[derive(Clone, Debug, PartialEq)]
pub struct FbxSource {
    /// Metres per file unit (the corpus's Mixamo downloads: 1, their UnitScaleFactor 100 cm).
    pub metres_per_unit: f64,
    /// The file's up axis: `"+Y"`, `"+Z"`, `"-Y"`, … (`"?"` when unstated).
    pub up_axis: String,
    /// The file's frame rate (frames per second).
    pub fps: f64,
    /// Every take's name, in file order.
    pub takes: Vec<String>,
}

/// One take of the file, sampled to a fixed-rate clip.
#[derive(Clone, Debug, PartialEq)]
pub struct FbxClip {
    /// The take's name.
    pub name: String,
    /// Index of the take in the file.
    pub take_index: usize,
    /// Seconds of the take's start in the file's timeline (the clip's frame 0).
    pub start_secs: f64,
    /// The take's length in seconds as the file states it.
    pub duration_secs: f64,
    /// The sampled clip on [`FbxAsset::skeleton`].
    pub clip: Clip,
}

/// Everything kinegraph takes from an FBX file.
#[derive(Clone, Debug, PartialEq)]
pub struct FbxAsset {
    /// The bone hierarchy, parents first, in metres, Y up.
    pub skeleton: Arc<Skeleton>,
    /// One clip per (selected) take.
    pub clips: Vec<FbxClip>,
    /// What the file declared (unit, up axis, frame rate, takes).
    pub source: FbxSource,
    /// With [`FbxReadOptions::meshes`]: one mesh per mesh node, in the skeleton's rest pose
    /// (metres, Y up), skinned meshes bound to [`FbxAsset::skeleton`] with exactly affine
    /// inverse bind matrices (the inverse rest world transforms); triangles grouped by
    /// material, each mesh with the materials it uses and their textures.
    pub meshes: Vec<Mesh>,
}

impl FbxAsset {
    /// One line for logs and `kg inspect`: the source unit, axis, rate and takes.
    pub fn describe(&self) -> String {
        let unit = unit_of(self.source.metres_per_unit).map_or_else(
            || format!("{} m per unit", self.source.metres_per_unit),
            |u| format!("'{}' ({} m per unit)", u.name(), self.source.metres_per_unit),
        );
        format!(
            "FBX in {unit}, {} up, {} fps, takes [{}]; converted to metres, Y up",
            self.source.up_axis,
            self.source.fps,
            self.source.takes.join(", ")
        )
    }
}

/// The named unit within 0.1 % of `metres_per_unit`, if any.
fn unit_of(metres_per_unit: f64) -> Option<LengthUnit> {
    LengthUnit::ALL.into_iter().find(|u| ((u.metres() - metres_per_unit) / u.metres()).abs() < 1e-3)
}

/// Reads an `.fbx` file from disk.
pub fn read_fbx_file(path: &Path, options: &FbxReadOptions) -> Result<Loaded<FbxAsset>, FormatError> {
    let bytes = std::fs::read(path).map_err(|e| FormatError::io(path, &e))?;
    read_fbx(&bytes, path, options)
}

fn axis_name(axis: ufbx::CoordinateAxis) -> &'static str {
    use ufbx::CoordinateAxis as A;
    match axis {
        A::PositiveX => "+X",
        A::NegativeX => "-X",
        A::PositiveY => "+Y",
        A::NegativeY => "-Y",
        A::PositiveZ => "+Z",
        A::NegativeZ => "-Z",
        A::Unknown => "?",
    }
}

/// The up axis the file's `GlobalSettings` state (`UpAxis` 0/1/2 = X/Y/Z, `UpAxisSign` ±1).
fn stated_up_axis(props: &ufbx::Props) -> Option<String> {
    let axis = ufbx::find_prop(props, "UpAxis")?.value_int;
    let sign = ufbx::find_prop(props, "UpAxisSign").map_or(1, |p| p.value_int);
    let letter = ["X", "Y", "Z"].get(usize::try_from(axis).ok()?)?;
    Some(format!("{}{letter}", if sign < 0 { "-" } else { "+" }))
}

/// ufbx's description of a load error, as text.
fn describe_error(error: &ufbx::Error) -> String {
    let mut buf = [0u8; 1024];
    let n = ufbx::format_error(&mut buf, error).min(buf.len());
    let text = String::from_utf8_lossy(&buf[..n]);
    // The first line says what; the rest is ufbx's internal call stack.
    text.lines().next().unwrap_or("unreadable FBX").trim().to_owned()
}

fn load_error(path: &Path, error: &ufbx::Error) -> FormatError {
    use ufbx::ErrorType as E;
    let kind = match error.type_ {
        E::TruncatedFile | E::TruncatedVertexStream | E::EmptyFile => Kind::Truncated,
        E::FileNotFound | E::ExternalFileNotFound | E::Io => Kind::Io,
        E::UnrecognizedFileFormat | E::UnsupportedVersion | E::FeatureDisabled => Kind::Unsupported,
        E::BadIndex | E::NodeDepthLimit | E::DuplicateOverride | E::BadNurbs | E::ZeroVertexSize => Kind::Structure,
        _ => Kind::Syntax,
    };
    FormatError::file(path, kind, format!("not a readable FBX file: {}", describe_error(error)))
}

/// A world transform without scale: rotation and position (metres).
#[derive(Clone, Copy, Debug)]
struct Rigid {
    rotation: DQuat,
    position: DVec3,
}

fn dmat(m: &ufbx::Matrix) -> DMat4 {
    DMat4::from_cols_array(&[
        m.m00, m.m10, m.m20, 0.0, m.m01, m.m11, m.m21, 0.0, m.m02, m.m12, m.m22, 0.0, m.m03, m.m13, m.m23, 1.0,
    ])
}

fn rigid(m: &ufbx::Matrix) -> Option<Rigid> {
    rigid_of(dmat(m))
}

/// The rotation and position of `mat` (scale dropped), or `None` when it is degenerate,
/// mirrored or not finite.
fn rigid_of(mat: DMat4) -> Option<Rigid> {
    let det = mat.determinant();
    if !(det.is_finite() && det > 1e-30) {
        return None;
    }
    let (_scale, rotation, position) = mat.to_scale_rotation_translation();
    let length = rotation.length();
    if !(length.is_finite() && length > 1e-12) {
        return None;
    }
    let rotation = rotation * length.recip();
    (rotation.is_finite() && position.is_finite()).then_some(Rigid { rotation, position })
}

/// Local (rotation, offset) of every joint from world transforms, parents first.
fn locals(parents: &[Option<usize>], world: &[Rigid]) -> Vec<(Quat, Vec3)> {
    parents
        .iter()
        .zip(world)
        .map(|(parent, w)| match parent {
            Some(p) => {
                let inv = world[*p].rotation.inverse();
                ((inv * w.rotation).normalize().as_quat(), (inv * (w.position - world[*p].position)).as_vec3())
            }
            None => (w.rotation.as_quat(), w.position.as_vec3()),
        })
        .collect()
}

/// Parses FBX `bytes`; `path` names the file in errors.
pub fn read_fbx(bytes: &[u8], path: &Path, options: &FbxReadOptions) -> Result<Loaded<FbxAsset>, FormatError> {
    let opts = ufbx::LoadOpts {
        target_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        target_unit_meters: 1.0,
        space_conversion: ufbx::SpaceConversion::AdjustTransforms,
        handedness_conversion_axis: ufbx::MirrorAxis::Z,
        ignore_geometry: !options.meshes,
        // Embedded textures are only wanted with the meshes' materials.
        ignore_embedded: !options.meshes,
        load_external_files: false,
        ..Default::default()
    };
    let scene = ufbx::load_memory(bytes, opts).map_err(|e| load_error(path, &e))?;
    let mut warnings = Vec::new();

    // Bones in depth-first order from the scene root: parents come first.
    let mut nodes: Vec<u32> = Vec::new(); // typed ids of joint nodes
    let mut parents: Vec<Option<usize>> = Vec::new();
    let mut stack: Vec<(&ufbx::Node, Option<usize>)> = vec![(&*scene.root_node, None)];
    while let Some((node, bone_parent)) = stack.pop() {
        let mut here = bone_parent;
        if node.bone.is_some() {
            nodes.push(node.element.typed_id);
            parents.push(bone_parent);
            here = Some(nodes.len() - 1);
        }
        for child in node.children.iter().rev() {
            stack.push((&**child, here));
        }
    }
    if nodes.is_empty() {
        return Err(FormatError::file(
            path,
            Kind::Structure,
            format!(
                "has no skeleton: no bone (LimbNode) among its {} nodes, {} meshes",
                scene.nodes.len().saturating_sub(1),
                scene.meshes.len()
            ),
        ));
    }

    let node_at = |scene: &ufbx::Scene, id: u32| -> Option<ufbx::Matrix> {
        scene.nodes.get(id as usize).map(|n| n.node_to_world)
    };
    let worlds = |scene: &ufbx::Scene, when: &str| -> Result<Vec<Rigid>, FormatError> {
        nodes
            .iter()
            .map(|&id| {
                let name = scene.nodes.get(id as usize).map_or_else(String::new, |n| n.element.name.to_string());
                node_at(scene, id).as_ref().and_then(rigid).ok_or_else(|| {
                    FormatError::file(
                        path,
                        Kind::Value,
                        format!("bone '{name}' has a degenerate, mirrored or non-finite transform {when}"),
                    )
                })
            })
            .collect()
    };

    // Rest pose: the static node transforms, or the skin's bind pose.
    let mut rest_world = worlds(&scene, "in the rest pose")?;
    if options.bind_pose {
        rest_world = bind_worlds(&scene, &nodes, &parents, &rest_world, path, &mut warnings);
    }
    let rest = locals(&parents, &rest_world);
    let mut joints = Vec::with_capacity(nodes.len());
    for ((&id, parent), (rotation, offset)) in nodes.iter().zip(&parents).zip(&rest) {
        let name = scene.nodes.get(id as usize).map_or_else(String::new, |n| n.element.name.to_string());
        let mut joint = Joint::new(name, *parent, *offset);
        joint.rest_rotation = *rotation;
        joints.push(joint);
    }
    let skeleton =
        Arc::new(Skeleton::new(joints).map_err(|e| FormatError::file(path, Kind::Structure, e.to_string()))?);

    let settings = &scene.settings;
    let file_fps = settings.frames_per_second;
    let takes: Vec<String> = scene.anim_stacks.iter().map(|s| s.element.name.to_string()).collect();
    let source = FbxSource {
        metres_per_unit: settings.original_unit_meters,
        up_axis: stated_up_axis(&settings.props).unwrap_or_else(|| axis_name(settings.original_axis_up).to_owned()),
        fps: file_fps,
        takes,
    };
    let fps = match options.sample_fps {
        Some(f) if f.is_finite() && f > 0.0 => f,
        Some(f) => return Err(FormatError::file(path, Kind::Value, format!("sample_fps {f} is not a positive rate"))),
        None if file_fps.is_finite() && file_fps > 0.0 => file_fps,
        None => {
            warnings.push(format!("{}: the file states no frame rate; sampled at {FALLBACK_FPS} fps", path.display()));
            FALLBACK_FPS
        }
    };
    let import_scale =
        ImportScale { unit: unit_of(source.metres_per_unit), metres_per_unit: source.metres_per_unit, detected: false };

    let mut clips = Vec::new();
    for (index, stack) in scene.anim_stacks.iter().enumerate() {
        if options.take.is_some_and(|t| t != index) {
            continue;
        }
        let (begin, end) = (stack.time_begin, stack.time_end);
        let span = end - begin;
        if !(span.is_finite() && begin.is_finite() && span >= 0.0) {
            return Err(FormatError::file(
                path,
                Kind::Value,
                format!("take '{}' has a bad time range {begin}..{end} s", stack.element.name),
            ));
        }
        let frames_f = (span * fps).round() + 1.0;
        if let Some(refusal) = sampling_refusal(frames_f, nodes.len(), options.max_clip_bytes, "sample_fps") {
            return Err(FormatError::file(
                path,
                Kind::Value,
                format!("take '{}' is too long to sample, {span} s at {fps} fps: {refusal}", stack.element.name),
            ));
        }
        let frames = frames_f as usize;
        let mut rotations = Vec::with_capacity(frames * nodes.len());
        let mut translations = Vec::with_capacity(frames * nodes.len());
        for f in 0..frames {
            let t = (begin + f as f64 / fps).min(end);
            let posed = ufbx::evaluate_scene(&scene, &stack.anim, t, ufbx::EvaluateOpts::default())
                .map_err(|e| load_error(path, &e))?;
            let world = worlds(&posed, &format!("at {t:.4} s of take '{}'", stack.element.name))?;
            for (q, p) in locals(&parents, &world) {
                rotations.push(q);
                translations.push(p);
            }
        }
        let clip = Clip::new(skeleton.clone(), fps, rotations, translations, import_scale)
            .map_err(|e| FormatError::file(path, Kind::Value, format!("take '{}': {e}", stack.element.name)))?;
        clips.push(FbxClip {
            name: stack.element.name.to_string(),
            take_index: index,
            start_secs: begin,
            duration_secs: span,
            clip,
        });
    }
    if let Some(t) = options.take
        && clips.is_empty()
    {
        return Err(FormatError::file(
            path,
            Kind::Structure,
            format!("has no take {t} (it has {}: [{}])", source.takes.len(), source.takes.join(", ")),
        ));
    }
    let meshes = if options.meshes {
        read_meshes(&scene, path, &skeleton, &nodes, &rest_world, options.bind_pose, &mut warnings)?
    } else {
        Vec::new()
    };
    Ok(Loaded { value: FbxAsset { skeleton, clips, source, meshes }, warnings })
}

/// The joints' world transforms in the pose the skin clusters bound them: a bone's bind
/// world is its mesh's geometry-to-world times the cluster's geometry-to-bone inverted (the
/// mesh node standing where it was bound); bones no cluster binds keep their node transform
/// under their parent. The first cluster of a bone is used; a file without clusters rests
/// in its node transforms, with a warning.
fn bind_worlds(
    scene: &ufbx::Scene,
    nodes: &[u32],
    parents: &[Option<usize>],
    node_world: &[Rigid],
    path: &Path,
    warnings: &mut Vec<String>,
) -> Vec<Rigid> {
    let mut bound: Vec<Option<Rigid>> = vec![None; nodes.len()];
    for node in scene.nodes.iter() {
        let Some(mesh) = node.mesh.as_ref() else { continue };
        for skin in mesh.skin_deformers.iter() {
            for cluster in skin.clusters.iter() {
                let Some(bone) = cluster.bone_node.as_ref() else { continue };
                let Some(j) = nodes.iter().position(|&n| n == bone.element.typed_id) else { continue };
                if bound[j].is_none() {
                    bound[j] = rigid_of(dmat(&node.geometry_to_world) * dmat(&cluster.geometry_to_bone).inverse());
                }
            }
        }
    }
    if bound.iter().all(Option::is_none) {
        warnings
            .push(format!("{}: no skin binds the bones; the skeleton rests in its node transforms", path.display()));
    }
    let node_local = locals(parents, node_world);
    let mut world: Vec<Rigid> = Vec::with_capacity(nodes.len());
    for ((j, parent), (rotation, offset)) in parents.iter().enumerate().zip(node_local) {
        let w = match (bound[j], parent) {
            (Some(b), _) => b,
            (None, None) => node_world[j],
            // Its node transform relative to its parent, under the parent's bind world.
            (None, Some(p)) => Rigid {
                rotation: world[*p].rotation * rotation.as_dquat(),
                position: world[*p].position + world[*p].rotation * offset.as_dvec3(),
            },
        };
        world.push(w);
    }
    world
}

/// Largest number of vertices (corners) of one mesh read.
const MAX_MESH_INDICES: usize = 50_000_000;

/// Every mesh node's mesh, triangulated, with one vertex per distinct (source vertex,
/// normal, UV) corner, put in the skeleton's rest pose: skinned vertices by linear blend skinning
/// with the rest bone matrices (`Σ w · bone world · geometry-to-bone`, the bone world being
/// its node transform, or with `bind_pose` its bind world `rest_world`), unskinned ones by
/// their node's world matrix. Four strongest weights per vertex, renormalised. Triangles are
/// grouped by material (in the node's material order, file order within each), and only the
/// materials used are kept.
fn read_meshes(
    scene: &ufbx::Scene,
    path: &Path,
    skeleton: &Arc<Skeleton>,
    nodes: &[u32],
    rest_world: &[Rigid],
    bind_pose: bool,
    warnings: &mut Vec<String>,
) -> Result<Vec<Mesh>, FormatError> {
    let joint_of = |node_id: u32| nodes.iter().position(|&n| n == node_id);
    // Exactly affine inverse bind matrices: inverses of rigid rest world transforms.
    let inverse_bind_matrices: Vec<Mat4> = rest_world
        .iter()
        .map(|w| {
            let inv = w.rotation.inverse();
            let m = Mat4::from_rotation_translation(inv.as_quat(), (-(inv * w.position)).as_vec3());
            let mut cols = m.to_cols_array();
            (cols[3], cols[7], cols[11], cols[15]) = (0.0, 0.0, 0.0, 1.0);
            Mat4::from_cols_array(&cols)
        })
        .collect();
    let mut material_reader = MaterialReader::new(path);
    let mut out = Vec::new();
    for node in scene.nodes.iter() {
        let Some(mesh) = node.mesh.as_ref() else { continue };
        let name = node.element.name.to_string();
        if mesh.num_indices > MAX_MESH_INDICES || !mesh.vertex_position.exists {
            warnings.push(format!("{}: mesh '{name}' skipped (no positions or too large)", path.display()));
            continue;
        }
        // Per source vertex: rest position and normal matrix, and the four strongest weights.
        let skin = mesh.skin_deformers.first();
        let n_vertices = mesh.num_vertices;
        let mut vertex_matrix: Vec<DMat4> = vec![dmat(&node.geometry_to_world); n_vertices];
        let mut vertex_weights: Vec<([u16; 4], [f32; 4])> = vec![([0; 4], [0.0; 4]); n_vertices];
        if let Some(skin) = skin {
            let cluster_joint: Vec<Option<usize>> =
                skin.clusters.iter().map(|c| c.bone_node.as_ref().and_then(|b| joint_of(b.element.typed_id))).collect();
            // The bone where the skeleton rests: its node transform, or in the bind pose its
            // bind world (so the mesh rests as it was bound).
            let cluster_matrix: Vec<DMat4> = skin
                .clusters
                .iter()
                .zip(&cluster_joint)
                .map(|(c, joint)| {
                    let bone = match (bind_pose, joint) {
                        (true, Some(j)) => {
                            DMat4::from_rotation_translation(rest_world[*j].rotation, rest_world[*j].position)
                        }
                        _ => c.bone_node.as_ref().map_or(DMat4::IDENTITY, |b| dmat(&b.node_to_world)),
                    };
                    bone * dmat(&c.geometry_to_bone)
                })
                .collect();
            for (v, sv) in skin.vertices.iter().enumerate().take(n_vertices) {
                let begin = sv.weight_begin as usize;
                let end = begin.saturating_add(sv.num_weights as usize).min(skin.weights.len());
                let all: &[ufbx::SkinWeight] = &skin.weights;
                let mut ws: Vec<(f64, usize, usize)> = all
                    .get(begin.min(end)..end)
                    .unwrap_or(&[])
                    .iter()
                    .filter_map(|w| {
                        let c = w.cluster_index as usize;
                        let j = (*cluster_joint.get(c)?)?;
                        (w.weight.is_finite() && w.weight > 0.0).then_some((w.weight, c, j))
                    })
                    .collect();
                ws.sort_by(|a, b| b.0.total_cmp(&a.0));
                ws.truncate(4);
                let total: f64 = ws.iter().map(|w| w.0).sum();
                if total <= 0.0 {
                    continue; // unweighted: stays where the node puts it, bound to the root
                }
                let mut m = DMat4::ZERO;
                for (k, &(w, c, j)) in ws.iter().enumerate() {
                    m += cluster_matrix[c] * (w / total);
                    vertex_weights[v].0[k] = u16::try_from(j).unwrap_or(0);
                    vertex_weights[v].1[k] = (w / total) as f32;
                }
                vertex_matrix[v] = m;
            }
        }

        // Corners → vertices, deduplicated by (vertex, normal, uv) index.
        let mut key_to_vertex = std::collections::BTreeMap::new();
        let (mut positions, mut normals, mut uvs, mut joints, mut weights) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut triangles = Vec::new();
        // Per triangle: its index into the node's materials (per instance, as ufbx advises).
        let face_materials = if node.materials.is_empty() { &mesh.materials } else { &node.materials };
        let mut triangle_materials = Vec::new();
        let mut corner_indices = vec![0u32; mesh.max_face_triangles.saturating_mul(3).max(3)];
        let has_normals = mesh.vertex_normal.exists;
        let has_uvs = mesh.vertex_uv.exists;
        for (face_index, face) in mesh.faces.iter().enumerate() {
            let material =
                mesh.face_material.get(face_index).map(|&m| m as usize).filter(|&m| m < face_materials.len());
            if face.num_indices < 3 || (face.num_indices as usize - 2) * 3 > corner_indices.len() {
                continue;
            }
            let n = mesh.triangulate_face(&mut corner_indices, *face) as usize;
            for tri in corner_indices[..(n * 3).min(corner_indices.len())].chunks_exact(3) {
                let mut t = [0u32; 3];
                for (slot, &corner) in t.iter_mut().zip(tri) {
                    let c = corner as usize;
                    let (Some(&v), Some(&pi)) = (mesh.vertex_indices.get(c), mesh.vertex_position.indices.get(c))
                    else {
                        return Err(FormatError::file(path, Kind::Structure, format!("mesh '{name}': bad corner {c}")));
                    };
                    let ni = if has_normals { mesh.vertex_normal.indices.get(c).copied().unwrap_or(0) } else { 0 };
                    let ui = if has_uvs { mesh.vertex_uv.indices.get(c).copied().unwrap_or(0) } else { 0 };
                    // Files often store one normal per corner: key on the values, not indices.
                    let key_n = mesh
                        .vertex_normal
                        .values
                        .get(ni as usize)
                        .map_or([0; 3], |n| [n.x.to_bits(), n.y.to_bits(), n.z.to_bits()]);
                    let key_uv =
                        mesh.vertex_uv.values.get(ui as usize).map_or([0; 2], |u| [u.x.to_bits(), u.y.to_bits()]);
                    let next = positions.len() as u32;
                    let index = *key_to_vertex.entry((v, key_n, key_uv)).or_insert(next);
                    if index == next {
                        let m = vertex_matrix.get(v as usize).copied().unwrap_or(DMat4::IDENTITY);
                        let p = mesh
                            .vertex_position
                            .values
                            .get(pi as usize)
                            .map_or(DVec3::ZERO, |p| DVec3::new(p.x, p.y, p.z));
                        positions.push(m.transform_point3(p).as_vec3());
                        let normal = if has_normals {
                            mesh.vertex_normal
                                .values
                                .get(ni as usize)
                                .map_or(DVec3::ZERO, |n| DVec3::new(n.x, n.y, n.z))
                        } else {
                            DVec3::ZERO
                        };
                        let normal_matrix = m.inverse().transpose();
                        normals.push(normal_matrix.transform_vector3(normal).normalize_or_zero().as_vec3());
                        let uv = if has_uvs {
                            mesh.vertex_uv
                                .values
                                .get(ui as usize)
                                .map_or(Vec2::ZERO, |u| Vec2::new(u.x as f32, 1.0 - u.y as f32))
                        } else {
                            Vec2::ZERO
                        };
                        uvs.push(uv);
                        let (j, w) = vertex_weights.get(v as usize).copied().unwrap_or(([0; 4], [0.0; 4]));
                        joints.push(j);
                        weights.push(if w[0] > 0.0 { w } else { [1.0, 0.0, 0.0, 0.0] });
                    }
                    *slot = index;
                }
                triangles.push(t);
                triangle_materials.push(material);
            }
        }
        if positions.is_empty() {
            warnings.push(format!("{}: mesh '{name}' has no triangles; skipped", path.display()));
            continue;
        }
        if !has_normals || normals.contains(&Vec3::ZERO) {
            normals = Mesh::compute_normals(&positions, &triangles);
        }
        let skin = skin.map(|_| Skin {
            skeleton: skeleton.clone(),
            joints,
            weights,
            inverse_bind_matrices: inverse_bind_matrices.clone(),
        });
        let mut mesh_out =
            Mesh { name, positions, normals, uvs: has_uvs.then_some(uvs), triangles, skin, ..Mesh::default() };
        if !face_materials.is_empty() {
            // Stable: file order is kept within each material; faces without one come last.
            let mut order: Vec<usize> = (0..mesh_out.triangles.len()).collect();
            order.sort_by_key(|&t| triangle_materials[t].unwrap_or(usize::MAX));
            mesh_out.triangles = order.iter().map(|&t| mesh_out.triangles[t]).collect();
            // The node's materials the faces use, in order: each one's triangles are one run.
            let mut used: Vec<usize> = Vec::new();
            for &t in &order {
                let index = triangle_materials[t].map(|m| {
                    if used.last() != Some(&m) {
                        used.push(m);
                    }
                    used.len() - 1
                });
                mesh_out.push_material_range(index, 1);
            }
            mesh_out.materials = used.iter().map(|&m| material_reader.material(&face_materials[m], warnings)).collect();
        }
        out.push(mesh_out);
    }
    Ok(out)
}
