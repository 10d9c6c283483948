//! Smoke around animated characters (issue 17, Klingner et al. 2006): `fluid.domain`,
//! `fluid.simulate` over [`crate::kernels::fluid::sim`] (with dynamic balls and boxes
//! two-way coupled to the air), and the exports `export.vdb` (OpenVDB grids per frame) and
//! `export.points` (PLY particles per frame).

use std::sync::Arc;

use glam::DVec3;

use crate::formats::ply::write_points_ply;
use crate::formats::vdb::{GridValues, VdbGrid, write_vdb};
use crate::kernels::fluid::mesh::MeshError;
use crate::kernels::fluid::mesher::{Obstacle, open_edge};
use crate::kernels::fluid::rigid::{GRAVITY_M_S2, RigidBody, RigidShape};
use crate::kernels::fluid::sim::{DynamicBodies, MovingObstacle, SimError, SimSettings, simulate_with_bodies};
use crate::model::choice::choices;
use crate::model::volume::{FluidDomain, Sizing, SmokeSource, VolumeFrame, VolumeSequence, VoxelGrid, y_up_to_z_up};
use crate::model::{Curves, Mesh, MeshSequence};
use crate::node::{
    ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, OutputPathParam,
    Registry, Report, TextParam, report_of,
};

/// Registers the fluid nodes and their exports.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Domain));
    registry.add(Box::new(Simulate));
    registry.add(Box::new(ExportVdb));
    registry.add(Box::new(ExportPoints));
}

const SIZE_X: FloatParam = FloatParam::new("size_x", "Box width along x, centred on x = 0.", 2.0, 0.05, 100.0, "m");
const SIZE_Y: FloatParam = FloatParam::new("size_y", "Box height, from the ground (y = 0) up.", 2.5, 0.05, 100.0, "m");
const SIZE_Z: FloatParam = FloatParam::new("size_z", "Box depth along z, centred on z = 0.", 2.0, 0.05, 100.0, "m");
const MIN_EDGE: FloatParam = FloatParam::new(
    "min_edge",
    "k0 of the sizing field: tet edge length at an obstacle in clear, still air (the finest detail).",
    0.08,
    0.002,
    10.0,
    "m",
);
const EDGE_GROWTH: FloatParam = FloatParam::new(
    "edge_growth",
    "kd: how fast tets grow with distance from the obstacles (m per m).",
    0.5,
    0.0,
    100.0,
    "",
);
const SMOKE_REFINE: FloatParam = FloatParam::new(
    "smoke_refine",
    "ks: edge length change per unit smoke density (negative refines where there is smoke).",
    -0.1,
    -100.0,
    100.0,
    "m",
);
const SWIRL_REFINE: FloatParam = FloatParam::new(
    "swirl_refine",
    "kω: edge length change per unit vorticity, 1/s (negative refines where the air swirls).",
    -0.005,
    -100.0,
    100.0,
    "m·s",
);
const MAX_EDGE: FloatParam = FloatParam::new("max_edge", "Largest tet edge length.", 0.3, 0.002, 100.0, "m");
const MAX_TETS: IntParam =
    IntParam::new("max_tets", "Refuse a step whose mesh needs more tetrahedra than this.", 200_000, 100, 50_000_000);
choices! {
    /// Whether the box's top lets smoke out.
    enum Top { Open = "open", Closed = "closed" }
}
const TOP: ChoiceParam<Top> = ChoiceParam::new("top", "Whether smoke can leave through the top of the box.", "open");
const SOURCE_X: FloatParam = FloatParam::new("source_x", "Smoke source centre, x.", 0.0, -100.0, 100.0, "m");
const SOURCE_Y: FloatParam = FloatParam::new("source_y", "Smoke source centre, y.", 0.3, -100.0, 100.0, "m");
const SOURCE_Z: FloatParam = FloatParam::new("source_z", "Smoke source centre, z.", 0.0, -100.0, 100.0, "m");
const SOURCE_RADIUS: FloatParam =
    FloatParam::new("source_radius", "Smoke source radius (0: no source).", 0.2, 0.0, 100.0, "m");
const SOURCE_DENSITY: FloatParam =
    FloatParam::new("source_density", "Smoke density inside the source.", 1.0, 0.0, 1000.0, "kg/m³");
const SOURCE_TEMPERATURE: FloatParam =
    FloatParam::new("source_temperature", "Temperature inside the source.", 333.15, 1.0, 5000.0, "K");
