//! Body shapes sized from the character's skinned mesh.
//!
//! A figure's capsules sized from the skeleton alone are guesses (a share of the bone's
//! length): on the Mixamo Xbot the pelvis capsule had a 5 cm radius where the mesh reaches
//! 15 cm from the bone, so the seated body sank 5 cm into the stool. With the mesh, each
//! body's radius is measured: the mesh is posed by linear blend skinning in the skeleton's
//! rest pose (the pose the figure is built in, which need not be the bind pose), every
//! vertex goes to the body that carries its most weighted joint, and the radius is the
//! median of those vertices' distances to the body's bone ([`RADIUS_QUANTILE`]): as much
//! skin outside the capsule as inside. Not the largest distance: limbs are not round (a
//! thigh's vertices near the buttock lie far off the bone), and a capsule as fat as the
//! farthest vertex would hold the body off the ground and the seat.
//!
//! The pelvis is the exception ([`SkinnedRest::seat_pad`]): what a seated body rests on is the buttocks,
//! below and behind the hip joints, not a ball about the pelvis's bone. A capsule round that
//! bone, as fat as the hips are wide, rolled forward on the seat like a wheel as the trunk
//! leant to rise (a 17 cm radius carries the hips 20 cm forward for a 1.2 rad lean) and the
//! figure fell off the stool. So with a mesh the pelvis's shape is a pad across the hips,
//! from the hip joints' height down to the lowest skin of the mesh posed seated.
//!
//! A foot's box is the shoe ([`sole_box`]): its bottom at the lowest skin, so the shoes rest
//! on the floor rather than on a box guessed from the ankle and toe joints.

use std::f32::consts::FRAC_PI_2;

use glam::{Quat, Vec3};

use crate::kernels::skinning::{SkinError, blend_matrices, check_skin, segment_distance, skinning_matrices};
use crate::model::fk::{Transform, pose_world, rest_world};
use crate::model::{Mesh, Skeleton, Skin};

/// Share of a body's vertices its capsule holds (the quantile of their distances to the
/// bone): the median.
pub const RADIUS_QUANTILE: f32 = 0.5;

/// The share for a hand: its fingers and thumb splay off the bone, and with the median the
/// thumbs stayed outside the capsule and went into the stool beside the seated hips.
pub const HAND_QUANTILE: f32 = 0.75;

/// A seat pad needs the buttocks at least this far below the hip joints, metres.
pub const MIN_PAD_DEPTH_M: f32 = 0.02;

/// A body carrying fewer vertices than this keeps its shape sized from the skeleton (a
/// few vertices say little about a body's girth or a shoe's sole).
pub const MIN_VERTICES: usize = 20;

/// A mesh checked once against the skeleton it is skinned to, with that skeleton's rest
/// pose: what the figure's shapes are measured from.
pub struct SkinnedRest<'a> {
    skeleton: &'a Skeleton,
    mesh: &'a Mesh,
    skin: &'a Skin,
    rest: Vec<Transform>,
}

impl<'a> SkinnedRest<'a> {
    /// `mesh` on `skeleton`; refused when it is not skinned to it ([`check_skin`]).
    pub fn new(skeleton: &'a Skeleton, mesh: &'a Mesh) -> Result<Self, SkinError> {
        let skin = mesh.skin.as_ref().ok_or(SkinError::NotSkinned)?;
        check_skin(skin, skeleton, mesh.positions.len())?;
        Ok(SkinnedRest { skeleton, mesh, skin, rest: rest_world(skeleton) })
    }

