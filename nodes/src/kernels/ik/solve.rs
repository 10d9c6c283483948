//! Weighted Jacobian IK (Meredith & Maddock): several end effectors at once, per-DOF
//! stiffness, joint limits, damping near singularities and the error-halving step.
//!
//! One iteration:
//! 1. `dX = X_g − X` for every effector, stacked (3 rows each).
//! 2. The analytic Jacobian `J` (3 rows per effector, one column per DOF): a rotation DOF
//!    with world axis `a` about pivot `p` moves effector `x` by `a × (x − p)` per radian; a
//!    root translation moves every effector along its axis.
//! 3. The weighted damped pseudo-inverse `J⁺ = W Jᵀ (J W Jᵀ + Λ²)⁻¹`. With `W = I` and no
//!    damping it is the paper's `Jᵀ(JJᵀ)⁻¹`; with `W < I` the step still reaches the
//!    linearised goal but stiff DOFs take less of it (eq. 1.6 with the weights inside the
//!    inverse, so a stiff joint does not stall convergence: [`Weighting::InsideInverse`]).
//!    The paper's own eq. 1.6, `Δθ = W J⁺ dX` with the unweighted `J⁺ = Jᵀ (J Jᵀ + Λ²)⁻¹`
//!    ([`Weighting::Paper`]), scales each DOF's share of the plain step by its weight, so a
//!    step falls short of the linearised goal and the iterations make up the rest. `Λ` damps only the singular
//!    directions of `J √W` whose singular value is under `singular_m` (a straight chain, an
//!    unreachable goal), growing to `max_damping_m` at an exact singularity.
//! 4. Error halving: the step is halved while the linear prediction `X + J·Δθ` misses the
//!    forward-kinematics result by more than `halving_m` (with damping, the paper's
//!    `‖(I − J J⁺) dX‖` only measures what the damping held back, which halving cannot
//!    fix; the prediction error is what halving controls), and, with the weights inside
//!    the inverse, while it does not improve the error (at most `max_halvings` times).
//! 5. `θ ← clamp(θ + J⁺ dX)` to the joint limits.
//! 6. Stop when every effector is within `tolerance_m`, or after `max_iterations`.
//!
//! The solver owns every buffer it needs: a solve allocates nothing.

use faer::diag::Diag;
use faer::dyn_stack::{MemStack, StackReq};
use faer::linalg::evd::{ComputeEigenvectors, self_adjoint_evd, self_adjoint_evd_scratch};
use faer::{Mat, Par};
use glam::{DQuat, DVec3};
use nalgebra::{DMatrix, DVector, SMatrix, SymmetricEigen};

use super::rig::{DofKind, IkPose, IkRig};

/// Stopping and stepping controls of a solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveParams {
    /// Stop when every effector is this close to its goal (metres).
    pub tolerance_m: f64,
    /// Stop after this many iterations.
    pub max_iterations: usize,
    /// Error-halving threshold `e` (metres): how far forward kinematics may land from the
    /// step's linear prediction.
    pub halving_m: f64,
    /// Halvings allowed per iteration (both the `dX` halving and the step backtracking).
    pub max_halvings: usize,
    /// Damping starts when the smallest singular value of the weighted Jacobian falls
    /// below this (metres per radian).
    pub singular_m: f64,
    /// Damping `λ` reached at an exact singularity (metres per radian).
    pub max_damping_m: f64,
    /// Where the DOF weights enter the pseudo-inverse.
    pub weighting: Weighting,
}

/// Where the DOF weights `W` enter a step (see the module doc, step 3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Weighting {
    /// `W Jᵀ (J W Jᵀ + Λ²)⁻¹`: every step reaches the linearised goal; stiff DOFs take less.
    #[default]
    InsideInverse,
    /// Meredith & Maddock's eq. 1.6, `W Jᵀ (J Jᵀ + Λ²)⁻¹`: the plain step, each DOF's share
    /// scaled by its weight.
    Paper,
}

impl Default for SolveParams {
    fn default() -> Self {
        SolveParams {
            tolerance_m: 1e-4,
            max_iterations: 50,
            halving_m: 0.02,
            max_halvings: 8,
            singular_m: 0.02,
            max_damping_m: 0.05,
            weighting: Weighting::InsideInverse,
        }
    }
}

/// How one solve ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveReport {
    /// Iterations run.
    pub iterations: usize,
    /// Largest effector distance to its goal at the end (metres).
    pub residual_m: f64,
    /// True when `residual_m <= tolerance_m`.
    pub converged: bool,
}

