//! Candidate paths: the K lowest-cost simple paths from one source to every target, exact.
//!
//! The paper precomputes K paths for every node pair (O(n²) tables). Here a source's table
//! is computed only when a transition first leaves that source, then cached; one table
//! holds every target:
//!
//! 1. Dijkstra from the source gives d(v), the cost of the cheapest path to every node,
//!    and its shortest-path tree. The tree path is each target's best path.
//! 2. Per target, the remaining paths come from Lawler's partition of Yen's algorithm,
//!    run from the target's end: a *sub-problem* fixes a path's suffix from a spur node u
//!    to the target and forbids some edges into u; its best path is the cheapest path
//!    from the source to u avoiding the suffix's nodes, followed by the suffix. Each time
//!    the cheapest pending sub-problem's path is taken as the next best path, its own
//!    sub-problem is split into disjoint ones (one per node of its path from the spur node
//!    back to the source: keep the suffix from that node, forbid the edge the path
//!    entered it by), so no path is ever produced twice and none is missed. A part that
//!    cannot beat the paths still needed that are already pending (its lower bound
//!    d(u) + suffix cost is dearer) is never solved.
//! 3. Each sub-problem is solved by A* searching backwards from u with d as the
//!    heuristic (a lower bound on the cost still to go, since avoiding nodes only makes
//!    paths dearer), given up once that bound passes what could still be kept. The search
//!    stops at the first popped node whose tree path from the source is free of avoided
//!    nodes: that path meets the lower bound, so it is optimal. Usually the very first
//!    node qualifies and the search costs a walk along the tree.
//!
//! The result is exact for edge costs > 0 (ties are broken by node order); the work per
//! target is at most K × path length sub-problems.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// One candidate path: nodes from source to target and the summed edge cost.
#[derive(Clone, Debug, PartialEq)]
pub struct CandidatePath {
    /// Visited nodes, source first, target last.
    pub nodes: Vec<u32>,
    /// Transition cost (eq. 1).
    pub cost: f64,
}

/// Every target's candidate paths from one source, best first.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct PathTable {
    /// Per target node: up to K paths, cheapest first (empty for the source itself).
    pub paths: Vec<Vec<CandidatePath>>,
    /// Sub-problems solved (the search's work, for benchmarks and reports).
    pub subproblems: usize,
}

/// What the search keeps.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PathLimits {
    /// K: paths kept per target.
    pub k: usize,
    /// Paths costing more are never kept.
    pub max_cost: f64,
}

/// Heap key ordered by cost, then by a tie-breaking index (for determinism).
#[derive(PartialEq)]
struct Key(f64, usize);
impl Eq for Key {}
impl PartialOrd for Key {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Key {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
    }
}

const NONE: u32 = u32::MAX;

/// A path of a sub-problem: its nodes, the cost of the edge into each (0 for the source),
/// where its fixed suffix starts and which predecessors of that spur node are forbidden.
struct Pending {
    nodes: Vec<u32>,
    step_costs: Vec<f64>,
    spur: usize,
    forbidden: Vec<u32>,
}

impl Pending {
    fn cost(&self) -> f64 {
        self.step_costs.iter().sum()
    }
}

/// Per-source state reused by every sub-problem: the source's shortest-path tree, the
/// in-edges, and stamped scratch arrays (a stamp equal to the current one means "set").
struct Search<'a> {
    source: u32,
    preds: &'a [Vec<(u32, f64)>],
    dist: Vec<f64>,
    parent: Vec<u32>,
    blocked: Vec<u32>,
    block_stamp: u32,
    g: Vec<f64>,
    next: Vec<u32>,
    seen: Vec<u32>,
    closed: Vec<u32>,
    search_stamp: u32,
    chain: Vec<u32>,
    chain_stamp: u32,
    heap: BinaryHeap<Reverse<Key>>,
    subproblems: usize,
}

