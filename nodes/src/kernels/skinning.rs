//! Binding meshes to skeletons and linear blend skinning (SSD): automatic weights, skinning
//! matrices, their blend and the LBS deformation.
//!
//! A kernel: `skin.bind`, `skin.deform` (pose-space deformation starts from LBS), the
//! bar-net deformer and the editor's viewport all skin with it.

use std::sync::Arc;

use glam::{Affine3A, Mat3A, Mat4, Vec3, Vec3A};
use rayon::prelude::*;

use crate::model::fk::{Transform, pose_world, rest_world};
use crate::model::{Clip, Mesh, MeshSequence, Skeleton, Skin};

/// Vertices per rayon task: large enough that scheduling costs little against the
/// arithmetic, small enough that two cores share a 10k-vertex mesh evenly.
const VERTEX_CHUNK: usize = 1024;

/// Distances below this (metres) count as on the bone, so the falloff stays finite.
const MIN_BONE_DISTANCE_M: f32 = 1e-4;

/// Why a skin cannot be used with a clip or built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkinError {
    /// The mesh has no skin.
    #[error("the mesh is not skinned: bind it to a skeleton first (skin.bind)")]
    NotSkinned,
    /// The skin's skeleton and the clip's differ.
    #[error(
        "the mesh is skinned to a different skeleton than the clip's ({skin} joints vs {clip}; first difference: {detail})"
    )]
    SkeletonMismatch {
        /// Joints of the skin's skeleton.
        skin: usize,
        /// Joints of the clip's skeleton.
        clip: usize,
        /// What differs.
        detail: String,
    },
    /// The skin's arrays do not match the mesh or skeleton.
    #[error("the skin's arrays do not match: {0}")]
    Inconsistent(String),
    /// The skeleton has no joint a vertex could be bound to.
    #[error("the skeleton has no joints to bind to")]
    EmptySkeleton,
}

/// Checks that `skin` can be driven by `skeleton` (same joint names and parents, in order)
/// and that its arrays match `vertices`.
pub fn check_skin(skin: &Skin, skeleton: &Skeleton, vertices: usize) -> Result<(), SkinError> {
    let (a, b) = (skin.skeleton.joints(), skeleton.joints());
    if let Some((i, (ja, jb))) =
        a.iter().zip(b).enumerate().find(|(_, (ja, jb))| ja.name != jb.name || ja.parent != jb.parent)
    {
        return Err(SkinError::SkeletonMismatch {
            skin: a.len(),
            clip: b.len(),
            detail: format!("joint {i} is '{}' in the skin, '{}' in the clip", ja.name, jb.name),
        });
    }
    if a.len() != b.len() {
        return Err(SkinError::SkeletonMismatch { skin: a.len(), clip: b.len(), detail: "joint counts".into() });
    }
    if skin.joints.len() != vertices || skin.weights.len() != vertices {
        return Err(SkinError::Inconsistent(format!(
            "{} joint rows and {} weight rows for {vertices} vertices",
            skin.joints.len(),
            skin.weights.len()
        )));
    }
    if skin.inverse_bind_matrices.len() != b.len() || skin.inverse_bind_matrices.iter().any(|m| !m.is_finite()) {
        return Err(SkinError::Inconsistent("one finite inverse bind matrix per joint is needed".into()));
    }
    if let Some(v) = skin.joints.iter().position(|row| row.iter().any(|&j| j as usize >= b.len())) {
        return Err(SkinError::Inconsistent(format!("vertex {v} names a joint outside the skeleton")));
    }
    Ok(())
}

/// A joint name the skeleton does not have.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("no joint '{name}'{hint}")]
pub struct UnknownJoint {
    /// The name asked for.
    pub name: String,
    /// `" (did you mean 'x'?)"` for the nearest joint name, or empty.
    pub hint: String,
}

/// The index of the joint called `name`, or an error naming the nearest joint.
pub fn joint_named(skeleton: &Skeleton, name: &str) -> Result<usize, UnknownJoint> {
    skeleton.index_of(name).ok_or_else(|| UnknownJoint {
        name: name.to_owned(),
        hint: crate::model::names::did_you_mean(name, skeleton.joints().iter().map(|j| j.name.as_str())),
    })
}

