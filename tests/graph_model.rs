//! The typed graph model as `kg` and the editor both meet it: one id rule, one set of
//! refusals with the same words, settings resolved once, and positions read from the
//! file's structure.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use kinegraph::editor::commands::{EditError, EditorCommand, apply};
use kinegraph::graph::{Graph, GraphFile, NodeId, PortRef};

fn kg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kg")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn assets() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets")
}

/// The 1-based line of the first line of `text` containing `needle`, found by a plain scan.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).expect("needle in text") + 1
}

#[test]
fn a_dotted_node_id_runs_and_takes_settings() {
    let dir = tempfile::tempdir().unwrap();
    let walk = assets().join("mannequin_walk.bvh");
    let graph = write(
        dir.path(),
        "dotted.ron",
        &format!(
            r#"(format: "kinegraph.graph", version: 2,
 nodes: {{
   "walk.load": (kind: "clip.load", params: {{ "path": "{}" }}),
   "walk.trim": (kind: "clip.trim", params: {{ "end_secs": 1.0 }}),
   "out.bvh": (kind: "export.bvh", params: {{ "file": "w.bvh" }}),
 }},
 edges: [ (from: "walk.load.clip", to: "walk.trim.clip"), (from: "walk.trim.clip", to: "out.bvh.clip") ])"#,
            walk.display()
        ),
    );
    let check = kg(&["check", graph.to_str().unwrap()]);
    assert_eq!(check.status.code(), Some(0), "{}", stderr(&check));
    let out = dir.path().join("out");
    let run = kg(&[
        "run",
        graph.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--set",
        "walk.trim.end_secs=0.5",
        "--json",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["nodes"]["walk.trim"]["status"], "ok");
    // The setting reached the dotted node: half a second of the clip, whatever its rate.
    let bvh = std::fs::read_to_string(out.join("w.bvh")).unwrap();
    let frames: f64 = bvh.lines().find_map(|l| l.strip_prefix("Frames:")).unwrap().trim().parse().unwrap();
    let frame_time: f64 = bvh.lines().find_map(|l| l.strip_prefix("Frame Time:")).unwrap().trim().parse().unwrap();
    assert!(((frames - 1.0) * frame_time - 0.5).abs() <= frame_time, "{frames} frames of {frame_time} s");
}

#[test]
fn a_description_that_mentions_nodes_moves_no_location() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"(format: "kinegraph.graph", version: 2,
 description: "the nodes: { \"trim\": (kind: ...) } of this graph",
 nodes: {
   // "trim": a comment that names the node
   "clip": (kind: "clip.load", params: { "path": "x.bvh" }),
   "trim": (kind: "clip.trim", params: {
       "start_secs": 0.0,
       "end_secs": "soon" }),
 },
 edges: [ (from: "clip.clip", to: "trim.clip") ])"#;
    let graph = write(dir.path(), "described.ron", text);
    let out = kg(&["check", graph.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    let expected = format!("{}:{}:", graph.display(), line_of(text, "\"end_secs\": \"soon\""));
    assert!(err.contains(&expected), "expected {expected} in {err}");
    assert!(err.contains("node 'trim', 'end_secs'"), "{err}");
}

/// The refusal `kg check` prints for a file and the one the editor gives for the same
/// edit carry the same words.
#[test]
fn kg_check_and_the_editor_refuse_with_the_same_words() {
    let registry = kinegraph_nodes::builtin::registry();
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&str, &str, EditorCommand); 3] = [
        (
            "mismatch.ron",
            r#"(format: "kinegraph.graph", version: 2,
 nodes: { "mesh": (kind: "mesh.load", params: { "path": "x.obj" }), "trim": (kind: "clip.trim") },
 edges: [ (from: "mesh.mesh", to: "trim.clip") ])"#,
            EditorCommand::Connect {
                from: PortRef::parse("mesh.mesh").unwrap(),
                to: PortRef::parse("trim.clip").unwrap(),
            },
        ),
        (
            "bad_id.ron",
            r#"(format: "kinegraph.graph", version: 2, nodes: { "a b": (kind: "scalar.constant") })"#,
            EditorCommand::AddNode { id: NodeId::from("a b"), kind: "scalar.constant".into(), pos: (0.0, 0.0) },
        ),
        (
            "no_port.ron",
            r#"(format: "kinegraph.graph", version: 2,
 nodes: { "c": (kind: "scalar.constant"), "t": (kind: "clip.trim") },
 edges: [ (from: "c.valu", to: "t.clip") ])"#,
            EditorCommand::Connect { from: PortRef::parse("c.valu").unwrap(), to: PortRef::parse("t.clip").unwrap() },
        ),
    ];
    for (name, text, command) in cases {
        let path = write(dir.path(), name, text);
        let out = kg(&["check", path.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{name}");
        // The editor starts from the same file without the offending part, then tries it.
        let mut graph = GraphFile::load(&path).unwrap().graph;
        let before = graph.to_doc();
        let mut stripped = before.clone();
        stripped.edges.clear();
        if matches!(command, EditorCommand::AddNode { .. }) {
            stripped.nodes.clear();
        }
        graph = Graph::from_doc(&stripped).unwrap();
        let refusal = match apply(&mut graph, &registry, &command) {
            Err(e @ EditError::Graph(_)) => e.to_string(),
            other => panic!("{name}: the editor accepted what kg check refuses: {other:?}"),
        };
        assert!(stderr(&out).contains(&refusal), "{name}: editor says '{refusal}', kg check says {}", stderr(&out));
    }
}

#[test]
fn files_never_lose_data_silently() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "duplicate_param.ron",
            "(format: \"kinegraph.graph\", version: 2,\n nodes: { \"t\": (kind: \"clip.trim\", params: {\n \"end_secs\": 1.0,\n \"end_secs\": 2.0 }) })",
            "duplicate parameter 'end_secs'",
        ),
        (
            "duplicate_input.ron",
            "(format: \"kinegraph.graph\", version: 2,\n inputs: { \"a\": \"t.end_secs\",\n \"a\": \"t.start_secs\" },\n nodes: { \"t\": (kind: \"clip.trim\") })",
            "duplicate graph input 'a'",
        ),
        (
            "shadowing_input.ron",
            "(format: \"kinegraph.graph\", version: 2,\n inputs: { \"t.start_secs\": \"t.end_secs\" },\n nodes: { \"t\": (kind: \"clip.trim\") })",
            "graph input 't.start_secs' is spelt like the parameter path",
        ),
        (
            "v1_twice.ron",
            "(format: \"kinegraph.graph\", version: 1,\n nodes: [ (id: \"a\", kind: \"clip.trim\"), (id: \"a\", kind: \"clip.resample\") ])",
            "two nodes have the id 'a'",
        ),
        (
            "v1_scale.ron",
            "(format: \"kinegraph.graph\", version: 1,\n nodes: [ (id: \"l\", kind: \"clip.load\", params: { \"scale\": 0.01, \"metres_per_unit\": 1.0 }) ])",
            "sets both 'scale'",
        ),
        (
            "map_param.ron",
            "(format: \"kinegraph.graph\", version: 2,\n nodes: { \"t\": (kind: \"clip.trim\", params: { \"end_secs\": { \"x\": 1 } }) })",
            "a parameter value must be a number, true/false or \"text\"",
        ),
    ];
    for (name, text, phrase) in cases {
        let path = write(dir.path(), name, text);
        // `kg fmt` only reads the file's shape; a shadowing input is a meaning, for `kg check`.
        let commands: &[&str] = if name == "shadowing_input.ron" { &["check"] } else { &["check", "fmt"] };
        for &command in commands {
            let out = kg(&[command, path.to_str().unwrap()]);
            assert_eq!(out.status.code(), Some(2), "{name} {command}: {}", stderr(&out));
            assert!(stderr(&out).contains(phrase), "{name} {command}: {}", stderr(&out));
            assert!(!stderr(&out).contains("untagged"), "{name}: serde internals in {}", stderr(&out));
        }
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text, "{name}: kg fmt rewrote a refused file");
    }
}

