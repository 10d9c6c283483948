//! Fuzz target `obj_reader`: arbitrary bytes into the OBJ reader (tobj underneath).
//!
//! The first byte picks the unit the caller passes (none = metres with the size warning,
//! centimetres, or a huge scale that can overflow `f32`); the rest is the file. The reader
//! must never panic, and whenever it accepts a file every mesh it returns must hold:
//! 1. at least one triangle, and every triangle index names one of the mesh's vertices;
//! 2. one normal per vertex, each finite and of unit length;
//! 3. finite positions, and UVs (when present) one per vertex and finite;
//! 4. the mesh's bounds and the normals recomputed from its triangles are finite (what the
//!    viewport and the skinning nodes do first with a loaded mesh).

#![no_main]

use std::path::Path;

use kinegraph_nodes::formats::obj::read_obj;
use kinegraph_nodes::model::Mesh;
use libfuzzer_sys::fuzz_target;

/// How far from 1 a normal's length may be.
const UNIT_TOL: f32 = 1e-3;

fuzz_target!(|data: &[u8]| {
    let Some((&unit, file)) = data.split_first() else { return };
    let metres_per_unit = match unit % 3 {
        0 => None,
        1 => Some(0.01),
        _ => Some(1e30),
    };
    let Ok(loaded) = read_obj(file, Path::new("fuzz.obj"), metres_per_unit) else {
        return;
    };
    assert!(!loaded.value.is_empty(), "the reader accepted a file but returned no mesh");
    for mesh in &loaded.value {
        let n = mesh.positions.len();
        // 1. Triangles.
        assert!(!mesh.triangles.is_empty(), "mesh '{}' has no triangles", mesh.name);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            assert!(
                tri.iter().all(|&i| (i as usize) < n),
                "mesh '{}' triangle {t} {tri:?} indexes past its {n} vertices",
                mesh.name
            );
        }
        // 2. Normals.
        assert_eq!(mesh.normals.len(), n, "mesh '{}' has {} normals for {n} vertices", mesh.name, mesh.normals.len());
        for (i, normal) in mesh.normals.iter().enumerate() {
            assert!(
                normal.is_finite() && (normal.length() - 1.0).abs() <= UNIT_TOL,
                "mesh '{}' normal {i} is not a finite unit vector: {normal:?}",
                mesh.name
            );
        }
        // 3. Positions and UVs.
        for (i, p) in mesh.positions.iter().enumerate() {
            assert!(p.is_finite(), "mesh '{}' position {i} is not finite: {p:?}", mesh.name);
        }
        if let Some(uvs) = &mesh.uvs {
            assert_eq!(uvs.len(), n, "mesh '{}' has {} UVs for {n} vertices", mesh.name, uvs.len());
            for (i, uv) in uvs.iter().enumerate() {
                assert!(uv.is_finite(), "mesh '{}' UV {i} is not finite: {uv:?}", mesh.name);
            }
        }
        // 4. What consumers compute first.
        if let Some((lo, hi)) = mesh.bounds() {
            assert!(lo.is_finite() && hi.is_finite(), "mesh '{}' bounds are not finite", mesh.name);
        }
        for (i, normal) in Mesh::compute_normals(&mesh.positions, &mesh.triangles).iter().enumerate() {
            assert!(normal.is_finite(), "mesh '{}' recomputed normal {i} is not finite: {normal:?}", mesh.name);
        }
    }
});
