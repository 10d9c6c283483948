//! Momentum-based editing, the spacetime optimisation (issue 15, step 3): from the naive
//! kinematic edit ([`naive_edit`]) to a clip whose momentum is physically plausible.
//!
//! Unknowns: per frame the root translation (3) and a rotation-vector increment ω_a (3) for
//! every *active* joint a (one whose subtree carries at least [`MIN_SUBTREE_MASS`] of the
//! body or holds a foot), applied in world axes about the joint: R_a ← W_pᵀ exp(ω) W_p R_a
//! (W_p the parent's world rotation). A world increment has the simplest FK derivative,
//! ∂p_j/∂ω_a = e × (p_j − p_a), and is re-linearised about the current pose each step.
//! Plus G: the control points of the momentum splines (per mass, so in m/s and m²/s) and
//! the value of every flight line, with the knots of [`fit_momentum`] fixed.
//!
//! Objective: Σ (δ_a / range_a)² over frames and active joints (δ_a the rotation vector
//! from the initial guess's local rotation, range_a the joint's natural range in the
//! original clip; the root translation likewise per axis) + the pseudo-balance term,
//! ((c(f) − c_init(f)) / [`BALANCE_SCALE_M`])² at the first frame of the first ground stage,
//! the last frame of the last and mid-frame of interior ones + smoothness, the paper's "as
//! smooth as possible": Σ (Δ²δ (fps · [`SMOOTH_SECS`])² / range)², δ's second difference
//! over frames.
//!
//! Constraints: planted feet on their edited places, held as the foot lock holds them (the
//! initial guess's toe tip at the contact's lowest frame, which is where the edit asked, the
//! ankle and toe tip moved by the toe's drift, so the capture's heel rise and roll stay; the
//! hold fading out after the contact); both ankles at their edited places at each ground
//! stage's first frame (the landing); ankles never below the floor;
//! linear and angular momentum of Q equal to the splines of G between every two frames
//! (at t = (f + ½)/fps, from the difference of the two frames); C1 between ground splines and
//! flight lines (the vertical momentum at a landing only C0). Central differences, as
//! [`momentum_of_poses`] measures momentum, would leave the constraints blind to a zigzag
//! (every other frame moved one way): the solver used it to meet the landing pins, and the
//! root's velocity jumped 2–4 m/s in one frame at the take-off and the landing (CMU 16_01).
//!
//! Solver: an augmented Lagrangian whose subproblems are damped Gauss–Newton
//! (Levenberg–Marquardt) steps on the sparse normal equations JᵀJ + λ diag(JᵀJ), factored by faer's
//! sparse Cholesky (already a dependency). Why not clarabel's QP: every constraint here is
//! an equality except the floor, the problem is a nonlinear least squares whose Gauss–Newton
//! Hessian *is* JᵀJ, and one sparse Cholesky per step is all an SQP's QP would cost without
//! the interior-point iterations on ~30 000 unknowns; the floor is a one-sided penalty.
//!
//! Joint limits: BVH clips carry none, so each active joint but the root (which the edit
//! turns) keeps within its natural range in the original clip: the angle of its local
//! rotation from the original's mean rotation stays under the largest such angle of the
//! original plus [`LIMIT_MARGIN_RAD`]. One-sided like the floor, but soft: a fixed penalty
//! whose final violation is reported, because as a hard constraint it stalled the solver
//! (0.025 rad left after 120 steps on CMU 16_01 landing 0.58 m away).

use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SymbolicSparseColMat, SymbolicSparseColMatRef};
use faer::{Par, Side};
use glam::{DMat3, DQuat, DVec3, Quat};

use super::angular::{MomentumTrack, momentum_of_poses};
use super::body::{BodyModel, limb_tip};
use super::ik::foot_lock::Plants;
use super::momentum_edit::{EditError, GroundEdit, floor_height, held_from_landings, naive_edit};
use super::momentum_splines::{MomentumFit, Piece, SplineError, basis, fit_momentum};
use crate::model::{Clip, ClipError, ClipPoses, FrameRange, Stage, StageKind, Stages, forward_kinematics};

/// Joints whose subtree carries less than this share of the body mass (fingers, toes, the
/// head's end) are left as the initial guess has them: they barely change the momentum.
pub const MIN_SUBTREE_MASS: f64 = 0.005;

/// Time scale of the smoothness term, seconds: the edit's displacement of a DOF may bend
/// over this time at the cost of its distance; a sharper bend costs more (as (SMOOTH_SECS / T)⁴
/// for a bend over T). Without it the frames at the clip's ends and beside the pins took up
/// whatever the momentum splines asked in one frame (an arm swung 69 cm into CMU 16_01's
/// second frame).
pub const SMOOTH_SECS: f64 = 0.1;

/// Distance that makes one unit of the pseudo-balance term, metres.
pub const BALANCE_SCALE_M: f64 = 0.02;

/// Frames within this time of a cut edge of the window an edit solves are held to the
/// initial guess [`CUT_EDGE_WEIGHT`] times harder: the frames beyond the cut keep that guess
/// (the capture moved rigidly), so the solved frames join them without a jump.
pub const CUT_EDGE_SECS: f64 = 0.1;

/// Weight of the similarity rows of the frames near a cut edge (see [`CUT_EDGE_SECS`]).
pub const CUT_EDGE_WEIGHT: f64 = 10.0;

/// Fewest frames an edit works on (two ground stages around a flight of a few frames).
pub const MIN_FRAMES: usize = 12;

/// The largest change of horizontal take-off speed an edit may ask for, m/s: beyond it the
/// legs cannot push (the landing is unreachable).
pub const MAX_EXTRA_SPEED_MPS: f64 = 4.0;

/// Accepted Levenberg–Marquardt steps between two multiplier updates. Over nine edits of
/// CMU 16_01 (landing moved up to 0.8 m, turned 0, 90 and 180°) 2 took 12–25 steps, 4 took
/// 27–28 for the same measures (root velocity, feet, floor within a few per cent).
const STEPS_PER_UPDATE: usize = 2;

/// Penalties grow at most this much above their start (beyond it the normal equations
/// lose precision; the multipliers do the rest).
const MAX_PENALTY_GROWTH: f64 = 100.0;

/// How far past its natural range a joint may go, radians: an edit asks for a stronger
/// push than the capture made, and a zero-width range (a joint the capture never moves)
/// would make the limit's gradient undefined.
pub const LIMIT_MARGIN_RAD: f64 = 0.1;

/// Time over which a planted foot's hold fades out after its contact, seconds (the foot
/// lock's default blend): released at once, the foot would jump by the drift the hold took
/// out of the capture.
const RELEASE_SECS: f64 = 0.15;

/// Ankles are kept this far above the floor, metres (a margin for the one-sided penalty).
const FLOOR_MARGIN_M: f64 = 2e-4;

/// One kind of constraint: its name for reports and errors, tolerance and starting penalty.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Group {
    name: &'static str,
    unit: &'static str,
    tolerance: f64,
    penalty: f64,
    /// A hard constraint must meet its tolerance (else the edit fails); a soft one is a
    /// fixed penalty whose final violation is only reported.
    hard: bool,
}

const FEET: usize = 0;
const FLOOR: usize = 1;
const LINEAR: usize = 2;
const ANGULAR: usize = 3;
const JOIN: usize = 4;
const LIMITS: usize = 5;

/// Groups whose constraints are inequalities g ≤ 0 (the value is the signed violation).
fn one_sided(group: usize) -> bool {
    group == FLOOR || group == LIMITS
}

/// The constraint groups (the floor and the joint limits one-sided), tolerances chosen from the acceptance measures: feet to 0.5 mm,
/// linear momentum per mass to 5 mm/s (a parabola well under 1 cm), angular momentum per
/// mass to 5·10⁻⁵ m²/s (3.5·10⁻³ kg·m²/s for 70 kg, a few % of a jump's flight spin).
const GROUPS: [Group; 6] = [
    Group { name: "planted feet", unit: "m", tolerance: 5e-4, penalty: 1e6, hard: true },
    Group { name: "feet above the floor", unit: "m", tolerance: 5e-4, penalty: 1e6, hard: true },
    Group { name: "linear momentum = splines", unit: "m/s", tolerance: 5e-3, penalty: 1e4, hard: true },
    Group { name: "angular momentum = splines", unit: "m²/s", tolerance: 5e-5, penalty: 1e7, hard: true },
    Group { name: "C1 splines at stage borders", unit: "m/s", tolerance: 5e-3, penalty: 1e4, hard: true },
    Group { name: "joint limits", unit: "rad", tolerance: 1e-3, penalty: 1e4, hard: false },
];

/// What the optimisation may change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveOptions {
    /// Gravity in flight as a multiple of the fitted gravity (1 keeps it).
    pub gravity_scale: f64,
    /// Knot spacing of the ground-stage momentum splines, seconds.
    pub knot_spacing_secs: f64,
    /// Most Gauss–Newton steps.
    pub max_iterations: usize,
    /// Which frames are re-solved.
    pub frames: SolvedFrames,
}

