//! Remeshing every step by a sizing field (Klingner et al. 2006, §6): nodes are placed so
//! that their spacing follows μ(x) = k0 + kd·d(x) + ks·s(x) + kω·ω(x)
//! ([`crate::model::volume::Sizing`]), starting from the previous step's nodes (the paper's
//! warm start, "corrected to match the sizing field of the current step"), then Delaunay'd
//! (TetGen), the tets inside obstacles removed, and the free nodes moved once to the average
//! of the barycentres of their tets (the paper's variant of the node optimisation) and
//! Delaunay'd again.
//!
//! tritet exposes only TetGen's global volume bound, so the nodes are placed here:
//! 1. box corners, then each box face on a square lattice at the smallest μ found on it;
//! 2. obstacle surface vertices, thinned to spacing ≥ ½ μ; those through a wall (as far as
//!    `fluid.simulate` allows: a sole a hair under the floor) are put on it, so the box
//!    stays the hull and the floor cuts a character standing on it;
//! 3. the previous step's free nodes, then a fill lattice whose spacing follows μ (cells of
//!    the largest edge, split into ⌈max/μ⌉³ sub-cells, at most 64 a side, each node offset
//!    by a hashed quarter of its sub-cell so that no four are cocircular), each accepted when
//!    it is inside the box at least ½ μ from the walls, outside the obstacles, and no
//!    accepted node lies within 0.7 μ.

use std::collections::HashMap;

use glam::{DVec3, IVec3};

use super::mesh::{MeshError, TetMesh, signed_volume};
use super::mesher::{Obstacle, box_corners, delaunay_tets, winding_number};
use crate::model::volume::Sizing;

/// Closest accepted spacing between two nodes, as a fraction of μ.
const MIN_SPACING: f64 = 0.7;
/// Most sub-cells per fill cell along an axis.
const MAX_SPLIT: u32 = 64;

/// Mean tets per node of a Delaunay mesh of well-spaced nodes (measured 5.5–6.5).
pub const TETS_PER_NODE: f64 = 6.5;

/// Nodes in hashed cells of one size: "is any node within r of p" in a few lookups.
struct SpatialHash {
    cell_m: f64,
    cells: HashMap<IVec3, Vec<DVec3>>,
}

impl SpatialHash {
    fn new(cell_m: f64) -> Self {
        SpatialHash { cell_m, cells: HashMap::new() }
    }
    fn key(&self, p: DVec3) -> IVec3 {
        (p / self.cell_m).floor().as_ivec3()
    }
    fn insert(&mut self, p: DVec3) {
        self.cells.entry(self.key(p)).or_default().push(p);
    }
    /// Whether a node lies within `r_m` (≤ the cell size times `reach`) of `p`.
    fn any_within(&self, p: DVec3, r_m: f64) -> bool {
        let reach = (r_m / self.cell_m).ceil() as i32;
        let c = self.key(p);
        for dz in -reach..=reach {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    if let Some(nodes) = self.cells.get(&(c + IVec3::new(dx, dy, dz)))
                        && nodes.iter().any(|q| (*q - p).length_squared() < r_m * r_m)
                    {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// An obstacle with its bounding box, for quick inside tests.
pub(super) struct Solid<'a> {
    surface: &'a Obstacle,
    lo: DVec3,
    hi: DVec3,
}

impl Solid<'_> {
    /// Whether `p` is inside (winding number > ½), tested only within the bounding box.
    pub(super) fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.lo).all() && p.cmple(self.hi).all() && winding_number(self.surface, p) > 0.5
    }
}

/// The obstacles with their bounding boxes.
pub(super) fn solids(obstacles: &[Obstacle]) -> Vec<Solid<'_>> {
    obstacles
        .iter()
        .map(|o| Solid {
            surface: o,
            lo: o.positions_m.iter().copied().fold(DVec3::INFINITY, DVec3::min),
            hi: o.positions_m.iter().copied().fold(DVec3::NEG_INFINITY, DVec3::max),
        })
        .collect()
}

/// Distance from `p` to the nearest obstacle surface vertex (∞ without obstacles): the
/// d(x) of the sizing field, at the resolution of the obstacle meshes.
pub struct ObstacleDistance {
    hash: SpatialHash,
    any: bool,
}

