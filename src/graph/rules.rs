//! The rules a graph must keep, in one place: `kg check` (through the engine's compile)
//! reports every breach of a file at once, and the editor refuses an edit that would break
//! one, with the same words.

use kinegraph_nodes::node::{NodeSchema, ParamSpec, ParamValue, PortSpec, PortType, Registry, did_you_mean, hint_for};

use super::{Graph, GraphError, NodeId, ParamPath, PortRef, Side};

/// The error for a node the graph does not have.
pub fn unknown_node(id: &NodeId) -> GraphError {
    GraphError::UnknownNode { id: id.clone(), hint: String::new() }
}

/// The schema of `kind`, for node `id`; an unknown kind gets the nearest registered name.
pub fn schema_of_kind(registry: &Registry, id: &NodeId, kind: &str) -> Result<&'static NodeSchema, GraphError> {
    registry.get(kind).map(|n| n.schema()).ok_or_else(|| GraphError::UnknownKind {
        node: id.clone(),
        kind: kind.to_string(),
        hint: hint_for(registry.nearest_kind(kind)),
    })
}

/// `kind` may be given to node `id`: a registered kind, or a subgraph (whose file is
/// checked when it is expanded).
pub fn check_kind(registry: &Registry, id: &NodeId, kind: &str) -> Result<(), GraphError> {
    if kind == crate::document::SUBGRAPH_KIND { Ok(()) } else { schema_of_kind(registry, id, kind).map(|_| ()) }
}

/// The schema of node `id` of `graph`.
pub fn schema_of(graph: &Graph, registry: &Registry, id: &NodeId) -> Result<&'static NodeSchema, GraphError> {
    let node = graph.node(id.as_str()).ok_or_else(|| unknown_node(id))?;
    schema_of_kind(registry, id, &node.kind)
}

/// The type of port `port` on `side`, from its node's schema.
pub fn port_type(graph: &Graph, registry: &Registry, port: &PortRef, side: Side) -> Result<PortType, GraphError> {
    port_spec(graph, registry, port, side).map(|p| p.ty)
}

/// The schema entry of port `port` on `side`.
pub fn port_spec(
    graph: &Graph,
    registry: &Registry,
    port: &PortRef,
    side: Side,
) -> Result<&'static PortSpec, GraphError> {
    if !graph.contains(port.node.as_str()) {
        return Err(GraphError::EdgeToUnknownNode {
            port: port.clone(),
            hint: did_you_mean(port.node.as_str(), graph.nodes().keys().map(NodeId::as_str)),
        });
    }
    let schema = schema_of(graph, registry, &port.node)?;
    let ports = match side {
        Side::Input => schema.inputs,
        Side::Output => schema.outputs,
    };
    ports.iter().find(|p| p.name == port.port).ok_or_else(|| GraphError::UnknownPort {
        port: port.clone(),
        kind: schema.kind,
        side,
        hint: did_you_mean(&port.port, ports.iter().map(|p| p.name)),
    })
}

/// Both ends exist and carry the same type: what every edge of a file must keep. A
/// subgraph node's ports are its file's: they are checked where the file is read (subgraph
/// expansion, the editor's subgraph faces), so only the other end is checked here.
pub fn check_edge(graph: &Graph, registry: &Registry, from: &PortRef, to: &PortRef) -> Result<(), GraphError> {
    let typed = |port: &PortRef, side: Side| {
        if is_subgraph(graph, &port.node) { Ok(None) } else { port_type(graph, registry, port, side).map(Some) }
    };
    match (typed(from, Side::Output)?, typed(to, Side::Input)?) {
        (Some(from_ty), Some(to_ty)) => same_type(from, from_ty, to, to_ty),
        _ => Ok(()),
    }
}

/// An output of type `from_ty` may feed an input of type `to_ty` only when they are equal.
pub fn same_type(from: &PortRef, from_ty: PortType, to: &PortRef, to_ty: PortType) -> Result<(), GraphError> {
    if from_ty != to_ty {
        return Err(GraphError::TypeMismatch {
            from: from.clone(),
            from_ty: from_ty.name(),
            to: to.clone(),
            to_ty: to_ty.name(),
        });
    }
    Ok(())
}

