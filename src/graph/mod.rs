//! The graph in memory: typed ids ([`NodeId`], [`PortRef`], [`ParamPath`]), the
//! [`Graph`] with its edits, the one set of [`rules`] that `kg check` and the editor share,
//! [`Overrides`] (settings from outside the file) and located [`Diagnostic`]s.
//!
//! [`crate::document`] is the file's form on disk; a file is read into a
//! [`Graph`] once ([`GraphFile::load`]) and everything else works on that.

mod diagnostics;
mod error;
mod ids;
mod model;
mod overrides;
pub mod rules;

use std::path::{Path, PathBuf};

pub use diagnostics::{Diagnostic, GraphErrors, located};
pub use error::{GraphError, Side, Subject};
pub use ids::{MAX_ID_CHARS, NodeId, ParamPath, PortRef};
pub use model::{Edge, Graph, GraphNode, Ports, Removal, RemovedNode};
pub use overrides::{OverrideError, Overrides, Setting, is_input_file};

use kinegraph_nodes::node::Registry;

use crate::document::{self, DocumentError, SourceMap};

/// A graph read from a file, with what is needed to point back into the file.
#[derive(Clone, Debug)]
pub struct GraphFile {
    /// The graph.
    pub graph: Graph,
    /// Positions of the file's nodes, params, edges and inputs.
    pub source: SourceMap,
    /// The file it was read from.
    pub path: PathBuf,
    /// The version found in the file before migration.
    pub file_version: u32,
}

/// Why a graph file could not be read into a [`Graph`].
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// Unreadable, not a graph file, or not valid RON.
    #[error(transparent)]
    Document(#[from] DocumentError),
    /// Valid RON whose edges or inputs are not `"node.port"` / `"node.param"`.
    #[error(transparent)]
    Structure(#[from] GraphErrors),
}

impl GraphFile {
    /// Reads and migrates a graph file.
    pub fn load(path: &Path) -> Result<GraphFile, LoadError> {
        Self::from_loaded(document::load_file(path)?)
    }

    /// Reads a graph file and applies `settings` to it (`--set`, a batch input, a farm
    /// task's bindings); the error text names the file and is ready to print.
    pub fn load_with(path: &Path, settings: &[Setting], registry: &Registry) -> Result<GraphFile, String> {
        let mut loaded = GraphFile::load(path).map_err(|e| e.to_string())?;
        Overrides(settings.to_vec())
            .apply(&mut loaded.graph, registry)
            .map_err(|e| format!("{}: --set {e}", path.display()))?;
        Ok(loaded)
    }

    /// Reads graph text; `path` names the file in errors and anchors relative paths.
    pub fn parse(text: &str, path: &Path) -> Result<GraphFile, LoadError> {
        Self::from_loaded(document::parse(text, path)?)
    }

    fn from_loaded(loaded: document::LoadedGraph) -> Result<GraphFile, LoadError> {
        let graph = Graph::from_doc(&loaded.doc).map_err(|errors| located(&loaded.path, &loaded.source, errors))?;
        Ok(GraphFile { graph, source: loaded.source, path: loaded.path, file_version: loaded.file_version })
    }

    /// A graph made in memory (e.g. by `kg convert`), named `path` in messages.
    pub fn in_memory(graph: Graph, path: &Path) -> GraphFile {
        GraphFile {
            graph,
            source: SourceMap::default(),
            path: path.to_path_buf(),
            file_version: document::CURRENT_VERSION,
        }
    }

    /// Folder that relative input paths resolve against.
    pub fn base_dir(&self) -> PathBuf {
        self.path.parent().map(Path::to_path_buf).unwrap_or_default()
    }
}
