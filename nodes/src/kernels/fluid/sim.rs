//! The smoke simulation loop (Klingner et al. 2006, §3–6) over the kernels of this module:
//! per step, a new mesh of the domain minus the obstacles where they are at the end of the
//! step ([`super::remesh`]), the velocity and smoke traced back through the previous mesh,
//! sources and buoyancy, the obstacles' surface velocities as wall conditions, the pressure
//! projection, and the marker particles moved through the new field; per frame, the fields
//! resampled onto the output voxel grid.
//!
//! Dynamic rigid bodies ([`super::rigid`]) are obstacles that move by their own state: each
//! step a body moves by its velocity, is carved out of the new mesh, gets gravity and the
//! hydrostatic buoyancy, and its velocity is solved for with the pressure
//! ([`PressureSolver::with_bodies`]).
//!
//! Temperature is carried as the excess over ambient (K), so clear air is 0 everywhere.

use std::time::Instant;

use glam::{DVec3, IVec3};
use nalgebra::Vector6;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::mesh::{MeshError, MeshStats, TetMesh};
use super::mesher::Obstacle;
use super::projection::{FaceCondition, PressureSolver, ProjectionError, RigidCoupling, face_conditions};
use super::remesh::{Nodes, ObstacleDistance, mesh_nodes, place_nodes, solids, tet_vorticity};
use super::rigid::{RigidBody, hydrostatic_wrench};
use super::smoke::{Buoyancy, Transfer, add_buoyancy, node_values, total};
use super::velocity::{VelocityField, advect_velocity, momentum};
use crate::cancel::{Cancel, Cancelled};
use crate::model::volume::{FluidDomain, VolumeFrame, VolumeSequence, VoxelGrid};

/// An obstacle where it is at one instant, with the velocity of each surface vertex.
#[derive(Debug, Clone, PartialEq)]
pub struct MovingObstacle {
    /// The closed surface.
    pub surface: Obstacle,
    /// Velocity per vertex, m/s.
    pub velocity_m_s: Vec<DVec3>,
}

/// How to step and what to produce.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSettings {
    /// Output frames per second.
    pub fps: f64,
    /// Output frames (frame 0 is the initial state).
    pub frames: usize,
    /// Simulation steps per output frame.
    pub substeps: usize,
    /// Density of the air, kg/m³ (pressure scale only).
    pub air_density_kg_m3: f64,
    /// Largest distance, in smallest edge lengths, an obstacle's surface may move in one
    /// step before the step is refused as unstable (the mesh could not follow it).
    pub max_cells_per_step: f64,
    /// Seed of the particle emission.
    pub seed: u64,
}

/// Figures of one step, for the node's report.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StepReport {
    /// Step number, from 1.
    pub step: usize,
    /// Tets of the step's mesh.
    pub tets: usize,
    /// Smallest dihedral angle, degrees.
    pub min_dihedral_deg: f64,
    /// Largest radius–edge ratio.
    pub max_radius_edge_ratio: f64,
    /// Seconds placing nodes and meshing.
    pub mesh_s: f64,
    /// Seconds tracing back velocity and smoke onto the new mesh.
    pub advect_s: f64,
    /// Seconds assembling, factoring and applying the pressure projection.
    pub pressure_s: f64,
    /// The air's largest speed at the start of the step, in smallest edges per step: the
    /// semi-Lagrangian tracing stays stable beyond 1, but loses detail (the caller warns).
    pub fluid_cells_per_step: f64,
    /// Relative change of the smoke total by the transfer onto the new mesh (advection
    /// and remeshing together, before this step's sources).
    pub transfer_mass_change: f64,
    /// Momentum of the air at the end of the step, kg·m/s: ρ Σ V_t u_t over the per-tet
    /// velocities.
    pub air_momentum_kg_m_s: [f64; 3],
}

/// Dynamic rigid bodies and the gravity that pulls them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DynamicBodies {
    /// The bodies at time 0.
    pub bodies: Vec<RigidBody>,
    /// Gravity, m/s² (Y up: (0, −9.81, 0) on Earth).
    pub gravity_m_s2: DVec3,
}

/// What a run produces.
#[derive(Debug, Clone)]
pub struct SimOutput {
    /// The fields per output frame.
    pub volumes: VolumeSequence,
    /// Figures per step.
    pub steps: Vec<StepReport>,
    /// Every dynamic body's state per output frame (frame 0: the start).
    pub bodies: Vec<Vec<RigidBody>>,
}