const PARTICLES: IntParam =
    IntParam::new("particles_per_step", "Marker particles the source seeds every step.", 40, 0, 100_000);
const ALPHA: FloatParam =
    FloatParam::new("smoke_weight", "Buoyancy α: downward pull per unit smoke density.", 0.1, 0.0, 100.0, "m/s²");
const BETA: FloatParam =
    FloatParam::new("heat_lift", "Buoyancy β: upward push per kelvin above ambient.", 0.05, 0.0, 100.0, "m/s²/K");
const AMBIENT: FloatParam = FloatParam::new("ambient", "Air temperature.", 293.15, 1.0, 5000.0, "K");
const VOXEL: FloatParam =
    FloatParam::new("voxel", "Voxel edge of the output volumes (VDB grids).", 0.05, 0.001, 10.0, "m");
const DOMAIN_OUT: Output<Arc<FluidDomain>> = Output::new("domain", "The box, its mesh sizing and its smoke source.");

/// `fluid.domain`.
pub struct Domain;

static DOMAIN: NodeSchema = NodeSchema {
    kind: "fluid.domain",
    category: "fluid",
    doc: "A box of air for fluid.simulate: its size (on the ground, centred on x = z = 0), how fine the tetrahedral mesh is (the sizing field μ = min_edge + edge_growth·distance + smoke_refine·smoke + swirl_refine·vorticity, between min_edge and max_edge), a smoke source and the buoyancy.",
    inputs: &[],
    outputs: &[DOMAIN_OUT.spec()],
    params: &[
        SIZE_X.0,
        SIZE_Y.0,
        SIZE_Z.0,
        MIN_EDGE.0,
        EDGE_GROWTH.0,
        SMOKE_REFINE.0,
        SWIRL_REFINE.0,
        MAX_EDGE.0,
        MAX_TETS.0,
        TOP.0,
        SOURCE_X.0,
        SOURCE_Y.0,
        SOURCE_Z.0,
        SOURCE_RADIUS.0,
        SOURCE_DENSITY.0,
        SOURCE_TEMPERATURE.0,
        PARTICLES.0,
        ALPHA.0,
        BETA.0,
        AMBIENT.0,
        VOXEL.0,
    ],
    writes_files: false,
    version: 1,
};

impl Node for Domain {
    fn schema(&self) -> &'static NodeSchema {
        &DOMAIN
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let size = DVec3::new(ctx.float(&SIZE_X)?, ctx.float(&SIZE_Y)?, ctx.float(&SIZE_Z)?);
        let (min_edge, max_edge) = (ctx.float(&MIN_EDGE)?, ctx.float(&MAX_EDGE)?);
        if max_edge < min_edge {
            return Err(NodeError::param(MAX_EDGE.0.name, format!("{max_edge} m is below min_edge {min_edge} m")));
        }
        if min_edge > 0.5 * size.min_element() {
            return Err(NodeError::param(
                MIN_EDGE.0.name,
                format!(
                    "{min_edge} m leaves fewer than 2 tets across the box's smallest side ({} m)",
                    size.min_element()
                ),
            ));
        }
        let min_m = [-0.5 * size.x, 0.0, -0.5 * size.z];
        let max_m = [0.5 * size.x, size.y, 0.5 * size.z];
        let radius = ctx.float(&SOURCE_RADIUS)?;
        let sources = if radius > 0.0 {
            vec![SmokeSource {
                centre_m: [ctx.float(&SOURCE_X)?, ctx.float(&SOURCE_Y)?, ctx.float(&SOURCE_Z)?],
                radius_m: radius,
                density: ctx.float(&SOURCE_DENSITY)?,
                temperature_k: ctx.float(&SOURCE_TEMPERATURE)?,
                particles_per_step: ctx.int(&PARTICLES)? as usize,
            }]
        } else {
            Vec::new()
        };
        let voxel = ctx.float(&VOXEL)?;
        let voxels = (size / voxel).ceil();
        ctx.reserve_memory((voxels.x * voxels.y * voxels.z * 20.0) as u64, VOXEL.0.name)?;
        let domain = FluidDomain {
            min_m,
            max_m,
            sizing: Sizing {
                k0_m: min_edge,
                kd: ctx.float(&EDGE_GROWTH)?,
                ks_m: ctx.float(&SMOKE_REFINE)?,
                kw_m_s: ctx.float(&SWIRL_REFINE)?,
                min_edge_m: min_edge,
                max_edge_m: max_edge,
            },
            max_radius_edge_ratio: 2.0,
            max_tets: ctx.int(&MAX_TETS)? as usize,
            open_top: ctx.choice(&TOP)? == Top::Open,
            sources,
            buoyancy_alpha: ctx.float(&ALPHA)?,
            buoyancy_beta: ctx.float(&BETA)?,
            ambient_k: ctx.float(&AMBIENT)?,
            voxel_m: voxel,
        };
        ctx.set_output(&DOMAIN_OUT, Arc::new(domain));
        Ok(())
    }
}

