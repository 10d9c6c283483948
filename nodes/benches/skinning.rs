//! Skinning throughput on the generated arm at the paper's mid resolution (11,618
//! vertices, 4 influences each): LBS against a plain single-threaded loop, and WPSD frames
//! per second with 8 sample poses.
//! Run: `cargo bench -p kinegraph-nodes --bench skinning`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::{Affine3A, Mat4, Vec3};
use kinegraph_nodes::builtin::barnet::{LoadParams, Selection, build, deform_net};
use kinegraph_nodes::builtin::pose_space::{PoseSpaceModel, PoseSpaceParams};
use kinegraph_nodes::kernels::arm::{SAMPLE_POSES, arm_clip, arm_flex_clip, arm_mesh};
use kinegraph_nodes::kernels::pose_vector::pose_vector;
use kinegraph_nodes::kernels::skinning::{AutoWeightParams, BindMode, bind, clip_skinning_matrices, lbs_frame};
use kinegraph_nodes::model::{Mesh, Skin};

/// 363 rings × 32 segments + 2 caps = 11,618 vertices.
fn arm() -> Arc<Mesh> {
    let clip = arm_flex_clip(2, 24.0).unwrap();
    Arc::new(bind(&arm_mesh(363, 32), clip.skeleton(), BindMode::Automatic, AutoWeightParams::default()).unwrap())
}

/// The straightforward reference: per vertex and influence, a full 4×4 matrix times the
/// point and the normal, summed; one thread.
fn lbs_plain(
    positions: &[Vec3],
    normals: &[Vec3],
    skin: &Skin,
    matrices: &[Mat4],
    out_p: &mut [Vec3],
    out_n: &mut [Vec3],
) {
    for v in 0..positions.len() {
        let mut p = Vec3::ZERO;
        let mut n = Vec3::ZERO;
        for k in 0..4 {
            let m = &matrices[skin.joints[v][k] as usize];
            let w = skin.weights[v][k];
            p += w * m.transform_point3(positions[v]);
            n += w * m.transform_vector3(normals[v]);
        }
        out_p[v] = p;
        out_n[v] = n.normalize_or_zero();
    }
}

fn bench(c: &mut Criterion) {
    let mesh = arm();
    let skin = mesh.skin.as_ref().unwrap();
    let n = mesh.positions.len();
    let clip = Arc::new(arm_flex_clip(24, 24.0).unwrap());
    let joints = clip.joint_count();
    let all = clip_skinning_matrices(&clip, skin);
    let frame = 12;
    let affine: &[Affine3A] = &all[frame * joints..(frame + 1) * joints];
    let mat4: Vec<Mat4> = affine.iter().map(|a| Mat4::from(*a)).collect();
    let influences = skin.weights.iter().map(|w| w.iter().filter(|x| **x > 0.0).count()).sum::<usize>();
    eprintln!("arm: {n} vertices, {:.2} influences per vertex on average", influences as f64 / n as f64);
    let (mut out_p, mut out_n) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);

    let mut group = c.benchmark_group("lbs");
    group.throughput(Throughput::Elements(n as u64));
    group.bench_function("plain_loop", |b| {
        b.iter(|| lbs_plain(&mesh.positions, &mesh.normals, skin, black_box(&mat4), &mut out_p, &mut out_n))
    });
    group.bench_function("kinegraph", |b| {
        b.iter(|| lbs_frame(&mesh.positions, &mesh.normals, skin, black_box(affine), &mut out_p, &mut out_n))
    });
    group.finish();

    // WPSD: 8 sample shapes from the bar-net (biceps bulge), one frame = positions + normals.
    let biceps = Selection::Box(Vec3::new(0.11, 1.34, 0.012), Vec3::new(0.31, 1.46, 0.1));
    let net = build(mesh.clone(), &biceps, 1.0, 1.0).unwrap();
    let loads = LoadParams { driver: Some(2), ramp_start_rad: 0.2, ramp_full_rad: 2.0, bulge_n: 0.05, pressure_n: 0.0 };
    let samples = deform_net(&net, &Arc::new(arm_clip(&SAMPLE_POSES, 24.0).unwrap()), &loads).unwrap();
    let mut group = c.benchmark_group("wpsd");
    group.sample_size(20);
    for (name, params) in [
        (
            "psd_frame",
            PoseSpaceParams {
                distance: kinegraph_nodes::builtin::pose_space::PoseDistance::Uniform,
                ..PoseSpaceParams::default()
            },
        ),
        ("wpsd_frame", PoseSpaceParams::default()),
    ] {
        let model = PoseSpaceModel::train(&mesh, &samples, params).unwrap();
        let pose = pose_vector(clip.skeleton(), clip.frame_rotations(frame));
        let mut scratch = model.scratch(n);
        group.bench_function(name, |b| {
            b.iter(|| {
                model.deform_frame(&mesh, skin, black_box(&pose), affine, &mut out_p, &mut scratch);
                black_box(Mesh::compute_normals(&out_p, &mesh.triangles))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
