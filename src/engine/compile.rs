//! Validation: turns a [`GraphDoc`] into a [`CompiledGraph`] or reports every problem at
//! once, each naming the node, the port or parameter, and the file position.

use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;

use kinegraph_nodes::node::{Node, ParamKind, ParamValue, Registry, did_you_mean, hint_for};
use petgraph::graph::{DiGraph, NodeIndex};

use crate::document::{GraphDoc, SourceMap, split_endpoint};

/// One validation problem.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Diagnostic {
    /// The node concerned, if any.
    pub node: Option<String>,
    /// The port or parameter concerned, if any.
    pub item: Option<String>,
    /// 1-based (line, column) in the graph file, when known.
    pub location: Option<(usize, usize)>,
    /// What is wrong and, where possible, how to fix it.
    pub message: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some((l, c)) = self.location {
            write!(f, "{l}:{c}: ")?;
        }
        match (&self.node, &self.item) {
            (Some(n), Some(i)) => write!(f, "node '{n}', '{i}': ")?,
            (Some(n), None) => write!(f, "node '{n}': ")?,
            _ => {}
        }
        f.write_str(&self.message)
    }
}

/// All validation problems of one graph file.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub struct GraphErrors {
    /// The graph file.
    pub path: PathBuf,
    /// Every problem found.
    pub diagnostics: Vec<Diagnostic>,
}

impl fmt::Display for GraphErrors {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.diagnostics.len();
        writeln!(f, "{}: {n} problem{}", self.path.display(), if n == 1 { "" } else { "s" })?;
        for d in &self.diagnostics {
            writeln!(f, "{}:{d}", self.path.display())?;
        }
        Ok(())
    }
}

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
}

/// A validated graph: nodes sorted by id, with a topological order.
pub struct CompiledGraph<'r> {
    /// Nodes, sorted by id.
    pub nodes: Vec<CompiledNode<'r>>,
    /// Indices into `nodes`, every node after the nodes it reads from.
    pub order: Vec<usize>,
}

impl CompiledGraph<'_> {
    /// Index of node `id`.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.nodes.binary_search_by(|n| n.id.as_str().cmp(id)).ok()
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

struct Checker<'a> {
    source: &'a SourceMap,
    diagnostics: Vec<Diagnostic>,
}

impl Checker<'_> {
    fn node(&mut self, node: &str, message: String) {
        let location = self.source.node(node);
        self.diagnostics.push(Diagnostic { node: Some(node.into()), item: None, location, message });
    }
    fn param(&mut self, node: &str, param: &str, message: String) {
        let location = self.source.param(node, param);
        self.diagnostics.push(Diagnostic { node: Some(node.into()), item: Some(param.into()), location, message });
    }
    fn edge(&mut self, endpoint: &str, node: Option<&str>, item: Option<&str>, message: String) {
        let location = self.source.edge(endpoint);
        self.diagnostics.push(Diagnostic { node: node.map(Into::into), item: item.map(Into::into), location, message });
    }
}

