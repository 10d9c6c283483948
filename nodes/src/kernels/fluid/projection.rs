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
//!
//! Two-way rigid coupling (§7, the matrix R): a dynamic rigid body's faces take the normal
//! velocity of its rigid motion, z_f = J_f U with U = (v, ω) and J_f = (n_f, r_f × n_f), r_f
//! from the body's centre of mass to the face centroid (the centroid makes A_f z_f the exact
//! flux of the rigid motion through the flat face). The pressure of each face's tet pushes
//! the body: U = U* + ΔU, ΔU = ρ M⁻¹ Bᵀ φ (= Δt M⁻¹ Σ_f J_fᵀ A_f p_f), where B (tets × 6)
//! holds per tet the sum of A_f J_f over its faces on the body. The body's velocity change
//! joins the pressure as unknowns of one symmetric system,
//!
//! ```text
//! [ L   B    ] [ φ  ]   [ −D z* ]
//! [ Bᵀ  −M/ρ ] [ ΔU ] = [   0   ]
//! ```
//!
//! whose Schur complement onto φ is the paper's DA = L + ρ B M⁻¹ Bᵀ (positive definite).
//! It is solved by eliminating φ with the Cholesky factor of L: (M/ρ + Bᵀ L⁻¹ B) ΔU =
//! Bᵀ L⁻¹ r, a symmetric positive definite 6 × 6 system per body whose ρ Bᵀ L⁻¹ B is the
//! body's added mass in this mesh, then φ = L⁻¹ (r − B ΔU). Factoring DA itself gives the
//! same answer but fills a dense block between every pair of the k tets touching a body
//! (k² entries, k³ work: 0.4 s against 0.02 s for a 0.3 m ball meshed at 0.025 m); here
//! the body costs 6 more columns in the triangular solves. D z = 0 holds exactly for any
//! ΔU. B·1 = Σ A_f J_f = 0 over a closed surface, so a closed box keeps its constant null
//! space and its consistency condition.

use faer::Side;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use glam::DVec3;
use nalgebra::{Matrix6, Vector6};

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
    /// A face on dynamic rigid body `i` (an index into the solver's bodies): its normal
    /// velocity is the body's rigid motion, solved for together with the pressure.
    Rigid(u32),
}

/// A dynamic rigid body as the pressure solve sees it; its faces are those marked
/// [`FaceCondition::Rigid`] with its index.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidCoupling {
    /// Where the angular velocity is taken about (the centre of mass), metres.
    pub centre_m: DVec3,
    /// Generalised mass diag(m, m, m, I) in world axes: kg on the linear block, kg·m² on the
    /// angular one (symmetric positive definite).
    pub mass: Matrix6<f64>,
}

/// J_f of face `f` on a body whose centre of mass is `centre_m`: its normal velocity per unit
/// body velocity, (n_f, (x̄_f − c) × n_f) with x̄_f the face centroid (dimensionless, then m).
pub fn rigid_face_row(mesh: &TetMesh, f: usize, centre_m: DVec3) -> Vector6<f64> {
    let n = mesh.face_normal[f];
    let centroid = mesh.faces[f].iter().map(|&i| mesh.nodes_m[i as usize]).sum::<DVec3>() / 3.0;
    let arm = (centroid - centre_m).cross(n);
    Vector6::new(n.x, n.y, n.z, arm.x, arm.y, arm.z)
}

/// One coupled body inside a factored solver: its faces with their rows J_f, and the tets
/// they touch with their rows of B (Σ A_f J_f).
struct CoupledBody {
    faces: Vec<(usize, Vector6<f64>)>,
    tets: Vec<(usize, Vector6<f64>)>,
    mass: Matrix6<f64>,
}

/// The body part of a factored coupled solve.
struct Coupling {
    bodies: Vec<CoupledBody>,
    /// L⁻¹ B, tets × 6·bodies.
    pressure_per_impulse: faer::Mat<f64>,
    /// Cholesky factor of M/ρ + Bᵀ L⁻¹ B (M = diag of the bodies' masses).
    reduced: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
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
    /// A face names a rigid body the solver was not given, or a body is not finite.
    #[error("rigid body {body}: {message}")]
    Body {
        /// Body index.
        body: usize,
        /// What is wrong.
        message: String,
    },
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
    coupling: Coupling,
    density_kg_m3: f64,
}

impl PressureSolver {
    /// Assembles L = −DG and factors it.
    pub fn new(mesh: &TetMesh, conditions: &[FaceCondition]) -> Result<PressureSolver, ProjectionError> {
        PressureSolver::with_bodies(mesh, conditions, &[], 1.0)
    }

