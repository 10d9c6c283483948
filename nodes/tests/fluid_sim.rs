//! The smoke simulation loop and its nodes (issue 17): remeshing by the sizing field keeps
//! the smoke (against the analytic integral of a Gaussian puff), air at rest under uniform
//! heat stays at rest (the hydrostatic balance), an obstacle moving through still air drags
//! the air next to it at its own speed (the no-through boundary condition), and bad input
//! is refused with errors naming the port, param or step. Coarse meshes: seconds in debug.
#![cfg(feature = "tetgen")]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed expect is a failed test

mod node_eval;

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use glam::DVec3;
use kinegraph_nodes::cancel::Cancel;
use kinegraph_nodes::kernels::fluid::mesh::MeshError;
use kinegraph_nodes::kernels::fluid::mesher::{Obstacle, enclosed_volume_m3};
use kinegraph_nodes::kernels::fluid::remesh::{carve, mesh_nodes, place_nodes};
use kinegraph_nodes::kernels::fluid::sim::{MovingObstacle, SimError, SimSettings, simulate};
use kinegraph_nodes::kernels::fluid::smoke::{advect_per_tet, total};
use kinegraph_nodes::kernels::fluid::velocity::VelocityField;
use kinegraph_nodes::model::Mesh;
use kinegraph_nodes::model::volume::{FluidDomain, Sizing, SmokeSource};
use kinegraph_nodes::node::{NodeError, NodeOutcome, ParamValue, Value};
use node_eval::eval_node;

fn sizing(k0: f64, max: f64) -> Sizing {
    Sizing { k0_m: k0, kd: 0.5, ks_m: 0.0, kw_m_s: 0.0, min_edge_m: k0, max_edge_m: max }
}

fn domain(open_top: bool, sources: Vec<SmokeSource>) -> FluidDomain {
    FluidDomain {
        min_m: [0.0; 3],
        max_m: [1.0; 3],
        sizing: sizing(0.1, 0.2),
        max_radius_edge_ratio: 2.0,
        max_tets: 200_000,
        open_top,
        sources,
        buoyancy_alpha: 0.1,
        buoyancy_beta: 0.05,
        ambient_k: 293.15,
        voxel_m: 0.1,
    }
}

fn settings(frames: usize) -> SimSettings {
    SimSettings { fps: 24.0, frames, substeps: 1, air_density_kg_m3: 1.2, max_cells_per_step: 3.0, seed: 3 }
}

fn still(obstacles: Vec<MovingObstacle>) -> impl Fn(f64) -> Vec<MovingObstacle> {
    move |_| obstacles.clone()
}

fn cube_at(centre: DVec3, half: f64, velocity: DVec3) -> MovingObstacle {
    let surface = Obstacle::cuboid(centre, DVec3::splat(half));
    let velocity_m_s = vec![velocity; surface.positions_m.len()];
    MovingObstacle { surface, velocity_m_s }
}

