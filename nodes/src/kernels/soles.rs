//! Skinned soles: where a character's feet meet the floor, read from its mesh. A rig's
//! ankle joint sits some centimetres above the skin, by an amount that differs from rig
//! to rig, so ankle heights say little about whether a planted foot floats or sinks.
//!
//! A foot is its ankle joint and every joint below it (toes, toe tips). Its sole is the
//! mesh's vertices whose heaviest skin weight is on one of those joints, chosen once from
//! the skin (the bind pose); in each frame the foot's lowest point is the lowest of those
//! vertices skinned by linear blend skinning. Heights are world y in the clip's metres.
//!
//! A kernel: the foot lock's ground mode puts this lowest point on the floor and the quality
//! measures check it.

use super::skinning::{SkinError, blend_matrices, check_skin, clip_skinning_matrices};
use crate::model::{Clip, Mesh, Skeleton, Skin};

/// The ankle `ankle` and every joint below it.
pub fn foot_joints(skeleton: &Skeleton, ankle: usize) -> Vec<usize> {
    (0..skeleton.len()).filter(|&j| j == ankle || skeleton.is_ancestor(ankle, j)).collect()
}

/// The vertices of a skinned mesh whose heaviest weight is on one of `joints`.
fn sole_vertices(skin: &Skin, joints: &[usize]) -> Vec<usize> {
    (0..skin.joints.len()).filter(|&v| joints.contains(&skin.heaviest_joint(v).0)).collect()
}

/// Per foot (each given by its joints, e.g. from [`foot_joints`]), the height of its sole's
/// lowest vertex in every frame of `clip` (metres), or `None` for a foot no vertex is bound
/// to. Refused when `mesh` is not skinned to the clip's skeleton.
pub fn lowest_sole_heights(clip: &Clip, mesh: &Mesh, feet: &[Vec<usize>]) -> Result<Vec<Option<Vec<f64>>>, SkinError> {
    let skin = mesh.skin.as_ref().ok_or(SkinError::NotSkinned)?;
    check_skin(skin, clip.skeleton(), mesh.positions.len())?;
    let matrices = clip_skinning_matrices(clip, skin);
    let joints = clip.joint_count();
    let heights = feet.iter().map(|foot| {
        let sole = sole_vertices(skin, foot);
        (!sole.is_empty()).then(|| {
            (0..clip.frame_count())
                .map(|f| {
                    let frame_matrices = &matrices[f * joints..(f + 1) * joints];
                    sole.iter()
                        .map(|&v| {
                            let m = blend_matrices(frame_matrices, &skin.joints[v], &skin.weights[v]);
                            f64::from(m.transform_point3(mesh.positions[v]).y)
                        })
                        .fold(f64::INFINITY, f64::min)
                })
                .collect()
        })
    });
    Ok(heights.collect())
}
