//! glTF reader: node hierarchy → [`Skeleton`], animations → fixed-rate [`Clip`]s, skinned
//! primitives → [`Mesh`] with [`Skin`].
//!
//! Steps: 1. load and validate the document (see `document`); 2. read every node's local
//! transform (TRS or matrix) and parent, refusing nodes with two parents and cycles;
//! 3. pick the joint nodes (one skin's joints plus the nodes between them) and order them
//! parents first; 4. sample each animation at a fixed rate, evaluating every node's local
//! transform and composing world similarity transforms (rotation, translation, uniform
//! scale) so that ancestors and scale can be baked into the clip; 5. read mesh primitives,
//! check weights and joint indices, and re-express skinned meshes in the rest pose.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Mat3, Mat4, Quat, Vec2, Vec3};
use gltf_json::animation::{Interpolation, Property};
use gltf_json::mesh::{Mode, Semantic};
use gltf_json::validation::Checked;

use crate::formats::error::{FormatError, FormatErrorKind as Kind, Loaded};
use crate::math::{quat_normalize_or_identity, slerp_short};
use crate::model::clip::sampling_refusal;
use crate::model::{Clip, ImportScale, Joint, Material, Mesh, Skeleton, Skin};

use super::ReadError;
use super::accessor::{Decoded, decode};
use super::document::{Document, load};
use super::material::read_materials;

/// Frame rate used when an animation's keys give no spacing to infer one from.
pub const FALLBACK_SAMPLE_FPS: f64 = 30.0;

/// Inferred rates outside `1..=1000` fps are not trusted; the fallback is used instead.
const INFERRED_FPS_RANGE: std::ops::RangeInclusive<f64> = 1.0..=1000.0;

/// Relative difference between scale components above which a scale counts as
/// non-uniform, and between an animated and rest scale above which the animated one is
/// reported as ignored.
const SCALE_TOL: f32 = 1e-4;

/// Weight sums further than this from one are renormalised with a warning.
const WEIGHT_SUM_TOL: f64 = 1e-3;

/// Options for reading glTF.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GltfReadOptions {
    /// Read only this animation (index into the file's `animations`); `None` reads all.
    pub animation: Option<usize>,
    /// Build the skeleton from this skin (index into `skins`); `None` uses skin 0 with the
    /// other skins over the same armature, or the animated nodes when the file has no skin.
    pub skin: Option<usize>,
    /// Sampling rate for clips (frames per second); `None` infers it per animation with
    /// [`infer_sample_fps`].
    pub sample_fps: Option<f64>,
    /// Largest clip to sample, in bytes of rotations and translations (the run's memory
    /// limit); `None` uses [`crate::model::clip::DEFAULT_MAX_SAMPLED_BYTES`].
    pub max_clip_bytes: Option<u64>,
    /// Read the meshes' materials, textures and images (see [`Mesh::materials`]). Off for
    /// motion and plain mesh loading, which must not fail over a missing texture file.
    pub materials: bool,
}

/// One animation of the file, sampled to a fixed-rate clip.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfClip {
    /// The animation's name, or `animation_<index>` when it has none.
    pub name: String,
    /// Index of the animation in the file.
    pub animation_index: usize,
    /// Seconds in the file's timeline of the clip's frame 0 (the earliest key).
    pub start_secs: f64,
    /// The sampled clip on [`GltfAsset::skeleton`].
    pub clip: Clip,
}

/// Everything kinegraph takes from a glTF file.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfAsset {
    /// The joint hierarchy, when the file has a skin or animations.
    pub skeleton: Option<Arc<Skeleton>>,
    /// For each skeleton joint, the glTF node index it came from.
    pub joint_nodes: Vec<usize>,
    /// One clip per (selected) animation, in file order.
    pub clips: Vec<GltfClip>,
    /// One mesh per node that carries a mesh, in node order (metres).
    pub meshes: Vec<Mesh>,
    /// Per mesh of `meshes`: for a mesh without a skin whose node hangs under a skeleton
    /// joint's node (a prop or armour plate parented to a bone), that joint; else `None`.
    pub mesh_joints: Vec<Option<usize>>,
    /// Per mesh of `meshes`: the name of the node carrying it (the object a viewer lists,
    /// which may differ from the mesh's own name), when the node has one.
    pub mesh_nodes: Vec<Option<String>>,
    /// Meshes whose skin binds joints outside the skeleton (a second character's skeleton):
    /// they are read unskinned, with a warning.
    pub foreign_skins: Vec<ForeignSkin>,
    /// Per skeleton joint: the skeleton's skin's own inverse bind matrix for it, in the
    /// skeleton's unscaled metre frame (a scaled ancestor's scale taken out), or `None`
    /// for joints the skin does not list and files without a skin.
    pub skin_inverse_bind_matrices: Vec<Option<Mat4>>,
}

/// A mesh whose skin binds joints outside the skeleton the file was read with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ForeignSkin {
    /// Index into [`GltfAsset::meshes`].
    pub mesh: usize,
    /// The skin (index into the file's `skins`).
    pub skin: usize,
    /// Names of its joints outside the skeleton (node names, or `node N`).
    pub outside: Vec<String>,
}

/// Reads a `.gltf` or `.glb` file from disk.
pub fn read_gltf_file(path: &Path, options: &GltfReadOptions) -> Result<Loaded<GltfAsset>, FormatError> {
    let bytes = std::fs::read(path).map_err(|e| FormatError::io(path, &e))?;
    read_gltf(&bytes, path, options)
}

/// Parses glTF or GLB `bytes`. `path` names the file in errors and is the base for
/// external buffer files (relative URIs only).
pub fn read_gltf(bytes: &[u8], path: &Path, options: &GltfReadOptions) -> Result<Loaded<GltfAsset>, FormatError> {
    read_inner(bytes, path, options).map_err(|e| e.into_format_error(path))
}