#[test]
fn smoke_mass_is_kept_across_sizing_field_remeshes() {
    let sigma: f64 = 0.1;
    let centre = DVec3::splat(0.5);
    let blob = |p: DVec3| (-(p - centre).length_squared() / (2.0 * sigma * sigma)).exp();
    // ∫ blob = (2π)^{3/2} σ³ (the box holds all but e^-12.5 of it).
    let analytic = (2.0 * std::f64::consts::PI).powf(1.5) * sigma.powi(3);
    // μ refined where there is smoke: 0.12 m in clear air down to 0.04 m in the puff.
    let s = Sizing { k0_m: 0.12, kd: 0.0, ks_m: -0.08, kw_m_s: 0.0, min_edge_m: 0.04, max_edge_m: 0.12 };
    let mu = move |p: DVec3| s.edge_m(0.0, blob(p), 0.0);
    let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
    let mut nodes = place_nodes(lo, hi, &[], &[], &s, &mu, 1_000_000).unwrap();
    let mut mesh = mesh_nodes(&mut nodes, &[], 1_000_000).unwrap();
    let mut free = nodes.free;
    let mut smoke: Vec<f64> = (0..mesh.tet_count()).map(|t| blob(mesh.tet_centroid(t))).collect();
    let start = total(&mesh, &smoke);
    eprintln!("sizing mesh: {:?}, mass {start:.6} vs analytic {analytic:.6}", mesh.stats());
    assert!((start - analytic).abs() < 0.03 * analytic, "{start} vs {analytic}");
    let mut worst: f64 = 0.0;
    let mut previous = start;
    for step in 1..=4 {
        let mut nodes = place_nodes(lo, hi, &[], &free, &s, &mu, 1_000_000).unwrap();
        let new = mesh_nodes(&mut nodes, &[], 1_000_000).unwrap();
        let still = VelocityField::new(&mesh, &vec![0.0; mesh.faces.len()]);
        smoke = advect_per_tet(&mesh, &still, &smoke, &new, 0.0);
        let mass = total(&new, &smoke);
        let change = (mass - previous) / previous;
        let stats = new.stats();
        eprintln!(
            "remesh {step}: {} tets, min dihedral {:.2}°, max radius-edge {:.2}, mass change {:+.4} %",
            stats.tet_count,
            stats.min_dihedral_deg,
            stats.max_radius_edge_ratio,
            100.0 * change
        );
        assert_eq!(stats.non_delaunay_faces, 0);
        worst = worst.max(change.abs());
        previous = mass;
        mesh = new;
        free = nodes.free;
    }
    eprintln!("total change over 4 remeshes {:+.4} %", 100.0 * (previous - start) / start);
    // Issue 17's bound is < 0.5 % per remesh; the transfer's per-node correction keeps a
    // still remesh's total to rounding (measured below 1e-14; −0.09 to −0.02 % per remesh
    // before it), while the start above is held to the analytic integral.
    assert!(worst < 1e-9, "worst mass change per remesh {worst}");
}

/// The smallest dihedral angle of a tet, degrees, seen along each edge: the angle between
/// the other two nodes projected onto the plane across the edge (the library measures it
/// between face normals).
fn smallest_dihedral_along_edges(p: [DVec3; 4]) -> f64 {
    let mut smallest: f64 = 180.0;
    for a in 0..4 {
        for b in a + 1..4 {
            let [c, d] = [0, 1, 2, 3].into_iter().filter(|k| *k != a && *k != b).collect::<Vec<_>>()[..] else {
                unreachable!()
            };
            let edge = (p[b] - p[a]).normalize();
            let across = |q: DVec3| (q - p[a]) - edge * (q - p[a]).dot(edge);
            smallest = smallest.min(across(p[c]).angle_between(across(p[d])).to_degrees());
        }
    }
    smallest
}

/// Remeshing mends slivers. A Delaunay mesh of well-spaced nodes still has tets of four
/// nearly coplanar nodes (dihedral angles near 0°, circumcentres far outside them); the
/// remesh moves their nodes until none is under `SLIVER_DEG` (10°) or no trial move helps.
/// Around a cube standing on the floor and a ball passing it, over steps warm-started from
/// each other: the nodes as placed mesh with slivers, the remesh leaves none under 9°.
#[test]
fn remeshing_leaves_no_slivers_around_obstacles() {
    let s = Sizing { k0_m: 0.04, kd: 0.3, ks_m: 0.0, kw_m_s: 0.0, min_edge_m: 0.04, max_edge_m: 0.2 };
    let (lo, hi) = (DVec3::ZERO, DVec3::new(1.2, 1.0, 1.0));
    let cube_centre = DVec3::new(0.4, 0.1, 0.5);
    let cube = Obstacle::cuboid(cube_centre, DVec3::splat(0.1)).subdivided().subdivided().subdivided();
    let mut previous = Vec::new();
    for step in 0..4 {
        let ball_centre = DVec3::new(0.3 + 0.15 * step as f64, 0.45, 0.45);
        let obstacles = [cube.clone(), Obstacle::sphere(ball_centre, 0.12, 3)];
        let mu = |p: DVec3| {
            let to_cube = ((p - cube_centre).abs().max_element() - 0.1).max(0.0);
            let to_ball = ((p - ball_centre).length() - 0.12).max(0.0);
            s.edge_m(to_cube.min(to_ball), 0.0, 0.0)
        };
        let mut nodes = place_nodes(lo, hi, &obstacles, &previous, &s, &mu, 1_000_000).unwrap();
        let placed: Vec<DVec3> = nodes.fixed.iter().chain(&nodes.free).copied().collect();
        let worst = |mesh: &kinegraph_nodes::kernels::fluid::mesh::TetMesh| {
            (0..mesh.tet_count())
                .map(|t| smallest_dihedral_along_edges(mesh.tets[t].map(|i| mesh.nodes_m[i as usize])))
                .fold(180.0, f64::min)
        };
        let as_placed = worst(&carve(&placed, &obstacles).unwrap());
        let mesh = mesh_nodes(&mut nodes, &obstacles, 1_000_000).unwrap();
        let remeshed = worst(&mesh);
        eprintln!(
            "step {step}: {} tets, smallest dihedral {as_placed:.3}° as placed, {remeshed:.2}° remeshed ({:?})",
            mesh.tet_count(),
            mesh.stats()
        );
        assert!(as_placed < 5.0, "step {step}: the placed nodes make no sliver ({as_placed}°): nothing tested");
        assert!(remeshed >= 9.0, "step {step}: a sliver of {remeshed}° is left");
        previous = nodes.free;
    }
}

