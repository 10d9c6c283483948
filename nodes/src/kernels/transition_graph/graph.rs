//! The transition graph (Peng et al. 2007, "Build the Transition Graph"): one node per
//! cluster holding the short clips (runs of consecutive frames of one corpus clip inside
//! the cluster), one edge per ordered cluster pair that some corpus clip passes between on
//! consecutive frames, holding every such passage (the run before plus the run after).
//!
//! Undirected graphs are stored as two directed edges per passage, the reverse one played
//! backwards, so the path search and synthesis only ever see directed edges.

use std::collections::BTreeMap;
use std::sync::{Arc, OnceLock};

use petgraph::graph::{DiGraph, NodeIndex};
use petgraph::visit::EdgeRef;

use super::cluster::Clusters;
use super::paths::{PathLimits, PathTable, k_best_paths};
use crate::cancel::{Cancel, Cancelled};

/// A run of frames `start..end` of corpus clip `clip`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub struct Run {
    /// Clip index in the clip set.
    pub clip: u32,
    /// First frame.
    pub start: u32,
    /// One past the last frame.
    pub end: u32,
}

impl Run {
    /// Frame count.
    pub fn len(&self) -> usize {
        (self.end - self.start) as usize
    }

    /// Whether the run is empty.
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// A clip realising an edge: `run` played forwards, or backwards for the reverse edges of
/// an undirected graph.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub struct EdgeClip {
    /// The frames.
    pub run: Run,
    /// Played last frame first.
    pub backward: bool,
}

/// A cluster node.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClusterNode {
    /// Centre frame (corpus index).
    pub centre: usize,
    /// The short clips inside the cluster.
    pub runs: Vec<Run>,
}

/// An edge between two clusters.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TransitionEdge {
    /// Every passage between the two clusters.
    pub clips: Vec<EdgeClip>,
    /// Distance between the two centres.
    pub centre_distance: f64,
    /// Frames of the shortest clip × centre distance (the edge's share of eq. 1).
    pub cost: f64,
}

/// Which way edges may be travelled.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Direction {
    /// Only as captured.
    Directed,
    /// Also backwards, playing the clip in reverse.
    Undirected,
}

/// Clusters joined by the passages between them, with lazily computed candidate paths.
/// Serialised without the path tables (they are rebuilt on first use).
#[derive(Debug, serde::Deserialize)]
#[serde(from = "OwnedParts")]
pub struct TransitionGraph {
    /// The clusters (and corpus) it was built from.
    pub clusters: Arc<Clusters>,
    /// Nodes are clusters (index = cluster id), edges carry clips.
    pub graph: DiGraph<ClusterNode, TransitionEdge>,
    /// Directed or undirected.
    pub direction: Direction,
    /// Limits of the candidate path search.
    pub limits: PathLimits,
    /// Candidate paths per source node, filled on first use.
    tables: Vec<OnceLock<Arc<PathTable>>>,
}

impl PartialEq for TransitionGraph {
    fn eq(&self, other: &Self) -> bool {
        let nodes = |g: &Self| g.graph.node_weights().cloned().collect::<Vec<_>>();
        let edges = |g: &Self| {
            g.graph.edge_references().map(|e| (e.source(), e.target(), e.weight().clone())).collect::<Vec<_>>()
        };
        self.clusters == other.clusters
            && self.direction == other.direction
            && self.limits == other.limits
            && nodes(self) == nodes(other)
            && edges(self) == edges(other)
    }
}

