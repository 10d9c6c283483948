//! Collapsing a selection into a subgraph: the selected nodes move to a new graph file
//! whose ports are the wires crossing the selection's border, and one subgraph node takes
//! their place, wired as they were (one undo step).
//!
//! Steps: 1. take the selection out of a copy of the graph (its nodes, the edges touching
//! them and the graph inputs pointing at them); 2. the edges inside stay inside; edges coming
//! in become input ports, one per outer output (an output feeding several selected inputs is
//! one port, as `lock_feet.ron`'s `clip`); edges going out become output ports, one per
//! inner output; 3. graph inputs that pointed inside are kept by the file and point at the
//! new node's parameter; 4. relative input paths are rewritten for the file's folder.

use std::collections::BTreeMap;
use std::path::Path;

use kinegraph_nodes::node::{ParamValue, Registry};

use super::commands::{EditError, EditorCommand};
use crate::document::{SUBGRAPH_FILE_PARAM, SUBGRAPH_KIND};
use crate::farm::plan::relative_to;
use crate::graph::{Edge, Graph, NodeId, ParamPath, PortRef, Ports, Removal};

/// A collapse worked out: the subgraph file's graph and the edit that puts the new node in
/// place of the selection.
#[derive(Debug)]
pub struct Collapse {
    /// The new file's graph.
    pub file: Graph,
    /// One undo step on the graph the selection was in.
    pub command: EditorCommand,
}

/// Collapses `selection` of `graph` (whose relative paths resolve against `graph_dir`) into
/// the file `file_path`, to be used by a new node `id`.
pub fn collapse(
    graph: &Graph,
    registry: &Registry,
    selection: &[NodeId],
    id: NodeId,
    graph_dir: &Path,
    file_path: &Path,
) -> Result<Collapse, EditError> {
    if selection.is_empty() {
        return Err(EditError::NothingTo("collapse"));
    }
    let mut rest = graph.clone();
    let removal = rest.remove_nodes(selection)?;
    let inside = |port: &PortRef| selection.contains(&port.node);
    let (internal, crossing): (Vec<&Edge>, Vec<&Edge>) =
        removal.edges.iter().partition(|e| inside(&e.from) && inside(&e.to));
    let (incoming, outgoing): (Vec<&Edge>, Vec<&Edge>) = crossing.into_iter().partition(|e| inside(&e.to));

    // Ports: one per outer output coming in, one per inner output going out.
    let mut ins: BTreeMap<&PortRef, Vec<PortRef>> = BTreeMap::new();
    for e in &incoming {
        ins.entry(&e.from).or_default().push(e.to.clone());
    }
    let outs: Vec<&PortRef> = {
        let mut v: Vec<&PortRef> = outgoing.iter().map(|e| &e.from).collect();
        v.sort();
        v.dedup();
        v
    };
    let in_names = port_names(ins.values().map(|targets| &targets[0]));
    let out_names = port_names(outs.iter().copied());
    let mut ports = Ports::default();
    for ((_, targets), name) in ins.iter().zip(&in_names) {
        ports.inputs.insert(name.clone(), targets.clone());
    }
    for (source, name) in outs.iter().zip(&out_names) {
        ports.outputs.insert(name.clone(), (*source).clone());
    }

    // The file: the selected nodes (placed from the origin), their inner edges, their inputs.
    let (min_x, min_y) = removal
        .nodes
        .iter()
        .filter_map(|n| n.pos)
        .fold((f32::INFINITY, f32::INFINITY), |(x, y), (px, py)| (x.min(px), y.min(py)));
    let shift = |p: (f32, f32)| if min_x.is_finite() { (p.0 - min_x, p.1 - min_y) } else { p };
    let mut file = Graph::new();
    file.restore(&Removal {
        nodes: removal.nodes.iter().map(|n| crate::graph::RemovedNode { pos: n.pos.map(shift), ..n.clone() }).collect(),
        edges: internal.into_iter().cloned().collect(),
        inputs: removal.inputs.clone(),
    })?;
    file.set_ports(ports);
    let names: Vec<&str> = selection.iter().map(NodeId::as_str).collect();
    file.set_description(&format!("Collapsed from nodes {}.", names.join(", ")));
    let file_dir = file_path.parent().unwrap_or(Path::new(""));
    if std::path::absolute(file_dir).ok() != std::path::absolute(graph_dir).ok() {
        file.relocate_input_files(registry, |text| {
            Path::new(text).is_relative().then(|| relative_to(&graph_dir.join(text), file_dir))
        })?;
    }

    // The edit: the node in the selection's place, wired through its ports.
    let centre =
        removal.nodes.iter().filter_map(|n| n.pos).fold((0.0, 0.0, 0.0), |(x, y, k), p| (x + p.0, y + p.1, k + 1.0));
    let pos = if centre.2 > 0.0 { (centre.0 / centre.2, centre.1 / centre.2) } else { (0.0, 0.0) };
    let mut cmds = vec![
        EditorCommand::RemoveNodes { ids: selection.to_vec() },
        EditorCommand::AddNode { id: id.clone(), kind: SUBGRAPH_KIND.into(), pos },
        EditorCommand::SetParam {
            param: ParamPath::new(id.clone(), SUBGRAPH_FILE_PARAM),
            value: ParamValue::Text(relative_to(file_path, graph_dir)),
        },
    ];
    for ((from, _), name) in ins.iter().zip(&in_names) {
        cmds.push(EditorCommand::Connect { from: (*from).clone(), to: PortRef::new(id.clone(), name.as_str()) });
    }
    for e in &outgoing {
        let index = outs.iter().position(|s| **s == e.from).unwrap_or(0);
        let from = PortRef::new(id.clone(), out_names[index].as_str());
        cmds.push(EditorCommand::Connect { from, to: e.to.clone() });
    }
    for (name, _) in &removal.inputs {
        cmds.push(EditorCommand::SetInput {
            name: name.clone(),
            target: Some(ParamPath::new(id.clone(), name.as_str())),
        });
    }
    Ok(Collapse { file, command: EditorCommand::Batch(cmds) })
}

/// Public names for ports led to `ports` in order: the inner port's own name where that is
/// unique, else `node_port`.
fn port_names<'a>(ports: impl Iterator<Item = &'a PortRef>) -> Vec<String> {
    let ports: Vec<&PortRef> = ports.collect();
    ports
        .iter()
        .map(|p| {
            let shared = ports.iter().filter(|q| q.port == p.port).count() > 1;
            if shared { format!("{}_{}", p.node.as_str(), p.port) } else { p.port.clone() }
        })
        .collect()
}