/// Whether a face's corners all lie in one face plane of the box `lo..hi`.
fn in_box_plane(corners: &[DVec3; 3], lo: DVec3, hi: DVec3) -> bool {
    (0..3).any(|a| corners.iter().all(|p| p[a] == lo[a]) || corners.iter().all(|p| p[a] == hi[a]))
}

/// The fluid's only walls are the box and the obstacles: every boundary face of a remeshed
/// domain lies in a face plane of the box or is a triangle of obstacle surface vertices,
/// and the tets fill the box less the obstacle's volume (no large holes: a flat tet has no
/// volume, so the faces are what find dropped ones). (Fill nodes placed on a cubic
/// lattice wherever μ is at its maximum once gave cospherical nodes whose flat tets were
/// dropped, leaving 656 walls inside the fluid of this domain.)
#[test]
fn a_remeshed_domain_has_walls_only_on_the_box_and_the_obstacles() {
    let s = Sizing { k0_m: 0.05, kd: 0.3, ks_m: 0.0, kw_m_s: 0.0, min_edge_m: 0.05, max_edge_m: 0.2 };
    let (lo, hi) = (DVec3::new(-1.0, 0.0, -1.0), DVec3::new(1.0, 2.4, 1.0));
    let centre = DVec3::new(0.3, 0.5, 0.0);
    let ball = Obstacle::sphere(centre, 0.2, 4);
    let mu = |p: DVec3| s.edge_m(((p - centre).length() - 0.2).max(0.0), 0.0, 0.0);
    let mut previous = Vec::new();
    for step in 0..2 {
        let mut nodes = place_nodes(lo, hi, std::slice::from_ref(&ball), &previous, &s, &mu, 1_000_000).unwrap();
        let mesh = mesh_nodes(&mut nodes, std::slice::from_ref(&ball), 1_000_000).unwrap();
        let on_ball = |p: DVec3| ball.positions_m.contains(&p);
        let walls = (0..mesh.faces.len()).filter(|&f| mesh.is_boundary(f)).filter(|&f| {
            let corners = mesh.faces[f].map(|i| mesh.nodes_m[i as usize]);
            !in_box_plane(&corners, lo, hi) && !corners.iter().all(|p| on_ball(*p))
        });
        assert_eq!(walls.count(), 0, "step {step}: boundary faces inside the fluid");
        // The ball's volume from its own surface, independent of the mesh.
        let ball_volume = enclosed_volume_m3(&ball);
        let box_volume = (hi - lo).x * (hi - lo).y * (hi - lo).z;
        let fluid: f64 = mesh.tet_volume_m3.iter().sum();
        // The carved ball is the polyhedron of its thinned surface nodes: within 1 % of it.
        let missing = box_volume - ball_volume - fluid;
        assert!(missing.abs() < 0.01 * ball_volume, "step {step}: {missing} m³ missing, ball {ball_volume} m³");
        previous = nodes.free;
    }
}

