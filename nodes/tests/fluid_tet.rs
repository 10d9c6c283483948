//! Smoke on tetrahedral meshes (issue 17, Klingner 2006): the mesh kernel, the circumcentric
//! discretisation, the projection and advection, each against an independent computation
//! (analytic volumes and areas, brute-force empty-sphere tests, hydrostatic pressure,
//! exact fields). Needs the TetGen mesher (`tetgen` feature, on by default).
#![cfg(feature = "tetgen")]
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed expect is a failed test

use glam::DVec3;
use kinegraph_nodes::kernels::fluid::mesh::{MeshError, NO_TET, TetMesh};
use kinegraph_nodes::kernels::fluid::mesher::{
    BoxMeshSpec, Obstacle, Tetrahedralisation, box_corners, delaunay, mesh_box,
};
use kinegraph_nodes::kernels::fluid::projection::{
    FaceCondition, PressureSolver, divergence, face_conditions, max_relative_divergence,
};
use kinegraph_nodes::kernels::fluid::rigid::{RigidBody, RigidShape};
use kinegraph_nodes::kernels::fluid::smoke::{Buoyancy, add_buoyancy, advect_per_tet, total};
use kinegraph_nodes::kernels::fluid::velocity::{VelocityField, advect_velocity, sample_faces, tet_velocities};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// An axis-aligned cube obstacle, triangles facing outwards.
fn cube(centre: DVec3, half: f64) -> Obstacle {
    Obstacle::cuboid(centre, DVec3::splat(half))
}

