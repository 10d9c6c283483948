//! Candidate paths: the K lowest-cost simple paths from one source to every target at once.
//!
//! The paper precomputes K paths for every node pair (O(n²) tables). Here one best-first
//! search per source, run only when a transition first leaves that source and then cached,
//! gives the table for all its targets:
//!
//! 1. Labels are partial paths from the source (cost, last node, visited set), popped in
//!    order of cost.
//! 2. A popped label at node v is *dominated*, and dropped, when K labels already popped at
//!    v cost no more and visited a subset of its nodes: every simple completion of it is
//!    also a simple completion of each of those K, at no higher cost, so it can never be
//!    among the K best for any target. Dominance is exact, unlike a plain "pop each node at
//!    most K times" rule, which can lose simple paths.
//! 3. An undominated label is a path to v (kept while v has fewer than K) and is extended
//!    along every edge to a node it has not visited, while the cost stays within the
//!    threshold.

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
    /// Labels popped by the search (its work, for benchmarks and reports).
    pub labels_popped: usize,
    /// True when the search stopped at its label budget: the table may then miss paths.
    pub truncated: bool,
    /// Undominated labels dropped at full nodes (`max_labels_per_node`): when nonzero the
    /// table may miss some paths.
    pub labels_dropped: usize,
}

/// Search limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathLimits {
    /// K: paths kept per target.
    pub k: usize,
    /// Paths costing more are never kept.
    pub max_cost: f64,
    /// Safety budget of popped labels per search.
    pub max_labels: usize,
    /// Undominated labels kept per node before further ones are dropped. Unbounded, the
    /// search is exact but can grow exponentially on large dense graphs; bounded, its work
    /// is linear in the graph size and the table counts what it dropped.
    pub max_labels_per_node: usize,
}

/// A label: a simple path from the source.
struct Label {
    node: u32,
    cost: f64,
    parent: Option<usize>,
    visited: Vec<u64>,
}

fn has(visited: &[u64], n: u32) -> bool {
    visited[n as usize / 64] & (1 << (n % 64)) != 0
}

fn subset(a: &[u64], b: &[u64]) -> bool {
    a.iter().zip(b).all(|(x, y)| x & !y == 0)
}

/// Heap key ordered by cost (then insertion order, for determinism).
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

/// The K best simple paths from `source` to every node of the graph given by its
/// out-edges `adjacency[v] = [(w, cost)]` (costs ≥ 0).
pub fn k_best_paths(adjacency: &[Vec<(u32, f64)>], source: u32, limits: PathLimits) -> PathTable {
    let n = adjacency.len();
    let words = n.div_ceil(64).max(1);
    let mut table = PathTable { paths: vec![Vec::new(); n], ..Default::default() };
    if source as usize >= n || limits.k == 0 {
        return table;
    }
    let mut visited = vec![0u64; words];
    visited[source as usize / 64] |= 1 << (source % 64);
    let mut labels = vec![Label { node: source, cost: 0.0, parent: None, visited }];
    let mut heap = BinaryHeap::from([Reverse(Key(0.0, 0))]);
    let mut popped: Vec<Vec<usize>> = vec![Vec::new(); n];
    while let Some(Reverse(Key(cost, id))) = heap.pop() {
        if table.labels_popped >= limits.max_labels {
            table.truncated = true;
            break;
        }
        let v = labels[id].node as usize;
        let dominating =
            popped[v].iter().filter(|&&p| labels[p].cost <= cost && subset(&labels[p].visited, &labels[id].visited));
        if dominating.take(limits.k).count() >= limits.k {
            continue;
        }
        if popped[v].len() >= limits.max_labels_per_node {
            table.labels_dropped += 1;
            continue;
        }
        table.labels_popped += 1;
        popped[v].push(id);
        if v != source as usize && table.paths[v].len() < limits.k {
            table.paths[v].push(CandidatePath { nodes: path_of(&labels, id), cost });
        }
        for &(w, c) in &adjacency[v] {
            let next = cost + c;
            if has(&labels[id].visited, w) || next > limits.max_cost {
                continue;
            }
            let mut visited = labels[id].visited.clone();
            visited[w as usize / 64] |= 1 << (w % 64);
            labels.push(Label { node: w, cost: next, parent: Some(id), visited });
            heap.push(Reverse(Key(next, labels.len() - 1)));
        }
    }
    table
}

fn path_of(labels: &[Label], mut id: usize) -> Vec<u32> {
    let mut nodes = vec![labels[id].node];
    while let Some(p) = labels[id].parent {
        nodes.push(labels[p].node);
        id = p;
    }
    nodes.reverse();
    nodes
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
        for trial in 0..60 {
            let n = rng.gen_range(2..8usize);
            let density = rng.gen_range(0.2..0.8);
            let mut adjacency: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
            for (v, out) in adjacency.iter_mut().enumerate() {
                for w in (0..n).filter(|&w| w != v) {
                    if rng.gen_bool(density) {
                        out.push((w as u32, rng.gen_range(1..20) as f64));
                    }
                }
            }
            let k = rng.gen_range(1..5usize);
            let max_cost = if trial % 2 == 0 { f64::INFINITY } else { 25.0 };
            for s in 0..n as u32 {
                let table = k_best_paths(
                    &adjacency,
                    s,
                    PathLimits { k, max_cost, max_labels: usize::MAX, max_labels_per_node: usize::MAX },
                );
                let all = brute_force(&adjacency, s);
                for (t, all_t) in all.iter().enumerate() {
                    let mut want: Vec<f64> = all_t.iter().copied().filter(|c| *c <= max_cost).collect();
                    want.sort_by(f64::total_cmp);
                    want.truncate(if t == s as usize { 0 } else { k });
                    let got: Vec<f64> = table.paths[t].iter().map(|p| p.cost).collect();
                    assert_eq!(got, want, "trial {trial}, {s} → {t}, k {k}: {adjacency:?}");
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
    fn unreachable_targets_and_the_budget() {
        let adjacency = vec![vec![(1, 1.0)], vec![], vec![(0, 1.0)]];
        let t = k_best_paths(
            &adjacency,
            0,
            PathLimits { k: 5, max_cost: f64::INFINITY, max_labels: 100, max_labels_per_node: 100 },
        );
        assert_eq!(t.paths[1], vec![CandidatePath { nodes: vec![0, 1], cost: 1.0 }]);
        assert!(t.paths[2].is_empty() && !t.truncated);
        let t = k_best_paths(
            &adjacency,
            0,
            PathLimits { k: 5, max_cost: f64::INFINITY, max_labels: 1, max_labels_per_node: 100 },
        );
        assert!(t.truncated && t.paths[1].is_empty());
    }
}
