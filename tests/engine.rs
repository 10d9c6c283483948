//! The evaluator through its library API: caching and incremental re-runs, failure
//! isolation, cancellation, parallel branches, deterministic files and migrations.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use kinegraph::document::{self, EdgeDoc, GraphDoc, NodeDoc, SourceMap};
use kinegraph::engine::{Engine, MEMORY_KEEP_RUNS, NodeStatus, RunOptions, compile};
use kinegraph::graph::Graph;
use kinegraph_nodes::node::{
    FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, ParamValue, Registry, Value,
};

fn node(kind: &str, params: &[(&str, ParamValue)]) -> NodeDoc {
    NodeDoc {
        kind: kind.into(),
        params: params.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
        bypass: false,
    }
}

fn edge(from: &str, to: &str) -> EdgeDoc {
    EdgeDoc { from: from.into(), to: to.into() }
}

/// c → a1 → a2 → a3, and c → b1 (a second branch).
fn chain_doc(offset_a2: f64) -> GraphDoc {
    let mut doc = GraphDoc::new();
    doc.nodes.insert("c".into(), node("scalar.constant", &[("value", ParamValue::Float(1.0))]));
    doc.nodes.insert("a1".into(), node("scalar.add", &[("offset", ParamValue::Float(1.0))]));
    doc.nodes.insert("a2".into(), node("scalar.add", &[("offset", ParamValue::Float(offset_a2))]));
    doc.nodes.insert("a3".into(), node("scalar.add", &[("offset", ParamValue::Float(1.0))]));
    doc.nodes.insert("b1".into(), node("scalar.add", &[("offset", ParamValue::Float(10.0))]));
    doc.edges = vec![edge("c.value", "a1.a"), edge("a1.sum", "a2.a"), edge("a2.sum", "a3.a"), edge("c.value", "b1.a")];
    doc
}

fn scalar(report: &kinegraph::engine::RunReport, id: &str) -> f64 {
    match report.outputs[id][0] {
        Some(Value::Scalar(x)) => x,
        ref other => panic!("{id}: {other:?}"),
    }
}

#[test]
fn rerun_after_one_param_change_recomputes_only_its_downstream() {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let options = RunOptions::new(PathBuf::from("."));
    let doc = chain_doc(1.0);
    let g =
        compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("chain"), &SourceMap::default()).unwrap();
    let first = engine.run(&g, &options);
    assert_eq!(first.count(NodeStatus::Ok), 5);
    assert_eq!(scalar(&first, "a3"), 4.0); // 1 + 1 + 1 + 1
    assert_eq!(scalar(&first, "b1"), 11.0);

    let changed = chain_doc(5.0);
    let g = compile(&Graph::from_doc(&changed).unwrap(), engine.registry(), Path::new("chain"), &SourceMap::default())
        .unwrap();
    let second = engine.run(&g, &options);
    let ran: Vec<&str> =
        second.nodes.iter().filter(|(_, n)| n.status == NodeStatus::Ok).map(|(id, _)| id.as_str()).collect();
    assert_eq!(ran, vec!["a2", "a3"]);
    // a1 and b1 come from the cache; c, read only by them, is not even visited.
    let cached: Vec<&str> =
        second.nodes.iter().filter(|(_, n)| n.status == NodeStatus::Cached).map(|(id, _)| id.as_str()).collect();
    assert_eq!(cached, vec!["a1", "b1"]);
    assert!(!second.nodes.contains_key("c"));
    assert_eq!(scalar(&second, "a3"), 8.0);
}