fn random_points(seed: u64, count: usize, lo: DVec3, hi: DVec3) -> Vec<DVec3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut points: Vec<DVec3> = box_corners(lo, hi).to_vec();
    points.extend((0..count).map(|_| lo + (hi - lo) * DVec3::new(rng.r#gen(), rng.r#gen(), rng.r#gen())));
    points
}

fn random_delaunay(seed: u64, count: usize) -> TetMesh {
    delaunay(&random_points(seed, count, DVec3::ZERO, DVec3::new(1.0, 0.8, 1.2))).expect("delaunay")
}

#[test]
fn box_minus_cube_volume_and_boundary_area_match_the_analytic_values() {
    let spec = BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::new(2.0, 1.0, 1.0),
        obstacles: vec![cube(DVec3::new(0.7, 0.5, 0.5), 0.15)],
        max_tet_volume_m3: 2e-3,
        max_radius_edge_ratio: 1.6,
        tetrahedralisation: Tetrahedralisation::Constrained,
        max_tets: 1_000_000,
    };
    let mesh = mesh_box(&spec).expect("mesh");
    let stats = mesh.stats();
    eprintln!("box minus cube: {stats:?}");
    let expected_volume = 2.0 - 0.3f64.powi(3);
    assert!((mesh.volume_m3() - expected_volume).abs() < 1e-12 * expected_volume, "{}", mesh.volume_m3());
    assert!(mesh.tet_volume_m3.iter().all(|&v| v <= 2e-3 * (1.0 + 1e-9)));
    // Boundary faces cover the box's surface (10 m²) plus the cube's (6 × 0.09 m²).
    let boundary_area: f64 = (0..mesh.faces.len()).filter(|&f| mesh.is_boundary(f)).map(|f| mesh.face_area_m2[f]).sum();
    assert!((boundary_area - (10.0 + 0.54)).abs() < 1e-10, "{boundary_area}");
    // Outward boundary normals integrate to zero over a closed surface (Σ A n = 0).
    let net: DVec3 = (0..mesh.faces.len())
        .filter(|&f| mesh.is_boundary(f))
        .map(|f| mesh.face_normal[f] * mesh.face_area_m2[f])
        .sum();
    assert!(net.length() < 1e-10, "{net}");
    // No node inside the obstacle.
    assert!(mesh.nodes_m.iter().all(|p| (*p - DVec3::new(0.7, 0.5, 0.5)).abs().max_element() >= 0.15 - 1e-12));
    // TetGen's radius-edge bound holds away from the input's own corners.
    assert!(stats.max_radius_edge_ratio < 2.5, "{stats:?}");
    assert!(stats.min_dihedral_deg > 3.0, "{stats:?}");
}

#[test]
fn circumcentres_are_equidistant_and_dual_edges_are_face_normals() {
    let mesh = random_delaunay(7, 300);
    for (t, tet) in mesh.tets.iter().enumerate() {
        let c = mesh.tet_circumcentre_m[t];
        let r: Vec<f64> = tet.iter().map(|&i| (mesh.nodes_m[i as usize] - c).length()).collect();
        let scale = r[0];
        assert!(r.iter().all(|x| (x - scale).abs() < 1e-8 * scale.max(1.0)), "tet {t}: {r:?}");
    }
    for f in 0..mesh.faces.len() {
        let x = mesh.face_circumcentre_m[f];
        let p = mesh.faces[f].map(|i| mesh.nodes_m[i as usize]);
        let d: Vec<f64> = p.iter().map(|q| (*q - x).length()).collect();
        assert!(d.iter().all(|v| (v - d[0]).abs() < 1e-8 * d[0].max(1.0)), "face {f}: {d:?}");
        let n = mesh.face_normal[f];
        assert!((x - p[0]).dot(n).abs() < 1e-9, "face circumcentre off the face plane");
        let [a, b] = mesh.face_tets[f];
        if b != NO_TET {
            // The line between the two tet circumcentres is the face normal through x_f.
            let ca = mesh.tet_circumcentre_m[a as usize];
            let cb = mesh.tet_circumcentre_m[b as usize];
            let along = cb - ca;
            assert!(along.cross(n).length() < 1e-7 * along.length().max(1e-3), "face {f}");
            assert!((x - ca).cross(n).length() < 1e-7 * (x - ca).length().max(1e-3), "face {f}");
        }
    }
}

#[test]
fn delaunay_mesh_has_empty_circumspheres() {
    let mesh = random_delaunay(11, 250);
    assert_eq!(mesh.stats().non_delaunay_faces, 0);
    assert!((mesh.volume_m3() - 0.96).abs() < 1e-12);
    for t in 0..mesh.tet_count() {
        let c = mesh.tet_circumcentre_m[t];
        let r = mesh.tet_circumradius_m[t];
        for (i, p) in mesh.nodes_m.iter().enumerate() {
            if mesh.tets[t].contains(&(i as u32)) {
                continue;
            }
            assert!((*p - c).length() >= r * (1.0 - 1e-9), "node {i} inside the circumsphere of tet {t}");
        }
    }
}

fn closed(mesh: &TetMesh) -> Vec<FaceCondition> {
    face_conditions(mesh, |_| FaceCondition::Wall)
}

#[test]
fn projection_leaves_no_divergence_on_random_delaunay_meshes() {
    for seed in [1, 2, 3] {
        let mesh = random_delaunay(seed, 400);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 100);
        for open in [false, true] {
            let conditions = face_conditions(&mesh, |f| {
                if open && mesh.face_circumcentre_m[f].y > 0.8 - 1e-9 {
                    FaceCondition::Open
                } else {
                    FaceCondition::Wall
                }
            });
            let mut z: Vec<f64> = (0..mesh.faces.len())
                .map(|f| if mesh.is_boundary(f) { 0.0 } else { rng.gen_range(-1.0..1.0) })
                .collect();
            let before = max_relative_divergence(&mesh, &z);
            let solver = PressureSolver::new(&mesh, &conditions).expect("solver");
            solver.project(&mesh, &mut z, 0.01, 1.2).expect("project");
            let after = max_relative_divergence(&mesh, &z);
            eprintln!("seed {seed} open {open}: relative divergence {before:.3e} -> {after:.3e}");
            assert!(before > 0.1);
            assert!(after < 1e-8, "seed {seed} open {open}: {after:e}");
            // The divergence-free field is recovered exactly by N_t u_t = z_t.
            let u = tet_velocities(&mesh, &z);
            let mut worst: f64 = 0.0;
            for (t, ut) in u.iter().enumerate() {
                for (k, (n, _, f)) in mesh.outward_faces(t).into_iter().enumerate() {
                    let zt = z[f] * mesh.tet_face_sign[t][k];
                    worst = worst.max((n.dot(*ut) - zt).abs());
                }
            }
            let scale = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(worst < 1e-8 * scale, "seed {seed}: N u - z = {worst:e}");
        }
    }
}

