//! The node contract: schemas with typed ports and parameters, the [`Node`] trait, errors,
//! and the registry nodes are added to. The contract names no built-in node: the built-in
//! catalogue is `crate::builtin::registry()`, one layer up.

mod context;
mod param;
mod port;
mod value;

use std::collections::BTreeMap;
use std::sync::Arc;

pub use context::{NodeContext, NodeOutcome, RunServices};
pub use param::{
    ChoiceParam, FloatParam, InputFolderParam, InputPathParam, IntParam, OutputPathParam, ParamKind, ParamSpec,
    ParamValue, TextParam,
};
pub use port::{Input, Output, PROPS_PORT, PortSpec};
pub use value::{PortType, PortValue, Report, Value, into_report, report_of};

pub use crate::model::choice::{Choice, OnOff};
pub use crate::model::names::{did_you_mean, edit_distance, hint_for, nearest_name};

use crate::formats::FormatError;

/// Everything the engine, the catalogue and the editor know about a node kind.
#[derive(Debug, serde::Serialize)]
pub struct NodeSchema {
    /// Stable persisted kind, e.g. `"clip.load"`. Renaming it is a file-format change.
    pub kind: &'static str,
    /// Menu group in the editor and catalogue (`"io"`, `"clip"`, …).
    pub category: &'static str,
    /// What the node does, for animators (tooltip and catalogue text).
    pub doc: &'static str,
    /// Input ports.
    pub inputs: &'static [PortSpec],
    /// Output ports.
    pub outputs: &'static [PortSpec],
    /// Parameters.
    pub params: &'static [ParamSpec],
    /// Writes files: never served from the cache, and run only with an output folder.
    pub writes_files: bool,
    /// The node's algorithm version, part of every cache key: bump it when the same inputs
    /// and parameters give different results, so cached results of the old version are not
    /// served (also those kept on disk between runs).
    pub version: u32,
}

impl NodeSchema {
    /// The input port called `name`.
    pub fn input(&self, name: &str) -> Option<&PortSpec> {
        self.inputs.iter().find(|p| p.name == name)
    }

    /// The output port called `name`.
    pub fn output(&self, name: &str) -> Option<&PortSpec> {
        self.outputs.iter().find(|p| p.name == name)
    }

    /// The parameter called `name`.
    pub fn param(&self, name: &str) -> Option<&ParamSpec> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// Why a node failed. The engine adds the node id.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NodeError {
    /// An input is missing or unusable.
    #[error("input '{port}' {message}")]
    Input {
        /// Port name.
        port: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A parameter is missing or unusable.
    #[error("parameter '{param}' {message}")]
    Param {
        /// Parameter name.
        param: &'static str,
        /// What is wrong.
        message: String,
    },
    /// A file could not be read or written.
    #[error(transparent)]
    Format(#[from] FormatError),
    /// A kernel could not produce a result: its typed error, kept whole with its sources.
    #[error(transparent)]
    Kernel(KernelError),
    /// The node could not produce a result for a reason of its own (no kernel error).
    #[error("{0}")]
    Failed(String),
    /// The run was cancelled.
    #[error("cancelled")]
    Cancelled,
}

impl From<crate::cancel::Cancelled> for NodeError {
    fn from(_: crate::cancel::Cancelled) -> Self {
        NodeError::Cancelled
    }
}

impl NodeError {
    /// An input error.
    pub fn input(port: &'static str, message: impl Into<String>) -> Self {
        NodeError::Input { port, message: message.into() }
    }

    /// A parameter error.
    pub fn param(param: &'static str, message: impl Into<String>) -> Self {
        NodeError::Param { param, message: message.into() }
    }

    /// The message followed by each underlying cause it does not already quote, so a run's
    /// report shows the whole chain, each part once.
    pub fn with_causes(&self) -> String {
        let mut text = self.to_string();
        let mut cause = std::error::Error::source(self);
        while let Some(c) = cause {
            let said = c.to_string();
            if !text.contains(&said) {
                text.push_str(": ");
                text.push_str(&said);
            }
            cause = c.source();
        }
        text
    }

    /// A kernel's failure, e.g. `.map_err(NodeError::kernel)`.
    pub fn kernel(error: impl std::error::Error + Send + Sync + 'static) -> Self {
        NodeError::Kernel(KernelError(Arc::new(error)))
    }
}

/// A kernel's typed error inside a [`NodeError`]: shared, so node errors stay cheap to
/// clone, and shown as the kernel words it, its sources following.
#[derive(Debug, Clone)]
pub struct KernelError(Arc<dyn std::error::Error + Send + Sync>);

impl KernelError {
    /// The kernel's error as its own type, when it is an `E`.
    pub fn downcast_ref<E: std::error::Error + 'static>(&self) -> Option<&E> {
        self.0.downcast_ref()
    }
}

impl std::fmt::Display for KernelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.0.fmt(f)
    }
}