/// Per joint, the matrix taking bind-pose mesh points to their posed world position:
/// `world_from_joint(pose) · inverse_bind`.
pub fn skinning_matrices(world_from_joint: &[Transform], inverse_bind: &[Mat4]) -> Vec<Affine3A> {
    world_from_joint.iter().zip(inverse_bind).map(|(t, ibm)| Affine3A::from_mat4(t.to_mat4() * *ibm)).collect()
}

/// Skinning matrices of every frame of `clip`, frame-major.
pub fn clip_skinning_matrices(clip: &Clip, skin: &Skin) -> Vec<Affine3A> {
    let joints = clip.joint_count();
    let mut world = vec![Transform::IDENTITY; joints];
    let mut out = Vec::with_capacity(joints * clip.frame_count());
    for f in 0..clip.frame_count() {
        pose_world(clip.skeleton(), clip.frame_rotations(f), clip.frame_translations(f), &mut world);
        out.extend(skinning_matrices(&world, &skin.inverse_bind_matrices));
    }
    out
}

/// The weighted sum of a vertex's (up to four) skinning matrices. The weights are used as
/// stored: the skin's rows already sum to one.
#[inline]
pub fn blend_matrices(matrices: &[Affine3A], joints: &[u16; 4], weights: &[f32; 4]) -> Affine3A {
    let mut x = Vec3A::ZERO;
    let mut y = Vec3A::ZERO;
    let mut z = Vec3A::ZERO;
    let mut t = Vec3A::ZERO;
    for (&j, &w) in joints.iter().zip(weights) {
        if w == 0.0 {
            continue;
        }
        let m = &matrices[j as usize];
        x += m.matrix3.x_axis * w;
        y += m.matrix3.y_axis * w;
        z += m.matrix3.z_axis * w;
        t += m.translation * w;
    }
    Affine3A { matrix3: Mat3A::from_cols(x, y, z), translation: t }
}

/// Linear blend skinning of one frame into `positions_m` and `normals` (both as long as
/// the rest arrays): `v = Σ_j w_j M_j v₀`, normals by the blended linear part, then
/// renormalised (the blend of rotations is not a rotation). Runs on all cores.
pub fn lbs_frame(
    rest_positions: &[Vec3],
    rest_normals: &[Vec3],
    skin: &Skin,
    matrices: &[Affine3A],
    positions_m: &mut [Vec3],
    normals: &mut [Vec3],
) {
    positions_m.par_chunks_mut(VERTEX_CHUNK).zip(normals.par_chunks_mut(VERTEX_CHUNK)).enumerate().for_each(
        |(chunk, (pos_out, nrm_out))| {
            let start = chunk * VERTEX_CHUNK;
            for (i, (p, n)) in pos_out.iter_mut().zip(nrm_out.iter_mut()).enumerate() {
                let v = start + i;
                let m = blend_matrices(matrices, &skin.joints[v], &skin.weights[v]);
                *p = m.transform_point3a(Vec3A::from(rest_positions[v])).into();
                *n = m.matrix3.mul_vec3a(Vec3A::from(rest_normals[v])).normalize_or_zero().into();
            }
        },
    );
}

/// Rest normals to skin: the mesh's own when it has one per vertex, else computed.
pub fn rest_normals(mesh: &Mesh) -> Vec<Vec3> {
    if mesh.normals.len() == mesh.positions.len() {
        mesh.normals.clone()
    } else {
        Mesh::compute_normals(&mesh.positions, &mesh.triangles)
    }
}

