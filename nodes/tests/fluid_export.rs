//! Volume and particle exports (issue 17), read back by independent readers: OpenVDB's own
//! library through Debian's `python3-openvdb` for `.vdb` files (CI installs it; outside CI
//! the test says it is skipped when the module is missing), and a plain PLY header parse.
#![allow(clippy::unwrap_used, clippy::expect_used)] // test code: a failed expect is a failed test

use std::path::Path;
use std::process::Command;

use glam::IVec3;
use kinegraph_nodes::formats::ply::write_points_ply;
use kinegraph_nodes::formats::vdb::{GridValues, VdbGrid, write_vdb};
use kinegraph_nodes::model::volume::VoxelGrid;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A Python with OpenVDB's bindings, or `None` (a failure under CI=1).
fn openvdb_python() -> Option<&'static str> {
    for python in ["python3", "/usr/bin/python3"] {
        let ok = Command::new(python).args(["-c", "import pyopenvdb"]).output().is_ok_and(|o| o.status.success());
        if ok {
            return Some(python);
        }
    }
    assert!(std::env::var_os("CI").is_none(), "CI needs python3-openvdb (apt-get install python3-openvdb)");
    eprintln!("skipped: no python3 with pyopenvdb (apt-get install python3-openvdb)");
    None
}

fn read_back(python: &str, path: &Path) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/tools/read_vdb.py");
    let out = Command::new(python).arg(script).arg(path).output().expect("run python");
    assert!(out.status.success(), "reader failed: {}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("json")
}

#[test]
fn vdb_grids_read_back_by_openvdb_hold_the_written_values() {
    let Some(python) = openvdb_python() else { return };
    // A lattice across an upper-node boundary (x = 0), a lower-node boundary (z = 128) and
    // many leaves, with about a third of the voxels empty (inactive).
    let grid = VoxelGrid { origin: IVec3::new(-13, -3, 117), dims: [30, 11, 19], voxel_m: 0.05 };
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let density: Vec<f32> =
        (0..grid.len()).map(|_| if rng.gen_bool(0.35) { 0.0 } else { rng.gen_range(-2.0..3.0) }).collect();
    let velocity: Vec<[f32; 3]> = (0..grid.len())
        .map(|_| if rng.gen_bool(0.35) { [0.0; 3] } else { [rng.r#gen(), rng.gen_range(-1.0..1.0), 0.0] })
        .collect();
    let bytes = write_vdb(
        &grid,
        &[
            VdbGrid { name: "density", values: GridValues::Float(&density) },
            VdbGrid { name: "velocity", values: GridValues::Vec3(&velocity) },
        ],
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.vdb");
    std::fs::write(&path, &bytes).unwrap();
    let read = read_back(python, &path);

    let check = |name: &str, width: usize, expected: &dyn Fn(usize) -> Vec<f32>, zero: &dyn Fn(usize) -> bool| {
        let g = &read[name];
        let size = g["voxel_size"].as_array().unwrap();
        assert!(size.iter().all(|s| (s.as_f64().unwrap() - 0.05f32 as f64).abs() < 1e-12), "{size:?}");
        let voxels = g["voxels"].as_array().unwrap();
        let active = (0..grid.len()).filter(|&n| !zero(n)).count();
        assert_eq!(voxels.len(), active, "{name}: active voxel count");
        for v in voxels {
            let v: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
            let c = IVec3::new(v[0] as i32, v[1] as i32, v[2] as i32) - grid.origin;
            assert!(
                c.cmpge(IVec3::ZERO).all()
                    && (c.as_uvec3().to_array().iter().zip(grid.dims).all(|(a, d)| (*a as usize) < d))
            );
            let n = grid.index(c.x as usize, c.y as usize, c.z as usize);
            let want = expected(n);
            assert_eq!(v.len(), 3 + width);
            for k in 0..width {
                assert_eq!(v[3 + k] as f32, want[k], "{name} at {c}");
            }
        }
    };
    check("density", 1, &|n| vec![density[n]], &|n| density[n] == 0.0);
    check("velocity", 3, &|n| velocity[n].to_vec(), &|n| velocity[n] == [0.0; 3]);
    assert_eq!(read["density"]["type"], "float");
    assert_eq!(read["velocity"]["type"], "vec3s");
}

#[test]
fn ply_points_parse_back_from_header_and_body() {
    let points = [[0.5f32, 1.25, -3.0], [1e-3, 2.0, 7.5], [0.0, 0.0, 0.0]];
    let bytes = write_points_ply(&points, "Y");
    let end = b"end_header\n";
    let at = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
    assert!(header.contains("element vertex 3\n"));
    let body = &bytes[at..];
    assert_eq!(body.len(), 36);
    let floats: Vec<f32> = body.chunks(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    assert_eq!(floats, points.iter().flatten().copied().collect::<Vec<_>>());
}
