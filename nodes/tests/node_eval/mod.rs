//! One built-in node evaluated outside a graph, as the evaluator runs it: shared by the
//! tests that check what a node says about bad input (`fluid_sim`, `gltf_export`,
//! `physics_sit`).

#![allow(dead_code, clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::AtomicBool;

use kinegraph_nodes::node::{NodeContext, NodeError, NodeOutcome, ParamValue, RunServices, Value};

/// Evaluates the built-in node `kind` once: `inputs` in the schema's order, `params` over
/// the schema's defaults, paths read from and files written to `dir`.
pub fn eval_node(
    kind: &str,
    inputs: Vec<Option<Value>>,
    params: &[(&str, ParamValue)],
    dir: &Path,
) -> Result<NodeOutcome, NodeError> {
    let registry = kinegraph_nodes::builtin::registry();
    let node = registry.get(kind).unwrap();
    let mut map: BTreeMap<String, ParamValue> =
        node.schema().params.iter().filter_map(|p| Some((p.name.to_string(), p.default_value()?))).collect();
    map.extend(params.iter().map(|(k, v)| (k.to_string(), v.clone())));
    let cancel = AtomicBool::new(false);
    let services = RunServices { base_dir: dir, out_dir: Some(dir), cancel: &cancel, memory_limit_bytes: 1 << 32 };
    let progress = |_: f32| {};
    let mut ctx = NodeContext::new(node.schema(), inputs, &map, &services, &progress);
    node.eval(&mut ctx)?;
    Ok(ctx.finish())
}
