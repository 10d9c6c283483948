//! `kg merge`: the per-task reports of a plan's run, collected into one summary.

use std::path::Path;

use super::{EXIT_FAILED, EXIT_INVALID, save_file};
use crate::farm::report::SUMMARY_FILE;
use crate::farm::{Plan, merge};
use crate::output::save_within;

/// Merges the reports under `out` for the plan at `plan_path`, saves the summary (default
/// `OUT/summary.json`) and prints it (as JSON with `json`). Exit 0 when every task is done,
/// 1 when any failed or has not run, 2 for a bad plan.
pub(super) fn merge_command(plan_path: &Path, out: &Path, summary_path: Option<&Path>, json: bool) -> u8 {
    let plan = match Plan::read(plan_path) {
        Ok(p) => p,
        Err(e) => {
            errln!("{e}");
            return EXIT_INVALID;
        }
    };
    let summary = merge(&plan, out);
    for w in &summary.warnings {
        errln!("warning: {w}");
    }
    let mut text = serde_json::to_string_pretty(&summary).unwrap_or_default();
    text.push('\n');
    let saved = match summary_path {
        Some(path) => save_file(path, text.as_bytes()).map(|()| path.to_path_buf()),
        None => save_within(out, Path::new(SUMMARY_FILE), text.as_bytes()),
    };
    let target = summary_path.map(Path::to_path_buf).unwrap_or_else(|| out.join(SUMMARY_FILE));
    if let Err(e) = saved {
        errln!("cannot save the summary: {e}");
        return EXIT_FAILED;
    }
    if json {
        out!("{text}");
    } else {
        errln!("{:<8} {:>8}  {:<5} task", "status", "seconds", "index");
        for t in &summary.per_task {
            let error = t.error.as_deref().map(|e| format!(" {e}")).unwrap_or_default();
            errln!("{:<8} {:>8.3}  {:<5} {}{error}", t.status, t.seconds, t.index, t.id);
        }
        let counts: Vec<String> = summary.counts.iter().map(|(k, v)| format!("{v} {k}")).collect();
        errln!(
            "{} tasks: {}; {:.2} s in all; summary in {}",
            summary.tasks,
            counts.join(", "),
            summary.total_seconds,
            target.display()
        );
    }
    if summary.all_done() { 0 } else { EXIT_FAILED }
}