/// A box standing on the floor (a character's foot), exactly or a hair under it as skinning
/// leaves it, is meshed with the floor cutting it: every node lies in the box, the fluid
/// fills the box less the cube (within the error of the same cube meshed away from the
/// walls), no fluid is left under or in the cube, and no boundary face off the box's planes
/// rises above the cube.
#[test]
fn an_obstacle_standing_on_the_floor_is_cut_by_it() {
    let s = Sizing { k0_m: 0.04, kd: 0.3, ks_m: 0.0, kw_m_s: 0.0, min_edge_m: 0.04, max_edge_m: 0.2 };
    let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
    let cube_volume = 0.2f64.powi(3);
    let missing = |bottom: f64| {
        let centre = DVec3::new(0.5, bottom + 0.1, 0.5);
        // Split three times: vertices 0.025 m apart, finer than the mesh's 0.04 m there.
        let cube = Obstacle::cuboid(centre, DVec3::splat(0.1)).subdivided().subdivided().subdivided();
        assert!((enclosed_volume_m3(&cube) - cube_volume).abs() < 1e-12);
        let mu = |p: DVec3| s.edge_m(((p - centre).abs().max_element() - 0.1).max(0.0), 0.0, 0.0);
        let mut nodes = place_nodes(lo, hi, std::slice::from_ref(&cube), &[], &s, &mu, 1_000_000).unwrap();
        let mesh = mesh_nodes(&mut nodes, std::slice::from_ref(&cube), 1_000_000).unwrap();
        let fluid: f64 = mesh.tet_volume_m3.iter().sum();
        assert!(
            mesh.nodes_m.iter().all(|p| p.cmpge(lo).all() && p.cmple(hi).all()),
            "bottom {bottom}: a node outside the box"
        );
        // Standing (checked only then): fluid tets centred over the cube's footprint, below
        // its top (shrunk by a tenth of an edge: the carve follows the surface to its nodes).
        let under = (0..mesh.tet_count())
            .map(|t| mesh.tet_centroid(t))
            .filter(|c| (c.x - 0.5).abs() < 0.096 && (c.z - 0.5).abs() < 0.096 && c.y < bottom + 0.196)
            .count();
        assert!(bottom > 0.1 || under == 0, "bottom {bottom}: {under} fluid tets under or inside the cube");
        // Boundary faces off the box's planes: the cube's.
        let highest_wall = (0..mesh.faces.len())
            .filter(|&f| mesh.is_boundary(f))
            .map(|f| mesh.faces[f].map(|i| mesh.nodes_m[i as usize]))
            .filter(|corners| !in_box_plane(corners, lo, hi))
            .flat_map(|corners| corners.map(|p| p.y))
            .fold(0.0, f64::max);
        let missing = 1.0 - cube_volume - fluid;
        eprintln!(
            "cube from {bottom} m: {} tets, {missing:+.2e} m³ missing against the cube's {cube_volume} m³, highest wall {highest_wall} m",
            mesh.tet_count()
        );
        assert!(highest_wall <= bottom + 0.2 + 1e-9, "bottom {bottom}: a wall at {highest_wall} m inside the fluid");
        missing
    };
    let floating = missing(0.3);
    assert!(floating.abs() < 0.05 * cube_volume, "floating: {floating} m³ missing");
    for bottom in [0.0, -1e-7] {
        let standing = missing(bottom);
        assert!(
            (standing - floating).abs() < 0.02 * cube_volume,
            "bottom {bottom}: {standing} m³ missing, floating {floating}"
        );
    }
}

