//! kinegraph's node contract, motion data model, file formats and built-in nodes.
//!
//! Everything here is engine-free: kernels take plain domain values and return new ones,
//! so they can be tested and reused without a graph.

pub mod formats;
pub mod math;
pub mod model;
#[cfg(any(test, feature = "test-support"))]
pub mod test_support;
