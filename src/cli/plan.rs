//! `kg plan`: one task per input binding, with content hashes, written as a plan file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use kinegraph_nodes::node::Registry;

use super::batch::{expand_glob, run_folder_names};
use super::run::{Setting, apply_settings, load_graph, names_input_file};
use super::{EXIT_INVALID, save_file};
use crate::document::LoadedGraph;
use crate::engine::compile;
use crate::farm::plan::{PLAN_FORMAT, PLAN_VERSION, plan_dir, relative_to, sha256_file};
use crate::farm::{HashedFile, Plan, Task};

/// One task's input files: (graph input or `node.param`, file) per `--input`, with the
/// labels that make its id.
#[derive(Clone, Default)]
struct Binding {
    labels: Vec<String>,
    files: Vec<(String, PathBuf)>,
}

impl Binding {
    fn id(&self) -> String {
        self.labels.join("+")
    }
}

/// The tasks' input bindings: the cartesian product of the `--input` globs' files, in
/// order (the first `--input` varies slowest).
fn bindings(inputs: &[Setting]) -> Result<Vec<Binding>, String> {
    let mut product = vec![Binding::default()];
    for input in inputs {
        let files = expand_glob(input)?;
        let labels = run_folder_names(&files);
        product = product
            .into_iter()
            .flat_map(|partial| {
                labels.iter().zip(&files).map(move |(label, file)| {
                    let mut next = partial.clone();
                    next.labels.push(label.clone());
                    next.files.push((input.name.clone(), file.clone()));
                    next
                })
            })
            .collect();
    }
    Ok(product)
}

/// A file for the plan and its hash: an absolute path as given, a relative one (typed
/// relative to the current folder) made relative to the plan's folder.
fn hashed(file: &Path, base: &Path) -> Result<HashedFile, String> {
    let path = if file.is_absolute() { file.to_string_lossy().into_owned() } else { relative_to(file, base) };
    Ok(HashedFile { path, sha256: sha256_file(file).map_err(|e| e.to_string())? })
}

/// Builds the plan of `graph` over the `--input` bindings, for a plan file at `plan_path`.
pub fn make_plan(
    graph: &Path,
    inputs: &[Setting],
    settings: &[Setting],
    plan_path: &Path,
    registry: &Registry,
) -> Result<Plan, String> {
    let loaded = load_graph(graph, &[], registry)?;
    for input in inputs {
        loaded.doc.resolve_setting(&input.name).map_err(|e| format!("{}: --input: {e}", graph.display()))?;
    }
    let base = plan_dir(plan_path);
    let mut file_settings: BTreeMap<String, HashedFile> = BTreeMap::new();
    let mut set: BTreeMap<String, String> = BTreeMap::new();
    for s in settings {
        if names_input_file(&loaded.doc, &s.name, registry).map_err(|e| format!("{}: --set: {e}", graph.display()))? {
            file_settings.insert(s.name.clone(), hashed(Path::new(&s.value), &base)?);
        } else {
            set.insert(s.name.clone(), s.value.clone());
        }
    }
    let graph_name = graph.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "graph".into());
    let mut tasks = Vec::new();
    for (index, binding) in bindings(inputs)?.into_iter().enumerate() {
        let id = if binding.labels.is_empty() { graph_name.clone() } else { binding.id() };
        let mut task_inputs = file_settings.clone();
        for (name, file) in &binding.files {
            task_inputs.insert(name.clone(), hashed(file, &base)?);
        }
        let all: Vec<Setting> = settings
            .iter()
            .cloned()
            .chain(
                binding
                    .files
                    .iter()
                    .map(|(name, file)| Setting { name: name.clone(), value: file.to_string_lossy().into() }),
            )
            .collect();
        let outputs = expected_outputs(&loaded, &all, registry)?.into_iter().map(|f| format!("{id}/{f}")).collect();
        tasks.push(Task { index, id, inputs: task_inputs, set: set.clone(), outputs, depends_on: Vec::new() });
    }
    Ok(Plan {
        format: PLAN_FORMAT.into(),
        version: PLAN_VERSION,
        graph: hashed(graph, &base)?,
        after: Vec::new(),
        tasks,
    })
}

/// The files a run of the graph with `settings` writes, relative to its output folder,
/// sorted; a validation error of the graph is returned as its printed text.
fn expected_outputs(loaded: &LoadedGraph, settings: &[Setting], registry: &Registry) -> Result<Vec<String>, String> {
    let mut doc = loaded.doc.clone();
    apply_settings(&mut doc, settings, registry).map_err(|e| format!("{}: --set: {e}", loaded.path.display()))?;
    let compiled = compile(&doc, registry, &loaded.path, &loaded.source).map_err(|e| e.to_string())?;
    let mut files: Vec<String> =
        compiled.output_files().iter().map(|o| o.file.to_string_lossy().replace('\\', "/")).collect();
    files.sort();
    Ok(files)
}

pub(super) fn plan_command(graph: &Path, inputs: &[Setting], settings: &[Setting], out: &Path) -> u8 {
    let registry = Registry::builtin();
    let plan = match make_plan(graph, inputs, settings, out, &registry) {
        Ok(plan) => plan,
        Err(e) => {
            eprint!("{e}");
            if !e.ends_with('\n') {
                eprintln!();
            }
            return EXIT_INVALID;
        }
    };
    if let Err(e) = save_file(out, plan.to_json().as_bytes()) {
        eprintln!("{e}");
        return EXIT_INVALID;
    }
    eprintln!("{}: {} tasks of {}", out.display(), plan.tasks.len(), graph.display());
    0
}
