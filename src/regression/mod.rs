//! Saved graphs as regression tests (`kg test`). Each `graphs/NAME.ron` runs into a
//! temporary folder and the facts of every node output are compared with
//! `graphs/NAME.expect.ron`: counts and hashes exactly, real numbers within the file's
//! relative tolerance. `--bless` rewrites the expectations from the current results.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use kinegraph_nodes::kernels::quality::QualityGate;
use kinegraph_nodes::model::forward_kinematics;
use kinegraph_nodes::node::Value;
use serde::{Deserialize, Serialize};

pub mod quality_gates;

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use self::quality_gates::gate_violations;
use crate::engine::{Engine, RunOptions, RunReport, compile_file};
use crate::graph::GraphFile;

/// Checkable facts about one output value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Facts {
    /// A clip.
    Clip {
        /// Frame count (exact).
        frames: usize,
        /// Joint count, end sites included (exact).
        joints: usize,
        /// Frames per second.
        fps: f64,
        /// Length, seconds.
        duration_secs: f64,
        /// Path length of the root over the clip, metres.
        root_travel_m: f64,
        /// Mean world height of all joints over all frames (FK), metres.
        mean_joint_height_m: f64,
    },
    /// A mesh.
    Mesh {
        /// Vertex count (exact).
        vertices: usize,
        /// Triangle count (exact).
        triangles: usize,
        /// Whether it is skinned (exact).
        skinned: bool,
        /// Bounding-box size, metres.
        extent_m: [f64; 3],
    },
    /// A number.
    Scalar(f64),
    /// A deformed mesh per frame.
    MeshSequence {
        /// Frame count (exact).
        frames: usize,
        /// Vertices per frame (exact).
        vertices: usize,
        /// Bounding-box size over all frames, metres.
        extent_m: [f64; 3],
        /// Mean distance of a vertex from its rest position over all frames, metres.
        mean_displacement_m: f64,
    },
    /// A bar-net.
    BarNet {
        /// Node count (exact).
        nodes: usize,
        /// Free node count (exact).
        free: usize,
        /// Bar count (exact).
        bars: usize,
        /// Sum of the bars' force densities, N/m.
        total_force_density: f64,
    },
    /// A written file: size and SHA-256 (exact).
    File {
        /// Size in bytes.
        bytes: u64,
        /// Hex SHA-256 of the content.
        sha256: String,
    },
    /// Structured data (curves summaries, phases, contacts, reports): whole numbers and
    /// text compared exactly, reals within tolerance.
    Data(serde_json::Value),
}

/// A graph's stored expectations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Expectation {
    /// Relative tolerance for real numbers (absolute below magnitude 1).
    pub tolerance: f64,
    /// Files or folders outside the repository the graph reads (relative to the graph's
    /// folder, e.g. the shared motion corpus). When one is missing the graph is skipped
    /// with a message, or fails when the `CI` environment variable is set.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub requires: Vec<String>,
    /// Limits on the reports of `motion.quality` nodes, by node id (see
    /// [`quality_gates`]); a run beyond one fails, blessed or not.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub quality: BTreeMap<String, QualityGate>,
    /// Facts per `node.port`.
    pub outputs: BTreeMap<String, Facts>,
}