/// Builds the graph: runs per cluster, and an edge wherever two consecutive frames of a
/// clip change cluster.
pub fn build_graph(clusters: Arc<Clusters>, direction: Direction, limits: PathLimits) -> TransitionGraph {
    let n = clusters.cluster_count();
    let mut runs_of: Vec<Vec<Run>> = vec![Vec::new(); n];
    let mut passages: BTreeMap<(u32, u32), Vec<EdgeClip>> = BTreeMap::new();
    for clip in 0..clusters.clip_starts.len() - 1 {
        let (first, last) = (clusters.clip_starts[clip], clusters.clip_starts[clip + 1]);
        let labels = &clusters.labels[first..last];
        // Split the clip into runs of equal label.
        let mut runs: Vec<(u32, Run)> = Vec::new();
        let mut start = 0;
        for f in 1..=labels.len() {
            if f == labels.len() || labels[f] != labels[start] {
                runs.push((labels[start], Run { clip: clip as u32, start: start as u32, end: f as u32 }));
                start = f;
            }
        }
        for (label, run) in &runs {
            runs_of[*label as usize].push(*run);
        }
        for pair in runs.windows(2) {
            let ((a, ra), (b, rb)) = (pair[0], pair[1]);
            let run = Run { clip: clip as u32, start: ra.start, end: rb.end };
            passages.entry((a, b)).or_default().push(EdgeClip { run, backward: false });
            if direction == Direction::Undirected {
                passages.entry((b, a)).or_default().push(EdgeClip { run, backward: true });
            }
        }
    }
    let mut graph = DiGraph::with_capacity(n, passages.len());
    for (c, runs) in runs_of.into_iter().enumerate() {
        graph.add_node(ClusterNode { centre: clusters.centres[c], runs });
    }
    for ((a, b), mut clips) in passages {
        clips.sort();
        let shortest = clips.iter().map(|c| c.run.len()).min().unwrap_or(0);
        let f = &clusters.features;
        let centre_distance = f64::from(f.distance(clusters.centres[a as usize], clusters.centres[b as usize]));
        let cost = shortest as f64 * centre_distance;
        graph.add_edge(
            NodeIndex::new(a as usize),
            NodeIndex::new(b as usize),
            TransitionEdge { clips, centre_distance, cost },
        );
    }
    GraphParts { clusters, graph, direction, limits }.into()
}

/// What a [`TransitionGraph`] is made of, less its lazily filled path tables.
#[derive(serde::Serialize, serde::Deserialize)]
struct GraphParts<C, G> {
    clusters: C,
    graph: G,
    direction: Direction,
    limits: PathLimits,
}

type OwnedParts = GraphParts<Arc<Clusters>, DiGraph<ClusterNode, TransitionEdge>>;

impl From<OwnedParts> for TransitionGraph {
    fn from(parts: OwnedParts) -> Self {
        let tables = (0..parts.graph.node_count()).map(|_| OnceLock::new()).collect();
        let GraphParts { clusters, graph, direction, limits } = parts;
        TransitionGraph { clusters, graph, direction, limits, tables }
    }
}

impl serde::Serialize for TransitionGraph {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let parts =
            GraphParts { clusters: &self.clusters, graph: &self.graph, direction: self.direction, limits: self.limits };
        parts.serialize(serializer)
    }
}

impl TransitionGraph {
    /// Out-edges as `(target, cost)` lists, sorted by target.
    pub fn adjacency(&self) -> Vec<Vec<(u32, f64)>> {
        self.graph
            .node_indices()
            .map(|v| {
                let mut out: Vec<(u32, f64)> =
                    self.graph.edges(v).map(|e| (e.target().index() as u32, e.weight().cost)).collect();
                out.sort_by_key(|e| e.0);
                out
            })
            .collect()
    }

    /// Candidate paths from `source` to every node: computed on first request, then cached.
    pub fn paths_from(&self, source: u32) -> Arc<PathTable> {
        self.tables[source as usize]
            .get_or_init(|| Arc::new(k_best_paths(&self.adjacency(), source, self.limits)))
            .clone()
    }

    /// The edge from `a` to `b`.
    pub fn edge(&self, a: u32, b: u32) -> Option<&TransitionEdge> {
        self.graph.find_edge(NodeIndex::new(a as usize), NodeIndex::new(b as usize)).map(|e| &self.graph[e])
    }

    /// The paper's statistics of the graph's shape (cheap: no path search).
    pub fn summary(&self) -> serde_json::Value {
        let runs: usize = self.graph.node_weights().map(|n| n.runs.len()).sum();
        serde_json::json!({
            "frames": self.clusters.features.len(),
            "clusters": self.graph.node_count(),
            "clips": runs,
            "edges": self.graph.edge_count(),
            "passages": self.graph.edge_weights().map(|e| e.clips.len()).sum::<usize>(),
            "directed": self.direction == Direction::Directed,
        })
    }