/// Which frames an edit re-solves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SolvedFrames {
    /// Around the edit for clips longer than [`AUTO_WINDOW_SECS`], every frame otherwise.
    #[default]
    Auto,
    /// Every frame: the whole capture comes out cleaned (every contact held, every flight
    /// ballistic), not only the part the edit changes.
    Whole,
    /// Only the frames around the edit ([`edit_window`]); the others are the capture moved
    /// rigidly with their ground stages, artefacts included.
    AroundEdit,
}

/// Clips longer than this are solved only around the edit under [`SolvedFrames::Auto`]:
/// CMU 01_01 (23 s, eleven hops, 198 k unknowns) did not converge in 120 steps as a whole
/// (82 s), and one of its hops converges in 35 (2.5 s) alone.
pub const AUTO_WINDOW_SECS: f64 = 10.0;

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions { gravity_scale: 1.0, knot_spacing_secs: 0.1, max_iterations: 120, frames: SolvedFrames::Auto }
    }
}

/// One constraint's state at the end.
#[derive(Clone, Debug, PartialEq)]
pub struct Violation {
    /// The constraint.
    pub constraint: &'static str,
    /// Largest violation, in `unit`.
    pub max: f64,
    /// What counts as met.
    pub tolerance: f64,
    /// Unit of both.
    pub unit: &'static str,
}

/// How the optimisation went.
#[derive(Clone, Debug, PartialEq)]
pub struct SolveReport {
    /// Gauss–Newton steps taken (each one sparse Cholesky solve, accepted or not).
    pub iterations: usize,
    /// Wall-clock time of the whole edit, seconds.
    pub seconds: f64,
    /// Unknowns: DOFs of every frame plus spline control points.
    pub unknowns: usize,
    /// Active joints (rotation DOFs per frame / 3).
    pub active_joints: usize,
    /// Similarity term Σ (w·δ/range)² (w = 1, or [`CUT_EDGE_WEIGHT`] near a cut edge).
    pub similarity: f64,
    /// Smoothness term Σ (Δ²δ (fps · SMOOTH_SECS)² / range)².
    pub smoothness: f64,
    /// Pseudo-balance term Σ (Δcom / BALANCE_SCALE_M)².
    pub balance: f64,
    /// Every constraint group at the end.
    pub violations: Vec<Violation>,
    /// The frames solved (see [`edit_window`]); the others are the capture moved rigidly
    /// with their ground stages.
    pub solved_frames: FrameRange,
}

/// Why an edit could not be optimised.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The edit itself is malformed.
    #[error(transparent)]
    Edit(#[from] EditError),
    /// Too few frames.
    #[error("the clip has {frames} frames; momentum editing needs at least {MIN_FRAMES}")]
    TooShort {
        /// Frames in the clip.
        frames: usize,
    },
    /// Nothing to edit: no flight between ground stages.
    #[error("the stages hold no flight between two ground stages; nothing is ballistic to edit")]
    NoFlight,
    /// The edit asks the legs for more than they can give.
    #[error(
        "ground stage {stage}: the edit needs {needed_mps:.2} m/s more take-off speed over the flight before it, more \
         than {MAX_EXTRA_SPEED_MPS} m/s (the landing is unreachable)"
    )]
    Unreachable {
        /// The ground stage whose edit is unreachable (0-based among ground stages).
        stage: usize,
        /// The change of horizontal speed asked, m/s.
        needed_mps: f64,
    },
    /// A bad gravity scale.
    #[error("gravity scale {0} must be positive and finite")]
    GravityScale(f64),
    /// The momentum splines could not be set up.
    #[error(transparent)]
    Splines(#[from] SplineError),
    /// The optimisation stopped with a constraint violated.
    #[error(
        "the optimisation did not converge in {iterations} steps: '{constraint}' is left violated by {violation:.3e} \
         {unit} (tolerance {tolerance:.1e})"
    )]
    NotConverged {
        /// The worst violated constraint (relative to its tolerance).
        constraint: &'static str,
        /// Its largest violation.
        violation: f64,
        /// Its tolerance.
        tolerance: f64,
        /// Unit of both.
        unit: &'static str,
        /// Steps taken.
        iterations: usize,
    },
    /// The linear algebra failed (a singular system even with damping).
    #[error("sparse factorisation failed: {0}")]
    Factor(String),
    /// The optimised clip is unusable.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// The edit to optimise.
#[derive(Clone, Copy, Debug)]
pub struct EditSetup<'a> {
    /// The captured clip.
    pub clip: &'a Clip,
    /// Its stages (from `motion.stages`), gravity fitted.
    pub stages: &'a Stages,
    /// Its body model.
    pub model: &'a BodyModel,
    /// Ankle joints.
    pub feet: [usize; 2],
    /// Contacts of the original: (ankle joint, frames).
    pub planted: &'a [(usize, FrameRange)],
    /// One edit per ground stage.
    pub edits: &'a [GroundEdit],
}

/// Fixed data of one optimisation.
struct Problem<'a> {
    setup: EditSetup<'a>,
    n: usize,
    joints: usize,
    fps: f64,
    mass: f64,
    root: usize,
    /// Active joints, and for each joint the active indices of its strict ancestors.
    active: Vec<usize>,
    ancestors: Vec<Vec<usize>>,
    dof: usize,
    range_rot: Vec<f64>,
    range_root: DVec3,
    /// Original local rotations' mean and natural range per active joint (joint limits).
    limit: Vec<(DQuat, f64)>,
    init_rot: Vec<DQuat>,
    init_root: Vec<DVec3>,
    /// Per frame, the weight of its similarity rows (see [`CUT_EDGE_SECS`]).
    similarity_weight: Vec<f64>,
    /// (ankle, frame, target).
    pins: Vec<(usize, usize, DVec3)>,
    floor: f64,
    balance: Vec<(usize, DVec3)>,
    fit: MomentumFit,
    /// Per channel, per piece, the first column of its unknowns within G.
    g_cols: Vec<Vec<usize>>,
    g_count: usize,
    slope_per_mass: Vec<f64>,
}

/// The unknowns.
#[derive(Clone)]
struct State {
    rot: Vec<DQuat>,
    root: Vec<DVec3>,
    g: Vec<f64>,
}

/// Forward kinematics and momentum of a state.
struct Eval {
    clip: Clip,
    poses: ClipPoses,
    track: MomentumTrack,
    /// Segment centres of mass, frame-major (frames × segments), metres.
    segments: Vec<DVec3>,
}

/// Optimises `setup`'s edit: returns the edited clip and the report.
pub fn momentum_edit(setup: EditSetup<'_>, options: &SolveOptions) -> Result<(Clip, SolveReport), SolveError> {
    check_reachable(setup.stages, setup.edits)?;
    let windowed = match options.frames {
        SolvedFrames::Whole => false,
        SolvedFrames::AroundEdit => true,
        SolvedFrames::Auto => setup.clip.duration_secs() > AUTO_WINDOW_SECS,
    };
    let Some(window) = edit_window(setup.stages, setup.edits).filter(|_| windowed) else {
        return solve(setup, options, [false; 2]);
    };
    let EditSetup { clip, stages, model, feet, planted, edits } = setup;
    let shift = |r: FrameRange| {
        let (start, end) = (r.start.max(window.start), r.end.min(window.end));
        (start < end).then(|| FrameRange::new(start - window.start, end - window.start))
    };
    let mut inside = Vec::new();
    let mut window_edits = Vec::new();
    let mut ground = 0;
    for stage in &stages.stages {
        if let Some(frames) = shift(stage.frames) {
            inside.push(Stage { kind: stage.kind, frames });
            if stage.kind == StageKind::Ground {
                window_edits.extend(edits.get(ground).copied());
            }
        }
        ground += usize::from(stage.kind == StageKind::Ground);
    }
    let window_stages = Stages { frame_count: window.len(), stages: inside, ..stages.clone() };
    // A contact cut by the window is held only from a while after its start and let go a
    // while before its end, so the foot moves between the capture's path (the frames beyond
    // the cut keep the capture's own slide) and its hold over the unpinned frames in between.
    let margin = ((CUT_EDGE_SECS + RELEASE_SECS) * stages.fps).round() as usize;
    let first_held = if window.start > 0 { margin } else { 0 };
    let last_held = if window.end < clip.frame_count() { window.len().saturating_sub(margin) } else { window.len() };
    let window_planted: Vec<(usize, FrameRange)> = planted
        .iter()
        .filter_map(|&(j, r)| shift(r).map(|r| (j, FrameRange::new(r.start.max(first_held), r.end.min(last_held)))))
        .filter(|(_, r)| r.start < r.end)
        .collect();
    let window_clip = clip.slice(window.start, window.end);
    let window_setup = EditSetup {
        clip: &window_clip,
        stages: &window_stages,
        model,
        feet,
        planted: &window_planted,
        edits: &window_edits,
    };
    let (solved, mut report) = solve(window_setup, options, [window.start > 0, window.end < clip.frame_count()])?;
    // Outside the window every ground stage moves as its neighbours do: the naive edit's
    // rigid move of the capture is the edit there.
    let rigid = naive_edit(clip, stages, model, edits)?;
    let j = clip.joint_count();
    let (mut rotations, mut translations) = (rigid.rotations().to_vec(), rigid.translations().to_vec());
    rotations[window.start * j..window.end * j].copy_from_slice(solved.rotations());
    translations[window.start * j..window.end * j].copy_from_slice(solved.translations());
    let spliced = Clip::new(clip.skeleton().clone(), clip.fps(), rotations, translations, clip.import_scale)?;
    report.solved_frames = window;
    Ok((spliced, report))
}