/// Facts of a value; files are read from `out_dir`.
pub fn facts_of(value: &Value, out_dir: &Path) -> Facts {
    match value {
        Value::Clip(clip) => {
            let poses = forward_kinematics(clip);
            let samples = (clip.frame_count() * clip.joint_count()).max(1) as f64;
            let height_sum: f64 =
                (0..clip.frame_count()).flat_map(|f| poses.frame(f).iter().map(|t| f64::from(t.translation.y))).sum();
            let roots: Vec<_> = clip.root_translations().collect();
            let travel: f64 = roots.windows(2).map(|w| f64::from((w[1] - w[0]).length())).sum();
            Facts::Clip {
                frames: clip.frame_count(),
                joints: clip.joint_count(),
                fps: clip.fps(),
                duration_secs: clip.duration_secs(),
                root_travel_m: travel,
                mean_joint_height_m: height_sum / samples,
            }
        }
        Value::Mesh(mesh) => {
            let extent = mesh.bounds().map(|(lo, hi)| hi - lo).unwrap_or_default();
            Facts::Mesh {
                vertices: mesh.positions.len(),
                triangles: mesh.triangles.len(),
                skinned: mesh.skin.is_some(),
                extent_m: [extent.x, extent.y, extent.z].map(f64::from),
            }
        }
        Value::Scalar(x) => Facts::Scalar(*x),
        Value::Curves(curves) => {
            let channels: serde_json::Map<String, serde_json::Value> = curves
                .channels()
                .iter()
                .map(|c| {
                    let (lo, hi) = c
                        .values
                        .iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
                    let mean = c.values.iter().sum::<f64>() / c.values.len().max(1) as f64;
                    (c.name.clone(), serde_json::json!({ "min": lo, "max": hi, "mean": mean }))
                })
                .collect();
            Facts::Data(
                serde_json::json!({ "frames": curves.frame_count(), "fps": curves.fps(), "channels": channels }),
            )
        }
        Value::Phases(phases) => Facts::Data(serde_json::to_value(phases.as_ref()).unwrap_or_default()),
        Value::Contacts(contacts) => Facts::Data(serde_json::to_value(contacts.as_ref()).unwrap_or_default()),
        Value::Report(report) => {
            // A report's "timings" (wall-clock seconds, e.g. fluid.simulate's per step) differ
            // from run to run: they are not facts.
            let mut facts = report.as_ref().clone();
            facts.remove("timings");
            Facts::Data(serde_json::Value::Object(facts))
        }
        Value::MeshSequence(seq) => {
            let all = seq.positions_m();
            let (lo, hi) = all
                .iter()
                .fold((glam::Vec3::splat(f32::INFINITY), glam::Vec3::splat(f32::NEG_INFINITY)), |(lo, hi), p| {
                    (lo.min(*p), hi.max(*p))
                });
            let extent = if all.is_empty() { glam::Vec3::ZERO } else { hi - lo };
            let rest = &seq.rest.positions;
            let moved: f64 = (0..seq.frame_count())
                .flat_map(|f| seq.frame_positions(f).iter().zip(rest).map(|(p, r)| f64::from((*p - *r).length())))
                .sum();
            Facts::MeshSequence {
                frames: seq.frame_count(),
                vertices: seq.vertex_count(),
                extent_m: [extent.x, extent.y, extent.z].map(f64::from),
                mean_displacement_m: moved / all.len().max(1) as f64,
            }
        }
        Value::BarNet(net) => Facts::BarNet {
            nodes: net.node_count(),
            free: net.free_count(),
            bars: net.bars.len(),
            total_force_density: net.force_density.iter().sum(),
        },
        Value::ClipSet(set) => Facts::Data(set.summary()),
        Value::Clusters(clusters) => Facts::Data(clusters.summary()),
        Value::TransitionGraph(graph) => Facts::Data(graph.summary()),
        Value::BoneMap(map) => Facts::Data(serde_json::to_value(&map.joints).unwrap_or_default()),
        Value::Stages(stages) => Facts::Data(serde_json::to_value(stages.as_ref()).unwrap_or_default()),
        Value::FluidDomain(domain) => Facts::Data(serde_json::to_value(domain.as_ref()).unwrap_or_default()),
        Value::VolumeSequence(volumes) => Facts::Data(volumes.summary()),
        Value::Family(family) => Facts::Data(family.summary()),
        Value::File(relative) => {
            let bytes = std::fs::read(out_dir.join(relative.as_path())).unwrap_or_default();
            Facts::File { bytes: bytes.len() as u64, sha256: crate::digest::sha256_hex(&bytes) }
        }
    }
}

/// Facts of every output of a run, by `node.port`.
pub fn run_facts(report: &RunReport, engine: &Engine, out_dir: &Path) -> BTreeMap<String, Facts> {
    let mut facts = BTreeMap::new();
    // Kinds from the report: it names every node that ran, subgraphs' inner nodes included.
    for (id, outputs) in &report.outputs {
        let kind = report.nodes.get(id).map(|n| n.kind.as_str());
        let Some(schema) = kind.and_then(|k| engine.registry().get(k)).map(|n| n.schema()) else { continue };
        for (spec, value) in schema.outputs.iter().zip(outputs) {
            if let Some(v) = value {
                facts.insert(format!("{id}.{}", spec.name), facts_of(v, out_dir));
            }
        }
    }
    facts
}

fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance * b.abs().max(1.0)
}

/// One output's field-by-field comparison: a line in `problems` per differing field.
struct FieldDiff<'a> {
    key: &'a str,
    tol: f64,
    problems: &'a mut Vec<String>,
}

impl FieldDiff<'_> {
    fn differ(&mut self, name: &str, want: String, got: String) {
        self.problems.push(format!("{}.{name}: expected {want}, got {got}", self.key));
    }

    /// Counts, flags and hashes: equal or different.
    fn exact<T: PartialEq + std::fmt::Display>(&mut self, name: &str, want: &T, got: &T) {
        if want != got {
            self.differ(name, want.to_string(), got.to_string());
        }
    }

    /// Real numbers: equal within the expectation's relative tolerance.
    fn near(&mut self, name: &str, want: f64, got: f64) {
        if !close(want, got, self.tol) {
            self.differ(name, want.to_string(), got.to_string());
        }
    }

    /// Vectors of real numbers, compared element by element.
    fn near_all(&mut self, name: &str, want: &[f64], got: &[f64]) {
        if want.len() != got.len() || want.iter().zip(got).any(|(a, b)| !close(*a, *b, self.tol)) {
            self.differ(name, format!("{want:?}"), format!("{got:?}"));
        }
    }
}

/// Differences between expected and actual facts, one line each.
pub fn compare(expected: &Expectation, actual: &BTreeMap<String, Facts>) -> Vec<String> {
    let tol = expected.tolerance;
    let mut problems = Vec::new();
    for (key, want) in &expected.outputs {
        let Some(got) = actual.get(key) else {
            problems.push(format!("{key}: expected an output, the run produced none"));
            continue;
        };
        let mut d = FieldDiff { key, tol, problems: &mut problems };
        match (want, got) {
            (
                Facts::Clip { frames, joints, fps, duration_secs, root_travel_m, mean_joint_height_m },
                Facts::Clip {
                    frames: f2,
                    joints: j2,
                    fps: fps2,
                    duration_secs: d2,
                    root_travel_m: r2,
                    mean_joint_height_m: h2,
                },
            ) => {
                d.exact("frames", frames, f2);
                d.exact("joints", joints, j2);
                d.near("fps", *fps, *fps2);
                d.near("duration_secs", *duration_secs, *d2);
                d.near("root_travel_m", *root_travel_m, *r2);
                d.near("mean_joint_height_m", *mean_joint_height_m, *h2);
            }
            (
                Facts::Mesh { vertices, triangles, skinned, extent_m },
                Facts::Mesh { vertices: v2, triangles: t2, skinned: s2, extent_m: e2 },
            ) => {
                d.exact("vertices", vertices, v2);
                d.exact("triangles", triangles, t2);
                d.exact("skinned", skinned, s2);
                d.near_all("extent_m", extent_m, e2);
            }
            (Facts::Scalar(a), Facts::Scalar(b)) => d.near("value", *a, *b),
            (
                Facts::MeshSequence { frames, vertices, extent_m, mean_displacement_m },
                Facts::MeshSequence { frames: f2, vertices: v2, extent_m: e2, mean_displacement_m: m2 },
            ) => {
                d.exact("frames", frames, f2);
                d.exact("vertices", vertices, v2);
                d.near_all("extent_m", extent_m, e2);
                d.near("mean_displacement_m", *mean_displacement_m, *m2);
            }
            (
                Facts::BarNet { nodes, free, bars, total_force_density },
                Facts::BarNet { nodes: n2, free: f2, bars: b2, total_force_density: q2 },
            ) => {
                d.exact("nodes", nodes, n2);
                d.exact("free", free, f2);
                d.exact("bars", bars, b2);
                d.near("total_force_density", *total_force_density, *q2);
            }
            (Facts::File { bytes, sha256 }, Facts::File { bytes: b2, sha256: s2 }) => {
                d.exact("bytes", bytes, b2);
                d.exact("sha256", sha256, s2);
            }
            (Facts::Data(want), Facts::Data(got)) => compare_data(key, want, got, tol, &mut problems),
            (want, got) => problems.push(format!("{key}: expected {want:?}, got {got:?}")),
        }
    }
    for key in actual.keys().filter(|k| !expected.outputs.contains_key(*k)) {
        problems.push(format!("{key}: new output not in the expectation (run kg test --bless to accept)"));
    }
    problems
}