impl ObstacleDistance {
    /// Indexes the obstacles' vertices.
    pub fn new(obstacles: &[Obstacle], cell_m: f64) -> Self {
        let mut hash = SpatialHash::new(cell_m);
        obstacles.iter().flat_map(|o| &o.positions_m).for_each(|p| hash.insert(*p));
        ObstacleDistance { any: !hash.cells.is_empty(), hash }
    }

    /// d(p), metres, searched out to `limit_m` (beyond it, `limit_m`).
    pub fn at(&self, p: DVec3, limit_m: f64) -> f64 {
        if !self.any {
            return limit_m;
        }
        let reach = (limit_m / self.hash.cell_m).ceil() as i32;
        let c = self.hash.key(p);
        let mut best = limit_m * limit_m;
        for dz in -reach..=reach {
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    if let Some(nodes) = self.hash.cells.get(&(c + IVec3::new(dx, dy, dz))) {
                        for q in nodes {
                            best = best.min((*q - p).length_squared());
                        }
                    }
                }
            }
        }
        best.sqrt()
    }
}

/// The domain's nodes for one step: `fixed` (box and obstacle surfaces, never moved) and
/// `free` (interior, relaxed).
#[derive(Debug, Clone, Default)]
pub struct Nodes {
    /// Box corners, box-face lattices and obstacle surface vertices.
    pub fixed: Vec<DVec3>,
    /// Interior nodes.
    pub free: Vec<DVec3>,
}