/// Infers a sampling rate from key times: the reciprocal of the median spacing between
/// consecutive keys, snapped to a whole number of frames per second when within 1 %.
/// Falls back to 30 fps (`FALLBACK_SAMPLE_FPS`) when there is no spacing (single keys) or the
/// result lies outside 1–1000 fps. Median rather than minimum, so one pair of nearly
/// coincident keys does not force a huge rate.
pub fn infer_sample_fps<'a>(key_times_secs: impl IntoIterator<Item = &'a [f64]>) -> f64 {
    let mut deltas: Vec<f64> = Vec::new();
    for times in key_times_secs {
        deltas.extend(times.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 1e-6));
    }
    if deltas.is_empty() {
        return FALLBACK_SAMPLE_FPS;
    }
    deltas.sort_by(f64::total_cmp);
    let median = deltas[deltas.len() / 2];
    let fps = 1.0 / median;
    let rounded = fps.round();
    let fps = if (fps - rounded).abs() <= 0.01 * fps { rounded } else { fps };
    if INFERRED_FPS_RANGE.contains(&fps) { fps } else { FALLBACK_SAMPLE_FPS }
}

/// A similarity transform: rotation, translation and one uniform scale.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Similarity {
    translation: Vec3,
    rotation: Quat,
    scale: f32,
}

impl Similarity {
    const IDENTITY: Similarity = Similarity { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: 1.0 };

    /// `self ∘ child`.
    fn compose(&self, child: &Similarity) -> Similarity {
        Similarity {
            translation: self.translation + self.rotation * (self.scale * child.translation),
            rotation: self.rotation * child.rotation,
            scale: self.scale * child.scale,
        }
    }
}

/// A node's local transform as stored in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Trs {
    translation: Vec3,
    rotation: Quat,
    scale: Vec3,
}

impl Trs {
    fn to_mat4(self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// Uniform stand-in for a possibly non-uniform scale (mean of the components).
fn uniform_scale(scale: Vec3) -> f32 {
    (scale.x + scale.y + scale.z) / 3.0
}

fn is_uniform(scale: Vec3) -> bool {
    let m = uniform_scale(scale).abs().max(f32::MIN_POSITIVE);
    ((scale - Vec3::splat(uniform_scale(scale))).abs().max_element() / m) <= SCALE_TOL
}

/// The node tree: local rest transforms, parents and a parents-first order.
struct NodeTree {
    rest: Vec<Trs>,
    parent: Vec<Option<usize>>,
    /// Every node, parents before children.
    order: Vec<usize>,
    names: Vec<String>,
}

fn read_node_tree(doc: &Document, warnings: &mut Vec<String>) -> Result<NodeTree, ReadError> {
    let nodes = &doc.root.nodes;
    let n = nodes.len();
    let mut rest = Vec::with_capacity(n);
    let mut names = Vec::with_capacity(n);
    for (i, node) in nodes.iter().enumerate() {
        let path = format!("/nodes/{i}");
        names.push(node.name.clone().unwrap_or_else(|| format!("node_{i}")));
        let trs = if let Some(m) = node.matrix {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(ReadError::new(format!("{path}/matrix"), Kind::Value, "matrix holds a non-finite value"));
            }
            let mat = Mat4::from_cols_array(&m);
            if mat.determinant() < 0.0 {
                warnings.push(format!("node {i} ('{}') has a mirroring matrix; its reflection is not kept", names[i]));
            }
            let (scale, rotation, translation) = mat.to_scale_rotation_translation();
            Trs { translation, rotation: quat_normalize_or_identity(rotation), scale: scale.abs() }
        } else {
            let t = node.translation.unwrap_or([0.0; 3]);
            let r = node.rotation.as_ref().map(|q| q.0).unwrap_or([0.0, 0.0, 0.0, 1.0]);
            let s = node.scale.unwrap_or([1.0; 3]);
            if t.iter().chain(&r).chain(&s).any(|v| !v.is_finite()) {
                return Err(ReadError::new(
                    path,
                    Kind::Value,
                    "translation, rotation or scale holds a non-finite value",
                ));
            }
            Trs {
                translation: Vec3::from(t),
                rotation: quat_normalize_or_identity(Quat::from_array(r)),
                scale: Vec3::from(s),
            }
        };
        rest.push(trs);
    }

    let mut parent: Vec<Option<usize>> = vec![None; n];
    for (i, node) in nodes.iter().enumerate() {
        for (k, child) in node.children.iter().flatten().enumerate() {
            let c = child.value();
            let at = format!("/nodes/{i}/children/{k}");
            if c >= n {
                return Err(ReadError::new(at, Kind::Structure, format!("node {c} does not exist")));
            }
            if c == i {
                return Err(ReadError::new(at, Kind::Structure, format!("node {i} lists itself as a child (cycle)")));
            }
            if let Some(p) = parent[c] {
                return Err(ReadError::new(
                    at,
                    Kind::Structure,
                    format!("node {c} already has parent {p}; a node may have only one"),
                ));
            }
            parent[c] = Some(i);
        }
    }

    // Parents-first order; any node never reached from a parentless node is on a cycle.
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, node) in nodes.iter().enumerate() {
        children[i] = node.children.iter().flatten().map(|c| c.value()).collect();
    }
    let mut order = Vec::with_capacity(n);
    let mut visited = vec![false; n];
    for root in (0..n).filter(|&i| parent[i].is_none()) {
        let mut stack = vec![root];
        while let Some(v) = stack.pop() {
            if visited[v] {
                continue;
            }
            visited[v] = true;
            order.push(v);
            stack.extend(children[v].iter().rev().copied());
        }
    }
    if let Some(i) = visited.iter().position(|v| !v) {
        return Err(ReadError::new(
            format!("/nodes/{i}"),
            Kind::Structure,
            format!("node {i} is part of a cycle in the node hierarchy"),
        ));
    }
    Ok(NodeTree { rest, parent, order, names })
}

/// Chooses the joint nodes and orders them parents first.
struct JointSet {
    /// Node index per joint.
    nodes: Vec<usize>,
    /// Joint index per node.
    joint_of_node: Vec<Option<usize>>,
    /// Parent joint per joint.
    parent_joint: Vec<Option<usize>>,
}

