//! Validation: turns a [`GraphDoc`] into a [`CompiledGraph`] or reports every problem at
//! once, each naming the node, the port or parameter, and the file position.

use std::collections::{BTreeMap, BTreeSet};

use kinegraph_nodes::node::{Node, ParamKind, ParamValue, Registry};
use petgraph::graph::{DiGraph, NodeIndex};

use crate::document::SourceMap;
pub use crate::graph::{Diagnostic, GraphErrors};
use crate::graph::{Graph, GraphError, NodeId, ParamPath, PortRef, located, rules};

/// A node ready to run.
pub struct CompiledNode<'r> {
    /// Id from the graph file.
    pub id: String,
    /// The node implementation.
    pub node: &'r dyn Node,
    /// Checked parameters, defaults filled in.
    pub params: BTreeMap<String, ParamValue>,
    /// Per schema input: the (source node index, source output index) feeding it.
    pub inputs: Vec<Option<(usize, usize)>>,
    /// Nodes reading this node's outputs, sorted, each once.
    pub dependents: Vec<usize>,
    /// For a bypassed node: per schema output, the input whose value it passes on.
    pub pass_through: Option<Vec<Option<usize>>>,
}

impl CompiledNode<'_> {
    /// The files and folders this node reads: its input-file and input-folder parameters,
    /// as (parameter name, value as written).
    pub fn input_files(&self) -> impl Iterator<Item = (&str, &str)> {
        let schema = self.node.schema();
        self.params.iter().filter_map(move |(name, value)| match value {
            ParamValue::Text(path)
                if schema
                    .param(name)
                    .is_some_and(|p| matches!(p.kind, ParamKind::InputPath { .. } | ParamKind::InputFolder { .. })) =>
            {
                Some((name.as_str(), path.as_str()))
            }
            _ => None,
        })
    }
}

/// A validated graph: nodes sorted by id, with a topological order.
pub struct CompiledGraph<'r> {
    /// Nodes, sorted by id.
    pub nodes: Vec<CompiledNode<'r>>,
    /// Indices into `nodes`, every node after the nodes it reads from.
    pub order: Vec<usize>,
    /// The subgraph files the graph includes (absolute, sorted), for watchers.
    pub includes: Vec<std::path::PathBuf>,
}

impl CompiledGraph<'_> {
    /// Index of node `id`.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.nodes.binary_search_by(|n| n.id.as_str().cmp(id)).ok()
    }

    /// Every file and folder the graph's nodes read, as written, in node order.
    pub fn input_files(&self) -> impl Iterator<Item = &str> {
        self.nodes.iter().flat_map(|n| n.input_files().map(|(_, path)| path))
    }

    /// Every file the graph's export nodes write, in node order.
    pub fn output_files(&self) -> Vec<OutputFile<'_>> {
        output_files(&self.nodes)
    }
}

/// A file an export node writes.
#[derive(Clone, Debug, PartialEq)]
pub struct OutputFile<'a> {
    /// The node.
    pub node: &'a str,
    /// Its output-path parameter.
    pub param: &'static str,
    /// The parameter's text, as written in the graph.
    pub text: &'a str,
    /// The file relative to the run's output folder, `.` components removed.
    pub file: std::path::PathBuf,
}

