//! Flexible motion transition (Peng, Lin et al. 2007): a corpus of short action clips is
//! clustered frame by frame, the clusters become a graph whose edges are the clips passing
//! between them, and any sequence of actions is played with transitions found in the graph
//! — or, where the data never connects two poses, interpolated through the clusters on the
//! way (Bézier fallback).

pub mod actions;
pub mod quality;
pub mod synthesis;

use std::collections::BTreeMap;
use std::sync::Arc;

use rand::SeedableRng;
use serde_json::json;

use self::actions::{Action, ActionLabels, find_actions};
use self::synthesis::{Frames, Motion, SynthesisParams, TransitionInfo, append_transition};
use crate::kernels::analysis::{AnalysisOptions, analyse};
use crate::kernels::baseline::{BaselineParams, concatenate_baseline};
use crate::kernels::clip_set::{conform, load_clip_set};
use crate::kernels::contacts::ContactThresholds;
use crate::kernels::ik::foot_lock::{HoldError, hold_detected_plants};
use crate::kernels::join::foot_skate_m;
use crate::kernels::transition_graph::distance::{self, DistanceParams};
use crate::kernels::transition_graph::graph::Direction;
use crate::kernels::transition_graph::paths::PathLimits;
use crate::kernels::transition_graph::{Clusters, TransitionGraph};
use crate::kernels::transition_graph::{cluster, graph};
use crate::model::choice::choices;
use crate::model::{Clip, ClipSet, FrameRange};
use crate::node::{
    ChoiceParam, FloatParam, Input, InputFolderParam, InputPathParam, IntParam, Node, NodeContext, NodeError,
    NodeSchema, OnOff, Output, Registry, Report, TextParam, report_of,
};

/// Registers the transition nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(LoadClipSet));
    registry.add(Box::new(ClusterFrames));
    registry.add(Box::new(BuildGraph));
    registry.add(Box::new(Transition));
    registry.add(Box::new(Sequence));
}

const FOLDER: InputFolderParam = InputFolderParam::new(
    "folder",
    "Folder to read clips from (sub-folders included). Relative paths start at the graph file's folder.",
    // The clip files, and the buffers a .gltf may keep beside it.
    &["bvh", "glb", "gltf", "fbx", "bin"],
    ".",
);
const PATTERN: TextParam = TextParam::new(
    "pattern",
    "Which files to read: file-name wildcards separated by commas, e.g. \"02_*.bvh, 144_05.bvh\".",
    "*.bvh",
);
const SET_FPS: FloatParam =
    FloatParam::new("fps", "Every clip is resampled to this frame rate.", 30.0, 1.0, 1000.0, "fps");
const FAMILY: TextParam = TextParam::new(
    "family",
    "Clips must share one skeleton: keep the family of the clip with this name; empty keeps the largest family.",
    "",
);
const CLIP_SET_OUT: Output<Arc<ClipSet>> =
    Output::new("clip_set", "The clips, named by file stem, on one skeleton at one frame rate.");
const REPORT: Output<Arc<Report>> = Output::new("report", "What was decided and measured.");

/// `load.clip_set`.
pub struct LoadClipSet;

static LOAD_CLIP_SET: NodeSchema = NodeSchema {
    kind: "load.clip_set",
    category: "io",
    doc: "Loads a folder of action clips as one set: one skeleton family (others are left out with a warning), one frame rate, each action named by its file name.",
    inputs: &[],
    outputs: &[CLIP_SET_OUT.spec(), REPORT.spec()],
    params: &[FOLDER.0, PATTERN.0, SET_FPS.0, FAMILY.0],
    writes_files: false,
    version: 1,
};

