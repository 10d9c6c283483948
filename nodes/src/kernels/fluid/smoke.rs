//! Smoke carried per tet: buoyancy from density and temperature, semi-Lagrangian transfer
//! of per-tet quantities onto the next step's mesh, and the mass bookkeeping of a remesh.
//!
//! Buoyancy (Fedkiw et al. 2001, as Klingner et al. use it): f = (−α s + β (T − T_amb)) ŷ
//! per unit mass (m/s²), s smoke density (kg/m³ of smoke, or any concentration), T in
//! kelvin; added to the face velocities as Δt f·n with s and T the mean of the face's tets.

use glam::DVec3;

use super::mesh::{NO_TET, TetMesh};
use super::velocity::VelocityField;

/// Buoyancy constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Buoyancy {
    /// Downward pull per unit smoke density, m/s² per (kg/m³).
    pub alpha: f64,
    /// Upward push per kelvin above ambient, m/s² per K.
    pub beta: f64,
    /// Ambient temperature, K.
    pub ambient_k: f64,
}

impl Default for Buoyancy {
    /// α = 0.1, β = 0.05, ambient 293.15 K.
    fn default() -> Self {
        Buoyancy { alpha: 0.1, beta: 0.05, ambient_k: 293.15 }
    }
}

/// Adds Δt·buoyancy·n to every face velocity (m/s) that `fluid(face)` allows.
pub fn add_buoyancy(
    mesh: &TetMesh,
    face_velocity_m_s: &mut [f64],
    density: &[f64],
    temperature_k: &[f64],
    buoyancy: &Buoyancy,
    dt_s: f64,
    fluid: impl Fn(usize) -> bool,
) {
    for (f, z) in face_velocity_m_s.iter_mut().enumerate() {
        if !fluid(f) {
            continue;
        }
        let [a, b] = mesh.face_tets[f];
        let (s, t) = if b == NO_TET {
            (density[a as usize], temperature_k[a as usize])
        } else {
            (
                0.5 * (density[a as usize] + density[b as usize]),
                0.5 * (temperature_k[a as usize] + temperature_k[b as usize]),
            )
        };
        let up = -buoyancy.alpha * s + buoyancy.beta * (t - buoyancy.ambient_k);
        *z += dt_s * up * DVec3::Y.dot(mesh.face_normal[f]);
    }
}

/// Per-node values of a per-tet quantity: the volume-weighted mean of the node's tets.
pub fn node_values(mesh: &TetMesh, per_tet: &[f64]) -> Vec<f64> {
    let mut sum = vec![0.0; mesh.nodes_m.len()];
    let mut weight = vec![0.0; mesh.nodes_m.len()];
    for (t, tet) in mesh.tets.iter().enumerate() {
        for &v in tet {
            sum[v as usize] += per_tet[t] * mesh.tet_volume_m3[t];
            weight[v as usize] += mesh.tet_volume_m3[t];
        }
    }
    sum.iter().zip(&weight).map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 }).collect()
}

/// Total of a per-tet density over the mesh (Σ V_t s_t; kg for a density in kg/m³).
pub fn total(mesh: &TetMesh, per_tet: &[f64]) -> f64 {
    mesh.tet_volume_m3.iter().zip(per_tet).map(|(v, s)| v * s).sum()
}

/// Barycentric weight of the vertex each point of the 4-point, degree-2 tet quadrature
/// rule sits nearest (Keast 1986: a = (5 + 3√5)/20), the other three taking (1 − a)/3.
const QUADRATURE_A: f64 = 0.585_410_196_624_968_5;

/// Bounds of the per-node correction of [`Transfer`]: a node whose hat function the new
/// mesh covers much less (or more) than the old one sits where an obstacle moved, and its
/// smoke is the advection's to carry, not the correction's.
const CORRECTION_RANGE: (f64, f64) = (0.5, 2.0);

/// A point located in a mesh: its tet and barycentric coordinates.
type Located = Option<(usize, [f64; 4])>;