/// [`EigenBuffers::decompose`] for the fixed sizes listed, on the stack (nalgebra's static
/// `SymmetricEigen`), with the same fallback: zero eigenvalues if it does not converge.
/// Returns false for any other size. A macro because nalgebra's eigen-decomposition is
/// only implemented for concrete dimensions, not over a const generic.
macro_rules! decompose_fixed {
    ($a:expr, $basis:expr, $values:expr, $($m:literal),+) => {
        match $a.nrows() {
            $($m => {
                /// QR sweeps allowed; a 15 × 15 matrix converges in a few dozen.
                const MAX_SWEEPS: usize = 1000;
                let fixed = SMatrix::<f64, $m, $m>::from_fn(|r, c| $a[(r, c)]);
                match SymmetricEigen::try_new(fixed, f64::EPSILON, MAX_SWEEPS) {
                    Some(eigen) => {
                        $basis.copy_from(&eigen.eigenvectors);
                        $values.copy_from(&eigen.eigenvalues);
                    }
                    None => {
                        $basis.fill_with_identity();
                        $values.fill(0.0);
                    }
                }
                true
            })+
            _ => false,
        }
    };
}

/// Buffers of faer's symmetric eigen-decomposition for `m × m` matrices. nalgebra's
/// `SymmetricEigen` on a dynamic matrix allocates its results, which a solve with several
/// effectors paid on every iteration; on a fixed-size matrix it lives on the stack and, for
/// the 3–15 task rows of one to five effectors, is several times faster than faer's general
/// routine (whose tridiagonalisation is built for large matrices), so those sizes use it.
#[derive(Clone, Debug)]
struct EigenBuffers {
    matrix: Mat<f64>,
    vectors: Mat<f64>,
    values: Diag<f64>,
    scratch: Vec<std::mem::MaybeUninit<u8>>,
}

impl EigenBuffers {
    fn new(m: usize) -> Self {
        let req: StackReq = self_adjoint_evd_scratch::<f64>(m, ComputeEigenvectors::Yes, Par::Seq, Default::default());
        EigenBuffers {
            matrix: Mat::zeros(m, m),
            vectors: Mat::zeros(m, m),
            values: Diag::zeros(m),
            scratch: vec![std::mem::MaybeUninit::new(0); req.unaligned_bytes_required()],
        }
    }

    /// Eigenvectors (columns of `basis`) and eigenvalues of the symmetric `a`. If the
    /// iteration does not converge (not seen on finite input) the eigenvalues are zero, so
    /// every direction gets the full damping instead of a NaN.
    fn decompose(&mut self, a: &DMatrix<f64>, basis: &mut DMatrix<f64>, values: &mut DVector<f64>) {
        let m = a.nrows();
        if decompose_fixed!(a, basis, values, 3, 6, 9, 12, 15) {
            return;
        }
        for c in 0..m {
            for r in 0..m {
                self.matrix[(r, c)] = a[(r, c)];
            }
        }
        let stack = MemStack::new(&mut self.scratch);
        let solved = self_adjoint_evd(
            self.matrix.as_ref(),
            self.values.as_mut(),
            Some(self.vectors.as_mut()),
            Par::Seq,
            stack,
            Default::default(),
        );
        for c in 0..m {
            values[c] = if solved.is_ok() { self.values[c] } else { 0.0 };
            for r in 0..m {
                basis[(r, c)] = self.vectors[(r, c)];
            }
        }
    }
}

/// The weighted IK solver: a rig and the buffers for its Jacobian and solves.
#[derive(Clone, Debug)]
pub struct IkSolver {
    rig: IkRig,
    world: Vec<(DQuat, DVec3)>,
    axes: Vec<(DVec3, DVec3)>,
    /// `Jᵀ` (DOFs × task rows): a task row of `J` is a contiguous column here.
    jt: DMatrix<f64>,
    /// `W Jᵀ`.
    wjt: DMatrix<f64>,
    /// `J W Jᵀ` (task rows × task rows).
    jwjt: DMatrix<f64>,
    /// Its eigenvectors (columns) and eigenvalues (squared singular values of `J √W`).
    basis: DMatrix<f64>,
    sigma_sq: DVector<f64>,
    /// Damped inverse per eigen-direction.
    inverse: DVector<f64>,
    /// The eigen-decomposition's input, outputs and scratch memory, made once per rig so a
    /// solve with any number of effectors allocates nothing.
    eigen: EigenBuffers,
    /// Goal offsets `X_g − X`, stacked.
    pub(crate) dx: DVector<f64>,
    /// Goal offsets of a trial pose.
    trial_dx: DVector<f64>,
    /// `(J W Jᵀ + Λ²)⁻¹ dX`.
    y: DVector<f64>,
    /// Predicted effector motion `J · step`.
    motion: DVector<f64>,
    /// DOF step `W Jᵀ y`.
    step: DVector<f64>,
    start: Vec<f64>,
    weights: Vec<f64>,
    /// Scratch pose for trial steps.
    trial: Option<IkPose>,
}