impl Node for LoadClipSet {
    fn schema(&self) -> &'static NodeSchema {
        &LOAD_CLIP_SET
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let folder = ctx.input_folder(&FOLDER)?;
        if !folder.is_dir() {
            return Err(NodeError::param("folder", format!("{} is not a folder", folder.display())));
        }
        let family = ctx.text_param(&FAMILY)?.trim().to_string();
        let family = (!family.is_empty()).then_some(family.as_str());
        let limit = Some(ctx.memory_limit_bytes());
        let loaded = load_clip_set(&folder, ctx.text_param(&PATTERN)?, ctx.float(&SET_FPS)?, family, limit)
            .map_err(NodeError::kernel)?;
        ctx.warn_all(loaded.warnings);
        if !loaded.left_out.is_empty() {
            ctx.warn(format!(
                "left out {} clip(s) on other skeletons: {}",
                loaded.left_out.len(),
                loaded.left_out.join(", ")
            ));
        }
        let mut report = loaded.set.summary();
        report["left_out"] = json!(loaded.left_out);
        ctx.set_output(&CLIP_SET_OUT, Arc::new(loaded.set));
        ctx.set_output(&REPORT, report_of(report));
        Ok(())
    }
}

const CLIP_SET_IN: Input<Arc<ClipSet>> = Input::required("clip_set", "The action clips to cluster.");
const RADIUS: FloatParam = FloatParam::new(
    "radius",
    "Cluster radius r in pose-distance units (about rad² summed over the weighted joints): frames nearer than r to a centre join it, frames beyond 2r start a new cluster. Larger means fewer clusters.",
    0.6,
    1e-6,
    1e6,
    "",
);
const VELOCITY_WEIGHT: FloatParam = FloatParam::new(
    "velocity_weight",
    "ν: how much differences in joint and root velocities count beside differences in pose.",
    0.003,
    0.0,
    100.0,
    "s²",
);
const JOINT_WEIGHTS: TextParam = TextParam::new(
    "joint_weights",
    "Per-joint weights overriding the defaults (1 for pelvis, spine, hips, knees, shoulders and elbows, 0 elsewhere), e.g. \"LeftFoot=0.5, Head=1\".",
    "",
);
const CLUSTERS_OUT: Output<Arc<Clusters>> = Output::new("clusters", "Every frame labelled with its pose cluster.");

/// `motion.cluster`.
pub struct ClusterFrames;

static CLUSTER_FRAMES: NodeSchema = NodeSchema {
    kind: "motion.cluster",
    category: "motion",
    doc: "Groups every frame of a clip set into pose clusters (two passes with radius r), comparing poses whatever the character's position and facing.",
    inputs: &[CLIP_SET_IN.spec()],
    outputs: &[CLUSTERS_OUT.spec(), REPORT.spec()],
    params: &[RADIUS.0, VELOCITY_WEIGHT.0, JOINT_WEIGHTS.0],
    writes_files: false,
    version: 1,
};

impl Node for ClusterFrames {
    fn schema(&self) -> &'static NodeSchema {
        &CLUSTER_FRAMES
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let set = ctx.input(&CLIP_SET_IN)?;
        let params = DistanceParams::lee_defaults(set.skeleton(), ctx.float(&VELOCITY_WEIGHT)? as f32)
            .with_overrides(set.skeleton(), ctx.text_param(&JOINT_WEIGHTS)?)
            .map_err(|e| NodeError::param("joint_weights", e.to_string()))?;
        if params.weights.iter().all(|w| *w == 0.0) {
            return Err(NodeError::param("joint_weights", "every joint has weight 0"));
        }
        let clusters = cluster::cluster(set, params, ctx.float(&RADIUS)? as f32, ctx.cancel())?;
        ctx.set_output(&REPORT, report_of(clusters.summary()));
        ctx.set_output(&CLUSTERS_OUT, Arc::new(clusters));
        Ok(())
    }
}

