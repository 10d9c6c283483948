//! Smoke on tetrahedral meshes (Klingner, Feldman, Chentanez, O'Brien 2006, "Fluid
//! animation with dynamic meshes"): the mesh and its circumcentric dual, the mesher
//! (TetGen, `tetgen` feature), the pressure projection and velocity reconstruction and
//! advection. Metres, seconds, kg/m³, Pa; Y up.
//!
//! | concept | module |
//! |---|---|
//! | tet mesh, faces, circumcentres, adjacency, quality stats | [`mesh`] |
//! | TetGen meshing of a box minus obstacles, Delaunay of points | `mesher` (feature `tetgen`) |
//! | divergence, gradient, pressure solve (with rigid bodies coupled in) | [`projection`] |
//! | per-tet and per-node velocity, point sampling, advection | [`velocity`] |
//! | buoyancy, per-tet smoke transfer across meshes, mass totals | [`smoke`] |
//! | sizing field, node placement warm-started from the last step, relaxation | `remesh` (feature `tetgen`) |
//! | dynamic rigid bodies: mass, surface, buoyancy, wall contact | `rigid` (feature `tetgen`) |
//! | the step loop: remesh, advect, sources, obstacles, projection, particles, resampling | `sim` (feature `tetgen`) |

pub mod mesh;
#[cfg(feature = "tetgen")]
pub mod mesher;
pub mod projection;
#[cfg(feature = "tetgen")]
pub mod remesh;
#[cfg(feature = "tetgen")]
pub mod rigid;
#[cfg(feature = "tetgen")]
pub mod sim;
pub mod smoke;
pub mod velocity;