impl IkSolver {
    /// A solver for `rig`.
    pub fn new(rig: IkRig) -> Self {
        let (n, m) = (rig.dofs().len(), 3 * rig.effectors().len());
        let joints = rig.skeleton().len();
        IkSolver {
            world: vec![(DQuat::IDENTITY, DVec3::ZERO); joints],
            axes: vec![(DVec3::ZERO, DVec3::ZERO); n],
            jt: DMatrix::zeros(n, m),
            wjt: DMatrix::zeros(n, m),
            jwjt: DMatrix::zeros(m, m),
            basis: DMatrix::zeros(m, m),
            sigma_sq: DVector::zeros(m),
            inverse: DVector::zeros(m),
            eigen: EigenBuffers::new(m),
            dx: DVector::zeros(m),
            trial_dx: DVector::zeros(m),
            y: DVector::zeros(m),
            motion: DVector::zeros(m),
            step: DVector::zeros(n),
            start: vec![0.0; n],
            weights: rig.dofs().iter().map(|d| d.weight.clamp(0.0, 1.0)).collect(),
            trial: None,
            rig,
        }
    }

    /// The rig.
    pub fn rig(&self) -> &IkRig {
        &self.rig
    }

    /// Changes the stiffness of DOF `d` (clamped to [0, 1]).
    pub fn set_weight(&mut self, d: usize, weight: f64) {
        let w = if weight.is_finite() { weight.clamp(0.0, 1.0) } else { 0.0 };
        self.rig.dofs_mut()[d].weight = w;
        self.weights[d] = w;
    }

    /// Makes effector `e` a point `offset` in its joint's frame ([`IkRig::set_effector_offset`]).
    pub fn set_effector_offset(&mut self, e: usize, offset: DVec3) {
        self.rig.set_effector_offset(e, offset);
    }

    /// World positions of the effectors in `pose` into `out`.
    pub fn effector_positions(&mut self, pose: &IkPose, out: &mut [DVec3]) {
        self.rig.forward(pose, &mut self.world);
        for (e, o) in out.iter_mut().enumerate().take(self.rig.effectors().len()) {
            *o = self.rig.effector_position(e, &self.world);
        }
    }

    /// World transforms of every joint after the last forward pass.
    pub fn world(&self) -> &[(DQuat, DVec3)] {
        &self.world
    }

    /// Runs forward kinematics, fills `dx` with `goals − X` and `jt` with `Jᵀ`; returns the
    /// largest effector error (metres).
    pub(crate) fn linearise(&mut self, pose: &IkPose, goals: &[DVec3]) -> f64 {
        self.rig.forward(pose, &mut self.world);
        self.linearise_forward(pose, goals)
    }

    /// [`IkSolver::linearise`] for `pose`, the pose of the last forward pass (its world
    /// transforms are current), so a step's accepted trial is not run through FK twice.
    fn linearise_forward(&mut self, pose: &IkPose, goals: &[DVec3]) -> f64 {
        self.rig.dof_axes(pose, &self.world, &mut self.axes);
        let mut worst = 0.0f64;
        for (e, goal) in goals.iter().enumerate().take(self.rig.effectors().len()) {
            let x = self.rig.effector_position(e, &self.world);
            // Unconstrained axes are zero rows: no error, no motion asked of them.
            let keep = self.rig.effector_masks()[e];
            let d = (*goal - x) * keep;
            worst = worst.max(d.length());
            for k in 0..3 {
                self.dx[3 * e + k] = d[k];
            }
            for (dof, &(axis, pivot)) in self.axes.iter().enumerate() {
                let col = if !self.rig.moves(dof, e) {
                    DVec3::ZERO
                } else if matches!(self.rig.dofs()[dof].kind, DofKind::Translation { .. }) {
                    axis
                } else {
                    axis.cross(x - pivot)
                } * keep;
                for k in 0..3 {
                    self.jt[(dof, 3 * e + k)] = col[k];
                }
            }
        }
        worst
    }

    /// The current `Jᵀ` (DOFs × task rows), after [`IkSolver::effector_positions`] or a solve.
    pub fn jacobian_transposed(&self) -> &DMatrix<f64> {
        &self.jt
    }

