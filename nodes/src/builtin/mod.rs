//! The built-in nodes, one file per family; each file holds the pure kernels and the thin
//! node adapters over them.

pub mod arm;
pub mod barnet;
pub mod clip_edit;
pub mod clip_io;
pub mod contacts;
pub mod ik;
pub mod mannequin;
pub mod mesh_io;
pub mod momentum;
pub mod pose_space;
pub mod scalar;
pub mod skin;
pub mod transitions;

use crate::node::Registry;

/// Adds every built-in node to `registry`.
pub fn register(registry: &mut Registry) {
    clip_io::register(registry);
    mesh_io::register(registry);
    clip_edit::register(registry);
    scalar::register(registry);
    mannequin::register(registry);
    contacts::register(registry);
    ik::register(registry);
    momentum::register(registry);
    arm::register(registry);
    skin::register(registry);
    pose_space::register(registry);
    barnet::register(registry);
    transitions::register(registry);
}
