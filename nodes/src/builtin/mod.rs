//! The built-in nodes, one file per family; each file holds the pure kernels and the thin
//! node adapters over them.

pub mod clip_edit;
pub mod clip_io;
pub mod contacts;
pub mod mannequin;
pub mod mesh_io;
pub mod momentum;
pub mod scalar;

use crate::node::Registry;

/// Adds every built-in node to `registry`.
pub fn register(registry: &mut Registry) {
    clip_io::register(registry);
    mesh_io::register(registry);
    clip_edit::register(registry);
    scalar::register(registry);
    mannequin::register(registry);
    contacts::register(registry);
    momentum::register(registry);
}