    /// Fills `jt` for `pose` (and returns it).
    pub fn jacobian(&mut self, pose: &IkPose) -> &DMatrix<f64> {
        let goals = vec![DVec3::ZERO; self.rig.effectors().len()];
        self.linearise(pose, &goals);
        &self.jt
    }

    /// Builds `W Jᵀ` and the eigen-decomposition of `J W Jᵀ` (of `J Jᵀ` under
    /// [`Weighting::Paper`]), and the per-direction
    /// inverse `1 / (σ² + λ²)` with the damping `λ` applied only to singular directions of
    /// `J √W` whose singular value is under the threshold (selective damping). The threshold
    /// is `singular` in metres per radian, or, when `relative`, a fraction of the largest
    /// singular value. Returns the dexterity `σ_min / σ_max` of `J √W` over the directions
    /// the tasks constrain (an effector's unconstrained axis is a zero row, whose zero
    /// singular value says nothing of the limbs).
    pub(crate) fn decompose(&mut self, singular: f64, max_damping: f64, relative: bool, weighting: Weighting) -> f64 {
        self.wjt.copy_from(&self.jt);
        for (mut row, w) in self.wjt.row_iter_mut().zip(&self.weights) {
            row *= *w;
        }
        let inner = match weighting {
            Weighting::InsideInverse => &self.wjt,
            Weighting::Paper => &self.jt,
        };
        // Symmetric (W is diagonal): the upper triangle's dot products, mirrored.
        let m = self.jwjt.nrows();
        for i in 0..m {
            for k in i..m {
                let v = self.jt.column(i).dot(&inner.column(k));
                self.jwjt[(i, k)] = v;
                self.jwjt[(k, i)] = v;
            }
        }
        self.eigen.decompose(&self.jwjt, &mut self.basis, &mut self.sigma_sq);
        let s_max = self.sigma_sq.max().max(0.0).sqrt();
        let masks = self.rig.effector_masks();
        // A direction lying mostly along zero rows is an unconstrained axis.
        let unconstrained = |i: usize| {
            (0..self.basis.nrows())
                .filter(|&r| masks[r / 3][r % 3] == 0.0)
                .map(|r| self.basis[(r, i)].powi(2))
                .sum::<f64>()
        };
        let s_min = (0..self.sigma_sq.len())
            .filter(|&i| unconstrained(i) < 0.5)
            .map(|i| self.sigma_sq[i])
            .fold(f64::INFINITY, f64::min)
            .max(0.0)
            .sqrt();
        for i in 0..self.sigma_sq.len() {
            let s = self.sigma_sq[i].max(0.0).sqrt();
            let measure = if relative { if s_max > 0.0 { s / s_max } else { 0.0 } } else { s };
            let lambda_sq = if measure < singular {
                let r = measure / singular;
                max_damping * max_damping * (1.0 - r * r)
            } else {
                0.0
            };
            let denom = s * s + lambda_sq;
            self.inverse[i] = if denom > 1e-300 { denom.recip() } else { 0.0 };
        }
        if s_max > 0.0 && s_min.is_finite() { s_min / s_max } else { 0.0 }
    }

    /// `out = J⁺ dX`, the task error of the last [`IkSolver::linearise`] or
    /// [`IkSolver::task_offsets`], with the last [`IkSolver::decompose`].
    pub(crate) fn apply_pinv_to_task(&mut self, out: &mut DVector<f64>) {
        let dx = std::mem::take(&mut self.dx);
        self.apply_pinv(&dx, out);
        self.dx = dx;
    }

    /// `out = J⁺ rhs` with the last [`IkSolver::decompose`] (`rhs` has one row per task row).
    pub(crate) fn apply_pinv(&mut self, rhs: &DVector<f64>, out: &mut DVector<f64>) {
        self.y.fill(0.0);
        for i in 0..self.inverse.len() {
            let u = self.basis.column(i);
            let coef = u.dot(rhs) * self.inverse[i];
            self.y.axpy(coef, &u, 1.0);
        }
        out.gemv(1.0, &self.wjt, &self.y, 0.0);
    }

    /// The goal offsets of `pose` as the task error (as [`IkSolver::linearise`] gives it,
    /// without the Jacobian, which is kept); returns the largest effector error (metres).
    pub(crate) fn task_offsets(&mut self, pose: &IkPose, goals: &[DVec3]) -> f64 {
        let worst = self.evaluate(pose, goals);
        self.dx.copy_from(&self.trial_dx);
        worst
    }