fn joint_set(tree: &NodeTree, seeds: &[usize]) -> JointSet {
    let n = tree.parent.len();
    let mut is_seed = vec![false; n];
    for &s in seeds {
        is_seed[s] = true;
    }
    let mut member = is_seed.clone();
    for &s in seeds {
        let mut path = Vec::new();
        let mut cur = tree.parent[s];
        while let Some(p) = cur {
            if is_seed[p] {
                for &q in &path {
                    member[q] = true;
                }
                break;
            }
            path.push(p);
            cur = tree.parent[p];
        }
    }
    let nodes: Vec<usize> = tree.order.iter().copied().filter(|&v| member[v]).collect();
    let mut joint_of_node = vec![None; n];
    for (j, &v) in nodes.iter().enumerate() {
        joint_of_node[v] = Some(j);
    }
    let parent_joint = nodes.iter().map(|&v| tree.parent[v].and_then(|p| joint_of_node[p])).collect();
    JointSet { nodes, joint_of_node, parent_joint }
}

/// One animation channel with decoded keys.
struct Channel<'a> {
    node: usize,
    property: Property,
    interpolation: Interpolation,
    times: &'a [f64],
    values: &'a Decoded,
}

/// Samples a channel at `t` seconds into `out` (3 or 4 numbers).
fn sample_channel(ch: &Channel<'_>, t: f64) -> [f32; 4] {
    let times = ch.times;
    let n = times.len();
    let cubic = ch.interpolation == Interpolation::CubicSpline;
    let value = |k: usize| -> [f64; 4] {
        let e = ch.values.element(if cubic { 3 * k + 1 } else { k });
        [e[0], e[1], e[2], e.get(3).copied().unwrap_or(0.0)]
    };
    let to_f32 = |v: [f64; 4]| v.map(|x| x as f32);
    let last = n - 1;
    if n == 1 || t <= times[0] {
        return to_f32(value(0));
    }
    if t >= times[last] {
        return to_f32(value(last));
    }
    let k = times.partition_point(|&x| x <= t).saturating_sub(1).min(last - 1);
    let dt = times[k + 1] - times[k];
    if dt <= 0.0 {
        return to_f32(value(k + 1));
    }
    let s = (t - times[k]) / dt;
    let is_rotation = ch.property == Property::Rotation;
    match ch.interpolation {
        Interpolation::Step => to_f32(value(k)),
        Interpolation::Linear => {
            let (a, b) = (value(k), value(k + 1));
            if is_rotation {
                let qa = Quat::from_array(to_f32(a));
                let qb = Quat::from_array(to_f32(b));
                slerp_short(quat_normalize_or_identity(qa), quat_normalize_or_identity(qb), s as f32).to_array()
            } else {
                to_f32(std::array::from_fn(|i| a[i] + (b[i] - a[i]) * s))
            }
        }
        Interpolation::CubicSpline => {
            let p0 = value(k);
            let p1 = value(k + 1);
            let out_tangent = ch.values.element(3 * k + 2);
            let in_tangent = ch.values.element(3 * (k + 1));
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            let c = ch.values.components;
            let mut out = [0.0f64; 4];
            for i in 0..c.min(4) {
                out[i] = h00 * p0[i] + h10 * dt * out_tangent[i] + h01 * p1[i] + h11 * dt * in_tangent[i];
            }
            let out = to_f32(out);
            if is_rotation { quat_normalize_or_identity(Quat::from_array(out)).to_array() } else { out }
        }
    }
}

fn read_inner(bytes: &[u8], path: &Path, options: &GltfReadOptions) -> Result<Loaded<GltfAsset>, ReadError> {
    let doc = load(bytes, path)?;
    let mut warnings = doc.warnings.clone();
    let tree = read_node_tree(&doc, &mut warnings)?;
    let root = &doc.root;

    if let Some(fps) = options.sample_fps
        && !(fps.is_finite() && fps > 0.0)
    {
        return Err(ReadError::file(Kind::Value, format!("sample rate must be positive and finite, got {fps}")));
    }
    let animation_indices: Vec<usize> = match options.animation {
        Some(a) if a >= root.animations.len() => {
            return Err(ReadError::new(
                "/animations",
                Kind::Structure,
                format!("animation {a} requested, the file has {}", root.animations.len()),
            ));
        }
        Some(a) => vec![a],
        None => (0..root.animations.len()).collect(),
    };

    // Seeds of the skeleton: a skin's joints, else the animated nodes.
    let skin_index = match options.skin {
        Some(s) if s >= root.skins.len() => {
            return Err(ReadError::new(
                "/skins",
                Kind::Structure,
                format!("skin {s} requested, the file has {}", root.skins.len()),
            ));
        }
        Some(s) => Some(s),
        None if root.skins.is_empty() => None,
        None => Some(0),
    };
    let mut seeds = Vec::new();
    if let Some(s) = skin_index {
        let mut seen = vec![false; tree.parent.len()];
        for (k, joint) in root.skins[s].joints.iter().enumerate() {
            let v = joint.value();
            let at = format!("/skins/{s}/joints/{k}");
            if v >= tree.parent.len() {
                return Err(ReadError::new(at, Kind::Structure, format!("node {v} does not exist")));
            }
            if seen[v] {
                return Err(ReadError::new(at, Kind::Structure, format!("node {v} is listed twice")));
            }
            seen[v] = true;
            seeds.push(v);
        }
        // Without a chosen skin, the other skins over the same armature (one per mesh, some
        // listing bones skin 0 does not: a face's, a weapon's) join the skeleton; skins over
        // another armature (another character) stay out.
        if options.skin.is_none() {
            let top = |mut v: usize| {
                while let Some(p) = tree.parent[v] {
                    v = p;
                }
                v
            };
            let armature = seeds.first().map(|&v| top(v));
            for other in root.skins.iter().skip(1) {
                let nodes: Vec<usize> = other.joints.iter().map(|j| j.value()).filter(|&v| v < seen.len()).collect();
                if nodes.iter().all(|&v| Some(top(v)) == armature) {
                    for v in nodes {
                        if !std::mem::replace(&mut seen[v], true) {
                            seeds.push(v);
                        }
                    }
                }
            }
        }
    } else {
        for &a in &animation_indices {
            for (c, ch) in root.animations[a].channels.iter().enumerate() {
                let v = ch.target.node.value();
                if v >= tree.parent.len() {
                    return Err(ReadError::new(
                        format!("/animations/{a}/channels/{c}/target/node"),
                        Kind::Structure,
                        format!("node {v} does not exist"),
                    ));
                }
                if !seeds.contains(&v) {
                    seeds.push(v);
                }
            }
        }
    }

    let joints = joint_set(&tree, &seeds);
    let skeleton = if joints.nodes.is_empty() { None } else { Some(build_skeleton(&tree, &joints, &mut warnings)?) };

    let mut clips = Vec::new();
    if let Some(skeleton) = &skeleton {
        let mut cache: BTreeMap<usize, Decoded> = BTreeMap::new();
        for &a in &animation_indices {
            clips.push(read_animation(&doc, a, &tree, &joints, skeleton, options, &mut cache, &mut warnings)?);
        }
    } else if !animation_indices.is_empty() {
        warnings.push("animations found but no skeleton could be formed; no clips read".to_string());
    }

    let materials = if options.materials { read_materials(&doc, path, &mut warnings)? } else { Vec::new() };
    let NodeMeshes { meshes, mesh_joints, mesh_nodes, foreign_skins } =
        read_meshes(&doc, &tree, &joints, skeleton.as_ref(), skin_index, &materials, &mut warnings)?;
    let mut skin_inverse_bind_matrices = vec![None; joints.nodes.len()];
    if let Some(s) = skin_index {
        let ibms = skin_matrices(&doc, s, root.skins[s].joints.len())?;
        let mut world = vec![Similarity::IDENTITY; tree.parent.len()];
        world_similarities(&tree, &tree.rest, &mut world);
        for (k, joint) in root.skins[s].joints.iter().enumerate() {
            if let Some(j) = joints.joint_of_node[joint.value()] {
                skin_inverse_bind_matrices[j] = Some(unscaled_ibm(world[joint.value()].scale, ibms[k]));
            }
        }
    }
    Ok(Loaded {
        value: GltfAsset {
            skeleton,
            joint_nodes: joints.nodes.clone(),
            clips,
            meshes,
            mesh_joints,
            mesh_nodes,
            foreign_skins,
            skin_inverse_bind_matrices,
        },
        warnings,
    })
}

