//! Copy and paste of graph fragments: some nodes, the wires between them and their canvas
//! positions, carried as the text of a graph file. A copied fragment pasted into a text
//! editor is a graph `kg check` reads, and the text of any graph file pastes as a fragment.
//!
//! Pasting is one undoable batch: the nodes are added under ids not yet used (`trim` →
//! `trim_2`), offset so they do not hide the originals, then the fragment's own wires are
//! connected through the reducer, which checks their port types like any other connection.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use kinegraph_nodes::node::Registry;

use super::commands::{EditError, EditorCommand};
use crate::document;
use crate::graph::{Graph, GraphError, GraphFile, NodeId, PortRef, Removal, RemovedNode, rules};

/// Where a pasted fragment lands relative to where it was copied from (canvas units).
pub const PASTE_OFFSET: (f32, f32) = (40.0, 40.0);

/// The graph-file text of nodes `ids` of `graph` with the wires between them and their
/// positions; `None` when none of `ids` exists. Wires to nodes outside the fragment and
/// graph inputs are left out.
pub fn copy(graph: &Graph, ids: &[String]) -> Option<String> {
    let wanted: BTreeSet<&str> = ids.iter().map(String::as_str).filter(|id| graph.contains(id)).collect();
    if wanted.is_empty() {
        return None;
    }
    let mut whole = graph.to_doc();
    let inside = |endpoint: &str| PortRef::parse(endpoint).is_ok_and(|p| wanted.contains(p.node.as_str()));
    whole.nodes.retain(|id, _| wanted.contains(id.as_str()));
    whole.edges.retain(|e| inside(&e.from) && inside(&e.to));
    whole.layout.retain(|id, _| wanted.contains(id.as_str()));
    whole.inputs.clear();
    whole.description.clear();
    Some(document::to_string(&whole))
}

/// The batch that pastes fragment `text` into `graph`, and the ids the pasted nodes get (in
/// the fragment's order). Refused, with why, when the text is not a graph, a kind is not
/// registered or a wire does not fit.
pub fn paste(graph: &Graph, registry: &Registry, text: &str) -> Result<(EditorCommand, Vec<NodeId>), EditError> {
    let fragment =
        GraphFile::parse(text, Path::new("clipboard")).map_err(|e| EditError::BadFragment(e.to_string()))?.graph;
    if fragment.nodes().is_empty() {
        return Err(EditError::BadFragment("it holds no nodes".into()));
    }
    for (id, node) in fragment.nodes() {
        rules::check_kind(registry, id, &node.kind)?;
    }
    let mut renamed: BTreeMap<&NodeId, NodeId> = BTreeMap::new();
    let mut taken: BTreeSet<String> = graph.nodes().keys().map(|id| id.as_str().to_string()).collect();
    for id in fragment.nodes().keys() {
        let new_id = unused_id(id.as_str(), &taken);
        taken.insert(new_id.clone());
        renamed.insert(id, NodeId::new(new_id));
    }
    let nodes = fragment
        .nodes()
        .iter()
        .map(|(id, node)| RemovedNode {
            id: renamed[id].clone(),
            node: node.clone(),
            pos: fragment.layout().get(id).map(|&(x, y)| (x + PASTE_OFFSET.0, y + PASTE_OFFSET.1)),
        })
        .collect();
    let rename = |port: &PortRef| -> Result<PortRef, GraphError> {
        let node = renamed
            .get(&port.node)
            .ok_or_else(|| GraphError::EdgeToUnknownNode { port: port.clone(), hint: String::new() })?;
        Ok(PortRef::new(node.clone(), port.port.as_str()))
    };
    let mut batch = vec![EditorCommand::RestoreNodes(Removal { nodes, ..Removal::default() })];
    for edge in fragment.edges() {
        batch.push(EditorCommand::Connect { from: rename(&edge.from)?, to: rename(&edge.to)? });
    }
    Ok((EditorCommand::Batch(batch), renamed.into_values().collect()))
}

