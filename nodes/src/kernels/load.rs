//! Loading clips and meshes from files by extension, with the warnings found. A kernel:
//! `clip.load`, `mesh.load` and the clip-set loader of the transitions read files with it.

use std::path::Path;

use crate::formats::bvh::{BvhReadOptions, read_bvh_file};
use crate::formats::fbx::{FbxReadOptions, read_fbx_file};
use crate::formats::gltf::{GltfReadOptions, read_gltf_file};
use crate::formats::{FormatError, FormatErrorKind, Loaded};
use crate::model::fk::rest_world;
use glam::Mat4;

use crate::model::{Clip, Mesh, Skeleton, Skin, Transform};

/// How to read a clip file.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClipLoadOptions {
    /// BVH only: metres per file unit; `None` detects it.
    pub metres_per_unit: Option<f64>,
    /// glTF and FBX: which animation (FBX: which take; default the first).
    pub animation: Option<usize>,
    /// glTF and FBX: sampling rate; `None` infers it from the key spacing (glTF) or uses
    /// the file's frame rate (FBX).
    pub sample_fps: Option<f64>,
    /// BVH only: the file's up axis; Z-up files are turned to kinegraph's Y up.
    pub up_axis: UpAxis,
    /// glTF and FBX: largest clip to sample, in bytes (the run's memory limit); `None`
    /// uses the readers' default.
    pub max_clip_bytes: Option<u64>,
    /// What to do with a T-pose captured before the motion (the file as stored by default).
    pub t_pose: LeadingTPose,
}

/// A T-pose before the first captured frame: cgspeed's CMU conversions (most CMU BVH files
/// users find) put one there, and kept it is a pop into the motion's first frame (the arms
/// swing 80–90° in 1/120 s) that every later step inherits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LeadingTPose {
    /// Keep every frame of the file.
    #[default]
    Keep,
    /// Drop the first frame when it is a T-pose ([`starts_with_t_pose`]), with a warning.
    Drop,
}

/// Whether a captured T-pose starts the clip: it is recognised as a pop of most of the body,
/// at least half of the joints between the root and the end sites turning more than 0.1 rad from frame 0 to
/// frame 1 and more than five times as far as they turn from frame 1 to frame 2. (The
/// T-pose's local rotations are not all identity: cgspeed's rest pose bends the arms and
/// legs. A count rather than a mean: CMU 90_11's legs and 90_28's thumbs jitter over the
/// first captured frames, which hid the pop from a mean over the joints.)
pub fn starts_with_t_pose(clip: &Clip) -> bool {
    if clip.frame_count() < 3 || clip.joint_count() < 2 {
        return false;
    }
    let (r0, r1, r2) = (clip.frame_rotations(0), clip.frame_rotations(1), clip.frame_rotations(2));
    let turn = |p: &glam::Quat, q: &glam::Quat| 2.0 * p.dot(*q).abs().min(1.0).acos();
    // Joints that turn something: those with children (end sites never rotate).
    let mut has_children = vec![false; clip.joint_count()];
    for joint in clip.skeleton().joints() {
        if let Some(p) = joint.parent {
            has_children[p] = true;
        }
    }
    let turning: Vec<usize> =
        (0..clip.joint_count()).filter(|&j| has_children[j] && clip.skeleton().joints()[j].parent.is_some()).collect();
    let popping = turning
        .iter()
        .filter(|&&j| {
            let pop = turn(&r0[j], &r1[j]);
            pop > 0.1 && pop > 5.0 * turn(&r1[j], &r2[j]).max(0.002)
        })
        .count();
    !turning.is_empty() && 2 * popping >= turning.len()
}

/// Which axis points up in a source file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UpAxis {
    /// Y up (kinegraph's own convention, and most BVH exporters').
    #[default]
    Y,
    /// Z up (some MakeHuman and 3ds Max exports).
    Z,
}

/// A rest pose much taller along Z than along Y, and tallest along Z, is probably Z-up.
fn looks_z_up(clip: &Clip) -> bool {
    let e = clip.skeleton().rest_extent();
    e.z >= e.max_element() && e.z > 1.5 * e.y
}