/// Walks two JSON trees side by side, one problem line per differing leaf.
fn compare_data(path: &str, want: &serde_json::Value, got: &serde_json::Value, tol: f64, problems: &mut Vec<String>) {
    use serde_json::Value as J;
    match (want, got) {
        (J::Object(a), J::Object(b)) => {
            for key in a.keys().chain(b.keys().filter(|k| !a.contains_key(*k))) {
                match (a.get(key), b.get(key)) {
                    (Some(x), Some(y)) => compare_data(&format!("{path}.{key}"), x, y, tol, problems),
                    (Some(_), None) => problems.push(format!("{path}.{key}: expected, missing from the run")),
                    (None, _) => problems.push(format!("{path}.{key}: new in the run, not expected")),
                }
            }
        }
        (J::Array(a), J::Array(b)) if a.len() == b.len() => {
            for (i, (x, y)) in a.iter().zip(b).enumerate() {
                compare_data(&format!("{path}[{i}]"), x, y, tol, problems);
            }
        }
        (J::Number(a), J::Number(b)) if a.is_f64() || b.is_f64() => {
            let (x, y) = (a.as_f64().unwrap_or(f64::NAN), b.as_f64().unwrap_or(f64::NAN));
            if !close(x, y, tol) {
                problems.push(format!("{path}: expected {x}, got {y}"));
            }
        }
        (a, b) if a == b => {}
        (a, b) => problems.push(format!("{path}: expected {a}, got {b}")),
    }
}

/// `graphs/NAME.ron` → `graphs/NAME.expect.ron`.
pub fn expectation_path(graph: &Path) -> PathBuf {
    let stem = graph.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    graph.with_file_name(format!("{stem}.expect.ron"))
}

/// Every graph in `dir` (not expectations), sorted.
pub fn graphs_in(dir: &Path) -> Vec<PathBuf> {
    let mut graphs: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == "ron") && !p.to_string_lossy().ends_with(".expect.ron"))
                .collect()
        })
        .unwrap_or_default();
    graphs.sort();
    graphs
}

/// How one regression graph fared.
#[derive(Clone, Debug, PartialEq)]
pub enum GraphTest {
    /// Ran and matched (or was blessed).
    Passed,
    /// Not run: data it requires is absent (outside CI).
    Skipped(String),
    /// Ran and differed, or could not run; one line per problem.
    Failed(Vec<String>),
}

/// The expectation next to `graph`, if there is one (or why it cannot be read).
fn read_expectation(graph: &Path) -> Option<Result<Expectation, String>> {
    let path = expectation_path(graph);
    std::fs::read_to_string(&path)
        .ok()
        .map(|t| ron::from_str::<Expectation>(&t).map_err(|e| format!("{}:{e}", path.display())))
}

/// `text` (a path in a graph or expectation, relative to `base`) with the part up to the
/// shared corpus (`…/shared/data/`) replaced by `$KG_SHARED_DATA` when that is set, so the
/// same graphs test against a corpus kept anywhere.
pub fn corpus_path(base: &Path, text: &str) -> PathBuf {
    let corpus = std::env::var_os("KG_SHARED_DATA").filter(|v| !v.is_empty());
    let normalised = text.replace('\\', "/");
    match (corpus, normalised.find("shared/data")) {
        (Some(dir), Some(at)) => {
            let rest = normalised[at + "shared/data".len()..].trim_start_matches('/');
            PathBuf::from(dir).join(rest)
        }
        _ => base.join(text),
    }
}