impl<'a> Search<'a> {
    fn new(preds: &'a [Vec<(u32, f64)>], succs: &[Vec<(u32, f64)>], source: u32) -> Search<'a> {
        let n = preds.len();
        let (mut dist, mut parent) = (vec![f64::INFINITY; n], vec![NONE; n]);
        dist[source as usize] = 0.0;
        let mut heap = BinaryHeap::from([Reverse(Key(0.0, source as usize))]);
        let mut done = vec![false; n];
        while let Some(Reverse(Key(d, v))) = heap.pop() {
            if std::mem::replace(&mut done[v], true) {
                continue;
            }
            for &(w, c) in &succs[v] {
                let next = d + c;
                if next < dist[w as usize] {
                    dist[w as usize] = next;
                    parent[w as usize] = v as u32;
                    heap.push(Reverse(Key(next, w as usize)));
                }
            }
        }
        Search {
            source,
            preds,
            dist,
            parent,
            blocked: vec![0; n],
            block_stamp: 0,
            g: vec![0.0; n],
            next: vec![NONE; n],
            seen: vec![0; n],
            closed: vec![0; n],
            search_stamp: 0,
            chain: vec![0; n],
            chain_stamp: 0,
            heap: BinaryHeap::new(),
            subproblems: 0,
        }
    }

    /// The tree path from the source to `v`, source first.
    fn tree_path(&self, mut v: u32) -> Vec<u32> {
        let mut nodes = vec![v];
        while v != self.source {
            v = self.parent[v as usize];
            nodes.push(v);
        }
        nodes.reverse();
        nodes
    }

    /// Whether `v`'s tree path avoids every blocked node and every node on the search's
    /// chain from `v` to the spur node (which would close a cycle).
    fn tree_path_is_free(&mut self, v: u32) -> bool {
        self.chain_stamp += 1;
        let mut c = self.next[v as usize];
        while c != NONE {
            self.chain[c as usize] = self.chain_stamp;
            c = self.next[c as usize];
        }
        let mut x = v;
        loop {
            if self.blocked[x as usize] == self.block_stamp || self.chain[x as usize] == self.chain_stamp {
                return false;
            }
            if x == self.source {
                return true;
            }
            x = self.parent[x as usize];
        }
    }

    /// The cheapest path from the source to `spur` that avoids the blocked nodes and does
    /// not enter `spur` from a `forbidden` node, if it costs at most `budget`: its nodes
    /// (source first, `spur` last) and the cost of the edge into each.
    fn best_prefix(&mut self, spur: u32, forbidden: &[u32], budget: f64) -> Option<(Vec<u32>, Vec<f64>)> {
        self.subproblems += 1;
        self.search_stamp += 1;
        let stamp = self.search_stamp;
        self.heap.clear();
        self.next[spur as usize] = NONE;
        for &(w, c) in &self.preds[spur as usize] {
            let wi = w as usize;
            if self.blocked[wi] == self.block_stamp || forbidden.contains(&w) || !self.dist[wi].is_finite() {
                continue;
            }
            if self.seen[wi] != stamp || c < self.g[wi] {
                (self.seen[wi], self.g[wi], self.next[wi]) = (stamp, c, spur);
                self.heap.push(Reverse(Key(c + self.dist[wi], wi)));
            }
        }
        while let Some(Reverse(Key(f, x))) = self.heap.pop() {
            if f > budget {
                return None;
            }
            if self.closed[x] == stamp {
                continue;
            }
            self.closed[x] = stamp;
            if self.tree_path_is_free(x as u32) {
                let mut nodes = self.tree_path(x as u32);
                let mut c = self.next[x];
                while c != NONE {
                    nodes.push(c);
                    c = self.next[c as usize];
                }
                let step_costs =
                    std::iter::once(0.0).chain(nodes.windows(2).map(|w| edge_cost(self.preds, w[0], w[1]))).collect();
                return Some((nodes, step_costs));
            }
            for &(y, c) in &self.preds[x] {
                let yi = y as usize;
                if self.blocked[yi] == self.block_stamp || self.closed[yi] == stamp || !self.dist[yi].is_finite() {
                    continue;
                }
                let g = self.g[x] + c;
                if self.seen[yi] != stamp || g < self.g[yi] {
                    (self.seen[yi], self.g[yi], self.next[yi]) = (stamp, g, x as u32);
                    self.heap.push(Reverse(Key(g + self.dist[yi], yi)));
                }
            }
        }
        None
    }

    /// Up to `limits.k` cheapest simple paths from the source to `target`.
    fn paths_to(&mut self, target: u32, limits: PathLimits) -> Vec<CandidatePath> {
        let mut found = Vec::new();
        let d = self.dist[target as usize];
        if target == self.source || !d.is_finite() || d > limits.max_cost {
            return found;
        }
        let nodes = self.tree_path(target);
        let step_costs = std::iter::once(0.0).chain(nodes.windows(2).map(|w| edge_cost(self.preds, w[0], w[1])));
        let root = Pending { spur: nodes.len() - 1, step_costs: step_costs.collect(), nodes, forbidden: Vec::new() };
        // Pending sub-problems' best paths, dearest first (of equal ones the later found
        // first), so the cheapest is popped from the end and the n-th cheapest is at
        // `len - n`.
        let mut queue: Vec<(f64, Pending)> = vec![(root.cost(), root)];
        while let Some((cost, path)) = queue.pop() {
            let still_needed = limits.k - found.len() - 1;
            if still_needed == 0 {
                found.push(CandidatePath { nodes: path.nodes, cost });
                break;
            }
            // Split the sub-problem: for spur nodes from the old spur back to the source's
            // successor, keep the suffix from there and forbid the edge the path came by.
            // A part whose paths cannot beat the paths still needed already pending is
            // skipped; its lower bound is d(spur) + the suffix's cost.
            self.block_stamp += 1;
            for &v in &path.nodes[path.spur + 1..] {
                self.blocked[v as usize] = self.block_stamp;
            }
            let mut suffix_cost: f64 = path.step_costs[path.spur + 1..].iter().sum();
            for i in (1..=path.spur).rev() {
                let spur = path.nodes[i];
                self.blocked[spur as usize] = self.block_stamp;
                let threshold =
                    if queue.len() >= still_needed { queue[queue.len() - still_needed].0 } else { limits.max_cost };
                if self.dist[spur as usize] + suffix_cost <= threshold {
                    let mut forbidden = if i == path.spur { path.forbidden.clone() } else { Vec::new() };
                    forbidden.push(path.nodes[i - 1]);
                    if let Some((mut nodes, mut step_costs)) =
                        self.best_prefix(spur, &forbidden, threshold - suffix_cost)
                    {
                        let spur_index = nodes.len() - 1;
                        nodes.extend_from_slice(&path.nodes[i + 1..]);
                        step_costs.extend_from_slice(&path.step_costs[i + 1..]);
                        let child = Pending { spur: spur_index, nodes, step_costs, forbidden };
                        let cost = child.cost();
                        if cost <= threshold {
                            let at = queue.partition_point(|e| e.0 > cost);
                            queue.insert(at, (cost, child));
                        }
                    }
                }
                suffix_cost += path.step_costs[i];
            }
            found.push(CandidatePath { nodes: path.nodes, cost });
        }
        found
    }
}

/// The cost of edge `a → b` from the in-edge lists (present by construction).
fn edge_cost(preds: &[Vec<(u32, f64)>], a: u32, b: u32) -> f64 {
    let list = &preds[b as usize];
    list.binary_search_by_key(&a, |e| e.0).map_or(f64::INFINITY, |i| list[i].1)
}

/// In-edge lists `preds[w] = [(v, cost)]`, sorted by `v`, self-loops dropped and of
/// parallel edges the cheapest kept (a path is a node sequence, so only it matters).
fn in_edges(adjacency: &[Vec<(u32, f64)>]) -> Vec<Vec<(u32, f64)>> {
    let mut preds: Vec<Vec<(u32, f64)>> = vec![Vec::new(); adjacency.len()];
    for (v, out) in adjacency.iter().enumerate() {
        for &(w, c) in out.iter().filter(|e| e.0 as usize != v && (e.0 as usize) < adjacency.len()) {
            preds[w as usize].push((v as u32, c));
        }
    }
    for list in &mut preds {
        list.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
        list.dedup_by_key(|e| e.0);
    }
    preds
}

/// Out-edge lists made from the in-edge lists (so both hold the same edges).
fn out_edges(preds: &[Vec<(u32, f64)>]) -> Vec<Vec<(u32, f64)>> {
    let mut succs: Vec<Vec<(u32, f64)>> = vec![Vec::new(); preds.len()];
    for (w, list) in preds.iter().enumerate() {
        for &(v, c) in list {
            succs[v as usize].push((w as u32, c));
        }
    }
    succs
}

/// The K best simple paths from `source` to every node of the graph given by its
/// out-edges `adjacency[v] = [(w, cost)]` (costs > 0).
pub fn k_best_paths(adjacency: &[Vec<(u32, f64)>], source: u32, limits: PathLimits) -> PathTable {
    let n = adjacency.len();
    let mut table = PathTable { paths: vec![Vec::new(); n], subproblems: 0 };
    if source as usize >= n || limits.k == 0 {
        return table;
    }
    let preds = in_edges(adjacency);
    let mut search = Search::new(&preds, &out_edges(&preds), source);
    for t in 0..n as u32 {
        table.paths[t as usize] = search.paths_to(t, limits);
    }
    table.subproblems = search.subproblems;
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every simple path from `s` by depth-first enumeration: cost lists per target.
    fn brute_force(adjacency: &[Vec<(u32, f64)>], s: u32) -> Vec<Vec<f64>> {
        fn walk(adj: &[Vec<(u32, f64)>], v: u32, cost: f64, on: &mut Vec<bool>, out: &mut Vec<Vec<f64>>) {
            for &(w, c) in &adj[v as usize] {
                if !on[w as usize] {
                    on[w as usize] = true;
                    out[w as usize].push(cost + c);
                    walk(adj, w, cost + c, on, out);
                    on[w as usize] = false;
                }
            }
        }
        let mut out = vec![Vec::new(); adjacency.len()];
        let mut on = vec![false; adjacency.len()];
        on[s as usize] = true;
        walk(adjacency, s, 0.0, &mut on, &mut out);
        out
    }

    #[test]
    fn k_best_matches_brute_force_on_random_graphs() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for trial in 0..400 {
            // Small dense graphs and larger sparse ones (like the corpus graphs, whose
            // out-degree is about 2), with many equal costs to exercise ties.
            let n = if trial % 2 == 0 { rng.gen_range(2..8usize) } else { rng.gen_range(8..13usize) };
            let density = if trial % 2 == 0 { rng.gen_range(0.2..0.8) } else { rng.gen_range(1.5..3.0) / n as f64 };
            let mut adjacency: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
            for (v, out) in adjacency.iter_mut().enumerate() {
                for w in (0..n).filter(|&w| w != v) {
                    if rng.gen_bool(density) {
                        out.push((w as u32, rng.gen_range(1..20) as f64));
                    }
                }
            }
            let k = rng.gen_range(1..7usize);
            let max_cost = if trial % 3 == 0 { 25.0 } else { f64::INFINITY };
            for s in 0..n as u32 {
                let table = k_best_paths(&adjacency, s, PathLimits { k, max_cost });
                let all = brute_force(&adjacency, s);
                for (t, all_t) in all.iter().enumerate() {
                    let mut want: Vec<f64> = all_t.iter().copied().filter(|c| *c <= max_cost).collect();
                    want.sort_by(f64::total_cmp);
                    want.truncate(if t == s as usize { 0 } else { k });
                    let got: Vec<f64> = table.paths[t].iter().map(|p| p.cost).collect();
                    assert_eq!(got, want, "trial {trial}, {s} → {t}, k {k}: {adjacency:?}");
                    let mut distinct: Vec<&Vec<u32>> = table.paths[t].iter().map(|p| &p.nodes).collect();
                    distinct.sort();
                    distinct.dedup();
                    assert_eq!(distinct.len(), table.paths[t].len(), "a path listed twice");
                    for p in &table.paths[t] {
                        // Each path is simple, starts at s, ends at t, and costs what its edges sum to.
                        let mut seen = p.nodes.clone();
                        seen.sort();
                        seen.dedup();
                        assert_eq!(seen.len(), p.nodes.len());
                        assert_eq!((p.nodes[0], *p.nodes.last().unwrap() as usize), (s, t));
                        let sum: f64 = p
                            .nodes
                            .windows(2)
                            .map(|w| {
                                adjacency[w[0] as usize].iter().find(|e| e.0 == w[1]).map(|e| e.1).unwrap_or(f64::NAN)
                            })
                            .sum();
                        assert_eq!(sum, p.cost);
                    }
                }
            }
        }
    }