/// World similarity of every node for local transforms `local` (parents first).
fn world_similarities(tree: &NodeTree, local: &[Trs], out: &mut [Similarity]) {
    for &v in &tree.order {
        let l = local[v];
        let own = Similarity { translation: l.translation, rotation: l.rotation, scale: uniform_scale(l.scale) };
        out[v] = match tree.parent[v] {
            Some(p) => out[p].compose(&own),
            None => own,
        };
    }
}

/// A joint's clip-space local transform: rotation and translation in its parent joint's
/// unscaled frame, with non-joint ancestors baked in for roots.
fn joint_local(tree: &NodeTree, joints: &JointSet, j: usize, local: &[Trs], world: &[Similarity]) -> (Quat, Vec3) {
    let v = joints.nodes[j];
    let l = local[v];
    match tree.parent[v] {
        Some(p) if joints.parent_joint[j].is_some() => (l.rotation, world[p].scale * l.translation),
        Some(p) => {
            let a = world[p];
            (a.rotation * l.rotation, a.translation + a.rotation * (a.scale * l.translation))
        }
        None => (l.rotation, l.translation),
    }
}

fn build_skeleton(tree: &NodeTree, joints: &JointSet, warnings: &mut Vec<String>) -> Result<Arc<Skeleton>, ReadError> {
    let mut world = vec![Similarity::IDENTITY; tree.parent.len()];
    world_similarities(tree, &tree.rest, &mut world);
    // Non-uniform scale on the joints or their ancestors.
    let mut reported = vec![false; tree.parent.len()];
    for &v in &joints.nodes {
        let mut cur = Some(v);
        while let Some(u) = cur {
            if !reported[u] && !is_uniform(tree.rest[u].scale) {
                reported[u] = true;
                warnings.push(format!(
                    "node {u} ('{}') has non-uniform scale {:?}; the skeleton uses its mean",
                    tree.names[u], tree.rest[u].scale
                ));
            }
            cur = tree.parent[u];
        }
    }
    let mut names_seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut list = Vec::with_capacity(joints.nodes.len());
    for (j, &v) in joints.nodes.iter().enumerate() {
        let mut name = tree.names[v].clone();
        if names_seen.contains_key(&name) {
            let renamed = format!("{name}_node{v}");
            warnings.push(format!("duplicate joint name '{name}' (node {v}) renamed to '{renamed}'"));
            name = renamed;
        }
        names_seen.insert(name.clone(), j);
        let (rotation, offset) = joint_local(tree, joints, j, &tree.rest, &world);
        let mut joint = Joint::new(name, joints.parent_joint[j], offset);
        joint.rest_rotation = rotation;
        list.push(joint);
    }
    Skeleton::new(list).map(Arc::new).map_err(|e| {
        ReadError::new(format!("/nodes/{}", joints.nodes.first().copied().unwrap_or(0)), Kind::Structure, e.to_string())
    })
}

/// Decodes accessor `index` once per file.
fn cached<'c>(
    doc: &Document,
    cache: &'c mut BTreeMap<usize, Decoded>,
    index: usize,
    referenced_at: &str,
) -> Result<&'c Decoded, ReadError> {
    match cache.entry(index) {
        std::collections::btree_map::Entry::Occupied(slot) => Ok(slot.into_mut()),
        std::collections::btree_map::Entry::Vacant(slot) => Ok(slot.insert(decode(doc, index, referenced_at)?)),
    }
}