const CLUSTERS_IN: Input<Arc<Clusters>> = Input::required("clusters", "Clustered frames of a clip set.");
choices!(Direction { Directed = "directed", Undirected = "undirected" });
const DIRECTION: ChoiceParam<Direction> = ChoiceParam::new(
    "direction",
    "\"directed\": clips only play forwards; \"undirected\": a transition may also play a clip backwards.",
    "directed",
);
const K: IntParam = IntParam::new("paths", "K: candidate paths kept per pair of clusters.", 5, 1, 100);
const MAX_COST: FloatParam = FloatParam::optional(
    "max_cost",
    "Candidate paths costing more (frames × pose distance, summed over the path) are discarded; unset keeps all.",
    0.0,
    1e12,
    "",
);
const GRAPH_OUT: Output<Arc<TransitionGraph>> = Output::new(
    "graph",
    "Clusters joined by the clips passing between them; candidate paths are found when first needed.",
);

/// `motion.transition_graph`.
pub struct BuildGraph;

static BUILD_GRAPH: NodeSchema = NodeSchema {
    kind: "motion.transition_graph",
    category: "motion",
    doc: "Builds the transition graph: one node per pose cluster with its short clips, an edge wherever a clip passes from one cluster to another. The report gives frames, clusters, clips, edges and the share of cluster pairs with a candidate path.",
    inputs: &[CLUSTERS_IN.spec()],
    outputs: &[GRAPH_OUT.spec(), REPORT.spec()],
    params: &[DIRECTION.0, K.0, MAX_COST.0],
    writes_files: false,
    version: 1,
};

impl Node for BuildGraph {
    fn schema(&self) -> &'static NodeSchema {
        &BUILD_GRAPH
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clusters = ctx.input(&CLUSTERS_IN)?;
        let direction = ctx.choice(&DIRECTION)?;
        let limits =
            PathLimits { k: ctx.int(&K)? as usize, max_cost: ctx.optional_float(&MAX_COST)?.unwrap_or(f64::INFINITY) };
        let graph = graph::build_graph(clusters, direction, limits);
        let summary = graph.summary_with_paths(ctx.cancel())?;
        ctx.set_output(&REPORT, report_of(summary));
        ctx.set_output(&GRAPH_OUT, Arc::new(graph));
        Ok(())
    }
}

const GRAPH_IN: Input<Arc<TransitionGraph>> = Input::required("graph", "The transition graph to travel.");
const SEED: IntParam =
    IntParam::new("seed", "Seed of the random choice among candidate paths (same seed, same result).", 0, 0, 1 << 40);
const WINDOW_OUT: IntParam =
    IntParam::new("window_out_frames", "Frames at the end of the motion searched for each join point.", 10, 1, 1000);
const WINDOW_IN: IntParam = IntParam::new(
    "window_in_frames",
    "Frames at the start of each incoming clip searched for its join point.",
    25,
    1,
    1000,
);
const MAX_CLIP_SECS: FloatParam = FloatParam::new(
    "max_clip_secs",
    "Passing clips longer than this are used only when nothing shorter links two clusters.",
    2.0,
    0.0,
    1e4,
    "s",
);
const SIGMA: FloatParam = FloatParam::new(
    "sigma",
    "σ: pose distance covered per frame where no path exists and the pose is interpolated; smaller means longer, slower fallbacks.",
    0.05,
    1e-6,
    1e6,
    "",
);

fn synthesis_params(ctx: &NodeContext<'_>, fps: f64) -> Result<SynthesisParams, NodeError> {
    Ok(SynthesisParams {
        window_out_frames: ctx.int(&WINDOW_OUT)? as usize,
        window_in_frames: ctx.int(&WINDOW_IN)? as usize,
        max_clip_frames: (ctx.float(&MAX_CLIP_SECS)? * fps).round() as usize,
        sigma_per_frame: ctx.float(&SIGMA)?,
        ..SynthesisParams::default()
    })
}

fn rng_of(ctx: &NodeContext<'_>) -> Result<rand_chacha::ChaCha8Rng, NodeError> {
    Ok(rand_chacha::ChaCha8Rng::seed_from_u64(ctx.int(&SEED)? as u64))
}

