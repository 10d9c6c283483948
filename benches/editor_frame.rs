//! UI frame time of the editor on a 500-node graph (issue goal: < 16 ms per frame), measured
//! headless through egui_kittest: layout, canvas, panel and painting into egui's shapes,
//! without GPU rasterisation; and the wall time from an edit of `walk_punch_kick` to its
//! evaluated result (goal < 0.5 s; needs the shared corpus). Run: `cargo bench --bench
//! editor_frame`.

#![allow(missing_docs, clippy::unwrap_used, clippy::expect_used)]

use std::fmt::Write as _;

use criterion::{Criterion, criterion_group, criterion_main};
use egui_kittest::Harness;
use kinegraph::editor::EditorApp;

/// A graph of `n` nodes: constants feeding a chain of adders, laid out on a grid.
fn big_graph(n: usize) -> String {
    let mut nodes = String::new();
    let mut edges = String::new();
    let mut layout = String::new();
    for i in 0..n {
        let (kind, params) = if i % 2 == 0 {
            ("scalar.constant", format!("{{\"value\": {i}.0}}"))
        } else {
            ("scalar.add", "{\"offset\": 1.0}".to_string())
        };
        writeln!(nodes, "\"n{i}\": (kind: \"{kind}\", params: {params}),").unwrap();
        if i % 2 == 1 {
            writeln!(edges, "(from: \"n{}.value\", to: \"n{i}.a\"),", i - 1).unwrap();
            if i >= 3 {
                writeln!(edges, "(from: \"n{}.sum\", to: \"n{i}.b\"),", i - 2).unwrap();
            }
        }
        writeln!(layout, "\"n{i}\": ({}.0, {}.0),", (i % 25) * 220, (i / 25) * 140).unwrap();
    }
    format!(
        "(format: \"kinegraph.graph\", version: 2, nodes: {{ {nodes} }}, edges: [ {edges} ], layout: {{ {layout} }})"
    )
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.ron");
    std::fs::write(&path, big_graph(500)).unwrap();
    // Its own settings folder: no recent files or autosaves of the machine's user.
    let mut app = EditorApp::with_settings_dir(&egui::Context::default(), Some(&path), dir.path().join("settings"));
    app.wait_for_evaluation();
    assert_eq!(app.doc().nodes.len(), 500);
    let mut harness =
        Harness::builder().with_size([1600.0, 1000.0]).build_ui_state(|ui, app: &mut EditorApp| app.ui(ui), app);
    harness.run_steps(4);
    c.bench_function("editor/frame_500_nodes_as_opened", |b| b.iter(|| harness.step()));
    harness.state_mut().select(Some("n251"));
    harness.run_steps(2);
    c.bench_function("editor/frame_500_nodes_with_panel", |b| b.iter(|| harness.step()));
    edit_to_result(c);
}

/// An edit of the motion.sequence seed of `graphs/walk_punch_kick.ron` until its result is
/// in: validation, the worker's hand-over and the nodes downstream of the edit (upstream ones
/// come from the cache). A new seed each time, so the sequence never comes from the cache.
fn edit_to_result(c: &mut Criterion) {
    if kinegraph::nodes::corpus::shared_data().is_none() {
        eprintln!("skipping editor/edit_walk_punch_kick: no shared corpus (KG_SHARED_DATA)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let graph = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/walk_punch_kick.ron");
    let mut app = EditorApp::with_settings_dir(&egui::Context::default(), Some(&graph), dir.path().join("settings"));
    app.wait_for_evaluation();
    let seed = kinegraph::graph::ParamPath::parse("sequence.seed").unwrap();
    let mut next = 1000_i64;
    c.bench_function("editor/edit_walk_punch_kick_to_result", |b| {
        b.iter(|| {
            next += 1;
            let value = kinegraph::nodes::node::ParamValue::Int(next);
            app.edit(kinegraph::editor::commands::EditorCommand::SetParam { param: seed.clone(), value }).unwrap();
            app.wait_for_evaluation();
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