#[test]
fn uniformly_heated_air_in_a_closed_box_with_an_obstacle_stays_at_rest() {
    // A source covering the whole box keeps the air uniformly 10 K warm and smoke-free: the
    // buoyancy is uniform and the pressure balances it exactly (hydrostatic), so nothing moves.
    let heat =
        SmokeSource { centre_m: [0.5; 3], radius_m: 2.0, density: 0.0, temperature_k: 303.15, particles_per_step: 0 };
    let d = domain(false, vec![heat]);
    let obstacle = cube_at(DVec3::new(0.5, 0.4, 0.5), 0.15, DVec3::ZERO);
    let (volumes, steps) =
        simulate(&d, &settings(5), &still(vec![obstacle]), Cancel::NEVER, &mut |_, _, _| {}).unwrap();
    let impulse = (1.0 / 24.0) * d.buoyancy_beta * 10.0;
    let fastest = volumes
        .frames
        .iter()
        .flat_map(|f| &f.velocity_m_s)
        .map(|v| DVec3::from(v.map(f64::from)).length())
        .fold(0.0, f64::max);
    eprintln!(
        "heated box: {} steps of {:?} tets, fastest voxel {fastest:e} m/s against one step's impulse {impulse} m/s",
        steps.len(),
        steps.iter().map(|s| s.tets).collect::<Vec<_>>()
    );
    // Exact but for the clamped dual lengths of near-cospherical ties, whose residual adds
    // up over the steps (fluid_tet measures ~2 % of the impulse per step on TetGen meshes):
    // at most 3 % of one step's impulse per step.
    assert!(fastest < 0.03 * impulse * steps.len() as f64, "{fastest} of {impulse}");
}

#[test]
fn a_sphere_started_through_still_air_sets_up_the_potential_flow_around_it() {
    // An impulsively started sphere in inviscid air: after a projection the air
    // moves by the potential flow, u = U R³/(2r³) (3 (x̂·n) n − x̂) at distance r in the
    // direction n from the centre (Lamb §92; U R³/r³ on the axis ahead), evaluated at the
    // centre of every voxel sampled. The box walls 0.35 m away and the mesh (0.02 m edges at
    // the sphere) are the approximations.
    let mut d = domain(true, Vec::new());
    d.sizing = Sizing { k0_m: 0.02, kd: 0.6, ks_m: 0.0, kw_m_s: 0.0, min_edge_m: 0.02, max_edge_m: 0.2 };
    d.voxel_m = 0.05;
    let (speed, radius, centre) = (0.5, 0.15, DVec3::splat(0.5));
    let moving = move |t: f64| {
        let surface = Obstacle::sphere(centre + DVec3::X * speed * t, radius, 3);
        let velocity_m_s = vec![DVec3::X * speed; surface.positions_m.len()];
        vec![MovingObstacle { surface, velocity_m_s }]
    };
    let mut s = settings(2);
    s.fps = 240.0; // a short step: the sphere moves 2 mm
    let (volumes, steps) = simulate(&d, &s, &moving, Cancel::NEVER, &mut |_, _, _| {}).unwrap();
    let grid = volumes.grid;
    let last = volumes.frames.last().unwrap();
    eprintln!("sphere: {:?}", steps[0]);
    let now = centre + DVec3::X * speed / s.fps;
    let potential = |at: DVec3| {
        let dir = at.normalize();
        speed * radius.powi(3) / (2.0 * at.length().powi(3)) * (3.0 * dir.x * dir - DVec3::X)
    };
    // Every voxel centre of the shell r = 0.2 .. 0.25 m (0.05–0.1 m from the surface):
    // RMS and largest error, as shares of U and of the flow's RMS there (a still field errs
    // by 100 % of it).
    let (mut sum_sq, mut flow_sq, mut count, mut worst) = (0.0, 0.0, 0usize, 0.0_f64);
    for n in 0..grid.len() {
        let at = grid.centre_m(n).as_dvec3() - now;
        if !(0.2..=0.25).contains(&at.length()) {
            continue;
        }
        let (v, flow) = (last.velocity_m_s[n], potential(at));
        let error = (DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])) - flow).length() / speed;
        sum_sq += error * error;
        flow_sq += (flow / speed).length_squared();
        count += 1;
        worst = worst.max(error);
    }
    let rms = (sum_sq / count as f64).sqrt();
    let flow_rms = (flow_sq / count as f64).sqrt();
    eprintln!(
        "  {count} voxels at r = 0.2 .. 0.25 m: error RMS {:.1} % of U ({:.1} % of the flow's RMS), largest {:.1} % of U",
        100.0 * rms,
        100.0 * rms / flow_rms,
        100.0 * worst
    );
    assert!(count > 100, "{count}");
    // Measured: RMS 4.9 % of U, 22 % of the flow's RMS, largest 13.4 % of U. The error is
    // the mesh's: with 0.04 m edges at the sphere it was 70 % of the flow's RMS, with the
    // box twice as large 17 % (the walls' blockage adds the rest).
    assert!(rms / flow_rms < 0.3, "{rms} of U, flow {flow_rms}");
    assert!(worst < 0.2, "{worst} of U");
}