    #[test]
    fn k_best_matches_brute_force_on_a_real_corpus_graph() {
        // The example's three CMU clips (walk, punches, kicks), both directions: real
        // costs (frames × pose distance, not integers) and real structure.
        use crate::kernels::clip_set::load_clip_set;
        use crate::kernels::transition_graph::{cluster, distance, graph};
        let Some(data) = crate::corpus::shared_data() else { return };
        let set =
            load_clip_set(&data.join("bvh/cmu"), "02_01.bvh, 02_05.bvh, 144_05.bvh", 30.0, None, None).unwrap().set;
        let params = distance::DistanceParams::lee_defaults(set.skeleton(), 0.003);
        let clusters = std::sync::Arc::new(
            cluster::cluster(std::sync::Arc::new(set), params, 0.6, crate::cancel::Cancel::NEVER).unwrap(),
        );
        let limits = PathLimits { k: 5, max_cost: f64::INFINITY };
        for direction in [graph::Direction::Directed, graph::Direction::Undirected] {
            let adjacency = graph::build_graph(clusters.clone(), direction, limits).adjacency();
            let mut compared = 0;
            for s in 0..adjacency.len() as u32 {
                let table = k_best_paths(&adjacency, s, limits);
                for (t, all) in brute_force(&adjacency, s).into_iter().enumerate() {
                    let mut want = all;
                    want.sort_by(f64::total_cmp);
                    want.truncate(if t == s as usize { 0 } else { 5 });
                    let got: Vec<f64> = table.paths[t].iter().map(|p| p.cost).collect();
                    assert_eq!(got, want, "{direction:?} {s} → {t}");
                    compared += got.len();
                }
            }
            assert!(compared > 50, "{direction:?}: only {compared} paths compared");
        }
    }