#[allow(clippy::too_many_arguments)]
fn read_animation(
    doc: &Document,
    a: usize,
    tree: &NodeTree,
    joints: &JointSet,
    skeleton: &Arc<Skeleton>,
    options: &GltfReadOptions,
    cache: &mut BTreeMap<usize, Decoded>,
    warnings: &mut Vec<String>,
) -> Result<GltfClip, ReadError> {
    let animation = &doc.root.animations[a];
    let apath = format!("/animations/{a}");
    let name = animation.name.clone().unwrap_or_else(|| format!("animation_{a}"));
    let n_nodes = tree.parent.len();

    // Decode and check every sampler used.
    struct Spec {
        node: usize,
        property: Property,
        interpolation: Interpolation,
        input: usize,
        output: usize,
    }
    let mut specs: Vec<Spec> = Vec::new();
    let mut skipped_weights = false;
    for (c, ch) in animation.channels.iter().enumerate() {
        let cpath = format!("{apath}/channels/{c}");
        let s = ch.sampler.value();
        let sampler = animation.samplers.get(s).ok_or_else(|| {
            ReadError::new(format!("{cpath}/sampler"), Kind::Structure, format!("sampler {s} does not exist"))
        })?;
        let node = ch.target.node.value();
        if node >= n_nodes {
            return Err(ReadError::new(
                format!("{cpath}/target/node"),
                Kind::Structure,
                format!("node {node} does not exist"),
            ));
        }
        let Checked::Valid(property) = ch.target.path else {
            return Err(ReadError::new(format!("{cpath}/target/path"), Kind::Value, "unknown target path"));
        };
        if property == Property::MorphTargetWeights {
            skipped_weights = true;
            continue;
        }
        let Checked::Valid(interpolation) = sampler.interpolation else {
            return Err(ReadError::new(
                format!("{apath}/samplers/{s}/interpolation"),
                Kind::Value,
                "unknown interpolation",
            ));
        };
        let spath = format!("{apath}/samplers/{s}");
        let input = sampler.input.value();
        let output = sampler.output.value();
        let times = cached(doc, cache, input, &format!("{spath}/input"))?;
        if times.components != 1 || times.count == 0 {
            return Err(ReadError::new(
                format!("/accessors/{input}"),
                Kind::Structure,
                "animation input must be a non-empty SCALAR accessor",
            ));
        }
        if let Some(k) = times.values.windows(2).position(|w| w[1] < w[0]) {
            return Err(ReadError::new(
                format!("/accessors/{input}"),
                Kind::Value,
                format!("key time {} decreases", k + 1),
            ));
        }
        let key_count = times.count;
        let values = cached(doc, cache, output, &format!("{spath}/output"))?;
        let want_components = if property == Property::Rotation { 4 } else { 3 };
        let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        if values.components != want_components || values.count != key_count * per_key {
            return Err(ReadError::new(
                format!("{spath}/output"),
                Kind::Structure,
                format!(
                    "output accessor {output} has {} elements of {} components; expected {} of {want_components} for {key_count} keys",
                    values.count,
                    values.components,
                    key_count * per_key
                ),
            ));
        }
        specs.push(Spec { node, property, interpolation, input, output });
    }
    if skipped_weights {
        warnings.push(format!("animation '{name}': morph target weight channels ignored"));
    }
    let channels: Vec<Channel<'_>> = specs
        .iter()
        .filter_map(|s| {
            Some(Channel {
                node: s.node,
                property: s.property,
                interpolation: s.interpolation,
                times: &cache.get(&s.input)?.values,
                values: cache.get(&s.output)?,
            })
        })
        .collect();

    // Channels that cannot move the skeleton.
    let mut affects = vec![false; n_nodes];
    for &v in &joints.nodes {
        let mut cur = Some(v);
        while let Some(u) = cur {
            affects[u] = true;
            cur = tree.parent[u];
        }
    }
    let outside = channels.iter().filter(|c| !affects[c.node]).count();
    if outside > 0 {
        warnings.push(format!(
            "animation '{name}': {outside} channel(s) target nodes outside the skeleton and are ignored"
        ));
    }

    let start_secs = channels.iter().map(|c| c.times[0]).fold(f64::INFINITY, f64::min);
    let end_secs = channels.iter().map(|c| c.times[c.times.len() - 1]).fold(f64::NEG_INFINITY, f64::max);
    let (start_secs, end_secs) = if channels.is_empty() { (0.0, 0.0) } else { (start_secs, end_secs) };
    let fps = options.sample_fps.unwrap_or_else(|| infer_sample_fps(channels.iter().map(|c| c.times)));
    let span_frames = (end_secs - start_secs) * fps;
    if let Some(refusal) = sampling_refusal(span_frames + 1.0, skeleton.len(), options.max_clip_bytes, "sample_fps") {
        return Err(ReadError::new(
            apath,
            Kind::Unsupported,
            format!("{:.3} s at {fps} fps: {refusal}", end_secs - start_secs),
        ));
    }
    let frames = span_frames.round() as usize + 1;

    // Animated scale is not representable: report where it departs from the rest scale.
    let mut scale_reported = vec![false; n_nodes];
    let mut local = tree.rest.clone();
    let mut world = vec![Similarity::IDENTITY; n_nodes];
    let joint_count = skeleton.len();
    let mut rotations = Vec::with_capacity(frames * joint_count);
    let mut translations = Vec::with_capacity(frames * joint_count);
    for f in 0..frames {
        let t = (start_secs + f as f64 / fps).min(end_secs);
        local.copy_from_slice(&tree.rest);
        for ch in &channels {
            let v = sample_channel(ch, t);
            let l = &mut local[ch.node];
            match ch.property {
                Property::Translation => l.translation = Vec3::new(v[0], v[1], v[2]),
                Property::Rotation => l.rotation = quat_normalize_or_identity(Quat::from_array(v)),
                Property::Scale => {
                    let s = Vec3::new(v[0], v[1], v[2]);
                    let rest = tree.rest[ch.node].scale;
                    if affects[ch.node]
                        && !scale_reported[ch.node]
                        && (s - rest).abs().max_element() > SCALE_TOL * rest.abs().max_element().max(1.0)
                    {
                        scale_reported[ch.node] = true;
                        warnings.push(format!(
                            "animation '{name}': node {} ('{}') animates scale to {s:?} (rest {rest:?}); animated scale is ignored",
                            ch.node, tree.names[ch.node]
                        ));
                    }
                }
                Property::MorphTargetWeights => {}
            }
        }
        world_similarities(tree, &local, &mut world);
        for j in 0..joint_count {
            let (r, tr) = joint_local(tree, joints, j, &local, &world);
            rotations.push(r);
            translations.push(tr);
        }
    }
    let clip = Clip::new(skeleton.clone(), fps, rotations, translations, ImportScale::METRES)
        .map_err(|e| ReadError::new(format!("/animations/{a}"), Kind::Value, e.to_string()))?;
    Ok(GltfClip { name, animation_index: a, start_secs, clip })
}