    /// Forward kinematics only: the goal offsets of `pose` into `trial_dx`; returns the
    /// largest effector error (metres).
    fn evaluate(&mut self, pose: &IkPose, goals: &[DVec3]) -> f64 {
        self.rig.forward(pose, &mut self.world);
        let mut worst = 0.0f64;
        for (e, goal) in goals.iter().enumerate().take(self.rig.effectors().len()) {
            let d = (*goal - self.rig.effector_position(e, &self.world)) * self.rig.effector_masks()[e];
            worst = worst.max(d.length());
            for k in 0..3 {
                self.trial_dx[3 * e + k] = d[k];
            }
        }
        worst
    }

    /// Runs the weighted IK from `pose` towards `goals` (one per effector, world metres),
    /// updating `pose` in place.
    pub fn solve(&mut self, pose: &mut IkPose, goals: &[DVec3], params: &SolveParams) -> SolveReport {
        let mut trial = self.trial.take().unwrap_or_else(|| pose.clone());
        let mut iterations = 0;
        let mut error = self.linearise(pose, goals);
        while error > params.tolerance_m && iterations < params.max_iterations {
            iterations += 1;
            self.decompose(params.singular_m, params.max_damping_m, false, params.weighting);
            let mut step = std::mem::take(&mut self.step);
            self.apply_pinv_to_task(&mut step);
            self.step = step;
            // The motion the linear model predicts for the full step: J · step.
            self.motion.gemv_tr(1.0, &self.jt, &self.step, 0.0);
            for d in 0..self.start.len() {
                self.start[d] = self.rig.dof_value(pose, d);
            }
            let mut scale = 1.0;
            let mut accepted = None;
            for halving in 0..=params.max_halvings {
                trial.clone_from(pose);
                for d in 0..self.start.len() {
                    self.rig.set_dof(&mut trial, d, self.start[d] + scale * self.step[d]);
                }
                let trial_error = self.evaluate(&trial, goals);
                // Error of the linear prediction: (dX − scale·J·step) vs the real offsets.
                let mut predict_sq = 0.0;
                for r in 0..self.dx.len() {
                    let p = self.dx[r] - scale * self.motion[r] - self.trial_dx[r];
                    predict_sq += p * p;
                }
                // Eq. 1.6's step (I − J W J⁺ with eigenvalues in [0, 1) on the error) shrinks
                // the error over iterations but not always in every one: it is held to the
                // paper's test, the linear prediction, alone.
                let improves = trial_error < error || params.weighting == Weighting::Paper;
                if improves && (predict_sq.sqrt() <= params.halving_m || halving == params.max_halvings) {
                    accepted = Some(trial_error);
                    break;
                }
                scale *= 0.5;
            }
            let Some(new_error) = accepted else {
                // No improving step (a local minimum, a limit or a singular goal): stop.
                break;
            };
            std::mem::swap(pose, &mut trial);
            error = new_error;
            if error > params.tolerance_m && iterations < params.max_iterations {
                // The accepted trial was the last pose evaluated: its forward pass is current.
                self.linearise_forward(pose, goals);
            }
        }
        self.trial = Some(trial);
        SolveReport { iterations, residual_m: error, converged: error <= params.tolerance_m }
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec3};

    use std::sync::Arc;

    use super::*;
    use crate::model::{Joint, Skeleton};

    /// A planar chain along +X with the given link lengths, turning about Z only.
    fn planar_chain(lengths: &[f32], weights: &[f64]) -> IkRig {
        let mut joints = vec![Joint::new("j0", None, Vec3::ZERO)];
        for (i, l) in lengths.iter().enumerate() {
            joints.push(Joint::new(format!("j{}", i + 1), Some(i), Vec3::new(*l, 0.0, 0.0)));
        }
        let mut rig = IkRig::new(Arc::new(Skeleton::new(joints).unwrap()));
        for (j, w) in weights.iter().enumerate() {
            rig.add_joint(j, [false, false, true], *w);
        }
        rig.add_effector(lengths.len());
        rig.finish().unwrap()
    }

    fn rest_pose(rig: &IkRig) -> IkPose {
        let sk = rig.skeleton();
        let rot = vec![Quat::IDENTITY; sk.len()];
        let tr: Vec<Vec3> = sk.joints().iter().map(|j| j.rest_offset).collect();
        rig.pose_from(&rot, &tr)
    }

