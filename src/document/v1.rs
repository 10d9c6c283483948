//! Version 1 of the graph file (the pre-release draft): nodes as a list, edges as
//! `("node.port", "node.port")` pairs, and the clip loader's scale parameter named
//! `scale`. Frozen: a fixture lives in `graphs/legacy/v1/`; never edit this shape.

use std::collections::BTreeMap;

use kinegraph_nodes::node::ParamValue;
use serde::Deserialize;

use super::{CURRENT_VERSION, EdgeDoc, FORMAT, GraphDoc, NodeDoc};

/// A version-1 graph file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraphDocV1 {
    /// Always `"kinegraph.graph"`.
    pub format: String,
    /// Always 1.
    pub version: u32,
    /// Nodes in file order.
    pub nodes: Vec<NodeV1>,
    /// Edges as (from, to).
    #[serde(default)]
    pub edges: Vec<(String, String)>,
}

/// A version-1 node.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeV1 {
    /// Node id.
    pub id: String,
    /// Node kind.
    pub kind: String,
    /// Parameters.
    #[serde(default)]
    pub params: BTreeMap<String, ParamValue>,
}

/// Brings a version-1 document to the current version.
pub fn migrate(old: GraphDocV1) -> GraphDoc {
    let nodes = old
        .nodes
        .into_iter()
        .map(|n| {
            let mut params = n.params;
            if n.kind == "clip.load"
                && let Some(scale) = params.remove("scale")
            {
                params.insert("metres_per_unit".to_string(), scale);
            }
            (n.id, NodeDoc { kind: n.kind, params })
        })
        .collect();
    GraphDoc {
        format: FORMAT.to_string(),
        version: CURRENT_VERSION,
        description: String::new(),
        inputs: BTreeMap::new(),
        nodes,
        edges: old.edges.into_iter().map(|(from, to)| EdgeDoc { from, to }).collect(),
        layout: BTreeMap::new(),
    }
}