/// Reads a clip from a BVH, glTF, GLB or FBX file (by extension), with the warnings found,
/// including the unit a BVH was taken to be in and what an FBX declared (unit, up axis,
/// frame rate, takes) before its conversion to metres, Y up.
pub fn load_clip(path: &Path, options: ClipLoadOptions) -> Result<Loaded<Clip>, FormatError> {
    let Loaded { value: clip, mut warnings } = load_stored_clip(path, options)?;
    if options.t_pose == LeadingTPose::Drop && starts_with_t_pose(&clip) {
        warnings.push(format!(
            "{}: dropped the T-pose before the motion (frame 0; cgspeed's CMU conversions put one there); set t_pose to \"keep\" to keep it",
            path.display()
        ));
        return Ok(Loaded { value: clip.slice(1, clip.frame_count()), warnings });
    }
    Ok(Loaded { value: clip, warnings })
}

/// The clip as the file stores it.
fn load_stored_clip(path: &Path, options: ClipLoadOptions) -> Result<Loaded<Clip>, FormatError> {
    let ext = crate::formats::extension(path);
    match ext.as_str() {
        "bvh" => {
            let loaded = read_bvh_file(path, BvhReadOptions { metres_per_unit: options.metres_per_unit })?;
            let (clip, stats) = loaded.value;
            let mut warnings = loaded.warnings;
            if clip.import_scale.detected {
                let unit = clip.import_scale.unit.map(|u| u.name()).unwrap_or("?");
                warnings.push(format!(
                    "{}: detected unit '{unit}' ({} m per unit) from a rest extent of {:.3} file units; set metres_per_unit to override",
                    path.display(),
                    clip.import_scale.metres_per_unit,
                    stats.rest_extent_file_units
                ));
            }
            let clip = match options.up_axis {
                UpAxis::Z => clip
                    .rotated(glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2))
                    .map_err(|e| FormatError::file(path, FormatErrorKind::Value, e.to_string()))?,
                UpAxis::Y => {
                    if looks_z_up(&clip) {
                        warnings.push(format!(
                            "{}: the skeleton is tallest along Z, so the file looks Z-up; set up_axis to \"z\" to convert",
                            path.display()
                        ));
                    }
                    clip
                }
            };
            Ok(Loaded { value: clip, warnings })
        }
        "gltf" | "glb" => {
            let gltf_options = GltfReadOptions {
                animation: options.animation,
                skin: None,
                sample_fps: options.sample_fps,
                max_clip_bytes: options.max_clip_bytes,
                materials: false,
            };
            let loaded = read_gltf_file(path, &gltf_options)?;
            let mut warnings = loaded.warnings;
            if options.metres_per_unit.is_some() {
                warnings.push("metres_per_unit is ignored for glTF, which is in metres by specification".into());
            }
            let asset = loaded.value;
            let wanted = options.animation.unwrap_or(0);
            let clip = match asset.clips.into_iter().find(|c| c.animation_index == wanted) {
                Some(c) => c.clip,
                None if options.animation.is_none() => {
                    let skeleton = asset.skeleton.ok_or_else(|| {
                        FormatError::file(
                            path,
                            FormatErrorKind::Structure,
                            "the file has neither animations nor a skeleton",
                        )
                    })?;
                    warnings.push("the file has no animation: loaded its rest pose as a one-frame clip".into());
                    Clip::rest_pose(skeleton, 30.0, 1)
                        .map_err(|e| FormatError::file(path, FormatErrorKind::Value, e.to_string()))?
                }
                None => {
                    return Err(FormatError::file(
                        path,
                        FormatErrorKind::Structure,
                        format!("the file has no animation {wanted}"),
                    ));
                }
            };
            Ok(Loaded { value: clip, warnings })
        }
        "fbx" => {
            let fbx_options = FbxReadOptions {
                take: options.animation,
                sample_fps: options.sample_fps,
                meshes: false,
                max_clip_bytes: options.max_clip_bytes,
                bind_pose: false,
            };
            let Loaded { value: asset, mut warnings } = read_fbx_file(path, &fbx_options)?;
            if options.metres_per_unit.is_some() {
                warnings.push("metres_per_unit is ignored for FBX, which states its unit".into());
            }
            if options.up_axis != UpAxis::Y {
                warnings.push("up_axis is ignored for FBX, which states its axes".into());
            }
            warnings.push(format!("{}: {}", path.display(), asset.describe()));
            let wanted = options.animation.unwrap_or(0);
            match asset.clips.into_iter().find(|c| c.take_index == wanted) {
                Some(c) => Ok(Loaded { value: c.clip, warnings }),
                None => Err(FormatError::file(
                    path,
                    FormatErrorKind::Structure,
                    format!(
                        "has no take {wanted} to animate its skeleton of {} bones (takes found: [{}])",
                        asset.skeleton.len(),
                        asset.source.takes.join(", ")
                    ),
                )),
            }
        }
        _ => Err(FormatError::file(path, FormatErrorKind::Unsupported, "expected a .bvh, .gltf, .glb or .fbx file")),
    }
}

