//! `kg` on shared storage and under a farm's signals (issue 22): no write outside `--out`,
//! one run per output folder, temporary files of dead runs removed, clean stops.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const CLIP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/mannequin_walk.bvh");

fn kg(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kg")).args(args).current_dir(dir).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A graph that loads the mannequin walk and writes it as BVH to `file` (relative to
/// `--out`), saved as `dir/graph.ron`.
fn bvh_graph(dir: &Path, file: &str) -> PathBuf {
    let path = dir.join("graph.ron");
    let text = format!(
        r#"(format: "kinegraph.graph", version: 2, inputs: {{ "clip": "load.path" }},
 nodes: {{ "load": (kind: "clip.load", params: {{ "path": "{CLIP}" }}),
          "bvh": (kind: "export.bvh", params: {{ "file": "{file}" }}) }},
 edges: [ (from: "load.clip", to: "bvh.clip") ])"#
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// Every file name under `dir`, recursively, relative to it, sorted (links not followed).
fn tree(dir: &Path) -> Vec<String> {
    fn walk(dir: &Path, base: &Path, names: &mut Vec<String>) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for entry in entries.flatten() {
            let path = entry.path();
            names.push(path.strip_prefix(base).unwrap().to_string_lossy().into_owned());
            if entry.file_type().unwrap().is_dir() {
                walk(&path, base, names);
            }
        }
    }
    let mut names = Vec::new();
    walk(dir, dir, &mut names);
    names.sort();
    names
}

/// A pid that no process has now.
fn dead_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    let pid = child.id();
    child.wait().unwrap();
    pid
}

#[cfg(unix)]
#[test]
fn a_linked_folder_inside_out_is_refused_and_its_target_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let graph = bvh_graph(dir.path(), "task/walk.bvh");
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::os::unix::fs::symlink(&elsewhere, out.join("task")).unwrap();
    let o = kg(dir.path(), &["run", graph.to_str().unwrap(), "--out", "out"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("symbolic link"), "{}", stderr(&o));
    assert!(tree(&elsewhere).is_empty(), "written through the link: {:?}", tree(&elsewhere));
}