const DOMAIN_IN: Input<Arc<FluidDomain>> = Input::required("domain", "The box of air (fluid.domain).");
const MOVING_IN: Input<Arc<MeshSequence>> = Input::optional(
    "obstacle",
    "A moving obstacle: a closed mesh per frame (skin.deform), its vertex velocities the boundary condition. It may touch the box's walls (a character standing on the floor) or cross them by up to half the smallest edge; what lies beyond is cut off.",
);
const STATIC_IN: Input<Arc<Mesh>> = Input::optional(
    "static_obstacle",
    "A closed mesh that stays still; like the moving obstacle, it may touch the walls or cross them by up to half the smallest edge.",
);
const FRAMES: IntParam = IntParam::optional(
    "frames",
    "Frames to simulate (default: the obstacle sequence's frame count, else 48).",
    1,
    100_000,
);
const FPS: FloatParam =
    FloatParam::optional("fps", "Output frame rate (default: the obstacle sequence's, else 24).", 1.0, 1000.0, "fps");
const SUBSTEPS: IntParam = IntParam::new("substeps", "Simulation steps per output frame.", 2, 1, 1000);
const MAX_CELLS: FloatParam = FloatParam::new(
    "max_cells_per_step",
    "Refuse steps in which an obstacle moves more than this many smallest edges (min_edge); warn when the air does.",
    3.0,
    0.1,
    100.0,
    "",
);
const SEED: IntParam = IntParam::new("seed", "Seed of the particle emission.", 1, 0, i64::MAX);
const BODIES: TextParam = TextParam::new(
    "bodies",
    "Dynamic rigid bodies pushed by the air and pushing it, separated by `;`: `ball size=0.3 density=0.6 at=0,0.5,0` \
     (size: diameter, m; density: kg/m³, air is 1.2; at: centre, m; optional velocity=x,y,z m/s and spin=x,y,z rad/s), \
     or `box …` for a cube of edge `size`. Each must fit inside the domain with min_edge to spare.",
    "",
);
const GRAVITY: FloatParam = FloatParam::new(
    "gravity",
    "Pull on the bodies, downwards (the air's own weight is balanced by its pressure and buoys them).",
    GRAVITY_M_S2,
    0.0,
    100.0,
    "m/s²",
);
const VOLUMES_OUT: Output<Arc<VolumeSequence>> =
    Output::new("volumes", "Density, temperature and velocity per frame on the domain's voxel grid, and particles.");
const REPORT_OUT: Output<Arc<Report>> = Output::new(
    "report",
    "Per step: tet count, mesh quality, timings (mesh, advect, pressure), smoke transfer; per body: mass, start, end, top speed, first frame at a wall.",
);
const BODIES_OUT: Output<Arc<Curves>> = Output::new(
    "bodies",
    "Per frame and body (ball1, box2, … in the order of `bodies`): NAME.x/.y/.z centre (m), NAME.vx/.vy/.vz velocity (m/s), NAME.rx/.ry/.rz rotation vector (rad).",
);

/// `fluid.simulate`.
pub struct Simulate;

static SIMULATE: NodeSchema = NodeSchema {
    kind: "fluid.simulate",
    category: "fluid",
    doc: "Smoke in a box around moving or still obstacles (Klingner et al. 2006): a new tetrahedral mesh every step, refined near the obstacles, in smoke and in swirls; the obstacle's surface velocity pushes the air. Balls and boxes listed in `bodies` fall or rise by their weight, the air's buoyancy and its push, and push it back (solved with the pressure). Output: volumes per frame for export.vdb and particles for export.points, the bodies' paths as curves. Seconds and metres; stops cleanly on Ctrl-C.",
    inputs: &[DOMAIN_IN.spec(), MOVING_IN.spec(), STATIC_IN.spec()],
    outputs: &[VOLUMES_OUT.spec(), REPORT_OUT.spec(), BODIES_OUT.spec()],
    params: &[FRAMES.0, FPS.0, SUBSTEPS.0, MAX_CELLS.0, SEED.0, BODIES.0, GRAVITY.0],
    writes_files: false,
    version: 4,
};

