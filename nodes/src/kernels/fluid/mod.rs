//! Smoke on tetrahedral meshes (Klingner, Feldman, Chentanez, O'Brien 2006, "Fluid
//! animation with dynamic meshes"): the mesh and its circumcentric dual, the mesher
//! (TetGen, `tetgen` feature), the pressure projection and velocity reconstruction and
//! advection. Metres, seconds, kg/m³, Pa; Y up.
//!
//! | concept | module |
//! |---|---|
//! | tet mesh, faces, circumcentres, adjacency, quality stats | [`mesh`] |
//! | TetGen meshing of a box minus obstacles, Delaunay of points | `mesher` (feature `tetgen`) |
//! | divergence, gradient, pressure solve | [`projection`] |
//! | per-tet and per-node velocity, point sampling, advection | [`velocity`] |
//! | buoyancy, per-tet smoke transfer across meshes, mass totals | [`smoke`] |

pub mod mesh;
#[cfg(feature = "tetgen")]
pub mod mesher;
pub mod projection;
pub mod smoke;
pub mod velocity;