/// Places the nodes of the box `lo..hi` minus `obstacles` by the sizing `mu(x)` (metres,
/// within `sizing`'s clamp), keeping those of `previous` that still fit first. Refuses with
/// [`MeshError::TooManyTets`] once the nodes would give more than `max_tets` tets.
pub fn place_nodes(
    lo: DVec3,
    hi: DVec3,
    obstacles: &[Obstacle],
    previous: &[DVec3],
    sizing: &Sizing,
    mu: &(dyn Fn(DVec3) -> f64 + Sync),
    max_tets: usize,
) -> Result<Nodes, MeshError> {
    let max_nodes = (max_tets as f64 / TETS_PER_NODE).ceil() as usize;
    let too_many = |n: usize| MeshError::TooManyTets { tets: (n as f64 * TETS_PER_NODE) as usize, max_tets };
    let mut hash = SpatialHash::new(sizing.max_edge_m.max(1e-6));
    let mut nodes = Nodes::default();
    let accept = |p: DVec3, fixed: bool, nodes: &mut Nodes, hash: &mut SpatialHash| -> Result<(), MeshError> {
        if nodes.fixed.len() + nodes.free.len() >= max_nodes {
            return Err(too_many(nodes.fixed.len() + nodes.free.len() + 1));
        }
        hash.insert(p);
        if fixed {
            nodes.fixed.push(p)
        } else {
            nodes.free.push(p)
        }
        Ok(())
    };
    for c in box_corners(lo, hi) {
        accept(c, true, &mut nodes, &mut hash)?;
    }
    // 1. Box faces: a lattice per face at its smallest μ (sampled on 9 × 9 points).
    let size = hi - lo;
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [lo[axis], hi[axis]] {
            let at = |a: f64, b: f64| {
                let mut p = DVec3::ZERO;
                p[axis] = side;
                p[u] = lo[u] + a * size[u];
                p[v] = lo[v] + b * size[v];
                p
            };
            let h = (0..81).map(|i| mu(at((i % 9) as f64 / 8.0, (i / 9) as f64 / 8.0))).fold(f64::INFINITY, f64::min);
            let (nu, nv) = ((size[u] / h).ceil().max(1.0) as usize, (size[v] / h).ceil().max(1.0) as usize);
            if (nu + 1) * (nv + 1) > max_nodes {
                return Err(too_many((nu + 1) * (nv + 1)));
            }
            for j in 0..=nv {
                for i in 0..=nu {
                    let corner_u = i == 0 || i == nu;
                    let corner_v = j == 0 || j == nv;
                    // Edges of the box are shared by two faces: each takes them once
                    // (the lower axis index), corners are already in.
                    if corner_u && corner_v {
                        continue;
                    }
                    let p = at(i as f64 / nu as f64, j as f64 / nv as f64);
                    if (corner_u || corner_v) && hash.any_within(p, 1e-9 * size.length()) {
                        continue;
                    }
                    accept(p, true, &mut nodes, &mut hash)?;
                }
            }
        }
    }
    // 2. Obstacle surfaces, thinned, those through a wall put on it.
    for p in obstacles.iter().flat_map(|o| &o.positions_m) {
        let inside = p.clamp(lo, hi);
        if !hash.any_within(inside, 0.5 * mu(inside)) {
            accept(inside, true, &mut nodes, &mut hash)?;
        }
    }
    // 3. Interior: previous nodes first, then the fill lattice.
    let solids = solids(obstacles);
    let offer = |p: DVec3, nodes: &mut Nodes, hash: &mut SpatialHash| -> Result<(), MeshError> {
        let h = mu(p);
        let margin = 0.5 * h;
        if !(p.cmpgt(lo + margin).all() && p.cmplt(hi - margin).all()) || hash.any_within(p, MIN_SPACING * h) {
            return Ok(());
        }
        if solids.iter().any(|s| s.contains(p)) {
            return Ok(());
        }
        accept(p, false, nodes, hash)
    };
    for p in previous {
        offer(*p, &mut nodes, &mut hash)?;
    }
    let cell = sizing.max_edge_m;
    let cells = (size / cell).ceil().as_uvec3();
    for k in 0..cells.z {
        for j in 0..cells.y {
            for i in 0..cells.x {
                let corner = lo + DVec3::new(i as f64, j as f64, k as f64) * cell;
                let n = (cell / mu(corner + DVec3::splat(0.5 * cell))).ceil().clamp(1.0, f64::from(MAX_SPLIT)) as u32;
                let sub = cell / f64::from(n);
                let cell_index = (u64::from(k) * u64::from(cells.y) + u64::from(j)) * u64::from(cells.x) + u64::from(i);
                for c in 0..n * n * n {
                    let (a, b, d) = (c % n, (c / n) % n, c / (n * n));
                    // A fixed offset per sub-cell of the whole box, hashed from its index,
                    // breaks the lattice's cocircular ties without randomness (the same inputs
                    // give the same mesh). Offsets repeated from cell to cell left a cubic
                    // lattice wherever μ is at its maximum: four cocircular nodes per cube
                    // face, whose flat tets were dropped and left walls inside the fluid.
                    let jitter = sub_cell_jitter(cell_index * u64::from(MAX_SPLIT.pow(3)) + u64::from(c));
                    let p = corner + (DVec3::new(f64::from(a), f64::from(b), f64::from(d)) + 0.5 + jitter) * sub;
                    offer(p, &mut nodes, &mut hash)?;
                }
            }
        }
    }
    Ok(nodes)
}

/// An offset in [−¼, ¼)³ of a sub-cell for the sub-cell numbered `index`: three fractions
/// of a SplitMix64 hash of the index, so neighbouring sub-cells get unrelated offsets.
fn sub_cell_jitter(index: u64) -> DVec3 {
    let mut z = index.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    // Three 21-bit fractions of the 64-bit hash.
    let fraction = |shift: u32| ((z >> shift) & 0x1F_FFFF) as f64 / f64::from(1u32 << 21);
    DVec3::new(fraction(0), fraction(21), fraction(42)) * 0.5 - 0.25
}

/// The Delaunay tets of `points`, without those whose barycentre lies inside an obstacle
/// and without flat ones (TetGen fills the cocircular squares of the box-face lattices with
/// zero-volume tets; dropping one leaves the other diagonal of its square on the boundary).
pub fn carve(points: &[DVec3], obstacles: &[Obstacle]) -> Result<TetMesh, MeshError> {
    let (nodes, tets) = delaunay_tets(points)?;
    let solids = solids(obstacles);
    let keep = |tet: &[u32; 4]| {
        let [a, b, c, d] = tet.map(|i| nodes[i as usize]);
        let longest = [b - a, c - a, d - a, c - b, d - b, d - c].iter().map(|e| e.length()).fold(0.0, f64::max);
        let flat = signed_volume(a, b, c, d).abs() <= 1e-9 * longest.powi(3);
        !flat && !solids.iter().any(|s| s.contains((a + b + c + d) * 0.25))
    };
    let kept: Vec<[u32; 4]> = tets.into_iter().filter(keep).collect();
    let mesh = TetMesh::new(nodes, kept)?;
    largest_component(mesh)
}

