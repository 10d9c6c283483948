//! Quality gates of `kg test`: an expectation may hold `motion.quality` nodes to limits,
//! `quality: { "check": (max_skate_cm: 0.5, max_penetration_cm: 0.5) }`, so a run fails on
//! a regression in motion quality, not only on changed numbers. The limits and the
//! measures they read are the kernel's ([`kinegraph_nodes::kernels::quality`]).

use std::collections::BTreeMap;

use kinegraph_nodes::kernels::quality::{QualityGate, QualitySummary};

use crate::engine::RunReport;

/// The node kind a gate names.
const QUALITY_KIND: &str = "motion.quality";

/// One line per broken limit of `gates` (by node id) in `run`, naming the node and the
/// measure; a gate on a node that is not a `motion.quality` node of the run breaks too.
pub fn gate_violations(gates: &BTreeMap<String, QualityGate>, run: &RunReport) -> Vec<String> {
    let reports = run.reports();
    let mut lines = Vec::new();
    for (node, gate) in gates {
        let kind = run.nodes.get(node).map(|n| n.kind.as_str());
        let report = match (kind, reports.get(node.as_str())) {
            (Some(QUALITY_KIND), Some(report)) => report,
            (Some(QUALITY_KIND), None) | (None, _) => {
                lines.push(format!("quality gate '{node}': the run has no {QUALITY_KIND} node '{node}' with a report"));
                continue;
            }
            (Some(other), _) => {
                lines.push(format!("quality gate '{node}': the node is a {other}, not a {QUALITY_KIND}"));
                continue;
            }
        };
        match serde_json::from_value::<QualitySummary>(serde_json::Value::Object((*report).clone())) {
            Ok(summary) => {
                lines.extend(gate.violations(&summary).into_iter().map(|v| format!("quality gate '{node}': {v}")))
            }
            Err(e) => lines.push(format!("quality gate '{node}': its report cannot be read ({e})")),
        }
    }
    lines
}
