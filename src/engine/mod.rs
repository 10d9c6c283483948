//! The engine: subgraphs expanded ([`expand_subgraphs`]), validation into a
//! [`CompiledGraph`], then evaluation by an [`Engine`] that caches results and runs
//! independent branches in parallel.

mod compile;
mod evaluate;
mod report;
mod subgraph;

pub use compile::{CompiledGraph, CompiledNode, Diagnostic, GraphErrors, OutputFile, compile};
pub use evaluate::{Engine, RunEvent, RunOptions};
pub use report::{NodeReport, NodeStatus, RunReport};
pub use subgraph::{MAX_DEPTH, compile_file, expand_subgraphs};