    /// Assembles and factors L, and the reduced body system (module docs) for a fluid of
    /// density `density_kg_m3`; face condition `Rigid(i)` refers to `bodies[i]`.
    pub fn with_bodies(
        mesh: &TetMesh,
        conditions: &[FaceCondition],
        bodies: &[RigidCoupling],
        density_kg_m3: f64,
    ) -> Result<PressureSolver, ProjectionError> {
        if !(density_kg_m3 > 0.0 && density_kg_m3.is_finite()) {
            return Err(ProjectionError::Parameters { dt_s: 1.0, density_kg_m3 });
        }
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
                (FaceCondition::Wall | FaceCondition::Rigid(_), _) => {}
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
        let coupled = couple_bodies(mesh, conditions, bodies)?;
        let coupling = reduce(&llt, n, coupled, density_kg_m3)?;
        Ok(PressureSolver { llt, conditions: conditions.to_vec(), tet_count: n, coupling, density_kg_m3 })
    }

    /// Makes `face_velocity_m_s` (z*, walls already holding their prescribed values)
    /// divergence-free in place and returns the pressure per tet, Pa. For a solver without
    /// rigid bodies (see [`PressureSolver::project_with_bodies`]).
    pub fn project(
        &self,
        mesh: &TetMesh,
        face_velocity_m_s: &mut [f64],
        dt_s: f64,
        density_kg_m3: f64,
    ) -> Result<Vec<f64>, ProjectionError> {
        self.solve(mesh, face_velocity_m_s, &mut [], dt_s, density_kg_m3)
    }

    /// The coupled projection: `body_velocity[i]` holds body i's (v, ω) without pressure
    /// (m/s, rad/s; the paper's rigid-body z*) and comes back with the pressure's impulse
    /// added; its faces' velocities are set to its rigid motion before and after. The fluid
    /// density is the one the solver was built with. Returns the pressure per tet, Pa.
    pub fn project_with_bodies(
        &self,
        mesh: &TetMesh,
        face_velocity_m_s: &mut [f64],
        body_velocity: &mut [Vector6<f64>],
        dt_s: f64,
    ) -> Result<Vec<f64>, ProjectionError> {
        self.solve(mesh, face_velocity_m_s, body_velocity, dt_s, self.density_kg_m3)
    }

    fn solve(
        &self,
        mesh: &TetMesh,
        face_velocity_m_s: &mut [f64],
        body_velocity: &mut [Vector6<f64>],
        dt_s: f64,
        density_kg_m3: f64,
    ) -> Result<Vec<f64>, ProjectionError> {
        if face_velocity_m_s.len() != mesh.faces.len()
            || mesh.tet_count() != self.tet_count
            || body_velocity.len() != self.coupling.bodies.len()
        {
            return Err(ProjectionError::Size(format!(
                "{} face velocities for {} faces ({} tets, solver built for {}), {} body velocities for {} bodies",
                face_velocity_m_s.len(),
                mesh.faces.len(),
                mesh.tet_count(),
                self.tet_count,
                body_velocity.len(),
                self.coupling.bodies.len()
            )));
        }
        if !(dt_s > 0.0 && density_kg_m3 > 0.0) {
            return Err(ProjectionError::Parameters { dt_s, density_kg_m3 });
        }
        if let Some(body) = body_velocity.iter().position(|u| !u.iter().all(|x| x.is_finite())) {
            return Err(ProjectionError::Body { body, message: "its velocity is not finite".into() });
        }
        let set_faces = |faces: &mut [f64], body: &CoupledBody, u: &Vector6<f64>| {
            for (f, row) in &body.faces {
                faces[*f] = row.dot(u);
            }
        };
        let bodies = &self.coupling.bodies;
        for (body, u) in bodies.iter().zip(body_velocity.iter()) {
            set_faces(face_velocity_m_s, body, u);
        }
        let div = divergence(mesh, face_velocity_m_s);
        let mut rhs = faer::Mat::<f64>::zeros(self.tet_count, 1);
        for (t, d) in div.iter().enumerate() {
            rhs[(t, 0)] = -d;
        }
        faer::linalg::solvers::Solve::solve_in_place(&self.llt, rhs.as_mut());
        // The bodies' ΔU from the reduced system, then φ = L⁻¹ r − L⁻¹ B ΔU.
        let delta = if bodies.is_empty() {
            nalgebra::DVector::<f64>::zeros(0)
        } else {
            let mut projected = nalgebra::DVector::<f64>::zeros(6 * bodies.len());
            for (i, body) in bodies.iter().enumerate() {
                for (t, row) in &body.tets {
                    for k in 0..6 {
                        projected[6 * i + k] += row[k] * rhs[(*t, 0)];
                    }
                }
            }
            let delta =
                self.coupling.reduced.as_ref().map(|c| c.solve(&projected)).ok_or_else(|| {
                    ProjectionError::Factor("the rigid bodies' reduced system is not definite".into())
                })?;
            let x = &self.coupling.pressure_per_impulse;
            for t in 0..self.tet_count {
                rhs[(t, 0)] -= (0..delta.len()).map(|j| x[(t, j)] * delta[j]).sum::<f64>();
            }
            delta
        };
        for (f, condition) in self.conditions.iter().enumerate() {
            if matches!(condition, FaceCondition::Wall | FaceCondition::Rigid(_)) {
                continue;
            }
            let [a, b] = mesh.face_tets[f];
            let phi_b = if b == NO_TET { 0.0 } else { rhs[(b as usize, 0)] };
            face_velocity_m_s[f] -= (phi_b - rhs[(a as usize, 0)]) / dual_length(mesh, f);
        }
        for (i, (body, u)) in bodies.iter().zip(body_velocity.iter_mut()).enumerate() {
            *u += Vector6::from_fn(|k, _| delta[6 * i + k]);
            set_faces(face_velocity_m_s, body, u);
        }
        Ok((0..self.tet_count).map(|t| rhs[(t, 0)] * density_kg_m3 / dt_s).collect())
    }
}