/// The mesh's largest face-connected part. Obstacles that touch or overlap (a character's
/// limbs) can seal off pockets of air; such a pocket has no open face, so its pressure is
/// undetermined and its walls' fluxes need not balance: it is treated as solid.
fn largest_component(mesh: TetMesh) -> Result<TetMesh, MeshError> {
    let n = mesh.tet_count();
    let mut component = vec![u32::MAX; n];
    let mut sizes = Vec::new();
    for seed in 0..n {
        if component[seed] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut stack = vec![seed];
        component[seed] = id;
        let mut size = 0usize;
        while let Some(t) = stack.pop() {
            size += 1;
            for &f in &mesh.tet_faces[t] {
                for other in mesh.face_tets[f as usize] {
                    if other != super::mesh::NO_TET && component[other as usize] == u32::MAX {
                        component[other as usize] = id;
                        stack.push(other as usize);
                    }
                }
            }
        }
        sizes.push(size);
    }
    if sizes.len() <= 1 {
        return Ok(mesh);
    }
    let largest = (0..sizes.len()).max_by_key(|&c| sizes[c]).unwrap_or(0) as u32;
    let tets = mesh.tets.iter().zip(&component).filter(|(_, c)| **c == largest).map(|(t, _)| *t).collect();
    TetMesh::new(mesh.nodes_m, tets)
}

/// Meshes the nodes: Delaunay and carve, move every free node to the volume-weighted
/// average of the barycentres of its tets (once; `nodes.free` keeps the moved positions,
/// the next step's warm start), Delaunay and carve again. Fails with
/// [`MeshError::TooManyTets`] above `max_tets`.
pub fn mesh_nodes(nodes: &mut Nodes, obstacles: &[Obstacle], max_tets: usize) -> Result<TetMesh, MeshError> {
    let mut points: Vec<DVec3> = nodes.fixed.iter().chain(&nodes.free).copied().collect();
    let first = carve(&points, obstacles)?;
    let fixed = nodes.fixed.len();
    let mut sum = vec![DVec3::ZERO; points.len()];
    let mut weight = vec![0.0; points.len()];
    for (t, tet) in first.tets.iter().enumerate() {
        let (c, v) = (first.tet_centroid(t), first.tet_volume_m3[t]);
        for &i in tet {
            sum[i as usize] += c * v;
            weight[i as usize] += v;
        }
    }
    for i in fixed..points.len() {
        if weight[i] > 0.0 {
            points[i] = sum[i] / weight[i];
        }
    }
    nodes.free.copy_from_slice(&points[fixed..]);
    let mesh = carve(&points, obstacles)?;
    if mesh.tet_count() > max_tets {
        return Err(MeshError::TooManyTets { tets: mesh.tet_count(), max_tets });
    }
    Ok(mesh)
}

/// Vorticity magnitude per tet (1/s): the curl of the linear interpolant of the node
/// velocities, Σ_k ∇λ_k × u_k with ∇λ_k = −A_k n_k / (3V) (n_k the outward normal of the
/// face opposite vertex k).
pub fn tet_vorticity(mesh: &TetMesh, node_velocity_m_s: &[DVec3]) -> Vec<f64> {
    (0..mesh.tet_count())
        .map(|t| {
            let faces = mesh.outward_faces(t);
            let v = mesh.tet_volume_m3[t];
            (0..4)
                .map(|k| {
                    let (n, area, _) = faces[k];
                    (-n * area / (3.0 * v)).cross(node_velocity_m_s[mesh.tets[t][k] as usize])
                })
                .sum::<DVec3>()
                .length()
        })
        .collect()
}
