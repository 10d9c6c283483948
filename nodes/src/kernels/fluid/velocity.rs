//! Velocity vectors from face-normal velocities, interpolation at points, and
//! semi-Lagrangian advection across meshes (Klingner et al. 2006, §4–5, after Elcott et al.
//! 2005 and Warren et al. 2004).
//!
//! 1. Per tet: u_t solves N_t u_t = z_t (four outward normals, four outward normal
//!    velocities) in the area-weighted least-squares sense. When the tet is divergence-free
//!    (Σ A z = 0) the system is consistent and u_t reproduces all four face values exactly.
//! 2. Per node: the Voronoi-cell interpolation of the u_t of the tets around the node,
//!    evaluated at the node. Warren's coordinates at the cell's site reduce (the cell's faces
//!    are normal to the node's edges, at half their length) to w_t ∝ V_t / Π_j |e_j|², with
//!    e_j the three edges of t at the node.
//! 3. At a point: linear (barycentric) interpolation of the node velocities inside the tet
//!    that contains it (the paper's fast path for particles).
//! 4. Advection: each new face circumcentre is traced back through the previous mesh's
//!    velocity field (midpoint rule) and takes that velocity's component along its normal.

use glam::{DMat3, DVec3};

use super::mesh::TetMesh;

/// Velocity per tet (m/s) from face-normal velocities (m/s, along each face's normal).
pub fn tet_velocities(mesh: &TetMesh, face_velocity_m_s: &[f64]) -> Vec<DVec3> {
    (0..mesh.tet_count())
        .map(|t| {
            let mut normal_matrix = DMat3::ZERO;
            let mut rhs = DVec3::ZERO;
            for (k, (n, area, f)) in mesh.outward_faces(t).into_iter().enumerate() {
                let z = face_velocity_m_s[f] * mesh.tet_face_sign[t][k];
                normal_matrix += DMat3::from_cols(n * n.x, n * n.y, n * n.z) * area;
                rhs += n * (z * area);
            }
            if normal_matrix.determinant().abs() <= f64::MIN_POSITIVE {
                DVec3::ZERO
            } else {
                normal_matrix.inverse() * rhs
            }
        })
        .collect()
}

/// Velocity per node (m/s) by Voronoi-cell (Warren) weights of the surrounding tets.
///
/// A node on the boundary has an unbounded Voronoi cell, where those weights lose their
/// linear precision; there the velocity is the least-squares affine fit to the (circumcentre,
/// u_t) pairs of its tets (exact for linear fields), falling back to the weighted mean when
/// the circumcentres are coplanar.
pub fn node_velocities(mesh: &TetMesh, tet_velocity_m_s: &[DVec3]) -> Vec<DVec3> {
    let n = mesh.nodes_m.len();
    let mut sum = vec![DVec3::ZERO; n];
    let mut weight = vec![0.0; n];
    for (t, tet) in mesh.tets.iter().enumerate() {
        for k in 0..4 {
            let node = tet[k] as usize;
            let here = mesh.nodes_m[node];
            let product: f64 =
                (0..4).filter(|&l| l != k).map(|l| (mesh.nodes_m[tet[l] as usize] - here).length_squared()).product();
            let w = mesh.tet_volume_m3[t] / product.max(f64::MIN_POSITIVE);
            sum[node] += tet_velocity_m_s[t] * w;
            weight[node] += w;
        }
    }
    let mut velocity: Vec<DVec3> =
        sum.iter().zip(&weight).map(|(s, &w)| if w > 0.0 { *s / w } else { DVec3::ZERO }).collect();

    // Boundary nodes: affine least squares over their tets' circumcentres.
    let mut on_boundary = vec![false; n];
    for (f, face) in mesh.faces.iter().enumerate() {
        if mesh.is_boundary(f) {
            for &v in face {
                on_boundary[v as usize] = true;
            }
        }
    }
    let mut normal = vec![[[0.0f64; 4]; 4]; n];
    let mut rhs = vec![[DVec3::ZERO; 4]; n];
    let mut lo = vec![DVec3::INFINITY; n];
    let mut hi = vec![DVec3::NEG_INFINITY; n];
    for (t, tet) in mesh.tets.iter().enumerate() {
        for &v in tet {
            let v = v as usize;
            if !on_boundary[v] {
                continue;
            }
            let d = mesh.tet_circumcentre_m[t] - mesh.nodes_m[v];
            let row = [1.0, d.x, d.y, d.z];
            for i in 0..4 {
                for j in 0..4 {
                    normal[v][i][j] += row[i] * row[j];
                }
                rhs[v][i] += tet_velocity_m_s[t] * row[i];
            }
            lo[v] = lo[v].min(tet_velocity_m_s[t]);
            hi[v] = hi[v].max(tet_velocity_m_s[t]);
        }
    }
    for v in 0..n {
        if !on_boundary[v] {
            continue;
        }
        let m = nalgebra::Matrix4::from_fn(|i, j| normal[v][i][j]);
        if let Some(inverse) = m.try_inverse() {
            let fitted = (0..4).map(|j| rhs[v][j] * inverse[(0, j)]).sum::<DVec3>();
            // The fit extrapolates from one side of the wall: keep it within the range of
            // the tets' own velocities, so errors are never amplified from step to step.
            if fitted.is_finite() {
                velocity[v] = fitted.clamp(lo[v], hi[v]);
            }
        }
    }
    velocity
}

