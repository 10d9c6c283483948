//! Planning a farm run: one task per binding of the graph's inputs to files (the
//! cartesian product of the `--input` globs, or an upstream plan's outputs) and per point of
//! the `--sweep` parameter grid, each with the content hashes that make a retry idempotent
//! and the files it will write.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use kinegraph_nodes::node::Registry;

use super::inputs::{expand_glob, run_folder_names};
use super::plan::{PLAN_FORMAT, PLAN_VERSION, plan_dir, relative_to, sha256_file};
use super::sweep::Sweep;
use super::{Dependency, HashedFile, Plan, Task};
use crate::engine::compile_file;
use crate::graph::{GraphFile, Overrides, Setting, is_input_file};
use crate::output::safe_unique_names;

/// Most tasks the sweeps may make per input binding.
pub const MAX_TASKS: usize = 100_000;

/// A file bound to a graph input, and the upstream task that makes it, if any.
#[derive(Clone)]
struct BoundFile {
    name: String,
    path: PathBuf,
    from: Option<Dependency>,
}

/// One task's input files, one per `--input`, with the labels that make its id.
#[derive(Clone, Default)]
struct Binding {
    labels: Vec<String>,
    files: Vec<BoundFile>,
}

/// The files one `--input` takes: the glob's matches, or with `NAME=@PLAN` every output
/// of that upstream plan's tasks, found under `upstream_out` (its run's output root).
fn candidates(input: &Setting, upstream_out: &Path, base: &Path) -> Result<Vec<(PathBuf, Option<Dependency>)>, String> {
    let Some(upstream) = input.value.strip_prefix('@') else {
        return Ok(expand_glob(input)?.into_iter().map(|f| (f, None)).collect());
    };
    let plan = Plan::read(Path::new(upstream)).map_err(|e| format!("--input {}={}: {e}", input.name, input.value))?;
    let plan_path = relative_to(Path::new(upstream), base);
    let files: Vec<(PathBuf, Option<Dependency>)> = plan
        .tasks
        .iter()
        .flat_map(|task| {
            let from = Dependency { plan: plan_path.clone(), task: task.id.clone(), index: task.index };
            task.outputs.iter().map(move |o| (upstream_out.join(o), Some(from.clone())))
        })
        .collect();
    if files.is_empty() {
        return Err(format!("--input {}={}: the upstream plan makes no files", input.name, input.value));
    }
    Ok(files)
}

/// The tasks' input bindings: the cartesian product of the `--input` files, in order (the
/// first `--input` varies slowest).
fn bindings(inputs: &[Setting], upstream_out: &Path, base: &Path) -> Result<Vec<Binding>, String> {
    let mut product = vec![Binding::default()];
    for input in inputs {
        let files = candidates(input, upstream_out, base)?;
        let paths: Vec<PathBuf> = files.iter().map(|(p, _)| p.clone()).collect();
        let labels = run_folder_names(&paths);
        product = product
            .into_iter()
            .flat_map(|partial| {
                labels.iter().zip(&files).map(move |(label, (path, from))| {
                    let mut next = partial.clone();
                    next.labels.push(label.clone());
                    next.files.push(BoundFile { name: input.name.clone(), path: path.clone(), from: from.clone() });
                    next
                })
            })
            .collect();
    }
    Ok(product)
}

/// One point of the `--sweep` grid: its labels (`NAME=VALUE` per sweep) and settings.
type SweepPoint = (Vec<String>, Vec<Setting>);

/// The points of the `--sweep` grid: every combination of the sweeps' values, the first
/// sweep varying slowest.
fn sweep_points(sweeps: &[Sweep]) -> Vec<SweepPoint> {
    let mut product = vec![(Vec::new(), Vec::new())];
    for sweep in sweeps {
        let values = sweep.values();
        product = product
            .into_iter()
            .flat_map(|partial: SweepPoint| {
                values.iter().map(move |v| {
                    let (mut labels, mut settings) = partial.clone();
                    labels.push(format!("{}={v}", sweep.names.join(",")));
                    settings.extend(sweep.names.iter().map(|n| Setting { name: n.clone(), value: v.clone() }));
                    (labels, settings)
                })
            })
            .collect();
    }
    product
}

/// A file for the plan: an absolute path as given, a relative one (typed relative to the
/// current folder) made relative to the plan's folder.
fn plan_path_of(file: &Path, base: &Path) -> String {
    if file.is_absolute() { file.to_string_lossy().into_owned() } else { relative_to(file, base) }
}

/// A file for the plan and its hash.
fn hashed(file: &Path, base: &Path) -> Result<HashedFile, String> {
    Ok(HashedFile { path: plan_path_of(file, base), sha256: sha256_file(file).map_err(|e| e.to_string())?, size: None })
}

