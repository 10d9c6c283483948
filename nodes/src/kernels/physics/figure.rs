//! Skeleton → articulated rigid-body figure (the paper's 3-D character).
//!
//! Steps:
//! 1. Landmarks by joint name ([`find_landmarks`]): per side thigh, shank, foot, upper arm,
//!    forearm, hand; neck and head. The pelvis is the root; the chest is the deepest joint
//!    shared by the neck's and the shoulders' chains; the abdomen is the spine joint nearest
//!    the middle of pelvis → chest, when there is one. That gives up to 16 bodies, the
//!    segments of de Leva's table.
//! 2. Every skeleton joint belongs to the body of its nearest driving ancestor (a clavicle
//!    rides on the chest, fingers on the hand) and keeps its rest-relative rotation.
//! 3. Shapes from the rest pose: a capsule along each bone (radius a fixed share of the
//!    bone's length by role, trunk radii from the hip and shoulder widths; with the
//!    character's skinned mesh, measured from the vertices each body carries, see
//!    [`super::skin_fit`]), a box per foot from the ankle to the toe tip with its sole at
//!    the lowest point of the foot (with the mesh, the shoe's box: [`sole_box`]).
//! 4. Masses from [`body_model`] (de Leva 1996, the table the momentum nodes use): each
//!    limb segment and the head to the body of that name, the upper, middle and lower trunk
//!    to the chest, abdomen and pelvis (other models: to the body whose bone passes nearest
//!    the segment's centre of mass); the body's centre of mass is the mass-weighted mean of
//!    its segments'. Inertia: the solid shape's inertia tensor scaled to that mass, about
//!    that centre.
//! 5. Joints: the pelvis is the articulation's free root; knees and elbows are hinges, all
//!    other joints ball joints, with human ranges per body role about anatomical axes
//!    (X = the figure's left, Y = up, Z = forward in the rest pose).
//! 6. PD gains scaled by the supported mass: kp = [`FigureParams::stiffness_ratio`] ·
//!    m_s · g · d (m_s the mass the joint holds up when standing, d the distance from the
//!    joint to that mass's centre), kd critically damped for an inertia m_s · d².
//!
//! Body frames are world-aligned in the rest pose, so a body's world rotation is its rotation
//! relative to the rest pose.

use glam::{Mat3, Quat, Vec3};
use rapier3d::prelude::*;

use super::skin_fit::{HAND_QUANTILE, RADIUS_QUANTILE, SkinnedRest, SoleBox, capsule_radius, sole_box};
use super::{World, pose_to_rapier, rot_from_rapier, rot_to_rapier, to_rapier};
use crate::kernels::body::{BodyError, MassTable, body_model, find_landmarks, limb_tip};
use crate::kernels::skinning::{SkinError, segment_distance};
use crate::math::quat_normalize_or_identity;
use crate::model::choice::Choice;
use crate::model::fk::{Transform, pose_world, rest_world};
use crate::model::{Mesh, Skeleton};

/// The shortest bone that can carry a body, metres.
pub const MIN_BONE_M: f32 = 0.01;

/// What a body is, anatomically.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BodyRole {
    /// Pelvis (the articulation's root).
    Pelvis,
    /// Abdomen (middle trunk).
    Abdomen,
    /// Chest (upper trunk).
    Chest,
    /// Neck and head.
    Head,
    /// Thigh.
    Thigh,
    /// Shank (lower leg).
    Shank,
    /// Foot.
    Foot,
    /// Upper arm.
    UpperArm,
    /// Forearm.
    Forearm,
    /// Hand.
    Hand,
}

/// How a body hangs from its parent.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum JointKind {
    /// Free (the root).
    Free,
    /// Ball joint, three rotations about the joint frame's X, Y, Z, each limited to
    /// `[min, max]` radians.
    Ball {
        /// Limits about X, Y, Z, radians.
        limits_rad: [[f32; 2]; 3],
    },
    /// Hinge about the joint frame's X axis, limited to `[min, max]` radians.
    Hinge {
        /// Limits, radians.
        limits_rad: [f32; 2],
    },
}

/// The collision shape of a body, in its rest (world-aligned) frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum BodyShape {
    /// A capsule between two points, with a radius, metres.
    Capsule {
        /// First end, body frame, metres.
        a: Vec3,
        /// Second end, body frame, metres.
        b: Vec3,
        /// Radius, metres.
        radius_m: f32,
    },
    /// A box, metres.
    Box {
        /// Centre, body frame, metres.
        centre: Vec3,
        /// Half extents along the box's own axes, metres.
        half_extents: Vec3,
        /// Rotation of the box's axes in the body frame.
        rotation: Quat,
    },
}

