//! Tetrahedral meshing through TetGen (the `tritet` crate), behind the `tetgen` feature
//! because TetGen is AGPL-3.0.
//!
//! Two entry points:
//! - [`mesh_box`]: a quality, constrained Delaunay mesh of an axis-aligned box minus closed
//!   triangle-mesh obstacles (TetGen switches `pzAf`, `a<max volume>`, `q<max radius–edge
//!   ratio>`: tritet 3.4 passes its "min angle" argument as TetGen's `-q` value, which is the
//!   radius–edge bound; TetGen's own default bound is 2.0);
//! - [`delaunay`]: the Delaunay tetrahedralisation of a point set (switch `z`).
//!
//! TetGen keeps process-wide state, so every call holds one process-wide lock.

use std::sync::Mutex;

use glam::DVec3;
use tritet::Tetgen;

use super::mesh::{MeshError, TetMesh};

static TETGEN_LOCK: Mutex<()> = Mutex::new(());

/// A closed, outward-oriented triangle surface the fluid flows around.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    /// Vertex positions, metres.
    pub positions_m: Vec<DVec3>,
    /// Triangles (vertex indices), counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
}

/// The eight corners of the axis-aligned box `lo`..`hi`; corner `i` takes `hi` on x, y, z
/// where bits 0, 1, 2 of `i` are set.
pub fn box_corners(lo: DVec3, hi: DVec3) -> [DVec3; 8] {
    std::array::from_fn(|i| {
        DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The twelve edges of the box `lo..hi`, as pairs of [`box_corners`].
pub fn box_edges(lo: DVec3, hi: DVec3) -> impl Iterator<Item = (DVec3, DVec3)> {
    let corners = box_corners(lo, hi);
    // Corner i's coordinate along axis a is hi's when bit a of i is set.
    (0..8).flat_map(move |i| {
        [1, 2, 4].into_iter().filter(move |bit| i & bit == 0).map(move |bit| (corners[i], corners[i | bit]))
    })
}

impl Obstacle {
    /// An axis-aligned box obstacle (a dropped crate, a test solid) from its centre and half
    /// extents, metres: twelve triangles, counter-clockwise seen from outside.
    pub fn cuboid(centre_m: DVec3, half_m: DVec3) -> Obstacle {
        let positions_m = box_corners(centre_m - half_m, centre_m + half_m).to_vec();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        Obstacle { positions_m, triangles }
    }

    /// Every triangle split into four at its edge midpoints; neighbours share the midpoint of
    /// their common edge, so a closed surface stays closed and keeps its orientation.
    pub fn subdivided(&self) -> Obstacle {
        let mut positions_m = self.positions_m.clone();
        let mut middle: std::collections::BTreeMap<(u32, u32), u32> = std::collections::BTreeMap::new();
        let mut split = |a: u32, b: u32, positions: &mut Vec<DVec3>| {
            *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let at = |i: u32| positions.get(i as usize).copied().unwrap_or(DVec3::ZERO);
                positions.push(0.5 * (at(a) + at(b)));
                positions.len() as u32 - 1
            })
        };
        let triangles = self
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) =
                    (split(a, b, &mut positions_m), split(b, c, &mut positions_m), split(c, a, &mut positions_m));
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
        Obstacle { positions_m, triangles }
    }

    /// A closed sphere (a ball, a test solid): an octahedron subdivided `levels` times, each
    /// time its vertices pushed back onto the sphere; 8·4^levels triangles with edges of
    /// about 1.4·radius / 2^levels, counter-clockwise seen from outside.
    pub fn sphere(centre_m: DVec3, radius_m: f64, levels: usize) -> Obstacle {
        let mut unit = Obstacle {
            positions_m: vec![DVec3::X, -DVec3::X, DVec3::Y, -DVec3::Y, DVec3::Z, -DVec3::Z],
            triangles: vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]],
        };
        for _ in 0..levels {
            unit = unit.subdivided();
            unit.positions_m.iter_mut().for_each(|p| *p = p.normalize());
        }
        unit.positions_m.iter_mut().for_each(|p| *p = centre_m + *p * radius_m);
        unit
    }
}

/// Which tetrahedralisation of TetGen's quality nodes the fluid gets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tetrahedralisation {
    /// TetGen's constrained Delaunay mesh: the obstacle surfaces are exact, but tets next
    /// to them may be non-Delaunay (their circumcentres in reverse order across a face);
    /// the projection clamps those dual lengths and `MeshStats::non_delaunay_faces` counts
    /// them.
    Constrained,
    /// The Delaunay tetrahedralisation of the same nodes, tets whose barycentre lies inside
    /// an obstacle removed: Delaunay everywhere, as the paper's discretisation assumes; the
    /// obstacle boundary is the tets' faces nearest the surface (exact where TetGen's
    /// surface triangles are themselves Delaunay, which they are after quality refinement
    /// except at sharp features).
    #[default]
    Delaunay,
}