/// Linear blend skinning (SSD) of `mesh` over every frame of `clip`.
pub fn deform_lbs(mesh: &Arc<Mesh>, clip: &Arc<Clip>) -> Result<MeshSequence, SkinError> {
    let skin = mesh.skin.as_ref().ok_or(SkinError::NotSkinned)?;
    check_skin(skin, clip.skeleton(), mesh.positions.len())?;
    let n = mesh.positions.len();
    let normals0 = rest_normals(mesh);
    let matrices = clip_skinning_matrices(clip, skin);
    let joints = clip.joint_count();
    let mut positions = vec![Vec3::ZERO; n * clip.frame_count()];
    let mut normals = vec![Vec3::ZERO; n * clip.frame_count()];
    for f in 0..clip.frame_count() {
        let range = f * n..(f + 1) * n;
        lbs_frame(
            &mesh.positions,
            &normals0,
            skin,
            &matrices[f * joints..(f + 1) * joints],
            &mut positions[range.clone()],
            &mut normals[range],
        );
    }
    MeshSequence::new(mesh.clone(), clip.clone(), positions, normals)
        .map_err(|e| SkinError::Inconsistent(e.to_string()))
}

/// Per-vertex joint indices and matching weights: the rows of a [`Skin`].
pub type Influences = (Vec<[u16; 4]>, Vec<[f32; 4]>);

/// Settings of [`auto_weights`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoWeightParams {
    /// Exponent of the inverse-distance falloff (default 4): higher is stiffer, with a
    /// narrower blend zone around each joint.
    pub falloff_power: f32,
    /// Rounds of neighbour averaging over the mesh edges (default 2), which soften the seams
    /// the nearest-bone rule leaves.
    pub smoothing_iterations: usize,
}

impl Default for AutoWeightParams {
    fn default() -> Self {
        AutoWeightParams { falloff_power: 4.0, smoothing_iterations: 2 }
    }
}

/// Distance from `p` to the segment `a`–`b` (a point when they coincide).
pub fn segment_distance(p: Vec3, a: Vec3, b: Vec3) -> f32 {
    let ab = b - a;
    let length_sq = ab.length_squared();
    let t = if length_sq > 1e-12 { ((p - a).dot(ab) / length_sq).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).length()
}

/// Keeps the four largest weights of a dense row and normalises them (the rows of a
/// [`Skin`]); a row with no positive weight goes wholly to `fallback`.
pub fn top_four(dense: &[f32], fallback: u16) -> ([u16; 4], [f32; 4]) {
    let mut order: Vec<usize> = (0..dense.len()).filter(|&j| dense[j] > 0.0 && dense[j].is_finite()).collect();
    order.sort_by(|&a, &b| dense[b].total_cmp(&dense[a]).then(a.cmp(&b)));
    order.truncate(4);
    let sum: f32 = order.iter().map(|&j| dense[j]).sum();
    let mut joints = [0u16; 4];
    let mut weights = [0f32; 4];
    if order.is_empty() || sum <= 0.0 {
        joints[0] = fallback;
        weights[0] = 1.0;
        return (joints, weights);
    }
    for (k, &j) in order.iter().enumerate() {
        joints[k] = j as u16;
        weights[k] = dense[j] / sum;
    }
    (joints, weights)
}