/// One rigid body of a figure.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FigureBody {
    /// Stable name (`"pelvis"`, `"left_thigh"`), used by scripts to aim pushes.
    pub name: String,
    /// Anatomical role.
    pub role: BodyRole,
    /// Side: 0 left, 1 right, `None` for the trunk and head.
    pub side: Option<usize>,
    /// The skeleton joint that drives the body (its origin).
    pub joint: usize,
    /// Parent body, `None` for the pelvis.
    pub parent: Option<usize>,
    /// Mass, kilograms.
    pub mass_kg: f32,
    /// Centre of mass in the body frame, metres.
    pub com_local: Vec3,
    /// Collision shape.
    pub shape: BodyShape,
    /// How the body hangs from its parent.
    pub kind: JointKind,
    /// Joint frame in world at rest (X = hinge axis or the figure's left).
    pub joint_frame: Quat,
    /// The joint's position relative to the parent body's origin at rest, metres.
    pub anchor_in_parent: Vec3,
    /// PD stiffness, N·m/rad.
    pub kp: f32,
    /// PD damping, N·m·s/rad.
    pub kd: f32,
    /// Mass the joint holds up when standing, kilograms.
    pub supported_mass_kg: f32,
}

/// A figure: bodies, joints, gains, and how skeleton joints ride on bodies.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Figure {
    /// Bodies, parents before children; index 0 is the pelvis.
    pub bodies: Vec<FigureBody>,
    /// For each skeleton joint, the body it rides on.
    pub owner: Vec<usize>,
    /// Total mass, kilograms.
    pub total_mass_kg: f32,
    /// Standing height in the rest pose (lowest to highest point), metres.
    pub stature_m: f32,
    /// The figure's forward direction at rest (horizontal, unit).
    pub forward: Vec3,
    /// The figure's left at rest (horizontal, unit).
    pub left: Vec3,
    /// How the masses were obtained (body model method).
    pub mass_method: String,
    /// Coulomb friction of the figure's shapes against the ground.
    pub friction: f32,
    /// Height of the soles in the rest pose, metres: spawn the figure `−rest_sole_y_m` up to
    /// stand it on a ground at 0.
    pub rest_sole_y_m: f32,
    /// With a seat pad (a figure sized from its mesh, [`super::skin_fit::SkinnedRest::seat_pad`]): how far
    /// below the hip joints the seated skin reaches, metres.
    pub seat_depth_m: Option<f32>,
}

/// Figure set-up values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FigureParams {
    /// Body mass, kilograms (default 75).
    pub total_mass_kg: f64,
    /// Anthropometric table (default de Leva male).
    pub table: MassTable,
    /// Coulomb friction against the ground (default 0.9).
    pub friction: f32,
    /// PD stiffness as a multiple of the gravity torque m_s·g·d per radian (default 40: a
    /// joint sags 1/40 rad under the weight it holds; at 6 a CMU figure holding its rest pose
    /// sank and fell within 4 s, at 20 it sank 10 cm in 5 s).
    pub stiffness_ratio: f32,
    /// Gravity used to scale the gains, m/s².
    pub gravity_m_s2: f32,
}

impl Default for FigureParams {
    fn default() -> Self {
        FigureParams {
            total_mass_kg: 75.0,
            table: MassTable::DeLevaMale,
            friction: 0.9,
            stiffness_ratio: 40.0,
            gravity_m_s2: super::STANDARD_GRAVITY_M_S2,
        }
    }
}

