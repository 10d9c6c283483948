//! Dynamic rigid bodies in the fluid (Klingner et al. 2006, §7): a ball or a cube of a given
//! density, dropped or thrown into the box, moved by gravity and by the fluid's pressure
//! through the coupled projection ([`super::projection::PressureSolver::with_bodies`]).
//!
//! Per step (see `sim`): the body moves by its velocity and is carved out of the new mesh as
//! an obstacle whose surface moves rigidly; its velocity without the solved pressure (the
//! paper's rigid-body z*) is the old one plus gravity and the impulse of the hydrostatic
//! pressure p_h = ρ g·x over its faces ([`hydrostatic_wrench`], the buoyancy); the coupled
//! solve adds the impulse of the rest of the pressure (added mass, drag, the smoke's push).
//! The fluid's own weight is balanced by p_h and so left out of its faces, as the smoke's
//! Boussinesq buoyancy already assumes. Putting gravity on the fluid's faces instead (the
//! paper's form) lets the solve find p_h too, but reads it at the circumcentres of the tets
//! next to the body, half a tet off its faces: that buoyed a neutral 0.4 m cube up at 18 %
//! of g on tets of 4 dm³, where the exact face integral leaves it still (2e-15 g).
//!
//! A ball's inertia (2/5·m·r²) and a cube's (1/6·m·s²) are isotropic, so I⁻¹ is a scalar in
//! any orientation and torque-free motion keeps ω (no gyroscopic term).
//!
//! Contact is a clamp, not a collision model: a body stops one gap (the smallest tet edge)
//! short of a box wall, a layer of tets must stay between them, and loses its velocity into
//! the wall (inelastic, frictionless).

use glam::{DQuat, DVec3};
use nalgebra::{Matrix6, Vector6};

use super::mesh::TetMesh;
use super::mesher::Obstacle;
use super::projection::{FaceCondition, RigidCoupling, rigid_face_row};
use crate::model::{BodyPose, BodyShape};

/// Gravity of the bodies' world, m/s² (Y up).
pub const GRAVITY_M_S2: f64 = 9.81;

/// What a body looks like.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RigidShape {
    /// A sphere; its size is the diameter.
    Ball,
    /// A cube; its size is the edge length.
    Cube,
}

/// A free rigid body of uniform density, and its state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidBody {
    /// Ball or cube.
    pub shape: RigidShape,
    /// Diameter of a ball, edge of a cube, metres.
    pub size_m: f64,
    /// Density, kg/m³.
    pub density_kg_m3: f64,
    /// Centre of mass, metres.
    pub position_m: DVec3,
    /// Rotation from the body's axes to the world's.
    pub orientation: DQuat,
    /// Velocity of the centre of mass, m/s.
    pub velocity_m_s: DVec3,
    /// Angular velocity, rad/s, world axes.
    pub angular_velocity_rad_s: DVec3,
}

impl RigidBody {
    /// Where the body is and what it looks like, for display.
    pub fn pose(&self) -> BodyPose {
        let shape = match self.shape {
            RigidShape::Ball => BodyShape::Ball { radius_m: (0.5 * self.size_m) as f32 },
            RigidShape::Cube => BodyShape::Cube { edge_m: self.size_m as f32 },
        };
        BodyPose {
            shape,
            centre_m: self.position_m.as_vec3().to_array(),
            rotation_xyzw: self.orientation.as_quat().to_array(),
        }
    }

    /// A body at rest or moving, not rotated, not spinning.
    pub fn new(shape: RigidShape, size_m: f64, density_kg_m3: f64, position_m: DVec3, velocity_m_s: DVec3) -> Self {
        RigidBody {
            shape,
            size_m,
            density_kg_m3,
            position_m,
            orientation: DQuat::IDENTITY,
            velocity_m_s,
            angular_velocity_rad_s: DVec3::ZERO,
        }
    }

    /// Volume, m³.
    pub fn volume_m3(&self) -> f64 {
        match self.shape {
            RigidShape::Ball => std::f64::consts::PI / 6.0 * self.size_m.powi(3),
            RigidShape::Cube => self.size_m.powi(3),
        }
    }