/// Each body's faces (rows J_f) and the tets they touch (columns c_t = Σ A_f J_f), in face
/// and tet order so the assembly is deterministic.
fn couple_bodies(
    mesh: &TetMesh,
    conditions: &[FaceCondition],
    bodies: &[RigidCoupling],
) -> Result<Vec<CoupledBody>, ProjectionError> {
    let mut coupled: Vec<CoupledBody> =
        bodies.iter().map(|b| CoupledBody { faces: Vec::new(), tets: Vec::new(), mass: b.mass }).collect();
    for (i, body) in bodies.iter().enumerate() {
        if !(body.centre_m.is_finite() && body.mass.iter().all(|x| x.is_finite())) {
            return Err(ProjectionError::Body { body: i, message: "its centre or mass is not finite".into() });
        }
    }
    for (f, condition) in conditions.iter().enumerate() {
        let FaceCondition::Rigid(i) = *condition else { continue };
        let i = i as usize;
        let body = bodies.get(i).ok_or_else(|| ProjectionError::Body {
            body: i,
            message: format!("face {f} names it, but the solver has {} bodies", bodies.len()),
        })?;
        if !mesh.is_boundary(f) {
            return Err(ProjectionError::Body { body: i, message: format!("face {f} is inside the fluid") });
        }
        let row = rigid_face_row(mesh, f, body.centre_m);
        coupled[i].faces.push((f, row));
        coupled[i].tets.push((mesh.face_tets[f][0] as usize, row * mesh.face_area_m2[f]));
    }
    for body in &mut coupled {
        body.tets.sort_by_key(|(t, _)| *t);
        body.tets.dedup_by(|later, first| {
            let same = later.0 == first.0;
            if same {
                first.1 += later.1;
            }
            same
        });
    }
    Ok(coupled)
}

/// L⁻¹ B by the factor of L, and the Cholesky factor of the reduced body system
/// M/ρ + Bᵀ L⁻¹ B.
fn reduce(
    llt: &Llt<usize, f64>,
    tets: usize,
    bodies: Vec<CoupledBody>,
    density_kg_m3: f64,
) -> Result<Coupling, ProjectionError> {
    let m = 6 * bodies.len();
    let mut x = faer::Mat::<f64>::zeros(tets, m);
    for (i, body) in bodies.iter().enumerate() {
        for (t, row) in &body.tets {
            for k in 0..6 {
                x[(*t, 6 * i + k)] = row[k];
            }
        }
    }
    if m > 0 {
        faer::linalg::solvers::Solve::solve_in_place(llt, x.as_mut());
    }
    let mut reduced = nalgebra::DMatrix::<f64>::zeros(m, m);
    for (i, body) in bodies.iter().enumerate() {
        reduced.view_mut((6 * i, 6 * i), (6, 6)).copy_from(&(body.mass / density_kg_m3));
        for (t, row) in &body.tets {
            for k in 0..6 {
                for j in 0..m {
                    reduced[(6 * i + k, j)] += row[k] * x[(*t, j)];
                }
            }
        }
    }
    // Bᵀ L⁻¹ B is symmetric up to rounding; factor its symmetric part.
    let symmetric = (&reduced + reduced.transpose()) * 0.5;
    Ok(Coupling { bodies, pressure_per_impulse: x, reduced: symmetric.cholesky() })
}