/// Automatic weights: each joint owns the bones from it to its children (end sites own
/// nothing); a vertex's raw weight for a joint is `1 / distance^power` to the nearest of
/// its bones, averaged with the mesh neighbours `smoothing_iterations` times, then reduced
/// to the four largest and normalised. Assumes the mesh is modelled in the skeleton's rest
/// pose, in the same space.
pub fn auto_weights(mesh: &Mesh, skeleton: &Skeleton, params: AutoWeightParams) -> Result<Influences, SkinError> {
    let rest = skeleton.rest_positions();
    let owners: Vec<usize> = (0..skeleton.len()).filter(|&j| !skeleton.joints()[j].end_site).collect();
    if owners.is_empty() {
        return Err(SkinError::EmptySkeleton);
    }
    let bones: Vec<Vec<(Vec3, Vec3)>> = owners
        .iter()
        .map(|&j| {
            let children: Vec<(Vec3, Vec3)> = skeleton.children(j).map(|c| (rest[j], rest[c])).collect();
            if children.is_empty() { vec![(rest[j], rest[j])] } else { children }
        })
        .collect();
    let power = params.falloff_power.max(0.0);
    let mut dense: Vec<Vec<f32>> = mesh
        .positions
        .par_iter()
        .map(|&p| {
            let mut row = vec![0f32; skeleton.len()];
            for (k, &j) in owners.iter().enumerate() {
                let d = bones[k].iter().map(|&(a, b)| segment_distance(p, a, b)).fold(f32::INFINITY, f32::min);
                row[j] = d.max(MIN_BONE_DISTANCE_M).powf(-power);
            }
            let sum: f32 = row.iter().sum();
            if sum > 0.0 && sum.is_finite() {
                row.iter_mut().for_each(|w| *w /= sum);
            }
            row
        })
        .collect();
    let mut neighbours = vec![Vec::new(); mesh.positions.len()];
    for tri in &mesh.triangles {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            let (a, b) = (a as usize, b as usize);
            if a < neighbours.len() && b < neighbours.len() {
                neighbours[a].push(b);
                neighbours[b].push(a);
            }
        }
    }
    for _ in 0..params.smoothing_iterations {
        dense = (0..dense.len())
            .into_par_iter()
            .map(|v| {
                let mut row = dense[v].clone();
                let count = neighbours[v].len();
                if count > 0 {
                    // Half own value, half the neighbours' mean: smooths without drifting.
                    for (j, w) in row.iter_mut().enumerate() {
                        let mean = neighbours[v].iter().map(|&n| dense[n][j]).sum::<f32>() / count as f32;
                        *w = 0.5 * *w + 0.5 * mean;
                    }
                }
                row
            })
            .collect();
    }
    let fallback = owners[0] as u16;
    Ok(dense.iter().map(|row| top_four(row, fallback)).unzip())
}

/// How `skin.bind` treats a mesh that already has weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindMode {
    /// Keep the mesh's own weights when it has them (they must match the skeleton).
    Keep,
    /// Always compute automatic weights.
    Automatic,
}