    /// Mass, kg.
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.volume_m3()
    }

    /// Moment of inertia about any axis through the centre, kg·m².
    pub fn inertia_kg_m2(&self) -> f64 {
        let m = self.mass_kg();
        match self.shape {
            RigidShape::Ball => 0.1 * m * self.size_m * self.size_m,
            RigidShape::Cube => m * self.size_m * self.size_m / 6.0,
        }
    }

    /// Half the body's extent along the unit vector `axis`, metres.
    pub fn half_extent_along(&self, axis: DVec3) -> f64 {
        let half = 0.5 * self.size_m;
        match self.shape {
            RigidShape::Ball => half,
            RigidShape::Cube => {
                let local = self.orientation.inverse() * axis;
                half * (local.x.abs() + local.y.abs() + local.z.abs())
            }
        }
    }

    /// The closed surface where the body is now, its triangle edges at most about `edge_m`
    /// (the mesher keeps surface vertices at least half the local tet size apart).
    pub fn surface(&self, edge_m: f64) -> Obstacle {
        let half = 0.5 * self.size_m;
        let levels = |edge_at_level_0: f64| (edge_at_level_0 / edge_m.max(1e-9)).log2().ceil().clamp(0.0, 5.0) as usize;
        let local = match self.shape {
            RigidShape::Ball => Obstacle::sphere(DVec3::ZERO, half, levels(std::f64::consts::SQRT_2 * half)),
            RigidShape::Cube => {
                let mut cube = Obstacle::cuboid(DVec3::ZERO, DVec3::splat(half));
                for _ in 0..levels(self.size_m) {
                    cube = cube.subdivided();
                }
                cube
            }
        };
        Obstacle {
            positions_m: local.positions_m.iter().map(|p| self.position_m + self.orientation * *p).collect(),
            triangles: local.triangles,
        }
    }

    /// Velocity of the body's material point at `p_m`, m/s.
    pub fn point_velocity(&self, p_m: DVec3) -> DVec3 {
        self.velocity_m_s + self.angular_velocity_rad_s.cross(p_m - self.position_m)
    }

    /// (v, ω) as one 6-vector, m/s then rad/s.
    pub fn generalised_velocity(&self) -> Vector6<f64> {
        let (v, w) = (self.velocity_m_s, self.angular_velocity_rad_s);
        Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z)
    }

    /// Sets (v, ω) from a 6-vector, m/s then rad/s.
    pub fn set_generalised_velocity(&mut self, u: &Vector6<f64>) {
        self.velocity_m_s = DVec3::new(u[0], u[1], u[2]);
        self.angular_velocity_rad_s = DVec3::new(u[3], u[4], u[5]);
    }

    /// The body as the pressure solve needs it: centre and diag(m, m, m, I, I, I).
    pub fn coupling(&self) -> RigidCoupling {
        let (m, i) = (self.mass_kg(), self.inertia_kg_m2());
        RigidCoupling { centre_m: self.position_m, mass: Matrix6::from_diagonal(&Vector6::new(m, m, m, i, i, i)) }
    }

    /// Adds the impulse `wrench_n_s` (N·s, then N·m·s about the centre) to the velocity.
    pub fn apply_impulse(&mut self, wrench_n_s: &Vector6<f64>) {
        let (m, i) = (self.mass_kg(), self.inertia_kg_m2());
        self.velocity_m_s += DVec3::new(wrench_n_s[0], wrench_n_s[1], wrench_n_s[2]) / m;
        self.angular_velocity_rad_s += DVec3::new(wrench_n_s[3], wrench_n_s[4], wrench_n_s[5]) / i;
    }

    /// Moves the body by its velocity for `dt_s` seconds (position and orientation).
    pub fn advance(&mut self, dt_s: f64) {
        self.position_m += self.velocity_m_s * dt_s;
        self.orientation = (DQuat::from_scaled_axis(self.angular_velocity_rad_s * dt_s) * self.orientation).normalize();
    }

    /// Keeps the body `gap_m` inside the box `lo`..`hi`: a body past that is put back, and a
    /// body at it loses its velocity into the wall. Returns whether it touches a wall.
    pub fn keep_inside(&mut self, lo: DVec3, hi: DVec3, gap_m: f64) -> bool {
        let mut touching = false;
        for axis in 0..3 {
            let mut unit = DVec3::ZERO;
            unit[axis] = 1.0;
            let reach = self.half_extent_along(unit) + gap_m;
            let (low, high) = (lo[axis] + reach, hi[axis] - reach);
            if self.position_m[axis] <= low {
                self.position_m[axis] = low;
                self.velocity_m_s[axis] = self.velocity_m_s[axis].max(0.0);
                touching = true;
            } else if self.position_m[axis] >= high {
                self.position_m[axis] = high;
                self.velocity_m_s[axis] = self.velocity_m_s[axis].min(0.0);
                touching = true;
            }
        }
        touching
    }
}