/// Why a skeleton cannot become a figure.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FigureError {
    /// Fewer than two joints: nothing to articulate.
    #[error("the skeleton has {joints} joint(s); a figure needs a jointed body")]
    TooFewJoints {
        /// Joint count.
        joints: usize,
    },
    /// The joint names do not name a humanoid's limbs.
    #[error("the skeleton is not a recognisable humanoid (missing: {})", missing.join(", "))]
    NotHumanoid {
        /// What was not found.
        missing: Vec<String>,
    },
    /// A bone that should carry a body has no length.
    #[error("bone '{from}' → '{to}' is {length_m:.4} m long; a body needs at least {MIN_BONE_M} m")]
    ZeroLengthBone {
        /// Start joint.
        from: String,
        /// End joint.
        to: String,
        /// Its length, metres.
        length_m: f32,
    },
    /// The mass model failed.
    #[error(transparent)]
    Mass(#[from] BodyError),
    /// The mesh the shapes were to be sized from cannot be posed on the skeleton.
    #[error("the mesh cannot size the bodies: {0}")]
    Skin(#[from] SkinError),
    /// A set-up value is out of range.
    #[error("{0}")]
    BadParams(String),
}

/// Human joint ranges by role, radians, about (X = left, Y = up, Z = forward) for the left
/// side; the right side mirrors Y and Z. Hinges: flexion range.
fn ball_limits(role: BodyRole, side: Option<usize>) -> [[f32; 2]; 3] {
    let l = match role {
        // Hip: flexion is a negative X rotation of a downward thigh (115° flexion, 20°
        // extension), abduction 45° / adduction 25°, rotation ±40°.
        BodyRole::Thigh => [[-2.0, 0.35], [-0.7, 0.7], [-0.45, 0.8]],
        // Ankle: 20° dorsiflexion, 45° plantarflexion, ±20° rotation, ±30° inversion and
        // eversion (ankle and subtalar joints together; a rig whose rest pose splays the
        // legs by 20° needs that much to stand with its feet flat).
        BodyRole::Foot => [[-0.35, 0.8], [-0.35, 0.35], [-0.52, 0.52]],
        // Spine segments: 45° forward bend, 25° back, ±30° twist, ±25° side bend.
        BodyRole::Abdomen | BodyRole::Chest => [[-0.45, 0.8], [-0.5, 0.5], [-0.45, 0.45]],
        // Neck: 50° flexion, 60° extension, ±70° rotation, ±40° side bend.
        BodyRole::Head => [[-1.0, 0.9], [-1.2, 1.2], [-0.7, 0.7]],
        // Shoulder from a T-pose: ±90° twist about the arm, swing back 90° and forward 130°
        // (across the body), arm down 100°, up 85°.
        BodyRole::UpperArm => [[-1.6, 1.6], [-2.3, 1.6], [-1.75, 1.5]],
        // Wrist: ±70° flexion, ±30° deviation, forearm twist ±80° lives here too.
        BodyRole::Hand => [[-1.2, 1.2], [-1.4, 1.4], [-0.5, 0.5]],
        _ => [[-0.1, 0.1]; 3],
    };
    if side == Some(1) { [l[0], [-l[1][1], -l[1][0]], [-l[2][1], -l[2][0]]] } else { l }
}

/// Builds the figure of `skeleton` from its rest pose; with `mesh` (skinned to `skeleton`),
/// the capsules' radii, the seat pad and the feet's boxes are measured from it.
pub fn build_figure(skeleton: &Skeleton, params: &FigureParams, mesh: Option<&Mesh>) -> Result<Figure, FigureError> {
    if skeleton.len() < 2 {
        return Err(FigureError::TooFewJoints { joints: skeleton.len() });
    }
    if !(params.total_mass_kg.is_finite() && params.total_mass_kg > 1.0 && params.total_mass_kg < 1000.0) {
        return Err(FigureError::BadParams(format!("body mass {} kg must be within 1..1000", params.total_mass_kg)));
    }
    if !(params.friction.is_finite() && (0.0..=5.0).contains(&params.friction)) {
        return Err(FigureError::BadParams(format!("friction {} must be within 0..=5", params.friction)));
    }
    if !(params.stiffness_ratio.is_finite() && params.stiffness_ratio > 0.0 && params.stiffness_ratio <= 100.0) {
        return Err(FigureError::BadParams(format!(
            "stiffness ratio {} must be within 0..=100",
            params.stiffness_ratio
        )));
    }
    let lm = find_landmarks(skeleton).map_err(|missing| FigureError::NotHumanoid { missing })?;
    let joints = skeleton.joints();
    let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
    let root = 0usize;
    let ancestors = |j: usize| {
        let mut chain = vec![j];
        while let Some(p) = joints[*chain.last().unwrap_or(&root)].parent {
            chain.push(p);
        }
        chain
    };
    // Chest: deepest joint on the neck's chain that is also on a shoulder's chain.
    let neck_chain = ancestors(lm.neck);
    let shoulder_chain = ancestors(lm.limbs[0][3]);
    let chest = neck_chain.iter().copied().find(|j| shoulder_chain.contains(j) && *j != lm.neck).unwrap_or(root);
    let chest = if chest == root { None } else { Some(chest) };
    // Abdomen: the spine joint nearest the middle of pelvis → chest.
    let abdomen = chest.and_then(|c| {
        let mid = (rest[root] + rest[c]) * 0.5;
        ancestors(c)
            .into_iter()
            .filter(|&j| {
                j != c
                    && j != root
                    && rest[j].distance(rest[root]) >= MIN_BONE_M
                    && rest[j].distance(rest[c]) >= MIN_BONE_M
            })
            .min_by(|&a, &b| rest[a].distance(mid).total_cmp(&rest[b].distance(mid)))
    });

    // Figure axes from the hips: left = left hip − right hip, up = +Y, forward = left × up.
    let up = Vec3::Y;
    let left = (rest[lm.limbs[0][0]] - rest[lm.limbs[1][0]]).reject_from(up).try_normalize().ok_or_else(|| {
        FigureError::ZeroLengthBone {
            from: joints[lm.limbs[0][0]].name.clone(),
            to: joints[lm.limbs[1][0]].name.clone(),
            length_m: 0.0,
        }
    })?;
    let forward = left.cross(up);
    let basis = Quat::from_mat3(&Mat3::from_cols(left, up, forward));

    let lowest = rest.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let highest = rest.iter().map(|p| p.y).fold(f32::NEG_INFINITY, f32::max);
    let stature = (highest - lowest).max(MIN_BONE_M);
    let hip_width = rest[lm.limbs[0][0]].distance(rest[lm.limbs[1][0]]);
    let shoulder_width = rest[lm.limbs[0][3]].distance(rest[lm.limbs[1][3]]);

    // (name, role, side, joint, end point)
    struct Plan {
        name: String,
        role: BodyRole,
        side: Option<usize>,
        joint: usize,
        end: usize,
    }
    let mut plans = Vec::new();
    // A trunk body reaches the first joint above it that is not on top of it (CMU's neck
    // sits exactly on its chest joint).
    let trunk_end = |from: usize, candidates: &[Option<usize>]| {
        candidates.iter().flatten().copied().find(|&e| rest[e].distance(rest[from]) >= MIN_BONE_M).unwrap_or(lm.neck)
    };
    let above = [abdomen, chest, Some(lm.neck), Some(lm.head)];
    plans.push(Plan {
        name: "pelvis".into(),
        role: BodyRole::Pelvis,
        side: None,
        joint: root,
        end: trunk_end(root, &above),
    });
    if let Some(a) = abdomen {
        plans.push(Plan {
            name: "abdomen".into(),
            role: BodyRole::Abdomen,
            side: None,
            joint: a,
            end: trunk_end(a, &above[1..]),
        });
    }
    if let Some(c) = chest {
        plans.push(Plan {
            name: "chest".into(),
            role: BodyRole::Chest,
            side: None,
            joint: c,
            end: trunk_end(c, &above[2..]),
        });
    }
    let head_tip = limb_tip(skeleton, lm.head);
    plans.push(Plan { name: "head".into(), role: BodyRole::Head, side: None, joint: lm.neck, end: head_tip });
    let roles =
        [BodyRole::Thigh, BodyRole::Shank, BodyRole::Foot, BodyRole::UpperArm, BodyRole::Forearm, BodyRole::Hand];
    for side in 0..2 {
        let slots = lm.limbs[side];
        for (k, &role) in roles.iter().enumerate() {
            let joint = slots[k];
            let end = match k {
                0 | 1 | 3 | 4 => slots[k + 1],
                _ => limb_tip(skeleton, joint),
            };
            let name = format!("{}_{}", ["left", "right"][side], serde_name(role));
            plans.push(Plan { name, role, side: Some(side), joint, end });
        }
    }
    let driver_of: Vec<Option<usize>> = (0..skeleton.len()).map(|j| plans.iter().position(|p| p.joint == j)).collect();
    // Owner body of every joint: its nearest driving ancestor (or itself).
    let owner: Vec<usize> =
        (0..skeleton.len()).map(|j| ancestors(j).into_iter().find_map(|a| driver_of[a]).unwrap_or(0)).collect();

    let skinned = mesh.map(|m| SkinnedRest::new(skeleton, m)).transpose()?;
    let skin_points = skinned.as_ref().map(|s| s.vertices_by_body(&owner, plans.len()));
    // The pelvis's seat pad. One deeper than a tenth of stature below the hips is not
    // buttocks (a garment or a tail hanging from the pelvis): the pelvis keeps its capsule.
    let seated_body = |j: usize| matches!(plans[owner[j]].role, BodyRole::Pelvis | BodyRole::Thigh);
    let pad = skinned
        .as_ref()
        .and_then(|s| s.seat_pad([lm.limbs[0][0], lm.limbs[1][0]], seated_body, left))
        .filter(|&(_, radius)| radius <= 0.05 * stature);
    let mut bodies: Vec<FigureBody> = Vec::with_capacity(plans.len());
    // The feet's soles, lowest, and whether a foot's box was measured from its skin (see
    // `rest_sole_y_m` below).
    let (mut lowest_sole_y, mut any_shoe) = (f32::INFINITY, false);
    for (i, plan) in plans.iter().enumerate() {
        let origin = rest[plan.joint];
        let mut end = rest[plan.end];
        let bone = end - origin;
        let mut length = bone.length();
        if plan.role == BodyRole::Hand && length < 0.05 * stature {
            // A hand without finger joints: a hand's length is about a tenth of stature.
            let dir = (origin - rest[lm.limbs[plan.side.unwrap_or(0)][4]]).normalize_or_zero();
            end = origin + dir * 0.1 * stature;
            length = 0.1 * stature;
        }
        if plan.role == BodyRole::Head && length < 0.05 * stature {
            end = origin + up * 0.15 * stature;
            length = 0.15 * stature;
        }
        if length.is_nan() || length < MIN_BONE_M {
            return Err(FigureError::ZeroLengthBone {
                from: joints[plan.joint].name.clone(),
                to: joints[plan.end].name.clone(),
                length_m: length,
            });
        }
        let points = skin_points.as_ref().map(|points| points[i].as_slice());
        let shape = if let (BodyRole::Pelvis, Some(([a, b], radius_m))) = (plan.role, pad) {
            BodyShape::Capsule { a: a - origin, b: b - origin, radius_m }
        } else if plan.role == BodyRole::Foot {
            let toe = rest[plan.end];
            let dir = (toe - origin).reject_from(up).try_normalize().unwrap_or(forward);
            let rotation = Quat::from_mat3(&Mat3::from_cols(dir, up, -up.cross(dir)));
            // Measured from the foot's skin, or from the skeleton: the sole at the foot's
            // lowest joint less 1 % of stature, from behind the ankle to the toe tip.
            let shoe = points.and_then(|points| sole_box(points, origin, dir));
            any_shoe |= shoe.is_some();
            let sole = shoe.unwrap_or_else(|| {
                let heel = origin - dir * 0.04 * stature;
                let (sole_y, top_y) = (toe.y.min(origin.y) - 0.01 * stature, origin.y);
                SoleBox {
                    centre: ((heel + toe) * 0.5).with_y((sole_y + top_y) * 0.5),
                    half_extents: Vec3::new(
                        0.5 * (toe - heel).reject_from(up).length(),
                        0.5 * (top_y - sole_y).max(0.02),
                        0.03 * stature,
                    ),
                }
            });
            lowest_sole_y = lowest_sole_y.min(sole.centre.y - sole.half_extents.y);
            BodyShape::Box { centre: sole.centre - origin, half_extents: sole.half_extents, rotation }
        } else {
            let quantile = if plan.role == BodyRole::Hand { HAND_QUANTILE } else { RADIUS_QUANTILE };
            // The pelvis is a seat pad or keeps its skeleton-sized capsule: a capsule round its
            // short bone as fat as its skin rolls on a seat like a wheel (see skin_fit).
            let measured = points
                .filter(|_| plan.role != BodyRole::Pelvis)
                .and_then(|points| capsule_radius(points, origin, end, quantile));
            let radius = match (measured, plan.role) {
                // A trunk body can be fatter than it is long; a limb's end caps must not reach
                // past its neighbours' joints.
                (Some(r), BodyRole::Abdomen | BodyRole::Chest | BodyRole::Head) => r.clamp(0.005, 0.15 * stature),
                (Some(r), _) => r.clamp(0.005, 0.5 * length.max(0.02)),
                (None, role) => match role {
                    BodyRole::Pelvis | BodyRole::Abdomen => 0.5 * hip_width.max(0.5 * shoulder_width) * 0.9,
                    BodyRole::Chest => 0.3 * shoulder_width,
                    BodyRole::Head => 0.055 * stature,
                    BodyRole::Thigh => 0.15 * length,
                    BodyRole::Shank => 0.11 * length,
                    BodyRole::UpperArm => 0.15 * length,
                    BodyRole::Forearm => 0.13 * length,
                    BodyRole::Hand | BodyRole::Foot => 0.2 * length,
                }
                .clamp(0.005, 0.5 * length.max(0.02)),
            };
            // Limb capsules stop one radius short of the next joint, so the shank's end does
            // not poke through the sole.
            let dir = (end - origin) / length;
            let inset = match plan.role {
                BodyRole::Shank | BodyRole::Thigh | BodyRole::UpperArm | BodyRole::Forearm => radius.min(0.45 * length),
                _ => 0.0,
            };
            BodyShape::Capsule { a: Vec3::ZERO, b: dir * (length - inset), radius_m: radius }
        };
        let parent = plan.joint_parent(&owner, joints);
        let kind = match (plan.role, parent) {
            (_, None) => JointKind::Free,
            (BodyRole::Shank, _) => JointKind::Hinge { limits_rad: [0.0, 2.4] },
            (BodyRole::Forearm, _) => JointKind::Hinge { limits_rad: [0.0, 2.5] },
            (role, _) => JointKind::Ball { limits_rad: ball_limits(role, plan.side) },
        };
        // Hinge axes: flexion positive. Knee: bone × (−forward); elbow: bone × forward.
        let joint_frame = match plan.role {
            BodyRole::Shank | BodyRole::Forearm => {
                let bone_dir = (end - origin) / length;
                let flex = if plan.role == BodyRole::Shank { -forward } else { forward };
                let axis = bone_dir.cross(flex).try_normalize().unwrap_or(left);
                let y = bone_dir.reject_from(axis).try_normalize().unwrap_or(up);
                Quat::from_mat3(&Mat3::from_cols(axis, y, axis.cross(y)))
            }
            _ => basis,
        };
        let anchor_in_parent = parent.map(|p| origin - rest[bodies[p].joint]).unwrap_or(Vec3::ZERO);
        bodies.push(FigureBody {
            name: plan.name.clone(),
            role: plan.role,
            side: plan.side,
            joint: plan.joint,
            parent,
            mass_kg: 0.0,
            com_local: Vec3::ZERO,
            shape,
            kind,
            joint_frame,
            anchor_in_parent,
            kp: 0.0,
            kd: 0.0,
            supported_mass_kg: 0.0,
        });
    }
    impl Plan {
        fn joint_parent(&self, owner: &[usize], joints: &[crate::model::Joint]) -> Option<usize> {
            joints[self.joint].parent.map(|p| owner[p])
        }
    }

    // Masses from the body model: each table segment to its body by name, anything else
    // to the body whose bone passes nearest.
    let model = body_model(skeleton, params.total_mass_kg, params.table, None)?;
    // The method used, not the one asked for: a skeleton without named limbs falls back.
    let named = matches!(MassTable::from_name(&model.method), Some(MassTable::DeLevaMale | MassTable::DeLevaFemale));
    let mut mass = vec![0.0f64; bodies.len()];
    let mut moment = vec![Vec3::ZERO; bodies.len()];
    for segment in &model.segments {
        let com = model.segment_com(segment, &rest);
        let body = named.then(|| segment_body(&segment.name, &bodies)).flatten().unwrap_or_else(|| {
            (0..bodies.len())
                .min_by(|&a, &b| {
                    bone_distance(&bodies[a], &rest, com).total_cmp(&bone_distance(&bodies[b], &rest, com))
                })
                .unwrap_or(0)
        });
        mass[body] += segment.mass_kg;
        moment[body] += com * segment.mass_kg as f32;
    }
    for (i, body) in bodies.iter_mut().enumerate() {
        // A body no segment landed on (rare rigs) keeps a token 0.5 % of the mass at its
        // shape's centre, so it stays a proper rigid body.
        if mass[i] <= 0.0 {
            mass[i] = 0.005 * params.total_mass_kg;
            moment[i] = (rest[body.joint] + shape_centre(&body.shape)) * mass[i] as f32;
        }
        body.mass_kg = mass[i] as f32;
        body.com_local = moment[i] / mass[i] as f32 - rest[body.joint];
    }
    let total_mass_kg = mass.iter().sum::<f64>() as f32;

    // Gains from the supported mass.
    let world_com = |set: &[usize], bodies: &[FigureBody]| -> (f32, Vec3) {
        let m: f32 = set.iter().map(|&b| bodies[b].mass_kg).sum();
        let c: Vec3 = set.iter().map(|&b| (rest[bodies[b].joint] + bodies[b].com_local) * bodies[b].mass_kg).sum();
        (m, if m > 0.0 { c / m } else { Vec3::ZERO })
    };
    let g = params.gravity_m_s2.max(0.1);
    for i in 1..bodies.len() {
        let subtree: Vec<usize> = (0..bodies.len()).filter(|&b| is_body_ancestor(&bodies, i, b)).collect();
        let leg = matches!(bodies[i].role, BodyRole::Thigh | BodyRole::Shank | BodyRole::Foot);
        let supported: Vec<usize> = if leg {
            // Standing, a leg joint holds up everything above it, shared by two legs.
            (0..bodies.len()).filter(|b| !subtree.contains(b)).collect()
        } else {
            subtree
        };
        let (mut m, c) = world_com(&supported, &bodies);
        if leg {
            m *= 0.5;
        }
        let d = c.distance(rest[bodies[i].joint]).max(0.05);
        let kp = params.stiffness_ratio * m * g * d;
        let kd = 2.0 * (kp * m * d * d).sqrt();
        bodies[i].kp = kp;
        bodies[i].kd = kd;
        bodies[i].supported_mass_kg = m;
    }
    // From the skeleton the soles are 1 % of stature below the lowest joint; a shoe measured
    // from the skin sets its own, and then the lowest of the feet's boxes counts.
    let rest_sole_y_m = if any_shoe { lowest_sole_y } else { lowest - 0.01 * stature };
    Ok(Figure {
        bodies,
        owner,
        total_mass_kg,
        stature_m: stature,
        forward,
        left,
        mass_method: model.method,
        friction: params.friction,
        rest_sole_y_m,
        seat_depth_m: pad.map(|(_, radius)| 2.0 * radius),
    })
}

fn serde_name(role: BodyRole) -> &'static str {
    match role {
        BodyRole::Pelvis => "pelvis",
        BodyRole::Abdomen => "abdomen",
        BodyRole::Chest => "chest",
        BodyRole::Head => "head",
        BodyRole::Thigh => "thigh",
        BodyRole::Shank => "shank",
        BodyRole::Foot => "foot",
        BodyRole::UpperArm => "upper_arm",
        BodyRole::Forearm => "forearm",
        BodyRole::Hand => "hand",
    }
}

