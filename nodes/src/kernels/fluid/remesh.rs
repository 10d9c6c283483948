//! Remeshing every step by a sizing field (Klingner et al. 2006, §6): nodes are placed so
//! that their spacing follows μ(x) = k0 + kd·d(x) + ks·s(x) + kω·ω(x)
//! ([`crate::model::volume::Sizing`]), starting from the previous step's nodes (the paper's
//! warm start, "corrected to match the sizing field of the current step"), then Delaunay'd
//! (TetGen), the tets inside obstacles removed, and the free nodes moved once to the average
//! of the barycentres of their tets (the paper's variant of the node optimisation) and
//! Delaunay'd again; last, the nodes of slivers are moved until no tet has a dihedral angle
//! under [`SLIVER_DEG`] (at most [`SLIVER_ROUNDS`] rounds, see [`unsliver`]).
//!
//! tritet exposes only TetGen's global volume bound, so the nodes are placed here:
//! 1. box corners, then each box edge divided evenly at the smallest μ found along it;
//! 2. each box face filled in its plane as the interior is (step 4), so the face nodes
//!    follow μ;
//! 3. obstacle surface vertices, thinned to spacing ≥ ½ μ; those through a wall (as far as
//!    `fluid.simulate` allows: a sole a hair under the floor) or within ¼ μ of it are put on
//!    it, so the box stays the hull and the floor cuts a character standing on it;
//! 4. the previous step's free nodes, then a fill lattice whose spacing follows μ (cells of
//!    the largest edge, split into ⌈max/μ⌉³ sub-cells, at most 64 a side, each node offset
//!    by a hashed quarter of its sub-cell so that no four are cocircular), each accepted when
//!    it is inside the box at least ½ μ from the walls, outside the obstacles, and no
//!    accepted node lies within 0.7 μ.

use std::collections::HashMap;

use glam::{DVec3, IVec3};

use super::mesh::{MeshError, TetMesh, min_dihedral_deg, signed_volume};
use super::mesher::{Obstacle, RawMesh, box_corners, box_edges, delaunay_tets, winding_number};
use crate::model::volume::Sizing;