fn output_files<'a>(nodes: &'a [CompiledNode<'_>]) -> Vec<OutputFile<'a>> {
    let mut out = Vec::new();
    for node in nodes {
        for spec in node.node.schema().params.iter().filter(|p| matches!(p.kind, ParamKind::OutputPath { .. })) {
            if let Some(ParamValue::Text(text)) = node.params.get(spec.name) {
                let file = std::path::Path::new(text)
                    .components()
                    .filter(|c| !matches!(c, std::path::Component::CurDir))
                    .collect();
                out.push(OutputFile { node: &node.id, param: spec.name, text, file });
            }
        }
    }
    out
}

/// What a bypassed node passes on: per output, the first connected (or `fed`) input of the
/// output's type, one of the same name first (a clip filter passes its `clip` on as `clip`).
fn pass_through(node: &CompiledNode<'_>, fed: &BTreeSet<PortRef>) -> Vec<Option<usize>> {
    let schema = node.node.schema();
    let has_value =
        |i: usize| node.inputs[i].is_some() || fed.contains(&PortRef::new(node.id.as_str(), schema.inputs[i].name));
    schema
        .outputs
        .iter()
        .map(|out| {
            let candidates = || (0..schema.inputs.len()).filter(|&i| schema.inputs[i].ty == out.ty && has_value(i));
            candidates().find(|&i| schema.inputs[i].name == out.name).or_else(|| candidates().next())
        })
        .collect()
}

/// Validates `graph` against `registry` by the [`rules`], reporting every problem at once.
/// `path` and `source` only serve the messages.
pub fn compile<'r>(
    graph: &Graph,
    registry: &'r Registry,
    path: &std::path::Path,
    source: &SourceMap,
) -> Result<CompiledGraph<'r>, GraphErrors> {
    compile_fed(graph, registry, path, source, &BTreeSet::new())
}

