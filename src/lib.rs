//! kinegraph: a typed dataflow engine for character-animation node graphs.
//!
//! - [`document`]: the RON graph file (versioned on-disk structs and migrations).
//! - [`graph`]: the graph in memory (typed ids, edits, the validation rules, overrides).
//! - [`engine`]: validation into a compiled graph, and the parallel, caching evaluator
//!   that both `kg` and the editor call.
//! - [`editor`]: the editor's command reducer and undo history; with the `editor`
//!   feature, the egui node editor behind `kg edit`.
//! - [`farm`]: plans, task attempts, per-task reports and farm submission files (`kg plan`,
//!   `kg run --plan`, `kg emit`).
//! - [`output`]: how kg writes into an output folder: safe atomic writes, the folder's
//!   lock, task leases, and the removal of temporary files of runs that died.
//! - [`regression`]: saved graphs as regression tests (`kg test`): facts of every
//!   output compared with `NAME.expect.ron`, and quality gates.
//! - [`cli`]: the `kg` command line.
//! - [`digest`]: SHA-256 of bytes and files, one way for every part.

pub mod cli;
pub mod digest;
pub mod document;
pub mod editor;
pub mod engine;
pub mod farm;
pub mod graph;
pub mod output;
pub mod regression;

pub use kinegraph_nodes as nodes;