/// A body's name in curves and reports: its shape and 1-based place in `bodies`.
fn body_name(index: usize, body: &RigidBody) -> String {
    let shape = match body.shape {
        RigidShape::Ball => "ball",
        RigidShape::Cube => "box",
    };
    format!("{shape}{}", index + 1)
}

/// Parses `x,y,z` (finite numbers).
fn parse_vector(text: &str) -> Option<DVec3> {
    let parts: Vec<f64> = text.split(',').map(|p| p.trim().parse::<f64>()).collect::<Result<_, _>>().ok()?;
    match parts[..] {
        [x, y, z] if x.is_finite() && y.is_finite() && z.is_finite() => Some(DVec3::new(x, y, z)),
        _ => None,
    }
}

/// Parses the `bodies` text (see [`BODIES`]) and checks every body fits inside `domain`
/// with a smallest edge to spare; the message names the body.
fn parse_bodies(text: &str, domain: &FluidDomain) -> Result<Vec<RigidBody>, String> {
    let (lo, hi) = (DVec3::from(domain.min_m), DVec3::from(domain.max_m));
    let gap = domain.sizing.min_edge_m;
    let mut bodies = Vec::new();
    for (index, entry) in text.split(';').map(str::trim).filter(|e| !e.is_empty()).enumerate() {
        let n = index + 1;
        let mut words = entry.split_whitespace();
        let shape = match words.next() {
            Some("ball") => RigidShape::Ball,
            Some("box") => RigidShape::Cube,
            other => return Err(format!("body {n}: starts with {other:?}, not `ball` or `box`")),
        };
        let (mut size, mut density, mut at) = (None, None, None);
        let (mut velocity, mut spin) = (DVec3::ZERO, DVec3::ZERO);
        for word in words {
            let (key, value) = word.split_once('=').ok_or_else(|| format!("body {n}: `{word}` is not key=value"))?;
            let number = || value.parse::<f64>().ok().filter(|v| v.is_finite());
            let vector = || parse_vector(value).ok_or_else(|| format!("body {n}: {key}={value} is not x,y,z"));
            match key {
                "size" => size = Some(number().ok_or_else(|| format!("body {n}: size={value} is not a number"))?),
                "density" => {
                    density = Some(number().ok_or_else(|| format!("body {n}: density={value} is not a number"))?)
                }
                "at" => at = Some(vector()?),
                "velocity" => velocity = vector()?,
                "spin" => spin = vector()?,
                _ => {
                    return Err(format!("body {n}: unknown key `{key}` (size, density, at, velocity, spin)"));
                }
            }
        }
        let size = size.ok_or_else(|| format!("body {n}: give its size=… in metres"))?;
        let density = density.ok_or_else(|| format!("body {n}: give its density=… in kg/m³"))?;
        let at = at.ok_or_else(|| format!("body {n}: give its centre at=x,y,z in metres"))?;
        if size <= 0.0 {
            return Err(format!("body {n}: size {size} m must be above 0"));
        }
        if density <= 0.0 {
            return Err(format!("body {n}: density {density} kg/m³ must be above 0"));
        }
        let mut body = RigidBody::new(shape, size, density, at, velocity);
        body.angular_velocity_rad_s = spin;
        let reach = DVec3::new(
            body.half_extent_along(DVec3::X),
            body.half_extent_along(DVec3::Y),
            body.half_extent_along(DVec3::Z),
        ) + gap;
        if !((at - reach).cmpge(lo).all() && (at + reach).cmple(hi).all()) {
            return Err(format!(
                "body {n} ({}, {size} m across at {at} m) does not fit inside the domain box {lo} .. {hi} m with min_edge {gap} m to spare: move it or enlarge the fluid.domain",
                body_name(index, &body)
            ));
        }
        bodies.push(body);
    }
    Ok(bodies)
}