/// [`compile`] for a graph whose inputs `fed` are fed from outside (a subgraph's shown
/// inputs): those count as connected.
pub(super) fn compile_fed<'r>(
    graph: &Graph,
    registry: &'r Registry,
    path: &std::path::Path,
    source: &SourceMap,
    fed: &BTreeSet<PortRef>,
) -> Result<CompiledGraph<'r>, GraphErrors> {
    let mut errors: Vec<GraphError> = Vec::new();
    let mut nodes: Vec<CompiledNode<'r>> = Vec::with_capacity(graph.nodes().len());
    let mut known: BTreeMap<&str, usize> = BTreeMap::new();

    for (id, graph_node) in graph.nodes() {
        if let Err(e) = id.check() {
            errors.push(e);
        }
        let node = match registry.get(&graph_node.kind) {
            Some(node) => node,
            None => {
                errors.extend(rules::schema_of_kind(registry, id, &graph_node.kind).err());
                continue;
            }
        };
        let schema = node.schema();
        let mut params = BTreeMap::new();
        for (name, value) in &graph_node.params {
            match rules::check_value(schema, &ParamPath::new(id.clone(), name.as_str()), value) {
                Ok(v) => {
                    params.insert(name.clone(), v);
                }
                Err(e) => errors.push(e),
            }
        }
        for spec in schema.params {
            if !graph_node.params.contains_key(spec.name) {
                match spec.default_value() {
                    Some(v) => {
                        params.insert(spec.name.to_string(), v);
                    }
                    None if matches!(spec.kind, ParamKind::InputPath { required: true, .. }) => {
                        errors.push(GraphError::MissingParam { param: ParamPath::new(id.clone(), spec.name) });
                    }
                    None => {}
                }
            }
        }
        known.insert(id.as_str(), nodes.len());
        nodes.push(CompiledNode {
            id: id.as_str().to_string(),
            node,
            params,
            inputs: vec![None; schema.inputs.len()],
            dependents: Vec::new(),
            pass_through: None,
        });
    }

    let mut feeding: BTreeMap<&PortRef, &PortRef> = BTreeMap::new();
    for edge in graph.edges() {
        // Edges between nodes whose kind is unknown were reported with the kind.
        let unknown_kind = |p: &PortRef| graph.contains(p.node.as_str()) && !known.contains_key(p.node.as_str());
        if unknown_kind(&edge.from) || unknown_kind(&edge.to) {
            continue;
        }
        if let Err(e) = rules::check_edge(graph, registry, &edge.from, &edge.to) {
            errors.push(e);
            continue;
        }
        if let Some(first) = feeding.insert(&edge.to, &edge.from) {
            errors.push(GraphError::InputConnectedTwice { to: edge.to.clone(), first: first.clone() });
            continue;
        }
        let (src, dst) = (known[edge.from.node.as_str()], known[edge.to.node.as_str()]);
        let out_index = nodes[src].node.schema().outputs.iter().position(|p| p.name == edge.from.port);
        let in_index = nodes[dst].node.schema().inputs.iter().position(|p| p.name == edge.to.port);
        if let (Some(out_index), Some(in_index)) = (out_index, in_index) {
            nodes[dst].inputs[in_index] = Some((src, out_index));
            nodes[src].dependents.push(dst);
        }
    }

    for node in &mut nodes {
        if graph.node(&node.id).is_some_and(|n| n.bypass) {
            node.pass_through = Some(pass_through(node, fed));
        }
    }
    for edge in graph.edges() {
        let Some(src) = known.get(edge.from.node.as_str()).map(|&i| &nodes[i]) else { continue };
        let Some(pass) = &src.pass_through else { continue };
        let outputs = src.node.schema().outputs;
        if let Some(out) = outputs.iter().position(|p| p.name == edge.from.port)
            && pass[out].is_none()
        {
            errors.push(GraphError::NothingToPass {
                from: edge.from.clone(),
                to: edge.to.clone(),
                ty: outputs[out].ty.name(),
            });
        }
    }

    for node in &nodes {
        for (spec, input) in node.node.schema().inputs.iter().zip(&node.inputs) {
            let port = PortRef::new(node.id.as_str(), spec.name);
            if spec.required && input.is_none() && !fed.contains(&port) {
                errors.push(GraphError::InputNotConnected { input: port, ty: spec.ty.name() });
            }
        }
    }

    // Two exports writing one file would race and one result would silently vanish; one
    // writing a file where another needs a folder fails half way through a run.
    let mut writers: BTreeMap<String, &str> = BTreeMap::new();
    let outputs = output_files(&nodes);
    for output in &outputs {
        let key = output.file.to_string_lossy().to_lowercase();
        if let Some(first) = writers.insert(key, output.node) {
            errors.push(GraphError::SameOutputFile {
                param: ParamPath::new(output.node, output.param),
                file: output.text.to_string(),
                other: NodeId::new(first),
            });
        }
    }
    for output in &outputs {
        for folder in output.file.ancestors().skip(1).filter(|a| !a.as_os_str().is_empty()) {
            let key = folder.to_string_lossy().to_lowercase();
            if let Some(&other) = writers.get(&key) {
                errors.push(GraphError::BadValue {
                    param: ParamPath::new(output.node, output.param),
                    message: format!(
                        "'{}' needs a folder '{}', where node '{other}' writes a file",
                        output.text,
                        folder.display()
                    ),
                });
            }
        }
    }

    for (name, target) in graph.inputs() {
        if let Err(e) = rules::check_input(graph, registry, name, target) {
            errors.push(e);
        }
    }

    for node in &mut nodes {
        node.dependents.sort_unstable();
        node.dependents.dedup();
    }
    let mut dag: DiGraph<usize, ()> = DiGraph::new();
    let indices: Vec<NodeIndex> = (0..nodes.len()).map(|i| dag.add_node(i)).collect();
    for (i, node) in nodes.iter().enumerate() {
        for &d in &node.dependents {
            dag.add_edge(indices[i], indices[d], ());
        }
    }
    let order = match petgraph::algo::toposort(&dag, None) {
        Ok(order) => order.into_iter().map(|n| dag[n]).collect(),
        Err(_) => {
            for component in petgraph::algo::tarjan_scc(&dag) {
                let cyclic = component.len() > 1 || component.iter().any(|&n| dag.contains_edge(n, n));
                if cyclic {
                    let mut ids: Vec<NodeId> =
                        component.iter().map(|&n| NodeId::new(nodes[dag[n]].id.as_str())).collect();
                    ids.sort();
                    errors.push(GraphError::Cycle { nodes: ids });
                }
            }
            Vec::new()
        }
    };

    if errors.is_empty() {
        Ok(CompiledGraph { nodes, order, includes: Vec::new() })
    } else {
        Err(located(path, source, errors))
    }
}
