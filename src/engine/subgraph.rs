//! Subgraphs: a graph file used as a node (`kind: "graph.subgraph"`, `file` parameter).
//! The file's `ports` become the node's ports and its graph inputs the node's parameters.
//!
//! Before a run the engine expands every subgraph node in place (steps below), so caching,
//! parallelism and reports work on the inner nodes as on any others; an inner node is
//! named `outer/inner` in reports. Steps per subgraph node:
//! 1. read its file, relative to the graph that uses it; refuse a file that includes
//!    itself (directly or through others) or nests deeper than [`MAX_DEPTH`];
//! 2. set the file's graph inputs from the node's parameters (a relative input file given
//!    there is relative to the outer graph; the file's own relative paths to the file);
//! 3. expand the file's own subgraphs, then validate it alone (with its shown inputs
//!    counted as fed), so a problem inside is reported at its own file and line;
//! 4. inline its nodes and edges under the prefix `id/`, rewire the outer edges through
//!    its ports (types checked at the boundary), and point outer graph inputs that named
//!    the node's parameters at the inner parameters.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use kinegraph_nodes::node::{ParamValue, Registry};

use super::compile::{CompiledGraph, compile_fed};
use crate::document::{SUBGRAPH_FILE_PARAM, SUBGRAPH_KIND};
use crate::graph::{
    Edge, Graph, GraphError, GraphErrors, GraphFile, LoadError, NodeId, ParamPath, PortRef, Side, is_input_file,
    located, rules,
};

/// How deep subgraphs may nest.
pub const MAX_DEPTH: usize = 16;

/// A graph file ready to run: its subgraphs expanded, then validated. Every front end
/// (`kg run`, `kg check`, `kg watch`, the farm, the editor) prepares graphs through this.
pub fn compile_file<'r>(file: &GraphFile, registry: &'r Registry) -> Result<CompiledGraph<'r>, GraphErrors> {
    let mut includes = BTreeSet::new();
    let expanded = expand_subgraphs(file, registry, &mut includes)?;
    let mut compiled = super::compile(&expanded.graph, registry, &file.path, &file.source)?;
    compiled.includes = includes.into_iter().collect();
    Ok(compiled)
}

/// `file` with every subgraph node expanded; the files read on the way are added to
/// `includes` (for `kg watch`).
pub fn expand_subgraphs(
    file: &GraphFile,
    registry: &Registry,
    includes: &mut BTreeSet<PathBuf>,
) -> Result<GraphFile, GraphErrors> {
    let mut stack = vec![identity(&file.path)];
    let graph = expand(file, registry, &mut stack, includes)?;
    Ok(GraphFile { graph, ..file.clone() })
}

/// A file's identity for cycle detection: its canonical path when it exists.
fn identity(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()))
}

fn expand(
    file: &GraphFile,
    registry: &Registry,
    stack: &mut Vec<PathBuf>,
    includes: &mut BTreeSet<PathBuf>,
) -> Result<Graph, GraphErrors> {
    let ids: Vec<NodeId> =
        file.graph.nodes().iter().filter(|(_, n)| n.kind == SUBGRAPH_KIND).map(|(id, _)| id.clone()).collect();
    if ids.is_empty() {
        return Ok(file.graph.clone());
    }
    let mut out = file.graph.clone();
    let mut errors = Vec::new();
    for id in ids {
        if let Err(e) = inline(&mut out, file, &id, registry, stack, includes) {
            match e {
                Failure::Here(list) => errors.extend(list),
                Failure::Inside(inner) => return Err(inner),
            }
        }
    }
    if errors.is_empty() { Ok(out) } else { Err(located(&file.path, &file.source, errors)) }
}

/// Why one subgraph node could not be inlined.
enum Failure {
    /// Problems of the outer file, to be located there.
    Here(Vec<GraphError>),
    /// Problems inside the subgraph's file, located there already.
    Inside(GraphErrors),
}

impl From<GraphError> for Failure {
    fn from(e: GraphError) -> Self {
        Failure::Here(vec![e])
    }
}