/// Closest accepted spacing between two nodes, as a fraction of μ.
const MIN_SPACING: f64 = 0.7;
/// Most sub-cells per fill cell along an axis.
const MAX_SPLIT: u32 = 64;
/// Mixed into the box faces' sub-cell numbers so that their offsets are unrelated to the
/// interior's.
const FACE_SEED: u64 = 0x5EED_F00D_0000_0000;
/// Mixed into node numbers for [`unsliver`]'s trial directions.
const TRIAL_SEED: u64 = 0x7E57_D1E0_0000_0000;
/// Obstacle nodes closer to a wall than this fraction of μ are put on it: a gap a quarter of
/// an edge thin is below the mesh's resolution, and its tets would be flat.
const WALL_SNAP: f64 = 0.25;

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
    /// How many of `fixed` come first and lie on the box; the rest are obstacle surface
    /// vertices.
    pub walls: usize,
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
    // 1. Box edges, each divided evenly at the smallest μ found along it (on 17 points), so
    //    that the two faces meeting there share its nodes.
    let size = hi - lo;
    for (a, b) in box_edges(lo, hi) {
        let h = (0..17).map(|i| mu(a.lerp(b, f64::from(i) / 16.0))).fold(f64::INFINITY, f64::min);
        let n = ((b - a).length() / h).ceil().max(1.0) as usize;
        if n > max_nodes {
            return Err(too_many(n));
        }
        for k in 1..n {
            // Exactly on both of the edge's planes (lerp rounds 2.4 to 2.4000000000000004).
            let p = DVec3::select(a.cmpeq(b), a, a.lerp(b, k as f64 / n as f64));
            accept(p, true, &mut nodes, &mut hash)?;
        }
    }
    // 2. Box faces, filled in their plane as the interior is below (cells of the largest
    //    edge split by μ, hashed offsets, no two nodes within MIN_SPACING μ): the face nodes
    //    follow μ as the air beside them does. (A lattice at each face's smallest μ made the
    //    floor under a character six times denser than the air above it, and the tets between
    //    them slivers.)
    let cell = sizing.max_edge_m;
    for (face, (axis, side)) in [0, 1, 2].into_iter().flat_map(|a| [(a, lo[a]), (a, hi[a])]).enumerate() {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let (cells_u, cells_v) = ((size[u] / cell).ceil() as u32, (size[v] / cell).ceil() as u32);
        for j in 0..cells_v {
            for i in 0..cells_u {
                let mut corner = DVec3::ZERO;
                corner[axis] = side;
                corner[u] = lo[u] + f64::from(i) * cell;
                corner[v] = lo[v] + f64::from(j) * cell;
                let mut middle = corner;
                middle[u] += 0.5 * cell;
                middle[v] += 0.5 * cell;
                let n = (cell / mu(middle)).ceil().clamp(1.0, f64::from(MAX_SPLIT)) as u32;
                let sub = cell / f64::from(n);
                let cell_index =
                    ((face as u64 * u64::from(cells_v) + u64::from(j)) * u64::from(cells_u)) + u64::from(i);
                for c in 0..n * n {
                    let jitter = sub_cell_jitter(FACE_SEED ^ (cell_index * u64::from(MAX_SPLIT.pow(2)) + u64::from(c)));
                    let mut p = corner;
                    p[u] += (f64::from(c % n) + 0.5 + jitter.x) * sub;
                    p[v] += (f64::from(c / n) + 0.5 + jitter.y) * sub;
                    let inside = p[u] > lo[u] && p[u] < hi[u] && p[v] > lo[v] && p[v] < hi[v];
                    if inside && !hash.any_within(p, MIN_SPACING * mu(p)) {
                        accept(p, true, &mut nodes, &mut hash)?;
                    }
                }
            }
        }
    }
    nodes.walls = nodes.fixed.len();
    // 3. Obstacle surfaces, thinned, those through a wall or within WALL_SNAP μ of it put on
    //    it (a sole a hair above the floor made tets of the floor and the sole flat).
    for p in obstacles.iter().flat_map(|o| &o.positions_m) {
        let mut inside = p.clamp(lo, hi);
        let snap = WALL_SNAP * mu(inside);
        for a in 0..3 {
            if inside[a] - lo[a] < snap {
                inside[a] = lo[a];
            } else if hi[a] - inside[a] < snap {
                inside[a] = hi[a];
            }
        }
        if !hash.any_within(inside, 0.5 * mu(inside)) {
            accept(inside, true, &mut nodes, &mut hash)?;
        }
    }
    // 4. Interior: previous nodes first, then the fill lattice.
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
/// and without flat ones (TetGen fills four coplanar nodes, such as obstacle nodes put on a
/// wall beside the wall's own, with zero-volume tets; dropping one leaves its other
/// diagonal on the boundary).
pub fn carve(points: &[DVec3], obstacles: &[Obstacle]) -> Result<TetMesh, MeshError> {
    let (nodes, kept) = fluid_tets(points, &solids(obstacles))?;
    largest_component(TetMesh::new(nodes, kept)?)
}

