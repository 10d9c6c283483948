//! Rigid-body physics for simulated characters (issue 16, Faloutsos 2001), on rapier3d.
//!
//! We never integrate rigid bodies ourselves: rapier3d (f32, 3-D) does it, with
//! reduced-coordinate multibody joints (the figure is one articulation, so joints cannot
//! drift apart) and implicit PD motors. rapier's maths is glam 0.33; ours is glam 0.34, so
//! vectors and quaternions cross the boundary through [`to_rapier`] / [`from_rapier`] and
//! friends (plain arrays, no unsafe).
//!
//! Conventions as everywhere in kinegraph: metres, seconds, kilograms, radians, Y up,
//! right-handed. Gravity points along −Y.
//!
//! | concept | module |
//! |---|---|
//! | the world set-up: time step, solver, gravity, ground | this module |
//! | skeleton → articulated figure | [`figure`] |
//! | what the controllers sense (COM, support polygon, capture point) | [`state`] |
//! | the controller contract and the supervisor (Faloutsos 2001) | [`controller`] |
//! | the controllers: balance, protective step, protective fall, sit, rise, relax | [`controllers`] |
//! | a scripted run: pushes, requests, blow-up detection, clip out | [`simulate`] |
//! | pre-conditions learned from trials (SVM) | [`learned`] |
//! | a seat to sit on and rise from | [`seat`] |
//! | body shapes sized from the skinned mesh | [`skin_fit`] |

pub mod controller;
pub mod controllers;
pub mod figure;
pub mod learned;
pub mod seat;
pub mod simulate;
pub mod skin_fit;
pub mod state;

use rapier3d::prelude::*;

/// Standard gravity, m/s².
pub const STANDARD_GRAVITY_M_S2: f32 = 9.806_65;

/// The smallest and largest time steps the controllers are tuned for, seconds. Outside this
/// range a figure with stiff PD motors and contacts is not stable (or is needlessly slow).
pub const DT_RANGE_SECS: (f32, f32) = (1.0 / 2000.0, 1.0 / 60.0);

/// How the world is stepped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldParams {
    /// Time step, seconds (default 1/300 s: with 4 substeps a free fall is within 0.1 % of
    /// g·t²/2 after a second; rapier integrates by semi-implicit Euler).
    pub dt_secs: f32,
    /// Gravity along −Y, m/s² (default standard gravity).
    pub gravity_m_s2: f32,
    /// Solver iterations per step; rapier substeps the integration as many times (default 4).
    pub solver_iterations: usize,
    /// Projected Gauss–Seidel passes over the contacts and joints in each substep (default 1,
    /// rapier's). One pass lets static friction give a little every substep: a figure
    /// standing still under balance slides its feet 32–47 cm in 10 s. Four passes keep them
    /// within 1 cm for about 11 % more time per step; balance, the step and the fall work
    /// with either, the rise not yet with four (see the README).
    pub contact_iterations: usize,
}

impl Default for WorldParams {
    fn default() -> Self {
        WorldParams {
            dt_secs: 1.0 / 300.0,
            gravity_m_s2: STANDARD_GRAVITY_M_S2,
            solver_iterations: 4,
            contact_iterations: 1,
        }
    }
}

/// Why a simulation could not be set up or run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PhysicsError {
    /// The time step is outside [`DT_RANGE_SECS`].
    #[error("time step {dt_secs} s is outside the stable range {min}..={max} s")]
    UnstableTimeStep {
        /// The requested step, seconds.
        dt_secs: f32,
        /// Smallest allowed, seconds.
        min: f32,
        /// Largest allowed, seconds.
        max: f32,
    },
    /// Other bad set-up values.
    #[error("{0}")]
    BadParams(String),
}

/// A rapier world set up for characters: fixed step, deterministic (single thread, libm
/// maths through rapier's `enhanced-determinism`), no sleeping bodies.
pub struct World {
    /// rapier's world (bodies, colliders, joints, pipeline).
    pub inner: PhysicsWorld,
}

