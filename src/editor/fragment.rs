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

use super::commands::{EditError, EditorCommand, RemovedNode};
use crate::document::{self, GraphDoc, split_endpoint};

/// Where a pasted fragment lands relative to where it was copied from (canvas units).
pub const PASTE_OFFSET: (f32, f32) = (40.0, 40.0);

/// The graph-file text of nodes `ids` of `doc` with the wires between them and their
/// positions; `None` when none of `ids` exists. Wires to nodes outside the fragment and
/// graph inputs are left out.
pub fn copy(doc: &GraphDoc, ids: &[String]) -> Option<String> {
    let wanted: BTreeSet<&str> = ids.iter().map(String::as_str).filter(|id| doc.nodes.contains_key(*id)).collect();
    if wanted.is_empty() {
        return None;
    }
    let inside = |endpoint: &str| split_endpoint(endpoint).is_some_and(|(n, _)| wanted.contains(n));
    let mut fragment = GraphDoc::new();
    fragment.nodes =
        doc.nodes.iter().filter(|(id, _)| wanted.contains(id.as_str())).map(|(i, n)| (i.clone(), n.clone())).collect();
    fragment.edges = doc.edges.iter().filter(|e| inside(&e.from) && inside(&e.to)).cloned().collect();
    fragment.layout =
        doc.layout.iter().filter(|(id, _)| wanted.contains(id.as_str())).map(|(i, p)| (i.clone(), *p)).collect();
    Some(document::to_string(&fragment))
}

/// The batch that pastes fragment `text` into `doc`, and the ids the pasted nodes get (in
/// the fragment's order). Refused, with why, when the text is not a graph, a kind is not
/// registered or a wire does not fit.
pub fn paste(doc: &GraphDoc, registry: &Registry, text: &str) -> Result<(EditorCommand, Vec<String>), EditError> {
    let fragment =
        document::parse(text, Path::new("clipboard")).map_err(|e| EditError::BadFragment(e.to_string()))?.doc;
    if fragment.nodes.is_empty() {
        return Err(EditError::BadFragment("it holds no nodes".into()));
    }
    if let Some(node) = fragment.nodes.values().find(|n| registry.get(&n.kind).is_none()) {
        return Err(EditError::UnknownKind(node.kind.clone()));
    }
    let mut renamed: BTreeMap<&str, String> = BTreeMap::new();
    let mut taken: BTreeSet<String> = doc.nodes.keys().cloned().collect();
    for id in fragment.nodes.keys() {
        let new_id = unused_id(id, &taken);
        taken.insert(new_id.clone());
        renamed.insert(id, new_id);
    }
    let nodes = fragment
        .nodes
        .iter()
        .map(|(id, node)| RemovedNode {
            id: renamed[id.as_str()].clone(),
            node: node.clone(),
            pos: fragment.layout.get(id).map(|&(x, y)| (x + PASTE_OFFSET.0, y + PASTE_OFFSET.1)),
        })
        .collect();
    let rename = |endpoint: &str| -> Result<String, EditError> {
        let (node, port) = split_endpoint(endpoint).ok_or_else(|| EditError::BadEndpoint(endpoint.to_string()))?;
        let node = renamed.get(node).ok_or_else(|| EditError::UnknownNode(node.to_string()))?;
        Ok(format!("{node}.{port}"))
    };
    let mut batch = vec![EditorCommand::RestoreNodes { nodes, edges: Vec::new(), inputs: Vec::new() }];
    for edge in &fragment.edges {
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
    use crate::editor::commands::History;

    fn demo() -> GraphDoc {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        document::load_file(&path).unwrap().doc
    }

    #[test]
    fn a_copied_pair_pastes_with_fresh_ids_its_inner_wire_and_an_offset() {
        let (registry, mut doc) = (kinegraph_nodes::builtin::registry(), demo());
        let text = copy(&doc, &["trim".into(), "resample".into(), "nonexistent".into()]).unwrap();
        // The fragment is a graph file of its own with the wire between the two and no other.
        let fragment = document::parse(&text, Path::new("f.ron")).unwrap().doc;
        assert_eq!(fragment.nodes.keys().collect::<Vec<_>>(), ["resample", "trim"]);
        assert_eq!(fragment.edges.len(), 1);
        assert_eq!((fragment.edges[0].from.as_str(), fragment.edges[0].to.as_str()), ("trim.clip", "resample.clip"));

        let before = document::to_string(&doc);
        let mut history = History::new();
        let (cmd, ids) = paste(&doc, &registry, &text).unwrap();
        assert_eq!(ids, ["resample_2", "trim_2"]);
        assert!(history.apply(&mut doc, &registry, cmd).unwrap());
        assert_eq!(doc.nodes["trim_2"], doc.nodes["trim"]);
        assert!(doc.edges.iter().any(|e| e.from == "trim_2.clip" && e.to == "resample_2.clip"));
        assert!(!doc.edges.iter().any(|e| e.to == "trim_2.clip"), "the wire from outside the fragment stays out");
        let (x, y) = doc.layout["trim"];
        assert_eq!(doc.layout["trim_2"], (x + PASTE_OFFSET.0, y + PASTE_OFFSET.1));
        // One undo step takes the whole paste back, byte for byte.
        history.undo(&mut doc, &registry).unwrap();
        assert_eq!(document::to_string(&doc), before);
    }

    #[test]
    fn pasting_twice_keeps_ids_unique() {
        let (registry, mut doc) = (kinegraph_nodes::builtin::registry(), demo());
        let text = copy(&doc, &["trim".into()]).unwrap();
        for expected in ["trim_2", "trim_3"] {
            let (cmd, ids) = paste(&doc, &registry, &text).unwrap();
            assert_eq!(ids, [expected]);
            super::super::commands::apply(&mut doc, &registry, &cmd).unwrap();
        }
        assert_eq!(unused_id("trim_3", &doc.nodes.keys().cloned().collect()), "trim_4");
    }

    #[test]
    fn text_that_is_no_fragment_is_refused_and_changes_nothing() {
        let (registry, doc) = (kinegraph_nodes::builtin::registry(), demo());
        assert!(copy(&doc, &["nope".into()]).is_none());
        let empty = format!("(format: \"{}\", version: {}, nodes: {{}})", document::FORMAT, document::CURRENT_VERSION);
        for text in ["hello", empty.as_str()] {
            assert!(matches!(paste(&doc, &registry, text), Err(EditError::BadFragment(_))), "{text}");
        }
        let mut unknown = GraphDoc::new();
        unknown.nodes.insert("x".into(), crate::document::NodeDoc { kind: "no.such".into(), params: BTreeMap::new() });
        assert_eq!(
            paste(&doc, &registry, &document::to_string(&unknown)).unwrap_err(),
            EditError::UnknownKind("no.such".into())
        );
        // A wire between mismatched ports fails the batch as a whole.
        let mut bad = GraphDoc::new();
        bad.nodes.insert("m".into(), doc.nodes["mesh"].clone());
        bad.nodes.insert("t".into(), doc.nodes["trim"].clone());
        bad.edges.push(crate::document::EdgeDoc { from: "m.mesh".into(), to: "t.clip".into() });
        let (cmd, _) = paste(&doc, &registry, &document::to_string(&bad)).unwrap();
        let mut copy_of = doc.clone();
        assert!(matches!(
            super::super::commands::apply(&mut copy_of, &registry, &cmd),
            Err(EditError::TypeMismatch { .. })
        ));
        assert_eq!(copy_of, doc);
    }
}