fn shape_centre(shape: &BodyShape) -> Vec3 {
    match *shape {
        BodyShape::Capsule { a, b, .. } => (a + b) * 0.5,
        BodyShape::Box { centre, .. } => centre,
    }
}

/// The body that carries de Leva segment `segment`: limbs and head by name (bodies are
/// named like the table's segments), the trunk's thirds to the chest, abdomen and pelvis.
/// `None` when the skeleton has no such body (no abdomen joint: the middle trunk goes to
/// the nearest bone). The upper trunk moves with the shoulders, so it belongs on the chest
/// even where the rig's chest joint sits above the segment's centre (CMU's cgspeed rigs put
/// the shoulders and the neck on one joint, with no thorax bone).
fn segment_body(segment: &str, bodies: &[FigureBody]) -> Option<usize> {
    let body = match segment {
        "upper_trunk" => "chest",
        "middle_trunk" => "abdomen",
        "lower_trunk" => "pelvis",
        limb_or_head => limb_or_head,
    };
    bodies.iter().position(|b| b.name == body)
}

/// Distance from `p` (world, rest) to the body's bone (its shape's axis).
fn bone_distance(body: &FigureBody, rest: &[Vec3], p: Vec3) -> f32 {
    let origin = rest[body.joint];
    let (a, b) = match body.shape {
        BodyShape::Capsule { a, b, .. } => (origin + a, origin + b),
        BodyShape::Box { centre, half_extents, rotation } => {
            let axis = rotation * Vec3::X * half_extents.x;
            (origin + centre - axis, origin + centre + axis)
        }
    };
    segment_distance(p, a, b)
}