impl World {
    /// A world without bodies.
    pub fn new(params: WorldParams) -> Result<World, PhysicsError> {
        let (min, max) = DT_RANGE_SECS;
        if !(params.dt_secs.is_finite() && params.dt_secs >= min && params.dt_secs <= max) {
            return Err(PhysicsError::UnstableTimeStep { dt_secs: params.dt_secs, min, max });
        }
        if !(params.gravity_m_s2.is_finite() && (0.0..=100.0).contains(&params.gravity_m_s2)) {
            return Err(PhysicsError::BadParams(format!(
                "gravity {} m/s² must be within 0..=100",
                params.gravity_m_s2
            )));
        }
        if !(1..=64).contains(&params.solver_iterations) {
            return Err(PhysicsError::BadParams(format!(
                "solver iterations {} must be within 1..=64",
                params.solver_iterations
            )));
        }
        if !(1..=64).contains(&params.contact_iterations) {
            return Err(PhysicsError::BadParams(format!(
                "contact iterations {} must be within 1..=64",
                params.contact_iterations
            )));
        }
        let mut inner = PhysicsWorld::new();
        inner.gravity = Vector::new(0.0, -params.gravity_m_s2, 0.0);
        inner.integration_parameters.dt = params.dt_secs;
        inner.integration_parameters.num_solver_iterations = params.solver_iterations;
        inner.integration_parameters.num_internal_pgs_iterations = params.contact_iterations;
        Ok(World { inner })
    }

    /// The time step, seconds.
    pub fn dt_secs(&self) -> f32 {
        self.inner.integration_parameters.dt
    }

    /// Advances the world by one step.
    pub fn step(&mut self) {
        self.inner.step();
    }

    /// Removes rapier's default joint damping (0.1 per angular degree of freedom, the free
    /// root's included, which would slow a tumbling body down like air drag) from the
    /// articulation that `body` belongs to. The figure's PD motors do its damping.
    pub fn clear_articulation_damping(&mut self, body: RigidBodyHandle) {
        let Some(index) = self.inner.multibody_joints.rigid_body_link(body).map(|l| l.multibody) else { return };
        if let Some(mb) = self.inner.multibody_joints.get_multibody_mut(index) {
            mb.damping_mut().fill(0.0);
        }
    }

    /// Adds the ground: a fixed half-space below `y = height_m` with Coulomb `friction`.
    pub fn add_ground(&mut self, height_m: f32, friction: f32) -> RigidBodyHandle {
        let ground = ColliderBuilder::halfspace(nalgebra::Unit::new_unchecked(Vector::Y));
        self.add_fixed(ground, Pose::from_translation(Vector::new(0.0, height_m, 0.0)), friction)
    }

    /// Adds a fixed body at `pose` with `shape`, touching the figure as the ground does: its
    /// collision group, Coulomb `friction`, no restitution.
    pub fn add_fixed(&mut self, shape: ColliderBuilder, pose: Pose, friction: f32) -> RigidBodyHandle {
        let body = self.inner.bodies.insert(RigidBodyBuilder::fixed().pose(pose));
        let collider = shape.friction(friction).restitution(0.0).collision_groups(InteractionGroups::new(
            figure::GROUND_GROUP,
            Group::ALL,
            InteractionTestMode::And,
        ));
        self.inner.colliders.insert_with_parent(collider, body, &mut self.inner.bodies);
        body
    }
}

/// glam 0.34 → rapier vector.
#[inline]
pub fn to_rapier(v: glam::Vec3) -> Vector {
    Vector::from_array(v.to_array())
}

/// rapier vector → glam 0.34.
#[inline]
pub fn from_rapier(v: Vector) -> glam::Vec3 {
    glam::Vec3::from_array(v.to_array())
}

/// glam 0.34 quaternion → rapier rotation.
#[inline]
pub fn rot_to_rapier(q: glam::Quat) -> Rotation {
    Rotation::from_array(q.to_array())
}

/// rapier rotation → glam 0.34 quaternion.
#[inline]
pub fn rot_from_rapier(q: Rotation) -> glam::Quat {
    glam::Quat::from_array(q.to_array())
}

/// glam 0.34 rigid transform (rotation, translation) → rapier pose.
#[inline]
pub fn pose_to_rapier(rotation: glam::Quat, translation: glam::Vec3) -> Pose {
    Pose::from_parts(to_rapier(translation), rot_to_rapier(rotation))
}
