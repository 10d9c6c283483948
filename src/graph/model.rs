//! [`Graph`]: the graph in memory, with typed ids and the edits every front end makes.
//!
//! Built once from the file ([`Graph::from_doc`]) and written back with [`Graph::to_doc`];
//! `kg`, the farm and the editor's reducer all work on it. Reading a file keeps what it
//! says (an unknown kind or a bad value is reported by [`validate`](super::validate) with
//! its location, not lost); every edit goes through the same rules as `kg check`.

use std::collections::{BTreeMap, BTreeSet};

use kinegraph_nodes::node::{ParamValue, Registry};

use super::rules;
use super::{GraphError, NodeId, ParamPath, PortRef};
use crate::document::{EdgeDoc, GraphDoc, NodeDoc};

/// One node: its kind and the parameters the file sets (unset ones take the schema default).
#[derive(Clone, Debug, PartialEq)]
pub struct GraphNode {
    /// Registered kind, e.g. `"clip.trim"`.
    pub kind: String,
    /// Parameter values by name.
    pub params: BTreeMap<String, ParamValue>,
    /// Bypassed: it does not run and passes inputs on (see [`crate::document::NodeDoc::bypass`]).
    pub bypass: bool,
}

/// A connection from an output port to an input port.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Edge {
    /// The output.
    pub from: PortRef,
    /// The input.
    pub to: PortRef,
}

/// A node taken out by [`Graph::remove_nodes`], whole, so it can be put back.
#[derive(Clone, Debug, PartialEq)]
pub struct RemovedNode {
    /// Its id.
    pub id: NodeId,
    /// The node as it was.
    pub node: GraphNode,
    /// Its canvas position, if it had one.
    pub pos: Option<(f32, f32)>,
}

/// What [`Graph::remove_nodes`] took out, enough to put it all back.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Removal {
    /// The nodes.
    pub nodes: Vec<RemovedNode>,
    /// The edges that touched them.
    pub edges: Vec<Edge>,
    /// The graph inputs that pointed at them.
    pub inputs: Vec<(String, ParamPath)>,
}

/// The ports a graph shows when it is used as a subgraph.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Ports {
    /// Public input name → the inner inputs it feeds.
    pub inputs: BTreeMap<String, Vec<PortRef>>,
    /// Public output name → the inner output it gives.
    pub outputs: BTreeMap<String, PortRef>,
}

/// A graph in memory. Maps are sorted, so iteration (and the saved file) is deterministic.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Graph {
    description: String,
    inputs: BTreeMap<String, ParamPath>,
    nodes: BTreeMap<NodeId, GraphNode>,
    edges: BTreeSet<Edge>,
    layout: BTreeMap<NodeId, (f32, f32)>,
    ports: Ports,
}

impl Graph {
    /// An empty graph.
    pub fn new() -> Self {
        Graph::default()
    }

    /// The graph a file describes. Fails, with every problem, only when the file's text
    /// cannot be read as a graph at all (an edge that is not `"node.port"`); what it says
    /// about kinds and values is kept as written for the checks of [`rules`](super::rules).
    pub fn from_doc(doc: &GraphDoc) -> Result<Graph, Vec<GraphError>> {
        let mut errors = Vec::new();
        let mut edges = BTreeSet::new();
        for edge in &doc.edges {
            match (PortRef::parse(&edge.from), PortRef::parse(&edge.to)) {
                (Ok(from), Ok(to)) => {
                    edges.insert(Edge { from, to });
                }
                (Err(e), _) | (_, Err(e)) => errors.push(e),
            }
        }
        let mut inputs = BTreeMap::new();
        for (name, target) in &doc.inputs {
            match ParamPath::parse(target) {
                Some(path) => {
                    inputs.insert(name.clone(), path);
                }
                None => errors.push(GraphError::BadGraphInput { name: name.clone(), target: target.clone() }),
            }
        }
        let mut ports = Ports::default();
        for (name, targets) in &doc.ports.inputs {
            let parsed: Vec<PortRef> =
                targets.iter().filter_map(|t| PortRef::parse(t).map_err(|e| errors.push(e)).ok()).collect();
            ports.inputs.insert(name.clone(), parsed);
        }
        for (name, source) in &doc.ports.outputs {
            match PortRef::parse(source) {
                Ok(port) => {
                    ports.outputs.insert(name.clone(), port);
                }
                Err(e) => errors.push(e),
            }
        }
        if !errors.is_empty() {
            return Err(errors);
        }
        let nodes = doc
            .nodes
            .iter()
            .map(|(id, n)| {
                (
                    NodeId::new(id.as_str()),
                    GraphNode { kind: n.kind.clone(), params: n.params.clone(), bypass: n.bypass },
                )
            })
            .collect();
        let layout = doc.layout.iter().map(|(id, p)| (NodeId::new(id.as_str()), *p)).collect();
        Ok(Graph { description: doc.description.clone(), inputs, nodes, edges, layout, ports })
    }