/// Barycentric coordinates of `p` in tet `t`.
pub fn barycentric(mesh: &TetMesh, t: usize, p: DVec3) -> [f64; 4] {
    let [a, b, c, d] = mesh.tets[t].map(|i| mesh.nodes_m[i as usize]);
    let m = DMat3::from_cols(b - a, c - a, d - a);
    let det = m.determinant();
    if det.abs() <= f64::MIN_POSITIVE {
        return [0.25; 4];
    }
    let l = m.inverse() * (p - a);
    [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
}

/// A uniform grid over the mesh's bounding box, listing the tets whose bounding box
/// touches each cell: point location in a few barycentric tests.
#[derive(Debug, Clone)]
pub struct TetLocator {
    min_m: DVec3,
    cell_m: f64,
    dims: [usize; 3],
    cell_start: Vec<u32>,
    cell_tets: Vec<u32>,
}

impl TetLocator {
    /// Builds the grid with about one cell per tet.
    pub fn new(mesh: &TetMesh) -> TetLocator {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &mesh.nodes_m {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let extent = (hi - lo).max(DVec3::splat(1e-9));
        let cells = mesh.tet_count().max(1) as f64;
        let cell_m = (extent.x * extent.y * extent.z / cells).cbrt().max(1e-9);
        let dims = [0, 1, 2].map(|a| ((extent[a] / cell_m).ceil() as usize).clamp(1, 1024));
        let index = |p: DVec3| -> [usize; 3] {
            std::array::from_fn(|a| (((p[a] - lo[a]) / cell_m).floor().max(0.0) as usize).min(dims[a] - 1))
        };
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for (t, tet) in mesh.tets.iter().enumerate() {
            let ps = tet.map(|i| mesh.nodes_m[i as usize]);
            let (a, b) = (
                index(ps.iter().copied().fold(DVec3::INFINITY, DVec3::min)),
                index(ps.iter().copied().fold(DVec3::NEG_INFINITY, DVec3::max)),
            );
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        pairs.push((((z * dims[1] + y) * dims[0] + x) as u32, t as u32));
                    }
                }
            }
        }
        pairs.sort_unstable();
        let total = dims[0] * dims[1] * dims[2];
        let mut cell_start = vec![0u32; total + 1];
        for (c, _) in &pairs {
            cell_start[*c as usize + 1] += 1;
        }
        for c in 0..total {
            cell_start[c + 1] += cell_start[c];
        }
        TetLocator { min_m: lo, cell_m, dims, cell_start, cell_tets: pairs.into_iter().map(|(_, t)| t).collect() }
    }

    /// The tet containing `p`, or the nearest candidate (largest smallest barycentric
    /// coordinate) when `p` is outside the mesh, with its barycentric coordinates.
    pub fn locate(&self, mesh: &TetMesh, p: DVec3) -> Option<(usize, [f64; 4])> {
        // Points outside the grid start from the nearest cell.
        let cell = |a: usize| -> i64 {
            (((p[a] - self.min_m[a]) / self.cell_m).floor().max(0.0) as i64).min(self.dims[a] as i64 - 1)
        };
        let centre = [cell(0), cell(1), cell(2)];
        let mut best: Option<(usize, [f64; 4], f64)> = None;
        let max_ring = self.dims.iter().copied().max().unwrap_or(1) as i64;
        for ring in 0..=max_ring {
            for dz in -ring..=ring {
                for dy in -ring..=ring {
                    for dx in -ring..=ring {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != ring {
                            continue;
                        }
                        let c = [centre[0] + dx, centre[1] + dy, centre[2] + dz];
                        if (0..3).any(|a| c[a] < 0 || c[a] >= self.dims[a] as i64) {
                            continue;
                        }
                        let id = ((c[2] as usize * self.dims[1] + c[1] as usize) * self.dims[0]) + c[0] as usize;
                        for &t in &self.cell_tets[self.cell_start[id] as usize..self.cell_start[id + 1] as usize] {
                            let l = barycentric(mesh, t as usize, p);
                            let worst = l.iter().copied().fold(f64::INFINITY, f64::min);
                            if worst >= -1e-12 {
                                return Some((t as usize, l));
                            }
                            if best.as_ref().is_none_or(|b| worst > b.2) {
                                best = Some((t as usize, l, worst));
                            }
                        }
                    }
                }
            }
            if best.is_some() && ring >= 1 {
                break;
            }
        }
        best.map(|(t, l, _)| {
            // Outside the mesh: clamp to the tet (project the coordinates onto the simplex).
            let clamped = l.map(|x| x.max(0.0));
            let s: f64 = clamped.iter().sum();
            (t, if s > 0.0 { clamped.map(|x| x / s) } else { [0.25; 4] })
        })
    }
}