/// Refuses an edit whose ground stages move apart faster over a flight than
/// [`MAX_EXTRA_SPEED_MPS`] allows (numbered as the edits are, the first ground stage 0).
fn check_reachable(stages: &Stages, edits: &[GroundEdit]) -> Result<(), SolveError> {
    let grounds = stages.ground_frames();
    for (i, w) in grounds.windows(2).enumerate() {
        if let (Some(a), Some(b)) = (edits.get(i), edits.get(i + 1)) {
            let secs = (w[1].start + 1 - w[0].end) as f64 / stages.fps;
            let shift = b.offset_m - a.offset_m;
            let needed_mps = DVec3::new(shift.x, 0.0, shift.z).length() / secs;
            if needed_mps > MAX_EXTRA_SPEED_MPS {
                return Err(SolveError::Unreachable { stage: i + 1, needed_mps });
            }
        }
    }
    Ok(())
}

/// The frames an edit has to solve, when fewer than the whole clip: from the middle of the
/// ground stage before the first flight whose two ground stages do not move together to
/// the middle of the ground stage after the last such flight (the clip's start or end when
/// that stage is its first or last). Two stages move together when they have the same
/// offset and no turn (each stage turns about its own centre of mass, so two equal turns
/// are two different moves). Outside, the capture moved rigidly with its stages is already
/// the edit: a hop of CMU 01_01's eleven is solved alone, not the 23 s around it. None for
/// the whole clip.
pub fn edit_window(stages: &Stages, edits: &[GroundEdit]) -> Option<FrameRange> {
    let grounds = stages.ground_frames();
    let edit = |i: usize| edits.get(i).copied().unwrap_or_default();
    let together = |i: usize| edit(i) == edit(i + 1) && edit(i).turn_rad == 0.0;
    let changes: Vec<usize> = (0..grounds.len().saturating_sub(1)).filter(|&i| !together(i)).collect();
    let (&first, &last) = (changes.first()?, changes.last()?);
    let middle = |r: FrameRange| r.start + r.len() / 2;
    let start = if first == 0 { 0 } else { middle(grounds[first]) };
    let end = if last + 2 == grounds.len() { stages.frame_count } else { middle(grounds[last + 1]) };
    (start > 0 || end < stages.frame_count).then(|| FrameRange::new(start, end))
}

/// The optimisation of `setup`'s whole clip; `cut` says which of its ends (start, end) is
/// a cut through a longer clip, whose frames are held near the initial guess.
fn solve(setup: EditSetup<'_>, options: &SolveOptions, cut: [bool; 2]) -> Result<(Clip, SolveReport), SolveError> {
    let started = Instant::now();
    let (problem, mut state) = Problem::new(setup, options, cut)?;
    let mut penalty: Vec<f64> = GROUPS.iter().map(|g| g.penalty).collect();
    let mut eval = problem.eval(&state)?;
    let constraint_count = problem.constraints(&state, &eval, None).0.len();
    let mut multipliers = vec![0.0; constraint_count];
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut normal: Option<NormalEquations> = None;
    let mut worst = problem.worst(&state, &eval);
    while iterations < options.max_iterations && worst.1 > 1.0 {
        // Inner: Levenberg–Marquardt on the augmented Lagrangian until it stalls.
        let mut merit = problem.merit(&state, &eval, &multipliers, &penalty);
        for _ in 0..STEPS_PER_UPDATE {
            let rows = problem.system(&state, &eval, &multipliers, &penalty);
            let refilled = normal.as_mut().is_some_and(|n| n.refill(&rows));
            let normal = match normal.as_mut() {
                Some(n) if refilled => n,
                _ => normal.insert(NormalEquations::new(&rows, &problem.time_order())?),
            };
            let mut accepted = false;
            while iterations < options.max_iterations {
                iterations += 1;
                let step = normal.damped_step(lambda)?;
                let trial = problem.apply(&state, &eval, &step);
                let trial_eval = problem.eval(&trial)?;
                let trial_merit = problem.merit(&trial, &trial_eval, &multipliers, &penalty);
                if trial_merit < merit {
                    let gain = (merit - trial_merit) / merit.max(f64::MIN_POSITIVE);
                    (state, eval, merit) = (trial, trial_eval, trial_merit);
                    lambda = (lambda / 3.0).max(1e-9);
                    accepted = gain > 1e-4;
                    break;
                }
                lambda *= 10.0;
                if lambda > 1e8 {
                    break;
                }
            }
            if !accepted {
                break;
            }
        }
        // Outer: first-order multiplier update; raise the penalty of groups that lag.
        let (values, groups) = problem.constraints(&state, &eval, None);
        for ((y, c), g) in multipliers.iter_mut().zip(&values).zip(&groups) {
            if !GROUPS[*g].hard {
                continue;
            }
            *y += penalty[*g] * c;
            if one_sided(*g) {
                *y = y.max(0.0);
            }
        }
        let now = problem.worst(&state, &eval);
        for (g, p) in penalty.iter_mut().enumerate() {
            let lagging = problem.group_violation(&values, &groups, g) > GROUPS[g].tolerance && now.1 > 0.25 * worst.1;
            if lagging && GROUPS[g].hard && *p < MAX_PENALTY_GROWTH * GROUPS[g].penalty {
                *p *= 10.0;
            }
        }
        worst = now;
        lambda = lambda.max(1e-6);
    }
    let violations: Vec<Violation> = {
        let (values, groups) = problem.constraints(&state, &eval, None);
        GROUPS
            .iter()
            .enumerate()
            .map(|(g, group)| Violation {
                constraint: group.name,
                max: problem.group_violation(&values, &groups, g),
                tolerance: group.tolerance,
                unit: group.unit,
            })
            .collect()
    };
    if worst.1 > 1.0 {
        let v = &violations[worst.0];
        return Err(SolveError::NotConverged {
            constraint: v.constraint,
            violation: v.max,
            tolerance: v.tolerance,
            unit: v.unit,
            iterations,
        });
    }
    let [similarity, smoothness, balance] = problem.objective_terms(&state, &eval);
    let report = SolveReport {
        iterations,
        seconds: started.elapsed().as_secs_f64(),
        unknowns: problem.unknowns(),
        active_joints: problem.active.len(),
        similarity,
        smoothness,
        balance,
        violations,
        solved_frames: FrameRange::new(0, problem.n),
    };
    Ok((eval.clip, report))
}

/// Rotation vector of a unit quaternion (shortest way), radians.
fn rotation_vector(q: DQuat) -> DVec3 {
    let q = if q.w < 0.0 { -q } else { q };
    let (axis, angle) = q.to_axis_angle();
    if angle.is_finite() { axis * angle } else { DVec3::ZERO }
}

/// The local rotation of joint `j` at every frame, f64.
fn rotations_of(clip: &Clip, j: usize) -> Vec<DQuat> {
    let joints = clip.joint_count();
    (0..clip.frame_count()).map(|f| clip.rotations()[f * joints + j].as_dquat()).collect()
}

/// Sign-aligned normalised mean of `qs`, and the largest angle of any from it.
fn mean_and_spread(qs: &[DQuat]) -> (DQuat, f64) {
    let first = qs.first().copied().unwrap_or(DQuat::IDENTITY);
    let sum: DQuat =
        qs.iter().fold(DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), |acc, q| acc + if q.dot(first) < 0.0 { -*q } else { *q });
    let mean = if sum.length() > 1e-9 { sum.normalize() } else { first };
    let spread = qs.iter().map(|q| rotation_vector(*q * mean.inverse()).length()).fold(0.0, f64::max);
    (mean, spread)
}

