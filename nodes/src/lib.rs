//! kinegraph's node contract, motion data model, file formats, shared kernels and built-in
//! nodes.
//!
//! Everything here is engine-free: kernels take plain domain values and return new ones,
//! so they can be tested and reused without a graph.
//!
//! Layers, lowest first; a module imports only from its own layer or lower ones, and a
//! node family (a module of `builtin`) never imports another family
//! (`nodes/tests/layers.rs` checks it):
//! 1. `math` (and `corpus`, the shared-data locator for tests and benchmarks, and `cancel`,
//!    the stop request long kernels poll: std only);
//! 2. `model`: skeletons, clips, meshes, reports, name hints;
//! 3. `formats`: BVH, glTF, OBJ and bone-map files;
//! 4. `kernels`: motion operations several node families share;
//! 5. `node`: the node contract;
//! 6. `builtin`: the node families and `builtin::registry()`.

pub mod builtin;
pub mod cancel;
pub mod corpus;
pub mod formats;
pub mod kernels;
pub mod math;
pub mod model;
pub mod node;