    /// The vertices whose heaviest joint passes `keep`, posed by linear blend skinning with
    /// the joints' world transforms `world` (non-finite results dropped), with that joint.
    fn posed<'w>(
        &'w self,
        world: &[Transform],
        keep: impl Fn(usize) -> bool + 'w,
    ) -> impl Iterator<Item = (usize, Vec3)> + 'w {
        let matrices = skinning_matrices(world, &self.skin.inverse_bind_matrices);
        let skin = self.skin;
        self.mesh.positions.iter().enumerate().filter_map(move |(v, position)| {
            let (joint, _) = skin.heaviest_joint(v);
            let p = blend_matrices(&matrices, &skin.joints[v], &skin.weights[v]).transform_point3(*position);
            (keep(joint) && p.is_finite()).then_some((joint, p))
        })
    }

    /// The vertices posed in the rest pose (world metres), grouped by body: `owner[j]` is
    /// the body that carries joint `j`, `bodies` their number.
    pub fn vertices_by_body(&self, owner: &[usize], bodies: usize) -> Vec<Vec<Vec3>> {
        let mut by_body = vec![Vec::new(); bodies];
        for (joint, p) in self.posed(&self.rest, |_| true) {
            if let Some(list) = owner.get(joint).and_then(|&body| by_body.get_mut(body)) {
                list.push(p);
            }
        }
        by_body
    }

    /// The pelvis's seat pad: the mesh posed seated (the rest pose with both thighs turned
    /// forward by 90° about the figure's `left`), the vertices carried by the pelvis or a
    /// thigh (`seated_body(joint)`), and their lowest point below the hip joints `hips`: a
    /// capsule from under one hip to under the other, its top at the hips' height and its
    /// bottom at that lowest skin, as far back as the lowest tenth of those vertices lie on
    /// average. Seated, not at rest: at rest the thighs' skin hangs to the knees, so only
    /// the seated pose says which of it meets a seat (on the Xbot the lowest seated skin is
    /// 11.5 cm below the hips, within 0.4 mm of the pelvis's lowest skin at rest). Returns the
    /// two ends (world, rest pose) and the radius; `None` when `hips` are not joints, with
    /// fewer than [`MIN_VERTICES`] vertices, or with skin less than [`MIN_PAD_DEPTH_M`]
    /// below the hips. The lowest vertex sets the depth (it is what shows through a seat),
    /// so a caller bounds the radius against garments or tails hanging from the pelvis.
    pub fn seat_pad(
        &self,
        hips: [usize; 2],
        seated_body: impl Fn(usize) -> bool,
        left: Vec3,
    ) -> Option<([Vec3; 2], f32)> {
        let joints = self.skeleton.joints();
        if hips.iter().any(|&hip| hip >= joints.len()) {
            return None;
        }
        let rest = &self.rest;
        let mut rotations: Vec<Quat> = joints.iter().map(|j| j.rest_rotation).collect();
        let translations: Vec<Vec3> = joints.iter().map(|j| j.rest_offset).collect();
        let flex = Quat::from_axis_angle(left, -FRAC_PI_2);
        for &hip in &hips {
            let parent = joints[hip].parent.map_or(Quat::IDENTITY, |p| rest[p].rotation);
            rotations[hip] = parent.inverse() * flex * rest[hip].rotation;
        }
        let mut world = vec![Transform::IDENTITY; joints.len()];
        pose_world(self.skeleton, &rotations, &translations, &mut world);
        let seated: Vec<Vec3> = self.posed(&world, seated_body).map(|(_, p)| p).collect();
        if seated.len() < MIN_VERTICES {
            return None;
        }
        let (hip_l, hip_r) = (rest[hips[0]].translation, rest[hips[1]].translation);
        let mid = (hip_l + hip_r) * 0.5;
        let mut heights: Vec<f32> = seated.iter().map(|p| p.y).collect();
        let depth = mid.y - quantile_of(&mut heights, 0.0);
        if depth.is_nan() || depth < MIN_PAD_DEPTH_M {
            return None;
        }
        let forward = left.cross(Vec3::Y);
        let low = quantile_of(&mut heights, 0.1);
        let lowest: Vec<f32> = seated.iter().filter(|p| p.y <= low).map(|p| (*p - mid).dot(forward)).collect();
        let back = lowest.iter().sum::<f32>() / lowest.len().max(1) as f32;
        let radius = 0.5 * depth;
        let end = |hip: Vec3| hip.with_y(mid.y) - Vec3::Y * radius + forward * back;
        Some(([end(hip_l), end(hip_r)], radius))
    }
}

/// The radius of a capsule on the bone `a`–`b` that holds the share `quantile` of `points`
/// ([`RADIUS_QUANTILE`], [`HAND_QUANTILE`]); `None` for fewer than [`MIN_VERTICES`] points.
pub fn capsule_radius(points: &[Vec3], a: Vec3, b: Vec3, quantile: f32) -> Option<f32> {
    if points.len() < MIN_VERTICES {
        return None;
    }
    let mut distances: Vec<f32> = points.iter().map(|&p| segment_distance(p, a, b)).collect();
    Some(quantile_of(&mut distances, quantile))
}