    /// The file form of the graph (current version, sorted).
    pub fn to_doc(&self) -> GraphDoc {
        let mut doc = GraphDoc::new();
        doc.description = self.description.clone();
        doc.inputs = self.inputs.iter().map(|(n, p)| (n.clone(), p.text())).collect();
        doc.nodes = self
            .nodes
            .iter()
            .map(|(id, n)| {
                (id.as_str().to_string(), NodeDoc { kind: n.kind.clone(), params: n.params.clone(), bypass: n.bypass })
            })
            .collect();
        doc.edges = self.edges.iter().map(|e| EdgeDoc { from: e.from.text(), to: e.to.text() }).collect();
        doc.edges.sort();
        doc.layout = self.layout.iter().map(|(id, p)| (id.as_str().to_string(), *p)).collect();
        doc.ports.inputs =
            self.ports.inputs.iter().map(|(n, ps)| (n.clone(), ps.iter().map(PortRef::text).collect())).collect();
        doc.ports.outputs = self.ports.outputs.iter().map(|(n, p)| (n.clone(), p.text())).collect();
        doc
    }

    /// The ports the graph shows when used as a subgraph.
    pub fn ports(&self) -> &Ports {
        &self.ports
    }

    /// Adds a node as it is, without checks: for building a graph out of checked parts
    /// (subgraph expansion). Returns false, changing nothing, when the id is taken.
    pub(crate) fn insert_unchecked(&mut self, id: NodeId, node: GraphNode) -> bool {
        if self.nodes.contains_key(&id) {
            return false;
        }
        self.nodes.insert(id, node);
        true
    }

    /// Adds an edge as it is, without checks (see [`Graph::insert_unchecked`]).
    pub(crate) fn insert_edge_unchecked(&mut self, edge: Edge) {
        self.edges.insert(edge);
    }

    /// Replaces the ports without checks (subgraph expansion).
    pub(crate) fn set_ports(&mut self, ports: Ports) {
        self.ports = ports;
    }

    /// Points graph input `name` at `target` without checks (subgraph expansion).
    pub(crate) fn set_input_unchecked(&mut self, name: &str, target: ParamPath) {
        self.inputs.insert(name.to_string(), target);
    }

    /// Removes a node and the edges touching it, without checks (subgraph expansion).
    pub(crate) fn take_node(&mut self, id: &NodeId) -> Option<GraphNode> {
        self.edges.retain(|e| &e.from.node != id && &e.to.node != id);
        self.layout.remove(id);
        self.nodes.remove(id)
    }

    /// Free text shown in catalogues and the editor.
    pub fn description(&self) -> &str {
        &self.description
    }

    /// Nodes by id.
    pub fn nodes(&self) -> &BTreeMap<NodeId, GraphNode> {
        &self.nodes
    }

    /// Node `id`, if the graph has it.
    pub fn node(&self, id: &str) -> Option<&GraphNode> {
        self.nodes.get(id)
    }

    /// Whether the graph has node `id`.
    pub fn contains(&self, id: &str) -> bool {
        self.nodes.contains_key(id)
    }

    /// Every edge, sorted.
    pub fn edges(&self) -> impl Iterator<Item = &Edge> {
        self.edges.iter()
    }

    /// Whether `from → to` is an edge.
    pub fn has_edge(&self, from: &PortRef, to: &PortRef) -> bool {
        self.edges.contains(&Edge { from: from.clone(), to: to.clone() })
    }

    /// The edge feeding input `to`, if any.
    pub fn edge_into(&self, to: &PortRef) -> Option<&Edge> {
        self.edges.iter().find(|e| &e.to == to)
    }

    /// Graph inputs (promoted parameters) by public name.
    pub fn inputs(&self) -> &BTreeMap<String, ParamPath> {
        &self.inputs
    }

    /// Canvas positions by node id.
    pub fn layout(&self) -> &BTreeMap<NodeId, (f32, f32)> {
        &self.layout
    }

    /// Adds node `id` of `kind` (both checked; see [`rules::check_kind`]) at canvas position `pos`.
    pub fn add_node(&mut self, registry: &Registry, id: NodeId, kind: &str, pos: (f32, f32)) -> Result<(), GraphError> {
        id.check()?;
        if self.nodes.contains_key(&id) {
            return Err(GraphError::DuplicateId(id));
        }
        rules::check_kind(registry, &id, kind)?;
        self.layout.insert(id.clone(), pos);
        self.nodes.insert(id, GraphNode { kind: kind.to_string(), params: BTreeMap::new(), bypass: false });
        Ok(())
    }

