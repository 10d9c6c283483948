//! Fuzz target `graph_loader`: graph text into `document::parse` and `engine::compile`.
//!
//! Each input is used twice:
//! 1. **raw**: when the bytes are UTF-8 they are parsed as a graph file as they are;
//! 2. **structured**: the first byte picks one of the valid seed graphs (the files in
//!    `fuzz/seeds/graph_loader/`, compiled in), and the rest is read as an edit script of
//!    4-byte records `(op, pos_lo, pos_hi, arg)` applied to that text: overwrite a byte,
//!    insert a byte, delete up to 16 bytes, or insert a token from [`TOKENS`] (graph
//!    syntax, node kinds, port names, extreme numbers). Non-UTF-8 results are converted
//!    lossily, so the edits stay mostly near-valid graphs that reach compile.
//!
//! Parsing and compiling must never panic. A compiled graph's order must list every node
//! once, after the nodes it reads. Graphs made only of `scalar.*` nodes (pure arithmetic,
//! no file access) are also run twice on one engine: the first run reports every node, the
//! re-run every sink (it stops at cached results), and after a fully successful run the
//! re-run reports only results taken from the cache.
//! Nodes that touch files are never run.

#![no_main]

use std::path::{Path, PathBuf};

use kinegraph::engine::{Engine, NodeStatus, RunOptions, compile};
use kinegraph::graph::Graph;
use libfuzzer_sys::fuzz_target;

/// The valid graphs the structured mode edits.
const BASES: [&str; 3] = [
    include_str!("../seeds/graph_loader/scalar_sums.ron"),
    include_str!("../seeds/graph_loader/doc_example.ron"),
    include_str!("../seeds/graph_loader/v1_clip_chain.ron"),
];

/// Fragments the structured mode splices in.
const TOKENS: &[&str] = &[
    "\"scalar.add\"",
    "\"scalar.constant\"",
    "\"clip.load\"",
    "\"clip.trim\"",
    "\"export.glb\"",
    "\"sum.sum\"",
    "\"sum.a\"",
    "\"sum.b\"",
    "\"total.b\"",
    "\"one.value\"",
    "\"two.value\"",
    "(from: \"one.value\", to: \"total.b\"),",
    "(from: \"total.sum\", to: \"sum.b\"),",
    "\"x\": (kind: \"scalar.add\"),",
    "\"offset\": ",
    "\"value\": ",
    "\"\"",
    "\".\"",
    "\"a.b.c\"",
    "\"é\"",
    "1e308",
    "-1e308",
    "1e309",
    "NaN",
    "inf",
    "-0.0",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "true",
    "version: 1",
    "version: 3",
    "version: 4294967296",
    "format: \"kinegraph.graph\",",
    "nodes: {},",
    "edges: [],",
    "(",
    ")",
    "{",
    "}",
    "[",
    "]",
    ",",
    ":",
    "\"",
    "//",
    "/*",
    "*/",
    "\\",
    "\n",
];

/// Applies the edit script `script` to `base`.
fn mutate(base: &str, script: &[u8]) -> Vec<u8> {
    let mut text = base.as_bytes().to_vec();
    for op in script.chunks_exact(4) {
        let pos = usize::from(u16::from_le_bytes([op[1], op[2]])) % (text.len() + 1);
        let arg = op[3];
        match op[0] % 4 {
            0 => {
                if let Some(b) = text.get_mut(pos) {
                    *b = arg;
                }
            }
            1 => text.insert(pos, arg),
            2 => {
                let end = (pos + 1 + usize::from(arg % 16)).min(text.len());
                text.drain(pos..end);
            }
            _ => {
                let token = TOKENS[usize::from(arg) % TOKENS.len()].as_bytes();
                text.splice(pos..pos, token.iter().copied());
            }
        }
    }
    text
}

/// Parses, compiles and, for pure scalar graphs, runs `text`.
fn exercise(text: &str) {
    let path = Path::new("/nonexistent-kinegraph-fuzz/graph.ron");
    let Ok(loaded) = kinegraph::document::parse(text, path) else {
        return;
    };
    let Ok(graph) = Graph::from_doc(&loaded.doc) else {
        return;
    };
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let Ok(compiled) = compile(&graph, engine.registry(), path, &loaded.source) else {
        return;
    };

    // The order is a permutation in which every node follows its inputs.
    let n = compiled.nodes.len();
    assert_eq!(compiled.order.len(), n, "order does not list every node once");
    let mut position = vec![usize::MAX; n];
    for (at, &i) in compiled.order.iter().enumerate() {
        assert!(i < n && position[i] == usize::MAX, "order repeats or overflows at {at}");
        position[i] = at;
    }
    for (i, node) in compiled.nodes.iter().enumerate() {
        for &(src, _) in node.inputs.iter().flatten() {
            assert!(position[src] < position[i], "node '{}' is ordered before its input", node.id);
        }
    }

    if compiled.nodes.is_empty() || !compiled.nodes.iter().all(|n| n.node.schema().kind.starts_with("scalar.")) {
        return;
    }
    let options = RunOptions::new(PathBuf::from("/nonexistent-kinegraph-fuzz"));
    let first = engine.run(&compiled, &options);
    assert_eq!(first.nodes.len(), n, "a needed node has no report");
    // The re-run walks back from the sinks and stops at cached results (what only they
    // read is not visited), so it reports every sink; after a clean first run, all from
    // the cache and nothing run again.
    let second = engine.run(&compiled, &options);
    for node in compiled.nodes.iter().filter(|node| node.dependents.is_empty()) {
        assert!(second.nodes.contains_key(node.id.as_str()), "sink '{}' has no report on the re-run", node.id);
    }
    if first.succeeded() {
        assert!(
            second.nodes.values().all(|r| r.status == NodeStatus::Cached),
            "an unchanged successful graph was not taken from the cache"
        );
    }
}

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        exercise(text);
    }
    if let Some((&pick, script)) = data.split_first() {
        let mutated = mutate(BASES[usize::from(pick) % BASES.len()], script);
        exercise(&String::from_utf8_lossy(&mutated));
    }
});