impl std::error::Error for KernelError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

/// Two kernel errors are equal when they are the same error or say the same thing.
impl PartialEq for KernelError {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0) || self.0.to_string() == other.0.to_string()
    }
}

/// A node kind: a schema and an evaluation that adapts a pure kernel to the graph.
pub trait Node: Send + Sync {
    /// The node's schema (a `static`).
    fn schema(&self) -> &'static NodeSchema;
    /// Runs the node: read inputs and params from `ctx`, call the kernel, set outputs.
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError>;
}

/// The node kinds a graph may use, by kind name. Built explicitly: no inventory magic, so
/// the catalogue is exactly what is added (the built-in one: `kinegraph_nodes::builtin::registry()`).
pub struct Registry {
    nodes: BTreeMap<&'static str, Box<dyn Node>>,
}

impl Registry {
    /// An empty registry (tests add their own nodes).
    pub fn empty() -> Self {
        Registry { nodes: BTreeMap::new() }
    }

    /// Adds a node kind, replacing one of the same kind.
    pub fn add(&mut self, node: Box<dyn Node>) {
        self.nodes.insert(node.schema().kind, node);
    }

    /// The node of `kind`.
    pub fn get(&self, kind: &str) -> Option<&dyn Node> {
        self.nodes.get(kind).map(|b| b.as_ref())
    }

    /// All nodes, sorted by kind.
    pub fn iter(&self) -> impl Iterator<Item = &dyn Node> {
        self.nodes.values().map(|b| b.as_ref())
    }

    /// The registered kind closest to `kind` by edit distance, for "did you mean" hints.
    pub fn nearest_kind(&self, kind: &str) -> Option<&'static str> {
        nearest_name(kind, self.nodes.keys().copied())
    }
}

#[cfg(test)]
mod tests {
    use std::error::Error;

    use super::NodeError;
    use crate::kernels::contacts::UnnamedFeet;
    use crate::kernels::roles::{NamesMiss, RolesError, ShapeError};

    #[test]
    fn a_kernel_error_reads_as_the_kernel_words_it_and_keeps_its_sources() {
        let roles = RolesError { by_name: Some(NamesMiss::Disconnected), by_shape: ShapeError::NoFacing };
        let e = NodeError::kernel(UnnamedFeet(roles.clone()));
        assert_eq!(
            e.to_string(),
            "the named limbs do not hang from one body; by shape, no facing (the toes do not point forward of the \
             ankles); name them with the feet param (e.g. 'LeftFoot, RightFoot')"
        );
        let NodeError::Kernel(kernel) = &e else { panic!("not a kernel error: {e:?}") };
        assert_eq!(kernel.downcast_ref::<UnnamedFeet>(), Some(&UnnamedFeet(roles.clone())));
        // The chain below the node error: the roles, then the shape's reason, then nothing.
        let first = e.source().expect("the roles error");
        assert_eq!(first.downcast_ref::<RolesError>(), Some(&roles));
        let second = first.source().expect("the shape error");
        assert_eq!(second.downcast_ref::<ShapeError>(), Some(&ShapeError::NoFacing));
        assert!(second.source().is_none());
        assert_eq!(e.clone(), e);
        // Each cause is quoted in its parent's words already: the chain adds nothing.
        assert_eq!(e.with_causes(), e.to_string());
    }

    /// A cause its error does not quote is added after it; one it quotes is not repeated.
    #[test]
    fn causes_not_quoted_are_appended_once() {
        #[derive(Debug, thiserror::Error)]
        #[error("the feet could not be placed")]
        struct Outer(#[source] std::io::Error);
        let io = || std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        assert_eq!(NodeError::kernel(Outer(io())).with_causes(), "the feet could not be placed: no such file");
        #[derive(Debug, thiserror::Error)]
        #[error("the feet could not be placed: {0}")]
        struct Quoting(#[source] std::io::Error);
        assert_eq!(NodeError::kernel(Quoting(io())).with_causes(), "the feet could not be placed: no such file");
    }
}
