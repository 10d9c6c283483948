//! `kg watch` as a technical artist uses it: save the graph, see the new result; delete an
//! input, see the failure (never the old result); Ctrl-C ends it cleanly.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

fn next_report(lines: &Receiver<String>) -> serde_json::Value {
    let line = lines.recv_timeout(Duration::from_secs(60)).expect("a report within a minute");
    serde_json::from_str(&line).unwrap()
}

/// Reports arriving within half a second while nothing changes. One may be a late echo of
/// the last save on a busy machine; a watch that reacts to its own reads makes dozens.
fn unasked_runs(lines: &Receiver<String>) -> usize {
    let deadline = Instant::now() + Duration::from_millis(500);
    std::iter::from_fn(|| lines.recv_timeout(deadline.saturating_duration_since(Instant::now())).ok()).count()
}

/// Starts `kg watch GRAPH --out OUT --json`; its report lines arrive on the receiver.
fn watch(graph: &Path, out: &Path) -> (Child, Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_kg"))
        .args(["watch", graph.to_str().unwrap(), "--out", out.to_str().unwrap(), "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, lines) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    (child, lines)
}

#[test]
fn watch_reruns_what_a_save_reaches_and_never_serves_a_deleted_input() {
    let dir = tempfile::tempdir().unwrap();
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    std::fs::copy(assets.join("mannequin_walk.bvh"), dir.path().join("walk.bvh")).unwrap();
    let graph_text = |fps: f64| {
        format!(
            r#"(format: "kinegraph.graph", version: 2,
 nodes: {{
   "clip": (kind: "clip.load", params: {{ "path": "walk.bvh" }}),
   "trim": (kind: "clip.trim", params: {{ "end_secs": 1.0 }}),
   "resample": (kind: "clip.resample", params: {{ "fps": {fps:?} }}),
   "bvh": (kind: "export.bvh", params: {{ "file": "w.bvh" }}),
 }},
 edges: [ (from: "clip.clip", to: "trim.clip"), (from: "trim.clip", to: "resample.clip"), (from: "resample.clip", to: "bvh.clip") ])"#
        )
    };
    let graph = dir.path().join("g.ron");
    std::fs::write(&graph, graph_text(24.0)).unwrap();
    let out = dir.path().join("out");
    let (mut child, lines) = watch(&graph, &out);

    let first = next_report(&lines);
    assert_eq!(first["ok"], true, "{first}");
    assert_eq!(first["nodes"]["resample"]["status"], "ok");

    // A save of the graph re-runs the changed node and what follows; the rest is cached.
    std::thread::sleep(Duration::from_millis(200));
    let saved = Instant::now();
    std::fs::write(&graph, graph_text(12.0)).unwrap();
    let second = next_report(&lines);
    eprintln!("save → report: {:.0} ms", saved.elapsed().as_secs_f64() * 1e3);
    // The trim is served from memory, so the loader it reads is not even visited.
    assert_eq!(second["nodes"]["trim"]["status"], "cached", "{second}");
    assert!(second["nodes"].get("clip").is_none());
    assert_eq!(second["nodes"]["resample"]["status"], "ok");
    let bvh = std::fs::read_to_string(out.join("w.bvh")).unwrap();
    assert!(bvh.contains("Frame Time: 0.083333"), "the export is the 12 fps one");
    // The run read the graph again; reading is not a change, so nothing follows by itself.
    assert!(unasked_runs(&lines) <= 1, "runs nobody asked for");

    // The input deleted: the loader fails, nothing downstream is served from the cache.
    std::fs::remove_file(dir.path().join("walk.bvh")).unwrap();
    let third = next_report(&lines);
    assert_eq!(third["ok"], false, "{third}");
    assert_eq!(third["nodes"]["clip"]["status"], "error");
    assert_eq!(third["nodes"]["resample"]["status"], "blocked");

    // Ctrl-C: a clean stop.
    Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
}

#[test]
fn a_clip_added_to_a_watched_clip_set_folder_reruns_the_loader() {
    let dir = tempfile::tempdir().unwrap();
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    let clips = dir.path().join("clips");
    std::fs::create_dir_all(clips.join("walks")).unwrap();
    std::fs::copy(assets.join("mannequin_walk.bvh"), clips.join("walks/walk.bvh")).unwrap();
    let graph = dir.path().join("g.ron");
    std::fs::write(
        &graph,
        r#"(format: "kinegraph.graph", version: 2,
 nodes: { "set": (kind: "load.clip_set", params: { "folder": "clips" }) })"#,
    )
    .unwrap();
    // The output folder inside the watched folder: our own writes must not trigger runs.
    let out = clips.join("out");
    let (mut child, lines) = watch(&graph, &out);
    let clip_names = |report: &serde_json::Value| -> Vec<String> {
        report["reports"]["set"]["clips"].as_object().unwrap().keys().cloned().collect()
    };
    let first = next_report(&lines);
    assert_eq!(clip_names(&first), ["walk"], "{first}");

    // A clip saved into a sub-folder: the set is loaded again, not served from memory.
    std::thread::sleep(Duration::from_millis(200));
    std::fs::copy(assets.join("mannequin_walk.bvh"), clips.join("walks/walk_again.bvh")).unwrap();
    let second = next_report(&lines);
    assert_eq!(second["nodes"]["set"]["status"], "ok", "{second}");
    assert_eq!(clip_names(&second), ["walk", "walk_again"]);

    // No further run follows by itself (its own output folder is not a change).
    assert!(unasked_runs(&lines) <= 1, "runs nobody asked for");
    Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert_eq!(child.wait().unwrap().code(), Some(0));
}