/// Validates `doc` against `registry`. `path` and `source` only serve the messages.
pub fn compile<'r>(
    doc: &GraphDoc,
    registry: &'r Registry,
    path: &std::path::Path,
    source: &SourceMap,
) -> Result<CompiledGraph<'r>, GraphErrors> {
    let mut check = Checker { source, diagnostics: Vec::new() };
    let mut nodes: Vec<CompiledNode<'r>> = Vec::with_capacity(doc.nodes.len());
    let mut known: BTreeMap<&str, usize> = BTreeMap::new();

    for (id, node_doc) in &doc.nodes {
        if id.is_empty() || id.contains(char::is_whitespace) {
            check.node(id, "node ids must be non-empty and contain no spaces".into());
        }
        let Some(node) = registry.get(&node_doc.kind) else {
            let hint = hint_for(registry.nearest_kind(&node_doc.kind));
            check.node(id, format!("unknown node kind '{}'{hint}; `kg nodes` lists them", node_doc.kind));
            continue;
        };
        let schema = node.schema();
        let mut params = BTreeMap::new();
        for (name, value) in &node_doc.params {
            match schema.param(name) {
                None => {
                    let hint = did_you_mean(name, schema.params.iter().map(|p| p.name));
                    check.param(id, name, format!("'{}' has no parameter '{name}'{hint}", schema.kind));
                }
                Some(spec) => match spec.check(value) {
                    Ok(v) => {
                        params.insert(name.clone(), v);
                    }
                    Err(message) => check.param(id, name, message),
                },
            }
        }
        for spec in schema.params {
            if !params.contains_key(spec.name) && !node_doc.params.contains_key(spec.name) {
                match spec.default_value() {
                    Some(v) => {
                        params.insert(spec.name.to_string(), v);
                    }
                    None if matches!(spec.kind, ParamKind::InputPath { required: true, .. }) => {
                        check.param(id, spec.name, "is required: give the file to read".into());
                    }
                    None => {}
                }
            }
        }
        known.insert(id, nodes.len());
        nodes.push(CompiledNode {
            id: id.clone(),
            node,
            params,
            inputs: vec![None; schema.inputs.len()],
            dependents: Vec::new(),
        });
    }

    for edge in &doc.edges {
        let ends = (split_endpoint(&edge.from), split_endpoint(&edge.to));
        let (Some((from_node, from_port)), Some((to_node, to_port))) = ends else {
            check.edge(
                &edge.from,
                None,
                None,
                format!("edge {} → {} must join \"node.port\" to \"node.port\"", edge.from, edge.to),
            );
            continue;
        };
        let mut endpoint = |node: &str, endpoint: &str| -> Option<usize> {
            let found = known.get(node).copied();
            if found.is_none() && !doc.nodes.contains_key(node) {
                let hint = did_you_mean(node, doc.nodes.keys().map(String::as_str));
                check.edge(
                    endpoint,
                    Some(node),
                    None,
                    format!("edge names node '{node}', which the graph does not have{hint}"),
                );
            }
            found
        };
        let (Some(src), Some(dst)) = (endpoint(from_node, &edge.from), endpoint(to_node, &edge.to)) else { continue };
        let (src_schema, dst_schema) = (nodes[src].node.schema(), nodes[dst].node.schema());
        let Some(out_index) = src_schema.outputs.iter().position(|p| p.name == from_port) else {
            let hint = did_you_mean(from_port, src_schema.outputs.iter().map(|p| p.name));
            check.edge(
                &edge.from,
                Some(from_node),
                Some(from_port),
                format!("'{}' has no output '{from_port}'{hint}", src_schema.kind),
            );
            continue;
        };
        let Some(in_index) = dst_schema.inputs.iter().position(|p| p.name == to_port) else {
            let hint = did_you_mean(to_port, dst_schema.inputs.iter().map(|p| p.name));
            check.edge(
                &edge.to,
                Some(to_node),
                Some(to_port),
                format!("'{}' has no input '{to_port}'{hint}", dst_schema.kind),
            );
            continue;
        };
        let (out_ty, in_ty) = (src_schema.outputs[out_index].ty, dst_schema.inputs[in_index].ty);
        if out_ty != in_ty {
            check.edge(
                &edge.to,
                Some(to_node),
                Some(to_port),
                format!(
                    "type mismatch: {} is a {}, but {} takes a {}",
                    edge.from,
                    out_ty.name(),
                    edge.to,
                    in_ty.name()
                ),
            );
            continue;
        }
        if nodes[dst].inputs[in_index].is_some() {
            check.edge(&edge.to, Some(to_node), Some(to_port), "input is connected more than once".into());
            continue;
        }
        nodes[dst].inputs[in_index] = Some((src, out_index));
        nodes[src].dependents.push(dst);
    }

    for node in &nodes {
        for (spec, input) in node.node.schema().inputs.iter().zip(&node.inputs) {
            if spec.required && input.is_none() {
                let location = source.node(&node.id);
                check.diagnostics.push(Diagnostic {
                    node: Some(node.id.clone()),
                    item: Some(spec.name.into()),
                    location,
                    message: format!("required input '{}' ({}) is not connected", spec.name, spec.ty.name()),
                });
            }
        }
    }

    // Two exports writing one file would race and one result would silently vanish.
    let mut writers: BTreeMap<String, &str> = BTreeMap::new();
    for output in output_files(&nodes) {
        let key = output.file.to_string_lossy().to_lowercase();
        if let Some(first) = writers.insert(key, output.node) {
            check.param(
                output.node,
                output.param,
                format!("writes '{}', which node '{first}' also writes", output.text),
            );
        }
    }

    for (name, target) in &doc.inputs {
        let ok = split_endpoint(target)
            .and_then(|(n, p)| known.get(n).map(|&i| (i, p)))
            .is_some_and(|(i, p)| nodes[i].node.schema().param(p).is_some());
        if !ok {
            let location = source.input(name);
            check.diagnostics.push(Diagnostic {
                node: None,
                item: Some(name.clone()),
                location,
                message: format!("graph input '{name}' points at '{target}', which is not a node.param of this graph"),
            });
        }
    }

    for node in &mut nodes {
        node.dependents.sort_unstable();
        node.dependents.dedup();
    }
    let mut graph: DiGraph<usize, ()> = DiGraph::new();
    let indices: Vec<NodeIndex> = (0..nodes.len()).map(|i| graph.add_node(i)).collect();
    for (i, node) in nodes.iter().enumerate() {
        for &d in &node.dependents {
            graph.add_edge(indices[i], indices[d], ());
        }
    }
    let order = match petgraph::algo::toposort(&graph, None) {
        Ok(order) => order.into_iter().map(|n| graph[n]).collect(),
        Err(_) => {
            for component in petgraph::algo::tarjan_scc(&graph) {
                let cyclic = component.len() > 1 || component.iter().any(|&n| graph.contains_edge(n, n));
                if cyclic {
                    let mut ids: Vec<&str> = component.iter().map(|&n| nodes[graph[n]].id.as_str()).collect();
                    ids.sort();
                    check.node(
                        ids[0],
                        format!("cycle through nodes {}: a node cannot depend on its own output", ids.join(" → ")),
                    );
                }
            }
            Vec::new()
        }
    };

    if check.diagnostics.is_empty() {
        Ok(CompiledGraph { nodes, order })
    } else {
        let mut diagnostics = check.diagnostics;
        diagnostics.sort_by(|a, b| a.location.cmp(&b.location).then_with(|| a.message.cmp(&b.message)));
        Err(GraphErrors { path: path.to_path_buf(), diagnostics })
    }
}