/// Reads meshes from an OBJ, glTF or GLB file (by extension).
pub fn load_meshes(path: &Path, metres_per_unit: Option<f64>) -> Result<Loaded<Vec<Mesh>>, FormatError> {
    let ext = crate::formats::extension(path);
    match ext.as_str() {
        "obj" => crate::formats::obj::read_obj_file(path, metres_per_unit),
        "gltf" | "glb" => {
            let loaded = read_gltf_file(path, &GltfReadOptions::default())?;
            Ok(Loaded { value: loaded.value.meshes, warnings: loaded.warnings })
        }
        _ => Err(FormatError::file(path, FormatErrorKind::Unsupported, "expected a .obj, .gltf or .glb file")),
    }
}

/// A whole character read from one glTF/GLB scene: its skeleton's clip and every mesh of
/// the scene merged into one skinned mesh on that skeleton.
#[derive(Clone, Debug, PartialEq)]
pub struct Character {
    /// The chosen animation, or the rest pose (one frame) when the file has none.
    pub clip: Clip,
    /// Every mesh and primitive, in file order, skinned to the clip's skeleton in its rest
    /// pose, with each primitive's material; each source mesh is one of its parts, so an
    /// export writes them back as separate objects. Its inverse bind matrices are the file's own
    /// when they fit the rest pose (see [`IBM_FIT_RELATIVE`]), else the exact inverse rest
    /// world transforms.
    pub mesh: Mesh,
    /// What each source mesh became, in order.
    pub parts: Vec<CharacterPart>,
    /// Whether the mesh's inverse bind matrices are the file's own (they fit the rest
    /// pose) rather than computed.
    pub file_inverse_bind_matrices: bool,
}

/// Whether the file's inverse bind matrices `source` (per joint, `None` where the skin has
/// none) can replace the `computed` ones: every vertex of `mesh` (at rest, skinned to
/// `joints`) lands within [`IBM_FIT_RELATIVE`] of the character's size of where the
/// computed ones put it, i.e. the rest pose is the skin's bind pose. Returns the largest
/// such distance (metres) when they fit.
fn source_ibms_fit(
    source: &[Option<Mat4>],
    computed: &[Mat4],
    mesh: &Mesh,
    joints: &[[u16; 4]],
    weights: &[[f32; 4]],
) -> Option<f32> {
    if source.len() != computed.len() || source.iter().all(Option::is_none) {
        return None;
    }
    let mut worst = 0.0f32;
    for ((p, row), w) in mesh.positions.iter().zip(joints).zip(weights) {
        for (&j, _) in row.iter().zip(w).filter(|(_, w)| **w > 0.0) {
            let j = j as usize;
            if let (Some(Some(s)), Some(c)) = (source.get(j), computed.get(j)) {
                worst = worst.max(s.transform_point3(*p).distance(c.transform_point3(*p)));
            }
        }
    }
    let size = mesh.bounds().map_or(0.0, |(lo, hi)| lo.distance(hi));
    (worst <= IBM_FIT_RELATIVE * size.max(1.0)).then_some(worst)
}

/// One source mesh of a [`Character`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CharacterPart {
    /// The mesh's name.
    pub name: String,
    /// Its vertices.
    pub vertices: usize,
    /// `"skinned"`, or `"rigid to <joint>"` for a mesh parented to a bone (or placed
    /// beside the skeleton, then bound to its root).
    pub binding: String,
}