#[test]
fn the_in_memory_cache_keeps_only_recent_runs_and_undo_within_them_is_free() {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let options = RunOptions::new(PathBuf::from("."));
    let run = |offset: f64| {
        let doc = chain_doc(offset);
        let g = compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("chain"), &SourceMap::default())
            .unwrap();
        engine.run(&g, &options)
    };
    // An artist drags a slider through 100 values: each run makes 2 new results (a2, a3).
    for step in 0..100 {
        run(f64::from(step));
    }
    // a1 and b1 (served every run; c, read only by them, is no longer visited and ages
    // out) plus 2 per kept run, not 2 per run ever made.
    assert_eq!(engine.cached_results(), 2 + 2 * MEMORY_KEEP_RUNS as usize);
    // Undo a few steps: still served from memory.
    let undo = run(97.0);
    assert_eq!(undo.count(NodeStatus::Ok), 0);
    assert_eq!(scalar(&undo, "a3"), 1.0 + 1.0 + 97.0 + 1.0);
    // A value from long ago was evicted and is computed again, correctly.
    let old = run(3.0);
    assert_eq!(old.count(NodeStatus::Ok), 2);
    assert_eq!(scalar(&old, "a3"), 6.0);
}

/// A node that fails on demand, counts its runs and can cancel the run it is in.
struct Probe {
    runs: Arc<AtomicUsize>,
    cancel: Option<Arc<AtomicBool>>,
}

const PROBE_IN: Input<f64> = Input::optional("x", "");
const PROBE_OUT: Output<f64> = Output::new("y", "");
const FAIL_IF: FloatParam = FloatParam::new("fail_if", "", -1.0, -1e9, 1e9, "");
static PROBE: NodeSchema = NodeSchema {
    kind: "test.probe",
    category: "test",
    doc: "Test node.",
    inputs: &[PROBE_IN.spec()],
    outputs: &[PROBE_OUT.spec()],
    params: &[FAIL_IF.0],
    writes_files: false,
    version: 1,
};

impl Node for Probe {
    fn schema(&self) -> &'static NodeSchema {
        &PROBE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        self.runs.fetch_add(1, Ordering::SeqCst);
        let x = ctx.optional_input(&PROBE_IN)?.unwrap_or(0.0);
        if x == ctx.float(&FAIL_IF)? {
            return Err(NodeError::Failed(format!("refusing {x}")));
        }
        if let Some(c) = &self.cancel {
            c.store(true, Ordering::SeqCst);
        }
        ctx.set_output(&PROBE_OUT, x + 1.0);
        Ok(())
    }
}

#[test]
fn a_failure_blocks_its_downstream_while_other_branches_finish() {
    let runs = Arc::new(AtomicUsize::new(0));
    let mut registry = kinegraph_nodes::builtin::registry();
    registry.add(Box::new(Probe { runs: runs.clone(), cancel: None }));
    let engine = Engine::new(registry);
    let mut doc = GraphDoc::new();
    doc.nodes.insert("bad".into(), node("test.probe", &[("fail_if", ParamValue::Float(0.0))]));
    doc.nodes.insert("after_bad".into(), node("test.probe", &[]));
    doc.nodes.insert("good".into(), node("test.probe", &[]));
    doc.nodes.insert("after_good".into(), node("test.probe", &[]));
    doc.edges = vec![edge("bad.y", "after_bad.x"), edge("good.y", "after_good.x")];
    let g = compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("g"), &SourceMap::default()).unwrap();
    let report = engine.run(&g, &RunOptions::new(PathBuf::from(".")));
    assert_eq!(report.nodes["bad"].status, NodeStatus::Error);
    assert!(report.nodes["bad"].error.as_deref().unwrap().contains("refusing 0"));
    assert_eq!(report.nodes["after_bad"].status, NodeStatus::Blocked);
    assert_eq!(report.nodes["after_good"].status, NodeStatus::Ok);
    assert_eq!(scalar(&report, "after_good"), 2.0);
    assert_eq!(runs.load(Ordering::SeqCst), 3);
    assert!(!report.succeeded());
}