fn is_body_ancestor(bodies: &[FigureBody], ancestor: usize, body: usize) -> bool {
    let mut b = Some(body);
    while let Some(i) = b {
        if i == ancestor {
            return true;
        }
        b = bodies[i].parent;
    }
    false
}

/// Collision groups: the figure's shapes touch the ground only (not each other).
pub const FIGURE_GROUP: Group = Group::GROUP_1;
/// The ground's collision group.
pub const GROUND_GROUP: Group = Group::GROUP_2;

/// A figure placed in a world.
#[derive(Clone, Debug)]
pub struct Spawned {
    /// Rigid body per figure body.
    pub handles: Vec<RigidBodyHandle>,
    /// Multibody joint per figure body (`None` for the root).
    pub joints: Vec<Option<MultibodyJointHandle>>,
}

impl Figure {
    /// How far below the hip joints the seated body reaches, metres: the radius of the
    /// thigh body `thigh`, or the seat pad's depth when the figure has one and it reaches
    /// lower (a figure sized from its mesh rests on its buttocks,
    /// [`super::skin_fit::SkinnedRest::seat_pad`]).
    pub fn seated_depth_m(&self, thigh: usize) -> f32 {
        let thigh_radius = match self.bodies[thigh].shape {
            BodyShape::Capsule { radius_m, .. } => radius_m,
            BodyShape::Box { half_extents, .. } => half_extents.min_element(),
        };
        self.seat_depth_m.map_or(thigh_radius, |pad| pad.max(thigh_radius))
    }

