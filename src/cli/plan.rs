//! `kg plan`: one task per input binding and sweep point, with content hashes, written as a plan file
//! (the planning itself is [`crate::farm::planner`]).

use std::path::Path;

use super::run::Setting;
use super::{EXIT_INVALID, save_file};
use crate::farm::planner::make_plan;
use crate::farm::sweep::Sweep;

pub(super) fn plan_command(
    graph: &Path,
    inputs: &[Setting],
    sweeps: &[Sweep],
    settings: &[Setting],
    upstream_out: &Path,
    out: &Path,
) -> u8 {
    let registry = kinegraph_nodes::builtin::registry();
    let plan = match make_plan(graph, inputs, sweeps, settings, upstream_out, out, &registry) {
        Ok(plan) => plan,
        Err(e) => {
            err!("{e}");
            if !e.ends_with('\n') {
                errln!("");
            }
            return EXIT_INVALID;
        }
    };
    if let Err(e) = save_file(out, plan.to_json().as_bytes()) {
        errln!("{e}");
        return EXIT_INVALID;
    }
    errln!("{}: {} tasks of {}", out.display(), plan.tasks.len(), graph.display());
    0
}