    /// Renames node `from` to `to` (a valid, unused id): its wires, canvas position, the
    /// graph inputs and ports that name it follow.
    pub fn rename_node(&mut self, from: &NodeId, to: NodeId) -> Result<(), GraphError> {
        to.check()?;
        if self.nodes.contains_key(&to) {
            return Err(GraphError::DuplicateId(to));
        }
        let node = self.nodes.remove(from).ok_or_else(|| rules::unknown_node(from))?;
        self.nodes.insert(to.clone(), node);
        if let Some(pos) = self.layout.remove(from) {
            self.layout.insert(to.clone(), pos);
        }
        let moved = |port: &PortRef| {
            if &port.node == from { PortRef::new(to.clone(), port.port.as_str()) } else { port.clone() }
        };
        self.edges = self.edges.iter().map(|e| Edge { from: moved(&e.from), to: moved(&e.to) }).collect();
        for target in self.inputs.values_mut() {
            if &target.node == from {
                target.node = to.clone();
            }
        }
        for targets in self.ports.inputs.values_mut() {
            targets.iter_mut().for_each(|t| *t = moved(t));
        }
        for source in self.ports.outputs.values_mut() {
            *source = moved(source);
        }
        Ok(())
    }

    /// Removes nodes `ids` with their edges, layout entries and the graph inputs that point
    /// at them; all or nothing.
    pub fn remove_nodes(&mut self, ids: &[NodeId]) -> Result<Removal, GraphError> {
        if let Some(missing) = ids.iter().find(|id| !self.nodes.contains_key(*id)) {
            return Err(GraphError::UnknownNode { id: missing.clone(), hint: String::new() });
        }
        let wanted: BTreeSet<&NodeId> = ids.iter().collect();
        let mut removal = Removal::default();
        for id in &wanted {
            if let Some(node) = self.nodes.remove(*id) {
                let pos = self.layout.remove(*id);
                removal.nodes.push(RemovedNode { id: (*id).clone(), node, pos });
            }
        }
        let (gone, kept): (BTreeSet<Edge>, BTreeSet<Edge>) = std::mem::take(&mut self.edges)
            .into_iter()
            .partition(|e| wanted.contains(&e.from.node) || wanted.contains(&e.to.node));
        self.edges = kept;
        removal.edges = gone.into_iter().collect();
        let (gone, kept): (BTreeMap<String, ParamPath>, BTreeMap<String, ParamPath>) =
            std::mem::take(&mut self.inputs).into_iter().partition(|(_, p)| wanted.contains(&p.node));
        self.inputs = kept;
        removal.inputs = gone.into_iter().collect();
        Ok(removal)
    }

