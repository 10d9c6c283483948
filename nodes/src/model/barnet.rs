//! Bar-nets (force density method, Schek 1974): a control mesh seen as a network of bars
//! between nodes, some fixed, some free to find their equilibrium.

use std::sync::Arc;

use super::mesh::Mesh;

/// Why a bar-net is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BarNetError {
    /// A bar names a node the control mesh does not have, or joins a node to itself.
    #[error("bar {bar} joins nodes {a} and {b}, but the net has {nodes} nodes (and a bar needs two different ones)")]
    BadBar {
        /// Bar index.
        bar: usize,
        /// First node.
        a: u32,
        /// Second node.
        b: u32,
        /// Node count.
        nodes: usize,
    },
    /// A force density is not a positive finite number.
    #[error("bar {bar} has force density {q}; force densities must be positive and finite")]
    BadForceDensity {
        /// Bar index.
        bar: usize,
        /// The rejected value.
        q: f64,
    },
    /// The free/fixed flags do not match the node count.
    #[error("{flags} free/fixed flags for {nodes} nodes")]
    BadFlags {
        /// Flags given.
        flags: usize,
        /// Node count.
        nodes: usize,
    },
    /// No node is free, so there is nothing to solve.
    #[error("no node is free: select the region that should deform")]
    NoFreeNode,
    /// Some free nodes have no path of bars to a fixed node: their equilibrium is not unique.
    #[error("{count} free nodes (e.g. node {example}) are not connected by bars to any fixed node")]
    Floating {
        /// How many free nodes float.
        count: usize,
        /// One of them.
        example: usize,
    },
}

/// A bar-net coupled to a control mesh: node `i` is vertex `i` of [`BarNet::control`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BarNet {
    /// The control mesh (usually skinned): its vertices are the nodes, its rest positions
    /// the net's rest shape.
    pub control: Arc<Mesh>,
    /// Bars as node index pairs, each once.
    pub bars: Vec<[u32; 2]>,
    /// Force density (force per unit length, N/m) of each bar: stiffer bars pull their
    /// nodes closer together.
    pub force_density: Vec<f64>,
    /// Per node: free (moves to balance the forces) or fixed (follows the control mesh).
    pub free: Vec<bool>,
}

impl BarNet {
    /// Validates bars, force densities and the free selection.
    pub fn new(
        control: Arc<Mesh>,
        bars: Vec<[u32; 2]>,
        force_density: Vec<f64>,
        free: Vec<bool>,
    ) -> Result<Self, BarNetError> {
        let nodes = control.positions.len();
        if free.len() != nodes {
            return Err(BarNetError::BadFlags { flags: free.len(), nodes });
        }
        for (bar, &[a, b]) in bars.iter().enumerate() {
            if a as usize >= nodes || b as usize >= nodes || a == b {
                return Err(BarNetError::BadBar { bar, a, b, nodes });
            }
        }
        if let Some(bar) = force_density.iter().position(|q| !(q.is_finite() && *q > 0.0)) {
            return Err(BarNetError::BadForceDensity { bar, q: force_density[bar] });
        }
        if force_density.len() != bars.len() {
            return Err(BarNetError::BadForceDensity { bar: bars.len().min(force_density.len()), q: f64::NAN });
        }
        if !free.iter().any(|f| *f) {
            return Err(BarNetError::NoFreeNode);
        }
        // A free node is anchored when a path of bars reaches a fixed node; flood from the
        // fixed nodes.
        let mut neighbours = vec![Vec::new(); nodes];
        for &[a, b] in &bars {
            neighbours[a as usize].push(b as usize);
            neighbours[b as usize].push(a as usize);
        }
        let mut anchored: Vec<bool> = free.iter().map(|f| !f).collect();
        let mut stack: Vec<usize> = (0..nodes).filter(|&i| anchored[i]).collect();
        while let Some(i) = stack.pop() {
            for &n in &neighbours[i] {
                if !anchored[n] {
                    anchored[n] = true;
                    stack.push(n);
                }
            }
        }
        let floating: Vec<usize> = (0..nodes).filter(|&i| !anchored[i]).collect();
        if let Some(&example) = floating.first() {
            return Err(BarNetError::Floating { count: floating.len(), example });
        }
        Ok(BarNet { control, bars, force_density, free })
    }

    /// Number of nodes (control mesh vertices).
    pub fn node_count(&self) -> usize {
        self.free.len()
    }

    /// Number of free nodes.
    pub fn free_count(&self) -> usize {
        self.free.iter().filter(|f| **f).count()
    }
}
