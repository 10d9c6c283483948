//! Subgraphs: a graph file used as a node, checked against the same pipeline written out
//! flat, and every way a subgraph can be wrong refused at the right file and line.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn kg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kg")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn write(path: &Path, text: &str) -> PathBuf {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, text).unwrap();
    path.to_path_buf()
}

/// The 1-based line of the first line of `text` containing `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).expect("needle in text") + 1
}

/// A stage in `stages/`: trim then resample, showing `clip` in and out, with its own
/// relative input-free nodes and two promoted parameters.
const STAGE: &str = r#"(format: "kinegraph.graph", version: 3,
 inputs: { "end": "trim.end_secs", "rate": "resample.fps" },
 nodes: {
   "trim": (kind: "clip.trim", params: { "end_secs": 1.0 }),
   "resample": (kind: "clip.resample", params: { "fps": 24.0 }),
 },
 edges: [ (from: "trim.clip", to: "resample.clip") ],
 ports: ( inputs: { "clip": ["trim.clip"] }, outputs: { "clip": "resample.clip" } ))"#;

fn setup(dir: &Path) {
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    std::fs::copy(assets.join("mannequin_walk.bvh"), dir.join("walk.bvh")).unwrap();
    write(&dir.join("stages/clean.ron"), STAGE);
}

fn run(graph: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend(extra);
    kg(&args)
}

#[test]
fn a_subgraph_gives_what_the_same_nodes_give_written_flat() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let with_stage = write(
        &dir.path().join("staged.ron"),
        r#"(format: "kinegraph.graph", version: 3,
 inputs: { "rate": "clean.rate" },
 nodes: {
   "load": (kind: "clip.load", params: { "path": "walk.bvh" }),
   "clean": (kind: "graph.subgraph", params: { "file": "stages/clean.ron", "end": 0.5 }),
   "bvh": (kind: "export.bvh", params: { "file": "w.bvh" }),
 },
 edges: [ (from: "load.clip", to: "clean.clip"), (from: "clean.clip", to: "bvh.clip") ])"#,
    );
    let flat = write(
        &dir.path().join("flat.ron"),
        r#"(format: "kinegraph.graph", version: 2,
 nodes: {
   "load": (kind: "clip.load", params: { "path": "walk.bvh" }),
   "trim": (kind: "clip.trim", params: { "end_secs": 0.5 }),
   "resample": (kind: "clip.resample", params: { "fps": 12.0 }),
   "bvh": (kind: "export.bvh", params: { "file": "w.bvh" }),
 },
 edges: [ (from: "load.clip", to: "trim.clip"), (from: "trim.clip", to: "resample.clip"), (from: "resample.clip", to: "bvh.clip") ])"#,
    );
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let staged = run(&with_stage, &a, &["--set", "rate=12", "--json"]);
    assert_eq!(staged.status.code(), Some(0), "{}", stderr(&staged));
    let flat_run = run(&flat, &b, &[]);
    assert_eq!(flat_run.status.code(), Some(0), "{}", stderr(&flat_run));
    assert_eq!(std::fs::read(a.join("w.bvh")).unwrap(), std::fs::read(b.join("w.bvh")).unwrap());
    // Inner nodes report under the subgraph's id.
    let report: serde_json::Value = serde_json::from_slice(&staged.stdout).unwrap();
    assert_eq!(report["nodes"]["clean/resample"]["status"], "ok", "{report}");
    // A subgraph inside a subgraph: the stage wrapped once more gives the same file.
    write(
        &dir.path().join("stages/wrapped.ron"),
        r#"(format: "kinegraph.graph", version: 3,
 inputs: { "end": "inner.end", "rate": "inner.rate" },
 nodes: { "inner": (kind: "graph.subgraph", params: { "file": "clean.ron" }) },
 ports: ( inputs: { "clip": ["inner.clip"] }, outputs: { "clip": "inner.clip" } ))"#,
    );
    let nested = write(
        &dir.path().join("nested.ron"),
        &std::fs::read_to_string(&with_stage).unwrap().replace("stages/clean.ron", "stages/wrapped.ron"),
    );
    let c = dir.path().join("c");
    let nested_run = run(&nested, &c, &["--set", "rate=12"]);
    assert_eq!(nested_run.status.code(), Some(0), "{}", stderr(&nested_run));
    assert_eq!(std::fs::read(c.join("w.bvh")).unwrap(), std::fs::read(b.join("w.bvh")).unwrap());
}

