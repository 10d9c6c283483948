//! One simulation step of the standing 16-body figure built from a real CMU skeleton
//! (02_01), with ground contacts and PD motors, at the default 1/300 s step (4 substeps);
//! real-time factor = (1/300 s) / step cost. Also a bare chain of N capsules on ball joints
//! (no contacts) for how the cost grows with the number of bodies. And a whole
//! `simulate` of a push script (3 s: a 45 N·s chest shove at 0.5 s, balance → step →
//! …), which adds what the supervisor and the state sensing cost per step; its real-time
//! factor is 3 s / the measured time, printed once before the measurement.
//! Run: `cargo bench -p kinegraph-nodes --bench physics_step`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use glam::Vec3;
use kinegraph_nodes::cancel::Cancel;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::physics::figure::{FigureParams, build_figure};
use kinegraph_nodes::kernels::physics::simulate::{Push, Script, SimParams, simulate};
use kinegraph_nodes::kernels::physics::{World, WorldParams};
use rapier3d::prelude::*;

fn figure_step(c: &mut Criterion) {
    let Some(data) = shared_data() else { return };
    let (clip, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    let skeleton = clip.skeleton().clone();
    let figure = build_figure(&skeleton, &FigureParams::default(), None).unwrap();
    let mut world = World::new(WorldParams::default()).unwrap();
    world.add_ground(0.0, 0.9);
    figure.spawn(&mut world, &skeleton, Vec3::new(0.0, -figure.rest_sole_y_m, 0.0));
    // Settle onto the ground first, so the contacts are in place.
    for _ in 0..300 {
        world.step();
    }
    c.bench_function("physics_step/cmu_figure_16_bodies", |b| b.iter(|| world.step()));
}

fn chain_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("physics_step/chain");
    for n in [4usize, 8, 16, 32] {
        let mut w = World::new(WorldParams { gravity_m_s2: 0.0, ..WorldParams::default() }).unwrap();
        let mut handles = Vec::new();
        for i in 0..n {
            let body = w.inner.bodies.insert(RigidBodyBuilder::dynamic().can_sleep(false).translation(Vector::new(
                0.0,
                0.5 * i as f32,
                0.0,
            )));
            w.inner.colliders.insert_with_parent(ColliderBuilder::capsule_y(0.15, 0.05), body, &mut w.inner.bodies);
            handles.push(body);
        }
        for i in 1..n {
            let joint = SphericalJointBuilder::new()
                .local_anchor1(Vector::new(0.0, 0.25, 0.0))
                .local_anchor2(Vector::new(0.0, -0.25, 0.0));
            w.inner.multibody_joints.insert(handles[i - 1], handles[i], joint, true);
        }
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| b.iter(|| w.step()));
    }
    group.finish();
}

fn simulate_push(c: &mut Criterion) {
    let Some(data) = shared_data() else { return };
    let (clip, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    let skeleton = clip.skeleton().clone();
    let figure = build_figure(&skeleton, &FigureParams::default(), None).unwrap();
    let script = Script {
        duration_secs: 3.0,
        controllers: None,
        requests: vec![],
        pushes: vec![Push {
            body: "chest".into(),
            direction: figure.forward.to_array(),
            impulse_ns: 45.0,
            at_secs: 0.5,
            duration_secs: 0.1,
        }],
        chair: None,
    };
    let params = SimParams::default();
    let run = || simulate(&skeleton, None, &script, &params, Cancel::NEVER).unwrap();
    let start = std::time::Instant::now();
    let r = run();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "simulate 3 s push script: {} steps in {secs:.3} s, {:.1}× real time, {:.1} µs per step",
        r.steps,
        f64::from(script.duration_secs) / secs,
        secs / r.steps as f64 * 1e6
    );
    let mut group = c.benchmark_group("physics_simulate");
    group.sample_size(10);
    group.bench_function("cmu_push_script_3s", |b| b.iter(run));
    group.finish();
}

criterion_group!(benches, figure_step, chain_step, simulate_push);
criterion_main!(benches);
