//! Reading and writing the files users have: BVH, glTF/GLB and OBJ; reading FBX; writing
//! OpenVDB volumes and PLY points.

pub mod atomic;
pub mod bone_map;
pub mod bvh;
pub mod error;
pub mod fbx;
pub mod gltf;
pub mod obj;
pub mod ply;
pub mod vdb;

pub use error::{FormatError, FormatErrorKind, Loaded, Location};

/// The lowercase extension of `path` without the dot (`""` when it has none), which is
/// how every loader picks a format.
pub fn extension(path: &std::path::Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default()
}