/// Why a simulation stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The mesher failed or refused (too many tets) at a step.
    #[error("step {step}: {source}")]
    Mesh {
        /// Step number (0: the initial mesh).
        step: usize,
        /// What went wrong.
        source: MeshError,
    },
    /// The pressure solve failed at a step.
    #[error("step {step}: {source}")]
    Projection {
        /// Step number.
        step: usize,
        /// What went wrong.
        source: ProjectionError,
    },
    /// An obstacle moves too far in one step.
    #[error(
        "step {step}: an obstacle moves at up to {speed_m_s:.3} m/s, {cells:.1} smallest edges per step (at most {limit}): use more substeps or a larger minimum edge"
    )]
    Unstable {
        /// Step number.
        step: usize,
        /// Its largest speed.
        speed_m_s: f64,
        /// Distance per step in smallest edges.
        cells: f64,
        /// The limit.
        limit: f64,
    },
    /// The run was cancelled.
    #[error("cancelled")]
    Cancelled,
}

impl From<Cancelled> for SimError {
    fn from(_: Cancelled) -> Self {
        SimError::Cancelled
    }
}

/// The state between steps.
struct State {
    mesh: TetMesh,
    nodes: Nodes,
    face_velocity_m_s: Vec<f64>,
    density: Vec<f64>,
    heat_k: Vec<f64>,
    particles_m: Vec<DVec3>,
}

/// The voxel lattice covering the domain at `voxel_m`.
pub fn domain_grid(domain: &FluidDomain) -> VoxelGrid {
    let voxel = domain.voxel_m;
    let lo = DVec3::from(domain.min_m);
    let hi = DVec3::from(domain.max_m);
    let first = (lo / voxel).ceil().as_ivec3();
    let last = (hi / voxel).floor().as_ivec3();
    let dims = (last - first + IVec3::ONE).max(IVec3::ZERO);
    VoxelGrid { origin: first, dims: [dims.x as usize, dims.y as usize, dims.z as usize], voxel_m: voxel as f32 }
}

/// Builds one step's mesh: μ from the previous fields (if any), nodes warm-started from the
/// previous step's free nodes.
fn remesh(
    domain: &FluidDomain,
    obstacles: &[MovingObstacle],
    previous: Option<(&State, &VelocityField)>,
) -> Result<(TetMesh, Nodes), MeshError> {
    let (lo, hi) = (DVec3::from(domain.min_m), DVec3::from(domain.max_m));
    let surfaces: Vec<Obstacle> = obstacles.iter().map(|o| o.surface.clone()).collect();
    let sizing = domain.sizing;
    let distance = ObstacleDistance::new(&surfaces, sizing.max_edge_m);
    let (smoke_at_nodes, vorticity) = match previous {
        Some((state, field)) => {
            (node_values(&state.mesh, &state.density), tet_vorticity(&state.mesh, &field.node_velocity_m_s))
        }
        None => (Vec::new(), Vec::new()),
    };
    let mu = |p: DVec3| -> f64 {
        // d beyond the distance at which μ reaches its maximum does not matter.
        let d_limit = if sizing.kd > 0.0 { (sizing.max_edge_m - sizing.k0_m).max(0.0) / sizing.kd } else { 0.0 };
        let d = distance.at(p, d_limit.max(sizing.max_edge_m));
        let (s, w) = match previous {
            Some((state, field)) => match field.locator().locate(&state.mesh, p) {
                Some((t, l)) => {
                    let s: f64 = (0..4).map(|k| smoke_at_nodes[state.mesh.tets[t][k] as usize] * l[k]).sum();
                    (s, vorticity[t])
                }
                None => (0.0, 0.0),
            },
            None => (0.0, 0.0),
        };
        sizing.edge_m(d, s, w)
    };
    let warm: &[DVec3] = previous.map_or(&[], |(state, _)| &state.nodes.free);
    let mut nodes = place_nodes(lo, hi, &surfaces, warm, &sizing, &mu, domain.max_tets)?;
    let mesh = mesh_nodes(&mut nodes, &surfaces, domain.max_tets)?;
    Ok((mesh, nodes))
}

/// Whether boundary face `f` lies on the box's face `axis`/`side`.
fn on_box_face(mesh: &TetMesh, f: usize, lo: DVec3, hi: DVec3) -> Option<(usize, bool)> {
    let x = mesh.face_circumcentre_m[f];
    let eps = 1e-9 * (hi - lo).length();
    (0..3).find_map(|a| {
        if (x[a] - lo[a]).abs() < eps && mesh.face_normal[f][a].abs() > 0.99 {
            Some((a, false))
        } else if (x[a] - hi[a]).abs() < eps && mesh.face_normal[f][a].abs() > 0.99 {
            Some((a, true))
        } else {
            None
        }
    })
}