    /// Body index by name.
    pub fn body_index(&self, name: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.name == name)
    }

    /// The direction of body `b`'s bone in the rest pose (world, unit): along its capsule,
    /// or heel to toe for a foot.
    pub fn bone_direction(&self, b: usize) -> Vec3 {
        match self.bodies[b].shape {
            BodyShape::Capsule { a, b, .. } => (b - a).try_normalize().unwrap_or(Vec3::Y),
            BodyShape::Box { rotation, .. } => rotation * Vec3::X,
        }
    }

    /// Length of body `b`'s bone at rest (joint to the next joint), metres.
    pub fn bone_length(&self, b: usize) -> f32 {
        match self.bodies[b].shape {
            BodyShape::Capsule { a, b, radius_m } => (b - a).length() + radius_m,
            BodyShape::Box { half_extents, .. } => 2.0 * half_extents.x,
        }
    }

    /// Puts the figure in `world` in its rest pose, root translated by `offset`; motors are
    /// set to hold the rest pose.
    pub fn spawn(&self, world: &mut World, skeleton: &Skeleton, offset: Vec3) -> Spawned {
        let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
        let w = &mut world.inner;
        let mut handles = Vec::with_capacity(self.bodies.len());
        for body in &self.bodies {
            let origin = rest[body.joint] + offset;
            let rb = RigidBodyBuilder::dynamic()
                .translation(to_rapier(origin))
                .can_sleep(false)
                .additional_mass_properties(self.mass_properties(body));
            let h = w.bodies.insert(rb);
            let collider = match body.shape {
                BodyShape::Capsule { a, b, radius_m } => {
                    ColliderBuilder::capsule_from_endpoints(to_rapier(a), to_rapier(b), radius_m)
                }
                BodyShape::Box { centre, half_extents, rotation } => {
                    ColliderBuilder::cuboid(half_extents.x, half_extents.y, half_extents.z)
                        .position(pose_to_rapier(rotation, centre))
                }
            }
            .density(0.0)
            .friction(self.friction)
            .restitution(0.0)
            .collision_groups(InteractionGroups::new(FIGURE_GROUP, GROUND_GROUP, InteractionTestMode::And));
            w.colliders.insert_with_parent(collider, h, &mut w.bodies);
            handles.push(h);
        }
        let mut joints = vec![None; self.bodies.len()];
        for (i, body) in self.bodies.iter().enumerate() {
            let Some(p) = body.parent else { continue };
            let frame = rot_to_rapier(body.joint_frame);
            let mut data = GenericJointBuilder::new(match body.kind {
                JointKind::Hinge { .. } => JointAxesMask::LOCKED_REVOLUTE_AXES,
                _ => JointAxesMask::LIN_AXES,
            })
            .local_frame1(Pose::from_parts(to_rapier(body.anchor_in_parent), frame))
            .local_frame2(Pose::from_parts(Vector::ZERO, frame))
            .build();
            let axes: &[(JointAxis, [f32; 2])] = &match body.kind {
                JointKind::Hinge { limits_rad } => vec![(JointAxis::AngX, limits_rad)],
                JointKind::Ball { limits_rad } => {
                    vec![
                        (JointAxis::AngX, limits_rad[0]),
                        (JointAxis::AngY, limits_rad[1]),
                        (JointAxis::AngZ, limits_rad[2]),
                    ]
                }
                JointKind::Free => vec![],
            };
            let max_torque = self.ankle_torque_limit_nm(body, -w.gravity.y);
            for &(axis, limits) in axes {
                data.set_limits(axis, limits);
                data.set_motor_model(axis, MotorModel::ForceBased);
                data.set_motor_position(axis, 0.0, body.kp, body.kd);
                if let Some(max) = max_torque {
                    data.set_motor_max_force(axis, max);
                }
            }
            joints[i] = w.multibody_joints.insert(handles[p], handles[i], data, true);
        }
        world.clear_articulation_damping(handles[0]);
        Spawned { handles, joints }
    }

    /// The most torque an ankle may exert, N·m: the weight it holds up times the
    /// horizontal lever from the ankle to the toe tip. More than that tips the foot onto
    /// its toes instead of leaning the body, and stiff PD ankles then pole-vault the figure
    /// off the ground (a 45 N·s push lifted the CMU figure's COM at 0.4 m/s). `None` for
    /// other joints.
    pub fn ankle_torque_limit_nm(&self, body: &FigureBody, gravity_m_s2: f32) -> Option<f32> {
        let BodyShape::Box { centre, half_extents, rotation } = body.shape else { return None };
        let toe = centre + rotation * Vec3::X * half_extents.x;
        (body.role == BodyRole::Foot).then(|| body.supported_mass_kg * gravity_m_s2 * toe.with_y(0.0).length())
    }

    fn mass_properties(&self, body: &FigureBody) -> MassProperties {
        let unit = match body.shape {
            BodyShape::Capsule { a, b, radius_m } => {
                SharedShape::capsule(to_rapier(a), to_rapier(b), radius_m).mass_properties(1.0)
            }
            BodyShape::Box { centre, half_extents, rotation } => {
                SharedShape::cuboid(half_extents.x, half_extents.y, half_extents.z)
                    .mass_properties(1.0)
                    .transform_by(&pose_to_rapier(rotation, centre))
            }
        };
        let scale = if unit.mass() > 0.0 { body.mass_kg / unit.mass() } else { 0.0 };
        let inertia = unit.principal_inertia() * scale;
        MassProperties::with_principal_inertia_frame(
            to_rapier(body.com_local),
            body.mass_kg,
            inertia,
            unit.principal_inertia_local_frame,
        )
    }

    /// World transform of every skeleton joint given the bodies' world poses (rotation
    /// relative to rest, origin = the driving joint), for writing clips.
    pub fn joint_world(&self, skeleton: &Skeleton, body_rot: &[Quat], body_pos: &[Vec3]) -> Vec<Transform> {
        let rest = rest_world(skeleton);
        (0..skeleton.len())
            .map(|j| {
                let b = self.owner[j];
                let origin = rest[self.bodies[b].joint].translation;
                Transform {
                    rotation: quat_normalize_or_identity(body_rot[b] * rest[j].rotation),
                    translation: body_pos[b] + body_rot[b] * (rest[j].translation - origin),
                }
            })
            .collect()
    }

    /// The poses of the bodies (rotation relative to rest, origin position) when the
    /// skeleton stands in the pose given by local joint `rotations` and `translations`.
    pub fn body_poses(&self, skeleton: &Skeleton, rotations: &[Quat], translations: &[Vec3]) -> (Vec<Quat>, Vec<Vec3>) {
        let rest = rest_world(skeleton);
        let mut world = rest.clone();
        pose_world(skeleton, rotations, translations, &mut world);
        self.bodies
            .iter()
            .map(|b| {
                (
                    quat_normalize_or_identity(world[b.joint].rotation * rest[b.joint].rotation.inverse()),
                    world[b.joint].translation,
                )
            })
            .unzip()
    }

    /// Reads the bodies' poses from the world.
    pub fn read_poses(&self, world: &World, spawned: &Spawned) -> (Vec<Quat>, Vec<Vec3>) {
        spawned
            .handles
            .iter()
            .map(|&h| {
                let rb = &world.inner.bodies[h];
                (rot_from_rapier(*rb.rotation()), super::from_rapier(rb.translation()))
            })
            .unzip()
    }
}
