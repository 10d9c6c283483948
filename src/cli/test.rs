//! `kg test`: runs saved graphs as regression tests ([`crate::regression`]) and prints
//! one line per graph, the differences of those that fail, and a total.

use std::path::{Path, PathBuf};

use super::run::cancel_flag;
use super::{EXIT_FAILED, EXIT_INVALID};
use crate::engine::Engine;
use crate::regression::{GraphTest, graphs_in, summary, test_graph};

pub(super) fn test_command(graphs: Vec<PathBuf>, root: Option<&Path>, bless: bool) -> u8 {
    let explicit = !graphs.is_empty();
    let graphs: Vec<PathBuf> = if explicit {
        // A shell glob over a folder brings the expectation files too: they are not graphs.
        graphs.into_iter().filter(|g| !g.to_string_lossy().ends_with(".expect.ron")).collect()
    } else {
        let dir = root.unwrap_or(Path::new("graphs"));
        if !dir.is_dir() {
            errln!("kg test: {} is not a folder of graphs (give --root DIR or graph files)", dir.display());
            return EXIT_INVALID;
        }
        graphs_in(dir)
    };
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let cancel = cancel_flag();
    let (mut passed, mut failed, mut skipped) = (0, 0, 0);
    for graph in &graphs {
        match test_graph(&engine, graph, bless, &cancel) {
            GraphTest::Passed => {
                passed += 1;
                errln!("{} {}", if bless { "blessed" } else { "ok     " }, graph.display());
            }
            GraphTest::Skipped(why) => {
                skipped += 1;
                errln!("skipped {}: {why}", graph.display());
            }
            GraphTest::Failed(problems) => {
                failed += 1;
                errln!("FAILED  {}: {} difference(s)", graph.display(), problems.len());
                if problems.len() > 1 {
                    for line in summary(&problems) {
                        errln!("        {line}");
                    }
                    errln!("        detail:");
                }
                for p in problems {
                    errln!("        {p}");
                }
            }
        }
    }
    outln!("kg test: {passed} passed, {failed} failed, {skipped} skipped");
    if failed > 0 { EXIT_FAILED } else { 0 }
}
