//! The on-disk cache (`--cache DIR`) as a pipeline uses it: a second run of unchanged work
//! does no node work and writes the same files; a changed input is never served stale; a
//! damaged cache is rebuilt; an unusable cache folder is a clear error.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;
use std::process::{Command, Output};

fn kg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kg")).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().unwrap()
}

/// Runs `graph` with `--json` and the cache, returning the report.
fn run(graph: &Path, cache: &Path, out: &Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["run", graph.to_str().unwrap(), "--json", "--cache", cache.to_str().unwrap()];
    args.extend(["--out", out.to_str().unwrap()]);
    args.extend(extra);
    let o = kg(&args);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn statuses(report: &serde_json::Value) -> Vec<(String, String)> {
    report["nodes"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(id, n)| (id.clone(), n["status"].as_str().unwrap().to_string()))
        .collect()
}

fn warnings(report: &serde_json::Value) -> Vec<String> {
    report["nodes"]
        .as_object()
        .unwrap()
        .values()
        .flat_map(|n| n["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap().to_string()))
        .collect()
}

/// Every `.kgc` entry under the cache folder.
fn entries(cache: &Path) -> Vec<std::path::PathBuf> {
    let mut found = Vec::new();
    for shard in std::fs::read_dir(cache).unwrap().flatten() {
        if shard.path().is_dir() {
            found.extend(
                std::fs::read_dir(shard.path())
                    .unwrap()
                    .flatten()
                    .map(|e| e.path())
                    .filter(|p| p.extension().is_some_and(|e| e == "kgc")),
            );
        }
    }
    found
}

/// A copy of the demo graph and its two assets in a scratch folder, so the test can edit
/// the inputs.
fn demo_copy(dir: &Path) -> std::path::PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    std::fs::create_dir_all(dir.join("graphs")).unwrap();
    std::fs::create_dir_all(dir.join("assets")).unwrap();
    for asset in ["mannequin_walk.bvh", "mannequin.glb"] {
        std::fs::copy(root.join("assets").join(asset), dir.join("assets").join(asset)).unwrap();
    }
    std::fs::copy(root.join("graphs/demo.ron"), dir.join("graphs/demo.ron")).unwrap();
    dir.join("graphs/demo.ron")
}

#[test]
fn a_second_run_is_served_from_the_cache_and_restores_identical_exports() {
    let dir = tempfile::tempdir().unwrap();
    let graph = demo_copy(dir.path());
    let cache = dir.path().join("cache");
    let first = run(&graph, &cache, &dir.path().join("a"), &[]);
    assert!(statuses(&first).iter().all(|(_, s)| s == "ok"), "{first}");
    let nodes = statuses(&first).len();
    assert_eq!(entries(&cache).len(), nodes, "one entry per node, exports included");

    // A new process, a new output folder: nothing runs, everything is restored.
    let second = run(&graph, &cache, &dir.path().join("b"), &[]);
    assert!(statuses(&second).iter().all(|(_, s)| s == "cached"), "{second}");
    assert_eq!(first["files_written"].as_array().unwrap().len(), second["files_written"].as_array().unwrap().len());
    for name in ["mannequin_walk.glb", "mannequin_walk_24fps.bvh"] {
        let a = std::fs::read(dir.path().join("a").join(name)).unwrap();
        let b = std::fs::read(dir.path().join("b").join(name)).unwrap();
        assert!(a == b && !a.is_empty(), "{name} restored byte for byte");
    }
    // The reports (what `kg test` compares) are the same whether computed or restored.
    assert_eq!(first["reports"], second["reports"]);

    // A parameter change reruns that node and what depends on it (the exports and the
    // quality check of the resampled clip), nothing else.
    let third = run(&graph, &cache, &dir.path().join("c"), &["--set", "resample.fps=30"]);
    let ran: Vec<String> = statuses(&third).into_iter().filter(|(_, s)| s == "ok").map(|(id, _)| id).collect();
    assert_eq!(ran, ["bvh", "check", "glb", "resample"]);
}

#[test]
fn an_edited_input_file_is_never_served_stale_even_with_its_old_time() {
    let dir = tempfile::tempdir().unwrap();
    let graph = demo_copy(dir.path());
    let cache = dir.path().join("cache");
    run(&graph, &cache, &dir.path().join("a"), &[]);
    // Same size and modification time, different content: only the bytes can tell.
    let clip = dir.path().join("assets/mannequin_walk.bvh");
    let meta = std::fs::metadata(&clip).unwrap();
    let text = std::fs::read_to_string(&clip).unwrap();
    let edited = text.replacen("Frame Time: 0.03333333333333333", "Frame Time: 0.02500000000000000", 1);
    assert_ne!(edited, text, "the fixture's frame time line changed");
    assert_eq!(edited.len(), text.len());
    std::fs::write(&clip, edited).unwrap();
    std::fs::File::options().write(true).open(&clip).unwrap().set_modified(meta.modified().unwrap()).unwrap();
    assert_eq!(std::fs::metadata(&clip).unwrap().modified().unwrap(), meta.modified().unwrap());
    let second = run(&graph, &cache, &dir.path().join("b"), &[]);
    let status: std::collections::BTreeMap<String, String> = statuses(&second).into_iter().collect();
    assert_eq!(status["clip"], "ok", "{second}");
    assert_eq!(status["mesh"], "cached");
    // 40 fps instead of 30: the trimmed second holds more frames, so the BVH differs.
    let bvh = |out: &str| std::fs::read(dir.path().join(out).join("mannequin_walk_24fps.bvh")).unwrap();
    assert_ne!(bvh("a"), bvh("b"));
}

#[test]
fn damaged_entries_are_rebuilt_and_said_so() {
    let dir = tempfile::tempdir().unwrap();
    let graph = demo_copy(dir.path());
    let cache = dir.path().join("cache");
    let first = run(&graph, &cache, &dir.path().join("a"), &[]);
    for entry in entries(&cache) {
        let mut bytes = std::fs::read(&entry).unwrap();
        let middle = bytes.len() / 2;
        bytes[middle] ^= 0x5a;
        std::fs::write(&entry, bytes).unwrap();
    }
    let second = run(&graph, &cache, &dir.path().join("b"), &[]);
    assert!(statuses(&second).iter().all(|(_, s)| s == "ok"), "{second}");
    assert!(warnings(&second).iter().any(|w| w.contains("damaged entry in the cache folder")), "{second}");
    assert_eq!(first["reports"], second["reports"]);
    // Rebuilt: a third run is served from the cache again.
    let third = run(&graph, &cache, &dir.path().join("c"), &[]);
    assert!(statuses(&third).iter().all(|(_, s)| s == "cached"), "{third}");
}

#[test]
fn a_cache_folder_that_is_a_file_is_refused_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("not_a_folder");
    std::fs::write(&file, "x").unwrap();
    let o = kg(&["run", "graphs/demo.ron", "--cache", file.to_str().unwrap(), "--out", "target/cache-refused"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--cache") && err.contains("not_a_folder"), "{err}");
}

#[test]
fn the_cache_folder_is_trimmed_to_its_bound_at_the_end_of_a_run() {
    let dir = tempfile::tempdir().unwrap();
    let graph = demo_copy(dir.path());
    let cache = dir.path().join("cache");
    run(&graph, &cache, &dir.path().join("a"), &[]);
    assert!(!entries(&cache).is_empty());
    // A bound of 0 MiB leaves nothing once the run ends (the order of eviction, least
    // recently used first, is the unit test's).
    run(&graph, &cache, &dir.path().join("b"), &["--cache-max-mib", "0"]);
    assert!(entries(&cache).is_empty());
}