/// Binds `mesh` (modelled in the rest pose) to `skeleton`: automatic weights unless the
/// mesh already has a skin and `mode` keeps it; inverse bind matrices from the rest pose.
pub fn bind(
    mesh: &Mesh,
    skeleton: &Arc<Skeleton>,
    mode: BindMode,
    params: AutoWeightParams,
) -> Result<Mesh, SkinError> {
    if let (BindMode::Keep, Some(skin)) = (mode, &mesh.skin) {
        check_skin(skin, skeleton, mesh.positions.len())?;
        return Ok(mesh.clone());
    }
    let (joints, weights) = auto_weights(mesh, skeleton, params)?;
    let inverse_bind_matrices = rest_world(skeleton).iter().map(|t| t.to_mat4().inverse()).collect();
    let mut out = mesh.clone();
    if out.normals.len() != out.positions.len() {
        out.normals = Mesh::compute_normals(&out.positions, &out.triangles);
    }
    out.skin = Some(Skin { skeleton: skeleton.clone(), joints, weights, inverse_bind_matrices });
    Ok(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::formats::gltf::{GltfReadOptions, read_gltf_file};
    use crate::model::Joint;
    use crate::model::forward_kinematics;

    /// A straight two-bone chain along +X and a row of vertices along it.
    fn chain() -> (Arc<Skeleton>, Mesh) {
        let skeleton = Arc::new(
            Skeleton::new(vec![
                Joint::new("a", None, Vec3::ZERO),
                Joint::new("b", Some(0), Vec3::new(1.0, 0.0, 0.0)),
                Joint::new("c", Some(1), Vec3::new(1.0, 0.0, 0.0)),
            ])
            .unwrap(),
        );
        let positions: Vec<Vec3> = (0..=20).map(|i| Vec3::new(i as f32 * 0.1, 0.1, 0.0)).collect();
        let triangles = (0..20u32).map(|i| [i, i + 1, i]).collect();
        let mesh = Mesh { name: "row".into(), positions, triangles, ..Mesh::default() };
        (skeleton, mesh)
    }

    #[test]
    fn automatic_weights_are_normalised_local_and_blend_at_the_joint() {
        let (skeleton, mesh) = chain();
        let (joints, weights) = auto_weights(&mesh, &skeleton, AutoWeightParams::default()).unwrap();
        for (js, ws) in joints.iter().zip(&weights) {
            assert!((ws.iter().sum::<f32>() - 1.0).abs() < 1e-5);
            assert!(ws.iter().all(|w| (0.0..=1.0).contains(w)));
            assert!(js.iter().all(|&j| (j as usize) < skeleton.len()));
        }
        let weight_of = |v: usize, j: u16| {
            joints[v].iter().zip(&weights[v]).filter(|(k, _)| **k == j).map(|(_, w)| *w).sum::<f32>()
        };
        // Far along bone a, nearly all a; far along bone b, nearly all b; at the joint, shared.
        assert!(weight_of(2, 0) > 0.9, "{:?}", weights[2]);
        assert!(weight_of(18, 1) > 0.6, "{:?}", weights[18]);
        assert!((weight_of(10, 0) - weight_of(10, 1)).abs() < 0.3, "{:?}", weights[10]);
    }

    #[test]
    fn top_four_keeps_the_largest_and_falls_back_on_empty_rows() {
        let (j, w) = top_four(&[0.1, 0.5, 0.0, 0.2, 0.3, 0.05], 0);
        assert_eq!(j, [1, 4, 3, 0]);
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert_eq!(top_four(&[0.0, f32::NAN], 1), ([1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0]));
    }

    #[test]
    fn binding_at_rest_reproduces_the_mesh_and_mismatched_skeletons_are_refused() {
        let (skeleton, mesh) = chain();
        let bound = bind(&mesh, &skeleton, BindMode::Automatic, AutoWeightParams::default()).unwrap();
        let clip = Arc::new(Clip::rest_pose(skeleton.clone(), 30.0, 2).unwrap());
        let seq = deform_lbs(&Arc::new(bound.clone()), &clip).unwrap();
        for (p, q) in seq.frame_positions(1).iter().zip(&mesh.positions) {
            assert!((*p - *q).length() < 1e-5);
        }
        let other = Arc::new(Skeleton::new(vec![Joint::new("x", None, Vec3::ZERO)]).unwrap());
        assert!(matches!(
            bind(&bound, &other, BindMode::Keep, AutoWeightParams::default()),
            Err(SkinError::SkeletonMismatch { .. })
        ));
        assert!(matches!(deform_lbs(&Arc::new(mesh), &clip), Err(SkinError::NotSkinned)));
    }

    /// CesiumMan at several times, against a plain per-vertex sum written here from the
    /// glTF skinning definition: v = Σ_k w_k · (world_from_joint_k · inverse_bind_k) · v₀.
    #[test]
    fn lbs_of_cesium_man_matches_a_plain_per_vertex_sum() {
        let Some(data) = crate::corpus::shared_data() else { return };
        let path = data.join("gltf/CesiumMan.glb");
        let asset = read_gltf_file(&path, &GltfReadOptions::default()).unwrap().value;
        let mesh = Arc::new(asset.meshes.into_iter().find(|m| m.skin.is_some()).unwrap());
        let clip = Arc::new(asset.clips[0].clip.clone());
        let seq = deform_lbs(&mesh, &clip).unwrap();
        let skin = mesh.skin.as_ref().unwrap();
        let poses = forward_kinematics(&clip);
        let frames = clip.frame_count();
        for f in [0, frames / 3, frames / 2, frames - 1] {
            let world = poses.frame(f);
            for v in (0..mesh.positions.len()).step_by(7) {
                let p0 = mesh.positions[v].extend(1.0);
                let mut expected = glam::Vec4::ZERO;
                for k in 0..4 {
                    let j = skin.joints[v][k] as usize;
                    let m = Mat4::from_rotation_translation(world[j].rotation, world[j].translation)
                        * skin.inverse_bind_matrices[j];
                    expected += skin.weights[v][k] * (m * p0);
                }
                let got = seq.frame_positions(f)[v];
                assert!((got - expected.truncate()).length() < 1e-4, "frame {f} vertex {v}: {got} vs {expected}");
                assert!((seq.frame_normals(f)[v].length() - 1.0).abs() < 1e-3);
            }
        }
    }
}
