//! `deform.wrap` at production size (issue 23): the MakeHuman base mesh
//! (`../shared/data/obj/makehuman/base.obj`) subdivided until it has at least 100,000
//! vertices, wrapped onto a ~5,000-triangle proxy of the same body (vertex clustering on a
//! voxel grid). Binding once; then one frame of a deformed control mesh, with and without
//! the fine mesh's normals. Goals: bind < 1 s, frame < 5 ms.
//! Run: `cargo bench -p kinegraph-nodes --bench wrap`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::HashMap;
use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{IVec3, Quat, Vec3};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::obj::read_obj_file;
use kinegraph_nodes::kernels::wrap::{WrapScratch, bind, deform_frame};
use kinegraph_nodes::model::Mesh;

/// One level of midpoint subdivision: every triangle into four.
fn subdivide(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = positions.to_vec();
    let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
    let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
        *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
            positions.push((positions[a as usize] + positions[b as usize]) * 0.5);
            positions.len() as u32 - 1
        })
    };
    let mut out = Vec::with_capacity(triangles.len() * 4);
    for &[a, b, c] in triangles {
        let (ab, bc, ca) =
            (midpoint(a, b, &mut positions), midpoint(b, c, &mut positions), midpoint(c, a, &mut positions));
        out.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    (positions, out)
}

/// Vertex clustering: vertices merged per voxel of side `voxel_m`, collapsed triangles dropped.
fn cluster(positions: &[Vec3], triangles: &[[u32; 3]], voxel_m: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut cells: HashMap<IVec3, (u32, Vec3, f32)> = HashMap::new();
    let mut remap = Vec::with_capacity(positions.len());
    for &p in positions {
        let key = (p / voxel_m).floor().as_ivec3();
        let next = cells.len() as u32;
        let cell = cells.entry(key).or_insert((next, Vec3::ZERO, 0.0));
        cell.1 += p;
        cell.2 += 1.0;
        remap.push(cell.0);
    }
    let mut merged = vec![Vec3::ZERO; cells.len()];
    for (index, sum, count) in cells.into_values() {
        merged[index as usize] = sum / count;
    }
    let kept =
        triangles.iter().map(|t| t.map(|i| remap[i as usize])).filter(|[a, b, c]| a != b && b != c && a != c).collect();
    (merged, kept)
}

fn bench(c: &mut Criterion) {
    let Some(data) = shared_data() else {
        return;
    };
    let meshes = read_obj_file(&data.join("obj/makehuman/base.obj"), Some(0.1)).unwrap().value;
    let (mut positions, mut triangles) = (Vec::new(), Vec::new());
    for mesh in &meshes {
        let base = positions.len() as u32;
        positions.extend_from_slice(&mesh.positions);
        triangles.extend(mesh.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    let mut voxel_m = 0.02f32;
    let (control_positions, control_triangles) = loop {
        let (p, t) = cluster(&positions, &triangles, voxel_m);
        if t.len() <= 5_000 {
            break (p, t);
        }
        voxel_m *= 1.1;
    };
    let (mut fine_positions, mut fine_triangles) = (positions, triangles);
    while fine_positions.len() < 100_000 {
        (fine_positions, fine_triangles) = subdivide(&fine_positions, &fine_triangles);
    }
    let name = format!("{}k_vertices_on_{}_triangles", fine_positions.len() / 1000, control_triangles.len());
    let mut group = c.benchmark_group("wrap");
    group.sample_size(10);
    group.bench_function(format!("bind_{name}"), |b| {
        b.iter(|| bind(black_box(&fine_positions), &control_positions, &control_triangles).unwrap())
    });
    let bindings = bind(&fine_positions, &control_positions, &control_triangles).unwrap();
    // A bent control mesh: each vertex turned about the vertical by an angle growing with height.
    let deformed: Vec<Vec3> =
        control_positions.iter().map(|&p| Quat::from_rotation_y(0.3 * p.y) * p + Vec3::new(0.1, 0.0, 0.0)).collect();
    let mut scratch = WrapScratch::default();
    let mut out = vec![Vec3::ZERO; fine_positions.len()];
    group.bench_function(format!("frame_{name}"), |b| {
        b.iter(|| deform_frame(&bindings, black_box(&deformed), &control_triangles, &mut scratch, &mut out))
    });
    group.bench_function(format!("frame_with_normals_{name}"), |b| {
        b.iter(|| {
            deform_frame(&bindings, black_box(&deformed), &control_triangles, &mut scratch, &mut out);
            black_box(Mesh::compute_normals(&out, &fine_triangles))
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