impl<'a> Problem<'a> {
    fn new(setup: EditSetup<'a>, options: &SolveOptions, cut: [bool; 2]) -> Result<(Problem<'a>, State), SolveError> {
        let EditSetup { clip, stages, model, feet, planted, edits } = setup;
        let n = clip.frame_count();
        if n < MIN_FRAMES {
            return Err(SolveError::TooShort { frames: n });
        }
        if !(options.gravity_scale.is_finite() && options.gravity_scale > 0.0) {
            return Err(SolveError::GravityScale(options.gravity_scale));
        }
        let interior_flight = stages.stages.windows(3).any(|w| {
            w[0].kind == StageKind::Ground && w[1].kind == StageKind::Flight && w[2].kind == StageKind::Ground
        });
        if !interior_flight {
            return Err(SolveError::NoFlight);
        }
        let fps = clip.fps();
        let grounds = stages.ground_frames();
        let guess = naive_edit(clip, stages, model, edits)?;
        let skeleton = clip.skeleton();
        let joints = clip.joint_count();
        let parents: Vec<Option<usize>> = skeleton.joints().iter().map(|j| j.parent).collect();
        let root = parents.iter().position(Option::is_none).unwrap_or(0);
        // Mass carried below each joint, and the feet's ancestors.
        let mut below = vec![0.0; joints];
        for s in &model.segments {
            for &(j, w) in &s.com_weights {
                let mut a = parents[j];
                while let Some(p) = a {
                    below[p] += s.mass_kg * f64::from(w);
                    a = parents[p];
                }
            }
        }
        let mut holds_foot = vec![false; joints];
        for &foot in &feet {
            let mut a = parents[foot];
            while let Some(p) = a {
                holds_foot[p] = true;
                a = parents[p];
            }
        }
        let mass = model.total_mass_kg;
        let active: Vec<usize> =
            (0..joints).filter(|&j| holds_foot[j] || below[j] >= MIN_SUBTREE_MASS * mass).collect();
        let mut index_of = vec![usize::MAX; joints];
        for (k, &j) in active.iter().enumerate() {
            index_of[j] = k;
        }
        let ancestors: Vec<Vec<usize>> = (0..joints)
            .map(|j| {
                let mut out = Vec::new();
                let mut a = parents[j];
                while let Some(p) = a {
                    if index_of[p] != usize::MAX {
                        out.push(index_of[p]);
                    }
                    a = parents[p];
                }
                out
            })
            .collect();
        let limit: Vec<(DQuat, f64)> = active.iter().map(|&j| mean_and_spread(&rotations_of(clip, j))).collect();
        let range_rot: Vec<f64> = limit.iter().map(|(_, spread)| spread.max(0.2)).collect();
        let root_path: Vec<DVec3> = (0..n).map(|f| clip.translations()[f * joints + root].as_dvec3()).collect();
        let lo = root_path.iter().fold(DVec3::INFINITY, |a, b| a.min(*b));
        let hi = root_path.iter().fold(DVec3::NEG_INFINITY, |a, b| a.max(*b));
        let range_root = (hi - lo).max(DVec3::splat(0.1));
        let poses = forward_kinematics(&guess);
        let original_poses = forward_kinematics(clip);
        let floor = floor_height(&original_poses, &feet);
        let at = |f: usize, j: usize| poses.position(f, j).as_dvec3();
        // Where the edit asks a foot to be, lifted onto the floor where the capture has it
        // poking through (the floor is a percentile of the ankle heights).
        let asked = |f: usize, j: usize| {
            let p = at(f, j);
            DVec3::new(p.x, p.y.max(floor + FLOOR_MARGIN_M), p.z)
        };
        let mut pins = Vec::new();
        let ground_of = |f: usize| grounds.iter().any(|r| r.contains(f));
        // A foot's toe tip and the height it rests at in the original, once per foot.
        let toe_of = |j: usize| {
            let toe = limb_tip(skeleton, j);
            (toe, floor_height(&original_poses, &[toe]))
        };
        let toes: Vec<(usize, (usize, f64))> = feet.iter().map(|&j| (j, toe_of(j))).collect();
        for (j, r) in held_from_landings(planted, &grounds, fps) {
            // Frames of the contact in a ground stage, and after it, within that stage, the
            // frames over which the foot is handed back to the clip's (the foot lock's blend).
            let room =
                grounds.iter().find(|g| g.contains(r.end.saturating_sub(1))).map_or(0, |g| g.end.saturating_sub(r.end));
            let release = ((RELEASE_SECS * fps).round() as usize).min(room).max(1);
            let frames: Vec<usize> = (r.start..(r.end + release - 1).min(n)).filter(|&f| ground_of(f)).collect();
            if !frames.is_empty() {
                // The foot is held as the foot lock holds it: its toe tip where it is at the
                // contact's lowest frame, the whole foot (ankle and toe tip) moved by the
                // toe's horizontal drift, so the heel still rises and the foot still rolls
                // onto its toes at a take-off. (The ankle held still instead kept the heel
                // down through the roll and put the toes 5–6 cm under the floor on CMU 16_01.)
                let (toe, toe_floor) = toes.iter().find(|t| t.0 == j).map_or_else(|| toe_of(j), |t| t.1);
                let plant = Plants::along(|f| at(f, toe), n, &[r], release);
                for &f in &frames {
                    let shift = plant.shift(f, at(f, toe));
                    pins.push((j, f, asked(f, j) + shift));
                    if toe != j {
                        let held = at(f, toe) + shift;
                        pins.push((toe, f, held.with_y(held.y.max(toe_floor + FLOOR_MARGIN_M))));
                    }
                }
            }
        }
        for r in &grounds {
            for &j in &feet {
                if !pins.iter().any(|&(pj, pf, _)| pj == j && pf == r.start) {
                    pins.push((j, r.start, asked(r.start, j)));
                }
            }
        }
        let track = momentum_of_poses(&poses, fps, model);
        let mut balance = Vec::new();
        for (i, r) in grounds.iter().enumerate() {
            if i == 0 {
                balance.push(r.start);
            }
            if i + 1 == grounds.len() {
                balance.push(r.end - 1);
            }
            if i > 0 && i + 1 < grounds.len() {
                balance.push(r.start + r.len() / 2);
            }
        }
        let balance: Vec<(usize, DVec3)> = balance.into_iter().map(|f| (f, track.com_m[f])).collect();
        let scaled = Stages { gravity_mps2: stages.gravity_mps2 * options.gravity_scale, ..stages.clone() };
        let linear: Vec<DVec3> = track.com_velocity_mps.iter().map(|v| *v * mass).collect();
        let fit = fit_momentum(&scaled, &linear, &track.momentum, mass, options.knot_spacing_secs)?;
        let mut g_cols = Vec::new();
        let mut g = Vec::new();
        let mut slope_per_mass = Vec::new();
        for ch in &fit.channels {
            let mut cols = Vec::new();
            for piece in &ch.pieces {
                cols.push(g.len());
                match piece {
                    Piece::Line { value, slope, .. } => {
                        g.push(value / mass);
                        slope_per_mass.push(slope / mass);
                    }
                    Piece::Spline { spline, .. } => g.extend(spline.control.iter().map(|c| c / mass)),
                }
            }
            g_cols.push(cols);
        }
        let init_rot: Vec<DQuat> = guess.rotations().iter().map(|q| q.as_dquat()).collect();
        let init_root: Vec<DVec3> = (0..n).map(|f| guess.translations()[f * joints + root].as_dvec3()).collect();
        let state = State { rot: init_rot.clone(), root: init_root.clone(), g };
        let edge = (CUT_EDGE_SECS * fps).round() as usize;
        let similarity_weight = (0..n)
            .map(|f| if (cut[0] && f < edge) || (cut[1] && f + edge >= n) { CUT_EDGE_WEIGHT } else { 1.0 })
            .collect();
        let g_count = state.g.len();
        let problem = Problem {
            setup,
            n,
            joints,
            fps,
            mass,
            root,
            dof: 3 + 3 * active.len(),
            active,
            ancestors,
            range_rot,
            range_root,
            limit,
            init_rot,
            init_root,
            similarity_weight,
            pins,
            floor,
            balance,
            fit,
            g_cols,
            g_count,
            slope_per_mass,
        };
        Ok((problem, state))
    }

    fn unknowns(&self) -> usize {
        self.n * self.dof + self.g_count
    }

    fn col(&self, f: usize, k: usize) -> usize {
        f * self.dof + k
    }

    fn g_col(&self, i: usize) -> usize {
        self.n * self.dof + i
    }

    /// The unknowns in time order (new position → unknown): each frame's DOFs, and every
    /// spline control point or flight-line value just after the last frame it acts on. The
    /// rows couple only neighbouring frames and the G entries over them, so the Cholesky
    /// factor keeps to a band in this order. With G last (every frame couples to it) or by
    /// minimum degree it held twice the entries (6.6 M on CMU 16_01); with G in the middle
    /// of its frames, its elimination joined all of them (36 M).
    fn time_order(&self) -> Vec<usize> {
        let mut at: Vec<(f64, usize)> = (0..self.n * self.dof).map(|c| ((c / self.dof) as f64, c)).collect();
        for (c, ch) in self.fit.channels.iter().enumerate() {
            for (i, piece) in ch.pieces.iter().enumerate() {
                let base = self.g_cols[c][i];
                match piece {
                    Piece::Line { end_secs, .. } => at.push((end_secs * self.fps + 0.5, self.g_col(base))),
                    Piece::Spline { spline, .. } => {
                        for k in 0..spline.control.len() {
                            let end = spline.knots[(k + 4).min(spline.knots.len() - 1)];
                            at.push((end * self.fps + 0.5, self.g_col(base + k)));
                        }
                    }
                }
            }
        }
        at.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        at.into_iter().map(|(_, c)| c).collect()
    }

    fn eval(&self, state: &State) -> Result<Eval, SolveError> {
        let clip = self.setup.clip;
        let mut translations = clip.translations().to_vec();
        for f in 0..self.n {
            translations[f * self.joints + self.root] = state.root[f].as_vec3();
        }
        let rotations: Vec<Quat> = state.rot.iter().map(|q| q.as_quat()).collect();
        let clip = Clip::new(clip.skeleton().clone(), self.fps, rotations, translations, clip.import_scale)?;
        let poses = forward_kinematics(&clip);
        let track = momentum_of_poses(&poses, self.fps, self.setup.model);
        let model = self.setup.model;
        let segments = (0..self.n)
            .flat_map(|f| {
                let frame = poses.frame(f);
                model.segments.iter().map(move |s| {
                    s.com_weights.iter().map(|&(j, w)| f64::from(w) * frame[j].translation.as_dvec3()).sum::<DVec3>()
                })
            })
            .collect();
        Ok(Eval { clip, poses, track, segments })
    }