#[test]
fn long_values_and_control_characters_are_not_echoed_raw() {
    let dir = tempfile::tempdir().unwrap();
    let long = "x".repeat(100_000);
    let text = format!(
        "(format: \"kinegraph.graph\", version: 2,\n nodes: {{ \"t\\u{{1b}}[31m\": (kind: \"clip.resample\", params: {{ \"fps\": \"{long}\" }}) }})"
    );
    let path = write(dir.path(), "long.ron", &text);
    let out = kg(&["check", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.len() < 2_000, "{} bytes of message", err.len());
    assert!(!err.contains('\u{1b}'), "a control character reached the terminal: {err:?}");
    assert!(err.contains("more characters"), "{err}");
}

#[test]
fn kg_fmt_never_drops_comments() {
    let dir = tempfile::tempdir().unwrap();
    let text = "(format: \"kinegraph.graph\", version: 2,\n // why this trim: the first second is a T-pose\n nodes: { \"t\": (kind: \"clip.trim\") })";
    let path = write(dir.path(), "commented.ron", text);
    let out = kg(&["fmt", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("comments"), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
    // Without the comment the same file is rewritten in canonical form.
    let plain = write(dir.path(), "plain.ron", &text.replace("\n // why this trim: the first second is a T-pose", ""));
    let out = kg(&["fmt", plain.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(std::fs::read_to_string(&plain).unwrap().contains("nodes: {\n"));
}

#[test]
fn export_paths_that_cannot_be_written_are_refused_by_kg_check() {
    let dir = tempfile::tempdir().unwrap();
    let walk = assets().join("mannequin_walk.bvh");
    let graph = |a: &str, b: &str| {
        format!(
            "(format: \"kinegraph.graph\", version: 2,\n nodes: {{\n \"load\": (kind: \"clip.load\", params: {{ \"path\": \"{}\" }}),\n \"a\": (kind: \"export.bvh\", params: {{ \"file\": \"{a}\" }}),\n \"b\": (kind: \"export.bvh\", params: {{ \"file\": \"{b}\" }}),\n }},\n edges: [ (from: \"load.clip\", to: \"a.clip\"), (from: \"load.clip\", to: \"b.clip\") ])",
            walk.display()
        )
    };
    let cases = [
        ("nul.ron", graph("w\\u{0}.bvh", "v.bvh"), "which file names cannot carry"),
        ("clash.ron", graph("take.bvh", "take.bvh/w.bvh"), "needs a folder 'take.bvh', where node 'a' writes a file"),
        ("ours.ron", graph(".kg-lock/w.bvh", "v.bvh"), "kg's own"),
    ];
    for (name, text, phrase) in cases {
        let path = write(dir.path(), name, &text);
        let out = kg(&["check", path.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{name}: {}", stderr(&out));
        assert!(stderr(&out).contains(phrase), "{name}: {}", stderr(&out));
        assert!(!stderr(&out).contains('\0'), "{name}: a NUL reached the terminal");
    }
}