#[test]
fn cancelling_stops_the_run_and_leaves_no_export() {
    let cancel = Arc::new(AtomicBool::new(false));
    let mut registry = kinegraph_nodes::builtin::registry();
    registry.add(Box::new(Probe { runs: Arc::new(AtomicUsize::new(0)), cancel: Some(cancel.clone()) }));
    let engine = Engine::new(registry);
    // mannequin → export, with the probe (which cancels the run) on the way.
    let mut doc = GraphDoc::new();
    doc.nodes.insert("probe".into(), node("test.probe", &[]));
    doc.nodes.insert("m".into(), node("generate.mannequin", &[]));
    doc.nodes.insert("gate".into(), node("scalar.add", &[]));
    doc.nodes.insert("out".into(), node("export.bvh", &[]));
    doc.edges = vec![edge("probe.y", "gate.a"), edge("m.clip", "out.clip")];
    let g = compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("g"), &SourceMap::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut options = RunOptions::new(PathBuf::from("."));
    options.out_dir = Some(dir.path().to_path_buf());
    options.cancel = cancel.clone();
    options.threads = Some(1);
    options.targets = Some(vec!["gate".into()]);
    // First the probe alone: it cancels; then everything later in the same run stops.
    let report = engine.run(&g, &options);
    assert_eq!(report.nodes["probe"].status, NodeStatus::Ok);
    assert_eq!(report.nodes["gate"].status, NodeStatus::Cancelled);
    // A cancelled flag stops exports before they write anything.
    options.targets = None;
    let report = engine.run(&g, &options);
    assert_eq!(report.nodes["out"].status, NodeStatus::Cancelled);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    assert!(report.files_written.is_empty());
}

#[test]
fn independent_branches_run_in_parallel() {
    /// Sleeps, so overlap shows in wall time even on a loaded machine.
    struct Sleepy;
    const OUT: Output<f64> = Output::new("y", "");
    static SLEEPY: NodeSchema = NodeSchema {
        kind: "test.sleepy",
        category: "test",
        doc: "Sleeps 150 ms.",
        inputs: &[],
        outputs: &[OUT.spec()],
        params: &[],
        writes_files: false,
        version: 1,
    };
    impl Node for Sleepy {
        fn schema(&self) -> &'static NodeSchema {
            &SLEEPY
        }
        fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
            std::thread::sleep(std::time::Duration::from_millis(150));
            ctx.set_output(&OUT, 1.0);
            Ok(())
        }
    }
    let mut registry = Registry::empty();
    registry.add(Box::new(Sleepy));
    let engine = Engine::new(registry);
    let mut doc = GraphDoc::new();
    doc.nodes.insert("a".into(), node("test.sleepy", &[]));
    doc.nodes.insert("b".into(), node("test.sleepy", &[]));
    let g = compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("g"), &SourceMap::default()).unwrap();
    let mut options = RunOptions::new(PathBuf::from("."));
    options.threads = Some(2);
    let report = engine.run(&g, &options);
    // Each node slept 150 ms; serially that is ≥ 300 ms. Both ran, and their node times
    // add up to more than the run took: they overlapped.
    let node_secs: f64 = report.nodes.values().map(|n| n.seconds).sum();
    assert!(node_secs >= 0.3);
    assert!(report.seconds < node_secs, "run {} s vs nodes {} s", report.seconds, node_secs);
}

#[test]
fn saving_is_deterministic_and_round_trips() {
    let loaded = document::load_file(Path::new("graphs/demo.ron")).unwrap();
    let once = document::to_string(&loaded.doc);
    let again = document::to_string(&document::parse(&once, Path::new("x.ron")).unwrap().doc);
    assert_eq!(once, again);
    // The shipped graph is itself in saved form.
    assert_eq!(once, std::fs::read_to_string("graphs/demo.ron").unwrap());
    // Edge order in memory does not change the file.
    let mut shuffled = loaded.doc.clone();
    shuffled.edges.reverse();
    assert_eq!(document::to_string(&shuffled), once);
}