/// The triangles with coincident vertices (within 1 µm in the rest mesh) joined: meshes
/// that split vertices for flat shading or seams (the mannequin's boxes) are closed
/// surfaces geometrically but not by index.
fn welded(rest: &[glam::Vec3], triangles: &[[u32; 3]]) -> Vec<[u32; 3]> {
    let mut first: std::collections::BTreeMap<[i64; 3], u32> = std::collections::BTreeMap::new();
    let representative: Vec<u32> = rest
        .iter()
        .enumerate()
        .map(|(i, p)| *first.entry((p.as_dvec3() * 1e6).round().as_i64vec3().to_array()).or_insert(i as u32))
        .collect();
    triangles.iter().map(|t| t.map(|i| representative.get(i as usize).copied().unwrap_or(i))).collect()
}

/// The closed-surface and inside-the-box checks of one obstacle input, naming the port. An
/// obstacle may touch the walls or cross them by up to half the smallest edge (a character
/// standing on the floor: its soles lie on it, a hair under it after skinning's rounding);
/// the mesher leaves out what is beyond.
fn check_surface(
    port: &'static str,
    triangles: &[[u32; 3]],
    frames: &mut dyn Iterator<Item = (usize, &[glam::Vec3])>,
    domain: &FluidDomain,
) -> Result<(), NodeError> {
    let (lo, hi) = (DVec3::from(domain.min_m), DVec3::from(domain.max_m));
    let tolerance = 0.5 * domain.sizing.min_edge_m;
    let surface = Obstacle { positions_m: Vec::new(), triangles: triangles.to_vec() };
    if let Some(edge) = open_edge(&surface) {
        return Err(NodeError::input(
            port,
            format!(
                "is not a closed surface (edge {edge:?} has no opposite twin): the air would leak through it; close the mesh"
            ),
        ));
    }
    let inside = |p: &glam::Vec3| {
        let p = p.as_dvec3();
        p.cmpge(lo - tolerance).all() && p.cmple(hi + tolerance).all()
    };
    for (frame, positions) in frames {
        if let Some((v, p)) = positions.iter().enumerate().find(|(_, p)| !inside(p)) {
            return Err(NodeError::input(
                port,
                format!(
                    "reaches outside the domain box {lo} .. {hi} m (by more than half the smallest edge, {tolerance} m) at frame {frame} (vertex {v} at {p} m): enlarge the fluid.domain or move the obstacle"
                ),
            ));
        }
    }
    Ok(())
}

impl Node for Simulate {
    fn schema(&self) -> &'static NodeSchema {
        &SIMULATE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let domain = ctx.input(&DOMAIN_IN)?;
        let moving = ctx.optional_input(&MOVING_IN)?;
        let still = ctx.optional_input(&STATIC_IN)?;
        let sequence_fps = moving.as_ref().map(|s| s.clip.fps());
        let fps = ctx.optional_float(&FPS)?.or(sequence_fps).unwrap_or(24.0);
        let frames = match ctx.optional_int(&FRAMES)? {
            Some(f) => f as usize,
            None => moving.as_ref().map_or(48, |s| s.frame_count()),
        };
        let substeps = ctx.int(&SUBSTEPS)? as usize;
        let moving_triangles = moving.as_ref().map(|s| welded(&s.rest.positions, &s.rest.triangles));
        let still_triangles = still.as_ref().map(|m| welded(&m.positions, &m.triangles));
        if let (Some(seq), Some(triangles)) = (&moving, &moving_triangles) {
            let mut all = (0..seq.frame_count()).map(|f| (f, seq.frame_positions(f)));
            check_surface(MOVING_IN.name(), triangles, &mut all, &domain)?;
        }
        if let (Some(mesh), Some(triangles)) = (&still, &still_triangles) {
            check_surface(STATIC_IN.name(), triangles, &mut std::iter::once((0, &mesh.positions[..])), &domain)?;
        }
        let bodies = parse_bodies(ctx.text_param(&BODIES)?, &domain).map_err(|e| NodeError::param(BODIES.0.name, e))?;
        let voxels = crate::kernels::fluid::sim::domain_grid(&domain).len() as u64;
        ctx.reserve_memory(voxels.saturating_mul(20).saturating_mul(frames as u64), FRAMES.0.name)?;

