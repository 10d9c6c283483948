//! Farm runs as a pipeline drives them: `kg plan`, `kg run --plan --task-index`, `kg emit`,
//! `kg merge`. The real-engine runs (OpenJD, Slurm) are opt-in: `KG_OPENJD=1`, `KG_SLURM=1`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, SystemTime};

use kinegraph::farm::{self, EmitOptions, Plan, Target};

const GRAPH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/farm/to_glb.ron");
const DOWNSTREAM_GRAPH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/farm/to_bvh.ron");
const CLIP: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/mannequin_walk.bvh");

fn kg(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kg")).args(args).current_dir(dir).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A work folder with the graph, two good clips (`a`, `b`) and one that is not BVH
/// (`broken`), planned into `plan.json`.
struct Work {
    dir: tempfile::TempDir,
}

impl Work {
    fn new() -> Work {
        let dir = tempfile::tempdir().unwrap();
        let clips = dir.path().join("clips");
        std::fs::create_dir(&clips).unwrap();
        std::fs::copy(GRAPH, dir.path().join("to_glb.ron")).unwrap();
        std::fs::copy(CLIP, clips.join("a.bvh")).unwrap();
        std::fs::copy(CLIP, clips.join("b.bvh")).unwrap();
        std::fs::write(clips.join("broken.bvh"), "HIERARCHY\nROOT Hips\n{ this is not a skeleton").unwrap();
        let work = Work { dir };
        let out = work.kg(&["plan", "to_glb.ron", "--input", "clip=clips/*.bvh", "--out", "plans/plan.json"]);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        work
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    fn kg(&self, args: &[&str]) -> Output {
        kg(self.path(), args)
    }

    fn run_task(&self, index: usize) -> Output {
        self.kg(&["run", "--plan", "plans/plan.json", "--task-index", &index.to_string(), "--out", "out"])
    }

    fn report(&self, id: &str) -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(self.path().join(format!("out/reports/{id}.json"))).unwrap()).unwrap()
    }
}

#[test]
fn planning_twice_gives_identical_bytes_with_hashes_outputs_and_relative_paths() {
    let work = Work::new();
    let again = work.kg(&["plan", "to_glb.ron", "--input", "clip=clips/*.bvh", "--out", "plans/again.json"]);
    assert_eq!(again.status.code(), Some(0), "{}", stderr(&again));
    let first = std::fs::read(work.path().join("plans/plan.json")).unwrap();
    assert_eq!(first, std::fs::read(work.path().join("plans/again.json")).unwrap());

    let plan = Plan::read(&work.path().join("plans/plan.json")).unwrap();
    assert_eq!(plan.graph.path, "../to_glb.ron");
    assert_eq!(plan.graph.sha256, farm::plan::sha256_file(Path::new(GRAPH)).unwrap());
    let ids: Vec<&str> = plan.tasks.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["a", "b", "broken"]);
    let clip_hash = farm::plan::sha256_file(Path::new(CLIP)).unwrap();
    let a = &plan.tasks[0];
    assert_eq!(a.inputs["clip"].path, "../clips/a.bvh");
    assert_eq!(a.inputs["clip"].sha256, clip_hash);
    assert_eq!(a.outputs, ["a/clip.glb"]);
    // Keys are sorted at every level, and nothing depends on when or where it was made.
    let text = String::from_utf8(first).unwrap();
    assert!(text.find("\"after\"").unwrap() < text.find("\"format\"").unwrap());
    assert!(!text.contains(work.path().to_str().unwrap()));
}

