//! Triangle meshes and their skin bindings.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};

use super::skeleton::Skeleton;

/// Per-vertex joint influences and the bind pose of a skinned mesh.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Skin {
    /// The skeleton the joint indices refer to.
    pub skeleton: Arc<Skeleton>,
    /// Up to four joint indices per vertex (into `skeleton`).
    pub joints: Vec<[u16; 4]>,
    /// Matching weights per vertex, each row summing to one.
    pub weights: Vec<[f32; 4]>,
    /// Per skeleton joint: the inverse of its world transform in the bind pose (metres).
    pub inverse_bind_matrices: Vec<Mat4>,
}

/// A triangle mesh (metres, Y up), optionally skinned.
#[derive(Clone, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Mesh {
    /// Name from the source file.
    pub name: String,
    /// Vertex positions (metres).
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, one per position.
    pub normals: Vec<Vec3>,
    /// Texture coordinates, one per position, when the source had them.
    pub uvs: Option<Vec<Vec2>>,
    /// Counter-clockwise triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Skin binding, if the mesh deforms with a skeleton.
    pub skin: Option<Skin>,
}

impl Mesh {
    /// Bytes a skinned mesh of this size holds (positions, normals, UVs, four joints and
    /// weights per vertex, triangles): the estimate nodes check before building one.
    pub fn estimated_bytes(vertices: usize, triangles: usize) -> u64 {
        const PER_VERTEX: u64 = 12 + 12 + 8 + 8 + 16;
        (vertices as u64).saturating_mul(PER_VERTEX).saturating_add((triangles as u64).saturating_mul(12))
    }

    /// Area-weighted vertex normals from the triangles; vertices no triangle touches (or
    /// touched only by degenerate triangles) get +Y rather than NaN.
    pub fn compute_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; positions.len()];
        for tri in triangles {
            let [a, b, c] = tri.map(|i| i as usize);
            let (Some(pa), Some(pb), Some(pc)) = (positions.get(a), positions.get(b), positions.get(c)) else {
                continue;
            };
            let n = (*pb - *pa).cross(*pc - *pa);
            for i in [a, b, c] {
                normals[i] += n;
            }
        }
        normals.into_iter().map(|n| n.try_normalize().unwrap_or(Vec3::Y)).collect()
    }

    /// Axis-aligned bounds `(min, max)` of the positions, `None` when empty.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_a_ccw_quad_point_up_and_degenerate_ones_stay_finite() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, -1.0), Vec3::ZERO];
        let normals = Mesh::compute_normals(&positions, &[[0, 1, 2], [0, 2, 3], [4, 4, 4]]);
        for n in &normals[..4] {
            assert!((*n - Vec3::Y).length() < 1e-6);
        }
        assert_eq!(normals[4], Vec3::Y);
    }
}