    /// Between frames `f` and `f + 1`, each segment's mid-point arm r̄_s from the centre of
    /// mass and its velocity ū_s relative to the centre's.
    fn half_frame_arms(&self, eval: &Eval, f: usize) -> (Vec<DVec3>, Vec<DVec3>) {
        let count = self.setup.model.segments.len();
        let (now, next) =
            (&eval.segments[f * count..(f + 1) * count], &eval.segments[(f + 1) * count..(f + 2) * count]);
        let (c0, c1) = (eval.track.com_m[f], eval.track.com_m[f + 1]);
        let (centre, moved) = (0.5 * (c0 + c1), c1 - c0);
        now.iter().zip(next).map(|(a, b)| (0.5 * (*a + *b) - centre, (*b - *a - moved) * self.fps)).unzip()
    }

    /// Linear momentum (the COM's velocity) and angular momentum per mass between frames
    /// `f` and `f + 1` (channels p.x, p.y, p.z, L.x, L.y, L.z), with `arms` from
    /// [`Self::half_frame_arms`].
    fn half_frame_momentum(&self, eval: &Eval, f: usize, (r, u): &(Vec<DVec3>, Vec<DVec3>)) -> [f64; 6] {
        let mut l = DVec3::ZERO;
        for (s, seg) in self.setup.model.segments.iter().enumerate() {
            l += seg.mass_kg / self.mass * r[s].cross(u[s]);
        }
        let v = (eval.track.com_m[f + 1] - eval.track.com_m[f]) * self.fps;
        [v.x, v.y, v.z, l.x, l.y, l.z]
    }

    /// The model momentum of channel `c` at time `t` (seconds, per mass) and its G entries.
    fn model_row(&self, state: &State, c: usize, t: f64) -> (f64, Vec<(usize, f64)>) {
        let ch = &self.fit.channels[c];
        let Some(i) = ch.piece_at(t) else { return (0.0, Vec::new()) };
        let base = self.g_cols[c][i];
        match &ch.pieces[i] {
            Piece::Line { start_secs, .. } => {
                let slope = self.line_slope(c, i);
                (state.g[base] + slope * (t - start_secs), vec![(base, 1.0)])
            }
            Piece::Spline { spline, .. } => {
                let b = basis(&spline.knots, t);
                let v = b.iter().enumerate().map(|(k, w)| w * state.g[base + k]).sum();
                (v, b.iter().enumerate().filter(|(_, w)| **w != 0.0).map(|(k, w)| (base + k, *w)).collect())
            }
        }
    }

    /// Slope per mass of the line piece `i` of channel `c`.
    fn line_slope(&self, c: usize, i: usize) -> f64 {
        let lines_before = self.fit.channels[..c]
            .iter()
            .map(|ch| ch.pieces.iter().filter(|p| matches!(p, Piece::Line { .. })).count())
            .sum::<usize>()
            + self.fit.channels[c].pieces[..i].iter().filter(|p| matches!(p, Piece::Line { .. })).count();
        self.slope_per_mass[lines_before]
    }

    /// The C1 rows between ground splines and flight lines: (constant, [(g index, coefficient)]),
    /// the constraint being constant + Σ coefficient · g = 0.
    fn join_rows(&self) -> Vec<(f64, Vec<(usize, f64)>)> {
        let mut rows = Vec::new();
        for (c, ch) in self.fit.channels.iter().enumerate() {
            for (i, piece) in ch.pieces.iter().enumerate() {
                let Piece::Spline { start_secs: a, end_secs: b, spline } = piece else { continue };
                let base = self.g_cols[c][i];
                let m = spline.control.len();
                let k = &spline.knots;
                if let Some(Piece::Line { start_secs, end_secs, .. }) = i.checked_sub(1).map(|p| &ch.pieces[p]) {
                    let (line, slope) = (self.g_cols[c][i - 1], self.line_slope(c, i - 1));
                    rows.push((-slope * (end_secs - start_secs), vec![(base, 1.0), (line, -1.0)]));
                    // The vertical linear momentum at a landing: C0 only (fit_momentum).
                    if c != 1 {
                        rows.push((-slope * (k[4] - a) / 3.0, vec![(base + 1, 1.0), (base, -1.0)]));
                    }
                }
                if let Some(Piece::Line { .. }) = ch.pieces.get(i + 1) {
                    let (line, slope) = (self.g_cols[c][i + 1], self.line_slope(c, i + 1));
                    rows.push((0.0, vec![(base + m - 1, 1.0), (line, -1.0)]));
                    rows.push((-slope * (b - k[m - 1]) / 3.0, vec![(base + m - 1, 1.0), (base + m - 2, -1.0)]));
                }
            }
        }
        rows
    }

    /// Every constraint value in a stable order, with its group; with `jacobian` (the frames'
    /// geometry of `eval` and where to put the rows), also each row's entries (column, value).
    // `frames` is empty when no Jacobian is asked, so the loops index it by frame number.
    #[allow(clippy::type_complexity, clippy::needless_range_loop)]
    fn constraints(
        &self,
        state: &State,
        eval: &Eval,
        jacobian: Option<(&[FrameGeometry], &mut Vec<Vec<(usize, f64)>>)>,
    ) -> (Vec<f64>, Vec<usize>) {
        let mut values = Vec::new();
        let mut groups = Vec::new();
        let (frames, mut jacobian) = match jacobian {
            Some((frames, rows)) => (frames, Some(rows)),
            None => (&[][..], None),
        };
        let mut push = |v: f64, g: usize, row: Vec<(usize, f64)>, jac: &mut Option<&mut Vec<Vec<(usize, f64)>>>| {
            values.push(v);
            groups.push(g);
            if let Some(j) = jac.as_mut() {
                j.push(row);
            }
        };
        let want = jacobian.is_some();
        for &(j, f, target) in &self.pins {
            let d = eval.poses.position(f, j).as_dvec3() - target;
            for i in 0..3 {
                let row = if want { self.point_row(&frames[f], f, j, i, 1.0) } else { Vec::new() };
                push(d[i], FEET, row, &mut jacobian);
            }
        }
        for f in 0..self.n {
            for &j in &self.setup.feet {
                let below = self.floor + FLOOR_MARGIN_M - f64::from(eval.poses.position(f, j).y);
                let row = if want { self.point_row(&frames[f], f, j, 1, -1.0) } else { Vec::new() };
                push(below, FLOOR, row, &mut jacobian);
            }
        }
        for f in 0..self.n - 1 {
            let arms = self.half_frame_arms(eval, f);
            let measured = self.half_frame_momentum(eval, f, &arms);
            let mut angular = if want { self.angular_rows(frames, f, &arms) } else { Default::default() };
            for (c, measured) in measured.into_iter().enumerate() {
                let (model, g_entries) = self.model_row(state, c, (f as f64 + 0.5) / self.fps);
                let mut row = Vec::new();
                if want {
                    row = if c < 3 { self.linear_row(frames, f, c) } else { std::mem::take(&mut angular[c - 3]) };
                    row.extend(g_entries.iter().map(|&(i, w)| (self.g_col(i), -w)));
                }
                push(measured - model, if c < 3 { LINEAR } else { ANGULAR }, row, &mut jacobian);
            }
        }
        for f in 0..self.n {
            for (k, &j) in self.active.iter().enumerate() {
                if j == self.root {
                    continue;
                }
                let (mean, spread) = self.limit[k];
                let v = rotation_vector(state.rot[f * self.joints + j] * mean.inverse());
                let excess = v.length() - spread - LIMIT_MARGIN_RAD;
                let mut row = Vec::new();
                if want {
                    // Left increments δ = W_pᵀω change |v| by v̂·δ = (W_p v̂)·ω.
                    let d = frames[f].parent_rotation[k] * v.normalize_or_zero();
                    row = (0..3).map(|a| (self.col(f, 3 + 3 * k + a), d[a])).collect();
                }
                push(excess, LIMITS, row, &mut jacobian);
            }
        }
        for (constant, entries) in self.join_rows() {
            let v = constant + entries.iter().map(|&(i, w)| w * state.g[i]).sum::<f64>();
            let row = if want { entries.iter().map(|&(i, w)| (self.g_col(i), w)).collect() } else { Vec::new() };
            push(v, JOIN, row, &mut jacobian);
        }
        (values, groups)
    }

    /// Entries of component `i` of joint `j`'s world position at frame `f`, times `scale`.
    fn point_row(&self, geo: &FrameGeometry, f: usize, j: usize, i: usize, scale: f64) -> Vec<(usize, f64)> {
        let mut row = vec![(self.col(f, i), scale)];
        let p = geo.positions[j];
        for &k in &self.ancestors[j] {
            let arm = p - geo.positions[self.active[k]];
            for a in 0..3 {
                row.push((self.col(f, 3 + 3 * k + a), scale * axis(a).cross(arm)[i]));
            }
        }
        row
    }