#[test]
fn without_input_globs_a_plan_has_one_task_and_set_files_are_hashed() {
    let work = Work::new();
    let out = work.kg(&[
        "plan",
        "to_glb.ron",
        "--set",
        "clip=clips/b.bvh",
        "--set",
        "glb.file=walk.glb",
        "--out",
        "one.json",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let plan = Plan::read(&work.path().join("one.json")).unwrap();
    assert_eq!(plan.tasks.len(), 1);
    let task = &plan.tasks[0];
    assert_eq!(task.id, "to_glb");
    assert_eq!(task.inputs["clip"].path, "clips/b.bvh");
    assert_eq!(task.inputs["clip"].sha256, farm::plan::sha256_file(Path::new(CLIP)).unwrap());
    assert_eq!(task.set["glb.file"], "walk.glb");
    assert_eq!(task.outputs, ["to_glb/walk.glb"]);
    let ran = work.kg(&["run", "to_glb.ron", "--plan", "one.json", "--task-index", "0", "--out", "o"]);
    assert_eq!(ran.status.code(), Some(0), "{}", stderr(&ran));
    assert!(work.path().join("o/to_glb/walk.glb").is_file());
}

#[test]
fn a_retry_of_a_finished_task_does_no_work_and_says_so() {
    let work = Work::new();
    let first = work.run_task(0);
    assert_eq!(first.status.code(), Some(0), "{}", stderr(&first));
    assert_eq!(work.report("a")["status"], "ok");
    let glb = work.path().join("out/a/clip.glb");
    let old = SystemTime::now() - Duration::from_secs(3600);
    std::fs::File::options().write(true).open(&glb).unwrap().set_modified(old).unwrap();

    let retry = work.run_task(0);
    assert_eq!(retry.status.code(), Some(0), "{}", stderr(&retry));
    assert!(stderr(&retry).contains("nothing to do"), "{}", stderr(&retry));
    assert_eq!(std::fs::metadata(&glb).unwrap().modified().unwrap(), old, "the output was not rewritten");
    let report = work.report("a");
    assert_eq!(report["status"], "skipped");
    assert_eq!(report["outputs"][0]["sha256"], farm::plan::sha256_file(&glb).unwrap());

    // An output that no longer matches its recorded hash makes the retry run again.
    std::fs::write(&glb, b"damaged").unwrap();
    let rerun = work.run_task(0);
    assert_eq!(rerun.status.code(), Some(0), "{}", stderr(&rerun));
    assert!(!stderr(&rerun).contains("nothing to do"));
    assert_eq!(work.report("a")["status"], "ok");
    assert_ne!(std::fs::read(&glb).unwrap(), b"damaged");
}

#[test]
fn a_failing_task_leaves_nothing_and_does_not_block_the_others() {
    let work = Work::new();
    // The broken clip is task 2; run it first.
    let failed = work.run_task(2);
    assert_eq!(failed.status.code(), Some(1), "{}", stderr(&failed));
    assert!(stderr(&failed).contains("task 2 (broken): FAILED"), "{}", stderr(&failed));
    for index in [0, 1] {
        let ok = work.run_task(index);
        assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
    }
    let mut left: Vec<String> = std::fs::read_dir(work.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["a", "b", "reports"], "no folder (or staging folder) of the failed task survives");
    let report = work.report("broken");
    assert_eq!(report["status"], "failed");
    assert_eq!(report["exit_code"], 1);
    assert_eq!(report["outputs"], serde_json::json!([]));
    assert!(report["error"].as_str().unwrap().starts_with("load: "), "{report}");

    let merged = work.kg(&["merge", "plans/plan.json", "--out", "out", "--json"]);
    assert_eq!(merged.status.code(), Some(1), "a failed task fails the merge: {}", stderr(&merged));
    let summary: serde_json::Value = serde_json::from_slice(&merged.stdout).unwrap();
    assert_eq!(summary["tasks"], 3);
    assert_eq!(
        summary["counts"],
        serde_json::json!({"cancelled": 0, "failed": 1, "invalid": 0, "missing": 0, "ok": 2, "skipped": 0})
    );
    let statuses: Vec<&str> =
        summary["per_task"].as_array().unwrap().iter().map(|t| t["status"].as_str().unwrap()).collect();
    assert_eq!(statuses, ["ok", "ok", "failed"]);
    // Merging is deterministic: the same reports give the same summary file.
    let saved = std::fs::read(work.path().join("out/summary.json")).unwrap();
    assert_eq!(saved, merged.stdout);
    work.kg(&["merge", "plans/plan.json", "--out", "out"]);
    assert_eq!(std::fs::read(work.path().join("out/summary.json")).unwrap(), saved);
}

#[test]
fn an_input_or_graph_changed_since_planning_is_refused_with_exit_2() {
    let work = Work::new();
    // One more blank line at the end: the same clip to a parser, another file to a hash.
    std::fs::OpenOptions::new().append(true).open(work.path().join("clips/a.bvh")).unwrap().write_all(b"\n").unwrap();
    let refused = work.run_task(0);
    assert_eq!(refused.status.code(), Some(2));
    let err = stderr(&refused);
    assert!(
        err.contains("plans/plan.json: task 0 (a): input 'clip'") && err.contains("changed since planning"),
        "{err}"
    );
    assert!(!work.path().join("out/a").exists());

    let graph = work.path().join("to_glb.ron");
    std::fs::write(&graph, std::fs::read_to_string(&graph).unwrap().replace("clip.glb", "other.glb")).unwrap();
    let refused = work.run_task(1);
    assert_eq!(refused.status.code(), Some(2));
    assert!(stderr(&refused).contains("to_glb.ron changed since planning"), "{}", stderr(&refused));
}

#[test]
fn a_plan_fed_by_another_plans_outputs_depends_on_its_tasks() {
    let work = Work::new();
    std::fs::copy(DOWNSTREAM_GRAPH, work.path().join("to_bvh.ron")).unwrap();
    let planned = work.kg(&[
        "plan",
        "to_bvh.ron",
        "--input",
        "clip=@plans/plan.json",
        "--upstream-out",
        "out",
        "--out",
        "plans/down.json",
    ]);
    assert_eq!(planned.status.code(), Some(0), "{}", stderr(&planned));
    let down = Plan::read(&work.path().join("plans/down.json")).unwrap();
    assert_eq!(down.after, ["plan.json"]);
    let ids: Vec<&str> = down.tasks.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["a-clip", "b-clip", "broken-clip"]);
    let a = &down.tasks[0];
    assert_eq!(a.inputs["clip"].path, "../out/a/clip.glb");
    assert_eq!(a.inputs["clip"].sha256, "", "not made yet, so no hash");
    assert_eq!(a.depends_on, [farm::Dependency { plan: "plan.json".into(), task: "a".into(), index: 0 }]);
    assert_eq!(a.outputs, ["a-clip/clip.bvh"]);

    let run_down =
        |index: &str| work.kg(&["run", "--plan", "plans/down.json", "--task-index", index, "--out", "out-down"]);
    // Before its upstream task ran, the input is missing: invalid, with the reason.
    let early = run_down("0");
    assert_eq!(early.status.code(), Some(2));
    assert!(stderr(&early).contains("made by task 0 (a) of plan.json: has it finished?"), "{}", stderr(&early));
    assert_eq!(work.run_task(0).status.code(), Some(0));
    let late = run_down("0");
    assert_eq!(late.status.code(), Some(0), "{}", stderr(&late));
    assert!(work.path().join("out-down/a-clip/clip.bvh").is_file());
    // The report records the hash the input had when it was read.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(work.path().join("out-down/reports/a-clip.json")).unwrap()).unwrap();
    let glb_hash = farm::plan::sha256_file(&work.path().join("out/a/clip.glb")).unwrap();
    assert_eq!(report["inputs"]["clip"], glb_hash);
    let emitted = work.kg(&["emit", "slurm", "plans/down.json"]);
    assert!(String::from_utf8_lossy(&emitted.stdout).contains("--dependency=afterok:UPSTREAM_JOB_ID"));
}

#[test]
fn a_sweep_plans_one_task_per_value_and_each_task_runs_with_its_value() {
    let work = Work::new();
    // Two clips × metres_per_unit 0.01, 0.02, 0.03 (the first --input slowest, the sweep fastest).
    let out = work.kg(&[
        "plan",
        "to_glb.ron",
        "--input",
        "clip=clips/[ab].bvh",
        "--sweep",
        "load.metres_per_unit=0.01:0.03:3",
        "--out",
        "sweep.json",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let plan = Plan::read(&work.path().join("sweep.json")).unwrap();
    let ids: Vec<&str> = plan.tasks.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(
        ids,
        [
            "a+load.metres_per_unit=0.01",
            "a+load.metres_per_unit=0.02",
            "a+load.metres_per_unit=0.03",
            "b+load.metres_per_unit=0.01",
            "b+load.metres_per_unit=0.02",
            "b+load.metres_per_unit=0.03",
        ]
    );
    assert_eq!(plan.tasks[4].set["load.metres_per_unit"], "0.02");
    assert_eq!(plan.tasks[4].outputs, ["b+load.metres_per_unit=0.02/clip.glb"]);
    // Each task runs with its own value: the same clip at 0.01 and at 0.02 m per unit gives
    // GLBs whose root travels twice as far (read back by the GLB loader).
    let travel = |index: usize| {
        let ran = work.kg(&["run", "--plan", "sweep.json", "--task-index", &index.to_string(), "--out", "o"]);
        assert_eq!(ran.status.code(), Some(0), "{}", stderr(&ran));
        let glb = work.path().join("o").join(&plan.tasks[index].outputs[0]);
        let clip = kinegraph_nodes::kernels::load::load_clip(&glb, Default::default()).unwrap().value;
        let roots: Vec<glam::Vec3> = clip.root_translations().collect();
        (roots[roots.len() - 1] - roots[0]).length()
    };
    let (single, double) = (travel(3), travel(4));
    assert!(single > 0.0 && (double / single - 2.0).abs() < 1e-3, "{single} m vs {double} m");
    // Names and values are checked at planning time, each error naming the setting.
    let out = work.kg(&["plan", "to_glb.ron", "--sweep", "nope=0:1:2", "--out", "p.json"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--sweep nope"), "{}", stderr(&out));
    let out = work.kg(&["plan", "to_glb.ron", "--sweep", "load.metres_per_unit=-1:1:3", "--out", "p.json"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("load.metres_per_unit"), "{}", stderr(&out));
    let out = work.kg(&["plan", "to_glb.ron", "--sweep", "load.metres_per_unit=1:2", "--out", "p.json"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("NAME=START:END:COUNT"), "{}", stderr(&out));
}

#[test]
fn bad_task_indices_plans_and_globs_are_refused_with_exit_2() {
    let work = Work::new();
    let out = work.run_task(3);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("--task-index 3 is out of range: the plan has 3 tasks"), "{}", stderr(&out));
    let out = work.kg(&["run", "clips/a.bvh", "--plan", "plans/plan.json", "--task-index", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("plans/plan.json: the plan is of graph"), "{}", stderr(&out));
    let out = work.kg(&["run", "--plan", "plans/plan.json", "--task-index", "0", "--set", "clip=x.bvh"]);
    assert_eq!(out.status.code(), Some(2), "a plan fixes every parameter: {}", stderr(&out));
    let out = work.kg(&["run", "--plan", "to_glb.ron", "--task-index", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("to_glb.ron: not JSON"), "{}", stderr(&out));
    let out = work.kg(&["plan", "to_glb.ron", "--input", "clip=nothing/*.bvh", "--out", "p.json"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("no files match"), "{}", stderr(&out));
    let out = work.kg(&["plan", "to_glb.ron", "--input", "nope=clips/*.bvh", "--out", "p.json"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("'nope' is neither a graph input"), "{}", stderr(&out));
}

#[test]
fn emit_writes_a_submission_file_for_every_engine() {
    let work = Work::new();
    for (target, needle) in [
        ("slurm", "\"$SLURM_ARRAY_TASK_ID\""),
        ("k8s", "$JOB_COMPLETION_INDEX"),
        ("openjd", "{{Task.Param.TaskIndex}}"),
        ("opencue", "#IFRAME#"),
    ] {
        let file = format!("job.{target}");
        let out = work.kg(&["emit", target, "plans/plan.json", "--out", &file, "--cores", "2", "--memory-mib", "2048"]);
        assert_eq!(out.status.code(), Some(0), "{target}: {}", stderr(&out));
        let text = std::fs::read_to_string(work.path().join(&file)).unwrap();
        assert!(text.contains(needle), "{target}: {text}");
        let plan_path = work.path().join("plans/plan.json").canonicalize().unwrap();
        assert!(text.contains(plan_path.to_str().unwrap()), "{target}: absolute plan path in {text}");
    }
}

/// A fixed plan and options, so the snapshots do not depend on where the test runs.
fn snapshot_plan() -> (Plan, EmitOptions) {
    let task = |index: usize, id: &str| farm::Task {
        index,
        id: id.into(),
        inputs: [(
            "clip".to_string(),
            farm::HashedFile { path: format!("../clips/{id}.bvh"), sha256: format!("{index:064}"), size: None },
        )]
        .into_iter()
        .collect(),
        set: Default::default(),
        outputs: vec![format!("{id}/clip.glb")],
        depends_on: Vec::new(),
    };
    let plan = Plan {
        format: farm::plan::PLAN_FORMAT.into(),
        version: farm::plan::PLAN_VERSION,
        graph: farm::HashedFile { path: "../to_glb.ron".into(), sha256: "ab".repeat(32), size: None },
        after: Vec::new(),
        tasks: vec![task(0, "01_01"), task(1, "02_01"), task(2, "walk's end")],
    };
    let options = EmitOptions {
        kg: "/opt/kinegraph/bin/kg".into(),
        plan: "/studio/jobs/retarget/plans/plan.json".into(),
        out: "/studio/jobs/retarget/out".into(),
        workdir: "/studio/jobs/retarget".into(),
        name: "kg-to_glb".into(),
        cores: 4,
        memory_mib: Some(8192),
        max_parallel: Some(2),
        retries: 2,
        image: "registry.example/kinegraph:0.1".into(),
        volume_claim: "studio-jobs".into(),
        show: "demo".into(),
        shot: "retarget".into(),
        user: "pipeline".into(),
    };
    (plan, options)
}

#[test]
fn emitter_snapshots() {
    let (plan, options) = snapshot_plan();
    for (target, name) in
        [(Target::Slurm, "slurm"), (Target::K8s, "k8s"), (Target::OpenJd, "openjd"), (Target::OpenCue, "opencue")]
    {
        insta::assert_snapshot!(format!("emit_{name}"), farm::emit(target, &plan, &options).unwrap());
    }
}

#[test]
fn an_empty_plan_emits_nothing() {
    let (mut plan, options) = snapshot_plan();
    plan.tasks.clear();
    assert_eq!(farm::emit(Target::Slurm, &plan, &options).unwrap_err(), "the plan has no tasks");
}

/// `which`-style lookup of an executable on PATH.
fn on_path(name: &str) -> Option<PathBuf> {
    std::env::var_os("PATH")?.to_str()?.split(':').map(|d| Path::new(d).join(name)).find(|p| p.is_file())
}

/// A real engine's run of the whole BVH corpus (linked in as `clips/corpus`) beside the
/// work folder's own clips, one of them broken: plan, emit, `run` the engine on the
/// submission file, merge. Every good clip converts, the broken one fails alone, and a
/// retry of a finished task does nothing.
fn real_engine_run(flag: &str, tool: &str, target: &str, run: impl FnOnce(&Path, &Path) -> Output) {
    if std::env::var_os(flag).is_none() {
        eprintln!("skipping: set {flag}=1 to run this on a real {target} engine");
        return;
    }
    assert!(on_path(tool).is_some(), "{flag} is set but `{tool}` is not on PATH");
    let Some(data) = kinegraph::nodes::corpus::shared_data() else { return };
    let work = Work::new();
    std::os::unix::fs::symlink(data.join("bvh"), work.path().join("clips/corpus")).unwrap();
    let planned = work.kg(&["plan", "to_glb.ron", "--input", "clip=clips/**/*.bvh", "--out", "plans/plan.json"]);
    assert_eq!(planned.status.code(), Some(0), "{}", stderr(&planned));
    let file = work.path().join(format!("job.{target}"));
    let emitted = work.kg(&["emit", target, "plans/plan.json", "--out", file.to_str().unwrap(), "--cores", "1"]);
    assert_eq!(emitted.status.code(), Some(0), "{}", stderr(&emitted));
    let ran = run(work.path(), &file);
    eprintln!("{}\n{}", String::from_utf8_lossy(&ran.stdout), stderr(&ran));
    let merged = work.kg(&["merge", "plans/plan.json", "--out", "out", "--json"]);
    let summary: serde_json::Value = serde_json::from_slice(&merged.stdout).unwrap();
    // Every good clip converted; the broken one failed without stopping them.
    assert_eq!(summary["counts"]["ok"], summary["tasks"].as_u64().unwrap() - 1, "{summary}");
    assert_eq!(summary["counts"]["failed"], 1, "{summary}");
    // A retry of a finished task does nothing.
    let retry = work.run_task(0);
    assert!(stderr(&retry).contains("nothing to do"), "{}", stderr(&retry));
}

#[test]
fn openjd_runs_the_emitted_template_for_real() {
    real_engine_run("KG_OPENJD", "openjd", "openjd", |dir, file| {
        let check = Command::new("openjd").args(["check"]).arg(file).output().unwrap();
        assert!(check.status.success(), "openjd check: {}", String::from_utf8_lossy(&check.stdout));
        // `openjd run` runs a job in one local session, which stops at the first failed
        // task; a farm runs each task on its own, so run one session per task.
        let tasks = Plan::read(&dir.join("plans/plan.json")).unwrap().tasks.len();
        let mut last = None;
        for index in 0..tasks {
            let session = Command::new("openjd")
                .arg("run")
                .arg(file)
                .args(["--task-param", &format!("TaskIndex={index}")])
                .current_dir(dir)
                .output()
                .unwrap();
            last = Some(session);
        }
        last.unwrap()
    });
}

#[test]
fn slurm_runs_the_emitted_array_for_real() {
    real_engine_run("KG_SLURM", "sbatch", "slurm", |dir, file| {
        Command::new("sbatch").arg("--wait").arg(file).current_dir(dir).output().unwrap()
    });
}

/// The image farm submissions name, built from `Containerfile` and running one planned task
/// (opt-in: `KG_CONTAINER=1`; `KG_CONTAINER_ENGINE` picks the engine, podman by default).
/// The task's output inside the container must be the bytes the host's kg writes.
#[test]
fn the_container_image_runs_a_planned_task_like_the_host() {
    if std::env::var_os("KG_CONTAINER").is_none() {
        eprintln!("skipping: set KG_CONTAINER=1 (and have podman or docker) to build the image and run a task in it");
        return;
    }
    let engine = std::env::var("KG_CONTAINER_ENGINE").unwrap_or_else(|_| "podman".into());
    assert!(on_path(&engine).is_some(), "KG_CONTAINER is set but `{engine}` is not on PATH");
    let tag = "kinegraph:test";
    let built = Command::new(&engine)
        .args(["build", "-t", tag, "-f", "Containerfile", "."])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(built.status.success(), "{engine} build: {}", stderr(&built));
    let work = Work::new();
    let mount = format!("{}:/work", work.path().display());
    let ran = Command::new(&engine)
        .args(["run", "--rm", "--user", "0", "-v", &mount, "-w", "/work", tag])
        .args(["kg", "run", "--plan", "plans/plan.json", "--task-index", "0", "--out", "in_container"])
        .output()
        .unwrap();
    assert_eq!(ran.status.code(), Some(0), "{engine} run: {}", stderr(&ran));
    let host = work.kg(&["run", "--plan", "plans/plan.json", "--task-index", "0", "--out", "on_host"]);
    assert_eq!(host.status.code(), Some(0), "{}", stderr(&host));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(work.path().join("in_container/reports/a.json")).unwrap()).unwrap();
    assert_eq!(report["status"], "ok", "{report:#}");
    let inside = std::fs::read(work.path().join("in_container/a/clip.glb")).unwrap();
    let outside = std::fs::read(work.path().join("on_host/a/clip.glb")).unwrap();
    assert!(inside == outside, "a/clip.glb differs between the container and the host");
}
