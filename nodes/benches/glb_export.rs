//! GLB export time for a synthetic 10,000-frame, 31-joint clip (a CMU-sized skeleton).

#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed unwrap is a failed test

use std::sync::Arc;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::{Quat, Vec3};
use kinegraph_nodes::formats::gltf::write_glb;
use kinegraph_nodes::model::{Clip, ImportScale, Joint, Skeleton};

fn synthetic_clip(frames: usize, joints: usize) -> Clip {
    let list: Vec<Joint> = (0..joints)
        .map(|j| Joint::new(format!("j{j}"), j.checked_sub(1).map(|p| p / 2 * 2), Vec3::new(0.0, 0.1, 0.02)))
        .collect();
    let skeleton = Arc::new(Skeleton::new(list).expect("valid chain"));
    let mut rotations = Vec::with_capacity(frames * joints);
    let mut translations = Vec::with_capacity(frames * joints);
    for f in 0..frames {
        for j in 0..joints {
            let a = (f as f32 * 0.01 + j as f32 * 0.3).sin();
            rotations.push(Quat::from_rotation_x(a) * Quat::from_rotation_z(0.5 * a));
            translations.push(if j == 0 {
                Vec3::new(0.001 * f as f32, 1.0, 0.0)
            } else {
                skeleton.joints()[j].rest_offset
            });
        }
    }
    Clip::new(skeleton, 120.0, rotations, translations, ImportScale::METRES).expect("valid clip")
}

fn bench(c: &mut Criterion) {
    let clip = synthetic_clip(10_000, 31);
    c.bench_function("write_glb 10k frames x 31 joints", |b| b.iter(|| write_glb(std::hint::black_box(&clip), None)));
}

criterion_group!(benches, bench);
criterion_main!(benches);