/// What to mesh and how finely.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxMeshSpec {
    /// Lower corner of the box, metres.
    pub min_m: DVec3,
    /// Upper corner of the box, metres.
    pub max_m: DVec3,
    /// Obstacles carved out of the box (closed, inside the box, disjoint).
    pub obstacles: Vec<Obstacle>,
    /// Largest tet volume TetGen may leave, m³.
    pub max_tet_volume_m3: f64,
    /// Largest circumradius / shortest-edge ratio TetGen refines to (≥ 1.2; 2.0 is TetGen's
    /// default, smaller is rounder and costs more tets).
    pub max_radius_edge_ratio: f64,
    /// Constrained or Delaunay (see [`Tetrahedralisation`]).
    pub tetrahedralisation: Tetrahedralisation,
    /// Refuse to mesh (or to return a mesh) with more tets than this.
    pub max_tets: usize,
}

/// TetGen's quality meshes hold about this many tets per `max_tet_volume_m3` of domain
/// (measured 2.3–2.6 on boxes at radius–edge bounds 1.4–1.6).
pub const TETS_PER_MAX_VOLUME: f64 = 2.5;

/// Checks a spec before meshing: obstacles closed and inside the box, the expected tet
/// count within `max_tets`.
pub fn validate(spec: &BoxMeshSpec) -> Result<(), MeshError> {
    for (index, obstacle) in spec.obstacles.iter().enumerate() {
        if let Some((vertex, p)) = obstacle
            .positions_m
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.cmpgt(spec.min_m).all() && p.cmplt(spec.max_m).all()))
        {
            return Err(MeshError::ObstacleOutside { obstacle: index, vertex, position_m: *p });
        }
        if let Some(edge) = open_edge(obstacle) {
            return Err(MeshError::ObstacleNotClosed { obstacle: index, edge });
        }
        if obstacle.triangles.iter().flatten().any(|&i| i as usize >= obstacle.positions_m.len()) {
            return Err(MeshError::Mesher(format!("obstacle {index} names a vertex past its end")));
        }
    }
    let size = spec.max_m - spec.min_m;
    let volume = size.x * size.y * size.z - spec.obstacles.iter().map(enclosed_volume_m3).sum::<f64>();
    let expected = TETS_PER_MAX_VOLUME * volume / spec.max_tet_volume_m3.max(f64::MIN_POSITIVE);
    // NaN (a NaN max volume) is refused too.
    if expected.is_nan() || expected > spec.max_tets as f64 {
        return Err(MeshError::TooManyTets { tets: expected.min(usize::MAX as f64) as usize, max_tets: spec.max_tets });
    }
    Ok(())
}

/// Volume enclosed by a closed triangle surface, m³ (divergence theorem; positive when the
/// triangles face outwards).
pub fn enclosed_volume_m3(obstacle: &Obstacle) -> f64 {
    obstacle
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| obstacle.positions_m.get(i as usize).copied().unwrap_or(DVec3::ZERO));
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Winding number of the closed surface around `p` (≈ 1 inside, ≈ 0 outside).
pub fn winding_number(obstacle: &Obstacle, p: DVec3) -> f64 {
    crate::math::solid::winding_number(&obstacle.positions_m, &obstacle.triangles, p)
}

/// Edges used by exactly two triangles in opposite directions: the surface is closed and
/// consistently oriented. Returns the first offending edge otherwise.
pub fn open_edge(obstacle: &Obstacle) -> Option<[u32; 2]> {
    let mut edges: Vec<[u32; 2]> =
        obstacle.triangles.iter().flat_map(|t| [[t[0], t[1]], [t[1], t[2]], [t[2], t[0]]]).collect();
    edges.sort_unstable();
    for e in &edges {
        if edges.binary_search(&[e[1], e[0]]).is_err() {
            return Some(*e);
        }
    }
    None
}

/// A point strictly inside a closed surface (TetGen's hole seed): the first triangle
/// centroid pushed inwards by a fraction of its size whose winding number is ≈ 1.
pub fn interior_point(obstacle: &Obstacle) -> Option<DVec3> {
    for t in &obstacle.triangles {
        let [a, b, c] = t.map(|i| obstacle.positions_m.get(i as usize).copied().unwrap_or(DVec3::ZERO));
        let normal = (b - a).cross(c - a).try_normalize()?;
        let size = (b - a).length().min((c - a).length()).min((c - b).length());
        for fraction in [0.1, 0.01, 0.001] {
            let p = (a + b + c) / 3.0 - normal * size * fraction;
            if (winding_number(obstacle, p) - 1.0).abs() < 1e-3 {
                return Some(p);
            }
        }
    }
    None
}

fn tetgen_error(what: &str, e: &str) -> MeshError {
    MeshError::Mesher(format!("TetGen {what}: {e}"))
}

/// Nodes and tets as TetGen returns them.
pub type RawMesh = (Vec<DVec3>, Vec<[u32; 4]>);

fn read_output(tetgen: &Tetgen) -> Result<RawMesh, MeshError> {
    let npoint = tetgen.out_npoint();
    let ncell = tetgen.out_ncell();
    if ncell == 0 {
        return Err(MeshError::Mesher("TetGen returned no tetrahedra".into()));
    }
    let nodes = (0..npoint)
        .map(|i| DVec3::new(tetgen.out_point(i, 0), tetgen.out_point(i, 1), tetgen.out_point(i, 2)))
        .collect();
    let tets = (0..ncell).map(|c| std::array::from_fn(|m| tetgen.out_cell_point(c, m) as u32)).collect();
    Ok((nodes, tets))
}