#[test]
fn constant_field_is_reconstructed_exactly_per_tet_and_per_node() {
    let mesh = random_delaunay(5, 300);
    let u = DVec3::new(0.3, -1.1, 0.7);
    let z = sample_faces(&mesh, |_| u);
    // Exact up to the conditioning of flat hull tets.
    assert!(tet_velocities(&mesh, &z).iter().all(|v| (*v - u).length() < 1e-9));
    let field = VelocityField::new(&mesh, &z);
    assert!(field.node_velocity_m_s.iter().all(|v| (*v - u).length() < 1e-9));
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for _ in 0..100 {
        let p = DVec3::new(rng.r#gen(), rng.gen_range(0.0..0.8), rng.gen_range(0.0..1.2));
        assert!((field.sample(&mesh, p) - u).length() < 1e-9);
    }
}

#[test]
fn fluid_at_rest_under_gravity_stays_at_rest_with_hydrostatic_pressure() {
    let spec = BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::new(1.0, 2.0, 1.0),
        obstacles: vec![cube(DVec3::new(0.5, 0.8, 0.5), 0.2)],
        max_tet_volume_m3: 4e-3,
        max_radius_edge_ratio: 1.5,
        tetrahedralisation: Tetrahedralisation::Delaunay,
        max_tets: 1_000_000,
    };
    let mesh = mesh_box(&spec).expect("mesh");
    let stats = mesh.stats();
    let gravity = DVec3::new(0.0, -9.81, 0.0);
    let (dt, rho) = (0.02, 1.2);
    let conditions = closed(&mesh);
    // z* = z + Δt g·n on fluid faces; walls hold still.
    let mut z: Vec<f64> = (0..mesh.faces.len())
        .map(|f| if mesh.is_boundary(f) { 0.0 } else { dt * gravity.dot(mesh.face_normal[f]) })
        .collect();
    let solver = PressureSolver::new(&mesh, &conditions).expect("solver");
    let pressure = solver.project(&mesh, &mut z, dt, rho).expect("project");
    let max_speed = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    eprintln!("hydrostatic: {stats:?}, max speed after one step {max_speed:e} m/s");
    assert_eq!(stats.non_delaunay_faces, 0);
    // Exact where no dual length is clamped; the clamped faces (near-cospherical ties,
    // counted in the stats) leave a small residual flow.
    let tolerance = if stats.clamped_dual_faces == 0 { 1e-10 } else { 1e-2 * dt * 9.81 };
    assert!(max_speed < tolerance, "{max_speed}");
    // p = ρ g·x + const at the circumcentres (the analytic hydrostatic pressure), to the
    // same relative tolerance over the box's height (2 m).
    let offset = pressure[0] - rho * gravity.dot(mesh.tet_circumcentre_m[0]);
    let worst = pressure
        .iter()
        .enumerate()
        .map(|(t, p)| (p - rho * gravity.dot(mesh.tet_circumcentre_m[t]) - offset).abs())
        .fold(0.0f64, f64::max);
    eprintln!("hydrostatic: worst pressure error {worst:e} Pa of {} Pa", rho * 9.81 * 2.0);
    assert!(worst < tolerance / (dt * 9.81) * rho * 9.81 * 2.0, "{worst}");
}