#[test]
fn version_1_fixture_migrates_and_runs() {
    let path = Path::new("graphs/legacy/v1/load_export.ron");
    let loaded = document::load_file(path).unwrap();
    assert_eq!(loaded.file_version, 1);
    assert_eq!(loaded.doc.version, document::CURRENT_VERSION);
    let load = &loaded.doc.nodes["load"];
    assert_eq!(load.params.get("metres_per_unit"), Some(&ParamValue::Float(1.0)));
    assert!(!load.params.contains_key("scale"));
    assert_eq!(loaded.doc.edges, vec![edge("load.clip", "trim.clip"), edge("trim.clip", "export.clip")]);
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let g = compile(&Graph::from_doc(&loaded.doc).unwrap(), engine.registry(), path, &loaded.source).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut options = RunOptions::new(loaded.base_dir());
    options.out_dir = Some(dir.path().to_path_buf());
    let report = engine.run(&g, &options);
    assert!(report.succeeded(), "{:?}", report.nodes);
    assert!(dir.path().join("legacy.bvh").is_file());
}

#[test]
fn node_catalogue_snapshot() {
    let registry = kinegraph_nodes::builtin::registry();
    let schemas: Vec<_> = registry.iter().map(|n| n.schema()).collect();
    insta::assert_json_snapshot!("node_catalogue", schemas);
}

/// `motion.segment_phases` gives the curve it cut the phases from: the momentum along its
/// main-phase direction is |L| at the main-phase moment, and its sign agrees with every
/// phase (the sign test of Shum et al. read back from the other output).
#[test]
fn phase_curves_agree_with_the_phases() {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut doc = GraphDoc::new();
    let walk = root.join("assets/mannequin_walk.bvh").display().to_string();
    doc.nodes.insert("clip".into(), node("clip.load", &[("path", ParamValue::Text(walk))]));
    doc.nodes.insert("phases".into(), node("motion.segment_phases", &[]));
    doc.edges = vec![edge("clip.clip", "phases.clip")];
    let g = compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("phases"), &SourceMap::default())
        .unwrap();
    let report = engine.run(&g, &RunOptions::new(root.to_path_buf()));
    let outputs = &report.outputs["phases"];
    let (Some(Value::Phases(phases)), Some(Value::Curves(curves))) = (&outputs[0], &outputs[1]) else {
        panic!("{outputs:?}");
    };
    let channel = |name: &str| curves.channels().iter().find(|c| c.name == name).unwrap().values.clone();
    let (magnitude, along) = (channel("|L| smoothed"), channel("L along main"));
    assert_eq!(along.len(), magnitude.len());
    let m = phases.main_frame;
    assert!((along[m] - magnitude[m]).abs() < 1e-9 && magnitude[m] > 0.0);
    for (f, a) in along.iter().enumerate().take(phases.main.end).skip(phases.main.start) {
        assert!(*a >= 0.0, "main frame {f}: {a}");
    }
    for range in [phases.preparatory, phases.posterior].into_iter().flatten() {
        for (f, a) in along.iter().enumerate().take(range.end).skip(range.start) {
            assert!(*a < 0.0, "frame {f} of {range:?}: {a}");
        }
    }
    assert!(along.iter().zip(&magnitude).all(|(a, m)| a.abs() <= m + 1e-9), "a projection never exceeds the length");
}

/// `chain_doc` with `ids` bypassed, compiled.
fn bypassed_chain(engine: &Engine, offset_a2: f64, ids: &[&str]) -> Result<Graph, kinegraph::engine::GraphErrors> {
    let mut doc = chain_doc(offset_a2);
    for id in ids {
        doc.nodes.get_mut(*id).unwrap().bypass = true;
    }
    let graph = Graph::from_doc(&doc).unwrap();
    compile(&graph, engine.registry(), Path::new("chain"), &SourceMap::default()).map(|_| graph)
}