#[test]
fn subgraph_mistakes_are_refused_at_their_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    write(
        &dir.path().join("stages/self.ron"),
        r#"(format: "kinegraph.graph", version: 3,
 nodes: { "again": (kind: "graph.subgraph", params: { "file": "self.ron" }) })"#,
    );
    let broken_stage = "(format: \"kinegraph.graph\", version: 3,\n nodes: {\n   \"trim\": (kind: \"clip.trim\", params: { \"end_secs\": \"soon\" }),\n },\n ports: ( inputs: { \"clip\": [\"trim.clip\"] }, outputs: { \"clip\": \"trim.clip\" } ))";
    write(&dir.path().join("stages/broken.ron"), broken_stage);
    let parent = |file: &str, param: &str, edges: &str| {
        format!(
            "(format: \"kinegraph.graph\", version: 3,\n nodes: {{\n   \"load\": (kind: \"clip.load\", params: {{ \"path\": \"walk.bvh\" }}),\n   \"mesh\": (kind: \"mesh.load\", params: {{ \"path\": \"x.obj\" }}),\n   \"stage\": (kind: \"graph.subgraph\", params: {{ \"file\": \"{file}\"{param} }}),\n }},\n edges: [ {edges} ])"
        )
    };
    let cases = [
        ("missing.ron", parent("stages/nowhere.ron", "", ""), "\"file\"", "nowhere.ron"),
        (
            "wrong_type.ron",
            parent("stages/clean.ron", "", "(from: \"mesh.mesh\", to: \"stage.clip\")"),
            "to: \"stage.clip\"",
            "type mismatch: mesh.mesh gives a mesh, but stage.clip takes a clip",
        ),
        (
            "no_port.ron",
            parent("stages/clean.ron", "", "(from: \"load.clip\", to: \"stage.clips\")"),
            "to: \"stage.clips\"",
            "subgraph 'stage' (stages/clean.ron) has no input 'clips'; it shows clip",
        ),
        ("no_param.ron", parent("stages/clean.ron", ", \"rates\": 5", ""), "\"rates\"", "did you mean 'rate'?"),
    ];
    for (name, text, needle, phrase) in cases {
        let path = write(&dir.path().join(name), &text);
        let out = kg(&["check", path.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{name}: {}", stderr(&out));
        let err = stderr(&out);
        assert!(err.contains(phrase), "{name}: {err}");
        let at = format!("{}:{}:", path.display(), line_of(&text, needle));
        assert!(err.contains(&at), "{name}: expected {at} in {err}");
    }
    // A file that includes itself is refused where it does so.
    let path = write(&dir.path().join("loop.ron"), &parent("stages/self.ron", "", ""));
    let out = kg(&["check", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("includes itself"), "{}", stderr(&out));
    assert!(stderr(&out).contains(&format!("{}:2:", dir.path().join("stages/self.ron").display())), "{}", stderr(&out));
    // A problem inside the subgraph's file is reported at that file and line.
    let path = write(&dir.path().join("inside.ron"), &parent("stages/broken.ron", "", ""));
    let out = kg(&["check", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let at = format!("{}:{}:", dir.path().join("stages/broken.ron").display(), line_of(broken_stage, "soon"));
    assert!(stderr(&out).contains(&at), "expected {at} in {}", stderr(&out));
    // A subgraph node cannot be bypassed (its nodes can, inside its file).
    let text = parent("stages/clean.ron", "", "")
        .replace("(kind: \"graph.subgraph\",", "(kind: \"graph.subgraph\", bypass: true,");
    let path = write(&dir.path().join("bypassed.ron"), &text);
    let out = kg(&["check", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let at = format!("{}:{}:", path.display(), line_of(&text, "\"file\""));
    assert!(stderr(&out).contains(&at) && stderr(&out).contains("cannot be bypassed"), "{}", stderr(&out));
}