/// Boundary conditions and prescribed wall velocities of a mesh: box walls still, the top
/// open when asked, obstacle faces moving with the nearest obstacle vertex. Obstacles from
/// index `first_body` on are dynamic bodies: their faces are [`FaceCondition::Rigid`] (body
/// `index − first_body`), their velocities the solve's. In a closed box the other obstacles'
/// fluxes are balanced (their area-weighted mean removed) so the solve is consistent; a
/// body's rigid motion is balanced by construction.
fn boundary(
    domain: &FluidDomain,
    mesh: &TetMesh,
    obstacles: &[MovingObstacle],
    first_body: usize,
) -> (Vec<FaceCondition>, Vec<f64>) {
    let (lo, hi) = (DVec3::from(domain.min_m), DVec3::from(domain.max_m));
    let mut wall = vec![0.0; mesh.faces.len()];
    let mut obstacle_faces = Vec::new();
    let conditions = face_conditions(mesh, |f| match on_box_face(mesh, f, lo, hi) {
        Some((1, true)) if domain.open_top => FaceCondition::Open,
        Some(_) => FaceCondition::Wall,
        None => {
            let x = mesh.face_circumcentre_m[f];
            let nearest = obstacles
                .iter()
                .enumerate()
                .flat_map(|(i, o)| o.surface.positions_m.iter().zip(&o.velocity_m_s).map(move |(p, v)| (i, p, v)))
                .min_by(|a, b| (*a.1 - x).length_squared().total_cmp(&(*b.1 - x).length_squared()));
            wall[f] = nearest.map_or(0.0, |(_, _, v)| v.dot(mesh.face_normal[f]));
            match nearest {
                Some((i, _, _)) if i >= first_body => FaceCondition::Rigid((i - first_body) as u32),
                _ => {
                    obstacle_faces.push(f);
                    FaceCondition::Wall
                }
            }
        }
    });
    if !domain.open_top && !obstacle_faces.is_empty() {
        let area: f64 = obstacle_faces.iter().map(|&f| mesh.face_area_m2[f]).sum();
        let flux: f64 = obstacle_faces.iter().map(|&f| mesh.face_area_m2[f] * wall[f]).sum();
        obstacle_faces.iter().for_each(|&f| wall[f] -= flux / area);
    }
    (conditions, wall)
}

/// Resamples the state onto `grid`: 0 outside the box and inside obstacles.
fn sample_frame(
    grid: &VoxelGrid,
    state: &State,
    field: &VelocityField,
    obstacles: &[MovingObstacle],
    lo: DVec3,
    hi: DVec3,
    bodies: &[RigidBody],
) -> VolumeFrame {
    use rayon::prelude::*;
    let density_at_nodes = node_values(&state.mesh, &state.density);
    let heat_at_nodes = node_values(&state.mesh, &state.heat_k);
    let surfaces: Vec<Obstacle> = obstacles.iter().map(|o| o.surface.clone()).collect();
    let solids = solids(&surfaces);
    let samples: Vec<(f32, f32, [f32; 3])> = (0..grid.len())
        .into_par_iter()
        .map(|n| {
            let p = grid.centre_m(n).as_dvec3();
            if !(p.cmpge(lo).all() && p.cmple(hi).all()) || solids.iter().any(|s| s.contains(p)) {
                return (0.0, 0.0, [0.0; 3]);
            }
            let Some((t, l)) = field.locator().locate(&state.mesh, p) else { return (0.0, 0.0, [0.0; 3]) };
            let at = |values: &[f64]| (0..4).map(|k| values[state.mesh.tets[t][k] as usize] * l[k]).sum::<f64>();
            let v = field.sample(&state.mesh, p);
            (at(&density_at_nodes) as f32, at(&heat_at_nodes) as f32, v.as_vec3().to_array())
        })
        .collect();
    VolumeFrame {
        density: samples.iter().map(|s| s.0).collect(),
        temperature_k: samples.iter().map(|s| s.1).collect(),
        velocity_m_s: samples.iter().map(|s| s.2).collect(),
        particles_m: state.particles_m.iter().map(|p| p.as_vec3().to_array()).collect(),
        bodies: bodies.iter().map(RigidBody::pose).collect(),
    }
}

/// Runs the simulation: `obstacles_at(t)` gives the obstacles at time `t` (s);
/// `progress(done, total)` is called after every step, with that step's report.
pub fn simulate(
    domain: &FluidDomain,
    settings: &SimSettings,
    obstacles_at: &dyn Fn(f64) -> Vec<MovingObstacle>,
    cancel: Cancel<'_>,
    progress: &mut dyn FnMut(usize, usize, &StepReport),
) -> Result<(VolumeSequence, Vec<StepReport>), SimError> {
    let out = simulate_with_bodies(domain, settings, obstacles_at, &DynamicBodies::default(), cancel, progress)?;
    Ok((out.volumes, out.steps))
}