fn inline(
    out: &mut Graph,
    file: &GraphFile,
    id: &NodeId,
    registry: &Registry,
    stack: &mut Vec<PathBuf>,
    includes: &mut BTreeSet<PathBuf>,
) -> Result<(), Failure> {
    let file_param = ParamPath::new(id.clone(), SUBGRAPH_FILE_PARAM);
    let node = out.node(id.as_str()).cloned().ok_or_else(|| rules::unknown_node(id))?;
    let Some(ParamValue::Text(rel)) = node.params.get(SUBGRAPH_FILE_PARAM) else {
        return Err(GraphError::MissingParam { param: file_param }.into());
    };
    let fail = |message: String| GraphError::Subgraph { param: file_param.clone(), message };
    let path = file.base_dir().join(rel);
    let key = identity(&path);
    if let Some(at) = stack.iter().position(|p| p == &key) {
        let chain: Vec<String> = stack[at..].iter().chain([&key]).map(|p| p.display().to_string()).collect();
        return Err(fail(format!("'{rel}' includes itself: {}", chain.join(" → "))).into());
    }
    if stack.len() > MAX_DEPTH {
        return Err(fail(format!("subgraphs nest deeper than {MAX_DEPTH} files at '{rel}'")).into());
    }
    let mut child = match GraphFile::load(&path) {
        Ok(child) => child,
        Err(LoadError::Document(e)) => return Err(fail(format!("subgraph file: {e}")).into()),
        Err(LoadError::Structure(e)) => return Err(Failure::Inside(e)),
    };
    includes.insert(key.clone());
    // Relative input files inside the file are relative to the file, wherever its nodes go.
    let child_base = child.base_dir();
    let relocated = child.graph.relocate_input_files(registry, |text| {
        Path::new(text).is_relative().then(|| child_base.join(text).to_string_lossy().into_owned())
    });
    if let Err(e) = relocated {
        return Err(fail(format!("subgraph file {}: {e}", path.display())).into());
    }

    // 2. The node's parameters set the file's graph inputs.
    let mut errors = Vec::new();
    for (name, value) in node.params.iter().filter(|(n, _)| n.as_str() != SUBGRAPH_FILE_PARAM) {
        let here = ParamPath::new(id.clone(), name.as_str());
        let Some(target) = child.graph.inputs().get(name).cloned() else {
            let hint = kinegraph_nodes::node::did_you_mean(name, child.graph.inputs().keys().map(String::as_str));
            errors.push(GraphError::Subgraph {
                param: here,
                message: format!("'{rel}' has no graph input '{name}'{hint}"),
            });
            continue;
        };
        let value = match value {
            ParamValue::Text(p) if is_input_file(&child.graph, registry, &target).unwrap_or(false) => {
                ParamValue::Text(file.base_dir().join(p).to_string_lossy().into_owned())
            }
            other => other.clone(),
        };
        if let Err(e) = child.graph.set_param(registry, &target, &value) {
            errors.push(GraphError::Subgraph { param: here, message: e.to_string() });
        }
    }
    if !errors.is_empty() {
        return Err(Failure::Here(errors));
    }

    // 3. Its own subgraphs, then the file validated alone.
    stack.push(key);
    let inner = expand(&child, registry, stack, includes);
    stack.pop();
    let inner = inner.map_err(Failure::Inside)?;
    // Its ports as expanded (a port may lead into one of its own subgraphs).
    let ports = inner.ports().clone();
    let fed: BTreeSet<PortRef> = ports.inputs.values().flatten().cloned().collect();
    compile_fed(&inner, registry, &child.path, &child.source, &fed).map_err(Failure::Inside)?;

    // 4. Inline under `id/`, rewire the outer edges through the ports.
    let into: Vec<Edge> = out.edges().filter(|e| &e.to.node == id).cloned().collect();
    let from: Vec<Edge> = out.edges().filter(|e| &e.from.node == id).cloned().collect();
    out.take_node(id);
    let prefixed = |p: &PortRef| PortRef::new(format!("{}/{}", id.as_str(), p.node.as_str()), p.port.as_str());
    for (inner_id, inner_node) in inner.nodes() {
        let new_id = NodeId::new(format!("{}/{}", id.as_str(), inner_id.as_str()));
        if !out.insert_unchecked(new_id.clone(), inner_node.clone()) {
            errors.push(GraphError::DuplicateId(new_id));
        }
    }
    for e in inner.edges() {
        out.insert_edge_unchecked(Edge { from: prefixed(&e.from), to: prefixed(&e.to) });
    }
    let unknown_port = |port: &PortRef, side: Side| GraphError::UnknownSubgraphPort {
        port: port.clone(),
        file: rel.clone(),
        side,
        shown: match side {
            Side::Input => ports.inputs.keys().cloned().collect(),
            Side::Output => ports.outputs.keys().cloned().collect(),
        },
    };
    for e in into {
        let Some(targets) = ports.inputs.get(&e.to.port) else {
            errors.push(unknown_port(&e.to, Side::Input));
            continue;
        };
        for target in targets {
            if let Err(err) = boundary_types(out, &inner, registry, &e.from, target, &e.to) {
                errors.push(err);
                continue;
            }
            out.insert_edge_unchecked(Edge { from: e.from.clone(), to: prefixed(target) });
        }
    }
    for e in from {
        let Some(source) = ports.outputs.get(&e.from.port) else {
            errors.push(unknown_port(&e.from, Side::Output));
            continue;
        };
        out.insert_edge_unchecked(Edge { from: prefixed(source), to: e.to.clone() });
    }
    // The outer graph's own ports that lead into this node now lead to its inner ports.
    let mut outer_ports = out.ports().clone();
    for targets in outer_ports.inputs.values_mut() {
        let mut rewired = Vec::new();
        for t in targets.drain(..) {
            if &t.node != id {
                rewired.push(t);
            } else if let Some(inner_targets) = ports.inputs.get(&t.port) {
                rewired.extend(inner_targets.iter().map(prefixed));
            } else {
                errors.push(unknown_port(&t, Side::Input));
            }
        }
        *targets = rewired;
    }
    for source in outer_ports.outputs.values_mut() {
        if &source.node == id {
            match ports.outputs.get(&source.port) {
                Some(inner_source) => *source = prefixed(inner_source),
                None => errors.push(unknown_port(source, Side::Output)),
            }
        }
    }
    out.set_ports(outer_ports);
    let outer_inputs: Vec<(String, ParamPath)> =
        out.inputs().iter().filter(|(_, t)| &t.node == id).map(|(n, t)| (n.clone(), t.clone())).collect();
    for (name, target) in outer_inputs {
        match inner.inputs().get(&target.param) {
            Some(inner_target) => out.set_input_unchecked(
                &name,
                ParamPath::new(format!("{}/{}", id.as_str(), inner_target.node.as_str()), inner_target.param.as_str()),
            ),
            None => errors.push(GraphError::BadGraphInput { name, target: target.to_string() }),
        }
    }
    if errors.is_empty() { Ok(()) } else { Err(Failure::Here(errors)) }
}

/// An outer output feeding a subgraph's inner input must carry the inner input's type;
/// checked here, where the outer edge can still be pointed at in the outer file. An outer
/// end that is itself a subgraph is checked when the expanded graph is compiled.
fn boundary_types(
    out: &Graph,
    inner: &Graph,
    registry: &Registry,
    outer_from: &PortRef,
    inner_to: &PortRef,
    outer_to: &PortRef,
) -> Result<(), GraphError> {
    if rules::is_subgraph(out, &outer_from.node) || outer_from.node.as_str().contains('/') {
        return Ok(());
    }
    let from_ty = rules::port_type(out, registry, outer_from, Side::Output)?;
    let to_ty = rules::port_type(inner, registry, inner_to, Side::Input)?;
    if from_ty != to_ty {
        return Err(GraphError::TypeMismatch {
            from: outer_from.clone(),
            from_ty: from_ty.name(),
            to: outer_to.clone(),
            to_ty: to_ty.name(),
        });
    }
    Ok(())
}
