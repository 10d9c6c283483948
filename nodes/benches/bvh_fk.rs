//! BVH parse throughput over the whole corpus and FK throughput on the longest clip.
//! Run: `cargo bench -p kinegraph-nodes --bench bvh_fk`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use kinegraph_nodes::corpus::{files_with_extension, shared_data};
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh};
use kinegraph_nodes::model::forward_kinematics;

fn corpus() -> Vec<(std::path::PathBuf, Vec<u8>)> {
    let Some(data) = shared_data() else {
        return Vec::new();
    };
    files_with_extension(&data.join("bvh"), "bvh")
        .into_iter()
        .filter_map(|p| std::fs::read(&p).ok().map(|b| (p, b)))
        .collect()
}

fn bench(c: &mut Criterion) {
    let files = corpus();
    if files.is_empty() {
        return;
    }
    let total: usize = files.iter().map(|(_, b)| b.len()).sum();
    let mut group = c.benchmark_group("bvh");
    group.throughput(Throughput::Bytes(total as u64));
    group.sample_size(10);
    group.bench_function("parse_whole_corpus", |b| {
        b.iter(|| {
            for (path, bytes) in &files {
                black_box(read_bvh(bytes, Path::new(path), BvhReadOptions::default()).ok());
            }
        })
    });
    group.finish();

    let longest = files
        .iter()
        .filter_map(|(p, b)| read_bvh(b, p, BvhReadOptions::default()).ok().map(|l| l.value.0))
        .max_by_key(|c| c.frame_count() * c.joint_count());
    if let Some(clip) = longest {
        let mut group = c.benchmark_group("fk");
        group.throughput(Throughput::Elements((clip.frame_count() * clip.joint_count()) as u64));
        group.bench_function(format!("whole_clip_{}x{}", clip.frame_count(), clip.joint_count()), |b| {
            b.iter(|| black_box(forward_kinematics(black_box(&clip))))
        });
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
