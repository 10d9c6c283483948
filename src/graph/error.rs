//! [`GraphError`]: every way a graph or an edit of it can be wrong, with what it concerns
//! ([`Subject`]) so `kg check` and the editor can point at the place.

use super::{NodeId, ParamPath, PortRef};

/// Which side of a node a port is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// An input port.
    Input,
    /// An output port.
    Output,
}

impl Side {
    /// `"input"` or `"output"`.
    pub fn name(self) -> &'static str {
        match self {
            Side::Input => "input",
            Side::Output => "output",
        }
    }
}

/// One problem with a graph, or the reason an edit was refused. The message is written for
/// the person who made the graph.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GraphError {
    /// A node id breaks the id rule ([`NodeId::check`]).
    #[error("'{id}' is not a usable node id: {reason}")]
    BadNodeId {
        /// The id.
        id: NodeId,
        /// Which part of the rule it breaks.
        reason: &'static str,
    },
    /// An endpoint is not `"node.port"`.
    #[error("'{text}' is not \"node.port\"")]
    BadEndpoint {
        /// The text as written.
        text: String,
    },
    /// No node has this id.
    #[error("there is no node '{id}'{hint}")]
    UnknownNode {
        /// The id asked for.
        id: NodeId,
        /// A "did you mean" suffix, or empty.
        hint: String,
    },
    /// An edge names a node the graph does not have.
    #[error("edge names node '{}', which the graph does not have{hint}", .port.node)]
    EdgeToUnknownNode {
        /// The endpoint as written.
        port: PortRef,
        /// A "did you mean" suffix, or empty.
        hint: String,
    },
    /// The id is taken.
    #[error("a node called '{0}' already exists")]
    DuplicateId(NodeId),
    /// The node kind is not registered.
    #[error("unknown node kind '{kind}'{hint}; `kg nodes` lists them")]
    UnknownKind {
        /// The node.
        node: NodeId,
        /// The kind asked for.
        kind: String,
        /// A "did you mean" suffix, or empty.
        hint: String,
    },
    /// The node kind has no such port.
    #[error("'{kind}' has no {} '{}'{hint}", side.name(), port.port)]
    UnknownPort {
        /// The port asked for.
        port: PortRef,
        /// The node's kind.
        kind: &'static str,
        /// Input or output.
        side: Side,
        /// A "did you mean" suffix, or empty.
        hint: String,
    },
    /// The two ends carry different types.
    #[error("type mismatch: {from} gives a {from_ty}, but {to} takes a {to_ty}")]
    TypeMismatch {
        /// Source port.
        from: PortRef,
        /// Its type's name.
        from_ty: &'static str,
        /// Destination port.
        to: PortRef,
        /// Its type's name.
        to_ty: &'static str,
    },
    /// The edge would make a node depend on its own output.
    #[error("connecting {from} to {to} would make a cycle: a node cannot depend on its own output")]
    WouldCycle {
        /// Source port.
        from: PortRef,
        /// Destination port.
        to: PortRef,
    },
    /// A file's edges form a cycle.
    #[error("cycle through nodes {}: a node cannot depend on its own output", list(.nodes))]
    Cycle {
        /// The nodes on the cycle, sorted.
        nodes: Vec<NodeId>,
    },
    /// The edge exists already.
    #[error("{from} is already connected to {to}")]
    AlreadyConnected {
        /// Source port.
        from: PortRef,
        /// Destination port.
        to: PortRef,
    },
    /// The edge to remove does not exist.
    #[error("{from} is not connected to {to}")]
    NotConnected {
        /// Source port.
        from: PortRef,
        /// Destination port.
        to: PortRef,
    },
    /// A file connects one input twice.
    #[error("input is connected more than once (also from {first})")]
    InputConnectedTwice {
        /// The input.
        to: PortRef,
        /// The source of the edge written first.
        first: PortRef,
    },
    /// A required input has no edge.
    #[error("required input '{}' ({ty}) is not connected", .input.port)]
    InputNotConnected {
        /// The input.
        input: PortRef,
        /// Its type's name.
        ty: &'static str,
    },
    /// An input reads an output of a bypassed node that has no connected input of the
    /// output's type to pass on.
    #[error("{from} passes nothing while '{}' is bypassed (it has no connected {ty} input), so {to} gets no value", .from.node)]
    NothingToPass {
        /// The bypassed node's output.
        from: PortRef,
        /// The input reading it.
        to: PortRef,
        /// The output's type name.
        ty: &'static str,
    },
    /// The node kind has no such parameter.
    #[error("'{kind}' has no parameter '{}'{hint}", .param.param)]
    UnknownParam {
        /// The parameter asked for.
        param: ParamPath,
        /// The node's kind.
        kind: &'static str,
        /// A "did you mean" suffix, or empty.
        hint: String,
    },
    /// The value does not fit the parameter.
    #[error("{message}")]
    BadValue {
        /// The parameter.
        param: ParamPath,
        /// What is accepted.
        message: String,
    },
    /// A required file parameter has no value.
    #[error("is required: give the file to read")]
    MissingParam {
        /// The parameter.
        param: ParamPath,
    },
    /// Two export nodes write the same file.
    #[error("writes '{file}', which node '{other}' also writes")]
    SameOutputFile {
        /// The second writer's path parameter.
        param: ParamPath,
        /// The file as written.
        file: String,
        /// The first writer.
        other: NodeId,
    },
    /// A graph input points at something that is not a parameter of the graph.
    #[error("graph input '{name}' points at '{target}', which is not a node.param of this graph")]
    BadGraphInput {
        /// The input's public name.
        name: String,
        /// Its target, as written.
        target: String,
    },
    /// A graph input's name reads as another node's parameter path, so `--set NAME=…`
    /// would be ambiguous.
    #[error("graph input '{name}' is spelt like the parameter path {name} but points at {target}: rename the input")]
    InputShadowsParam {
        /// The input's public name.
        name: String,
        /// Where it points.
        target: ParamPath,
    },
    /// A subgraph node cannot be expanded: its file is missing, unreadable or includes
    /// itself, or the node uses a port or parameter the file does not show.
    #[error("{message}")]
    Subgraph {
        /// The subgraph node's parameter concerned (`file`, or a promoted one).
        param: ParamPath,
        /// What is wrong.
        message: String,
    },
    /// An edge uses a port a subgraph's file does not show.
    #[error("subgraph '{}' ({file}) has no {} '{}'; it shows {}", .port.node, .side.name(), .port.port, if .shown.is_empty() { "none".to_string() } else { .shown.join(", ") })]
    UnknownSubgraphPort {
        /// The port as used.
        port: PortRef,
        /// The subgraph's file.
        file: String,
        /// Input or output.
        side: Side,
        /// The ports it shows on that side.
        shown: Vec<String>,
    },
    /// A `--set` or task binding names neither a graph input nor a `node.param`.
    #[error("'{name}' is neither a graph input ({}) nor node.param", if .inputs.is_empty() { "none".to_string() } else { .inputs.join(", ") })]
    UnknownSetting {
        /// The name given.
        name: String,
        /// The graph's inputs.
        inputs: Vec<String>,
    },
}