/// The Delaunay tetrahedralisation of `points_m` as TetGen returns it (nodes and tets, flat
/// hull tets included), for callers that filter tets before building a [`TetMesh`].
pub fn delaunay_tets(points_m: &[DVec3]) -> Result<RawMesh, MeshError> {
    let _guard = TETGEN_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    let mut tetgen = Tetgen::new(points_m.len(), None, None, None).map_err(|e| tetgen_error("input", e))?;
    for (i, p) in points_m.iter().enumerate() {
        tetgen.set_point(i, 0, p.x, p.y, p.z).map_err(|e| tetgen_error("input", e))?;
    }
    tetgen.generate_delaunay(false).map_err(|e| tetgen_error("delaunay", e))?;
    read_output(&tetgen)
}

/// Delaunay tetrahedralisation of `points_m` (its convex hull filled).
pub fn delaunay(points_m: &[DVec3]) -> Result<TetMesh, MeshError> {
    let (nodes, tets) = delaunay_tets(points_m)?;
    TetMesh::new(nodes, tets)
}

/// A quality tet mesh of the box minus its obstacles (see the module docs for switches),
/// after [`validate`]; TetGen's failures come back as [`MeshError::Mesher`], a mesh over
/// `max_tets` as [`MeshError::TooManyTets`].
pub fn mesh_box(spec: &BoxMeshSpec) -> Result<TetMesh, MeshError> {
    let (lo, hi) = (spec.min_m, spec.max_m);
    if !(hi.x > lo.x && hi.y > lo.y && hi.z > lo.z) {
        return Err(MeshError::Mesher(format!("empty box {lo} .. {hi}")));
    }
    if !(spec.max_tet_volume_m3 > 0.0 && spec.max_radius_edge_ratio >= 1.0) {
        return Err(MeshError::Mesher("max tet volume must be > 0 and radius-edge ratio ≥ 1".into()));
    }
    validate(spec)?;
    let corners: Vec<DVec3> = box_corners(lo, hi).to_vec();
    let mut facets: Vec<Vec<usize>> = vec![
        vec![0, 2, 6, 4],
        vec![1, 5, 7, 3],
        vec![0, 4, 5, 1],
        vec![2, 3, 7, 6],
        vec![0, 1, 3, 2],
        vec![4, 6, 7, 5],
    ];
    let mut points = corners;
    let mut holes = Vec::new();
    for obstacle in &spec.obstacles {
        let base = points.len();
        points.extend(&obstacle.positions_m);
        facets.extend(obstacle.triangles.iter().map(|t| t.iter().map(|&i| base + i as usize).collect()));
        holes.push(
            interior_point(obstacle).ok_or_else(|| MeshError::Mesher("an obstacle has no interior point".into()))?,
        );
    }
    let (nodes, tets) = {
        let _guard = TETGEN_LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        constrained(&points, &facets, &holes, spec)?
    };
    if tets.len() > spec.max_tets {
        return Err(MeshError::TooManyTets { tets: tets.len(), max_tets: spec.max_tets });
    }
    match spec.tetrahedralisation {
        Tetrahedralisation::Constrained => TetMesh::new(nodes, tets),
        Tetrahedralisation::Delaunay => {
            let (nodes, tets) = delaunay_tets(&nodes)?;
            let fluid = tets
                .into_iter()
                .filter(|tet| {
                    let centroid = tet.iter().map(|&i| nodes[i as usize]).sum::<DVec3>() * 0.25;
                    spec.obstacles.iter().all(|o| winding_number(o, centroid) < 0.5)
                })
                .collect();
            TetMesh::new(nodes, fluid)
        }
    }
}

fn constrained(
    points: &[DVec3],
    facets: &[Vec<usize>],
    holes: &[DVec3],
    spec: &BoxMeshSpec,
) -> Result<RawMesh, MeshError> {
    let mut tetgen = Tetgen::new(points.len(), Some(facets.iter().map(Vec::len).collect()), Some(0), Some(holes.len()))
        .map_err(|e| tetgen_error("input", e))?;
    for (i, p) in points.iter().enumerate() {
        tetgen.set_point(i, 0, p.x, p.y, p.z).map_err(|e| tetgen_error("input", e))?;
    }
    for (i, facet) in facets.iter().enumerate() {
        for (m, &p) in facet.iter().enumerate() {
            tetgen.set_facet_point(i, m, p).map_err(|e| tetgen_error("input", e))?;
        }
    }
    for (i, h) in holes.iter().enumerate() {
        tetgen.set_hole(i, h.x, h.y, h.z).map_err(|e| tetgen_error("input", e))?;
    }
    tetgen
        .generate_mesh(false, false, Some(spec.max_tet_volume_m3), Some(spec.max_radius_edge_ratio))
        .map_err(|e| tetgen_error("tetrahedralize", e))?;
    read_output(&tetgen)
}