/// `id` itself when free, else its stem with the first free `_N` (`trim_2` → `trim_3`).
fn unused_id(id: &str, taken: &BTreeSet<String>) -> String {
    if !taken.contains(id) {
        return id.to_string();
    }
    let stem = match id.rsplit_once('_') {
        Some((stem, n)) if !stem.is_empty() && n.parse::<u32>().is_ok() => stem,
        _ => id,
    };
    (2..).map(|n| format!("{stem}_{n}")).find(|c| !taken.contains(c)).unwrap_or_else(|| id.to_string())
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::document::{EdgeDoc, GraphDoc, NodeDoc};
    use crate::editor::commands::{History, apply};
    use crate::graph::ParamPath;

    fn demo() -> Graph {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        GraphFile::load(&path).unwrap().graph
    }

    fn port(text: &str) -> PortRef {
        PortRef::parse(text).unwrap()
    }

    #[test]
    fn a_copied_pair_pastes_with_fresh_ids_its_inner_wire_and_an_offset() {
        let (registry, mut graph) = (kinegraph_nodes::builtin::registry(), demo());
        let text = copy(&graph, &["trim".into(), "resample".into(), "nonexistent".into()]).unwrap();
        // The fragment is a graph file of its own with the wire between the two and no other.
        let fragment = document::parse(&text, Path::new("f.ron")).unwrap().doc;
        assert_eq!(fragment.nodes.keys().collect::<Vec<_>>(), ["resample", "trim"]);
        assert_eq!(fragment.edges.len(), 1);
        assert_eq!((fragment.edges[0].from.as_str(), fragment.edges[0].to.as_str()), ("trim.clip", "resample.clip"));

        let before = document::to_string(&graph.to_doc());
        let mut history = History::new();
        let (cmd, ids) = paste(&graph, &registry, &text).unwrap();
        assert_eq!(ids, [NodeId::from("resample_2"), NodeId::from("trim_2")]);
        assert!(history.apply(&mut graph, &registry, cmd).unwrap());
        assert_eq!(graph.node("trim_2"), graph.node("trim"));
        assert!(graph.has_edge(&port("trim_2.clip"), &port("resample_2.clip")));
        assert!(graph.edge_into(&port("trim_2.clip")).is_none(), "the wire from outside the fragment stays out");
        let (x, y) = graph.layout()["trim"];
        assert_eq!(graph.layout()["trim_2"], (x + PASTE_OFFSET.0, y + PASTE_OFFSET.1));
        // One undo step takes the whole paste back, byte for byte.
        history.undo(&mut graph, &registry).unwrap();
        assert_eq!(document::to_string(&graph.to_doc()), before);
    }

    #[test]
    fn pasting_twice_keeps_ids_unique() {
        let (registry, mut graph) = (kinegraph_nodes::builtin::registry(), demo());
        let text = copy(&graph, &["trim".into()]).unwrap();
        for expected in ["trim_2", "trim_3"] {
            let (cmd, ids) = paste(&graph, &registry, &text).unwrap();
            assert_eq!(ids, [NodeId::from(expected)]);
            apply(&mut graph, &registry, &cmd).unwrap();
        }
        let taken = graph.nodes().keys().map(|id| id.as_str().to_string()).collect();
        assert_eq!(unused_id("trim_3", &taken), "trim_4");
        assert!(ParamPath::parse("trim_3.end_secs").is_some());
    }

    #[test]
    fn text_that_is_no_fragment_is_refused_and_changes_nothing() {
        let (registry, graph) = (kinegraph_nodes::builtin::registry(), demo());
        assert!(copy(&graph, &["nope".into()]).is_none());
        let empty = format!("(format: \"{}\", version: {}, nodes: {{}})", document::FORMAT, document::CURRENT_VERSION);
        for text in ["hello", empty.as_str()] {
            assert!(matches!(paste(&graph, &registry, text), Err(EditError::BadFragment(_))), "{text}");
        }
        let mut unknown = GraphDoc::new();
        unknown.nodes.insert("x".into(), NodeDoc { kind: "no.such".into(), params: BTreeMap::new(), bypass: false });
        assert!(matches!(
            paste(&graph, &registry, &document::to_string(&unknown)),
            Err(EditError::Graph(GraphError::UnknownKind { .. }))
        ));
        // A wire between mismatched ports fails the batch as a whole.
        let doc = graph.to_doc();
        let mut bad = GraphDoc::new();
        bad.nodes.insert("m".into(), doc.nodes["mesh"].clone());
        bad.nodes.insert("t".into(), doc.nodes["trim"].clone());
        bad.edges.push(EdgeDoc { from: "m.mesh".into(), to: "t.clip".into() });
        let (cmd, _) = paste(&graph, &registry, &document::to_string(&bad)).unwrap();
        let mut copy_of = graph.clone();
        assert!(matches!(apply(&mut copy_of, &registry, &cmd), Err(EditError::Graph(GraphError::TypeMismatch { .. }))));
        assert_eq!(copy_of, graph);
    }
}