/// A clip from a port made fit for `graph` (its skeleton and rate), or an error naming the port.
fn fit(graph: &TransitionGraph, clip: &Clip, port: &'static str) -> Result<Clip, NodeError> {
    let set = &graph.clusters.clip_set;
    if clip.frame_count() == 0 {
        return Err(NodeError::input(port, "has no frames"));
    }
    conform(clip, set.skeleton(), set.fps()).map_err(|e| NodeError::input(port, e.to_string()))
}

const SOURCE: Input<Arc<Clip>> = Input::required("source", "The clip the transition starts from (its last frame).");
const TARGET: Input<Arc<Clip>> = Input::required("target", "The clip the transition leads into (its first frame).");
const JOINED_OUT: Output<Arc<Clip>> =
    Output::new("clip", "Source, transition and target as one continuous clip, at the graph's frame rate.");
const TRANSITION_OUT: Output<Arc<Clip>> = Output::new("transition", "The transition frames alone.");

/// `motion.transition`.
pub struct Transition;

static TRANSITION: NodeSchema = NodeSchema {
    kind: "motion.transition",
    category: "motion",
    doc: "Links two clips through the transition graph: finds the clusters of the source's last and the target's first pose, picks a candidate path at random (cheaper paths likelier) and chains the clips along it, or interpolates through the clusters in between when no path exists.",
    inputs: &[GRAPH_IN.spec(), SOURCE.spec(), TARGET.spec()],
    outputs: &[JOINED_OUT.spec(), TRANSITION_OUT.spec(), REPORT.spec()],
    params: &[SEED.0, WINDOW_OUT.0, WINDOW_IN.0, MAX_CLIP_SECS.0, SIGMA.0, FOOT_LOCK.0],
    writes_files: false,
    version: 4,
};

impl Node for Transition {
    fn schema(&self) -> &'static NodeSchema {
        &TRANSITION
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let graph = ctx.input(&GRAPH_IN)?;
        let source = fit(&graph, ctx.input(&SOURCE)?.as_ref(), "source")?;
        let target = fit(&graph, ctx.input(&TARGET)?.as_ref(), "target")?;
        let params = synthesis_params(ctx, graph.clusters.clip_set.fps())?;
        let mut out = Motion::of_clip(&source);
        let info = append_transition(&graph, &mut out, Frames::of_clip(&target), &params, &mut rng_of(ctx)?);
        let joined = out.into_clip(&source).map_err(NodeError::kernel)?;
        let joined = lock_feet(ctx, joined)?;
        let transition = joined.slice(info.frames.start, info.frames.end);
        let mut report = serde_json::to_value(&info).unwrap_or_default();
        report["duration_secs"] = json!(transition.duration_secs());
        ctx.set_output(&TRANSITION_OUT, Arc::new(transition));
        ctx.set_output(&JOINED_OUT, Arc::new(joined));
        ctx.set_output(&REPORT, report_of(report));
        Ok(())
    }
}

const FOOT_LOCK: ChoiceParam<OnOff> = ChoiceParam::new(
    "foot_lock",
    "After synthesis, feet planted anywhere in the result (contacts detected on it, and on the held result until the \
     two agree) are held where they were put down by the foot lock's IK, and planted feet that a joined clip put under the floor are lifted onto it: the synthesised \
     transitions otherwise let the stance foot glide ('off' keeps the raw synthesis).",
    "on",
);

/// `clip` with its planted feet held and kept above the floor when `FOOT_LOCK` is on.
fn lock_feet(ctx: &NodeContext<'_>, clip: Clip) -> Result<Clip, NodeError> {
    if ctx.choice(&FOOT_LOCK)? == OnOff::Off {
        return Ok(clip);
    }
    hold_planted_feet(clip).map_err(|e| NodeError::kernel(SynthesisFootLock(e)))
}

