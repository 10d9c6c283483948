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

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use kinegraph_nodes::node::{ParamSpec, ParamValue, PortType, Registry};

use super::compile::{CompiledGraph, compile_fed};
use crate::document::{SUBGRAPH_FILE_PARAM, SUBGRAPH_KIND};
use crate::graph::{
    Edge, Graph, GraphError, GraphErrors, GraphFile, LoadError, NodeId, ParamPath, PortRef, Side, is_input_file,
    located, rules,
};

/// The spec of a subgraph node's `file` parameter, for forms that edit it as any input file.
pub static FILE_PARAM_SPEC: ParamSpec = ParamSpec {
    name: SUBGRAPH_FILE_PARAM,
    doc: "The graph file used as this node, relative to this graph's folder: its ports become \
          the node's ports and its graph inputs the node's parameters.",
    kind: kinegraph_nodes::node::ParamKind::InputPath { extensions: &["ron"], required: true },
};

/// How deep subgraphs may nest.
pub const MAX_DEPTH: usize = 16;

/// Graphs being edited and not yet saved, by the file they come from: a subgraph whose file
/// is one of these is read from here (the editor evaluates a subgraph opened from a graph
/// in that graph, with its unsaved edits).
pub type Unsaved = BTreeMap<PathBuf, Graph>;

/// A graph file ready to run: its subgraphs expanded, then validated. Every front end
/// (`kg run`, `kg check`, `kg watch`, the farm, the editor) prepares graphs through this.
pub fn compile_file<'r>(file: &GraphFile, registry: &'r Registry) -> Result<CompiledGraph<'r>, GraphErrors> {
    compile_file_with(file, registry, &Unsaved::new())
}

/// [`compile_file`], reading the subgraph files named in `unsaved` from there.
pub fn compile_file_with<'r>(
    file: &GraphFile,
    registry: &'r Registry,
    unsaved: &Unsaved,
) -> Result<CompiledGraph<'r>, GraphErrors> {
    let mut includes = BTreeSet::new();
    let unsaved: Unsaved = unsaved.iter().map(|(path, graph)| (identity(path), graph.clone())).collect();
    let expanded = expand(file, registry, &unsaved, &mut includes)?;
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
    expand(file, registry, &Unsaved::new(), includes)
}

fn expand(
    file: &GraphFile,
    registry: &Registry,
    unsaved: &Unsaved,
    includes: &mut BTreeSet<PathBuf>,
) -> Result<GraphFile, GraphErrors> {
    let mut stack = vec![identity(&file.path)];
    let graph = expand_in(file, registry, unsaved, &mut stack, includes)?;
    Ok(GraphFile { graph, ..file.clone() })
}

/// A file's identity for cycle detection: its canonical path when it exists.
fn identity(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()))
}

