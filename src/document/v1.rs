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
    /// Parameters (a repeated name is an error, as in the current version).
    #[serde(default, deserialize_with = "super::unique_param_names")]
    pub params: BTreeMap<String, ParamValue>,
}

/// Brings a version-1 document to the current version. Refused, saying what to keep,
/// where the old file is ambiguous: two nodes with one id (version 1 listed nodes, so
/// nothing stopped it), or a loader setting both `scale` and its new name.
pub fn migrate(old: GraphDocV1) -> Result<GraphDoc, String> {
    let mut nodes = BTreeMap::new();
    for n in old.nodes {
        let mut params = n.params;
        if n.kind == "clip.load"
            && let Some(scale) = params.remove("scale")
        {
            if let Some(new) = params.get("metres_per_unit") {
                return Err(format!(
                    "node '{}' sets both 'scale' ({scale}, the version-1 name) and 'metres_per_unit' ({new}): \
                     delete one of them",
                    n.id.escape_debug()
                ));
            }
            params.insert("metres_per_unit".to_string(), scale);
        }
        if nodes.insert(n.id.clone(), NodeDoc { kind: n.kind, params, bypass: false }).is_some() {
            return Err(format!("two nodes have the id '{}': rename or delete one of them", n.id.escape_debug()));
        }
    }
    Ok(GraphDoc {
        format: FORMAT.to_string(),
        version: CURRENT_VERSION,
        description: String::new(),
        inputs: BTreeMap::new(),
        nodes,
        edges: old.edges.into_iter().map(|(from, to)| EdgeDoc { from, to }).collect(),
        layout: BTreeMap::new(),
        ports: Default::default(),
    })
}