/// The impulse per second (N, then N·m about `centre_m`) of the hydrostatic pressure
/// p_h(x) = ρ g·(x − centre) of a fluid of density `density_kg_m3` under `gravity_m_s2` on
/// the faces of body `index`: Σ_f J_fᵀ A_f p_h(x̄_f), with the face normals pointing into
/// the body. Exact for the force on the flat faces (p_h is linear); over a closed surface it
/// is the buoyancy −ρ V g of the carved volume V.
pub fn hydrostatic_wrench(
    mesh: &TetMesh,
    conditions: &[FaceCondition],
    index: u32,
    centre_m: DVec3,
    density_kg_m3: f64,
    gravity_m_s2: DVec3,
) -> Vector6<f64> {
    conditions
        .iter()
        .enumerate()
        .filter(|(_, c)| **c == FaceCondition::Rigid(index))
        .map(|(f, _)| {
            let centroid = mesh.faces[f].iter().map(|&i| mesh.nodes_m[i as usize]).sum::<DVec3>() / 3.0;
            let pressure = density_kg_m3 * gravity_m_s2.dot(centroid - centre_m);
            rigid_face_row(mesh, f, centre_m) * (mesh.face_area_m2[f] * pressure)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn mass_properties_match_the_textbook_solids() {
        // A 0.2 m ball of water: V = π/6 · 0.008 = 4.18879e-3 m³, I = 2/5 m r².
        let ball = RigidBody::new(RigidShape::Ball, 0.2, 1000.0, DVec3::ZERO, DVec3::ZERO);
        assert!((ball.mass_kg() - 4.188_790_2).abs() < 1e-6);
        assert!((ball.inertia_kg_m2() - 0.4 * ball.mass_kg() * 0.01).abs() < 1e-12);
        // A 0.5 m cube of 800 kg/m³: 100 kg, I = m s²/6.
        let cube = RigidBody::new(RigidShape::Cube, 0.5, 800.0, DVec3::ZERO, DVec3::ZERO);
        assert!((cube.mass_kg() - 100.0).abs() < 1e-9);
        assert!((cube.inertia_kg_m2() - 100.0 * 0.25 / 6.0).abs() < 1e-9);
        // Rotated 45° about y, the cube reaches s/√2 along x.
        let mut turned = cube;
        turned.orientation = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_4);
        assert!((turned.half_extent_along(DVec3::X) - 0.5 / 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn surfaces_are_closed_and_enclose_the_solid() {
        use super::super::mesher::{enclosed_volume_m3, open_edge};
        let mut cube = RigidBody::new(RigidShape::Cube, 0.3, 500.0, DVec3::new(1.0, 2.0, 3.0), DVec3::ZERO);
        cube.orientation = DQuat::from_rotation_z(0.3);
        let surface = cube.surface(0.04);
        assert_eq!(open_edge(&surface), None);
        assert!((enclosed_volume_m3(&surface) - 0.027).abs() < 1e-12);
        let longest = surface
            .triangles
            .iter()
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2])])
            .map(|(a, b)| (surface.positions_m[a as usize] - surface.positions_m[b as usize]).length())
            .fold(0.0, f64::max);
        assert!(longest <= 0.04 * 2f64.sqrt() + 1e-12, "{longest}");
        let ball = RigidBody::new(RigidShape::Ball, 0.3, 500.0, DVec3::ZERO, DVec3::ZERO).surface(0.03);
        assert_eq!(open_edge(&ball), None);
        // An inscribed polyhedron: a little under the sphere's π/6 · 0.027 m³.
        let v = enclosed_volume_m3(&ball);
        assert!(v < 0.014_137_2 && v > 0.97 * 0.014_137_2, "{v}");
    }

    #[test]
    fn a_body_stops_a_gap_short_of_the_walls() {
        let mut ball =
            RigidBody::new(RigidShape::Ball, 0.2, 500.0, DVec3::new(0.5, 0.05, 0.5), DVec3::new(1.0, -2.0, 0.0));
        assert!(ball.keep_inside(DVec3::ZERO, DVec3::ONE, 0.05));
        assert!((ball.position_m - DVec3::new(0.5, 0.15, 0.5)).length() < 1e-15);
        assert_eq!(ball.velocity_m_s, DVec3::new(1.0, 0.0, 0.0));
        // Moving away from the floor it is free again.
        ball.velocity_m_s.y = 1.0;
        ball.advance(0.1);
        assert!(!ball.keep_inside(DVec3::ZERO, DVec3::ONE, 0.05));
    }
}