/// When data the expectation requires is absent: a skip, or under CI a failure.
fn missing_data(graph: &Path, expected: &Expectation, ci: bool) -> Option<GraphTest> {
    let base = graph.parent().unwrap_or(Path::new("."));
    let missing: Vec<&str> =
        expected.requires.iter().filter(|r| !corpus_path(base, r).exists()).map(String::as_str).collect();
    if missing.is_empty() {
        return None;
    }
    let what = format!("required data not found: {}", missing.join(", "));
    Some(if ci {
        GraphTest::Failed(vec![format!("{what} (CI is set, so this fails)")])
    } else {
        GraphTest::Skipped(what)
    })
}

/// Runs one graph and compares (or blesses); setting `cancel` stops the run.
pub fn test_graph(engine: &Engine, graph: &Path, bless: bool, cancel: &Arc<AtomicBool>) -> GraphTest {
    let existing = read_expectation(graph);
    if let Some(Ok(expected)) = &existing
        && let Some(outcome) = missing_data(graph, expected, std::env::var_os("CI").is_some())
    {
        return outcome;
    }
    match run_and_compare(engine, graph, bless, existing, cancel) {
        problems if problems.is_empty() => GraphTest::Passed,
        problems => GraphTest::Failed(problems),
    }
}

fn run_and_compare(
    engine: &Engine,
    graph: &Path,
    bless: bool,
    existing: Option<Result<Expectation, String>>,
    cancel: &Arc<AtomicBool>,
) -> Vec<String> {
    let mut loaded = match GraphFile::load_with(graph, &[], engine.registry()) {
        Ok(l) => l,
        Err(e) => return vec![e],
    };
    if let Err(e) = use_corpus_dir(&mut loaded, engine.registry()) {
        return vec![e];
    }
    let out_dir = match tempfile::tempdir() {
        Ok(d) => d,
        Err(e) => return vec![format!("cannot create a temporary folder: {e}")],
    };
    let compiled = match compile_file(&loaded, engine.registry()) {
        Ok(c) => c,
        Err(e) => return vec![format!("the graph is invalid:\n{e}")],
    };
    // Every node's output is a fact, so every node is a target: none is skipped because
    // what reads it came from the cache (the engine is shared by the graphs under test).
    let mut options = RunOptions::new(loaded.base_dir());
    options.targets = Some(compiled.nodes.iter().map(|n| n.id.clone()).collect());
    options.out_dir = Some(out_dir.path().to_path_buf());
    options.cancel = cancel.clone();
    let report = engine.run(&compiled, &options);
    let mut problems: Vec<String> = report
        .nodes
        .iter()
        .filter_map(|(id, n)| n.error.as_ref().map(|e| format!("node '{id}' {:?}: {e}", n.status)))
        .collect();
    if !problems.is_empty() {
        return problems;
    }
    let actual = run_facts(&report, engine, out_dir.path());
    let path = expectation_path(graph);
    if let Some(Ok(expected)) = &existing {
        problems.extend(gate_violations(&expected.quality, &report));
    }
    if bless {
        let (tolerance, requires, quality) = match existing {
            Some(Ok(e)) => (e.tolerance, e.requires, e.quality),
            _ => (1e-5, Vec::new(), BTreeMap::new()),
        };
        let expectation = Expectation { tolerance, requires, quality, outputs: actual };
        let config = ron::ser::PrettyConfig::new().indentor("    ");
        let text = ron::ser::to_string_pretty(&expectation, config).map(|t| t + "\n").unwrap_or_default();
        if let Err(e) = kinegraph_nodes::formats::atomic::write_atomic(&path, text.as_bytes()) {
            problems.push(e.to_string());
        }
        return problems;
    }
    match existing {
        None => vec![format!("no expectation file {}: run `kg test --bless` to create it", path.display())],
        Some(Err(e)) => vec![e],
        Some(Ok(expected)) => {
            problems.extend(compare(&expected, &actual));
            problems
        }
    }
}