/// The foot lock after synthesis failed.
#[derive(Debug, thiserror::Error)]
#[error("the foot lock after synthesis failed: {0} (set foot_lock off to skip it)")]
struct SynthesisFootLock(#[source] HoldError);

/// A synthesised motion with every planted foot (contacts detected on it) held where it was
/// put down and lifted onto the floor where a joined clip put it under: Peng et al.'s
/// transitions join clips whose stance feet do not line up, so without this the stance foot
/// glides through them.
pub fn hold_planted_feet(clip: Clip) -> Result<Clip, HoldError> {
    Ok(hold_detected_plants(&clip, &ContactThresholds::default(), |all| all)?.map_or(clip, |(held, _)| held))
}

const ACTIONS: TextParam = TextParam::new(
    "actions",
    "The actions to play in order, separated by commas: names from the label file, or clip names (e.g. \"walk, punch, kick\" or \"02_01, 02_05\").",
    "",
);
const LABELS: InputPathParam = InputPathParam::optional(
    "labels",
    "A RON file naming actions, each a whole clip or the stretch of one between two times, e.g. (actions: {\"punch\": (clip: \"02_05\", start_secs: 1.2, end_secs: 3.4)}).",
    &["ron"],
);
const SEQUENCE_OUT: Output<Arc<Clip>> = Output::new("clip", "The actions played one after another with transitions.");

/// `motion.sequence`.
pub struct Sequence;

static SEQUENCE: NodeSchema = NodeSchema {
    kind: "motion.sequence",
    category: "motion",
    doc: "Plays a list of actions from the graph's clip set in order as one continuous clip, with a transition between each two. Actions are clip names, or names given in a label file (whole clips or stretches of long takes). The report lists each transition's path, cost and whether it was interpolated, and compares its smoothness and foot sliding with a plain crossfade of the same two clips.",
    inputs: &[GRAPH_IN.spec()],
    outputs: &[SEQUENCE_OUT.spec(), REPORT.spec()],
    params: &[ACTIONS.0, LABELS.0, SEED.0, WINDOW_OUT.0, WINDOW_IN.0, MAX_CLIP_SECS.0, SIGMA.0, FOOT_LOCK.0],
    writes_files: false,
    version: 4,
};

/// Plays `actions` (at least one, from the graph's clip set) one after another with a
/// transition between each two: the motion and what each transition did.
pub fn play_sequence(
    graph: &TransitionGraph,
    actions: &[Action],
    params: &SynthesisParams,
    rng: &mut impl rand::Rng,
) -> (Motion, Vec<TransitionInfo>) {
    let mut out = Motion::of_clip(&actions[0].clip);
    // Room for every action and about two seconds of transition between each two.
    let fps = graph.clusters.clip_set.fps();
    out.reserve(actions[1..].iter().map(|a| a.clip.frame_count() + (2.0 * fps) as usize).sum());
    let infos = actions[1..]
        .iter()
        .map(|next| append_transition(graph, &mut out, Frames::of_clip(&next.clip), params, rng))
        .collect();
    (out, infos)
}

/// Smoothness of one transition of `output` (a sequence) between clips `a` and `b`,
/// against the crossfade of the same two clips (Motion Graphs' best-cut 0.25 s crossfade):
/// peak joint angular acceleration of the weighted joints of `layout` inside the
/// transition over the peak inside `a` and `b`, and foot skate (m) inside it.
pub fn smoothness_against_crossfade(
    layout: &distance::PoseFeatures,
    output: &Arc<Clip>,
    transition: FrameRange,
    a: &Arc<Clip>,
    b: &Arc<Clip>,
) -> Result<serde_json::Value, String> {
    use quality::peak_angular_acceleration;
    let options = AnalysisOptions::default();
    let whole = |c: &Clip| FrameRange::new(0, c.frame_count());
    let source_peak =
        peak_angular_acceleration(a, layout, whole(a)).max(peak_angular_acceleration(b, layout, whole(b)));
    let ours = analyse(output.clone(), &options, None, None).map_err(|e| e.to_string())?;
    let (fa, fb) = (
        analyse(a.clone(), &options, None, None).map_err(|e| e.to_string())?,
        analyse(b.clone(), &options, None, None).map_err(|e| e.to_string())?,
    );
    let fade = concatenate_baseline(&fa, &fb, &BaselineParams::default(), &options).map_err(|e| e.to_string())?;
    let window = fade.report.get("window_frames").and_then(|w| w.as_array()).map_or(FrameRange::new(0, 0), |w| {
        let at = |k: usize| w.get(k).and_then(|x| x.as_u64()).unwrap_or(0) as usize;
        FrameRange::new(at(0), at(1) + 1)
    });
    let ratio = |peak: f64| peak / source_peak.max(1e-9);
    Ok(json!({
        "source_peak_angular_acceleration": source_peak,
        "peak_ratio": ratio(peak_angular_acceleration(output, layout, transition)),
        "foot_skate_m": foot_skate_m(&ours, transition, options.contacts.enter_height_m),
        "crossfade_peak_ratio": ratio(peak_angular_acceleration(&fade.clip, layout, window)),
        "crossfade_foot_skate_m": fade.report.get("foot_skate_in_blend_m").cloned().unwrap_or_default(),
    }))
}

impl Node for Sequence {
    fn schema(&self) -> &'static NodeSchema {
        &SEQUENCE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let graph = ctx.input(&GRAPH_IN)?;
        let set = &graph.clusters.clip_set;
        let labelled = match ctx.optional_input_path(&LABELS)? {
            None => BTreeMap::new(),
            Some(path) => {
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| NodeError::param("labels", format!("cannot read {}: {e}", path.display())))?;
                ActionLabels::parse(&text)
                    .and_then(|labels| labels.resolve(set))
                    .map_err(|e| NodeError::param("labels", format!("{}:{e}", path.display())))?
            }
        };
        let text = ctx.text_param(&ACTIONS)?;
        let names: Vec<&str> = text.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
        let actions = find_actions(set, &labelled, &names).map_err(|e| NodeError::param("actions", e))?;
        if actions.is_empty() {
            return Err(NodeError::param("actions", "names no action"));
        }
        let params = synthesis_params(ctx, set.fps())?;
        ctx.check_cancelled()?;
        let (out, infos) = play_sequence(&graph, &actions, &params, &mut rng_of(ctx)?);
        let clip = out.into_clip(&actions[0].clip).map_err(NodeError::kernel)?;
        let clip = Arc::new(lock_feet(ctx, clip)?);
        let mut transitions = Vec::new();
        for (k, info) in infos.iter().enumerate() {
            ctx.check_cancelled()?;
            ctx.progress(k as f32 / infos.len() as f32);
            let mut entry = serde_json::to_value(info).unwrap_or_default();
            entry["from"] = json!(actions[k].name);
            entry["to"] = json!(actions[k + 1].name);
            let (a, b) = (&actions[k].clip, &actions[k + 1].clip);
            match smoothness_against_crossfade(&graph.clusters.features, &clip, info.frames, a, b) {
                Ok(q) => entry["smoothness"] = q,
                Err(e) => ctx.warn(format!("transition {k}: smoothness not measured: {e}")),
            }
            transitions.push(entry);
        }
        let played: Vec<serde_json::Value> = actions
            .iter()
            .map(|a| json!({"name": a.name, "clip": a.clip_name, "frames": [a.frames.start, a.frames.end]}))
            .collect();
        let report = json!({
            "actions": played,
            "frames": clip.frame_count(),
            "duration_secs": clip.duration_secs(),
            "fallbacks": infos.iter().filter(|i| i.fallback).count(),
            "transitions": transitions,
        });
        ctx.set_output(&SEQUENCE_OUT, clip);
        ctx.set_output(&REPORT, report_of(report));
        Ok(())
    }
}
