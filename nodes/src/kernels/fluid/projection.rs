//! Pressure projection on the circumcentric dual (Klingner et al. 2006, §4).
//!
//! Unknowns: one pressure per tet, at its circumcentre; one normal velocity per face, at
//! its circumcentre, along the face normal (m/s). Operators:
//! - divergence of tet t: D_t = Σ_f s_tf A_f u_f (s = +1 when the normal leaves t), m³/s;
//! - gradient on an interior face f from tet a to tet b: (p_b − p_a) / d_f, with d_f the
//!   distance between the circumcentres (the dual edge, along the normal on a Delaunay mesh);
//! - on an open boundary face the pressure outside is 0 at the face circumcentre.
//!
//! The update z = z* − (Δt/ρ) G p with D z = 0 gives L φ = −D z*, φ = Δt p / ρ, where
//! L = −D G is the weighted graph Laplacian of the dual with weights A_f / d_f: symmetric
//! positive semi-definite, made definite by the open faces or, in a closed domain, by adding
//! 1·w to the first tet's diagonal (exact when Σ D z* = 0, which closed walls with a
//! volume-preserving motion guarantee). Solved by faer's sparse Cholesky (LLᵀ).

use faer::Side;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};

use super::mesh::{NO_TET, TetMesh};

/// What a boundary face is. Interior faces are always fluid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaceCondition {
    /// An interior face: its velocity is solved for.
    Fluid,
    /// A solid wall or obstacle: its normal velocity is prescribed (the value the caller
    /// stores in the face velocity) and pressure does not change it.
    Wall,
    /// An open boundary: pressure 0 outside, velocity free.
    Open,
}

/// Why a projection failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProjectionError {
    /// Input vectors do not match the mesh.
    #[error("{0}")]
    Size(String),
    /// The time step or density is not positive.
    #[error("time step {dt_s} s and density {density_kg_m3} kg/m³ must be > 0")]
    Parameters {
        /// Time step.
        dt_s: f64,
        /// Fluid density.
        density_kg_m3: f64,
    },
    /// The sparse factorisation failed.
    #[error("pressure factorisation failed: {0}")]
    Factor(String),
}

/// The smallest dual length used in the Laplacian, as a fraction of √(face area): faces of
/// non-Delaunay pairs (dual length ≤ 0) and near-cospherical ties are clamped to this
/// (`MeshStats::clamped_dual_faces` counts them). The projection stays exactly
/// divergence-free with any positive lengths; only the gradient across a clamped face is
/// inexact. Smaller values make the Laplacian ill-conditioned (at 1e-6 the divergence left by
/// the Cholesky solve grows from ~1e-10 to ~1e-7 of the flux).
pub const MIN_DUAL_FRACTION: f64 = 1e-3;

fn dual_length(mesh: &TetMesh, f: usize) -> f64 {
    mesh.face_dual_length_m[f].max(MIN_DUAL_FRACTION * mesh.face_area_m2[f].sqrt())
}

/// Boundary conditions per face: interior faces [`FaceCondition::Fluid`], boundary faces
/// from `boundary(face)`.
pub fn face_conditions(mesh: &TetMesh, mut boundary: impl FnMut(usize) -> FaceCondition) -> Vec<FaceCondition> {
    (0..mesh.faces.len()).map(|f| if mesh.is_boundary(f) { boundary(f) } else { FaceCondition::Fluid }).collect()
}

/// Discrete divergence per tet, m³/s (Σ_f s A u).
pub fn divergence(mesh: &TetMesh, face_velocity_m_s: &[f64]) -> Vec<f64> {
    (0..mesh.tet_count())
        .map(|t| {
            (0..4)
                .map(|k| {
                    let f = mesh.tet_faces[t][k] as usize;
                    mesh.tet_face_sign[t][k] * mesh.face_area_m2[f] * face_velocity_m_s[f]
                })
                .sum()
        })
        .collect()
}

/// Largest |divergence| of a tet relative to its total face flux Σ A|u| (0 for still tets).
pub fn max_relative_divergence(mesh: &TetMesh, face_velocity_m_s: &[f64]) -> f64 {
    let div = divergence(mesh, face_velocity_m_s);
    let mut worst: f64 = 0.0;
    for (t, d) in div.iter().enumerate() {
        let flux: f64 = mesh.tet_faces[t]
            .iter()
            .map(|&f| mesh.face_area_m2[f as usize] * face_velocity_m_s[f as usize].abs())
            .sum();
        if flux > 0.0 {
            worst = worst.max(d.abs() / flux);
        }
    }
    worst
}