#[test]
fn a_second_run_on_the_same_out_is_refused_naming_the_holder() {
    let dir = tempfile::tempdir().unwrap();
    let graph = bvh_graph(dir.path(), "walk.bvh");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    // Stand in for a running `kg run`: hold the folder's lock the way it does.
    let lock =
        std::fs::OpenOptions::new().read(true).write(true).create(true).truncate(true).open(out.join(".kg-lock"));
    let lock = lock.unwrap();
    lock.try_lock().unwrap();
    std::fs::write(out.join(".kg-lock"), format!("pid {} on host here\n", std::process::id())).unwrap();
    for command in [
        vec!["run", graph.to_str().unwrap(), "--out", "out"],
        vec!["batch", graph.to_str().unwrap(), "--input", &format!("clip={CLIP}"), "--out", "out"],
    ] {
        let o = kg(dir.path(), &command);
        assert_eq!(o.status.code(), Some(3), "{command:?}: {}", stderr(&o));
        let err = stderr(&o);
        assert!(err.contains(&format!("pid {}", std::process::id())) && err.contains("in use"), "{err}");
    }
    assert!(!out.join("walk.bvh").exists());
    drop(lock);
    let o = kg(dir.path(), &["run", graph.to_str().unwrap(), "--out", "out"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

#[test]
fn temporary_files_of_dead_runs_are_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let graph = bvh_graph(dir.path(), "sub/walk.bvh");
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join("sub")).unwrap();
    let pid = dead_pid();
    let stale = [
        out.join(format!(".kg-tmp-{pid}-abcdefghij.walk.bvh")),
        out.join(format!("sub/.kg-tmp-{pid}-abcdefghij.walk.bvh")),
    ];
    for f in &stale {
        std::fs::write(f, vec![0u8; 1 << 20]).unwrap();
    }
    let o = kg(dir.path(), &["run", graph.to_str().unwrap(), "--out", "out"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(tree(&out), ["sub", "sub/walk.bvh"]);
}

const FARM_GRAPH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/farm/to_glb.ron");

/// A work folder with the farm graph and clips named `names` (each the mannequin walk),
/// planned into `plans/plan.json`.
fn planned(names: &[&str]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let clips = dir.path().join("clips");
    std::fs::create_dir(&clips).unwrap();
    std::fs::copy(FARM_GRAPH, dir.path().join("to_glb.ron")).unwrap();
    for name in names {
        std::fs::copy(CLIP, clips.join(name)).unwrap();
    }
    let o = kg(dir.path(), &["plan", "to_glb.ron", "--input", "clip=clips/*.bvh", "--out", "plans/plan.json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    dir
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

fn run_task(dir: &Path, index: usize) -> Output {
    kg(dir, &["run", "--plan", "plans/plan.json", "--task-index", &index.to_string(), "--out", "out"])
}

#[test]
fn a_tampered_plan_with_unsafe_or_duplicate_task_ids_is_refused_with_exit_2() {
    let dir = planned(&["a.bvh", "b.bvh"]);
    let plan_path = dir.path().join("plans/plan.json");
    let good = read_json(&plan_path);
    let before = tree(dir.path());
    let mut cases: Vec<(String, serde_json::Value)> = Vec::new();
    for bad in
        ["../../x", "/tmp/kg-abs-task", ".", "..", "", "reports", "summary.json", "a\u{0}b", "a\nb", ".a.partial-1"]
    {
        let mut plan = good.clone();
        plan["tasks"][0]["id"] = bad.into();
        plan["tasks"][0]["outputs"] = serde_json::json!([format!("{bad}/clip.glb")]);
        cases.push((format!("id {bad:?}"), plan));
    }
    let mut duplicate = good.clone();
    duplicate["tasks"][1]["id"] = "a".into();
    duplicate["tasks"][1]["outputs"] = serde_json::json!(["a/clip.glb"]);
    cases.push(("duplicate id".into(), duplicate));
    let mut escaping_output = good.clone();
    escaping_output["tasks"][0]["outputs"] = serde_json::json!(["a/../../x.glb"]);
    cases.push(("escaping output".into(), escaping_output));
    for (what, plan) in cases {
        std::fs::write(&plan_path, serde_json::to_string_pretty(&plan).unwrap()).unwrap();
        for index in [0, 1] {
            let o = run_task(dir.path(), index);
            assert_eq!(o.status.code(), Some(2), "{what}, task {index}: {}", stderr(&o));
            assert!(stderr(&o).contains("plan.json") && stderr(&o).contains("task"), "{what}: {}", stderr(&o));
        }
        let merged = kg(dir.path(), &["merge", "plans/plan.json", "--out", "out"]);
        assert_eq!(merged.status.code(), Some(2), "{what}: {}", stderr(&merged));
    }
    assert!(!Path::new("/tmp/kg-abs-task").exists());
    assert_eq!(tree(dir.path()), before, "a refused plan wrote something");
}

#[test]
fn input_stems_that_are_reserved_names_get_safe_unique_ids() {
    let dir = planned(&["a.bvh", "reports.bvh", "summary.json.bvh", ".hidden.bvh"]);
    let plan = read_json(&dir.path().join("plans/plan.json"));
    let ids: Vec<&str> = plan["tasks"].as_array().unwrap().iter().map(|t| t["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["_hidden", "a", "reports_2", "summary.json_2"]);
    for index in 0..ids.len() {
        let o = run_task(dir.path(), index);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    }
    let o = kg(dir.path(), &["merge", "plans/plan.json", "--out", "out", "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    for id in ids {
        assert!(dir.path().join(format!("out/reports/{id}.json")).is_file(), "{id}");
        assert!(dir.path().join(format!("out/{id}/clip.glb")).is_file(), "{id}");
    }
    assert!(dir.path().join("out/summary.json").is_file());
}

#[test]
fn a_batch_input_named_like_the_batch_report_keeps_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let clips = dir.path().join("clips");
    std::fs::create_dir(&clips).unwrap();
    std::fs::copy(CLIP, clips.join("batch_report.json.bvh")).unwrap();
    std::fs::copy(CLIP, clips.join("walk.bvh")).unwrap();
    let o = kg(dir.path(), &["batch", FARM_GRAPH, "--input", "clip=clips/*.bvh", "--out", "out"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report = read_json(&dir.path().join("out/batch_report.json"));
    assert_eq!(report["ok"], 2);
    assert!(dir.path().join("out/batch_report.json_2/clip.glb").is_file());
    assert!(dir.path().join("out/walk/clip.glb").is_file());
}

#[test]
fn a_retry_while_the_task_runs_is_refused_and_keeps_the_running_attempts_staging() {
    let dir = planned(&["a.bvh"]);
    let out = dir.path().join("out");
    let staging = out.join(".a.partial-4242-running");
    std::fs::create_dir_all(&staging).unwrap();
    std::fs::write(staging.join("clip.glb"), b"half").unwrap();
    // Stand in for the running attempt: hold the task's lease the way it does.
    let lease_path = out.join(".kg-lease-a");
    let lease = std::fs::OpenOptions::new().read(true).write(true).create(true).truncate(true).open(&lease_path);
    let mut lease = lease.unwrap();
    lease.try_lock().unwrap();
    std::io::Write::write_all(&mut lease, b"pid 4242 on host farm-7\n").unwrap();
    let o = run_task(dir.path(), 0);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("already running") && err.contains("pid 4242 on host farm-7"), "{err}");
    assert!(staging.join("clip.glb").is_file(), "the running attempt's staging folder was removed");
    assert!(!out.join("reports/a.json").exists());
    drop(lease);
    // A kg started by another test thread at that moment may hold a copy of the lease's
    // descriptor between its fork and its exec: wait until the lock is really free.
    let waited = std::time::Instant::now();
    while std::fs::File::open(&lease_path).unwrap().try_lock().is_err() {
        assert!(waited.elapsed().as_secs() < 10, "the lease stays locked after its holder let go");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let o = run_task(dir.path(), 0);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(!staging.exists(), "a dead attempt's staging folder is left");
    assert!(!lease_path.exists());
}

fn merge_json(dir: &Path) -> (Output, serde_json::Value) {
    let o = kg(dir, &["merge", "plans/plan.json", "--out", "out", "--json"]);
    let summary = serde_json::from_slice(&o.stdout).unwrap();
    (o, summary)
}

#[test]
fn merge_checks_every_output_against_its_report() {
    let dir = planned(&["a.bvh", "b.bvh", "c.bvh"]);
    for index in 0..3 {
        assert_eq!(run_task(dir.path(), index).status.code(), Some(0));
    }
    let (o, summary) = merge_json(dir.path());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(summary["counts"]["ok"], 3);
    // a: same size, one byte changed; b: deleted; c: truncated.
    let a = dir.path().join("out/a/clip.glb");
    let mut bytes = std::fs::read(&a).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0xff;
    std::fs::write(&a, bytes).unwrap();
    std::fs::remove_file(dir.path().join("out/b/clip.glb")).unwrap();
    let c = dir.path().join("out/c/clip.glb");
    let len = std::fs::metadata(&c).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&c).unwrap().set_len(len / 2).unwrap();
    let (o, summary) = merge_json(dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(summary["counts"]["failed"], 3, "{summary:#}");
    let error = |i: usize| summary["per_task"][i]["error"].as_str().unwrap().to_string();
    assert!(error(0).contains("a/clip.glb") && error(0).contains("sha256"), "{}", error(0));
    assert!(error(1).contains("b/clip.glb") && error(1).contains("No such file"), "{}", error(1));
    assert!(error(2).contains("c/clip.glb") && error(2).contains("bytes, the report says"), "{}", error(2));
}

#[test]
fn merge_warns_about_an_unreadable_report_and_counts_its_task_failed() {
    let dir = planned(&["a.bvh", "b.bvh"]);
    assert_eq!(run_task(dir.path(), 0).status.code(), Some(0));
    std::fs::create_dir_all(dir.path().join("out/reports")).unwrap();
    std::fs::write(dir.path().join("out/reports/b.json"), b"{ garbage").unwrap();
    let (o, summary) = merge_json(dir.path());
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(err.contains("warning") && err.contains("reports/b.json"), "{err}");
    assert_eq!(summary["counts"]["failed"], 1);
    assert_eq!(summary["counts"]["missing"], 0);
    assert_eq!(summary["per_task"][1]["status"], "failed");
    assert!(summary["warnings"][0].as_str().unwrap().contains("reports/b.json"));
}

/// Runs `kg args` with its standard output a pipe whose reading end is already closed.
fn kg_into_closed_pipe(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let child = Command::new(env!("CARGO_BIN_EXE_kg"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn listings_into_a_closed_pipe_end_quietly_with_exit_0() {
    for args in [
        vec!["nodes"],
        vec!["nodes", "--markdown"],
        vec!["nodes", "--json"],
        vec!["check", "--json", "graphs/demo.ron"],
        vec!["inspect", "assets/mannequin_walk.bvh"],
    ] {
        let o = kg_into_closed_pipe(&args);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{args:?}: {}", stderr(&o));
    }
}

/// A graph that takes a few seconds: the clip input `clip` exported as `walk.bvh`, and
/// `heavy` independent dense arm meshes (sinks, each with other params so none is
/// cached); with one thread they run one after another, so a signal lands between two.
fn slow_graph(dir: &Path, heavy: usize) -> PathBuf {
    let arms: Vec<String> = (0..heavy)
        .map(|i| {
            format!(
                r#""arm{i:02}": (kind: "generate.arm", params: {{ "rings": {}, "segments": 400, "frames": 2 }}),"#,
                400 + i
            )
        })
        .collect();
    let text = format!(
        r#"(format: "kinegraph.graph", version: 2, inputs: {{ "clip": "load.path" }},
 nodes: {{ "load": (kind: "clip.load", params: {{ "path": "{CLIP}" }}),
          {}
          "bvh": (kind: "export.bvh", params: {{ "file": "walk.bvh" }}) }},
 edges: [ (from: "load.clip", to: "bvh.clip") ])"#,
        arms.join("\n          ")
    );
    let path = dir.join("slow.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// Starts `kg args` in `dir`, waits until it holds `busy` (its output folder's lock or its
/// task's lease, a file with its pid, written once the graph is loaded), lets it evaluate
/// for a moment, sends it `signal` (`TERM`, `INT`), and waits for it.
fn kg_signalled(dir: &Path, args: &[&str], signal: &str, busy: &str) -> Output {
    let child = Command::new(env!("CARGO_BIN_EXE_kg"))
        .args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let busy = dir.join(busy);
    let waited = std::time::Instant::now();
    while !std::fs::read_to_string(&busy).is_ok_and(|t| t.contains(&format!("pid {}", child.id()))) {
        assert!(waited.elapsed().as_secs() < 60, "kg never took {}", busy.display());
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::thread::sleep(std::time::Duration::from_millis(100));
    let status = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
    assert!(status.success());
    child.wait_with_output().unwrap()
}

/// Names under `dir` (recursively) that are kg temporary files or staging folders.
fn leftovers(dir: &Path) -> Vec<String> {
    tree(dir).into_iter().filter(|n| n.contains(".kg-tmp-") || n.contains(".partial-")).collect()
}

#[test]
fn sigterm_cancels_a_run_which_reports_cancelled_and_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let graph = slow_graph(dir.path(), 40);
    let args = ["run", graph.to_str().unwrap(), "--out", "out", "--json", "--threads", "1"];
    let o = kg_signalled(dir.path(), &args, "TERM", "out/.kg-lock");
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["status"], "cancelled");
    assert_eq!(report["exit_code"], 130);
    let statuses: Vec<&str> =
        report["nodes"].as_object().unwrap().values().map(|n| n["status"].as_str().unwrap()).collect();
    assert!(statuses.contains(&"ok") && statuses.contains(&"cancelled"), "{statuses:?}");
    assert!(leftovers(dir.path()).is_empty(), "{:?}", leftovers(dir.path()));
}

#[test]
fn an_interrupted_batch_saves_its_report_with_unreached_inputs_not_run() {
    let dir = tempfile::tempdir().unwrap();
    let graph = slow_graph(dir.path(), 40);
    let clips = dir.path().join("clips");
    std::fs::create_dir(&clips).unwrap();
    for i in 0..6 {
        std::fs::copy(CLIP, clips.join(format!("walk{i}.bvh"))).unwrap();
    }
    let args = ["batch", graph.to_str().unwrap(), "--input", "clip=clips/*.bvh", "--out", "out", "--jobs", "1"];
    let o = kg_signalled(dir.path(), &args, "INT", "out/.kg-lock");
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let report = read_json(&dir.path().join("out/batch_report.json"));
    assert_eq!(report["failed"], 0, "{report:#}");
    assert_eq!(report["cancelled"], 1, "{report:#}");
    assert_eq!(report["not_run"], 5, "{report:#}");
    let statuses: Vec<&str> =
        report["runs"].as_array().unwrap().iter().map(|r| r["status"].as_str().unwrap()).collect();
    assert_eq!(statuses, ["cancelled", "not_run", "not_run", "not_run", "not_run", "not_run"]);
    let err = stderr(&o);
    assert!(err.contains("not run") && !err.contains("FAILED"), "{err}");
    assert!(leftovers(dir.path()).is_empty(), "{:?}", leftovers(dir.path()));
}

#[test]
fn an_interrupted_farm_task_reports_cancelled_and_keeps_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let graph = slow_graph(dir.path(), 40);
    std::fs::copy(CLIP, dir.path().join("walk.bvh")).unwrap();
    let o = kg(dir.path(), &["plan", graph.to_str().unwrap(), "--input", "clip=walk.bvh", "--out", "plan.json"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let args = ["run", "--plan", "plan.json", "--task-index", "0", "--out", "out", "--threads", "1"];
    let o = kg_signalled(dir.path(), &args, "TERM", "out/.kg-lease-walk");
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("cancelled") && !err.contains(": ok"), "{err}");
    assert_eq!(read_json(&dir.path().join("out/reports/walk.json"))["status"], "cancelled");
    assert!(!dir.path().join("out/walk").exists());
    assert!(leftovers(dir.path()).is_empty(), "{:?}", leftovers(dir.path()));
    assert!(!dir.path().join("out/.kg-lease-walk").exists());
}

/// `graph.ron` in `dir` holding the given nodes (RON map entries) and no edges.
fn nodes_graph(dir: &Path, nodes: &str) -> PathBuf {
    let path = dir.join("graph.ron");
    std::fs::write(&path, format!(r#"(format: "kinegraph.graph", version: 2, nodes: {{ {nodes} }}, edges: [])"#))
        .unwrap();
    path
}

/// `kg run --json` of `graph` with `extra` arguments: its exit code and report.
fn run_json(dir: &Path, graph: &Path, extra: &[&str]) -> (Option<i32>, serde_json::Value) {
    let mut args = vec!["run", graph.to_str().unwrap(), "--json"];
    args.extend_from_slice(extra);
    let o = kg(dir, &args);
    (o.status.code(), serde_json::from_slice(&o.stdout).unwrap_or_else(|_| panic!("{}", stderr(&o))))
}

/// An arm of 10,000 rings × 10,000 segments is 10⁸ vertices and 2·10⁸ triangles: at least
/// 10⁸ × (12 B position + 12 B normal) + 2·10⁸ × 12 B = 4.8 GB before any skin. Under a
/// 4 GiB limit it is refused before anything is allocated, naming the param; the same node
/// at its default resolution runs under the same limit.
#[test]
fn a_node_asking_for_more_memory_than_the_limit_is_refused_naming_its_param() {
    let dir = tempfile::tempdir().unwrap();
    let huge = r#""arm": (kind: "generate.arm", params: { "rings": 10000, "segments": 10000 })"#;
    let graph = nodes_graph(dir.path(), huge);
    let (code, report) = run_json(dir.path(), &graph, &["--max-memory", "4G"]);
    assert_eq!(code, Some(1), "{report:#}");
    let error = report["nodes"]["arm"]["error"].as_str().unwrap();
    assert!(error.contains("rings") && error.contains("4.0 GiB") && error.contains("--max-memory"), "{error}");
    let needed: f64 = error.split("about ").nth(1).unwrap().split(" GiB").next().unwrap().parse().unwrap();
    assert!(needed * (1u64 << 30) as f64 >= 4.8e9, "{error}");

    let graph = nodes_graph(dir.path(), r#""arm": (kind: "generate.arm", params: {})"#);
    let (code, report) = run_json(dir.path(), &graph, &["--max-memory", "4G"]);
    assert_eq!(code, Some(0), "{report:#}");
}

/// A clip's length in frames comes from data and params together: the mannequin's 100,000
/// frames at 24 fps last 4,167 s, which at 1,000 fps are 4.2 million frames of every joint
/// (> 1 GiB). `clip.resample` refuses under a 1 GiB limit, naming `fps`.
#[test]
fn resampling_a_long_clip_to_a_high_rate_is_refused_under_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let graph = dir.path().join("graph.ron");
    std::fs::write(
        &graph,
        r#"(format: "kinegraph.graph", version: 2,
 nodes: { "m": (kind: "generate.mannequin", params: { "frames": 100000 }),
          "fast": (kind: "clip.resample", params: { "fps": 1000.0 }) },
 edges: [ (from: "m.clip", to: "fast.clip") ])"#,
    )
    .unwrap();
    let (code, report) = run_json(dir.path(), &graph, &["--max-memory", "1G"]);
    assert_eq!(code, Some(1), "{report:#}");
    let error = report["nodes"]["fast"]["error"].as_str().unwrap();
    assert!(error.contains("fps") && error.contains("1.0 GiB"), "{error}");
    assert_eq!(report["nodes"]["m"]["status"], "ok");
}

#[test]
fn a_memory_size_that_is_not_one_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let graph = nodes_graph(dir.path(), r#""arm": (kind: "generate.arm", params: {})"#);
    let o = kg(dir.path(), &["run", graph.to_str().unwrap(), "--max-memory", "lots"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("'lots' is not a size"), "{}", stderr(&o));
}