/// Per vertex: skin joint indices and their weights.
type Influences = (Vec<[u16; 4]>, Vec<[f32; 4]>);

/// Primitive data gathered before merging.
struct PrimitiveData {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    triangles: Vec<[u32; 3]>,
    /// (skin joint indices, weights) per vertex.
    influences: Option<Influences>,
    /// Index of the file's material the primitive uses.
    material: Option<usize>,
}

fn vec3s(d: &Decoded, at: &str, what: &str) -> Result<Vec<Vec3>, ReadError> {
    if d.components != 3 {
        return Err(ReadError::new(at, Kind::Structure, format!("{what} must be VEC3")));
    }
    Ok(d.values.chunks_exact(3).map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)).collect())
}

fn read_primitive(
    doc: &Document,
    m: usize,
    p: usize,
    skin_joint_count: Option<usize>,
    warnings: &mut Vec<String>,
) -> Result<Option<PrimitiveData>, ReadError> {
    let prim = &doc.root.meshes[m].primitives[p];
    let ppath = format!("/meshes/{m}/primitives/{p}");
    match prim.mode {
        Checked::Valid(Mode::Triangles) => {}
        _ => {
            warnings.push(format!("mesh {m} primitive {p}: only triangle primitives are read; skipped"));
            return Ok(None);
        }
    }
    let attribute = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|i| i.value());
    let apath = |name: &str| format!("{ppath}/attributes/{name}");
    let Some(pos_index) = attribute(Semantic::Positions) else {
        return Err(ReadError::new(format!("{ppath}/attributes"), Kind::Structure, "primitive has no POSITION"));
    };
    let positions =
        vec3s(&decode(doc, pos_index, &apath("POSITION"))?, &format!("/accessors/{pos_index}"), "POSITION")?;
    let n = positions.len();
    let check_count = |d: &Decoded, index: usize, name: &str| -> Result<(), ReadError> {
        if d.count != n {
            return Err(ReadError::new(
                format!("/accessors/{index}"),
                Kind::Structure,
                format!("{name} has {} elements, POSITION has {n}", d.count),
            ));
        }
        Ok(())
    };
    let normals = match attribute(Semantic::Normals) {
        Some(i) => {
            let d = decode(doc, i, &apath("NORMAL"))?;
            check_count(&d, i, "NORMAL")?;
            Some(vec3s(&d, &format!("/accessors/{i}"), "NORMAL")?)
        }
        None => None,
    };
    let uvs = match attribute(Semantic::TexCoords(0)) {
        Some(i) => {
            let d = decode(doc, i, &apath("TEXCOORD_0"))?;
            check_count(&d, i, "TEXCOORD_0")?;
            if d.components != 2 {
                return Err(ReadError::new(format!("/accessors/{i}"), Kind::Structure, "TEXCOORD_0 must be VEC2"));
            }
            Some(d.values.chunks_exact(2).map(|c| Vec2::new(c[0] as f32, c[1] as f32)).collect())
        }
        None => None,
    };
    let triangles = match prim.indices {
        Some(index) => {
            let i = index.value();
            let d = decode(doc, i, &format!("{ppath}/indices"))?;
            if d.components != 1 || d.count % 3 != 0 {
                return Err(ReadError::new(
                    format!("/accessors/{i}"),
                    Kind::Structure,
                    "indices must be SCALAR with a multiple of 3 elements",
                ));
            }
            if let Some(k) = d.values.iter().position(|&v| v < 0.0 || v >= n as f64 || v.fract() != 0.0) {
                return Err(ReadError::new(
                    format!("/accessors/{i}"),
                    Kind::Value,
                    format!("index {k} is {}, outside 0..{n}", d.values[k]),
                ));
            }
            d.values.chunks_exact(3).map(|c| [c[0] as u32, c[1] as u32, c[2] as u32]).collect()
        }
        None => {
            if n % 3 != 0 {
                return Err(ReadError::new(
                    apath("POSITION"),
                    Kind::Structure,
                    "non-indexed triangles need a multiple of 3 vertices",
                ));
            }
            (0..n as u32 / 3).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect()
        }
    };
    let influences = match (skin_joint_count, attribute(Semantic::Joints(0)), attribute(Semantic::Weights(0))) {
        (Some(skin_joints), Some(ji), Some(wi)) => {
            let jd = decode(doc, ji, &apath("JOINTS_0"))?;
            let wd = decode(doc, wi, &apath("WEIGHTS_0"))?;
            check_count(&jd, ji, "JOINTS_0")?;
            check_count(&wd, wi, "WEIGHTS_0")?;
            if jd.components != 4 || wd.components != 4 {
                return Err(ReadError::new(
                    format!("{ppath}/attributes"),
                    Kind::Structure,
                    "JOINTS_0 and WEIGHTS_0 must be VEC4",
                ));
            }
            if attribute(Semantic::Joints(1)).is_some() {
                warnings
                    .push(format!("mesh {m} primitive {p}: JOINTS_1/WEIGHTS_1 ignored (at most 4 influences kept)"));
            }
            let mut joints = Vec::with_capacity(n);
            let mut weights = Vec::with_capacity(n);
            let mut renormalised = 0usize;
            for v in 0..n {
                let w = wd.element(v);
                let sum: f64 = w.iter().sum();
                if !(sum.is_finite() && sum > 0.0) || w.iter().any(|x| *x < 0.0) {
                    return Err(ReadError::new(
                        format!("/accessors/{wi}"),
                        Kind::Value,
                        format!(
                            "vertex {v} of mesh {m} primitive {p}: weights {w:?} are negative or sum to {sum}, not a positive number"
                        ),
                    ));
                }
                if (sum - 1.0).abs() > WEIGHT_SUM_TOL {
                    renormalised += 1;
                }
                let js = jd.element(v);
                let mut jrow = [0u16; 4];
                let mut wrow = [0f32; 4];
                for k in 0..4 {
                    wrow[k] = (w[k] / sum) as f32;
                    if wrow[k] > 0.0 {
                        let idx = js[k];
                        if idx < 0.0 || idx >= skin_joints as f64 {
                            return Err(ReadError::new(
                                format!("/accessors/{ji}"),
                                Kind::Value,
                                format!("vertex {v}: joint {idx} is outside the skin's {skin_joints} joints"),
                            ));
                        }
                        jrow[k] = idx as u16;
                    }
                }
                joints.push(jrow);
                weights.push(wrow);
            }
            if renormalised > 0 {
                warnings.push(format!(
                    "mesh {m} primitive {p}: {renormalised} vertex weight row(s) did not sum to 1 and were renormalised"
                ));
            }
            Some((joints, weights))
        }
        (Some(_), _, _) => {
            warnings.push(format!(
                "mesh {m} primitive {p}: skinned node but no JOINTS_0/WEIGHTS_0; bound rigidly to the first joint"
            ));
            Some((vec![[0; 4]; n], vec![[1.0, 0.0, 0.0, 0.0]; n]))
        }
        (None, _, _) => None,
    };
    Ok(Some(PrimitiveData {
        positions,
        normals,
        uvs,
        triangles,
        influences,
        material: prim.material.map(|m| m.value()),
    }))
}

