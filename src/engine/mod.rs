//! The engine: validation into a [`CompiledGraph`], then evaluation by an [`Engine`]
//! that caches results and runs independent branches in parallel.

mod compile;
mod evaluate;
mod report;

pub use compile::{CompiledGraph, CompiledNode, Diagnostic, GraphErrors, OutputFile, compile};
pub use evaluate::{Engine, RunEvent, RunOptions};
pub use report::{NodeReport, NodeStatus, RunReport};
