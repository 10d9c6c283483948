//! Reading and writing the files users have: BVH, glTF/GLB and OBJ.

pub mod atomic;
pub mod bvh;
pub mod error;
pub mod gltf;
pub mod obj;

pub use error::{FormatError, FormatErrorKind, Loaded, Location};