/// The meshes of a file, one per node carrying a mesh, with the joint each unskinned one
/// hangs under, the name of its node and the skins that bind another skeleton (see
/// [`GltfAsset`]'s fields of the same names).
struct NodeMeshes {
    meshes: Vec<Mesh>,
    mesh_joints: Vec<Option<usize>>,
    mesh_nodes: Vec<Option<String>>,
    foreign_skins: Vec<ForeignSkin>,
}

fn read_meshes(
    doc: &Document,
    tree: &NodeTree,
    joints: &JointSet,
    skeleton: Option<&Arc<Skeleton>>,
    skin_index: Option<usize>,
    materials: &[Material],
    warnings: &mut Vec<String>,
) -> Result<NodeMeshes, ReadError> {
    let root = &doc.root;
    // Rest world matrices of all nodes (full scale) and of joints (similarity, unscaled).
    let mut world_mat = vec![Mat4::IDENTITY; tree.parent.len()];
    for &v in &tree.order {
        let l = tree.rest[v].to_mat4();
        world_mat[v] = match tree.parent[v] {
            Some(p) => world_mat[p] * l,
            None => l,
        };
    }
    let mut world_sim = vec![Similarity::IDENTITY; tree.parent.len()];
    world_similarities(tree, &tree.rest, &mut world_sim);

    let mut meshes = Vec::new();
    let mut mesh_joints = Vec::new();
    let mut mesh_nodes = Vec::new();
    let mut foreign_skins = Vec::new();
    for (node_index, node) in root.nodes.iter().enumerate() {
        let Some(mesh_ref) = node.mesh else { continue };
        let m = mesh_ref.value();
        let Some(gmesh) = root.meshes.get(m) else {
            return Err(ReadError::new(
                format!("/nodes/{node_index}/mesh"),
                Kind::Structure,
                format!("mesh {m} does not exist"),
            ));
        };
        // Which skin, and can it be expressed on our skeleton?
        let mut skin = None;
        if let Some(s) = node.skin.map(|s| s.value()) {
            let Some(gskin) = root.skins.get(s) else {
                return Err(ReadError::new(
                    format!("/nodes/{node_index}/skin"),
                    Kind::Structure,
                    format!("skin {s} does not exist"),
                ));
            };
            let mapped: Option<Vec<usize>> =
                gskin.joints.iter().map(|n| joints.joint_of_node.get(n.value()).copied().flatten()).collect();
            match (mapped, skeleton) {
                (Some(mapped), Some(skeleton)) => skin = Some((s, mapped, skeleton.clone())),
                _ => {
                    warnings.push(format!(
                        "node {node_index}: skin {s} has joints outside the skeleton (built from skin {skin_index:?}); mesh read unskinned"
                    ));
                    let outside = gskin
                        .joints
                        .iter()
                        .map(|n| n.value())
                        .filter(|&n| joints.joint_of_node.get(n).copied().flatten().is_none())
                        .map(|n| root.nodes.get(n).and_then(|x| x.name.clone()).unwrap_or_else(|| format!("node {n}")))
                        .collect();
                    foreign_skins.push(ForeignSkin { mesh: meshes.len(), skin: s, outside });
                }
            }
        }

        let mut prims = Vec::new();
        for p in 0..gmesh.primitives.len() {
            if let Some(d) = read_primitive(doc, m, p, skin.as_ref().map(|s| s.1.len()), warnings)? {
                prims.push(d);
            }
        }
        let name = gmesh.name.clone().or_else(|| node.name.clone()).unwrap_or_else(|| format!("mesh_{m}"));
        let mut mesh = Mesh { name, ..Mesh::default() };
        let all_normals = prims.iter().all(|p| p.normals.is_some());
        let all_uvs = !prims.is_empty() && prims.iter().all(|p| p.uvs.is_some());
        if !all_uvs && prims.iter().any(|p| p.uvs.is_some()) {
            warnings.push(format!("mesh '{}': TEXCOORD_0 on only some primitives; UVs dropped", mesh.name));
        }
        let mut uvs = Vec::new();
        let mut skin_joints: Vec<[u16; 4]> = Vec::new();
        let mut skin_weights: Vec<[f32; 4]> = Vec::new();
        for prim in &prims {
            if !materials.is_empty() {
                let material = prim.material.and_then(|m| materials.get(m)).map(|m| mesh.material_index(m));
                mesh.push_material_range(material, prim.triangles.len());
            }
            let base = mesh.positions.len() as u32;
            mesh.triangles.extend(prim.triangles.iter().map(|t| t.map(|i| i + base)));
            mesh.positions.extend_from_slice(&prim.positions);
            if let Some(n) = &prim.normals {
                mesh.normals.extend_from_slice(n);
            }
            if let (true, Some(u)) = (all_uvs, &prim.uvs) {
                uvs.extend_from_slice(u);
            }
            if let Some((j, w)) = &prim.influences {
                skin_joints.extend_from_slice(j);
                skin_weights.extend_from_slice(w);
            }
        }
        mesh.drop_empty_material_ranges();
        if all_uvs {
            mesh.uvs = Some(uvs);
        } else if mesh.materials.iter().any(|m| m.textures().next().is_some()) {
            warnings.push(format!(
                "mesh '{}': textured materials without UVs on every primitive draw untextured",
                mesh.name
            ));
        }
        if !all_normals {
            mesh.normals = Mesh::compute_normals(&mesh.positions, &mesh.triangles);
        }

        match skin {
            Some((s, mapped, skeleton)) => {
                let ibm_file = skin_matrices(doc, s, mapped.len())?;
                // Skinning matrix world × IBM with the scale moved from the joint into the IBM.
                let fk = |j: usize| {
                    let w = world_sim[joints.nodes[j]];
                    Mat4::from_rotation_translation(w.rotation, w.translation)
                };
                let mut ibm: Vec<Mat4> = (0..skeleton.len()).map(|j| fk(j).inverse()).collect();
                for (k, &j) in mapped.iter().enumerate() {
                    ibm[j] = unscaled_ibm(world_sim[joints.nodes[j]].scale, ibm_file[k]);
                }
                // Reference joint: the one carrying the most weight.
                let mut load = vec![0f64; mapped.len()];
                for (js, ws) in skin_joints.iter().zip(&skin_weights) {
                    for k in 0..4 {
                        load[js[k] as usize] += ws[k] as f64;
                    }
                }
                let reference = (0..mapped.len()).max_by(|a, b| load[*a].total_cmp(&load[*b])).unwrap_or(0);
                let reference_joint = mapped.get(reference).copied().unwrap_or(0);
                let mut bind_to_rest = fk(reference_joint) * ibm[reference_joint];
                if !bind_to_rest.is_finite() || bind_to_rest.determinant().abs() < 1e-12 {
                    warnings.push(format!("mesh '{}': degenerate inverse bind matrix; kept as in the file", mesh.name));
                    bind_to_rest = Mat4::IDENTITY;
                }
                let mismatched = mapped
                    .iter()
                    .enumerate()
                    .filter(|(k, _)| load[*k] > 0.0)
                    .filter(|(_, j)| !(fk(**j) * ibm[**j]).abs_diff_eq(bind_to_rest, 1e-3))
                    .count();
                if mismatched > 0 {
                    warnings.push(format!(
                        "mesh '{}': the node rest pose differs from the bind pose for {mismatched} joint(s); mesh positions are those of the reference joint's bind",
                        mesh.name
                    ));
                }
                let rest_from_bind = bind_to_rest.inverse();
                for m in &mut ibm {
                    *m *= rest_from_bind;
                }
                transform_mesh(&mut mesh, bind_to_rest);
                let joints_remapped = skin_joints
                    .iter()
                    .map(|row| row.map(|k| mapped.get(k as usize).copied().unwrap_or(0) as u16))
                    .collect();
                mesh.skin =
                    Some(Skin { skeleton, joints: joints_remapped, weights: skin_weights, inverse_bind_matrices: ibm });
            }
            None => transform_mesh(&mut mesh, world_mat[node_index]),
        }
        // The joint an unskinned mesh's node hangs under (the node itself may be a joint).
        let mut attached = None;
        if mesh.skin.is_none() {
            let mut at = Some(node_index);
            while let Some(n) = at {
                if let Some(j) = joints.joint_of_node.get(n).copied().flatten() {
                    attached = Some(j);
                    break;
                }
                at = tree.parent[n];
            }
        }
        // Finite vertex data can still leave a node's (or bind pose's) transform as inf.
        if !mesh.positions.iter().all(|p| p.is_finite()) {
            return Err(ReadError::new(
                format!("/nodes/{node_index}"),
                Kind::Value,
                format!("mesh '{}' has non-finite positions once placed by its node's transform", mesh.name),
            ));
        }
        mesh_joints.push(attached);
        mesh_nodes.push(node.name.clone());
        meshes.push(mesh);
    }
    Ok(NodeMeshes { meshes, mesh_joints, mesh_nodes, foreign_skins })
}

