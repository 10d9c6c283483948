//! Bar-net solver on a 100 × 100 grid of free nodes (10,000) inside a fixed border:
//! factorisation (symbolic + numeric, and numeric alone) and a re-solve for new loads.
//! Run: `cargo bench -p kinegraph-nodes --bench barnet`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;
use kinegraph_nodes::builtin::barnet::FdmSolver;
use kinegraph_nodes::model::{BarNet, Mesh};

fn grid(n: usize) -> BarNet {
    let positions = (0..n * n).map(|i| Vec3::new((i % n) as f32 * 0.01, (i / n) as f32 * 0.01, 0.0)).collect();
    let mut bars = Vec::new();
    for i in 0..n * n {
        if i % n + 1 < n {
            bars.push([i as u32, i as u32 + 1]);
        }
        if i / n + 1 < n {
            bars.push([i as u32, (i + n) as u32]);
        }
    }
    let q = (0..bars.len()).map(|b| 1.0 + (b % 7) as f64 * 0.1).collect();
    let free = (0..n * n).map(|i| i % n != 0 && i / n != 0 && i % n != n - 1 && i / n != n - 1).collect();
    BarNet::new(Arc::new(Mesh { positions, ..Mesh::default() }), bars, q, free).unwrap()
}

fn bench(c: &mut Criterion) {
    let net = grid(102);
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