        let still_obstacle = still.as_ref().zip(still_triangles).map(|(m, triangles)| MovingObstacle {
            surface: Obstacle { positions_m: m.positions.iter().map(|p| p.as_dvec3()).collect(), triangles },
            velocity_m_s: vec![DVec3::ZERO; m.positions.len()],
        });
        let obstacles_at = |time_s: f64| -> Vec<MovingObstacle> {
            let mut all: Vec<MovingObstacle> = still_obstacle.iter().cloned().collect();
            if let (Some(seq), Some(seq_fps), Some(triangles)) = (&moving, sequence_fps, &moving_triangles) {
                let last = seq.frame_count().saturating_sub(1);
                let at = (time_s * seq_fps).clamp(0.0, last as f64);
                let f0 = (at.floor() as usize).min(last);
                let f1 = (f0 + 1).min(last);
                let w = at - f0 as f64;
                let (p0, p1) = (seq.frame_positions(f0), seq.frame_positions(f1));
                all.push(MovingObstacle {
                    surface: Obstacle {
                        positions_m: p0.iter().zip(p1).map(|(a, b)| a.as_dvec3().lerp(b.as_dvec3(), w)).collect(),
                        triangles: triangles.clone(),
                    },
                    velocity_m_s: if f1 > f0 {
                        p0.iter().zip(p1).map(|(a, b)| (b.as_dvec3() - a.as_dvec3()) * seq_fps).collect()
                    } else {
                        vec![DVec3::ZERO; p0.len()]
                    },
                });
            }
            all
        };
        let settings = SimSettings {
            fps,
            frames,
            substeps,
            air_density_kg_m3: 1.2,
            max_cells_per_step: ctx.float(&MAX_CELLS)?,
            seed: ctx.int(&SEED)? as u64,
        };
        let cancel = ctx.cancel();
        let mut on_step = |done: usize, total: usize, _: &crate::kernels::fluid::sim::StepReport| {
            ctx.progress(done as f32 / total.max(1) as f32);
        };
        let dynamic = DynamicBodies { bodies, gravity_m_s2: DVec3::NEG_Y * ctx.float(&GRAVITY)? };
        let result = simulate_with_bodies(&domain, &settings, &obstacles_at, &dynamic, cancel, &mut on_step);
        let out = result.map_err(|e| match e {
            SimError::Cancelled => NodeError::Cancelled,
            SimError::Unstable { .. } => NodeError::param(SUBSTEPS.0.name, format!("is too small: {e}")),
            SimError::Mesh { step, source: MeshError::TooManyTets { tets, max_tets } } => NodeError::input(
                DOMAIN_IN.name(),
                format!(
                    "step {step}: the mesh needs about {tets} tetrahedra, more than the domain's max_tets = {max_tets}: raise max_tets or min_edge"
                ),
            ),
            other => NodeError::kernel(other),
        })?;
        let (volumes, steps) = (out.volumes, out.steps);
        let curves = body_curves(&out.bodies, fps).map_err(NodeError::kernel)?;
        let limit = settings.max_cells_per_step;
        let fast: Vec<usize> = steps.iter().filter(|s| s.fluid_cells_per_step > limit).map(|s| s.step).collect();
        if let (Some(first), Some(worst)) =
            (fast.first(), steps.iter().map(|s| s.fluid_cells_per_step).reduce(f64::max))
        {
            ctx.warn(format!(
                "the air moved more than {limit} smallest edges per step in {} steps (from step {first}; at most {worst:.1}): the tracing stays stable but blurs; more substeps keep detail",
                fast.len()
            ));
        }
        let sum = |f: fn(&crate::kernels::fluid::sim::StepReport) -> f64| steps.iter().map(f).sum::<f64>();
        let worst_transfer = steps.iter().map(|s| s.transfer_mass_change.abs()).fold(0.0, f64::max);
        // Wall-clock seconds go under "timings", which regression expectations leave out.
        let per_step: Vec<serde_json::Value> = steps
            .iter()
            .map(|s| {
                serde_json::json!({
                    "step": s.step,
                    "tets": s.tets,
                    "min_dihedral_deg": s.min_dihedral_deg,
                    "max_radius_edge_ratio": s.max_radius_edge_ratio,
                    "fluid_cells_per_step": s.fluid_cells_per_step,
                    "transfer_mass_change": s.transfer_mass_change,
                })
            })
            .collect();
        let mut report = serde_json::json!({
            "steps": steps.len(),
            "frames": volumes.frames.len(),
            "dt_s": 1.0 / (fps * substeps as f64),
            "tets_max": steps.iter().map(|s| s.tets).max().unwrap_or(0),
            "min_dihedral_deg": steps.iter().map(|s| s.min_dihedral_deg).fold(f64::INFINITY, f64::min),
            "max_radius_edge_ratio": steps.iter().map(|s| s.max_radius_edge_ratio).fold(0.0, f64::max),
            "worst_transfer_mass_change": worst_transfer,
            "per_step": per_step,
            "timings": {
                "mesh_s": sum(|s| s.mesh_s),
                "advect_s": sum(|s| s.advect_s),
                "pressure_s": sum(|s| s.pressure_s),
                "per_step_mesh_advect_pressure_s": steps.iter().map(|s| [s.mesh_s, s.advect_s, s.pressure_s]).collect::<Vec<_>>(),
            },
        });
        if !dynamic.bodies.is_empty() {
            report["bodies"] = body_report(&out.bodies, &domain);
        }
        ctx.set_output(&REPORT_OUT, report_of(report));
        ctx.set_output(&VOLUMES_OUT, Arc::new(volumes));
        ctx.set_output(&BODIES_OUT, Arc::new(curves));
        Ok(())
    }
}