    /// Entries of COM velocity component `i` between frames `f` and `f + 1`.
    fn linear_row(&self, frames: &[FrameGeometry], f: usize, i: usize) -> Vec<(usize, f64)> {
        let mut row = Vec::new();
        for (h, s) in [(f, -self.fps), (f + 1, self.fps)] {
            row.push((self.col(h, i), s));
            for (k, d) in frames[h].com_arm.iter().enumerate() {
                for a in 0..3 {
                    row.push((self.col(h, 3 + 3 * k + a), s * axis(a).cross(*d)[i]));
                }
            }
        }
        row
    }

    /// Entries of the three components of (angular momentum / mass) between frames `f` and
    /// `f + 1`, with `arms` (r̄_s, ū_s) from [`Self::half_frame_arms`]:
    /// δL = Σ m_s (δr̄_s × ū_s + r̄_s × δū_s), δr̄ = ½(δx(f) + δx(f+1)), δū = fps (δx(f+1) − δx(f));
    /// the centre's own terms cancel (Σ m_s ū_s = Σ m_s r̄_s = 0), so root translations do
    /// not enter. All three at once: each entry's vector gives all three.
    fn angular_rows(
        &self,
        frames: &[FrameGeometry],
        f: usize,
        (r, u): &(Vec<DVec3>, Vec<DVec3>),
    ) -> [Vec<(usize, f64)>; 3] {
        let masses = &self.setup.model.segments;
        let k_count = self.active.len();
        let mut rows: [Vec<(usize, f64)>; 3] = std::array::from_fn(|_| Vec::with_capacity(6 * k_count));
        for (h, sign) in [(f, -1.0), (f + 1, 1.0)] {
            let geo = &frames[h];
            for k in 0..k_count {
                for a in 0..3 {
                    let e = axis(a);
                    let mut d = DVec3::ZERO;
                    for (s, seg) in masses.iter().enumerate() {
                        let moved = e.cross(geo.seg_arm[s * k_count + k]);
                        d += seg.mass_kg / self.mass * (0.5 * moved.cross(u[s]) + sign * self.fps * r[s].cross(moved));
                    }
                    for (i, row) in rows.iter_mut().enumerate() {
                        row.push((self.col(h, 3 + 3 * k + a), d[i]));
                    }
                }
            }
        }
        rows
    }

    /// Objective rows: similarity, smoothness, then balance, (value, entries); the entries
    /// only with `geometry` (the frames' geometry of `eval`).
    // `frames` is empty when no Jacobian is asked, so the loop indexes it by frame number.
    #[allow(clippy::needless_range_loop)]
    fn objective_rows(
        &self,
        state: &State,
        eval: &Eval,
        geometry: Option<&[FrameGeometry]>,
    ) -> Vec<(f64, Vec<(usize, f64)>)> {
        let mut rows = Vec::with_capacity((2 * self.n - 2) * self.dof + 3 * self.balance.len());
        let want = geometry.is_some();
        let frames = geometry.unwrap_or_default();
        for f in 0..self.n {
            let d = state.root[f] - self.init_root[f];
            for i in 0..3 {
                rows.push((d[i] / self.range_root[i], vec![(self.col(f, i), 1.0 / self.range_root[i])]));
            }
            for (k, &j) in self.active.iter().enumerate() {
                let idx = f * self.joints + j;
                let delta = rotation_vector(state.rot[idx] * self.init_rot[idx].inverse()) / self.range_rot[k];
                for i in 0..3 {
                    let entries = if want {
                        let wp = frames[f].parent_rotation[k];
                        (0..3).map(|a| (self.col(f, 3 + 3 * k + a), wp.col(i)[a] / self.range_rot[k])).collect()
                    } else {
                        Vec::new()
                    };
                    rows.push((delta[i], entries));
                }
            }
        }
        // Smoothness: the second difference of every DOF's displacement, so that a feature
        // shorter than SMOOTH_SECS costs more as acceleration than as distance.
        let scale = (self.fps * SMOOTH_SECS).powi(2);
        for f in 1..self.n - 1 {
            for i in 0..self.dof {
                let [prev, now, next] = [f - 1, f, f + 1].map(|h| &rows[h * self.dof + i]);
                let value = scale * (prev.0 - 2.0 * now.0 + next.0);
                let entries = [(prev, scale), (now, -2.0 * scale), (next, scale)]
                    .iter()
                    .flat_map(|(row, w)| row.1.iter().map(move |&(c, v)| (c, w * v)))
                    .collect();
                rows.push((value, entries));
            }
        }
        // Near a cut edge the similarity rows weigh more (after the smoothness rows, which
        // are made from the unweighted displacements).
        for (f, &w) in self.similarity_weight.iter().enumerate().filter(|(_, w)| **w != 1.0) {
            for (value, entries) in &mut rows[f * self.dof..(f + 1) * self.dof] {
                *value *= w;
                entries.iter_mut().for_each(|(_, v)| *v *= w);
            }
        }
        for &(f, target) in &self.balance {
            let d = (eval.track.com_m[f] - target) / BALANCE_SCALE_M;
            for i in 0..3 {
                let mut entries = Vec::new();
                if want {
                    entries.push((self.col(f, i), 1.0 / BALANCE_SCALE_M));
                    for (k, arm) in frames[f].com_arm.iter().enumerate() {
                        for a in 0..3 {
                            entries.push((self.col(f, 3 + 3 * k + a), axis(a).cross(*arm)[i] / BALANCE_SCALE_M));
                        }
                    }
                }
                rows.push((d[i], entries));
            }
        }
        rows
    }

    /// The objective's terms: similarity, smoothness and balance.
    fn objective_terms(&self, state: &State, eval: &Eval) -> [f64; 3] {
        let rows = self.objective_rows(state, eval, None);
        let (similar, smooth) = (self.n * self.dof, (self.n - 2) * self.dof);
        let sq = |r: &[(f64, Vec<(usize, f64)>)]| r.iter().map(|(v, _)| v * v).sum::<f64>();
        [sq(&rows[..similar]), sq(&rows[similar..similar + smooth]), sq(&rows[similar + smooth..])]
    }

    /// ½‖objective‖² + Σ_g μ_g/2 ‖c + y/μ_g‖² (inequalities: only the part above zero).
    fn merit(&self, state: &State, eval: &Eval, multipliers: &[f64], penalty: &[f64]) -> f64 {
        let terms: f64 = self.objective_terms(state, eval).iter().sum();
        let (values, groups) = self.constraints(state, eval, None);
        let c: f64 = values
            .iter()
            .zip(&groups)
            .zip(multipliers)
            .map(|((v, g), y)| penalty[*g] * shifted(*v, *y, penalty[*g], *g).powi(2))
            .sum();
        0.5 * (terms + c)
    }

    /// Residuals and Jacobian triplets of the least-squares subproblem.
    fn system(
        &self,
        state: &State,
        eval: &Eval,
        multipliers: &[f64],
        penalty: &[f64],
    ) -> Vec<(f64, Vec<(usize, f64)>)> {
        // The frames' geometry, shared by the objective's and the constraints' Jacobians.
        let frames = FrameGeometry::all(self, eval);
        let mut rows = self.objective_rows(state, eval, Some(&frames));
        let mut constraint_rows = Vec::new();
        let (values, groups) = self.constraints(state, eval, Some((&frames, &mut constraint_rows)));
        for (((v, g), y), entries) in values.iter().zip(&groups).zip(multipliers).zip(constraint_rows) {
            let shift = shifted(*v, *y, penalty[*g], *g);
            // An inactive inequality keeps its entries as zeros: JᵀJ keeps its pattern.
            let s = if one_sided(*g) && shift == 0.0 { 0.0 } else { penalty[*g].sqrt() };
            rows.push((penalty[*g].sqrt() * shift, entries.into_iter().map(|(c, w)| (c, s * w)).collect()));
        }
        rows
    }

    /// Largest violation of group `g` among `values`.
    fn group_violation(&self, values: &[f64], groups: &[usize], g: usize) -> f64 {
        let violation = |v: f64| if one_sided(g) { v.max(0.0) } else { v.abs() };
        values.iter().zip(groups).filter(|(_, gg)| **gg == g).map(|(v, _)| violation(*v)).fold(0.0, f64::max)
    }

    /// The hard group furthest beyond its tolerance, and by what ratio.
    fn worst(&self, state: &State, eval: &Eval) -> (usize, f64) {
        let (values, groups) = self.constraints(state, eval, None);
        (0..GROUPS.len())
            .filter(|g| GROUPS[*g].hard)
            .map(|g| (g, self.group_violation(&values, &groups, g) / GROUPS[g].tolerance))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
    }

    /// The state moved by a solved step.
    fn apply(&self, state: &State, eval: &Eval, step: &[f64]) -> State {
        let mut next = state.clone();
        for f in 0..self.n {
            let base = f * self.dof;
            next.root[f] += DVec3::new(step[base], step[base + 1], step[base + 2]);
            let frame = eval.poses.frame(f);
            for (k, &j) in self.active.iter().enumerate() {
                let o = base + 3 + 3 * k;
                let w = DVec3::new(step[o], step[o + 1], step[o + 2]);
                let wp = self.setup.clip.skeleton().joints()[j]
                    .parent
                    .map_or(DQuat::IDENTITY, |p| frame[p].rotation.as_dquat().normalize());
                let idx = f * self.joints + j;
                next.rot[idx] = (wp.inverse() * DQuat::from_scaled_axis(w) * wp * state.rot[idx]).normalize();
            }
        }
        for (i, g) in next.g.iter_mut().enumerate() {
            *g += step[self.g_col(i)];
        }
        next
    }
}

