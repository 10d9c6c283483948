//! Fault injection (issue 22): `kg run`, `kg batch` and farm tasks are killed with SIGKILL,
//! SIGTERM or SIGINT at random points of their work, over and over on the same `--out`.
//! After every kill: each visible output is complete (byte for byte the output of an
//! uninterrupted run), every report is whole JSON, nothing outside `--out` changed. After
//! every few kills, and at the end, a run is let finish: it succeeds, writes the reference
//! outputs and leaves no temporary file, staging folder, lock or lease behind.
//!
//! At least 200 kills land (a kill that arrives after the process finished does not count);
//! `KG_FAULT_KILLS` raises the number. The points are drawn from a fixed seed, so a failure
//! names a kill that can be replayed.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The main job's graph on the shipped assets: a clip in, a skinned GLB and a BVH out.
fn demo_graph() -> PathBuf {
    Path::new(ROOT).join("graphs/demo.ron")
}

/// A small deterministic generator (xorshift64*), so every kill point can be replayed.
struct Points(u64);

impl Points {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Every file under `dir` (recursively, links not followed) with its bytes, by relative path.
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(dir: &Path, base: &Path, found: &mut BTreeMap<String, Vec<u8>>) {
        let Ok(entries) = std::fs::read_dir(dir) else { return };
        for entry in entries.flatten() {
            let path = entry.path();
            let kind = entry.file_type().unwrap();
            if kind.is_dir() {
                walk(&path, base, found);
            } else {
                let name = path.strip_prefix(base).unwrap().to_string_lossy().into_owned();
                found.insert(name, std::fs::read(&path).unwrap_or_default());
            }
        }
    }
    let mut found = BTreeMap::new();
    walk(dir, dir, &mut found);
    found
}

/// Names a kg run keeps only while it works: temporary files, staging folders, the
/// output folder's lock and task leases.
fn is_transient(name: &str) -> bool {
    name.contains(".kg-tmp-") || name.contains(".partial-") || name.contains(".kg-lock") || name.contains(".kg-lease-")
}

/// One way a pipeline runs kg, in `work` (which holds the inputs), writing into `work/out`.
struct Scenario {
    name: &'static str,
    args: Vec<String>,
}

fn scenarios(work: &Path) -> Vec<Scenario> {
    let clips = work.join("clips");
    std::fs::create_dir_all(&clips).unwrap();
    for (from, to) in
        [("mannequin_walk.bvh", "walk.bvh"), ("mannequin_gait.bvh", "gait.bvh"), ("mannequin_walk.bvh", "again.bvh")]
    {
        std::fs::copy(Path::new(ROOT).join("assets").join(from), clips.join(to)).unwrap();
    }
    let graph = demo_graph().to_string_lossy().into_owned();
    let plan = Command::new(env!("CARGO_BIN_EXE_kg"))
        .args(["plan", &graph, "--input", "clip_path=clips/*.bvh", "--out", "plan.json"])
        .current_dir(work)
        .output()
        .unwrap();
    assert!(plan.status.success(), "kg plan: {}", String::from_utf8_lossy(&plan.stderr));
    let strings = |a: &[&str]| a.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
    vec![
        Scenario { name: "run", args: strings(&["run", &graph, "--set", "clip_path=clips/walk.bvh", "--out", "out"]) },
        Scenario {
            name: "batch",
            args: strings(&["batch", &graph, "--input", "clip_path=clips/*.bvh", "--out", "out", "--jobs", "1"]),
        },
        Scenario {
            name: "farm task",
            args: strings(&["run", "--plan", "plan.json", "--task-index", "1", "--out", "out"]),
        },
    ]
}

fn start(work: &Path, scenario: &Scenario) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_kg"))
        .args(&scenario.args)
        .current_dir(work)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Runs the scenario to the end; it must succeed and leave nothing transient behind.