/// The value below which the share `quantile` of `values` lies (nearest rank; `values` is
/// reordered). `values` must not be empty.
fn quantile_of(values: &mut [f32], quantile: f32) -> f32 {
    let k = ((values.len() - 1) as f32 * quantile.clamp(0.0, 1.0)).round() as usize;
    *values.select_nth_unstable_by(k, f32::total_cmp).1
}

/// Share of a foot's skin left outside its box at the heel, at the toe and at either side:
/// a stray vertex (a lace, a buckle) does not stretch the sole. (Nearest rank: with fewer
/// than 51 vertices nothing is trimmed.)
pub const SOLE_TRIM: f32 = 0.01;

/// A foot's box measured from its skin in the rest pose (world metres, Y up).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoleBox {
    /// The box's centre.
    pub centre: Vec3,
    /// Half its length along the foot, its height and its width.
    pub half_extents: Vec3,
}

/// The box of a foot from the skin it carries (`points`, rest pose): its bottom at the
/// lowest vertex, which is what meets the floor (a box from the skeleton's ankle and toe
/// joints left the Mixamo Xbot's shoes 1.5 cm above the floor); its top at the `ankle`
/// joint; heel to toe along `dir` (a horizontal unit vector, the foot's direction) and
/// side to side between the [`SOLE_TRIM`] and `1 − SOLE_TRIM` quantiles of the skin. `None`
/// with fewer than [`MIN_VERTICES`] points or no skin at least 1 cm below the ankle.
pub fn sole_box(points: &[Vec3], ankle: Vec3, dir: Vec3) -> Option<SoleBox> {
    if points.len() < MIN_VERTICES {
        return None;
    }
    let side = Vec3::Y.cross(dir);
    let bottom = points.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let height = ankle.y - bottom;
    if height.is_nan() || height < 0.01 {
        return None;
    }
    let range = |axis: Vec3| {
        let mut offsets: Vec<f32> = points.iter().map(|&p| (p - ankle).dot(axis)).collect();
        (quantile_of(&mut offsets, SOLE_TRIM), quantile_of(&mut offsets, 1.0 - SOLE_TRIM))
    };
    let ((heel, toe), (right, left)) = (range(dir), range(side));
    let centre = (ankle + dir * 0.5 * (heel + toe) + side * 0.5 * (right + left)).with_y(bottom + 0.5 * height);
    let half_extents = Vec3::new(0.5 * (toe - heel), 0.5 * height, 0.5 * (left - right));
    Some(SoleBox { centre, half_extents })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use std::f32::consts::TAU;
    use std::sync::Arc;

    use glam::{Mat4, Quat};

    use super::*;
    use crate::model::Joint;

    /// `n` points on a ring of radius `r` about the Y axis at height `y`.
    fn ring(n: usize, r: f32, y: f32) -> Vec<Vec3> {
        (0..n)
            .map(|i| Vec3::new(r * (TAU * i as f32 / n as f32).cos(), y, r * (TAU * i as f32 / n as f32).sin()))
            .collect()
    }

    #[test]
    fn a_round_limb_gives_its_radius() {
        let points: Vec<Vec3> = (0..5).flat_map(|k| ring(12, 0.06, 0.1 * k as f32)).collect();
        for quantile in [RADIUS_QUANTILE, HAND_QUANTILE, 1.0] {
            let r = capsule_radius(&points, Vec3::ZERO, Vec3::Y * 0.4, quantile).unwrap();
            assert!((r - 0.06).abs() < 1e-6, "{quantile}: {r}");
        }
    }

    #[test]
    fn the_quantile_sets_how_much_of_the_skin_the_capsule_holds() {
        // 30 points 5 cm off the bone and 10 at 20 cm (a splayed thumb): the median and the
        // 75 % quantile (the 30th of 40) are 5 cm, the 90 % one (the 36th) is 20 cm.
        let mut points = ring(30, 0.05, 0.2);
        points.extend(ring(10, 0.2, 0.2));
        let radius = |q: f32| capsule_radius(&points, Vec3::ZERO, Vec3::Y * 0.4, q).unwrap();
        assert!((radius(RADIUS_QUANTILE) - 0.05).abs() < 1e-6);
        assert!((radius(HAND_QUANTILE) - 0.05).abs() < 1e-6);
        assert!((radius(0.9) - 0.2).abs() < 1e-6);
        // Below the bone's end, the distance is to the end point (the capsule's cap).
        let cap: Vec<Vec3> = (0..MIN_VERTICES).map(|_| Vec3::new(0.0, -0.07, 0.0)).collect();
        assert!((capsule_radius(&cap, Vec3::ZERO, Vec3::Y * 0.4, 0.5).unwrap() - 0.07).abs() < 1e-6);
        assert_eq!(capsule_radius(&cap[..MIN_VERTICES - 1], Vec3::ZERO, Vec3::Y, 0.5), None);
    }

    /// A two-joint skeleton whose rest pose bends the child 90° from the bind pose the mesh
    /// was modelled in: the vertices must be grouped where the rest pose puts them.
    #[test]
    fn vertices_are_posed_at_rest_and_grouped_by_their_heaviest_joint() {
        let bend = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let child = Joint { rest_rotation: bend, ..Joint::new("child", Some(0), Vec3::Y) };
        let skeleton = Arc::new(Skeleton::new(vec![Joint::new("root", None, Vec3::ZERO), child]).unwrap());
        // Bind pose: both joints unrotated, the child 1 m up; one vertex 0.5 m above the
        // child, one beside the root.
        let inverse_bind_matrices = vec![Mat4::IDENTITY, Mat4::from_translation(-Vec3::Y)];
        let mesh = Mesh {
            positions: vec![Vec3::new(0.0, 1.5, 0.0), Vec3::new(0.1, 0.0, 0.0)],
            normals: vec![Vec3::Y; 2],
            skin: Some(Skin {
                skeleton: skeleton.clone(),
                joints: vec![[1, 0, 0, 0], [0, 1, 0, 0]],
                weights: vec![[0.8, 0.2, 0.0, 0.0], [0.9, 0.1, 0.0, 0.0]],
                inverse_bind_matrices,
            }),
            ..Mesh::default()
        };
        let by_body = SkinnedRest::new(&skeleton, &mesh).unwrap().vertices_by_body(&[0, 1], 2);
        // The first vertex: 0.8 of the child's bend (0.5 m along its +Y, turned 90° about Z
        // to −X: (−0.5, 1, 0)) and 0.2 of the root's (its bind position): by hand.
        let want = Vec3::new(-0.5, 1.0, 0.0) * 0.8 + Vec3::new(0.0, 1.5, 0.0) * 0.2;
        assert_eq!(by_body[1].len(), 1);
        assert!(by_body[1][0].distance(want) < 1e-6, "{:?}", by_body[1][0]);
        // The second: 0.9 of the root (unmoved) and 0.1 of the child, whose rest transform
        // (up 1 m, turned 90° about Z) takes the vertex's (0.1, −1, 0) in the child's bind
        // frame to (1, 1.1, 0).
        let want = Vec3::new(0.1, 0.0, 0.0) * 0.9 + Vec3::new(1.0, 1.1, 0.0) * 0.1;
        assert!(by_body[0][0].distance(want) < 1e-6, "{:?}", by_body[0][0]);
        let unskinned = Mesh { skin: None, ..mesh };
        assert_eq!(SkinnedRest::new(&skeleton, &unskinned).err(), Some(SkinError::NotSkinned));
    }

    /// A pelvis 1 m up with hips 10 cm to either side and 10 cm down; ten vertices on the
    /// pelvis 18 cm below it and 5 cm back (the buttocks), ten on the left thigh 20 cm below
    /// its hip and 10–14 cm in front of the bone. Standing, the thigh's are the lowest
    /// (0.70 m); seated, the thigh turns forward and carries them up to 1.00–1.04 m, 20 cm
    /// ahead (turned backward, they would drop to 0.76–0.80 m, below the buttocks), so the
    /// lowest skin is the buttocks' 0.82 m, 8 cm under the hips: a pad of radius 4 cm, its
    /// ends 4 cm under each hip and 5 cm back. By hand.
    #[test]
    fn the_seat_pad_reaches_the_lowest_skin_of_the_seated_pose() {
        let skeleton = Arc::new(
            Skeleton::new(vec![
                Joint::new("pelvis", None, Vec3::Y),
                Joint::new("hip_l", Some(0), Vec3::new(0.1, -0.1, 0.0)),
                Joint::new("hip_r", Some(0), Vec3::new(-0.1, -0.1, 0.0)),
            ])
            .unwrap(),
        );
        let inverse_bind_matrices = rest_world(&skeleton).iter().map(|t| t.to_mat4().inverse()).collect();
        let buttocks = (0..10).map(|i| Vec3::new(-0.05 + 0.01 * i as f32, 0.82, -0.05));
        let thigh = (0..10).map(|i| Vec3::new(0.1, 0.7, 0.1 + 0.004 * i as f32));
        let positions: Vec<Vec3> = buttocks.chain(thigh).collect();
        let joints: Vec<[u16; 4]> = (0..20).map(|v| [if v < 10 { 0 } else { 1 }, 0, 0, 0]).collect();
        let mesh = Mesh {
            normals: vec![Vec3::Y; positions.len()],
            positions,
            skin: Some(Skin {
                skeleton: skeleton.clone(),
                joints,
                weights: vec![[1.0, 0.0, 0.0, 0.0]; 20],
                inverse_bind_matrices,
            }),
            ..Mesh::default()
        };
        let skinned = SkinnedRest::new(&skeleton, &mesh).unwrap();
        let ([a, b], radius) = skinned.seat_pad([1, 2], |_| true, Vec3::X).unwrap();
        assert!((radius - 0.04).abs() < 1e-5, "{radius}");
        assert!(a.distance(Vec3::new(0.1, 0.86, -0.05)) < 1e-5, "{a:?}");
        assert!(b.distance(Vec3::new(-0.1, 0.86, -0.05)) < 1e-5, "{b:?}");
        // Fewer than MIN_VERTICES counted (the pelvis's ten alone, or none), or hips that are
        // not joints: no pad.
        assert_eq!(skinned.seat_pad([1, 2], |j| j == 0, Vec3::X), None);
        assert!(skinned.seat_pad([1, 2], |_| false, Vec3::X).is_none());
        assert!(skinned.seat_pad([1, 3], |_| true, Vec3::X).is_none());
    }

    /// A shoe-shaped skin by hand: the corners of a box 0.25 m long (5 cm behind the ankle
    /// to 20 cm in front), 9 cm wide (centred 1 cm to the foot's left of the ankle), from
    /// the floor up to 8 cm, each corner 20 times; one stray vertex (a lace) 50 cm ahead and
    /// one (a buckle) 30 cm to the side. The foot points diagonally, (1, 0, 1)/√2, from an
    /// ankle 9 cm up at (0.3, −0.2) in the plane. The box is the shoe's: its bottom at the
    /// floor, its top at the ankle, the strays trimmed.
    #[test]
    fn the_sole_box_holds_the_shoe_from_the_lowest_skin_up_to_the_ankle() {
        let (ankle, dir) = (
            Vec3::new(0.3, 0.09, -0.2),
            Vec3::new(std::f32::consts::FRAC_1_SQRT_2, 0.0, std::f32::consts::FRAC_1_SQRT_2),
        );
        let side = Vec3::new(dir.z, 0.0, -dir.x); // Y × dir: the foot's left.
        let at = |along: f32, aside: f32, y: f32| ankle.with_y(y) + dir * along + side * aside;
        let mut points = Vec::new();
        for along in [-0.05, 0.20] {
            for aside in [-0.035, 0.055] {
                for y in [0.0, 0.08] {
                    points.extend(std::iter::repeat_n(at(along, aside, y), 20));
                }
            }
        }
        points.extend([at(0.5, 0.0, 0.05), at(0.1, 0.3, 0.05)]);
        let sole = sole_box(&points, ankle, dir).unwrap();
        // Centre: 7.5 cm along and 1 cm aside of the ankle, i.e. 0.085/√2 = 0.0601041 on x and
        // (0.075 − 0.01)/√2 = 0.0459619 on z; halfway up to the ankle.
        let want_centre = Vec3::new(0.3601041, 0.045, -0.1540381);
        assert!(sole.centre.abs_diff_eq(want_centre, 1e-6), "{sole:?}");
        assert!(sole.half_extents.abs_diff_eq(Vec3::new(0.125, 0.045, 0.045), 1e-6), "{sole:?}");
        // Too few vertices, or no skin a centimetre below the ankle: no measured box.
        assert_eq!(sole_box(&points[..MIN_VERTICES - 1], ankle, dir), None);
        assert_eq!(sole_box(&points, ankle.with_y(0.005), dir), None);
    }
}