    #[test]
    fn two_link_reaches_the_hand_solved_angles() {
        let (l1, l2) = (0.3f64, 0.25f64);
        let rig = planar_chain(&[0.3, 0.25], &[1.0, 1.0]);
        let mut solver = IkSolver::new(rig);
        let mut pose = rest_pose(solver.rig());
        pose.euler[1][2] = 0.3; // elbow bent the positive way: expect that branch
        let (x, y) = (0.2f64, 0.35f64);
        let report = solver.solve(&mut pose, &[DVec3::new(x, y, 0.0)], &SolveParams::default());
        assert!(report.converged, "{report:?}");
        // Law of cosines, elbow-positive branch.
        let b = ((x * x + y * y - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)).acos();
        let a = y.atan2(x) - (l2 * b.sin()).atan2(l1 + l2 * b.cos());
        assert!((pose.euler[0][2] - a).abs() < 1e-3, "shoulder {} vs {a}", pose.euler[0][2]);
        assert!((pose.euler[1][2] - b).abs() < 1e-3, "elbow {} vs {b}", pose.euler[1][2]);
    }

    /// A 3D leg-like chain with three-axis joints, two effectors and a moving root.
    fn branching_rig() -> IkRig {
        let joints = vec![
            Joint::new("pelvis", None, Vec3::new(0.0, 1.0, 0.0)),
            Joint::new("hip", Some(0), Vec3::new(0.1, -0.05, 0.0)),
            Joint::new("knee", Some(1), Vec3::new(0.0, -0.45, 0.02)),
            Joint::new("ankle", Some(2), Vec3::new(0.0, -0.42, -0.03)),
            Joint::new("toe", Some(3), Vec3::new(0.0, -0.05, 0.15)),
            Joint::new("chest", Some(0), Vec3::new(0.0, 0.4, 0.0)),
            Joint::new("hand", Some(5), Vec3::new(0.5, 0.1, 0.1)),
        ];
        let mut rig = IkRig::new(Arc::new(Skeleton::new(joints).unwrap()));
        rig.add_root_translation(1.0);
        rig.add_chain("pelvis", "toe", 1.0).unwrap();
        rig.add_chain("pelvis", "hand", 1.0).unwrap();
        let toe = rig.joint("toe").unwrap();
        let hand = rig.joint("hand").unwrap();
        rig.add_effector(toe);
        rig.add_effector(hand);
        rig.finish().unwrap()
    }

    #[test]
    fn analytic_jacobian_matches_finite_differences() {
        let rig = branching_rig();
        let mut solver = IkSolver::new(rig);
        let mut pose = rest_pose(solver.rig());
        for (s, e) in pose.euler.iter_mut().enumerate() {
            *e = [0.3 + 0.1 * s as f64, -0.7 + 0.2 * s as f64, 1.1 - 0.3 * s as f64];
        }
        let jt = solver.jacobian(&pose).clone();
        let n = solver.rig().dofs().len();
        let h = 1e-6;
        let mut plus = [DVec3::ZERO; 2];
        let mut minus = [DVec3::ZERO; 2];
        for d in 0..n {
            let v = solver.rig().dof_value(&pose, d);
            let mut p = pose.clone();
            solver.rig().set_dof(&mut p, d, v + h);
            solver.effector_positions(&p, &mut plus);
            solver.rig().set_dof(&mut p, d, v - h);
            solver.effector_positions(&p, &mut minus);
            for e in 0..2 {
                let fd = (plus[e] - minus[e]) / (2.0 * h);
                for k in 0..3 {
                    let analytic = jt[(d, 3 * e + k)];
                    assert!((analytic - fd[k]).abs() < 1e-6, "dof {d} effector {e} row {k}: {analytic} vs {}", fd[k]);
                }
            }
        }
    }

    /// An effector on the ankle offset to where the toe sits in the ankle's frame stands
    /// for the toe joint: the same Jacobian and the same solve as the rig whose effector is
    /// the toe itself (positions through the joint's frame, as forward kinematics places the
    /// toe).
    #[test]
    fn an_offset_effector_stands_for_the_joint_at_that_point() {
        let with_toe = branching_rig();
        let mut rig = IkRig::new(with_toe.skeleton().clone());
        rig.add_root_translation(1.0);
        rig.add_chain("pelvis", "toe", 1.0).unwrap();
        rig.add_chain("pelvis", "hand", 1.0).unwrap();
        let (ankle, toe, hand) = (rig.joint("ankle").unwrap(), rig.joint("toe").unwrap(), rig.joint("hand").unwrap());
        let e = rig.add_effector(ankle);
        rig.add_effector(hand);
        rig.set_effector_offset(e, with_toe.skeleton().joints()[toe].rest_offset.as_dvec3());
        let mut a = IkSolver::new(with_toe);
        let mut b = IkSolver::new(rig.finish().unwrap());
        let mut pose = rest_pose(a.rig());
        for (s, e) in pose.euler.iter_mut().enumerate() {
            *e = [0.2 - 0.1 * s as f64, 0.4 * s as f64, -0.3];
        }
        let (ja, jb) = (a.jacobian(&pose).clone(), b.jacobian(&pose).clone());
        assert!((ja - jb).abs().max() < 1e-12);
        let goals = [DVec3::new(0.2, 0.1, 0.3), DVec3::new(0.3, 1.5, 0.2)];
        let (mut pa, mut pb) = (pose.clone(), pose);
        let (ra, rb) =
            (a.solve(&mut pa, &goals, &SolveParams::default()), b.solve(&mut pb, &goals, &SolveParams::default()));
        assert!(ra.converged && rb.converged && ra.iterations == rb.iterations, "{ra:?} {rb:?}");
        for (x, y) in pa.euler.iter().zip(&pb.euler) {
            for k in 0..3 {
                assert!((x[k] - y[k]).abs() < 1e-9, "{x:?} vs {y:?}");
            }
        }
    }

