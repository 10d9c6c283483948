//! Baked mesh animations: one set of deformed positions and normals per frame of a clip.

use std::sync::Arc;

use glam::Vec3;

use super::clip::Clip;
use super::mesh::Mesh;

/// Why a mesh sequence cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshSequenceError {
    /// The buffers do not hold `frames × vertices` entries.
    #[error(
        "a mesh sequence needs {expected} positions and normals ({frames} frames × {vertices} vertices), got {got}"
    )]
    BadLength {
        /// Entries needed.
        expected: usize,
        /// Entries given (the shorter buffer).
        got: usize,
        /// Frames of the clip.
        frames: usize,
        /// Vertices of the rest mesh.
        vertices: usize,
    },
    /// A position or normal is NaN or infinite.
    #[error("non-finite deformed vertex {vertex} at frame {frame}")]
    NonFinite {
        /// Frame index.
        frame: usize,
        /// Vertex index.
        vertex: usize,
    },
}

/// A deformed mesh per frame of a clip (metres, Y up, world space).
///
/// Frame-major storage (`[frame * vertices + vertex]`), like [`Clip`], because deformers and
/// exporters produce and consume a whole frame at a time.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MeshSequence {
    /// Topology, UVs and (when skinned) the bind of the undeformed mesh.
    pub rest: Arc<Mesh>,
    /// The motion: frame `f` of the sequence is the mesh at frame `f` of this clip.
    pub clip: Arc<Clip>,
    positions_m: Vec<Vec3>,
    normals: Vec<Vec3>,
}

impl MeshSequence {
    /// Bytes of the baked positions and normals of `frames` frames of `vertices` vertices:
    /// the estimate nodes check before baking.
    pub fn estimated_bytes(frames: usize, vertices: usize) -> u64 {
        (frames as u64).saturating_mul(vertices as u64).saturating_mul(24)
    }

    /// Checks sizes and finiteness, so consumers can index without further checks.
    pub fn new(
        rest: Arc<Mesh>,
        clip: Arc<Clip>,
        positions_m: Vec<Vec3>,
        normals: Vec<Vec3>,
    ) -> Result<Self, MeshSequenceError> {
        let vertices = rest.positions.len();
        let frames = clip.frame_count();
        let expected = frames * vertices;
        if positions_m.len() != expected || normals.len() != expected {
            return Err(MeshSequenceError::BadLength {
                expected,
                got: positions_m.len().min(normals.len()),
                frames,
                vertices,
            });
        }
        if let Some(i) = positions_m.iter().zip(&normals).position(|(p, n)| !p.is_finite() || !n.is_finite()) {
            return Err(MeshSequenceError::NonFinite { frame: i / vertices.max(1), vertex: i % vertices.max(1) });
        }
        Ok(MeshSequence { rest, clip, positions_m, normals })
    }

    /// Number of frames (the clip's).
    pub fn frame_count(&self) -> usize {
        self.clip.frame_count()
    }

    /// Vertices per frame (the rest mesh's).
    pub fn vertex_count(&self) -> usize {
        self.rest.positions.len()
    }

    /// Deformed positions (metres) at `frame`.
    pub fn frame_positions(&self, frame: usize) -> &[Vec3] {
        let n = self.vertex_count();
        &self.positions_m[frame * n..(frame + 1) * n]
    }

    /// Deformed unit normals at `frame`.
    pub fn frame_normals(&self, frame: usize) -> &[Vec3] {
        let n = self.vertex_count();
        &self.normals[frame * n..(frame + 1) * n]
    }

    /// All positions, frame-major.
    pub fn positions_m(&self) -> &[Vec3] {
        &self.positions_m
    }

    /// The mesh at `frame` as a plain, unskinned mesh (for wrapping or export).
    pub fn frame_mesh(&self, frame: usize) -> Mesh {
        Mesh {
            name: self.rest.name.clone(),
            positions: self.frame_positions(frame).to_vec(),
            normals: self.frame_normals(frame).to_vec(),
            uvs: self.rest.uvs.clone(),
            triangles: self.rest.triangles.clone(),
            skin: None,
            materials: self.rest.materials.clone(),
            material_ranges: self.rest.material_ranges.clone(),
            parts: self.rest.parts.clone(),
        }
    }
}