/// The bodies' paths per frame (`frames[frame][body]`) as curves at `fps`.
fn body_curves(frames: &[Vec<RigidBody>], fps: f64) -> Result<Curves, crate::model::curves::CurvesError> {
    let mut curves = Curves::new(fps, frames.len());
    let Some(first) = frames.first() else { return Ok(curves) };
    for (i, body) in first.iter().enumerate() {
        let name = body_name(i, body);
        let channel = |f: &dyn Fn(&RigidBody) -> f64| frames.iter().map(|bodies| f(&bodies[i])).collect::<Vec<f64>>();
        for (axis, a) in ["x", "y", "z"].into_iter().enumerate() {
            curves.push(&format!("{name}.{a}"), "m", channel(&|b| b.position_m[axis]))?;
            curves.push(&format!("{name}.v{a}"), "m/s", channel(&|b| b.velocity_m_s[axis]))?;
            curves.push(&format!("{name}.r{a}"), "rad", channel(&|b| b.orientation.to_scaled_axis()[axis]))?;
        }
    }
    Ok(curves)
}

/// Per body: mass, where it started and ended, its top speed and the first frame it
/// touched a wall (it stops a smallest edge short of it).
fn body_report(frames: &[Vec<RigidBody>], domain: &FluidDomain) -> serde_json::Value {
    let (lo, hi) = (DVec3::from(domain.min_m), DVec3::from(domain.max_m));
    let count = frames.first().map_or(0, Vec::len);
    let bodies: Vec<serde_json::Value> = (0..count)
        .map(|i| {
            let (first, last) = (frames[0][i], frames[frames.len() - 1][i]);
            let at_wall = frames.iter().position(|bodies| {
                // keep_inside moves only a body past the limit: touching is being on it.
                let mut copy = bodies[i];
                copy.keep_inside(lo, hi, domain.sizing.min_edge_m)
            });
            serde_json::json!({
                "name": body_name(i, &first),
                "shape": first.shape,
                "size_m": first.size_m,
                "density_kg_m3": first.density_kg_m3,
                "mass_kg": first.mass_kg(),
                "start_m": first.position_m.to_array(),
                "end_m": last.position_m.to_array(),
                "end_velocity_m_s": last.velocity_m_s.to_array(),
                "top_speed_m_s": frames.iter().map(|b| b[i].velocity_m_s.length()).fold(0.0, f64::max),
                "first_frame_at_wall": at_wall,
            })
        })
        .collect();
    serde_json::Value::Array(bodies)
}

const VOLUMES_IN: Input<Arc<VolumeSequence>> = Input::required("volumes", "The smoke volumes (fluid.simulate).");
const VDB_FILE: OutputPathParam = OutputPathParam::new(
    "file",
    "Where to write, relative to the run's output folder; frame N goes to NAME_NNNN.vdb beside it.",
    "vdb",
    "smoke/smoke.vdb",
);
const PLY_FILE: OutputPathParam = OutputPathParam::new(
    "file",
    "Where to write, relative to the run's output folder; frame N goes to NAME_NNNN.ply beside it.",
    "ply",
    "smoke/particles.ply",
);
const LAST_FILE_OUT: Output<Arc<std::path::PathBuf>> =
    Output::new("file", "The last written file, relative to the output folder.");
choices! {
    /// The up axis of written volumes and particles.
    enum FileUp { Y = "y", Z = "z" }
}
const FILE_UP: ChoiceParam<FileUp> = ChoiceParam::new(
    "up_axis",
    "The axis that points up in the files: \"y\" as simulated (Houdini and most renderers); \"z\" for Blender, turned as its glTF importer turns a GLB ((x, y, z) → (x, −z, y)), so the smoke lines up with a character exported by export.glb.",
    "y",
);

