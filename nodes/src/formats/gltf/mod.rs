//! glTF 2.0: reading `.gltf`/`.glb` into skeletons, clips and skinned meshes with their
//! materials, and writing clips (with an optional skinned, textured mesh) as `.glb`.
//!
//! gltf-json parses and validates the JSON; accessor bytes are decoded here with explicit
//! bounds checks so that malformed files give a [`FormatError`] located by JSON path
//! (`/accessors/3`) instead of a panic, and nothing is allocated from an unchecked count.
//!
//! # What the reader makes of a scene
//! - **Skeleton**: the joints of one skin (see [`GltfReadOptions::skin`]) plus any nodes
//!   between them, parents first. Without skins, the animated nodes and the nodes between
//!   them form the skeleton. Non-joint ancestors of the root (an `Armature` or `Z_UP`
//!   node) are baked into the root's rest and animated transform, so world positions match
//!   what a glTF viewer shows. Uniform node scale is baked into translations (exact);
//!   non-uniform scale is averaged with a warning; animated scale is ignored with a warning
//!   when it differs from the node's rest scale.
//! - **Clips**: one per animation, sampled at a fixed rate (see [`GltfReadOptions::sample_fps`]).
//! - **Meshes**: one per node that has a mesh, its triangle primitives merged. Static
//!   meshes are placed in world space. Skinned meshes are re-expressed so that the rest
//!   pose *is* the bind pose where the file allows: positions are the rest-pose skinned
//!   positions and inverse bind matrices are adjusted to match (skinning at any pose gives
//!   exactly what the file's own data would).
//! - **Materials** (only when [`GltfReadOptions::materials`] asks): each primitive's
//!   metallic-roughness material with its textures' encoded images, kept on the merged
//!   mesh as runs of triangles per material (see `material`).

mod accessor;
mod builder;
mod document;
mod material;
mod morph;
mod reader;
mod writer;

pub use builder::GlbChunks;
pub use morph::write_sequence_glb;
pub use reader::{GltfAsset, GltfClip, GltfReadOptions, infer_sample_fps, read_gltf, read_gltf_file};
pub use writer::{DEFAULT_ANIMATION_NAME, GlbAnimation, build_glb, build_glb_animations, write_glb, write_glb_file};

use crate::formats::error::{FormatError, FormatErrorKind, Location};

/// A problem found while reading, located by JSON path; the file name is added at the
/// public boundary. An empty path means the whole file.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ReadError {
    /// JSON pointer such as `/accessors/3`, empty for the whole file.
    pub path: String,
    /// Category.
    pub kind: FormatErrorKind,
    /// Explanation.
    pub message: String,
}

impl ReadError {
    /// An error at JSON path `path`.
    pub fn new(path: impl Into<String>, kind: FormatErrorKind, message: impl Into<String>) -> Self {
        ReadError { path: path.into(), kind, message: message.into() }
    }

    /// An error about the whole file.
    pub fn file(kind: FormatErrorKind, message: impl Into<String>) -> Self {
        Self::new(String::new(), kind, message)
    }

    /// Attaches the file name.
    pub fn into_format_error(self, file: &std::path::Path) -> FormatError {
        let location = if self.path.is_empty() { Location::File } else { Location::JsonPath(self.path) };
        FormatError::new(file, location, self.kind, self.message)
    }
}