/// Largest distance the file's own inverse bind matrices may move any vertex of a
/// character at rest, compared with the inverse rest world transforms, and still be
/// written instead of them, as a fraction of the character's size (its bounding box
/// diagonal, at least 1 m): 18 µm on a 1.8 m human, far below what a viewer shows, above
/// the f32 noise of composing a rig's transforms (1.1e-6 m on the Mixamo Xbot, 6.5e-5 on
/// the 150-unit Fox).
pub const IBM_FIT_RELATIVE: f32 = 1e-5;

/// What a character file holds, whatever its format: the skeleton, the chosen clip, the
/// meshes with the joint each unskinned one hangs under and the name of the object holding
/// it, and the file's own inverse bind matrices per joint where it has them.
struct CharacterSource {
    skeleton: std::sync::Arc<crate::model::Skeleton>,
    clip: Clip,
    meshes: Vec<Mesh>,
    mesh_joints: Vec<Option<usize>>,
    mesh_objects: Vec<Option<String>>,
    file_ibms: Vec<Option<Mat4>>,
}

/// The clip a character file's animation `animation` gives, or its rest pose (one frame)
/// when the file has no animation at all.
fn character_clip(
    path: &Path,
    skeleton: &std::sync::Arc<crate::model::Skeleton>,
    clips: impl IntoIterator<Item = Clip>,
    animation: usize,
    warnings: &mut Vec<String>,
) -> Result<Clip, FormatError> {
    match clips.into_iter().nth(animation) {
        Some(c) => Ok(c),
        None if animation == 0 => {
            warnings.push("the file has no animation; the character stands in its rest pose".into());
            Clip::rest_pose(skeleton.clone(), 30.0, 1)
                .map_err(|e| FormatError::file(path, FormatErrorKind::Structure, e.to_string()))
        }
        None => Err(FormatError::file(path, FormatErrorKind::Structure, format!("has no animation {animation}"))),
    }
}

/// Which pose a loaded character's skeleton rests in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RestPose {
    /// The file's node transforms (what a viewer shows with no animation playing).
    #[default]
    Nodes,
    /// The skin's bind pose: each joint where its inverse bind matrix puts it (the pose the
    /// mesh was modelled and bound in; CesiumMan's differs from its node transforms). Joints
    /// the skin does not list keep their node transforms under their parents.
    Bind,
}
crate::model::choice::choices!(RestPose { Nodes = "nodes", Bind = "bind" });

/// `skeleton` resting in the bind pose of `ibms` (per joint, `None` where the skin has
/// none): each listed joint's world transform is `B` times its inverse bind matrix
/// inverted (scale dropped), its local one that relative to its parent's. `B` places the
/// bind space (exporters bind in the scene's space, as Xbot's, or in the armature's, as
/// CesiumMan's Z-up one): it is the one that leaves the first listed joint (the root, as a
/// rule) where the node transforms put it, so the character stands where it stood.
fn bind_rest_skeleton(skeleton: &Skeleton, ibms: &[Option<Mat4>]) -> Result<Skeleton, String> {
    let node_world = rest_world(skeleton);
    let bind_space = ibms
        .iter()
        .zip(&node_world)
        .find_map(|(ibm, world)| ibm.map(|ibm| world.to_mat4() * ibm))
        .ok_or("the skin lists no joint of the skeleton")?;
    let mut world: Vec<Transform> = Vec::with_capacity(skeleton.len());
    let mut joints = skeleton.joints().to_vec();
    for (j, joint) in joints.iter_mut().enumerate() {
        let parent = joint.parent.map_or(Transform::IDENTITY, |p| world[p]);
        let bound = match ibms.get(j).copied().flatten() {
            Some(ibm) if ibm.determinant().abs() > f32::EPSILON => {
                let (_, rotation, translation) = (bind_space * ibm.inverse()).to_scale_rotation_translation();
                Transform { rotation: crate::math::quat_normalize_or_identity(rotation), translation }
            }
            // Not in the skin: its node transform under its (bound) parent.
            _ => parent.compose(joint.rest_rotation, joint.rest_offset),
        };
        let to_parent = parent.rotation.inverse();
        joint.rest_rotation = to_parent * bound.rotation;
        joint.rest_offset = to_parent * (bound.translation - parent.translation);
        world.push(bound);
    }
    Skeleton::new(joints).map_err(|e| e.to_string())
}

