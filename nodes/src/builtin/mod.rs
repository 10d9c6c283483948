//! The built-in nodes, one module per family; each holds its own pure kernels and the thin
//! node adapters over them. What several families share lives one layer down, in
//! [`crate::kernels`]: a family imports kernels, the model, the formats and the contract,
//! never another family. Adding a family is one file here, registered in [`register`].

pub mod arm;
pub mod barnet;
pub mod clip_edit;
pub mod clip_io;
pub mod contacts;
#[cfg(feature = "tetgen")]
pub mod fluid;
pub mod ik;
pub mod mannequin;
pub mod mesh_io;
pub mod momentum;
pub mod physics;
pub mod pose_space;
pub mod quality;
pub mod scalar;
pub mod skin;
pub mod transitions;

use crate::node::Registry;

/// A registry holding every built-in node: the catalogue `kg`, the editor and the tests use.
pub fn registry() -> Registry {
    let mut r = Registry::empty();
    register(&mut r);
    r
}

/// Adds every built-in node to `registry`. Adding a node family is one line here.
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
    quality::register(registry);
    #[cfg(feature = "tetgen")]
    fluid::register(registry);
    physics::register(registry);
}

#[cfg(test)]
mod tests {
    #[test]
    fn nearest_kind_suggests_typos_only() {
        let r = super::registry();
        assert_eq!(r.nearest_kind("clip.lod"), Some("clip.load"));
        assert_eq!(r.nearest_kind("completely.different.thing"), None);
    }
}