/// A body as an obstacle: its surface at the domain's smallest edge, moving rigidly.
fn body_obstacle(body: &RigidBody, edge_m: f64) -> MovingObstacle {
    let surface = body.surface(edge_m);
    let velocity_m_s = surface.positions_m.iter().map(|p| body.point_velocity(*p)).collect();
    MovingObstacle { surface, velocity_m_s }
}

/// [`simulate`] with dynamic rigid bodies, two-way coupled to the air. A body closer to a
/// box wall than the smallest edge starts moved back to that distance.
pub fn simulate_with_bodies(
    domain: &FluidDomain,
    settings: &SimSettings,
    obstacles_at: &dyn Fn(f64) -> Vec<MovingObstacle>,
    dynamic: &DynamicBodies,
    cancel: Cancel<'_>,
    progress: &mut dyn FnMut(usize, usize, &StepReport),
) -> Result<SimOutput, SimError> {
    let (lo, hi) = (DVec3::from(domain.min_m), DVec3::from(domain.max_m));
    let dt = 1.0 / (settings.fps * settings.substeps as f64);
    let buoyancy = Buoyancy { alpha: domain.buoyancy_alpha, beta: domain.buoyancy_beta, ambient_k: 0.0 };
    let grid = domain_grid(domain);
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
    let total_steps = settings.frames.saturating_sub(1) * settings.substeps;
    let (edge, gap) = (domain.sizing.min_edge_m, domain.sizing.min_edge_m);
    let air_density = settings.air_density_kg_m3;
    let mut bodies = dynamic.bodies.clone();
    bodies.iter_mut().for_each(|b| {
        b.keep_inside(lo, hi, gap);
    });
    // The kinematic obstacles at `time`, then the bodies where they are.
    let all_obstacles = |time: f64, bodies: &[RigidBody]| -> (Vec<MovingObstacle>, usize) {
        let mut obstacles = obstacles_at(time);
        let first_body = obstacles.len();
        obstacles.extend(bodies.iter().map(|b| body_obstacle(b, edge)));
        (obstacles, first_body)
    };

    let (obstacles, first_body) = all_obstacles(0.0, &bodies);
    let (mesh, nodes) = remesh(domain, &obstacles, None).map_err(|source| SimError::Mesh { step: 0, source })?;
    let n = mesh.tet_count();
    let mut state = State {
        face_velocity_m_s: boundary(domain, &mesh, &obstacles, first_body).1,
        density: vec![0.0; n],
        heat_k: vec![0.0; n],
        particles_m: Vec::new(),
        mesh,
        nodes,
    };
    let mut field = VelocityField::new(&state.mesh, &state.face_velocity_m_s);
    let mut frames = vec![sample_frame(&grid, &state, &field, &obstacles, lo, hi, &bodies)];
    let mut body_frames = vec![bodies.clone()];
    let mut reports = Vec::with_capacity(total_steps);
    for step in 1..=total_steps {
        cancel.check()?;
        let time = step as f64 * dt;
        for body in &mut bodies {
            body.advance(dt);
            body.keep_inside(lo, hi, gap);
        }
        let (obstacles, first_body) = all_obstacles(time, &bodies);
        let limit = settings.max_cells_per_step;
        let cell = domain.sizing.min_edge_m;
        let speed_m_s = obstacles.iter().flat_map(|o| &o.velocity_m_s).map(|v| v.length()).fold(0.0, f64::max);
        let cells = speed_m_s * dt / cell;
        if cells > limit {
            return Err(SimError::Unstable { step, speed_m_s, cells, limit });
        }
        let fluid_speed = field.node_velocity_m_s.iter().map(|v| v.length()).fold(0.0, f64::max);

        let clock = Instant::now();
        let (mesh, nodes) =
            remesh(domain, &obstacles, Some((&state, &field))).map_err(|source| SimError::Mesh { step, source })?;
        let mesh_s = clock.elapsed().as_secs_f64();
        cancel.check()?;

        let clock = Instant::now();
        let (conditions, wall) = boundary(domain, &mesh, &obstacles, first_body);
        let mut z = advect_velocity(&state.mesh, &field, &mesh, dt, |f| mesh.is_boundary(f));
        let before = total(&state.mesh, &state.density);
        let transfer = Transfer::new(&state.mesh, &field, &mesh, dt);
        let mut density = transfer.apply(&state.mesh, &state.density);
        let mut heat = transfer.apply(&state.mesh, &state.heat_k);
        let after = total(&mesh, &density);
        let advect_s = clock.elapsed().as_secs_f64();

        for source in &domain.sources {
            let centre = DVec3::from(source.centre_m);
            for t in 0..mesh.tet_count() {
                if (mesh.tet_centroid(t) - centre).length() < source.radius_m {
                    density[t] = density[t].max(source.density);
                    heat[t] = heat[t].max(source.temperature_k - domain.ambient_k);
                }
            }
        }
        add_buoyancy(&mesh, &mut z, &density, &heat, &buoyancy, dt, |f| !mesh.is_boundary(f));
        for (f, c) in conditions.iter().enumerate() {
            if *c == FaceCondition::Wall {
                z[f] = wall[f];
            }
        }
        let couplings: Vec<RigidCoupling> = bodies.iter().map(RigidBody::coupling).collect();
        let clock = Instant::now();
        let solver = PressureSolver::with_bodies(&mesh, &conditions, &couplings, air_density)
            .map_err(|source| SimError::Projection { step, source })?;
        // The bodies' velocities without the solved pressure: gravity and buoyancy.
        let mut body_velocity: Vec<Vector6<f64>> = bodies
            .iter()
            .enumerate()
            .map(|(i, body)| {
                let buoyancy = hydrostatic_wrench(
                    &mesh,
                    &conditions,
                    i as u32,
                    body.position_m,
                    air_density,
                    dynamic.gravity_m_s2,
                );
                let weight = dynamic.gravity_m_s2 * body.mass_kg();
                let impulse = (Vector6::new(weight.x, weight.y, weight.z, 0.0, 0.0, 0.0) + buoyancy) * dt;
                let mut free = *body;
                free.apply_impulse(&impulse);
                free.keep_inside(lo, hi, gap);
                free.generalised_velocity()
            })
            .collect();
        solver
            .project_with_bodies(&mesh, &mut z, &mut body_velocity, dt)
            .map_err(|source| SimError::Projection { step, source })?;
        let pressure_s = clock.elapsed().as_secs_f64();
        for (body, u) in bodies.iter_mut().zip(&body_velocity) {
            body.set_generalised_velocity(u);
            // At a wall the body stops; the air keeps the divergence-free solve.
            body.keep_inside(lo, hi, gap);
        }
        let new_field = VelocityField::new(&mesh, &z);
        let surfaces: Vec<Obstacle> = obstacles.iter().map(|o| o.surface.clone()).collect();
        let solids = solids(&surfaces);

        // Particles: midpoint rule through the new field; those leaving the fluid are dropped.
        let mut particles: Vec<DVec3> = state
            .particles_m
            .iter()
            .map(|p| {
                let mid = *p + new_field.sample(&mesh, *p) * (0.5 * dt);
                *p + new_field.sample(&mesh, mid) * dt
            })
            .filter(|p| p.cmpgt(lo).all() && p.cmplt(hi).all() && !solids.iter().any(|s| s.contains(*p)))
            .collect();
        for source in &domain.sources {
            let centre = DVec3::from(source.centre_m);
            for _ in 0..source.particles_per_step {
                let offset = loop {
                    let q = DVec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
                    if q.length_squared() <= 1.0 {
                        break q * source.radius_m;
                    }
                };
                particles.push(centre + offset);
            }
        }

        let stats: MeshStats = mesh.stats();
        let report = StepReport {
            step,
            tets: stats.tet_count,
            min_dihedral_deg: stats.min_dihedral_deg,
            max_radius_edge_ratio: stats.max_radius_edge_ratio,
            mesh_s,
            advect_s,
            pressure_s,
            fluid_cells_per_step: fluid_speed * dt / domain.sizing.min_edge_m,
            transfer_mass_change: if before > 0.0 { (after - before) / before } else { 0.0 },
            air_momentum_kg_m_s: momentum(&mesh, &new_field.tet_velocity_m_s, air_density).to_array(),
        };
        state = State { mesh, nodes, face_velocity_m_s: z, density, heat_k: heat, particles_m: particles };
        field = new_field;
        if step % settings.substeps == 0 {
            frames.push(sample_frame(&grid, &state, &field, &obstacles, lo, hi, &bodies));
            body_frames.push(bodies.clone());
        }
        progress(step, total_steps, &report);
        reports.push(report);
    }
    Ok(SimOutput { volumes: VolumeSequence { grid, fps: settings.fps, frames }, steps: reports, bodies: body_frames })
}