/// Returns its outputs (reports left out: they hold timings) and how long it took.
fn complete(work: &Path, scenario: &Scenario, context: &str) -> (BTreeMap<String, Vec<u8>>, Duration) {
    let began = Instant::now();
    let out = start(work, scenario).wait_with_output().unwrap();
    let took = began.elapsed();
    assert!(
        out.status.success(),
        "{context}: {} did not complete after the kills: {:?}\n{}",
        scenario.name,
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let outputs = files(&work.join("out"));
    let transient: Vec<&String> = outputs.keys().filter(|n| is_transient(n)).collect();
    assert!(transient.is_empty(), "{context}: {} left {transient:?}", scenario.name);
    (outputs.into_iter().filter(|(name, _)| !name.ends_with(".json")).collect(), took)
}

/// The state a kill may leave: every non-transient file is a reference output with the
/// reference bytes, or a report that parses as JSON.
fn check_visible_outputs(work: &Path, reference: &BTreeMap<String, Vec<u8>>, context: &str) {
    for (name, bytes) in files(&work.join("out")) {
        if is_transient(&name) {
            continue;
        }
        if name.ends_with(".json") {
            assert!(
                serde_json::from_slice::<serde_json::Value>(&bytes).is_ok(),
                "{context}: report {name} is not whole JSON ({} bytes)",
                bytes.len()
            );
            continue;
        }
        let Some(want) = reference.get(&name) else {
            panic!("{context}: {name} is not an output of an uninterrupted run");
        };
        assert!(
            bytes == *want,
            "{context}: {name} is incomplete ({} of {} bytes, or other bytes)",
            bytes.len(),
            want.len()
        );
    }
}

/// How the killed process ended: true when the kill landed (killed by the signal, or
/// cancelled cleanly with kg's exit code 130), false when it had already finished.
fn landed(status: ExitStatus, stderr: &[u8], context: &str) -> bool {
    match (status.code(), status.signal()) {
        (Some(0), _) => false,
        (Some(130), _) | (None, Some(_)) => true,
        _ => panic!("{context}: unexpected end {status:?}\n{}", String::from_utf8_lossy(stderr)),
    }
}

#[test]
fn kills_at_random_points_never_leave_partial_outputs_or_touch_anything_outside_out() {
    let wanted: usize = std::env::var("KG_FAULT_KILLS").ok().and_then(|v| v.parse().ok()).unwrap_or(200).max(200);
    let dir = tempfile::tempdir().unwrap();
    let work = dir.path();
    let all = scenarios(work);
    let outside_before: BTreeMap<String, Vec<u8>> =
        files(work).into_iter().filter(|(name, _)| !name.starts_with("out/")).collect();
    let mut points = Points(0x6b67_2d66_6175_6c74);
    let signals = [("KILL", "SIGKILL"), ("TERM", "SIGTERM"), ("INT", "SIGINT")];
    let mut landed_by_signal = BTreeMap::<&str, usize>::new();
    let per_scenario = wanted.div_ceil(all.len());
    for scenario in &all {
        let _ = std::fs::remove_dir_all(work.join("out"));
        let (reference, first) = complete(work, scenario, "reference run");
        assert!(!reference.is_empty(), "{} wrote nothing", scenario.name);
        // The first run pays for cold caches: a second, warm one sets the run's length.
        let (again, warm) = complete(work, scenario, "second reference run");
        assert!(again == reference, "{}: two uninterrupted runs differ", scenario.name);
        let duration = first.min(warm);
        let (mut kills, mut attempts) = (0, 0);
        // Kill points are drawn over the run's length; a run that ends before its kill shows
        // the reference was slower than runs are now (a busy machine), so the window shrinks,
        // never below a quarter of the reference, so kills still spread over the run.
        let mut window = duration;
        while kills < per_scenario {
            attempts += 1;
            assert!(attempts < per_scenario * 4, "{}: only {kills} of {attempts} kills landed", scenario.name);
            let (signal, name) = signals[(points.unit() * signals.len() as f64) as usize % signals.len()];
            let delay = window.mul_f64(points.unit());
            let context =
                format!("{} kill {attempts} ({name} after {:.0} ms)", scenario.name, delay.as_secs_f64() * 1e3);
            let child = start(work, scenario);
            std::thread::sleep(delay);
            // The child is not reaped before the kill, so its pid cannot have been reused.
            let sent = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status().unwrap();
            let ended = child.wait_with_output().unwrap();
            if sent.success() && landed(ended.status, &ended.stderr, &context) {
                kills += 1;
                *landed_by_signal.entry(name).or_default() += 1;
            } else {
                window = window.min(delay).max(duration / 4);
            }
            check_visible_outputs(work, &reference, &context);
            let outside: BTreeMap<String, Vec<u8>> =
                files(work).into_iter().filter(|(name, _)| !name.starts_with("out/")).collect();
            assert!(outside == outside_before, "{context}: a file outside --out changed");
            if attempts % 10 == 0 {
                let (outputs, _) = complete(work, scenario, &context);
                assert!(outputs == reference, "{context}: the rerun's outputs differ from the reference");
            }
        }
        let (outputs, _) = complete(work, scenario, &format!("{} after {kills} kills", scenario.name));
        assert!(outputs == reference, "{}: the final rerun's outputs differ from the reference", scenario.name);
        eprintln!(
            "{}: {kills} kills landed in {attempts} attempts (reference run {duration:.2?}, window {window:.2?})",
            scenario.name
        );
    }
    eprintln!("kills by signal: {landed_by_signal:?}");
    assert!(landed_by_signal.values().sum::<usize>() >= wanted);
    assert_eq!(landed_by_signal.len(), 3, "every signal was sent and landed: {landed_by_signal:?}");
}
