//! The engine: subgraphs expanded ([`expand_subgraphs`]), validation into a
//! [`CompiledGraph`], then evaluation by an [`Engine`] that caches results and runs
//! independent branches in parallel.

mod compile;
mod disk_cache;
mod evaluate;
mod fingerprint;
mod memory;
mod report;
mod subgraph;

pub use compile::{CompiledGraph, CompiledNode, Diagnostic, GraphErrors, OutputFile, compile};
pub use disk_cache::{CacheError, DEFAULT_MAX_BYTES, DiskCache};
pub use evaluate::{Engine, MEMORY_KEEP_RUNS, RunEvent, RunOptions};
pub use fingerprint::{FileIdentity, Fingerprint};
pub use memory::{default_memory_limit, parse_memory_size};
pub use report::{NodeReport, NodeStatus, RunReport};
pub use subgraph::{
    FILE_PARAM_SPEC, FaceParam, FacePort, MAX_DEPTH, SubgraphFace, Unsaved, check_connect, check_face_types,
    compile_file, compile_file_with, expand_subgraphs, face,
};