    #[test]
    fn several_effectors_converge_together() {
        let mut solver = IkSolver::new(branching_rig());
        let mut pose = rest_pose(solver.rig());
        let goals = [DVec3::new(0.15, 0.15, 0.25), DVec3::new(0.3, 1.6, 0.3)];
        let report = solver.solve(&mut pose, &goals, &SolveParams::default());
        assert!(report.converged, "{report:?}");
        let mut got = [DVec3::ZERO; 2];
        solver.effector_positions(&pose, &mut got);
        for (g, want) in got.iter().zip(&goals) {
            assert!((*g - *want).length() < 1e-4);
        }
    }

    #[test]
    fn unreachable_target_stretches_toward_it_without_nan() {
        let mut solver = IkSolver::new(planar_chain(&[0.3, 0.25], &[1.0, 1.0]));
        let mut pose = rest_pose(solver.rig());
        pose.euler[1][2] = 0.5;
        let goal = DVec3::new(0.6, 0.8, 0.0); // 1 m away, reach 0.55 m
        let report = solver.solve(&mut pose, &[goal], &SolveParams::default());
        assert!(!report.converged);
        assert!(pose.euler.iter().flatten().all(|v| v.is_finite()));
        let mut tip = [DVec3::ZERO];
        solver.effector_positions(&pose, &mut tip);
        // Best effort: the chain points at the goal, nearly straight.
        let angle = tip[0].angle_between(goal);
        assert!(angle < 0.01, "off by {angle} rad, {report:?}");
        assert!((report.residual_m - 0.45).abs() < 0.01, "{report:?}");
    }

    #[test]
    fn straight_singular_chain_stays_finite_and_bends_to_an_off_axis_goal() {
        let params = SolveParams::default();
        let mut solver = IkSolver::new(planar_chain(&[0.3, 0.3, 0.3], &[1.0; 3]));
        // Goal on the chain's own line: the Jacobian has no radial row at all.
        let mut pose = rest_pose(solver.rig());
        let report = solver.solve(&mut pose, &[DVec3::new(0.6, 0.0, 0.0)], &params);
        assert!(pose.euler.iter().flatten().all(|v| v.is_finite()));
        assert!(report.residual_m <= 0.3 + 1e-6, "{report:?}");
        // A goal off the line from the same straight start converges.
        let mut pose = rest_pose(solver.rig());
        let report = solver.solve(&mut pose, &[DVec3::new(0.5, 0.3, 0.0)], &params);
        assert!(report.converged, "{report:?}");
    }

    /// Meredith & Maddock's Figure 1.4: stiffen the root of a planar chain and the other
    /// joints take the motion. The goal is the tip turned 0.5 rad about the root, which the
    /// root alone could reach.
    #[test]
    fn stiffening_a_joint_moves_the_motion_to_the_others() {
        let run = |weights: &[f64]| {
            let mut solver = IkSolver::new(planar_chain(&[0.3, 0.3, 0.3], weights));
            let mut pose = rest_pose(solver.rig());
            pose.euler[1][2] = 0.4;
            pose.euler[2][2] = 0.4;
            let mut tip = [DVec3::ZERO];
            solver.effector_positions(&pose, &mut tip);
            let goal = DQuat::from_rotation_z(0.5) * tip[0];
            let report = solver.solve(&mut pose, &[goal], &SolveParams::default());
            let moved = [pose.euler[0][2], pose.euler[1][2] - 0.4, pose.euler[2][2] - 0.4];
            (moved[0].abs(), moved[1].abs() + moved[2].abs(), report.converged)
        };
        let (even_root, even_others, even_ok) = run(&[1.0, 1.0, 1.0]);
        let (stiff_root, stiff_others, stiff_ok) = run(&[0.2, 1.0, 1.0]);
        assert!(even_ok && stiff_ok);
        // Measured: root 0.475 → 0.437 rad, the other two 0.157 → 0.560 rad (see the note).
        assert!(stiff_root < 0.95 * even_root, "root {stiff_root} vs {even_root}");
        assert!(stiff_others > 2.0 * even_others, "others {stiff_others} vs {even_others}");
        // A fully stiff root does not move at all (the goal is then out of reach).
        let (locked_root, _, _) = run(&[0.0, 1.0, 1.0]);
        assert!(locked_root < 1e-12, "{locked_root}");
    }

