//! Bar-net solver on a 100 × 100 grid of free nodes (10,000) inside a fixed border:
//! factorisation (symbolic + numeric, and numeric alone) and a re-solve for new loads.
//! Run: `cargo bench -p kinegraph-nodes --bench barnet`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use kinegraph_nodes::builtin::barnet::{FdmSolver, square_grid_net};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let net = square_grid_net(102, 0.01).unwrap();
    assert_eq!(net.free_count(), 10_000);
    let mut group = c.benchmark_group("barnet_10k_free");
    group.sample_size(20);
    group.bench_function("factor_symbolic_and_numeric", |b| b.iter(|| FdmSolver::new(black_box(&net)).unwrap()));
    let mut solver = FdmSolver::new(&net).unwrap();
    let q2: Vec<f64> = net.force_density.iter().map(|q| q * 1.5).collect();
    group.bench_function("refactor_numeric_only", |b| b.iter(|| solver.refactor(black_box(&q2)).unwrap()));
    let loads: Vec<Vec3> = (0..10_000).map(|i| Vec3::new(0.0, 0.0, 0.01 * ((i % 13) as f32 - 6.0))).collect();
    group.bench_function("resolve_new_loads", |b| {
        b.iter(|| solver.solve(black_box(&loads), &net.control.positions).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
