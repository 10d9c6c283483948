//! How far a skinned character goes into the scene's fixed objects (props: the stool a
//! simulated figure sits on). Per frame the mesh is posed by linear blend skinning; a vertex
//! is inside a prop when the prop's surface winds around it (winding number above ½, so a
//! prop must be a closed surface, like physics.simulate's stool), and how deep it is is
//! its distance to the prop's nearest triangle. An animator sees a body through a chair
//! at once; the physics figure's capsules are thinner than the skinned mesh, so a figure
//! resting on a seat can sink into it.
//!
//! A kernel: `motion.quality` reports it beside the floor's penetration, and `kg test`
//! gates on it (`max_props_penetration_cm`).

use glam::{DVec3, Vec3};
use serde::Serialize;

use super::skinning::{SkinError, blend_matrices, check_skin, skinning_matrices};
use super::wrap::closest_barycentric;
use crate::math::solid::winding_number;
use crate::model::fk::{Transform, pose_world};
use crate::model::{Clip, FrameRange, Mesh};

/// A vertex this far inside a prop counts, metres (as a foot under the floor).
pub const INSIDE_SLACK_M: f64 = 0.001;

/// The deepest the mesh goes into the props over a window of frames.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PropsPenetration {
    /// Deepest vertex inside a prop, cm (0 when none is more than [`INSIDE_SLACK_M`] in).
    pub max_cm: f64,
    /// The frame of the deepest, if any vertex went in further than the slack.
    pub max_frame: Option<usize>,
    /// Frames with a vertex more than [`INSIDE_SLACK_M`] inside a prop.
    pub frames_inside: usize,
}

/// Distance from `p` to the nearest of `props`' triangles, metres.
fn distance_to_surface(props: &Mesh, p: Vec3) -> f32 {
    props
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| props.positions[i as usize]);
            let w = closest_barycentric(p, a, b, c);
            p.distance(a * w.x + b * w.y + c * w.z)
        })
        .fold(f32::INFINITY, f32::min)
}

/// How deep `mesh`, skinned to `clip`'s skeleton, goes into `props` (world metres, closed
/// surfaces) over the frames of `window`.
///
/// Errors: the mesh is not skinned to the clip's skeleton; the props index past their
/// vertices or have a non-finite one.
pub fn props_penetration(
    clip: &Clip,
    mesh: &Mesh,
    props: &Mesh,
    window: FrameRange,
) -> Result<PropsPenetration, SkinError> {
    let skin = mesh.skin.as_ref().ok_or(SkinError::NotSkinned)?;
    check_skin(skin, clip.skeleton(), mesh.positions.len())?;
    let n = props.positions.len();
    if props.triangles.iter().flatten().any(|&i| i as usize >= n) {
        return Err(SkinError::Inconsistent(format!("the props' triangles index past their {n} vertices")));
    }
    if props.positions.iter().any(|p| !p.is_finite()) {
        return Err(SkinError::Inconsistent("the props have a non-finite vertex".into()));
    }
    let corners: Vec<DVec3> = props.positions.iter().map(|p| p.as_dvec3()).collect();
    let lo = props.positions.iter().copied().fold(Vec3::INFINITY, Vec3::min);
    let hi = props.positions.iter().copied().fold(Vec3::NEG_INFINITY, Vec3::max);
    let mut out = PropsPenetration { max_cm: 0.0, max_frame: None, frames_inside: 0 };
    let mut world = vec![Transform::IDENTITY; clip.joint_count()];
    for f in window.start..window.end.min(clip.frame_count()) {
        pose_world(clip.skeleton(), clip.frame_rotations(f), clip.frame_translations(f), &mut world);
        let matrices = skinning_matrices(&world, &skin.inverse_bind_matrices);
        let mut deepest_m = 0.0f64;
        for (v, rest) in mesh.positions.iter().enumerate() {
            let p = blend_matrices(&matrices, &skin.joints[v], &skin.weights[v]).transform_point3(*rest);
            if p.cmplt(lo).any() || p.cmpgt(hi).any() {
                continue;
            }
            // Either orientation: a prop whose triangles wind clockwise is just as solid.
            if winding_number(&corners, &props.triangles, p.as_dvec3()).abs() < 0.5 {
                continue;
            }
            deepest_m = deepest_m.max(f64::from(distance_to_surface(props, p)));
        }
        if deepest_m <= INSIDE_SLACK_M {
            continue;
        }
        out.frames_inside += 1;
        if 100.0 * deepest_m > out.max_cm {
            out.max_cm = 100.0 * deepest_m;
            out.max_frame = Some(f);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{Mat4, Quat};

    use super::*;
    use crate::model::{ImportScale, Joint, Skeleton, Skin};

    /// A one-joint skeleton whose root moves down by 0.1 m a frame, carrying one vertex
    /// from 0.25 m above a unit cube's top to 0.15 m into it; and a cube (top at 1 m) as
    /// the prop.
    fn sinking() -> (Clip, Mesh, Mesh) {
        let skeleton = Arc::new(Skeleton::new(vec![Joint::new("root", None, Vec3::ZERO)]).unwrap());
        let heights = [1.25f32, 1.15, 1.05, 0.95, 0.85];
        let translations: Vec<Vec3> = heights.iter().map(|&y| Vec3::new(0.5, y, 0.5)).collect();
        let clip =
            Clip::new(skeleton.clone(), 30.0, vec![Quat::IDENTITY; 5], translations, ImportScale::METRES).unwrap();
        let skin = Skin {
            skeleton,
            joints: vec![[0, 0, 0, 0]],
            weights: vec![[1.0, 0.0, 0.0, 0.0]],
            inverse_bind_matrices: vec![Mat4::IDENTITY],
        };
        let mesh = Mesh { positions: vec![Vec3::ZERO], normals: vec![Vec3::Y], skin: Some(skin), ..Mesh::default() };
        let mut cube = Mesh::default();
        cube.push_box(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32));
        (clip, mesh, cube)
    }

    /// The vertex's depth below the cube's top, worked out by hand: 0 for the frames above
    /// it, then 0.05 m and 0.15 m; the deepest in the last frame; two frames inside.
    #[test]
    fn a_vertex_sinking_into_a_box_is_measured_from_its_surface() {
        let (clip, mesh, cube) = sinking();
        let got = props_penetration(&clip, &mesh, &cube, FrameRange { start: 0, end: 5 }).unwrap();
        assert!((got.max_cm - 15.0).abs() < 1e-3, "{got:?}");
        assert_eq!((got.max_frame, got.frames_inside), (Some(4), 2));
        let above = props_penetration(&clip, &mesh, &cube, FrameRange { start: 0, end: 3 }).unwrap();
        assert_eq!(above, PropsPenetration { max_cm: 0.0, max_frame: None, frames_inside: 0 });
    }

    /// The same cube with every triangle turned clockwise measures the same.
    #[test]
    fn an_inside_out_box_is_as_solid() {
        let (clip, mesh, mut cube) = sinking();
        cube.triangles.iter_mut().for_each(|t| t.swap(1, 2));
        let got = props_penetration(&clip, &mesh, &cube, FrameRange { start: 0, end: 5 }).unwrap();
        assert!((got.max_cm - 15.0).abs() < 1e-3, "{got:?}");
    }

    #[test]
    fn an_unskinned_mesh_is_refused() {
        let (clip, mut mesh, cube) = sinking();
        mesh.skin = None;
        assert!(matches!(
            props_penetration(&clip, &mesh, &cube, FrameRange { start: 0, end: 5 }),
            Err(SkinError::NotSkinned)
        ));
    }
}