/// The augmented-Lagrangian residual of a constraint with value `v`, multiplier `y` and
/// penalty `mu`, divided by √mu: v + y/mu, or for an inequality its part above zero.
fn shifted(v: f64, y: f64, mu: f64, group: usize) -> f64 {
    let s = v + y / mu;
    if one_sided(group) { s.max(0.0) } else { s }
}

/// e_x, e_y or e_z.
fn axis(a: usize) -> DVec3 {
    [DVec3::X, DVec3::Y, DVec3::Z][a]
}

/// Per-frame quantities the Jacobian rows share.
struct FrameGeometry {
    positions: Vec<DVec3>,
    /// World rotation of each active joint's parent (identity for the root).
    parent_rotation: Vec<DMat3>,
    /// Per (segment, active joint): Σ w (p_j − p_a) over the segment's joints below a, so
    /// that δx_s = ω_a × seg_arm.
    seg_arm: Vec<DVec3>,
    /// Per active joint: the body COM's arm, Σ m_s seg_arm / M.
    com_arm: Vec<DVec3>,
}

impl FrameGeometry {
    fn all(p: &Problem<'_>, eval: &Eval) -> Vec<FrameGeometry> {
        let segments = &p.setup.model.segments;
        let k_count = p.active.len();
        let skeleton = p.setup.clip.skeleton();
        (0..p.n)
            .map(|f| {
                let frame = eval.poses.frame(f);
                let positions: Vec<DVec3> = frame.iter().map(|t| t.translation.as_dvec3()).collect();
                let parent_rotation = p
                    .active
                    .iter()
                    .map(|&j| {
                        skeleton.joints()[j]
                            .parent
                            .map_or(DMat3::IDENTITY, |q| DMat3::from_quat(frame[q].rotation.as_dquat().normalize()))
                    })
                    .collect();
                let mut seg_arm = vec![DVec3::ZERO; segments.len() * k_count];
                for (s, seg) in segments.iter().enumerate() {
                    for &(j, w) in &seg.com_weights {
                        for &k in &p.ancestors[j] {
                            seg_arm[s * k_count + k] += f64::from(w) * (positions[j] - positions[p.active[k]]);
                        }
                    }
                }
                let com_arm = (0..k_count)
                    .map(|k| {
                        segments
                            .iter()
                            .enumerate()
                            .map(|(s, seg)| seg.mass_kg * seg_arm[s * k_count + k])
                            .sum::<DVec3>()
                            / p.mass
                    })
                    .collect();
                FrameGeometry { positions, parent_rotation, seg_arm, com_arm }
            })
            .collect()
    }
}

/// The Gauss–Newton normal equations JᵀJ δ = −Jᵀr, kept from one linearisation to the
/// next. Every linearisation has the same rows with the same columns (an inactive
/// inequality keeps its entries as zeros), so J's transpose, the product's pattern and the
/// Cholesky factor's symbolic part (a fill-reducing ordering) are made once per edit and
/// every step only refills values into buffers it owns: no allocation per step, where
/// building them afresh spent about half of each step in the allocator and the kernel's
/// page faults (the whole factor, ~100 MB on CMU 16_01, new every step).
/// Only JᵀJ's lower triangle is made: the factorisation reads no more, and copies what it
/// is given (permuted) into its workspace, so the full product cost its size twice over
/// (6.1 M entries on CMU 16_01, ~100 MB with the copy).
struct NormalEquations {
    /// Jᵀ, one column per residual row.
    jt: SparseColMat<usize, f64>,
    /// J, column-major, and where each of its values sits in `jt`'s.
    j: SparseColMat<usize, f64>,
    j_from_jt: Vec<usize>,
    /// JᵀJ's lower triangle (row ≥ column); each column's first entry is its diagonal.
    jtj: SparseColMat<usize, f64>,
    /// One column of the product being summed, by row (zero between columns).
    accumulator: Vec<f64>,
    /// The diagonal entries undamped.
    undamped: Vec<f64>,
    /// −Jᵀr.
    gradient: Vec<f64>,
    cholesky: SymbolicCholesky<usize>,
    factor: Vec<f64>,
    workspace: MemBuffer,
    /// A row's entries sorted by column, reused.
    sorted: Vec<(usize, f64)>,
}

fn factor_error(e: &dyn std::fmt::Debug) -> SolveError {
    SolveError::Factor(format!("{e:?}"))
}

/// Parallelism of the factorisation: none. On CMU 16_01 two threads made each step slower
/// (faer's sparse product 31 → 54 ms), and a family already solves its samples in parallel.
const PAR: Par = Par::Seq;

impl NormalEquations {
    /// Makes the pattern from the first linearisation's residual rows (value, entries by
    /// unknown) and fills it; `order` lists the unknowns in the order to factor them.
    fn new(rows: &[(f64, Vec<(usize, f64)>)], order: &[usize]) -> Result<Self, SolveError> {
        let unknowns = order.len();
        let mut inverse = vec![usize::MAX; unknowns];
        for (new, &old) in order.iter().enumerate() {
            match inverse.get_mut(old) {
                Some(slot) if *slot == usize::MAX => *slot = new,
                _ => return Err(SolveError::Factor(format!("the order lists unknown {old} twice or out of range"))),
            }
        }
        let mut col_ptr = Vec::with_capacity(rows.len() + 1);
        col_ptr.push(0);
        let mut row_idx = Vec::new();
        let mut sorted = Vec::new();
        for (_, entries) in rows {
            sort_merged(entries, &mut sorted);
            if let Some(&(c, _)) = sorted.iter().find(|(c, _)| *c >= unknowns) {
                return Err(SolveError::Factor(format!("unknown {c} is out of range ({unknowns} unknowns)")));
            }
            row_idx.extend(sorted.iter().map(|(c, _)| *c));
            col_ptr.push(row_idx.len());
        }
        let nnz = row_idx.len();
        let pattern = SymbolicSparseColMat::new_checked(unknowns, rows.len(), col_ptr, None, row_idx);
        // J's values as positions in Jᵀ's: transposing the positions themselves (exact in f64).
        let positions = SparseColMat::new(pattern, (0..nnz).map(|p| p as f64).collect());
        let j = positions.as_ref().transpose().to_col_major().map_err(|e| factor_error(&e))?;
        let j_from_jt = j.val().iter().map(|p| *p as usize).collect();
        let jt = SparseColMat::new(positions.symbolic().to_owned().map_err(|e| factor_error(&e))?, vec![0.0; nnz]);
        if let Some(c) = (0..unknowns).find(|&c| j.symbolic().col_range(c).is_empty()) {
            return Err(SolveError::Factor(format!("unknown {c} enters no residual")));
        }
        let jtj_pattern = lower_gram_pattern(jt.symbolic(), j.symbolic());
        let jtj_nnz = jtj_pattern.row_idx().len();
        let jtj = SparseColMat::new(jtj_pattern, vec![0.0; jtj_nnz]);
        let cholesky = factorize_symbolic_cholesky(
            jtj.symbolic(),
            Side::Lower,
            SymmetricOrdering::Custom(PermRef::new_checked(order, &inverse, unknowns)),
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| factor_error(&e))?;
        let workspace = MemBuffer::try_new(StackReq::any_of(&[
            cholesky.factorize_numeric_llt_scratch::<f64>(PAR, Default::default()),
            cholesky.solve_in_place_scratch::<f64>(1, PAR),
        ]))
        .map_err(|e| factor_error(&e))?;
        let mut normal = NormalEquations {
            factor: vec![0.0; cholesky.len_val()],
            jt,
            j,
            j_from_jt,
            jtj,
            accumulator: vec![0.0; unknowns],
            undamped: vec![0.0; unknowns],
            gradient: vec![0.0; unknowns],
            cholesky,
            workspace,
            sorted,
        };
        if !normal.refill(rows) {
            return Err(SolveError::Factor("the residual rows changed their pattern while being read".into()));
        }
        Ok(normal)
    }

    /// Fills JᵀJ and −Jᵀr from a linearisation's rows; false (nothing changed) when the
    /// rows do not have the pattern these equations were made for.
    fn refill(&mut self, rows: &[(f64, Vec<(usize, f64)>)]) -> bool {
        if rows.len() != self.jt.ncols() {
            return false;
        }
        self.gradient.fill(0.0);
        let (pattern, jt_values) = self.jt.parts_mut();
        let (col_ptr, row_idx) = (pattern.col_ptr(), pattern.row_idx());
        let mut values = std::mem::take(&mut self.sorted);
        for (r, (residual, entries)) in rows.iter().enumerate() {
            sort_merged(entries, &mut values);
            let span = col_ptr[r]..col_ptr[r + 1];
            if values.len() != span.len() || values.iter().zip(&row_idx[span.clone()]).any(|((c, _), i)| c != i) {
                self.sorted = values;
                return false;
            }
            for ((c, w), slot) in values.iter().zip(&mut jt_values[span]) {
                *slot = *w;
                self.gradient[*c] -= w * residual;
            }
        }
        self.sorted = values;
        let jt_values = self.jt.val();
        for (slot, &p) in self.j.val_mut().iter_mut().zip(&self.j_from_jt) {
            *slot = jt_values[p];
        }
        self.fill_lower_gram();
        let diagonal = &self.jtj.symbolic().col_ptr()[..self.undamped.len()];
        for (u, &p) in self.undamped.iter_mut().zip(diagonal) {
            *u = self.jtj.val()[p];
        }
        true
    }