#[test]
fn coupled_projection_leaves_no_divergence_and_moves_the_body_by_the_pressure_it_returns() {
    // A cube coupled in as a dynamic body (Klingner §7), random air and a random body
    // velocity: after the one solve the air is divergence-free around the moving body, and
    // the body's velocity changed by exactly the impulse of the returned pressure over its
    // faces, Δt M⁻¹ Σ_f p A_f (n_f, r_f × n_f) (the fluid pushes it as hard as it pushes
    // the fluid).
    let (centre, half) = (DVec3::new(0.5, 0.8, 0.5), 0.2);
    let spec = BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::new(1.0, 2.0, 1.0),
        obstacles: vec![cube(centre, half)],
        max_tet_volume_m3: 4e-3,
        max_radius_edge_ratio: 1.5,
        tetrahedralisation: Tetrahedralisation::Delaunay,
        max_tets: 1_000_000,
    };
    let mesh = mesh_box(&spec).expect("mesh");
    let on_wall = |f: usize, axis: usize, value: f64| {
        (mesh.face_circumcentre_m[f][axis] - value).abs() < 1e-9 && mesh.face_normal[f][axis].abs() > 0.99
    };
    let (dt, rho) = (0.02, 1000.0);
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for open in [false, true] {
        let conditions = face_conditions(&mesh, |f| {
            if open && on_wall(f, 1, 2.0) {
                FaceCondition::Open
            } else if (0..3).any(|a| on_wall(f, a, 0.0) || on_wall(f, a, spec.max_m[a])) {
                FaceCondition::Wall
            } else {
                FaceCondition::Rigid(0)
            }
        });
        let mut body = RigidBody::new(RigidShape::Cube, 2.0 * half, 1500.0, centre, DVec3::ZERO);
        body.set_generalised_velocity(&nalgebra::Vector6::from_fn(|_, _| rng.gen_range(-1.0..1.0)));
        let mut z: Vec<f64> =
            (0..mesh.faces.len()).map(|f| if mesh.is_boundary(f) { 0.0 } else { rng.gen_range(-1.0..1.0) }).collect();
        let mut u = [body.generalised_velocity()];
        let solver = PressureSolver::with_bodies(&mesh, &conditions, &[body.coupling()], rho).expect("solver");
        let pressure = solver.project_with_bodies(&mesh, &mut z, &mut u, dt).expect("project");
        // Divergence against the flux scale (a corner tet walled on three sides has a
        // single open face, so per-tet relative figures are meaningless there).
        let flux = (0..mesh.faces.len()).map(|f| mesh.face_area_m2[f] * z[f].abs()).fold(0.0, f64::max);
        let divergence = divergence(&mesh, &z).iter().fold(0.0f64, |m, d| m.max(d.abs())) / flux;
        let impulse: nalgebra::Vector6<f64> = (0..mesh.faces.len())
            .filter(|&f| conditions[f] == FaceCondition::Rigid(0))
            .map(|f| {
                let n = mesh.face_normal[f];
                let centroid = mesh.faces[f].iter().map(|&i| mesh.nodes_m[i as usize]).sum::<DVec3>() / 3.0;
                let arm = (centroid - centre).cross(n);
                let p = pressure[mesh.face_tets[f][0] as usize];
                nalgebra::Vector6::new(n.x, n.y, n.z, arm.x, arm.y, arm.z) * (p * mesh.face_area_m2[f] * dt)
            })
            .sum();
        let mut pushed = body;
        pushed.apply_impulse(&impulse);
        let change = (u[0] - body.generalised_velocity()).norm();
        let newton = (pushed.generalised_velocity() - u[0]).norm();
        eprintln!(
            "coupled cube, open {open}: divergence {divergence:.1e} of the largest flux, ΔU {change:.3} (m/s, rad/s), Newton residual {newton:.1e}"
        );
        assert!(divergence < 1e-10, "{divergence:e}");
        assert!(change > 0.01, "the pressure should change the body's velocity: {change}");
        assert!(newton < 1e-9 * change, "{newton:e}");
    }
}

#[test]
fn rigid_translation_is_advected_exactly_onto_a_new_mesh() {
    let old = random_delaunay(21, 300);
    let new = random_delaunay(22, 350);
    let u = DVec3::new(0.4, 0.2, -0.5);
    let field = VelocityField::new(&old, &sample_faces(&old, |_| u));
    let z = advect_velocity(&old, &field, &new, 0.05, |_| false);
    let exact = sample_faces(&new, |_| u);
    let worst = z.iter().zip(&exact).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(worst < 1e-9, "{worst:e}");
}

/// Least-squares angular velocity about the Y axis of the tets within `radius` of the axis.
fn fitted_spin(mesh: &TetMesh, u: &[DVec3], centre: DVec3, radius: f64) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (t, v) in u.iter().enumerate() {
        let r = mesh.tet_circumcentre_m[t] - centre;
        let r_perp = DVec3::new(r.x, 0.0, r.z);
        if r_perp.length() < radius && r.y.abs() < radius {
            // u = ω ŷ × r = ω (r.z, 0, −r.x)
            let basis = DVec3::new(r.z, 0.0, -r.x);
            num += v.dot(basis);
            den += basis.length_squared();
        }
    }
    num / den
}

