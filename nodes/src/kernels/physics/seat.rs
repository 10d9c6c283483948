//! A seat for the sit and rise controllers: a fixed box standing on the ground behind the
//! figure (a stool or a chair without a back), placed by the script relative to where the
//! figure first stands, and the sense of whether the figure sits on it.

use glam::{Vec2, Vec3};
use rapier3d::prelude::*;
use serde::Deserialize;

use super::World;
use super::figure::{BodyRole, BodyShape, Figure};
use super::state::FigureState;
use crate::model::{Material, Mesh};

/// A body rests on the seat when its lowest point is this close to the seat's top, metres
/// (the same bar as a sole on the ground).
pub const SEAT_CONTACT_M: f32 = super::state::CONTACT_HEIGHT_M;

/// Points sampled along a capsule's axis (plus one) when asking whether it rests on the seat.
const SEAT_SAMPLES: usize = 6;

/// The chair of a script: where it stands relative to the figure's initial facing.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Chair {
    /// Height of the seat's top above the ground, metres.
    #[serde(default = "default_height")]
    pub seat_height_m: f32,
    /// Distance from the figure's initial centre of mass (its ground projection) back to the
    /// seat's front edge, along the figure's initial facing, metres.
    #[serde(default = "default_behind")]
    pub behind_m: f32,
    /// Seat width (side to side) and depth (front to back), metres.
    #[serde(default = "default_size")]
    pub size_m: [f32; 2],
}

fn default_height() -> f32 {
    0.45
}
fn default_behind() -> f32 {
    0.15
}
fn default_size() -> [f32; 2] {
    [0.5, 0.45]
}

impl Default for Chair {
    fn default() -> Self {
        Chair { seat_height_m: default_height(), behind_m: default_behind(), size_m: default_size() }
    }
}

impl Chair {
    /// What is wrong with the chair's numbers, if anything.
    pub fn check(&self) -> Result<(), String> {
        let ok = |v: f32, lo: f32, hi: f32| v.is_finite() && (lo..=hi).contains(&v);
        if !ok(self.seat_height_m, 0.1, 1.5) {
            return Err(format!("seat_height_m {} must be within 0.1..=1.5 m", self.seat_height_m));
        }
        if !ok(self.behind_m, -0.5, 2.0) {
            return Err(format!("behind_m {} must be within -0.5..=2 m", self.behind_m));
        }
        if !(ok(self.size_m[0], 0.1, 3.0) && ok(self.size_m[1], 0.1, 3.0)) {
            return Err(format!("size_m {:?} must be within 0.1..=3 m each", self.size_m));
        }
        Ok(())
    }

    /// The seat placed behind a figure whose COM projects to `com_xz` and faces `forward`
    /// (horizontal, unit).
    pub fn place(&self, com_xz: Vec2, forward: Vec3) -> Seat {
        let front = Vec3::new(com_xz.x, 0.0, com_xz.y) - forward * self.behind_m;
        let half = Vec2::new(0.5 * self.size_m[0], 0.5 * self.size_m[1]);
        Seat { top_centre: front - forward * half.y + Vec3::Y * self.seat_height_m, forward, half_size_m: half }
    }
}

/// A placed seat, world metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seat {
    /// Centre of the seat's top face.
    pub top_centre: Vec3,
    /// The direction the seat faces (horizontal, unit): its front edge is this way.
    pub forward: Vec3,
    /// Half width (side to side) and half depth (front to back), metres.
    pub half_size_m: Vec2,
}

impl Seat {
    /// The seat's left (horizontal, unit).
    pub fn left(&self) -> Vec3 {
        Vec3::Y.cross(self.forward)
    }

    /// Midpoint of the seat's front edge, at the seat's height.
    pub fn front_edge(&self) -> Vec3 {
        self.top_centre + self.forward * self.half_size_m.y
    }

    /// Whether the horizontal position of `p` lies over the seat, grown by `margin_m`.
    pub fn over(&self, p: Vec3, margin_m: f32) -> bool {
        let d = p - self.top_centre;
        d.dot(self.left()).abs() <= self.half_size_m.x + margin_m
            && d.dot(self.forward).abs() <= self.half_size_m.y + margin_m
    }

    /// The seat as a box from the ground to its top (world metres, unskinned), with a
    /// matt wood-coloured material: what an export or a viewer draws where the figure sits.
    pub fn mesh(&self) -> Mesh {
        let mut mesh = Mesh { name: "stool".into(), ..Mesh::default() };
        let (left, ground) = (self.left(), self.top_centre.with_y(0.0));
        let half = self.half_size_m;
        // Edges left, up, forward: a right-handed box, so its faces point outwards.
        mesh.push_box(|i| {
            ground
                + left * if i & 1 == 0 { -half.x } else { half.x }
                + Vec3::Y * if i & 2 == 0 { 0.0 } else { self.top_centre.y }
                + self.forward * if i & 4 == 0 { -half.y } else { half.y }
        });
        let wood = Material {
            name: Some("stool".into()),
            base_color_factor: [0.55, 0.4, 0.26, 1.0],
            metallic_factor: 0.0,
            roughness_factor: 0.8,
            ..Material::default()
        };
        let material = mesh.material_index(&wood);
        mesh.push_material_range(Some(material), mesh.triangles.len());
        mesh
    }

    /// Puts the seat in `world` as a fixed box from the ground to its top, touching the
    /// figure as the ground does.
    pub fn add_to(&self, world: &mut World, friction: f32) -> RigidBodyHandle {
        let h = 0.5 * self.top_centre.y;
        let pose =
            super::pose_to_rapier(glam::Quat::from_rotation_arc(Vec3::Z, self.forward), self.top_centre - Vec3::Y * h);
        world.add_fixed(ColliderBuilder::cuboid(self.half_size_m.x, h, self.half_size_m.y), pose, friction)
    }

    /// Whether the figure sits on the seat: a point of the pelvis's or a thigh's capsule over
    /// the seat is within [`SEAT_CONTACT_M`] of its top.
    pub fn sitting(&self, figure: &Figure, state: &FigureState) -> bool {
        figure.bodies.iter().enumerate().any(|(i, body)| {
            let (BodyRole::Pelvis | BodyRole::Thigh, BodyShape::Capsule { a, b, radius_m }) = (body.role, body.shape)
            else {
                return false;
            };
            let (q, p) = (state.body_rot[i], state.body_pos[i]);
            let (a, b) = (p + q * a, p + q * b);
            // Points along the capsule's axis: a thigh sloping down to the knee rests on the
            // seat's front edge, not at its lowest point.
            (0..=SEAT_SAMPLES).any(|k| {
                let c = a.lerp(b, k as f32 / SEAT_SAMPLES as f32);
                self.over(c, 0.0) && c.y - radius_m < self.top_centre.y + SEAT_CONTACT_M
            })
        })
    }
}