/// Builds the plan of `graph` over the `--input` bindings and the `--sweep` grid, for a plan
/// file at `plan_path`; `upstream_out` is where the tasks of an upstream plan
/// (`--input NAME=@PLAN`) write.
pub fn make_plan(
    graph: &Path,
    inputs: &[Setting],
    sweeps: &[Sweep],
    settings: &[Setting],
    upstream_out: &Path,
    plan_path: &Path,
    registry: &Registry,
) -> Result<Plan, String> {
    let loaded = GraphFile::load_with(graph, &[], registry)?;
    for input in inputs {
        loaded.graph.resolve(&input.name).map_err(|e| format!("{}: --input {}: {e}", graph.display(), input.name))?;
    }
    for name in sweeps.iter().flat_map(|s| &s.names) {
        loaded.graph.resolve(name).map_err(|e| format!("{}: --sweep {name}: {e}", graph.display()))?;
    }
    let point_count = sweeps.iter().fold(1usize, |n, s| n.saturating_mul(s.count));
    if point_count > MAX_TASKS {
        return Err(format!(
            "{}: the sweeps make {point_count} tasks per input binding, more than {MAX_TASKS}",
            graph.display()
        ));
    }
    let points = sweep_points(sweeps);
    let base = plan_dir(plan_path);
    let mut file_settings: BTreeMap<String, HashedFile> = BTreeMap::new();
    let mut set: BTreeMap<String, String> = BTreeMap::new();
    for s in settings {
        let is_file = loaded
            .graph
            .resolve(&s.name)
            .and_then(|path| is_input_file(&loaded.graph, registry, &path))
            .map_err(|e| format!("{}: --set {}: {e}", graph.display(), s.name))?;
        if is_file {
            file_settings.insert(s.name.clone(), hashed(Path::new(&s.value), &base)?);
        } else {
            set.insert(s.name.clone(), s.value.clone());
        }
    }
    let graph_name = graph.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "graph".into());
    // Every binding at every sweep point, the sweeps varying fastest.
    let runs: Vec<(Binding, SweepPoint)> = bindings(inputs, upstream_out, &base)?
        .into_iter()
        .flat_map(|b| points.iter().map(move |p| (b.clone(), p.clone())))
        .collect();
    let raw_ids: Vec<String> = runs
        .iter()
        .map(|(b, (point_labels, _))| {
            let labels: Vec<String> = b.labels.iter().chain(point_labels).cloned().collect();
            if labels.is_empty() { graph_name.clone() } else { labels.join("+") }
        })
        .collect();
    let mut tasks = Vec::new();
    for ((index, (binding, (_, point))), id) in runs.into_iter().enumerate().zip(safe_unique_names(&raw_ids)) {
        let mut task_inputs = file_settings.clone();
        let mut depends_on = Vec::new();
        for file in &binding.files {
            let entry = match &file.from {
                // Not made yet: no hash; the task waits for the one that makes it.
                Some(from) => {
                    depends_on.push(from.clone());
                    HashedFile { path: plan_path_of(&file.path, &base), sha256: String::new(), size: None }
                }
                None => hashed(&file.path, &base)?,
            };
            task_inputs.insert(file.name.clone(), entry);
        }
        depends_on.sort();
        depends_on.dedup();
        let all: Vec<Setting> = settings
            .iter()
            .cloned()
            .chain(
                binding.files.iter().map(|f| Setting { name: f.name.clone(), value: f.path.to_string_lossy().into() }),
            )
            .chain(point.iter().cloned())
            .collect();
        let outputs = expected_outputs(&loaded, &all, registry)?.into_iter().map(|f| format!("{id}/{f}")).collect();
        let mut task_set = set.clone();
        task_set.extend(point.into_iter().map(|s| (s.name, s.value)));
        tasks.push(Task { index, id, inputs: task_inputs, set: task_set, outputs, depends_on });
    }
    let mut after: Vec<String> = tasks.iter().flat_map(|t| t.depends_on.iter().map(|d| d.plan.clone())).collect();
    after.sort();
    after.dedup();
    Ok(Plan { format: PLAN_FORMAT.into(), version: PLAN_VERSION, graph: hashed(graph, &base)?, after, tasks })
}

/// The files a run of the graph with `settings` writes, relative to its output folder,
/// sorted; a validation error of the graph is returned as its printed text.
fn expected_outputs(loaded: &GraphFile, settings: &[Setting], registry: &Registry) -> Result<Vec<String>, String> {
    let mut file = loaded.clone();
    Overrides(settings.to_vec())
        .apply(&mut file.graph, registry)
        .map_err(|e| format!("{}: --set {e}", loaded.path.display()))?;
    let compiled = compile_file(&file, registry).map_err(|e| e.to_string())?;
    let mut files: Vec<String> =
        compiled.output_files().iter().map(|o| o.file.to_string_lossy().replace('\\', "/")).collect();
    files.sort();
    Ok(files)
}