/// A glTF/GLB scene as a [`CharacterSource`] (materials read), resting in `rest`.
fn gltf_character(path: &Path, animation: usize, rest: RestPose) -> Result<Loaded<CharacterSource>, FormatError> {
    let options = GltfReadOptions { materials: true, ..GltfReadOptions::default() };
    let Loaded { value: mut asset, mut warnings } = read_gltf_file(path, &options)?;
    let Some(mut skeleton) = asset.skeleton.clone() else {
        return Err(FormatError::file(path, FormatErrorKind::Structure, "has no skeleton (no skin and no animation)"));
    };
    if rest == RestPose::Bind {
        if asset.skin_inverse_bind_matrices.iter().all(Option::is_none) {
            return Err(FormatError::file(path, FormatErrorKind::Structure, "has no skin, so no bind pose to rest in"));
        }
        let bound = bind_rest_skeleton(&skeleton, &asset.skin_inverse_bind_matrices)
            .map_err(|e| FormatError::file(path, FormatErrorKind::Value, format!("its bind pose: {e}")))?;
        // A mesh hung on a bone goes with its bone from the node pose to the bind pose.
        let (node_world, bind_world) = (rest_world(&skeleton), rest_world(&bound));
        for (mesh, joint) in asset.meshes.iter_mut().zip(&asset.mesh_joints) {
            if let (Some(j), None) = (*joint, &mesh.skin) {
                let moved = bind_world[j].to_mat4() * node_world[j].inverse_to_mat4();
                let turned = glam::Mat3::from_mat4(moved);
                mesh.positions.iter_mut().for_each(|p| *p = moved.transform_point3(*p));
                mesh.normals.iter_mut().for_each(|n| *n = turned * *n);
            }
        }
        skeleton = std::sync::Arc::new(bound);
        // The animations' frames are local transforms, the same on either rest pose.
        for c in &mut asset.clips {
            c.clip = Clip::new(
                skeleton.clone(),
                c.clip.fps(),
                c.clip.rotations().to_vec(),
                c.clip.translations().to_vec(),
                c.clip.import_scale,
            )
            .map_err(|e| FormatError::file(path, FormatErrorKind::Value, e.to_string()))?;
        }
    }
    // A character has one skeleton: a mesh skinned to another one cannot follow it.
    if let Some(foreign) = asset.foreign_skins.first() {
        let mesh = &asset.meshes[foreign.mesh].name;
        let shown: Vec<&str> = foreign.outside.iter().take(5).map(String::as_str).collect();
        let more = foreign.outside.len().saturating_sub(shown.len());
        let more = if more > 0 { format!(" and {more} more") } else { String::new() };
        return Err(FormatError::file(
            path,
            FormatErrorKind::Structure,
            format!(
                "holds two skeletons: mesh '{mesh}' is skinned (skin {}) to {} joints of another armature \
                 ({}{more}); a character has one skeleton: export each character to its own file, or join the \
                 armatures into one",
                foreign.skin,
                foreign.outside.len(),
                shown.join(", ")
            ),
        ));
    }
    let clip = character_clip(path, &skeleton, asset.clips.into_iter().map(|c| c.clip), animation, &mut warnings)?;
    let value = CharacterSource {
        skeleton,
        clip,
        meshes: asset.meshes,
        mesh_joints: asset.mesh_joints,
        mesh_objects: asset.mesh_nodes,
        file_ibms: asset.skin_inverse_bind_matrices,
    };
    Ok(Loaded { value, warnings })
}

/// An FBX scene as a [`CharacterSource`]: its meshes come skinned to the skeleton in the
/// rest pose with their materials (see [`read_fbx_file`]); the clip is take `animation`.
fn fbx_character(path: &Path, animation: usize, rest: RestPose) -> Result<Loaded<CharacterSource>, FormatError> {
    let options = FbxReadOptions { meshes: true, bind_pose: rest == RestPose::Bind, ..FbxReadOptions::default() };
    let Loaded { value: asset, mut warnings } = read_fbx_file(path, &options)?;
    // What was converted (unit, axes, frame rate, takes), as clip.load reports it.
    warnings.push(format!("{}: {}", path.display(), asset.describe()));
    let clip =
        character_clip(path, &asset.skeleton, asset.clips.into_iter().map(|c| c.clip), animation, &mut warnings)?;
    let mesh_joints = vec![None; asset.meshes.len()];
    let mesh_objects = vec![None; asset.meshes.len()];
    let value = CharacterSource {
        skeleton: asset.skeleton,
        clip,
        meshes: asset.meshes,
        mesh_joints,
        mesh_objects,
        file_ibms: Vec::new(),
    };
    Ok(Loaded { value, warnings })
}