#[test]
fn a_too_fine_mesh_too_fast_an_obstacle_and_cancelling_are_typed_errors() {
    let mut d = domain(true, Vec::new());
    d.max_tets = 500;
    let none = |_: f64| Vec::new();
    let err = simulate(&d, &settings(2), &none, Cancel::NEVER, &mut |_, _, _| {}).unwrap_err();
    assert!(matches!(err, SimError::Mesh { step: 0, source: MeshError::TooManyTets { max_tets: 500, .. } }), "{err}");

    let d = domain(true, Vec::new());
    let fast = |t: f64| vec![cube_at(DVec3::new(0.3 + 20.0 * t, 0.5, 0.5), 0.1, DVec3::X * 20.0)];
    let err = simulate(&d, &settings(2), &fast, Cancel::NEVER, &mut |_, _, _| {}).unwrap_err();
    assert!(matches!(err, SimError::Unstable { step: 1, .. }), "{err}");

    let flag = AtomicBool::new(true);
    let err = simulate(&d, &settings(3), &none, Cancel::on(&flag), &mut |_, _, _| {}).unwrap_err();
    assert_eq!(err, SimError::Cancelled);
}

/// Runs `fluid.simulate` on `domain` with `params` over its defaults (2 frames, 1 substep),
/// the static obstacle `mesh` if any.
fn run_simulate(
    domain: FluidDomain,
    mesh: Option<Mesh>,
    params: &[(&str, ParamValue)],
) -> Result<NodeOutcome, NodeError> {
    let mut params = params.to_vec();
    params.splice(0..0, [("substeps", ParamValue::Int(1)), ("frames", ParamValue::Int(2))]);
    let inputs = vec![Some(Value::FluidDomain(Arc::new(domain))), None, mesh.map(|m| Value::Mesh(Arc::new(m)))];
    eval_node("fluid.simulate", inputs, &params, Path::new("."))
}

fn cube_mesh(centre: DVec3, half: f64) -> Mesh {
    let o = Obstacle::cuboid(centre, DVec3::splat(half));
    Mesh {
        name: "cube".into(),
        positions: o.positions_m.iter().map(|p| p.as_vec3()).collect(),
        normals: vec![glam::Vec3::Y; 8],
        uvs: None,
        triangles: o.triangles,
        ..Mesh::default()
    }
}