    /// JᵀJ's lower triangle from `j` and `jt`'s current values, a column at a time: column
    /// `c` sums, over the residual rows `r` that hold unknown `c`, `J[r, c]` times row `r`'s
    /// entries at unknowns from `c` on (Gustavson's product, scattered into `accumulator`).
    fn fill_lower_gram(&mut self) {
        let (pattern, values) = self.jtj.parts_mut();
        let accumulator = &mut self.accumulator;
        for c in 0..pattern.ncols() {
            for (&r, &v) in self.j.symbolic().row_idx_of_col_raw(c).iter().zip(self.j.val_of_col(c)) {
                let (row, weights) = (self.jt.symbolic().row_idx_of_col_raw(r), self.jt.val_of_col(r));
                let from = row.partition_point(|&k| k < c);
                for (&k, &w) in row[from..].iter().zip(&weights[from..]) {
                    accumulator[k] += v * w;
                }
            }
            for p in pattern.col_range(c) {
                let k = pattern.row_idx()[p];
                values[p] = accumulator[k];
                accumulator[k] = 0.0;
            }
        }
    }

    /// One damped step, (JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr by sparse Cholesky.
    fn damped_step(&mut self, lambda: f64) -> Result<Vec<f64>, SolveError> {
        let (pattern, values) = self.jtj.parts_mut();
        for (&p, &u) in pattern.col_ptr().iter().zip(&self.undamped) {
            // Marquardt's scaling: the damping follows each unknown's own curvature, so the
            // penalties' large rows do not swamp it.
            values[p] = u + lambda * u + 1e-9;
        }
        let stack = MemStack::new(&mut self.workspace);
        let llt = self
            .cholesky
            .factorize_numeric_llt(
                &mut self.factor,
                self.jtj.as_ref(),
                Side::Lower,
                Default::default(),
                PAR,
                stack,
                Default::default(),
            )
            .map_err(|e| factor_error(&e))?;
        let mut rhs = faer::Mat::<f64>::from_fn(self.gradient.len(), 1, |i, _| self.gradient[i]);
        llt.solve_in_place_with_conj(faer::Conj::No, rhs.as_mut(), PAR, MemStack::new(&mut self.workspace));
        Ok((0..self.gradient.len()).map(|i| rhs[(i, 0)]).collect())
    }
}

/// The pattern of JᵀJ's lower triangle from those of `Jᵀ` and `J`: column `c` holds every
/// unknown from `c` on that shares a residual row with it, sorted (so `c` itself first).
fn lower_gram_pattern(
    jt: SymbolicSparseColMatRef<'_, usize>,
    j: SymbolicSparseColMatRef<'_, usize>,
) -> SymbolicSparseColMat<usize> {
    let unknowns = j.ncols();
    let mut seen_in = vec![usize::MAX; unknowns];
    let mut col_ptr = Vec::with_capacity(unknowns + 1);
    col_ptr.push(0);
    let mut row_idx = Vec::new();
    for c in 0..unknowns {
        let start = row_idx.len();
        for &r in j.row_idx_of_col_raw(c) {
            let row = jt.row_idx_of_col_raw(r);
            for &k in &row[row.partition_point(|&k| k < c)..] {
                if seen_in[k] != c {
                    seen_in[k] = c;
                    row_idx.push(k);
                }
            }
        }
        row_idx[start..].sort_unstable();
        col_ptr.push(row_idx.len());
    }
    SymbolicSparseColMat::new_checked(unknowns, unknowns, col_ptr, None, row_idx)
}

/// `entries` sorted by column into `out`, entries of the same column added.
fn sort_merged(entries: &[(usize, f64)], out: &mut Vec<(usize, f64)>) {
    out.clear();
    out.extend_from_slice(entries);
    out.sort_unstable_by_key(|&(c, _)| c);
    out.dedup_by(|next, kept| {
        let same = next.0 == kept.0;
        if same {
            kept.1 += next.1;
        }
        same
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// Random sparse residual rows (some entries repeated, which add) over `unknowns`, every
    /// unknown in at least one row.
    fn random_rows(unknowns: usize, count: usize, seed: u64) -> Vec<(f64, Vec<(usize, f64)>)> {
        let mut state = seed;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let unit = |x: u64| (x % 2001) as f64 / 1000.0 - 1.0;
        let mut rows: Vec<(f64, Vec<(usize, f64)>)> =
            (0..unknowns).map(|c| (unit(next()), vec![(c, 1.0 + unit(next()).abs())])).collect();
        for _ in 0..count {
            let entries = (0..1 + next() % 5).map(|_| ((next() % unknowns as u64) as usize, unit(next()))).collect();
            rows.push((unit(next()), entries));
        }
        rows
    }

    /// The window runs from the middle of the ground stage before the first changed flight
    /// to the middle of the one after the last, or to the clip's ends (hand-solved).
    #[test]
    fn the_edit_window_spans_the_changed_flights() {
        let stage = |kind, start, end| Stage { kind, frames: FrameRange::new(start, end) };
        use StageKind::{Flight, Ground};
        let stages = Stages {
            fps: 100.0,
            frame_count: 100,
            stages: vec![
                stage(Ground, 0, 10),
                stage(Flight, 10, 20),
                stage(Ground, 20, 40),
                stage(Flight, 40, 50),
                stage(Ground, 50, 70),
                stage(Flight, 70, 80),
                stage(Ground, 80, 100),
            ],
            gravity_mps2: 9.81,
        };
        let moved = GroundEdit { offset_m: DVec3::X, turn_rad: 0.0 };
        let still = GroundEdit::default();
        let window = |edits: &[GroundEdit]| edit_window(&stages, edits).map(|r| (r.start, r.end));
        assert_eq!(window(&[still, still, moved, moved]), Some((30, 60)));
        assert_eq!(window(&[still, still, still, moved]), Some((60, 100)));
        assert_eq!(window(&[still, moved, moved, moved]), Some((0, 30)));
        assert_eq!(window(&[still, moved, still, still]), Some((0, 60)));
        // Missing trailing edits are no edit.
        assert_eq!(window(&[still, still, moved]), Some((30, 100)));
        assert_eq!(window(&[moved; 4]), None);
        assert_eq!(window(&[still, moved, moved, still]), None);
        // Equal turns are different moves (each stage turns about its own centre of mass).
        let turned = GroundEdit { offset_m: DVec3::ZERO, turn_rad: 0.5 };
        assert_eq!(window(&[still, still, turned, turned]), Some((30, 100)));
    }

    /// JᵀJ's lower triangle, built by Gustavson's product over the sparse rows, equals the
    /// dense product's, and the damped step solves the dense system (nalgebra's LU).
    #[test]
    fn normal_equations_match_the_dense_product_and_solve() {
        let unknowns = 40;
        let rows = random_rows(unknowns, 120, 0x9e37_79b9_7f4a_7c15);
        let mut dense = DMatrix::<f64>::zeros(rows.len(), unknowns);
        let mut residuals = DVector::<f64>::zeros(rows.len());
        for (r, (residual, entries)) in rows.iter().enumerate() {
            residuals[r] = *residual;
            for &(c, w) in entries {
                dense[(r, c)] += w;
            }
        }
        let gram = dense.transpose() * &dense;
        let order: Vec<usize> = (0..unknowns).rev().collect();
        let mut normal = NormalEquations::new(&rows, &order).unwrap();
        let pattern = normal.jtj.symbolic();
        for c in 0..unknowns {
            let rows_of_c = pattern.row_idx_of_col_raw(c);
            assert_eq!(rows_of_c.first(), Some(&c), "column {c} starts at its diagonal");
            for (&k, &v) in rows_of_c.iter().zip(normal.jtj.val_of_col(c)) {
                assert!((v - gram[(k, c)]).abs() < 1e-12, "({k}, {c}): {v} vs {}", gram[(k, c)]);
            }
            // Every structurally non-zero entry of the dense lower triangle is in the pattern.
            for k in c..unknowns {
                let shares_a_row = (0..rows.len()).any(|r| dense[(r, k)] != 0.0 && dense[(r, c)] != 0.0);
                assert_eq!(rows_of_c.contains(&k), shares_a_row, "({k}, {c})");
            }
        }
        let lambda = 0.25;
        let step = normal.damped_step(lambda).unwrap();
        let mut damped = gram.clone();
        for c in 0..unknowns {
            damped[(c, c)] += lambda * gram[(c, c)] + 1e-9;
        }
        let expected = damped.lu().solve(&(-(dense.transpose() * residuals))).unwrap();
        for (c, (s, e)) in step.iter().zip(expected.iter()).enumerate() {
            assert!((s - e).abs() < 1e-9 * (1.0 + e.abs()), "unknown {c}: {s} vs {e}");
        }
    }
}