/// Reads a glTF/GLB or FBX file as one character (see [`Character`]): skinned meshes keep
/// their weights and are put in the skeleton's rest pose; meshes without a skin hang rigidly
/// from the joint their node is parented under (weight 1), or from the root joint with a
/// warning when they are not under the skeleton. Each primitive keeps its material (shared
/// ones merged); UVs are kept when any mesh has them (zero on the others). A glTF texture
/// whose image file is missing is an error naming the file; an FBX texture neither embedded
/// nor beside the file is left out with a warning (FBX files often name textures on the
/// machine that wrote them; see [`crate::formats::fbx`]).
pub fn load_character(path: &Path, animation: usize) -> Result<Loaded<Character>, FormatError> {
    load_character_resting(path, animation, RestPose::Nodes)
}

/// [`load_character`] with the skeleton resting in `rest`.
pub fn load_character_resting(path: &Path, animation: usize, rest: RestPose) -> Result<Loaded<Character>, FormatError> {
    let fbx = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("fbx"));
    let Loaded { value: source, mut warnings } =
        if fbx { fbx_character(path, animation, rest)? } else { gltf_character(path, animation, rest)? };
    let CharacterSource { skeleton, clip, meshes, mesh_joints, mesh_objects, file_ibms } = source;
    if meshes.is_empty() {
        return Err(FormatError::file(path, FormatErrorKind::Structure, "has no mesh"));
    }
    let rest = rest_world(&skeleton);
    let has_uvs = |m: &Mesh| m.uvs.as_ref().is_some_and(|u| u.len() == m.positions.len());
    let any_uvs = meshes.iter().any(has_uvs);
    let name = path.file_stem().map_or_else(|| "character".to_owned(), |s| s.to_string_lossy().into_owned());
    let mut mesh = Mesh { name, ..Mesh::default() };
    let (mut joints, mut weights, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
    let mut parts = Vec::new();
    for ((part, attached), object) in meshes.iter().zip(&mesh_joints).zip(&mesh_objects) {
        let base = mesh.positions.len() as u32;
        let n = part.positions.len();
        let normals = if part.normals.len() == n {
            part.normals.clone()
        } else {
            Mesh::compute_normals(&part.positions, &part.triangles)
        };
        let binding = match &part.skin {
            Some(skin)
                if skin.skeleton.len() == skeleton.len() && skin.joints.len() == n && skin.weights.len() == n =>
            {
                // Put every vertex in the rest pose: Σ w · rest world · inverse bind.
                for (v, (p, normal)) in part.positions.iter().zip(&normals).enumerate() {
                    let mut m = glam::Mat4::ZERO;
                    for (&j, &w) in skin.joints[v].iter().zip(&skin.weights[v]) {
                        let j = j as usize;
                        if let (true, Some(world), Some(ibm)) =
                            (w != 0.0, rest.get(j), skin.inverse_bind_matrices.get(j))
                        {
                            m += (world.to_mat4() * *ibm) * w;
                        }
                    }
                    // A vertex no bone weighs stays where the file put it.
                    if m == glam::Mat4::ZERO {
                        m = glam::Mat4::IDENTITY;
                    }
                    mesh.positions.push(m.transform_point3(*p));
                    mesh.normals.push(m.transform_vector3(*normal).try_normalize().unwrap_or(glam::Vec3::Y));
                }
                joints.extend_from_slice(&skin.joints);
                weights.extend_from_slice(&skin.weights);
                "skinned".to_owned()
            }
            _ => {
                let j = match attached {
                    Some(j) => *j,
                    None => {
                        warnings.push(format!(
                            "mesh '{}' is not parented to a joint; bound rigidly to the root joint '{}'",
                            part.name,
                            skeleton.joints()[0].name
                        ));
                        0
                    }
                };
                mesh.positions.extend_from_slice(&part.positions);
                mesh.normals.extend(normals);
                joints.extend(std::iter::repeat_n([j as u16, 0, 0, 0], n));
                weights.extend(std::iter::repeat_n([1.0, 0.0, 0.0, 0.0], n));
                format!("rigid to {}", skeleton.joints()[j].name)
            }
        };
        match &part.uvs {
            Some(u) if has_uvs(part) => uvs.extend_from_slice(u),
            _ if any_uvs => {
                if part.materials.iter().any(|m| m.textures().next().is_some()) {
                    warnings.push(format!("mesh '{}' has textures but no UVs; it draws untextured", part.name));
                }
                uvs.extend(std::iter::repeat_n(glam::Vec2::ZERO, n));
            }
            _ => {}
        }
        mesh.triangles.extend(part.triangles.iter().map(|t| t.map(|i| i + base)));
        mesh.append_materials_of(part);
        mesh.push_part(&part.name, object.as_deref());
        parts.push(CharacterPart { name: part.name.clone(), vertices: n, binding });
    }
    if any_uvs {
        mesh.uvs = Some(uvs);
    }
    mesh.drop_empty_material_ranges();
    // One character, one skeleton: skin on bones under two roots is two characters (an FBX
    // scene's bones all become one skeleton, whatever armature they belong to).
    let mut root_of: Vec<usize> = (0..skeleton.len()).collect();
    for j in 0..skeleton.len() {
        if let Some(p) = skeleton.joints()[j].parent {
            root_of[j] = root_of[p];
        }
    }
    let mut carried: Vec<usize> = joints
        .iter()
        .zip(&weights)
        .flat_map(|(js, ws)| js.iter().zip(ws).filter(|(_, w)| **w > 0.0).map(|(&j, _)| root_of[usize::from(j)]))
        .collect();
    carried.sort_unstable();
    carried.dedup();
    if carried.len() > 1 {
        let names: Vec<&str> = carried.iter().map(|&r| skeleton.joints()[r].name.as_str()).collect();
        return Err(FormatError::file(
            path,
            FormatErrorKind::Structure,
            format!(
                "holds {} skeletons: its meshes are skinned to bones under the roots {}; a character has one \
                 skeleton: export each character to its own file, or join the armatures into one",
                carried.len(),
                names.join(", ")
            ),
        ));
    }
    let computed: Vec<Mat4> = rest.iter().map(|t| t.inverse_to_mat4()).collect();
    let fit = source_ibms_fit(&file_ibms, &computed, &mesh, &joints, &weights);
    let file_inverse_bind_matrices = fit.is_some();
    let inverse_bind_matrices = match fit {
        Some(_) => file_ibms.iter().zip(computed).map(|(s, c)| s.unwrap_or(c)).collect(),
        None => computed,
    };
    mesh.skin = Some(Skin { skeleton, joints, weights, inverse_bind_matrices });
    Ok(Loaded { value: Character { clip, mesh, parts, file_inverse_bind_matrices }, warnings })
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{Quat, Vec3};

    use super::*;
    use crate::model::{ImportScale, Joint, Skeleton};

    #[test]
    fn a_t_pose_first_frame_is_recognised_and_a_smooth_start_is_not() {
        let s = Arc::new(
            Skeleton::new(vec![
                Joint::new("Hips", None, Vec3::Y),
                Joint::new("LeftArm", Some(0), Vec3::X),
                Joint::new("RightArm", Some(0), -Vec3::X),
                Joint::new("LeftHand", Some(1), Vec3::X),
                Joint::new("RightHand", Some(2), -Vec3::X),
            ])
            .unwrap(),
        );
        // Arms 0.14 rad in the T-pose, then captured at 1.6 rad moving 0.004 rad a frame.
        let clip = |first: f32| {
            let angles = [first, 1.6, 1.604, 1.608];
            let rotations = angles.iter().flat_map(|a| {
                [Quat::IDENTITY, Quat::from_rotation_z(*a), Quat::from_rotation_z(-*a), Quat::IDENTITY, Quat::IDENTITY]
            });
            Clip::new(s.clone(), 120.0, rotations.collect(), vec![Vec3::Y; 20], ImportScale::METRES).unwrap()
        };
        assert!(starts_with_t_pose(&clip(0.14)));
        assert!(!starts_with_t_pose(&clip(1.596)));
    }
}