/// Whether `from → to` may be added: a valid edge ([`check_edge`]) that is new and closes
/// no cycle. An occupied input is fine: connecting replaces its edge.
pub fn check_connect(graph: &Graph, registry: &Registry, from: &PortRef, to: &PortRef) -> Result<(), GraphError> {
    check_edge(graph, registry, from, to)?;
    if graph.has_edge(from, to) {
        return Err(GraphError::AlreadyConnected { from: from.clone(), to: to.clone() });
    }
    if reaches(graph, &to.node, &from.node) {
        return Err(GraphError::WouldCycle { from: from.clone(), to: to.clone() });
    }
    Ok(())
}

/// True when `target` is `start` or downstream of it.
fn reaches(graph: &Graph, start: &NodeId, target: &NodeId) -> bool {
    graph.downstream_of([start]).contains(target)
}

/// The schema entry of parameter `path`.
pub fn param_spec(graph: &Graph, registry: &Registry, path: &ParamPath) -> Result<&'static ParamSpec, GraphError> {
    let schema = schema_of(graph, registry, &path.node)?;
    spec_in(schema, path)
}

fn spec_in(schema: &'static NodeSchema, path: &ParamPath) -> Result<&'static ParamSpec, GraphError> {
    schema.param(&path.param).ok_or_else(|| GraphError::UnknownParam {
        param: path.clone(),
        kind: schema.kind,
        hint: did_you_mean(&path.param, schema.params.iter().map(|p| p.name)),
    })
}

/// `value` checked against parameter `path` of a node of `schema`: the canonical value, or
/// why it does not fit.
pub fn check_value(
    schema: &'static NodeSchema,
    path: &ParamPath,
    value: &ParamValue,
) -> Result<ParamValue, GraphError> {
    // A value can be megabytes of text: the message never echoes more than a few lines.
    spec_in(schema, path)?.check(value).map_err(|message| GraphError::BadValue {
        param: path.clone(),
        message: crate::document::shorten(&message, 300),
    })
}

/// `value` checked against parameter `path` of `graph`. A subgraph node's parameters are
/// its file and its file's graph inputs: they are checked when the subgraph is expanded.
pub fn check_param(
    graph: &Graph,
    registry: &Registry,
    path: &ParamPath,
    value: &ParamValue,
) -> Result<ParamValue, GraphError> {
    if is_subgraph(graph, &path.node) {
        return Ok(value.clone());
    }
    check_value(schema_of(graph, registry, &path.node)?, path, value)
}

/// Whether node `id` is a subgraph node.
pub fn is_subgraph(graph: &Graph, id: &NodeId) -> bool {
    graph.node(id.as_str()).is_some_and(|n| n.kind == crate::document::SUBGRAPH_KIND)
}

/// Graph input `name` may point at `target`: a parameter of the graph, and a name that
/// does not read as another node's parameter path (`--set NAME=…` must mean one thing).
pub fn check_input(graph: &Graph, registry: &Registry, name: &str, target: &ParamPath) -> Result<(), GraphError> {
    let bad = || GraphError::BadGraphInput { name: name.to_string(), target: target.to_string() };
    if !graph.contains(target.node.as_str()) {
        return Err(bad());
    }
    // A subgraph node's parameters are its file's graph inputs, checked when it is expanded.
    if is_subgraph(graph, &target.node) {
        return Ok(());
    }
    let schema = schema_of(graph, registry, &target.node).map_err(|_| bad())?;
    if schema.param(&target.param).is_none() {
        return Err(bad());
    }
    if let Some(spelt) = ParamPath::parse(name)
        && &spelt != target
        && graph.contains(spelt.node.as_str())
    {
        return Err(GraphError::InputShadowsParam { name: name.to_string(), target: target.clone() });
    }
    Ok(())
}