    #[test]
    fn unreachable_targets_and_the_cost_threshold() {
        // 0 → 1 → 3 (cost 2), 0 → 2 → 3 (cost 11); 4 is never reached.
        let adjacency = vec![vec![(1, 1.0), (2, 1.0)], vec![(3, 1.0)], vec![(3, 10.0)], vec![], vec![(0, 1.0)]];
        let limits = |max_cost| PathLimits { k: 5, max_cost };
        let t = k_best_paths(&adjacency, 0, limits(f64::INFINITY));
        assert_eq!(
            t.paths[3],
            vec![CandidatePath { nodes: vec![0, 1, 3], cost: 2.0 }, CandidatePath { nodes: vec![0, 2, 3], cost: 11.0 }]
        );
        assert!(t.paths[4].is_empty() && t.paths[0].is_empty());
        let t = k_best_paths(&adjacency, 0, limits(5.0));
        assert_eq!(t.paths[3], vec![CandidatePath { nodes: vec![0, 1, 3], cost: 2.0 }]);
        let t = k_best_paths(&adjacency, 0, limits(1.5));
        assert!(t.paths[3].is_empty() && t.paths[2].len() == 1);
    }

    #[test]
    fn a_path_through_the_spur_node_is_not_taken_for_a_detour() {
        // The second path to 3 must avoid the cycle 0 → 1 → 2 → 1: the tree path to 2
        // runs through 1, so the detour 0 → 2 → 1 → 3 has to be found by search.
        let adjacency = vec![vec![(1, 1.0), (2, 5.0)], vec![(2, 1.0), (3, 1.0)], vec![(1, 1.0)], vec![]];
        let t = k_best_paths(&adjacency, 0, PathLimits { k: 5, max_cost: f64::INFINITY });
        let nodes: Vec<&[u32]> = t.paths[3].iter().map(|p| p.nodes.as_slice()).collect();
        assert_eq!(nodes, vec![&[0, 1, 3][..], &[0, 2, 1, 3][..]]);
        assert_eq!(t.paths[3][1].cost, 7.0);
    }
}