#[test]
fn solid_body_rotation_keeps_its_spin_after_one_revolution() {
    let centre = DVec3::splat(0.5);
    let omega = 2.0 * std::f64::consts::PI; // one revolution per second
    let spin = move |p: DVec3| DVec3::new(0.0, omega, 0.0).cross(p - centre);
    let spec = BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::ONE,
        obstacles: vec![],
        max_tet_volume_m3: 5e-4,
        max_radius_edge_ratio: 1.4,
        tetrahedralisation: Tetrahedralisation::Delaunay,
        max_tets: 1_000_000,
    };
    let mesh = mesh_box(&spec).expect("mesh");
    eprintln!("rotation mesh: {:?}", mesh.stats());
    let conditions = closed(&mesh);
    let solver = PressureSolver::new(&mesh, &conditions).expect("solver");
    let walls = sample_faces(&mesh, spin);
    let mut z = walls.clone();
    let steps = 96;
    let dt = 1.0 / steps as f64;
    for _ in 0..steps {
        let field = VelocityField::new(&mesh, &z);
        z = advect_velocity(&mesh, &field, &mesh, dt, |f| mesh.is_boundary(f));
        for f in 0..mesh.faces.len() {
            if mesh.is_boundary(f) {
                z[f] = walls[f];
            }
        }
        solver.project(&mesh, &mut z, dt, 1.2).expect("project");
    }
    let fitted = fitted_spin(&mesh, &tet_velocities(&mesh, &z), centre, 0.3);
    // Advect-then-project turns the rotated velocity found at the traced-back point into
    // its tangential part: cos(ω Δt) of the speed per step, even with exact interpolation
    // (the first-order splitting's own loss). Measured on top of it: 16 % more loss at 96
    // steps on 4.7k tets, from the node velocities next to the walls (whose Voronoi cells
    // are unbounded); the tolerance is 20 %.
    let predicted = omega * (omega * dt).cos().powi(steps);
    let error = (fitted - predicted).abs() / predicted;
    eprintln!(
        "rotation: {} tets, {steps} steps, spin after one revolution {fitted:.4} rad/s, splitting predicts {predicted:.4} ({error:.3e} relative)",
        mesh.tet_count()
    );
    assert!(error < 0.2, "relative spin error {error}");
}

#[test]
fn delaunay_mode_is_delaunay_and_carves_the_obstacle() {
    let spec = BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::new(2.0, 1.0, 1.0),
        obstacles: vec![cube(DVec3::new(0.7, 0.5, 0.5), 0.15)],
        max_tet_volume_m3: 2e-3,
        max_radius_edge_ratio: 1.6,
        tetrahedralisation: Tetrahedralisation::Delaunay,
        max_tets: 1_000_000,
    };
    let mesh = mesh_box(&spec).expect("mesh");
    let stats = mesh.stats();
    let expected_volume = 2.0 - 0.3f64.powi(3);
    let error = (mesh.volume_m3() - expected_volume).abs() / 0.3f64.powi(3);
    eprintln!("box minus cube, Delaunay: {stats:?}, volume error {error:.3e} of the obstacle's volume");
    assert_eq!(stats.non_delaunay_faces, 0);
    assert!(error < 0.05, "{error}");
}

fn unit_box(max_tet_volume_m3: f64) -> TetMesh {
    mesh_box(&BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::ONE,
        obstacles: vec![],
        max_tet_volume_m3,
        max_radius_edge_ratio: 1.5,
        tetrahedralisation: Tetrahedralisation::Delaunay,
        max_tets: 1_000_000,
    })
    .expect("mesh")
}

#[test]
fn smoke_mass_is_kept_across_remeshes() {
    let sigma: f64 = 0.1;
    let centre = DVec3::splat(0.5);
    let blob = |p: DVec3| (-(p - centre).length_squared() / (2.0 * sigma * sigma)).exp();
    // ∫ blob over space = (2π)^{3/2} σ³ (the box holds all but e^-12.5 of it).
    let analytic = (2.0 * std::f64::consts::PI).powf(1.5) * sigma.powi(3);
    let meshes = [unit_box(2e-4), unit_box(1.7e-4)];
    let first = &meshes[0];
    let mut smoke: Vec<f64> = (0..first.tet_count()).map(|t| blob(first.tet_centroid(t))).collect();
    let start = total(first, &smoke);
    eprintln!("smoke: {} tets, mass {start:.6} vs analytic {analytic:.6}", first.tet_count());
    assert!((start - analytic).abs() < 0.02 * analytic);
    let mut previous = start;
    let mut worst: f64 = 0.0;
    for step in 1..=4 {
        let (old, new) = (&meshes[(step + 1) % 2], &meshes[step % 2]);
        let still = VelocityField::new(old, &vec![0.0; old.faces.len()]);
        smoke = advect_per_tet(old, &still, &smoke, new, 0.0);
        let mass = total(new, &smoke);
        let change = (mass - previous) / previous;
        eprintln!(
            "remesh {step}: {} → {} tets, mass change {:+.4} %",
            old.tet_count(),
            new.tet_count(),
            100.0 * change
        );
        worst = worst.max(change.abs());
        previous = mass;
    }
    eprintln!("smoke: total mass change over 4 remeshes {:+.4} %", 100.0 * (previous - start) / start);
    // Issue 17's bound is < 0.5 % per remesh; with the per-node correction a still remesh
    // keeps the total to rounding (measured below 1e-14; 0.02–0.05 % with the plain
    // 4-point transfer).
    assert!(worst < 1e-9, "worst mass change per remesh {worst}");
}