/// A factored pressure system for one mesh and set of face conditions; reuse it for every
/// projection on that mesh (the symbolic analysis and the numbers are kept).
pub struct PressureSolver {
    llt: Llt<usize, f64>,
    conditions: Vec<FaceCondition>,
    tet_count: usize,
}

impl PressureSolver {
    /// Assembles L = −DG and factors it.
    pub fn new(mesh: &TetMesh, conditions: &[FaceCondition]) -> Result<PressureSolver, ProjectionError> {
        if conditions.len() != mesh.faces.len() {
            return Err(ProjectionError::Size(format!(
                "{} face conditions for {} faces",
                conditions.len(),
                mesh.faces.len()
            )));
        }
        let n = mesh.tet_count();
        let mut diagonal = vec![0.0; n];
        let mut triplets = Vec::with_capacity(mesh.faces.len() * 2 + n);
        let mut open = false;
        for (f, condition) in conditions.iter().enumerate() {
            let [a, b] = mesh.face_tets[f];
            let w = mesh.face_area_m2[f] / dual_length(mesh, f);
            match (condition, b == NO_TET) {
                (FaceCondition::Wall, _) => {}
                (_, false) => {
                    diagonal[a as usize] += w;
                    diagonal[b as usize] += w;
                    // Lower triangle only.
                    let (row, col) = if a > b { (a, b) } else { (b, a) };
                    triplets.push(Triplet::new(row as usize, col as usize, -w));
                }
                (_, true) => {
                    diagonal[a as usize] += w;
                    open = true;
                }
            }
        }
        if !open && n > 0 {
            let scale = diagonal[0].max(f64::MIN_POSITIVE);
            diagonal[0] += scale;
        }
        triplets.extend(diagonal.iter().enumerate().map(|(i, d)| Triplet::new(i, i, *d)));
        let matrix = SparseColMat::try_new_from_triplets(n, n, &triplets)
            .map_err(|e| ProjectionError::Factor(format!("{e:?}")))?;
        let symbolic = SymbolicLlt::try_new(matrix.symbolic(), Side::Lower)
            .map_err(|e| ProjectionError::Factor(format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(symbolic, matrix.as_ref(), Side::Lower)
            .map_err(|e| ProjectionError::Factor(format!("{e:?}")))?;
        Ok(PressureSolver { llt, conditions: conditions.to_vec(), tet_count: n })
    }

    /// Makes `face_velocity_m_s` (z*, walls already holding their prescribed values)
    /// divergence-free in place and returns the pressure per tet, Pa.
    pub fn project(
        &self,
        mesh: &TetMesh,
        face_velocity_m_s: &mut [f64],
        dt_s: f64,
        density_kg_m3: f64,
    ) -> Result<Vec<f64>, ProjectionError> {
        if face_velocity_m_s.len() != mesh.faces.len() || mesh.tet_count() != self.tet_count {
            return Err(ProjectionError::Size(format!(
                "{} face velocities for {} faces ({} tets, solver built for {})",
                face_velocity_m_s.len(),
                mesh.faces.len(),
                mesh.tet_count(),
                self.tet_count
            )));
        }
        if !(dt_s > 0.0 && density_kg_m3 > 0.0) {
            return Err(ProjectionError::Parameters { dt_s, density_kg_m3 });
        }
        let div = divergence(mesh, face_velocity_m_s);
        let mut rhs = faer::Mat::<f64>::zeros(self.tet_count, 1);
        for (t, d) in div.iter().enumerate() {
            rhs[(t, 0)] = -d;
        }
        faer::linalg::solvers::Solve::solve_in_place(&self.llt, rhs.as_mut());
        for (f, condition) in self.conditions.iter().enumerate() {
            if *condition == FaceCondition::Wall {
                continue;
            }
            let [a, b] = mesh.face_tets[f];
            let phi_b = if b == NO_TET { 0.0 } else { rhs[(b as usize, 0)] };
            face_velocity_m_s[f] -= (phi_b - rhs[(a as usize, 0)]) / dual_length(mesh, f);
        }
        Ok((0..self.tet_count).map(|t| rhs[(t, 0)] * density_kg_m3 / dt_s).collect())
    }
}
