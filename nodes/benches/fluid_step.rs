//! One smoke step on tet meshes of a 1 m box with a 0.3 m cube obstacle at about 25k, 50k
//! and 100k tets (issue 17's goal: < 2 s per step at 100k on the 2-core machine), split into
//! meshing (TetGen quality mesh + Delaunay of its nodes), the pressure solve (assembly,
//! Cholesky, one projection; and the same with the cube a dynamic body coupled in, Klingner
//! §7) and advection (velocity reconstruction + tracing every face). Group `fluid_remesh`:
//! the remesh `fluid.simulate` runs every step (node placement by a uniform sizing field
//! warm-started from the last step's nodes, Delaunay, carving, relaxation, Delaunay and
//! carving again, then sliver mending) around the same cube at about 25k, 50k, 100k and 200k tets.
//! Run: `cargo bench -p kinegraph-nodes --bench fluid_step`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use kinegraph_nodes::kernels::fluid::mesher::{BoxMeshSpec, Obstacle, Tetrahedralisation, mesh_box};
use kinegraph_nodes::kernels::fluid::projection::{FaceCondition, PressureSolver, face_conditions};
use kinegraph_nodes::kernels::fluid::remesh::{mesh_nodes, place_nodes};
use kinegraph_nodes::kernels::fluid::rigid::{RigidBody, RigidShape};
use kinegraph_nodes::kernels::fluid::velocity::{VelocityField, advect_velocity, sample_faces};
use kinegraph_nodes::model::volume::Sizing;
use std::hint::black_box;

fn cube(centre: DVec3, half: f64) -> Obstacle {
    Obstacle::cuboid(centre, DVec3::splat(half))
}

fn bench(c: &mut Criterion) {
    for target in [25_000usize, 50_000, 100_000] {
        let spec = BoxMeshSpec {
            min_m: DVec3::ZERO,
            max_m: DVec3::ONE,
            obstacles: vec![cube(DVec3::splat(0.5), 0.15)],
            max_tet_volume_m3: 2.5 * (1.0 - 0.027) / target as f64,
            max_radius_edge_ratio: 1.5,
            tetrahedralisation: Tetrahedralisation::Delaunay,
            max_tets: 10 * target,
        };
        let mesh = mesh_box(&spec).unwrap();
        eprintln!("fluid_step {target}: {:?}", mesh.stats());
        let mut group = c.benchmark_group(format!("fluid_step_{}k", target / 1000));
        group.sample_size(10);
        group.bench_function("mesh", |b| b.iter(|| mesh_box(black_box(&spec)).unwrap()));
        let conditions = face_conditions(&mesh, |_| FaceCondition::Wall);
        let swirl = |p: DVec3| DVec3::new(p.z - 0.5, 0.3, 0.5 - p.x);
        let z0: Vec<f64> = sample_faces(&mesh, swirl)
            .iter()
            .enumerate()
            .map(|(f, z)| if mesh.is_boundary(f) { 0.0 } else { *z })
            .collect();
        group.bench_function("pressure_assemble_factor_project", |b| {
            b.iter(|| {
                let solver = PressureSolver::new(&mesh, &conditions).unwrap();
                let mut z = z0.clone();
                solver.project(&mesh, &mut z, 0.02, 1.2).unwrap();
                z
            })
        });
        // The cube as a dynamic body: its faces (boundary faces off the box walls) coupled.
        let body = RigidBody::new(RigidShape::Cube, 0.3, 500.0, DVec3::splat(0.5), DVec3::X * 0.1);
        let on_walls = |x: DVec3| (0..3).any(|a| x[a].abs() < 1e-9 || (x[a] - 1.0).abs() < 1e-9);
        let coupled = face_conditions(&mesh, |f| {
            if on_walls(mesh.face_circumcentre_m[f]) { FaceCondition::Wall } else { FaceCondition::Rigid(0) }
        });
        group.bench_function("pressure_coupled_body", |b| {
            b.iter(|| {
                let solver = PressureSolver::with_bodies(&mesh, &coupled, &[body.coupling()], 1.2).unwrap();
                let mut z = z0.clone();
                let mut u = [body.generalised_velocity()];
                solver.project_with_bodies(&mesh, &mut z, &mut u, 0.02).unwrap();
                u
            })
        });
        group.bench_function("advect_velocity", |b| {
            b.iter(|| {
                let field = VelocityField::new(&mesh, &z0);
                advect_velocity(&mesh, &field, &mesh, 0.02, |f| mesh.is_boundary(f))
            })
        });
        group.finish();
    }
}

/// The per-step remesh at a uniform edge length μ chosen for about `target` tets (measured:
/// about 5.5 tets per μ³ of air).
fn remesh(c: &mut Criterion) {
    let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
    let obstacles = [cube(DVec3::splat(0.5), 0.15)];
    let mut group = c.benchmark_group("fluid_remesh");
    group.sample_size(10);
    for target in [25_000usize, 50_000, 100_000, 200_000] {
        let edge = (5.5 * (1.0 - 0.027) / target as f64).cbrt();
        let sizing = Sizing { k0_m: edge, kd: 0.0, ks_m: 0.0, kw_m_s: 0.0, min_edge_m: edge, max_edge_m: edge };
        let mu = |_: DVec3| edge;
        let max_tets = 10 * target;
        let mut nodes = place_nodes(lo, hi, &obstacles, &[], &sizing, &mu, max_tets).unwrap();
        let mesh = mesh_nodes(&mut nodes, &obstacles, max_tets).unwrap();
        eprintln!("fluid_remesh {target}: edge {edge:.4} m, {:?}", mesh.stats());
        let previous = nodes.free;
        group.bench_function(format!("{}k", target / 1000), |b| {
            b.iter(|| {
                let mut nodes = place_nodes(lo, hi, &obstacles, black_box(&previous), &sizing, &mu, max_tets).unwrap();
                mesh_nodes(&mut nodes, &obstacles, max_tets).unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench, remesh);
criterion_main!(benches);