fn expand_in(
    file: &GraphFile,
    registry: &Registry,
    unsaved: &Unsaved,
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
        if let Err(e) = inline(&mut out, file, &id, registry, unsaved, stack, includes) {
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
    unsaved: &Unsaved,
    stack: &mut Vec<PathBuf>,
    includes: &mut BTreeSet<PathBuf>,
) -> Result<(), Failure> {
    let file_param = ParamPath::new(id.clone(), SUBGRAPH_FILE_PARAM);
    let node = out.node(id.as_str()).cloned().ok_or_else(|| rules::unknown_node(id))?;
    let Some(ParamValue::Text(rel)) = node.params.get(SUBGRAPH_FILE_PARAM) else {
        return Err(GraphError::MissingParam { param: file_param }.into());
    };
    let fail = |message: String| GraphError::Subgraph { param: file_param.clone(), message };
    if node.bypass {
        return Err(fail("a subgraph node cannot be bypassed: open it and bypass the nodes inside".into()).into());
    }
    let path = file.base_dir().join(rel);
    let key = identity(&path);
    if let Some(at) = stack.iter().position(|p| p == &key) {
        let chain: Vec<String> = stack[at..].iter().chain([&key]).map(|p| p.display().to_string()).collect();
        return Err(fail(format!("'{rel}' includes itself: {}", chain.join(" → "))).into());
    }
    if stack.len() > MAX_DEPTH {
        return Err(fail(format!("subgraphs nest deeper than {MAX_DEPTH} files at '{rel}'")).into());
    }
    let loaded = match unsaved.get(&key) {
        Some(graph) => Ok(GraphFile::in_memory(graph.clone(), &path)),
        None => GraphFile::load(&path),
    };
    let mut child = match loaded {
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
    let inner = expand_in(&child, registry, unsaved, stack, includes);
    stack.pop();
    let inner = inner.map_err(Failure::Inside)?;
    // Its ports as expanded (a port may lead into one of its own subgraphs).
    let ports = inner.ports().clone();
    let fed: BTreeSet<PortRef> = ports.inputs.values().flatten().cloned().collect();
    compile_fed(&inner, registry, &child.path, &child.source, &fed).map_err(Failure::Inside)?;
    let (face_inputs, _) =
        face_ports(&inner, registry).map_err(|e| Failure::Inside(located(&child.path, &child.source, e)))?;

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
        let Some(face) = face_inputs.iter().find(|p| p.name == e.to.port) else {
            errors.push(unknown_port(&e.to, Side::Input));
            continue;
        };
        // An outer end that is itself a subgraph is checked when the expanded graph is compiled.
        if !rules::is_subgraph(out, &e.from.node) && !e.from.node.as_str().contains('/') {
            let checked = rules::port_type(out, registry, &e.from, Side::Output)
                .and_then(|ty| rules::same_type(&e.from, ty, &e.to, face.ty));
            if let Err(err) = checked {
                errors.push(err);
                continue;
            }
        }
        for target in &face.inner {
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

/// A port a subgraph file shows, typed by the inner ports it leads to.
#[derive(Clone, Debug, PartialEq)]
pub struct FacePort {
    /// The port's public name.
    pub name: String,
    /// Its type.
    pub ty: PortType,
    /// Inputs: whether an inner input it feeds refuses to run without it.
    pub required: bool,
    /// The inner port's doc text (the first one's, for an input feeding several).
    pub doc: &'static str,
    /// Where it leads in the expanded file: the inner inputs it feeds, or the one inner
    /// output it gives.
    pub inner: Vec<PortRef>,
}

/// A parameter a subgraph node takes: one of its file's graph inputs.
#[derive(Clone, Debug)]
pub struct FaceParam {
    /// The graph input's name (the node's parameter name).
    pub name: String,
    /// The spec of the inner parameter it sets.
    pub spec: &'static ParamSpec,
    /// The value the file itself gives that parameter, if any (else the spec's default).
    pub value: Option<ParamValue>,
}

/// What a subgraph node shows of its file: typed ports and parameters, for the editor to
/// draw pins and parameter fields as for any node.
#[derive(Clone, Debug)]
pub struct SubgraphFace {
    /// The subgraph's file.
    pub path: PathBuf,
    /// The file's description.
    pub description: String,
    /// Its input ports.
    pub inputs: Vec<FacePort>,
    /// Its output ports.
    pub outputs: Vec<FacePort>,
    /// Its graph inputs, in name order.
    pub params: Vec<FaceParam>,
}

impl SubgraphFace {
    /// The port called `name` on `side`.
    pub fn port(&self, name: &str, side: Side) -> Option<&FacePort> {
        let ports = match side {
            Side::Input => &self.inputs,
            Side::Output => &self.outputs,
        };
        ports.iter().find(|p| p.name == name)
    }
}

/// The face of the subgraph file at `path`: its own subgraphs expanded, each port typed by
/// what it leads to. The error names the file and what is wrong in it.
pub fn face(path: &Path, registry: &Registry) -> Result<SubgraphFace, String> {
    let file = GraphFile::load(path).map_err(|e| e.to_string())?;
    let mut includes = BTreeSet::new();
    let expanded = expand_subgraphs(&file, registry, &mut includes).map_err(|e| e.to_string())?;
    let inner = &expanded.graph;
    let (inputs, outputs) =
        face_ports(inner, registry).map_err(|e| located(&file.path, &file.source, e).to_string())?;
    let mut params = Vec::new();
    for (name, target) in inner.inputs() {
        let spec = rules::param_spec(inner, registry, target)
            .map_err(|e| format!("{}: graph input '{name}': {e}", path.display()))?;
        let value = inner.node(target.node.as_str()).and_then(|n| n.params.get(&target.param)).cloned();
        params.push(FaceParam { name: name.clone(), spec, value });
    }
    Ok(SubgraphFace { path: path.to_path_buf(), description: inner.description().to_string(), inputs, outputs, params })
}

/// The typed ports of an expanded subgraph file; an input leading to inner inputs of
/// different types is refused, as no outer wire could feed it.
fn face_ports(inner: &Graph, registry: &Registry) -> Result<(Vec<FacePort>, Vec<FacePort>), Vec<GraphError>> {
    let mut errors = Vec::new();
    let mut inputs = Vec::new();
    for (name, targets) in &inner.ports().inputs {
        let mut face: Option<FacePort> = None;
        for target in targets {
            let spec = match rules::port_spec(inner, registry, target, Side::Input) {
                Ok(spec) => spec,
                Err(e) => {
                    errors.push(e);
                    continue;
                }
            };
            match &mut face {
                None => {
                    face = Some(FacePort {
                        name: name.clone(),
                        ty: spec.ty,
                        required: spec.required,
                        doc: spec.doc,
                        inner: vec![target.clone()],
                    });
                }
                Some(face) => match rules::same_type(&face.inner[0], face.ty, target, spec.ty) {
                    Ok(()) => {
                        face.required |= spec.required;
                        face.inner.push(target.clone());
                    }
                    Err(e) => errors.push(e),
                },
            }
        }
        inputs.extend(face);
    }
    let mut outputs = Vec::new();
    for (name, source) in &inner.ports().outputs {
        match rules::port_spec(inner, registry, source, Side::Output) {
            Ok(spec) => outputs.push(FacePort {
                name: name.clone(),
                ty: spec.ty,
                required: false,
                doc: spec.doc,
                inner: vec![source.clone()],
            }),
            Err(e) => errors.push(e),
        }
    }
    if errors.is_empty() { Ok((inputs, outputs)) } else { Err(errors) }
}

/// Whether `from → to` may be added to `graph` whose subgraph nodes show `faces` (by node
/// id): the graph's own rules ([`rules::check_connect`]) and [`check_face_types`]. The
/// editor refuses with this what a run would refuse.
pub fn check_connect(
    graph: &Graph,
    registry: &Registry,
    faces: &BTreeMap<NodeId, SubgraphFace>,
    from: &PortRef,
    to: &PortRef,
) -> Result<(), GraphError> {
    rules::check_connect(graph, registry, from, to)?;
    check_face_types(graph, registry, faces, from, to)
}

/// At a subgraph end of `from → to`, the port its file shows exists and carries the other
/// end's type. An end whose type is not known here (a node not in `graph` yet, a subgraph
/// whose file cannot be read) is left to the run.
pub fn check_face_types(
    graph: &Graph,
    registry: &Registry,
    faces: &BTreeMap<NodeId, SubgraphFace>,
    from: &PortRef,
    to: &PortRef,
) -> Result<(), GraphError> {
    if !faces.contains_key(&from.node) && !faces.contains_key(&to.node) {
        return Ok(());
    }
    let typed = |port: &PortRef, side: Side| -> Result<Option<PortType>, GraphError> {
        let Some(face) = faces.get(&port.node) else {
            let known = graph.contains(port.node.as_str()) && !rules::is_subgraph(graph, &port.node);
            return if known { rules::port_type(graph, registry, port, side).map(Some) } else { Ok(None) };
        };
        match face.port(&port.port, side) {
            Some(p) => Ok(Some(p.ty)),
            None => Err(GraphError::UnknownSubgraphPort {
                port: port.clone(),
                file: face.path.display().to_string(),
                side,
                shown: match side {
                    Side::Input => face.inputs.iter().map(|p| p.name.clone()).collect(),
                    Side::Output => face.outputs.iter().map(|p| p.name.clone()).collect(),
                },
            }),
        }
    };
    match (typed(from, Side::Output)?, typed(to, Side::Input)?) {
        (Some(from_ty), Some(to_ty)) => rules::same_type(from, from_ty, to, to_ty),
        _ => Ok(()),
    }
}