/// Semi-Lagrangian transfer of per-tet quantities onto a new mesh: each new tet takes the
/// mean of the old quantity (linear over the old tets, from [`node_values`]) at the four
/// points of a degree-2 quadrature rule, each traced back through the old field. The
/// quadrature matters: the old field is only piecewise linear across the new tets, and
/// sampling each new tet once at its barycentre lost ~1 % of a Gaussian puff per remesh.
///
/// Even four points miss the kinks of a sharp front (a source's edge: −0.56 % of its smoke
/// in one remesh of ball_in_smoke, +0.6 % in kick_through_smoke), so the node values are
/// first scaled per node by the ratio of the node's hat function integral on the old mesh
/// (exact: a quarter of the volume of its tets) to the same integral by this quadrature on
/// the new mesh. The ratio scales the node values' departure from the field's mean, so a
/// uniform field stays uniform; totals are then kept exactly by a remesh without motion
/// of a domain of unchanged volume, for any field (the quadrature integrates constants
/// exactly and the transfer is linear in the node values). The ratio is clamped to
/// [0.5, 2] (`CORRECTION_RANGE`) where an obstacle moved over or off the node.
pub struct Transfer {
    /// Per new tet and quadrature point: the old tet the traced point lies in (or is
    /// nearest) and its barycentric coordinates there; `None` on an empty old mesh.
    samples: Vec<[Located; 4]>,
    /// Per old node, the factor of its value.
    scale: Vec<f64>,
}

impl Transfer {
    /// Locates the traced (`dt_s` back through `old_field`) and the untraced quadrature
    /// points of every tet of `new_mesh` in `old_mesh`.
    pub fn new(old_mesh: &TetMesh, old_field: &VelocityField, new_mesh: &TetMesh, dt_s: f64) -> Transfer {
        use rayon::prelude::*;
        let b = (1.0 - QUADRATURE_A) / 3.0;
        let locate = |p: DVec3| old_field.locator().locate(old_mesh, p);
        let located: Vec<([Located; 4], [Located; 4])> = (0..new_mesh.tet_count())
            .into_par_iter()
            .map(|t| {
                let corners = new_mesh.tets[t].map(|i| new_mesh.nodes_m[i as usize]);
                let points: [DVec3; 4] = std::array::from_fn(|k| {
                    corners.iter().enumerate().map(|(j, c)| *c * if j == k { QUADRATURE_A } else { b }).sum()
                });
                (points.map(|p| locate(old_field.trace_back(old_mesh, p, dt_s))), points.map(locate))
            })
            .collect();
        let mut exact = vec![0.0; old_mesh.nodes_m.len()];
        for (t, tet) in old_mesh.tets.iter().enumerate() {
            tet.iter().for_each(|&n| exact[n as usize] += 0.25 * old_mesh.tet_volume_m3[t]);
        }
        let mut quadrature = vec![0.0; old_mesh.nodes_m.len()];
        for (t, (_, still)) in located.iter().enumerate() {
            for (old, l) in still.iter().flatten() {
                for m in 0..4 {
                    quadrature[old_mesh.tets[*old][m] as usize] += 0.25 * new_mesh.tet_volume_m3[t] * l[m];
                }
            }
        }
        let scale = exact
            .iter()
            .zip(&quadrature)
            .map(|(e, q)| if *q > 0.0 { (e / q).clamp(CORRECTION_RANGE.0, CORRECTION_RANGE.1) } else { 1.0 })
            .collect();
        Transfer { samples: located.into_iter().map(|(traced, _)| traced).collect(), scale }
    }

    /// The per-tet quantity `per_tet` of the old mesh on the new one.
    pub fn apply(&self, old_mesh: &TetMesh, per_tet: &[f64]) -> Vec<f64> {
        let mean = total(old_mesh, per_tet) / old_mesh.volume_m3();
        let at_nodes: Vec<f64> =
            node_values(old_mesh, per_tet).iter().zip(&self.scale).map(|(v, s)| mean + (v - mean) * s).collect();
        self.samples
            .iter()
            .map(|points| {
                let sum: f64 = points
                    .iter()
                    .flatten()
                    .map(|(old, l)| (0..4).map(|m| at_nodes[old_mesh.tets[*old][m] as usize] * l[m]).sum::<f64>())
                    .sum();
                0.25 * sum
            })
            .collect()
    }
}

/// [`Transfer`] of one per-tet quantity (with `dt_s = 0`, the plain remesh transfer).
pub fn advect_per_tet(
    old_mesh: &TetMesh,
    old_field: &VelocityField,
    per_tet: &[f64],
    new_mesh: &TetMesh,
    dt_s: f64,
) -> Vec<f64> {
    Transfer::new(old_mesh, old_field, new_mesh, dt_s).apply(old_mesh, per_tet)
}