    /// `ids` and every node downstream of them (fed by their outputs, directly or not).
    pub fn downstream_of<'a>(&self, ids: impl IntoIterator<Item = &'a NodeId>) -> BTreeSet<NodeId> {
        let mut seen = BTreeSet::new();
        let mut stack: Vec<&NodeId> = ids.into_iter().collect();
        while let Some(node) = stack.pop() {
            if seen.insert(node.clone()) {
                stack.extend(self.edges.iter().filter(|e| &e.from.node == node).map(|e| &e.to.node));
            }
        }
        seen
    }

    /// Puts back what [`Graph::remove_nodes`] took out (or pastes nodes): all or nothing.
    /// Ids are checked by the id rule; edges and inputs are restored as they were.
    pub fn restore(&mut self, removal: &Removal) -> Result<(), GraphError> {
        let mut ids = BTreeSet::new();
        for n in &removal.nodes {
            n.id.check()?;
            if self.nodes.contains_key(&n.id) || !ids.insert(&n.id) {
                return Err(GraphError::DuplicateId(n.id.clone()));
            }
        }
        for n in &removal.nodes {
            self.nodes.insert(n.id.clone(), n.node.clone());
            if let Some(pos) = n.pos {
                self.layout.insert(n.id.clone(), pos);
            }
        }
        self.edges.extend(removal.edges.iter().cloned());
        self.inputs.extend(removal.inputs.iter().cloned());
        Ok(())
    }

    /// Connects output `from` to input `to` after [`rules::check_connect`]; whatever fed
    /// `to` before is replaced and returned.
    pub fn connect(&mut self, registry: &Registry, from: &PortRef, to: &PortRef) -> Result<Option<Edge>, GraphError> {
        rules::check_connect(self, registry, from, to)?;
        let replaced = self.edge_into(to).cloned();
        if let Some(old) = &replaced {
            self.edges.remove(old);
        }
        self.edges.insert(Edge { from: from.clone(), to: to.clone() });
        Ok(replaced)
    }

    /// Removes the edge `from → to`.
    pub fn disconnect(&mut self, from: &PortRef, to: &PortRef) -> Result<(), GraphError> {
        if self.edges.remove(&Edge { from: from.clone(), to: to.clone() }) {
            Ok(())
        } else {
            Err(GraphError::NotConnected { from: from.clone(), to: to.clone() })
        }
    }

    /// Sets a parameter after checking it against its schema (the stored value is the
    /// checked, canonical one: an integer given for a real becomes a real). Returns the
    /// value it had in the graph, if any.
    pub fn set_param(
        &mut self,
        registry: &Registry,
        path: &ParamPath,
        value: &ParamValue,
    ) -> Result<Option<ParamValue>, GraphError> {
        let value = rules::check_param(self, registry, path, value)?;
        let node = self.nodes.get_mut(&path.node).ok_or_else(|| rules::unknown_node(&path.node))?;
        Ok(node.params.insert(path.param.clone(), value))
    }

    /// Bypasses node `id` (`true`) or lets it run again; returns whether it was bypassed.
    pub fn set_bypass(&mut self, id: &NodeId, bypass: bool) -> Result<bool, GraphError> {
        let node = self.nodes.get_mut(id).ok_or_else(|| rules::unknown_node(id))?;
        Ok(std::mem::replace(&mut node.bypass, bypass))
    }

    /// Removes a parameter's value so the schema default applies; returns the old value.
    pub fn reset_param(&mut self, registry: &Registry, path: &ParamPath) -> Result<Option<ParamValue>, GraphError> {
        if !rules::is_subgraph(self, &path.node) {
            rules::param_spec(self, registry, path)?;
        }
        let node = self.nodes.get_mut(&path.node).ok_or_else(|| rules::unknown_node(&path.node))?;
        Ok(node.params.remove(&path.param))
    }

    /// Sets (`Some`) or removes (`None`) a node's canvas position; returns the old one.
    pub fn set_position(&mut self, id: &NodeId, pos: Option<(f32, f32)>) -> Result<Option<(f32, f32)>, GraphError> {
        if !self.nodes.contains_key(id) {
            return Err(rules::unknown_node(id));
        }
        Ok(match pos {
            Some(p) => self.layout.insert(id.clone(), p),
            None => self.layout.remove(id),
        })
    }

    /// Promotes a parameter to graph input `name` (`Some`) or removes the input (`None`);
    /// returns what it pointed at before.
    pub fn set_input(
        &mut self,
        registry: &Registry,
        name: &str,
        target: Option<&ParamPath>,
    ) -> Result<Option<ParamPath>, GraphError> {
        if let Some(target) = target {
            rules::check_input(self, registry, name, target)?;
        }
        Ok(match target {
            Some(t) => self.inputs.insert(name.to_string(), t.clone()),
            None => self.inputs.remove(name),
        })
    }

    /// Replaces the description; returns the old one.
    pub fn set_description(&mut self, text: &str) -> String {
        std::mem::replace(&mut self.description, text.to_string())
    }

    /// Rewrites the graph's input-file parameters: `relocate` gets each path as written and
    /// returns its new text, or `None` to leave it. One place for "where do this graph's files
    /// live" (subgraph files moved into another graph, a corpus kept elsewhere).
    pub fn relocate_input_files(
        &mut self,
        registry: &Registry,
        relocate: impl Fn(&str) -> Option<String>,
    ) -> Result<(), GraphError> {
        let mut moves = Vec::new();
        for (id, node) in &self.nodes {
            for (name, value) in &node.params {
                let path = ParamPath::new(id.clone(), name.as_str());
                if let ParamValue::Text(text) = value
                    && super::is_input_file(self, registry, &path).unwrap_or(false)
                    && let Some(moved) = relocate(text)
                {
                    moves.push((path, ParamValue::Text(moved)));
                }
            }
        }
        for (path, value) in moves {
            self.set_param(registry, &path, &value)?;
        }
        Ok(())
    }

    /// The parameter a setting name means: a graph input's target, else `node.param`.
    pub fn resolve(&self, name: &str) -> Result<ParamPath, GraphError> {
        let unknown =
            || GraphError::UnknownSetting { name: name.to_string(), inputs: self.inputs.keys().cloned().collect() };
        let path = match self.inputs.get(name) {
            Some(path) => path.clone(),
            None => ParamPath::parse(name).ok_or_else(unknown)?,
        };
        if !self.nodes.contains_key(&path.node) {
            return Err(GraphError::UnknownNode {
                id: path.node.clone(),
                hint: kinegraph_nodes::node::did_you_mean(path.node.as_str(), self.nodes.keys().map(NodeId::as_str)),
            });
        }
        Ok(path)
    }
}