/// Writes one file per frame of `volumes` (encoded by `encode`) beside the file named by
/// `param`, with progress, and outputs the last one written.
fn write_frames(
    ctx: &mut NodeContext<'_>,
    param: &OutputPathParam,
    volumes: &VolumeSequence,
    encode: impl Fn(&VolumeFrame) -> Vec<u8>,
) -> Result<(), NodeError> {
    let mut last = None;
    for (f, frame) in volumes.frames.iter().enumerate() {
        last = Some(ctx.write_output_frame(param, f, &encode(frame))?);
        ctx.progress((f + 1) as f32 / volumes.frames.len() as f32);
    }
    if let Some(path) = last {
        ctx.set_output(&LAST_FILE_OUT, Arc::new(path));
    }
    Ok(())
}

/// `export.vdb`.
pub struct ExportVdb;

static EXPORT_VDB: NodeSchema = NodeSchema {
    kind: "export.vdb",
    category: "io",
    doc: "Writes smoke volumes as OpenVDB files, one per frame (NAME_0000.vdb, …): float grids `density` and `temperature` (kelvin above ambient) and a vec3 grid `velocity` (m/s), on a uniform grid in metres, Y up (or Z up for Blender, see up_axis). Blender, Houdini and renderers load them as a sequence; Blender puts NAME_0000 on its frame 1 unless the volume's start frame is set to 0, where its glTF import starts an animation.",
    inputs: &[VOLUMES_IN.spec()],
    outputs: &[LAST_FILE_OUT.spec()],
    params: &[VDB_FILE.0, FILE_UP.0],
    writes_files: true,
    version: 1,
};

impl Node for ExportVdb {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_VDB
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let volumes = ctx.input(&VOLUMES_IN)?;
        let encode = |grid: &VoxelGrid, density: &[f32], temperature: &[f32], velocity: &[[f32; 3]]| {
            write_vdb(
                grid,
                &[
                    VdbGrid { name: "density", values: GridValues::Float(density) },
                    VdbGrid { name: "temperature", values: GridValues::Float(temperature) },
                    VdbGrid { name: "velocity", values: GridValues::Vec3(velocity) },
                ],
            )
        };
        match ctx.choice(&FILE_UP)? {
            FileUp::Y => write_frames(ctx, &VDB_FILE, &volumes, |frame| {
                encode(&volumes.grid, &frame.density, &frame.temperature_k, &frame.velocity_m_s)
            }),
            FileUp::Z => {
                let (grid, from) = volumes.grid.z_up();
                // Each turned voxel takes the value of the voxel `from` names.
                let gather = |values: &[f32]| -> Vec<f32> { from.iter().map(|&n| values[n]).collect() };
                write_frames(ctx, &VDB_FILE, &volumes, |frame| {
                    let velocity: Vec<[f32; 3]> = from.iter().map(|&n| y_up_to_z_up(frame.velocity_m_s[n])).collect();
                    encode(&grid, &gather(&frame.density), &gather(&frame.temperature_k), &velocity)
                })
            }
        }
    }
}

/// `export.points`.
pub struct ExportPoints;

static EXPORT_POINTS: NodeSchema = NodeSchema {
    kind: "export.points",
    category: "io",
    doc: "Writes the smoke's marker particles as binary PLY point clouds, one per frame (NAME_0000.ply, …), metres, Y up (or Z up, see up_axis).",
    inputs: &[VOLUMES_IN.spec()],
    outputs: &[LAST_FILE_OUT.spec()],
    params: &[PLY_FILE.0, FILE_UP.0],
    writes_files: true,
    version: 1,
};

impl Node for ExportPoints {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_POINTS
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let volumes = ctx.input(&VOLUMES_IN)?;
        match ctx.choice(&FILE_UP)? {
            FileUp::Y => write_frames(ctx, &PLY_FILE, &volumes, |frame| write_points_ply(&frame.particles_m, "Y")),
            FileUp::Z => write_frames(ctx, &PLY_FILE, &volumes, |frame| {
                let turned: Vec<[f32; 3]> = frame.particles_m.iter().map(|&p| y_up_to_z_up(p)).collect();
                write_points_ply(&turned, "Z")
            }),
        }
    }
}