#[test]
fn a_bypassed_node_passes_its_input_on_and_runs_again_when_let_go() {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let options = RunOptions::new(PathBuf::from("."));
    let run = |graph: &Graph| {
        let g = compile(graph, engine.registry(), Path::new("chain"), &SourceMap::default()).unwrap();
        engine.run(&g, &options)
    };
    // c = 1, a1 = c + 1, a2 = a1 + 5 (bypassed: a2 gives a1's 2), a3 = a2 + 1.
    let bypassed = run(&bypassed_chain(&engine, 5.0, &["a2"]).unwrap());
    assert_eq!(bypassed.nodes["a2"].status, NodeStatus::Bypassed);
    assert_eq!(scalar(&bypassed, "a2"), 2.0);
    assert_eq!(scalar(&bypassed, "a3"), 3.0);
    assert!(bypassed.succeeded());
    // Let go, a2 adds its 5 again and a3 is recomputed, not taken from the bypassed run.
    let running = run(&bypassed_chain(&engine, 5.0, &[]).unwrap());
    assert_eq!(running.nodes["a2"].status, NodeStatus::Ok);
    assert_eq!(running.nodes["a3"].status, NodeStatus::Ok);
    assert_eq!(scalar(&running, "a3"), 8.0);
    // And bypassed once more: a3 comes back as the bypassed graph gave it.
    let again = run(&bypassed_chain(&engine, 5.0, &["a2"]).unwrap());
    assert_eq!(again.nodes["a3"].status, NodeStatus::Cached);
    assert_eq!(scalar(&again, "a3"), 3.0);
}

#[test]
fn a_bypassed_node_with_nothing_of_the_type_to_pass_is_an_error_at_each_reader() {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    // The constant has no input at all: both nodes reading it get nothing.
    let errors = bypassed_chain(&engine, 1.0, &["c"]).unwrap_err();
    let readers: Vec<(Option<&str>, Option<&str>)> =
        errors.diagnostics.iter().map(|d| (d.node.as_deref(), d.item.as_deref())).collect();
    assert_eq!(readers, vec![(Some("a1"), Some("a")), (Some("b1"), Some("a"))]);
    assert_eq!(
        errors.diagnostics[0].message,
        "c.value passes nothing while 'c' is bypassed (it has no connected scalar input), so a1.a gets no value"
    );
}

#[test]
fn bypass_is_saved_as_version_3_and_read_back() {
    let mut doc = chain_doc(1.0);
    doc.nodes.get_mut("a2").unwrap().bypass = true;
    let text = document::to_string(&doc);
    assert!(text.contains("version: 3"), "{text}");
    assert_eq!(text.matches("bypass: true").count(), 1, "{text}");
    let back = document::parse(&text, Path::new("x.ron")).unwrap().doc;
    assert_eq!(Graph::from_doc(&back).unwrap(), Graph::from_doc(&doc).unwrap());
    // Let go, the file is what it was before bypass existed.
    doc.nodes.get_mut("a2").unwrap().bypass = false;
    let text = document::to_string(&doc);
    assert!(text.contains("version: 2") && !text.contains("bypass"), "{text}");
}

#[test]
fn a_bypassed_export_writes_nothing() {
    let engine = Engine::new(kinegraph_nodes::builtin::registry());
    let mut doc = GraphDoc::new();
    doc.nodes.insert("m".into(), node("generate.mannequin", &[]));
    doc.nodes.insert("out".into(), node("export.bvh", &[]));
    doc.nodes.get_mut("out").unwrap().bypass = true;
    doc.edges = vec![edge("m.clip", "out.clip")];
    let g = compile(&Graph::from_doc(&doc).unwrap(), engine.registry(), Path::new("g"), &SourceMap::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut options = RunOptions::new(PathBuf::from("."));
    options.out_dir = Some(dir.path().to_path_buf());
    let report = engine.run(&g, &options);
    assert_eq!(report.nodes["out"].status, NodeStatus::Bypassed);
    assert!(report.files_written.is_empty());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}