/// Skin `s`'s first `count` inverse bind matrices as the file stores them (identity when
/// it has none).
fn skin_matrices(doc: &Document, s: usize, count: usize) -> Result<Vec<Mat4>, ReadError> {
    let Some(i) = doc.root.skins[s].inverse_bind_matrices else {
        return Ok(vec![Mat4::IDENTITY; count]);
    };
    let d = decode(doc, i.value(), &format!("/skins/{s}/inverseBindMatrices"))?;
    if d.components != 16 || d.count < count {
        return Err(ReadError::new(
            format!("/skins/{s}/inverseBindMatrices"),
            Kind::Structure,
            format!("need {count} MAT4 elements, accessor {} has {} of {} numbers", i.value(), d.count, d.components),
        ));
    }
    Ok((0..count).map(|k| Mat4::from_cols_slice(&d.element(k).iter().map(|&x| x as f32).collect::<Vec<_>>())).collect())
}

/// A file's inverse bind matrix for a joint whose world transform carries uniform `scale`,
/// re-expressed against the joint's unscaled frame (the skeleton's): the scale moves from
/// the joint into the matrix. Scale 1 leaves the file's matrix bit for bit.
fn unscaled_ibm(scale: f32, ibm: Mat4) -> Mat4 {
    if scale == 1.0 { ibm } else { Mat4::from_scale(Vec3::splat(scale)) * ibm }
}

/// Maps positions and normals of `mesh` through `m`.
fn transform_mesh(mesh: &mut Mesh, m: Mat4) {
    if m == Mat4::IDENTITY {
        return;
    }
    let normal_matrix = Mat3::from_mat4(m).inverse().transpose();
    for p in &mut mesh.positions {
        *p = m.transform_point3(*p);
    }
    for n in &mut mesh.normals {
        *n = (normal_matrix * *n).try_normalize().unwrap_or(Vec3::Y);
    }
}