/// The Delaunay nodes and tets of `points` that carving keeps ([`is_fluid`]), before the
/// dual geometry of a [`TetMesh`] is built (the remesh's intermediate meshes need none).
fn fluid_tets(points: &[DVec3], solids: &[Solid<'_>]) -> Result<RawMesh, MeshError> {
    let (nodes, tets) = delaunay_tets(points)?;
    let kept = tets.into_iter().filter(|tet| is_fluid(tet.map(|i| nodes[i as usize]), solids)).collect();
    Ok((nodes, kept))
}

/// Whether carving keeps the tet `p`: it is not flat and its barycentre is outside `solids`.
fn is_fluid(p: [DVec3; 4], solids: &[Solid<'_>]) -> bool {
    let [a, b, c, d] = p;
    let longest = [b - a, c - a, d - a, c - b, d - b, d - c].iter().map(|e| e.length()).fold(0.0, f64::max);
    let flat = signed_volume(a, b, c, d).abs() <= 1e-9 * longest.powi(3);
    !flat && !solids.iter().any(|s| s.contains((a + b + c + d) * 0.25))
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
/// the next step's warm start), Delaunay and carve again, then up to [`SLIVER_ROUNDS`] rounds
/// of [`unsliver`]. Fails with [`MeshError::TooManyTets`] above `max_tets`.
pub fn mesh_nodes(nodes: &mut Nodes, obstacles: &[Obstacle], max_tets: usize) -> Result<TetMesh, MeshError> {
    let solids = solids(obstacles);
    let mut points: Vec<DVec3> = nodes.fixed.iter().chain(&nodes.free).copied().collect();
    let (first_nodes, first_tets) = fluid_tets(&points, &solids)?;
    let fixed = nodes.fixed.len();
    let mut sum = vec![DVec3::ZERO; points.len()];
    let mut weight = vec![0.0; points.len()];
    for tet in &first_tets {
        let [a, b, c, d] = tet.map(|i| first_nodes[i as usize]);
        let (centroid, volume) = ((a + b + c + d) * 0.25, signed_volume(a, b, c, d).abs());
        for &i in tet {
            sum[i as usize] += centroid * volume;
            weight[i as usize] += volume;
        }
    }
    for i in fixed..points.len() {
        if weight[i] > 0.0 {
            points[i] = sum[i] / weight[i];
        }
    }
    nodes.free.copy_from_slice(&points[fixed..]);
    let (mut tet_nodes, mut tets) = fluid_tets(&points, &solids)?;
    for _ in 0..SLIVER_ROUNDS {
        if !unsliver(&tet_nodes, &tets, nodes, &solids)? {
            break;
        }
        let points: Vec<DVec3> = nodes.fixed.iter().chain(&nodes.free).copied().collect();
        (tet_nodes, tets) = fluid_tets(&points, &solids)?;
    }
    let mesh = largest_component(TetMesh::new(tet_nodes, tets)?)?;
    if mesh.tet_count() > max_tets {
        return Err(MeshError::TooManyTets { tets: mesh.tet_count(), max_tets });
    }
    Ok(mesh)
}

/// Tets whose smallest dihedral angle is below this many degrees are slivers: four nearly
/// coplanar nodes that a Delaunay mesh of well-spaced nodes still makes (their circumcentre,
/// a pressure sample, lies far outside them and their faces' dual lengths are near zero).
pub const SLIVER_DEG: f64 = 10.0;
/// Most rounds of [`unsliver`] per remesh, each one Delaunay and carve.
pub const SLIVER_ROUNDS: usize = 8;
/// Trial moves of a sliver's node away from the plane of the other three, as fractions of
/// its shortest edge.
const LIFT_STEPS: [f64; 3] = [0.1, 0.2, 0.35];
/// Trial moves along hashed directions per node, when no lift is good enough ...
const TRIAL_DIRECTIONS: u64 = 6;
/// ... each this fraction of its shortest edge.
const HASHED_STEP: f64 = 0.2;

/// Moves nodes so that the next Delaunay has no slivers, as Tournois et al. (2009) perturb
/// them: for each sliver, each of its movable nodes (free ones, and box nodes inside one
/// face, which move in its plane) is tried at a few positions (away from the plane of the
/// other three, and along hashed directions), each judged by the smallest dihedral angle of
/// the Delaunay tets of its neighbourhood (two rings of the mesh) that the move changes; the
/// best trial is kept when that angle beats the sliver's. Trials stay in the box and out of
/// the obstacles. A sliver with nothing to move drops the obstacle surface node nearest the
/// plane of its other three (the obstacle is sampled more thinly there; carving still tests
/// tets against the whole surface); one of box edge and corner nodes only stays.
/// Returns whether anything changed.
fn unsliver(
    tet_nodes: &[DVec3],
    tets: &[[u32; 4]],
    nodes: &mut Nodes,
    solids: &[Solid<'_>],
) -> Result<bool, MeshError> {
    let dihedral = |t: usize| min_dihedral_deg(tets[t].map(|i| tet_nodes[i as usize]));
    let slivers: Vec<usize> = (0..tets.len()).filter(|&t| dihedral(t) < SLIVER_DEG).collect();
    if slivers.is_empty() {
        return Ok(false);
    }
    let fixed = nodes.fixed.len();
    let mut points = tet_nodes.to_vec();
    let (lo, hi) = points.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    // The axes node i may move along: all for free nodes, the face's plane for a box node on
    // one face, none for box edges and corners and obstacle nodes.
    let movable = |i: usize, p: DVec3| -> DVec3 {
        if i >= fixed {
            return DVec3::ONE;
        }
        if i < nodes.walls {
            let on = DVec3::select(p.cmpeq(lo) | p.cmpeq(hi), DVec3::ONE, DVec3::ZERO);
            if on.element_sum() == 1.0 {
                return DVec3::ONE - on;
            }
        }
        DVec3::ZERO
    };
    // Tets per node (compressed rows), for the rings of the few nodes tried.
    let mut row = vec![0usize; points.len() + 1];
    tets.iter().flatten().for_each(|&i| row[i as usize + 1] += 1);
    (0..points.len()).for_each(|i| row[i + 1] += row[i]);
    let mut incident = vec![0u32; row[points.len()]];
    let mut filled = row.clone();
    for (t, tet) in tets.iter().enumerate() {
        for &i in tet {
            incident[filled[i as usize]] = t as u32;
            filled[i as usize] += 1;
        }
    }
    let neighbours = |nodes: &[usize]| -> Vec<u32> {
        let mut ring: Vec<u32> =
            nodes.iter().flat_map(|&i| incident[row[i]..row[i + 1]].iter().flat_map(|&t| tets[t as usize])).collect();
        ring.sort_unstable();
        ring.dedup();
        ring.retain(|j| !nodes.contains(&(*j as usize)));
        ring
    };
    // The smallest dihedral angle near node i placed at `at`: the Delaunay tets of its two
    // rings whose nodes are all i or its first ring (the tets a move of i can change).
    let local_quality = |points: &[DVec3], i: usize, first: &[u32], at: DVec3| -> Result<f64, MeshError> {
        let mut around: Vec<usize> = first.iter().map(|&j| j as usize).collect();
        around.push(i);
        let second = neighbours(&around);
        let local: Vec<DVec3> =
            std::iter::once(at).chain(first.iter().chain(&second).map(|&j| points[j as usize])).collect();
        let (local_nodes, local_tets) = delaunay_tets(&local)?;
        let near = |k: u32| (k as usize) <= first.len();
        Ok(local_tets
            .iter()
            .filter(|tet| tet.iter().all(|&k| near(k)))
            .map(|tet| tet.map(|k| local_nodes[k as usize]))
            .filter(|q| is_fluid(*q, solids))
            .map(min_dihedral_deg)
            .fold(180.0, f64::min))
    };
    let mut changed = false;
    let mut drop = vec![false; fixed];
    for t in slivers {
        let tet = tets[t].map(|i| i as usize);
        let p = tet.map(|i| points[i]);
        let sliver = min_dihedral_deg(p);
        if sliver >= SLIVER_DEG {
            continue; // an earlier move mended it
        }
        // Unit direction from the plane of the other three to local node k, and k's height.
        let lift = |k: usize| {
            let [a, b, c] = [(k + 1) % 4, (k + 2) % 4, (k + 3) % 4].map(|j| p[j]);
            let normal = (b - a).cross(c - a).normalize_or_zero();
            let height = (p[k] - a).dot(normal);
            (normal * height.signum(), height.abs())
        };
        let mut best: Option<(usize, DVec3, f64)> = None;
        let mut any_movable = false;
        'search: for k in 0..4 {
            let i = tet[k];
            let axes = movable(i, p[k]);
            if axes == DVec3::ZERO {
                continue;
            }
            any_movable = true;
            let first = neighbours(&[i]);
            let shortest = first.iter().map(|&j| (points[j as usize] - p[k]).length()).fold(f64::INFINITY, f64::min);
            // Trials as (direction, fraction of the shortest edge): the lift first.
            let lift_trials = LIFT_STEPS.map(|step| (lift(k).0, step));
            let hashed = (0..TRIAL_DIRECTIONS)
                .map(|d| (sub_cell_jitter(TRIAL_SEED ^ ((i as u64) << 8 | d)).normalize_or_zero(), HASHED_STEP));
            // A trial must beat the sliver (so the smallest angle around the node rises) and
            // every trial kept so far.
            let mut here = sliver.max(best.map_or(f64::NEG_INFINITY, |b| b.2));
            for (direction, step) in lift_trials.into_iter().chain(hashed) {
                let along = direction * axes;
                if along.length() < 0.5 {
                    continue; // mostly out of a box node's face
                }
                let to = p[k] + along.normalize_or_zero() * step * shortest;
                let inside = (0..3).all(|a| axes[a] == 0.0 || (to[a] > lo[a] && to[a] < hi[a]));
                if !inside || solids.iter().any(|s| s.contains(to)) {
                    continue;
                }
                let quality = local_quality(&points, i, &first, to)?;
                if quality > here {
                    here = quality;
                    best = Some((i, to, quality));
                    if quality >= SLIVER_DEG {
                        break 'search;
                    }
                }
            }
        }
        if let Some((i, to, _)) = best {
            points[i] = to;
            changed = true;
        } else if !any_movable {
            let obstacle_nodes = (0..4).filter(|&k| (nodes.walls..fixed).contains(&tet[k]));
            if let Some(k) = obstacle_nodes.min_by(|&a, &b| lift(a).1.total_cmp(&lift(b).1)) {
                drop[tet[k]] = true;
                changed = true;
            }
        }
    }
    nodes.fixed.copy_from_slice(&points[..fixed]);
    nodes.free.copy_from_slice(&points[fixed..]);
    if drop.iter().any(|d| *d) {
        let mut index = 0;
        nodes.fixed.retain(|_| {
            index += 1;
            !drop[index - 1]
        });
    }
    Ok(changed)
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
