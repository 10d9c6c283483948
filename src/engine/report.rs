//! What a run reports, per node and overall; serialises to the `--json` report.

use std::collections::BTreeMap;
use std::path::PathBuf;

use kinegraph_nodes::node::{Registry, Report, Value};

use crate::graph::PortRef;
use serde::Serialize;

/// How a node's evaluation ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeStatus {
    /// Ran and succeeded.
    Ok,
    /// Result reused from an earlier run with identical inputs and parameters.
    Cached,
    /// Ran and failed.
    Error,
    /// Not run because an upstream node failed or was blocked.
    Blocked,
    /// Not run (or stopped) because the run was cancelled.
    Cancelled,
    /// Not run: bypassed in the graph, it passed its inputs on.
    Bypassed,
}

/// One node's part of a run.
#[derive(Clone, Debug, Serialize)]
pub struct NodeReport {
    /// Node kind.
    pub kind: String,
    /// Outcome.
    pub status: NodeStatus,
    /// Wall time spent in the node (0 when cached or not run), seconds.
    pub seconds: f64,
    /// Bytes of the node's output arrays ([`Value::array_bytes`]; 0 when not run).
    pub output_bytes: u64,
    /// Oddities the node reported.
    pub warnings: Vec<String>,
    /// The failure, for `error`, or what blocked it, for `blocked`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The result of one run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RunReport {
    /// Per node id, the nodes the run needed.
    pub nodes: BTreeMap<String, NodeReport>,
    /// Files written, absolute paths, sorted.
    pub files_written: Vec<PathBuf>,
    /// Whole run, seconds.
    pub seconds: f64,
    /// Output values per node id, in schema order (not serialised).
    #[serde(skip)]
    pub outputs: BTreeMap<String, Vec<Option<Value>>>,
}

impl RunReport {
    /// The value a node gave at output `port` (found by its kind's schema), if it ran.
    pub fn output(&self, registry: &Registry, port: &PortRef) -> Option<&Value> {
        let kind = &self.nodes.get(port.node.as_str())?.kind;
        let index = registry.get(kind)?.schema().outputs.iter().position(|p| p.name == port.port)?;
        self.outputs.get(port.node.as_str())?.get(index)?.as_ref()
    }

    /// True when every needed node succeeded (ran, cached or bypassed).
    pub fn succeeded(&self) -> bool {
        self.nodes.values().all(|n| matches!(n.status, NodeStatus::Ok | NodeStatus::Cached | NodeStatus::Bypassed))
    }

    /// Each node's structured report (its first report output), by node id; a bypassed
    /// node has none of its own.
    pub fn reports(&self) -> BTreeMap<&str, &Report> {
        self.outputs
            .iter()
            .filter(|(id, _)| self.nodes.get(id.as_str()).is_none_or(|n| n.status != NodeStatus::Bypassed))
            .filter_map(|(id, outputs)| {
                outputs.iter().flatten().find_map(|v| match v {
                    Value::Report(r) => Some((id.as_str(), r.as_ref())),
                    _ => None,
                })
            })
            .collect()
    }

    /// How many nodes ended with `status`.
    pub fn count(&self, status: NodeStatus) -> usize {
        self.nodes.values().filter(|n| n.status == status).count()
    }
}