#[test]
fn fluid_simulate_names_the_port_or_param_of_bad_input() {
    // Through the wall by 0.08 m, more than half the smallest edge (0.05 m).
    let outside = run_simulate(domain(true, Vec::new()), Some(cube_mesh(DVec3::new(0.98, 0.5, 0.5), 0.1)), &[]);
    assert!(
        matches!(&outside, Err(NodeError::Input { port: "static_obstacle", message }) if message.contains("outside the domain")),
        "{outside:?}"
    );
    // On the floor, a hair under it: simulated.
    let standing = run_simulate(domain(true, Vec::new()), Some(cube_mesh(DVec3::new(0.5, 0.1 - 1e-7, 0.5), 0.1)), &[]);
    assert!(standing.is_ok(), "{standing:?}");
    let mut open = cube_mesh(DVec3::splat(0.5), 0.1);
    open.triangles.pop();
    let open = run_simulate(domain(true, Vec::new()), Some(open), &[]);
    assert!(
        matches!(&open, Err(NodeError::Input { port: "static_obstacle", message }) if message.contains("not a closed surface")),
        "{open:?}"
    );
    let mut small = domain(true, Vec::new());
    small.max_tets = 400;
    let many = run_simulate(small, Some(cube_mesh(DVec3::splat(0.5), 0.1)), &[]);
    assert!(
        matches!(&many, Err(NodeError::Input { port: "domain", message }) if message.contains("max_tets = 400") && message.contains("step 0")),
        "{many:?}"
    );
    let ok = run_simulate(domain(true, Vec::new()), Some(cube_mesh(DVec3::splat(0.5), 0.1)), &[]);
    assert!(ok.is_ok(), "{ok:?}");

    // Dynamic bodies: each bad value is refused naming `bodies` and the body.
    let bad = [
        ("ball size=0.2 density=500 at=0.5,0.95,0.5", "does not fit inside the domain"),
        ("ball size=0.2 density=0 at=0.5,0.5,0.5", "density 0 kg/m³ must be above 0"),
        ("ball size=0.2 density=1 at=0.5,0.5,0.5; box size=-0.1 density=1 at=0.5,0.5,0.5", "body 2: size -0.1"),
        ("ball size=0.2 density=nan at=0.5,0.5,0.5", "density=nan is not a number"),
        ("ball size=0.2 density=1 at=0.5,0.5", "at=0.5,0.5 is not x,y,z"),
        ("sphere size=0.2 density=1 at=0.5,0.5,0.5", "not `ball` or `box`"),
        ("ball size=0.2 density=1", "give its centre"),
        ("ball size=0.2 density=1 at=0.5,0.5,0.5 mass=3", "unknown key `mass`"),
    ];
    for (text, expected) in bad {
        let got = run_simulate(domain(true, Vec::new()), None, &[("bodies", ParamValue::Text(text.into()))]);
        assert!(
            matches!(&got, Err(NodeError::Param { param: "bodies", message }) if message.contains(expected)),
            "{text}: {got:?}"
        );
    }
}

#[test]
fn fluid_simulate_drops_a_heavy_box_onto_the_floor_and_reports_its_path() {
    // A dense box dropped in air falls at g less its buoyancy (ρ_air / ρ_b = 0.12 %) and the
    // air's drag, then rests a smallest edge (0.1 m) above the floor: y = 0.1 + 0.1 m.
    let mut d = domain(true, Vec::new());
    d.voxel_m = 0.25;
    let out = run_simulate(
        d,
        None,
        &[
            ("bodies", ParamValue::Text("box size=0.2 density=1000 at=0.5,0.45,0.5".into())),
            ("frames", ParamValue::Int(8)),
            ("substeps", ParamValue::Int(2)),
        ],
    )
    .unwrap();
    let Some(Value::Curves(curves)) = &out.outputs[2] else { panic!("{:?}", out.outputs[2]) };
    let channel = |name: &str| curves.channel(name).unwrap().values.clone();
    let (y, vy) = (channel("box1.y"), channel("box1.vy"));
    eprintln!("box1.y {y:.4?}\nbox1.vy {vy:.4?}");
    // Free fall for the first frames: after t seconds from rest v = −g t (1 − 0.12 %), here
    // within 1 % (measured −0.26 %: the air it pushes ahead of it).
    let t = 2.0 / 24.0;
    assert!((vy[2] + 9.81 * t).abs() < 0.01 * 9.81 * t, "{vy:?}");
    // At rest on the floor; the box has turned a little (the air's push is not symmetric on
    // the mesh), so its lowest corner, not its face, keeps the gap: measured 0.20002 m.
    assert!((y.last().unwrap() - 0.2).abs() < 1e-3 && vy.last().unwrap().abs() < 1e-12, "{y:?} {vy:?}");
    let Some(Value::Report(report)) = &out.outputs[1] else { panic!() };
    let body = &report["bodies"][0];
    assert_eq!(body["name"], "box1");
    assert!(body["first_frame_at_wall"].as_u64().is_some_and(|f| f < 7), "{body}");
}