    /// [`Self::summary`] plus how many ordered node pairs have a candidate path, which
    /// computes every source's table (one bounded search each, `cancel` polled between).
    pub fn summary_with_paths(&self, cancel: Cancel) -> Result<serde_json::Value, Cancelled> {
        let n = self.graph.node_count();
        let mut connected = 0;
        for v in 0..n as u32 {
            cancel.check()?;
            connected += self.paths_from(v).paths.iter().filter(|p| !p.is_empty()).count();
        }
        let pairs = n * n.saturating_sub(1);
        let mut s = self.summary();
        s["node_pairs_with_path"] = connected.into();
        s["share_of_pairs_with_path"] = (connected as f64 / pairs.max(1) as f64).into();
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::transition_graph::cluster::{cluster, tests::tilts};
    use crate::kernels::transition_graph::distance::DistanceParams;
    use crate::model::{ClipSet, Joint, NamedClip, Skeleton};
    use glam::Vec3;

    /// Three clips over three well-separated tilts (0, 1, 2 rad): A = 0,0,1,1,1;
    /// B = 1,1,2; C = 2,0,0. Clusters by first appearance: 0 rad → 0, 1 → 1, 2 → 2.
    fn corpus(direction: Direction) -> TransitionGraph {
        let s = Arc::new(Skeleton::new(vec![Joint::new("Hips", None, Vec3::Y)]).unwrap());
        let clip = |a: &[f32]| Arc::new(tilts(&s, a));
        let set = ClipSet::new(vec![
            NamedClip { name: "a".into(), clip: clip(&[0.0, 0.0, 1.0, 1.0, 1.0]) },
            NamedClip { name: "b".into(), clip: clip(&[1.0, 1.0, 2.0]) },
            NamedClip { name: "c".into(), clip: clip(&[2.0, 0.0, 0.0]) },
        ])
        .unwrap();
        let c =
            cluster(Arc::new(set), DistanceParams { weights: vec![1.0], velocity_weight: 0.0 }, 0.01, Cancel::NEVER)
                .unwrap();
        build_graph(Arc::new(c), direction, PathLimits { k: 5, max_cost: f64::INFINITY })
    }

    #[test]
    fn nodes_runs_and_edges_follow_the_corpus() {
        let g = corpus(Direction::Directed);
        assert_eq!(g.graph.node_count(), 3);
        let runs = |c: usize| g.graph[NodeIndex::new(c)].runs.clone();
        let r = |clip, start, end| Run { clip, start, end };
        assert_eq!(runs(0), vec![r(0, 0, 2), r(2, 1, 3)]);
        assert_eq!(runs(1), vec![r(0, 2, 5), r(1, 0, 2)]);
        assert_eq!(runs(2), vec![r(1, 2, 3), r(2, 0, 1)]);
        // Edges 0→1 (clip a), 1→2 (clip b), 2→0 (clip c), nothing else.
        assert_eq!(g.graph.edge_count(), 3);
        let e01 = g.edge(0, 1).unwrap();
        assert_eq!(e01.clips, vec![EdgeClip { run: r(0, 0, 5), backward: false }]);
        // Cost: 5 frames × (half of 1 rad)².
        let d = (0.5f32).powi(2);
        assert!((e01.cost - 5.0 * f64::from(d)).abs() < 1e-5);
        assert!(g.edge(1, 0).is_none());
        // 0 → 2 only through 1.
        let p = g.paths_from(0);
        assert_eq!(p.paths[2].len(), 1);
        assert_eq!(p.paths[2][0].nodes, vec![0, 1, 2]);
        assert_eq!(g.summary_with_paths(Cancel::NEVER).unwrap()["share_of_pairs_with_path"], 1.0);
    }

    #[test]
    fn undirected_graphs_add_backward_passages() {
        let g = corpus(Direction::Undirected);
        assert_eq!(g.graph.edge_count(), 6);
        let back = g.edge(1, 0).unwrap();
        assert_eq!(back.clips.len(), 1);
        assert!(back.clips[0].backward);
        // 2 → 1 now has the direct backward edge (3 frames) and the detour through 0.
        assert_eq!(g.paths_from(2).paths[1].len(), 2);
    }
}