fn list(nodes: &[NodeId]) -> String {
    nodes.iter().map(ToString::to_string).collect::<Vec<_>>().join(" → ")
}

/// What a [`GraphError`] is about, so it can be located in the file and on the canvas.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Subject {
    /// The graph as a whole.
    Graph,
    /// A node.
    Node(NodeId),
    /// A port of a node, written in an edge.
    Port(PortRef),
    /// A parameter of a node.
    Param(ParamPath),
    /// An edge endpoint that is not even `"node.port"`.
    Endpoint(String),
    /// A graph input, by its public name.
    Input(String),
}

impl GraphError {
    /// What the problem concerns.
    pub fn subject(&self) -> Subject {
        use GraphError as E;
        match self {
            E::BadNodeId { id, .. } | E::UnknownNode { id, .. } | E::DuplicateId(id) => Subject::Node(id.clone()),
            E::UnknownKind { node, .. } => Subject::Node(node.clone()),
            E::BadEndpoint { text } => Subject::Endpoint(text.clone()),
            E::UnknownPort { port, .. } | E::EdgeToUnknownNode { port, .. } | E::UnknownSubgraphPort { port, .. } => {
                Subject::Port(port.clone())
            }
            E::TypeMismatch { to, .. }
            | E::WouldCycle { to, .. }
            | E::AlreadyConnected { to, .. }
            | E::NotConnected { to, .. }
            | E::InputConnectedTwice { to, .. }
            | E::NothingToPass { to, .. } => Subject::Port(to.clone()),
            E::InputNotConnected { input, .. } => Subject::Port(input.clone()),
            E::Cycle { nodes } => nodes.first().cloned().map_or(Subject::Graph, Subject::Node),
            E::UnknownParam { param, .. }
            | E::BadValue { param, .. }
            | E::MissingParam { param }
            | E::SameOutputFile { param, .. }
            | E::Subgraph { param, .. } => Subject::Param(param.clone()),
            E::BadGraphInput { name, .. } | E::InputShadowsParam { name, .. } => Subject::Input(name.clone()),
            E::UnknownSetting { .. } => Subject::Graph,
        }
    }
}