    /// One step of each weighting on a bent three-link planar chain (weights 0.2, 1, 0.5),
    /// against the formulas evaluated with nalgebra: `W J⁺ dX` with the SVD pseudo-inverse
    /// (eq. 1.6) and `W Jᵀ (J W Jᵀ)⁻¹ dX`, `J` by central differences. The inside weighting
    /// meets the linearised goal (`J Δθ = dX`), the paper's falls short of it; both reach
    /// the goal when iterated.
    #[test]
    fn both_weightings_take_the_step_their_formula_gives() {
        let weights = [0.2, 1.0, 0.5];
        let rig = planar_chain(&[0.3, 0.3, 0.3], &weights);
        let mut start = rest_pose(&rig);
        start.euler[1][2] = 0.4;
        start.euler[2][2] = 0.6;
        let mut solver = IkSolver::new(rig);
        let mut tip = [DVec3::ZERO];
        solver.effector_positions(&start, &mut tip);
        let goal = tip[0] + DVec3::new(-0.004, 0.003, 0.0);
        let dx = DVector::from_vec(vec![goal.x - tip[0].x, goal.y - tip[0].y, 0.0]);
        let mut j = DMatrix::<f64>::zeros(3, 3);
        for d in 0..3 {
            let h = 1e-6;
            let mut at = |s: f64| {
                let mut p = start.clone();
                p.euler[d][2] += s * h;
                solver.effector_positions(&p, &mut tip);
                tip[0]
            };
            let column = (at(1.0) - at(-1.0)) / (2.0 * h);
            for k in 0..3 {
                j[(k, d)] = column[k];
            }
        }
        let w = DMatrix::from_diagonal(&DVector::from_row_slice(&weights));
        let paper = &w * j.clone().pseudo_inverse(1e-12).unwrap() * &dx;
        let jw = j.rows(0, 2).into_owned();
        let inside = &w * jw.transpose() * (&jw * &w * jw.transpose()).try_inverse().unwrap() * dx.rows(0, 2);
        let mut one_step = |weighting: Weighting| {
            let mut pose = start.clone();
            let params = SolveParams { max_iterations: 1, halving_m: 1.0, weighting, ..SolveParams::default() };
            solver.solve(&mut pose, &[goal], &params);
            DVector::from_iterator(3, (0..3).map(|d| pose.euler[d][2] - start.euler[d][2]))
        };
        let (got_paper, got_inside) = (one_step(Weighting::Paper), one_step(Weighting::InsideInverse));
        assert!((&got_paper - &paper).norm() < 1e-6 * paper.norm(), "{got_paper} vs {paper}");
        assert!((&got_inside - &inside).norm() < 1e-6 * inside.norm(), "{got_inside} vs {inside}");
        let reached = |step: &DVector<f64>| (&j * step - &dx).norm() / dx.norm();
        assert!(reached(&got_inside) < 1e-5, "{}", reached(&got_inside));
        assert!(reached(&got_paper) > 0.1, "{}", reached(&got_paper));
        for weighting in [Weighting::Paper, Weighting::InsideInverse] {
            let mut pose = start.clone();
            let report = solver.solve(&mut pose, &[goal], &SolveParams { weighting, ..SolveParams::default() });
            assert!(report.converged, "{weighting:?}: {report:?}");
        }
    }

    #[test]
    fn joint_limits_hold() {
        let mut rig = planar_chain(&[0.3, 0.25], &[1.0, 1.0]);
        rig.dofs_mut()[1].min = 0.0;
        rig.dofs_mut()[1].max = 0.5;
        let mut solver = IkSolver::new(rig);
        let mut pose = rest_pose(solver.rig());
        solver.solve(&mut pose, &[DVec3::new(0.0, 0.3, 0.0)], &SolveParams::default());
        assert!((0.0..=0.5).contains(&pose.euler[1][2]), "{:?}", pose.euler);
    }
}
