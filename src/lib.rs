//! kinegraph: a typed dataflow engine for character-animation node graphs.
//!
//! - [`document`]: the RON graph file (versioned on-disk structs and migrations).
//! - [`engine`]: validation into a compiled graph, and the parallel, caching evaluator
//!   that both `kg` and the editor call.
//! - [`cli`]: the `kg` command line.

pub mod cli;
pub mod document;
pub mod engine;

pub use kinegraph_nodes as nodes;