/// Points the graph's input files inside the shared corpus at `$KG_SHARED_DATA` (see
/// [`corpus_path`]); a no-op when it is not set.
fn use_corpus_dir(
    loaded: &mut crate::graph::GraphFile,
    registry: &kinegraph_nodes::node::Registry,
) -> Result<(), String> {
    if std::env::var_os("KG_SHARED_DATA").is_none() {
        return Ok(());
    }
    let base = loaded.base_dir();
    loaded
        .graph
        .relocate_input_files(registry, |text| {
            text.contains("shared/data").then(|| corpus_path(&base, text).to_string_lossy().into_owned())
        })
        .map_err(|e| format!("{}: {e}", loaded.path.display()))
}

/// The first screen of a failure: per output, how many facts differ, before the detail.
pub fn summary(problems: &[String]) -> Vec<String> {
    let mut per_output: BTreeMap<&str, usize> = BTreeMap::new();
    for p in problems {
        let key = p.split([':', '.', '[']).next().unwrap_or(p);
        *per_output.entry(key).or_default() += 1;
    }
    let mut lines: Vec<String> = per_output.iter().map(|(k, n)| format!("{k}: {n} fact(s) differ")).collect();
    if lines.len() > 20 {
        let more = lines.len() - 20;
        lines.truncate(20);
        lines.push(format!("… and {more} more outputs"));
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_required_data_skips_locally_and_fails_under_ci() {
        let dir = tempfile::tempdir().unwrap();
        let graph = dir.path().join("g.ron");
        std::fs::create_dir(dir.path().join("here")).unwrap();
        let expected = |requires: &[&str]| Expectation {
            tolerance: 1e-5,
            requires: requires.iter().map(|r| r.to_string()).collect(),
            quality: BTreeMap::new(),
            outputs: BTreeMap::new(),
        };
        assert_eq!(missing_data(&graph, &expected(&["here"]), true), None);
        let gone = expected(&["here", "../nowhere/data"]);
        assert_eq!(
            missing_data(&graph, &gone, false),
            Some(GraphTest::Skipped("required data not found: ../nowhere/data".into()))
        );
        assert!(matches!(missing_data(&graph, &gone, true), Some(GraphTest::Failed(p)) if p[0].contains("CI is set")));
    }

    #[test]
    fn structured_data_compares_numbers_within_tolerance_and_the_rest_exactly() {
        let want = serde_json::json!({"a": 1.0, "n": 3, "s": "x", "v": [1.0, 2.0]});
        let mut problems = Vec::new();
        let close_enough = serde_json::json!({"a": 1.000_000_1, "n": 3, "s": "x", "v": [1.0, 2.0]});
        compare_data("k", &want, &close_enough, 1e-5, &mut problems);
        assert!(problems.is_empty(), "{problems:?}");
        let off = serde_json::json!({"a": 1.1, "n": 4, "s": "y", "v": [1.0], "extra": 0});
        compare_data("k", &want, &off, 1e-5, &mut problems);
        assert_eq!(problems.len(), 5, "{problems:?}");
        assert!(problems.iter().any(|p| p == "k.n: expected 3, got 4"));
    }

    #[test]
    fn comparison_uses_the_tolerance_for_reals_and_exactness_for_counts() {
        let clip = |frames, fps| Facts::Clip {
            frames,
            joints: 3,
            fps,
            duration_secs: 1.0,
            root_travel_m: 2.0,
            mean_joint_height_m: 1.0,
        };
        let expected = Expectation {
            tolerance: 1e-3,
            requires: Vec::new(),
            quality: BTreeMap::new(),
            outputs: [("a.clip".to_string(), clip(10, 30.0))].into(),
        };
        let same = [("a.clip".to_string(), clip(10, 30.01))].into();
        assert!(compare(&expected, &same).is_empty());
        let off = [("a.clip".to_string(), clip(11, 30.1))].into();
        let problems = compare(&expected, &off);
        assert_eq!(problems.len(), 2, "{problems:?}");
        assert!(problems[0].contains("frames"));
        let extra: BTreeMap<String, Facts> =
            [("a.clip".to_string(), clip(10, 30.0)), ("b.value".to_string(), Facts::Scalar(1.0))].into();
        assert_eq!(compare(&expected, &extra).len(), 1);
    }
}