/// Momentum of the fluid, kg·m/s: ρ Σ_t V_t u_t over per-tet velocities (m/s) of a fluid of
/// density `density_kg_m3`.
pub fn momentum(mesh: &TetMesh, tet_velocity_m_s: &[DVec3], density_kg_m3: f64) -> DVec3 {
    density_kg_m3 * mesh.tet_volume_m3.iter().zip(tet_velocity_m_s).map(|(v, u)| *u * *v).sum::<DVec3>()
}

/// A velocity field on one mesh that can be sampled anywhere.
#[derive(Debug, Clone)]
pub struct VelocityField {
    /// Velocity per tet ([`tet_velocities`]), m/s.
    pub tet_velocity_m_s: Vec<DVec3>,
    /// Velocity per node, m/s.
    pub node_velocity_m_s: Vec<DVec3>,
    locator: TetLocator,
}

impl VelocityField {
    /// Reconstructs tet and node velocities from face-normal velocities.
    pub fn new(mesh: &TetMesh, face_velocity_m_s: &[f64]) -> VelocityField {
        let per_tet = tet_velocities(mesh, face_velocity_m_s);
        VelocityField {
            node_velocity_m_s: node_velocities(mesh, &per_tet),
            tet_velocity_m_s: per_tet,
            locator: TetLocator::new(mesh),
        }
    }

    /// Velocity at `p`, m/s (clamped to the nearest tet outside the mesh).
    pub fn sample(&self, mesh: &TetMesh, p: DVec3) -> DVec3 {
        match self.locator.locate(mesh, p) {
            Some((t, l)) => (0..4).map(|k| self.node_velocity_m_s[mesh.tets[t][k] as usize] * l[k]).sum(),
            None => DVec3::ZERO,
        }
    }

    /// Interpolates a per-node quantity at `p`.
    pub fn locator(&self) -> &TetLocator {
        &self.locator
    }

    /// Where a particle at `p` was `dt_s` ago (midpoint rule through this field).
    pub fn trace_back(&self, mesh: &TetMesh, p: DVec3, dt_s: f64) -> DVec3 {
        let mid = p - self.sample(mesh, p) * (0.5 * dt_s);
        p - self.sample(mesh, mid) * dt_s
    }
}

/// Semi-Lagrangian advection of the velocity onto a new mesh: each new face takes the old
/// velocity at its traced-back circumcentre, along its normal (m/s). Faces for which
/// `keep(face)` is true (walls with prescribed velocities) are left to the caller: they get 0.
pub fn advect_velocity(
    old_mesh: &TetMesh,
    old_field: &VelocityField,
    new_mesh: &TetMesh,
    dt_s: f64,
    keep: impl Fn(usize) -> bool + Sync,
) -> Vec<f64> {
    use rayon::prelude::*;
    (0..new_mesh.faces.len())
        .into_par_iter()
        .map(|f| {
            if keep(f) {
                return 0.0;
            }
            let x = new_mesh.face_circumcentre_m[f];
            let from = old_field.trace_back(old_mesh, x, dt_s);
            old_field.sample(old_mesh, from).dot(new_mesh.face_normal[f])
        })
        .collect()
}

/// Face-normal velocities (m/s) of a velocity field given as a function of position.
pub fn sample_faces(mesh: &TetMesh, field: impl Fn(DVec3) -> DVec3) -> Vec<f64> {
    (0..mesh.faces.len()).map(|f| field(mesh.face_circumcentre_m[f]).dot(mesh.face_normal[f])).collect()
}