#[test]
fn uniform_heat_in_a_closed_box_stays_at_rest_and_a_hot_blob_rises() {
    let mesh = unit_box(1e-3);
    let stats = mesh.stats();
    let buoyancy = Buoyancy::default();
    let (dt, rho) = (0.02, 1.2);
    let solver = PressureSolver::new(&mesh, &closed(&mesh)).expect("solver");
    let smoke = vec![0.0; mesh.tet_count()];

    let warm = vec![buoyancy.ambient_k + 10.0; mesh.tet_count()];
    let mut z = vec![0.0; mesh.faces.len()];
    add_buoyancy(&mesh, &mut z, &smoke, &warm, &buoyancy, dt, |f| !mesh.is_boundary(f));
    solver.project(&mesh, &mut z, dt, rho).expect("project");
    let max_speed = z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let push = dt * buoyancy.beta * 10.0;
    eprintln!("uniform heat: {stats:?}, max speed {max_speed:e} m/s of an impulse {push} m/s");
    // Exact without clamped dual lengths; the clamped faces leave ~2 % of the impulse.
    let tolerance = if stats.clamped_dual_faces == 0 { 1e-12 } else { 3e-2 * push };
    assert!(max_speed < tolerance);

    // A hot blob at the centre: the fluid inside it moves up, slower than the unopposed push.
    let centre = DVec3::splat(0.5);
    let hot: Vec<f64> = (0..mesh.tet_count())
        .map(|t| buoyancy.ambient_k + if (mesh.tet_centroid(t) - centre).length() < 0.15 { 10.0 } else { 0.0 })
        .collect();
    let mut z = vec![0.0; mesh.faces.len()];
    add_buoyancy(&mesh, &mut z, &smoke, &hot, &buoyancy, dt, |f| !mesh.is_boundary(f));
    solver.project(&mesh, &mut z, dt, rho).expect("project");
    let v = VelocityField::new(&mesh, &z).sample(&mesh, centre);
    eprintln!("hot blob: velocity at its centre {v} m/s, unopposed push {push} m/s");
    assert!(v.y > 0.1 * push && v.y < push, "{v}");
}

#[test]
fn bad_domains_are_refused_with_typed_errors() {
    let spec = |obstacle: Obstacle, max_tets: usize| BoxMeshSpec {
        min_m: DVec3::ZERO,
        max_m: DVec3::ONE,
        obstacles: vec![obstacle],
        max_tet_volume_m3: 1e-3,
        max_radius_edge_ratio: 1.5,
        tetrahedralisation: Tetrahedralisation::Delaunay,
        max_tets,
    };
    let outside = mesh_box(&spec(cube(DVec3::new(0.95, 0.5, 0.5), 0.1), 1_000_000));
    assert!(matches!(outside, Err(MeshError::ObstacleOutside { obstacle: 0, .. })), "{outside:?}");
    let mut open = cube(DVec3::splat(0.5), 0.1);
    open.triangles.pop();
    let open = mesh_box(&spec(open, 1_000_000));
    assert!(matches!(open, Err(MeshError::ObstacleNotClosed { obstacle: 0, .. })), "{open:?}");
    // About 2.5 tets per max volume: 1 m³ / 1e-3 m³ asks for ~2500.
    let many = mesh_box(&spec(cube(DVec3::splat(0.5), 0.1), 1000));
    assert!(matches!(many, Err(MeshError::TooManyTets { max_tets: 1000, .. })), "{many:?}");
    let fits = mesh_box(&spec(cube(DVec3::splat(0.5), 0.1), 4000)).expect("mesh");
    assert!(fits.tet_count() <= 4000);
}
