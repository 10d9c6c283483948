//! Learned pre-conditions (Faloutsos et al. 2001, §5): instead of a hand-written region of
//! the state space, a controller's pre-condition is a classifier trained on trials.
//!
//! A trial ([`Trial`]) shoves the figure standing on its PD stand pose (chest, a random
//! horizontal direction and impulse, 0.1 s), lets it move for a random delay after the
//! shove, then hands it to the one controller under study and runs until the controller
//! reports success or failure, or a bounded time passes. The state at the hand-over is the
//! sample; the label is whether the controller succeeded from there ([`Success`]): balance
//! (no post-condition) succeeds when it holds for [`TrialSetup::run_secs`] without failing,
//! the protective step when it reaches its own post-condition without its expected
//! performance failing first. The sample's features ([`features`]) are a compact summary
//! of the [`FigureState`]; a support vector machine (linfa-svm, Gaussian kernel) on the
//! standardised features is trained on them ([`train`]).
//!
//! [`Learned`] wraps a controller and replaces its bid with the classifier's, keeping
//! everything else; the model ([`LearnedPrecondition`]) is stored as RON, so it is trained
//! once (`cargo run --release -p kinegraph-nodes --example learn_precondition`) and shipped.

use std::path::Path;
use std::sync::Arc;

use glam::Vec2;
use linfa::prelude::{Fit, Predict};
use linfa_svm::Svm;
use ndarray016 as nd;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::controller::{BID_CAN_REACH, ControlContext, Controller, Status, Targets};
use super::controllers::{self, facing, step::choose_feet, xz};
use super::simulate::{Push, SimError, SimParams, apply_pushes, blown_up, context, energy_bound_j, stage};
use super::state::FigureState;
use crate::model::Skeleton;

/// Names of the features, in [`features`] order (stored in the model and checked on load).
pub const FEATURES: [&str; 11] = [
    "capture_support_m",
    "com_support_m",
    "capture_offset_forward_m",
    "capture_offset_side_m",
    "com_speed_forward_m_s",
    "com_speed_side_m_s",
    "com_speed_up_m_s",
    "com_height_ratio",
    "trunk_upright",
    "feet_down",
    "stance_reach_legs",
];

/// Number of features.
pub const N_FEATURES: usize = FEATURES.len();

/// The feature vector of a state: signed capture point–support and COM–support distances
/// (metres, clamped to ±1, +1 without support); the capture point's offset from the support
/// centre forward and sideways (metres; sideways as a magnitude, the figure being
/// left–right symmetric); the COM velocity forward, sideways (magnitude) and up (m/s); the
/// COM height over its standing height; the chest's uprightness (cosine); how many feet are
/// down; and the capture point's distance from the sole a step would pivot on, in leg
/// lengths.
pub fn features(state: &FigureState, ctx: &ControlContext<'_>) -> [f64; N_FEATURES] {
    let (forward, left) = facing(state, ctx);
    let distance = |d: f32| if d.is_finite() { d.clamp(-1.0, 1.0) } else { 1.0 };
    let u = xz(state.capture_point - state.support_centre());
    let v = state.com_vel;
    let (_, stance) = choose_feet(state, ctx);
    let sole = state.sole_centre[stance];
    let reach = state.capture_point.distance(Vec2::new(sole.x, sole.z)) / ctx.leg_length_m.max(0.1);
    [
        distance(state.capture_distance_m),
        distance(state.com_support_distance_m),
        u.dot(forward),
        u.dot(left).abs(),
        v.dot(forward),
        v.dot(left).abs(),
        v.y,
        state.com.y / ctx.standing_com_height_m.max(0.1),
        state.trunk_upright,
        f32::from(u8::from(state.foot_down[0]) + u8::from(state.foot_down[1])),
        reach,
    ]
    .map(f64::from)
}

/// When a controller counts as successful from a state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Success {
    /// It runs for the whole trial without reporting failure (a controller without a
    /// post-condition, like balance).
    Holds,
    /// It reports its post-condition before failing or running out of time.
    PostCondition,
}

/// How trials of one controller are set up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialSetup {
    /// Range of the chest shove's impulse, N·s.
    pub impulse_ns: [f32; 2],
    /// Range of the time from the shove's end to the hand-over, seconds.
    pub delay_secs: [f32; 2],
    /// How long the controller runs at most, seconds.
    pub run_secs: f32,
    /// What success is.
    pub success: Success,
}

/// Start of the shove, seconds into a trial.
pub const SHOVE_AT_SECS: f32 = 0.05;
/// Length of the shove, seconds.
pub const SHOVE_SECS: f32 = 0.1;

/// The trial set-up of a controller that can be learned, `None` for the others: balance
/// (holds 1.5 s), protective step (post-condition; the step times out after 0.8 s).
pub fn trial_setup(controller: &str) -> Option<TrialSetup> {
    match controller {
        "balance" => Some(TrialSetup {
            impulse_ns: [0.0, 40.0],
            delay_secs: [0.0, 0.25],
            run_secs: 1.5,
            success: Success::Holds,
        }),
        "step" => Some(TrialSetup {
            impulse_ns: [15.0, 60.0],
            delay_secs: [0.0, 0.2],
            run_secs: 1.0,
            success: Success::PostCondition,
        }),
        _ => None,
    }
}

/// One sampled initial condition.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// Shove direction, radians from the figure's forward towards its left.
    pub direction_rad: f32,
    /// Shove impulse, N·s.
    pub impulse_ns: f32,
    /// Time from the shove's end to the hand-over, seconds.
    pub delay_secs: f32,
}

impl Trial {
    /// Trial `index` of the sequence of `seed` (each trial its own random stream, so a
    /// data set does not depend on the order trials run in).
    pub fn sample(setup: &TrialSetup, seed: u64, index: u64) -> Trial {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(index);
        Trial {
            direction_rad: rng.gen_range(0.0..std::f32::consts::TAU),
            impulse_ns: rng.gen_range(setup.impulse_ns[0]..=setup.impulse_ns[1]),
            delay_secs: rng.gen_range(setup.delay_secs[0]..=setup.delay_secs[1]),
        }
    }
}

/// A trial's sample and label.
#[derive(Clone, Debug, PartialEq)]
pub struct Labelled {
    /// The initial condition.
    pub trial: Trial,
    /// Features of the state at the hand-over.
    pub features: [f64; N_FEATURES],
    /// The hand-written pre-condition's bid in that state.
    pub hand_bid: u32,
    /// The bid of the controller that ran (the hand-written one's, or a [`Learned`]
    /// wrapper's).
    pub bid: u32,
    /// Whether the controller succeeded from there.
    pub success: bool,
}

/// Why learning failed.
#[derive(Debug, thiserror::Error)]
pub enum LearnError {
    /// The controller has no trial set-up.
    #[error("controller '{0}' cannot be learned (learnable: balance, step)")]
    NotLearnable(String),
    /// A trial's simulation failed.
    #[error("trial {index}: {source}")]
    Trial {
        /// Trial index.
        index: u64,
        /// What failed.
        source: SimError,
    },
    /// The trials are all successes or all failures: nothing to separate.
    #[error("{successes} successes and {failures} failures: both outcomes are needed to train")]
    OneClass {
        /// Successful trials.
        successes: usize,
        /// Failed trials.
        failures: usize,
    },
    /// The SVM solver failed.
    #[error("SVM training: {0}")]
    Svm(String),
    /// A model file is unreadable or inconsistent.
    #[error("{path}: {message}")]
    BadModel {
        /// The file.
        path: String,
        /// What is wrong.
        message: String,
    },
}

/// Runs one trial of controller `c` on a figure built from `skeleton`; `setup` is the
/// trial set-up of its name.
pub fn run_trial(
    skeleton: &Skeleton,
    mut c: Box<dyn Controller>,
    setup: &TrialSetup,
    trial: Trial,
    params: &SimParams,
) -> Result<Labelled, SimError> {
    let hand = controllers::pool_of(&[c.name()]).pop();
    let s = stage(skeleton, None, params)?;
    let g = params.world.gravity_m_s2;
    let state0 = FigureState::read(&s.figure, &s.world, &s.spawned, g, 0.0);
    let ctx = context(&s.figure, &s.stand, &state0, g);
    let (mut world, spawned) = (s.world, s.spawned);
    let chest = s.figure.body_index("chest").unwrap_or(0);
    let dir = s.figure.forward * trial.direction_rad.cos() + s.figure.left * trial.direction_rad.sin();
    let push = [Push {
        body: s.figure.bodies[chest].name.clone(),
        direction: dir.to_array(),
        impulse_ns: trial.impulse_ns,
        at_secs: SHOVE_AT_SECS,
        duration_secs: SHOVE_SECS,
    }];
    let bound = energy_bound_j(&s.figure, &push, g);
    let dt = world.dt_secs();
    let hand_over = SHOVE_AT_SECS + SHOVE_SECS + trial.delay_secs;
    let end = hand_over + setup.run_secs;
    let mut targets: Targets = s.stand.clone();
    let mut first: Option<([f64; N_FEATURES], u32, u32)> = None;
    let mut step = 0usize;
    loop {
        let t = step as f32 * dt;
        let state = FigureState::read(&s.figure, &world, &spawned, g, t);
        if let Some(what) = blown_up(&state, bound) {
            return Err(SimError::BlowUp { time_secs: t, what });
        }
        if t + 0.5 * dt >= hand_over {
            if first.is_none() {
                let hand_bid = hand.as_ref().map_or(0, |h| h.bid(&state, &ctx));
                first = Some((features(&state, &ctx), hand_bid, c.bid(&state, &ctx)));
                c.activate(&state, &ctx);
            }
            let status = c.control(&state, &ctx, &mut targets);
            let done = match (status, setup.success) {
                (Status::Failed(_), _) => Some(false),
                (Status::Succeeded, Success::PostCondition) => Some(true),
                // A controller without a post-condition that reports one anyway has
                // succeeded as well.
                (Status::Succeeded, Success::Holds) => Some(true),
                (Status::Running, Success::Holds) if t >= end => Some(true),
                (Status::Running, _) if t >= end => Some(false),
                (Status::Running, _) => None,
            };
            if let (Some(success), Some((features, hand_bid, bid))) = (done, first) {
                return Ok(Labelled { trial, features, hand_bid, bid, success });
            }
        }
        targets.apply(&s.figure, &mut world, &spawned);
        apply_pushes(&mut world, &spawned, &push, &[chest], t);
        world.step();
        step += 1;
    }
}

/// Runs trials `first..first + count` of `seed` for `controller`, in parallel; with a
/// `model`, the controller runs wrapped in [`Learned`] (so [`Labelled::bid`] is the
/// model's).
pub fn sample_trials(
    skeleton: &Skeleton,
    controller: &str,
    model: Option<&Arc<LearnedPrecondition>>,
    (seed, first, count): (u64, u64, u64),
    params: &SimParams,
) -> Result<Vec<Labelled>, LearnError> {
    let not_learnable = || LearnError::NotLearnable(controller.to_string());
    let setup = trial_setup(controller).ok_or_else(not_learnable)?;
    (first..first + count)
        .into_par_iter()
        .map(|i| {
            let plain = controllers::pool_of(&[controller]).pop().ok_or_else(not_learnable)?;
            let c: Box<dyn Controller> = match model {
                Some(m) => Box::new(Learned::new(plain, m.clone())?),
                None => plain,
            };
            run_trial(skeleton, c, &setup, Trial::sample(&setup, seed, i), params)
                .map_err(|source| LearnError::Trial { index: i, source })
        })
        .collect()
}

/// A trained pre-condition: the standardisation of the features and the SVM on them.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LearnedPrecondition {
    /// The controller it was trained for.
    pub controller: String,
    /// Feature names ([`FEATURES`] when trained).
    pub features: Vec<String>,
    /// Feature means over the training trials.
    pub mean: Vec<f64>,
    /// Feature standard deviations over the training trials (floored).
    pub scale: Vec<f64>,
    /// The Gaussian kernel's width ε: k(a, b) = exp(−|a − b|² / ε), on standardised features.
    pub kernel_eps: f64,
    /// The SVM's C (both classes).
    pub c: f64,
    /// How it was trained (trial count, seed, accuracies), for the record.
    pub provenance: Provenance,
    svm: Svm<f64, bool>,
}

/// How a model was trained.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// Training trials.
    pub trials: usize,
    /// Trial seed.
    pub seed: u64,
    /// Of them successful.
    pub successes: usize,
    /// Accuracy on the training trials.
    pub training_accuracy: f64,
    /// The hand-written pre-condition's accuracy on the same trials.
    pub hand_accuracy: f64,
}

/// Kernel widths and C values tried by [`train`].
const EPS_GRID: [f64; 4] = [1.0, 3.0, 10.0, 30.0];
const C_GRID: [f64; 4] = [1.0, 10.0, 100.0, 1000.0];

/// Trains a pre-condition on labelled trials: standardises the features, picks the kernel
/// width and C among a small grid by accuracy on every fourth trial held out, and refits
/// on all of them.
pub fn train(controller: &str, seed: u64, data: &[Labelled]) -> Result<LearnedPrecondition, LearnError> {
    let successes = data.iter().filter(|d| d.success).count();
    if successes == 0 || successes == data.len() || data.len() < 8 {
        return Err(LearnError::OneClass { successes, failures: data.len() - successes });
    }
    let n = data.len() as f64;
    let mut mean = vec![0.0; N_FEATURES];
    let mut scale = vec![0.0; N_FEATURES];
    for d in data {
        for (m, x) in mean.iter_mut().zip(d.features) {
            *m += x / n;
        }
    }
    for d in data {
        for ((s, m), x) in scale.iter_mut().zip(&mean).zip(d.features) {
            *s += (x - m) * (x - m) / n;
        }
    }
    // A feature that never varies (e.g. both feet always down) gets unit scale.
    scale.iter_mut().for_each(|s| *s = if s.sqrt() > 1e-6 { s.sqrt() } else { 1.0 });
    let standardise = |rows: &[&Labelled]| {
        let flat: Vec<f64> =
            rows.iter().flat_map(|d| d.features.iter().zip(&mean).zip(&scale).map(|((x, m), s)| (x - m) / s)).collect();
        let targets: Vec<bool> = rows.iter().map(|d| d.success).collect();
        nd::Array2::from_shape_vec((rows.len(), N_FEATURES), flat)
            .map(|x| linfa::Dataset::new(x, nd::Array1::from(targets)))
    };
    let fit = |rows: &[&Labelled], eps: f64, c: f64| -> Result<Svm<f64, bool>, LearnError> {
        let set = standardise(rows).map_err(|e| LearnError::Svm(e.to_string()))?;
        Svm::<f64, bool>::params()
            .pos_neg_weights(c, c)
            .gaussian_kernel(eps)
            .fit(&set)
            .map_err(|e| LearnError::Svm(e.to_string()))
    };
    let fit_rows: Vec<&Labelled> = data.iter().enumerate().filter(|(i, _)| i % 4 != 3).map(|(_, d)| d).collect();
    let check_rows: Vec<&Labelled> = data.iter().skip(3).step_by(4).collect();
    let mut best = (f64::NEG_INFINITY, EPS_GRID[0], C_GRID[0]);
    for eps in EPS_GRID {
        for c in C_GRID {
            let svm = fit(&fit_rows, eps, c)?;
            let probe = LearnedPrecondition::assemble(controller, &mean, &scale, eps, c, svm, seed, data);
            let acc = probe.accuracy(check_rows.iter().copied()).learned;
            if acc > best.0 {
                best = (acc, eps, c);
            }
        }
    }
    let all: Vec<&Labelled> = data.iter().collect();
    let svm = fit(&all, best.1, best.2)?;
    let mut model = LearnedPrecondition::assemble(controller, &mean, &scale, best.1, best.2, svm, seed, data);
    let acc = model.accuracy(data.iter());
    model.provenance.training_accuracy = acc.learned;
    model.provenance.hand_accuracy = acc.hand;
    Ok(model)
}

/// Accuracies on a set of trials.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Accuracy {
    /// Trials.
    pub trials: usize,
    /// Share where the learned pre-condition predicted the outcome.
    pub learned: f64,
    /// Share where the hand-written one did (bid > 0 ⇔ success).
    pub hand: f64,
}

impl LearnedPrecondition {
    #[allow(clippy::too_many_arguments)]
    fn assemble(
        controller: &str,
        mean: &[f64],
        scale: &[f64],
        kernel_eps: f64,
        c: f64,
        svm: Svm<f64, bool>,
        seed: u64,
        data: &[Labelled],
    ) -> LearnedPrecondition {
        LearnedPrecondition {
            controller: controller.to_string(),
            features: FEATURES.iter().map(|s| s.to_string()).collect(),
            mean: mean.to_vec(),
            scale: scale.to_vec(),
            kernel_eps,
            c,
            provenance: Provenance {
                trials: data.len(),
                seed,
                successes: data.iter().filter(|d| d.success).count(),
                training_accuracy: f64::NAN,
                hand_accuracy: f64::NAN,
            },
            svm,
        }
    }

    /// Whether the controller is predicted to succeed from a state with these features
    /// (non-finite features: no).
    pub fn predicts_success(&self, x: &[f64; N_FEATURES]) -> bool {
        if !x.iter().all(|v| v.is_finite()) {
            return false;
        }
        let z: nd::Array1<f64> = x.iter().zip(&self.mean).zip(&self.scale).map(|((x, m), s)| (x - m) / s).collect();
        self.svm.predict(z)
    }

    /// Accuracies of this model and of the hand-written pre-condition on `data`.
    pub fn accuracy<'a>(&self, data: impl Iterator<Item = &'a Labelled>) -> Accuracy {
        let (mut n, mut learned, mut hand) = (0usize, 0usize, 0usize);
        for d in data {
            n += 1;
            learned += usize::from(self.predicts_success(&d.features) == d.success);
            hand += usize::from((d.hand_bid > 0) == d.success);
        }
        let share = |k: usize| if n > 0 { k as f64 / n as f64 } else { f64::NAN };
        Accuracy { trials: n, learned: share(learned), hand: share(hand) }
    }

    /// The model as RON text.
    pub fn to_ron(&self) -> Result<String, LearnError> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default())
            .map_err(|e| LearnError::Svm(format!("cannot serialise the model: {e}")))
    }

    /// Reads a model from RON text; `path` names it in errors. Checks the feature list, the
    /// standardisation and the support vectors' dimension, so a model that does not fit
    /// this build's features is refused here rather than misread later.
    pub fn from_ron(text: &str, path: &str) -> Result<LearnedPrecondition, LearnError> {
        let bad = |message: String| LearnError::BadModel { path: path.to_string(), message };
        let model: LearnedPrecondition = ron::from_str(text).map_err(|e| bad(e.to_string()))?;
        if model.features != FEATURES {
            return Err(bad(format!("features {:?} are not this build's {FEATURES:?}", model.features)));
        }
        if model.mean.len() != N_FEATURES
            || model.scale.len() != N_FEATURES
            || !model.mean.iter().all(|m| m.is_finite())
            || !model.scale.iter().all(|s| s.is_finite() && *s > 0.0)
        {
            return Err(bad(format!("mean and scale must be {N_FEATURES} finite values (scales positive)")));
        }
        let shape: ShapeProbe = ron::from_str(text).map_err(|e| bad(e.to_string()))?;
        shape.check(&model.svm).map_err(bad)?;
        Ok(model)
    }

    /// Reads a model file.
    pub fn read(path: &Path) -> Result<LearnedPrecondition, LearnError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| LearnError::BadModel { path: path.display().to_string(), message: e.to_string() })?;
        LearnedPrecondition::from_ron(&text, &path.display().to_string())
    }
}

/// The parts of a stored SVM whose shapes [`LearnedPrecondition::from_ron`] checks:
/// linfa evaluates the kernel between the sample and each support vector, which needs
/// every support vector to have [`N_FEATURES`] entries and one weight each.
#[derive(Deserialize)]
struct ShapeProbe {
    svm: SvmProbe,
}

#[derive(Deserialize)]
struct SvmProbe {
    rho: f64,
    sep_hyperplane: HyperplaneProbe,
}

#[derive(Deserialize)]
enum HyperplaneProbe {
    Linear(ArrayProbe<(usize,)>),
    WeightedCombination(ArrayProbe<(usize, usize)>),
}

/// ndarray's serde form: version, shape (a tuple), data.
#[derive(Deserialize)]
struct ArrayProbe<D> {
    dim: D,
    data: Vec<f64>,
}

impl ShapeProbe {
    fn check(&self, svm: &Svm<f64, bool>) -> Result<(), String> {
        let weights = svm.nsupport();
        if !self.svm.rho.is_finite() || !svm.alpha.iter().all(|a| a.is_finite()) {
            return Err("the SVM's weights must be finite".into());
        }
        let (dim, data, want) = match &self.svm.sep_hyperplane {
            HyperplaneProbe::Linear(a) => (vec![a.dim.0], &a.data, vec![N_FEATURES]),
            HyperplaneProbe::WeightedCombination(a) => (vec![a.dim.0, a.dim.1], &a.data, vec![weights, N_FEATURES]),
        };
        if dim != want || !data.iter().all(|v| v.is_finite()) {
            return Err(format!("support vectors of shape {dim:?}: {want:?} of finite values expected"));
        }
        Ok(())
    }
}

/// A controller whose pre-condition is a learned model: it bids [`BID_CAN_REACH`] where
/// the model predicts success and 0 elsewhere; activation and control are the wrapped
/// controller's.
pub struct Learned {
    inner: Box<dyn Controller>,
    model: Arc<LearnedPrecondition>,
}

impl Learned {
    /// Wraps `inner` with `model`, which must have been trained for it.
    pub fn new(inner: Box<dyn Controller>, model: Arc<LearnedPrecondition>) -> Result<Learned, LearnError> {
        if model.controller != inner.name() {
            return Err(LearnError::BadModel {
                path: format!("model for '{}'", model.controller),
                message: format!("cannot be the pre-condition of '{}'", inner.name()),
            });
        }
        Ok(Learned { inner, model })
    }
}

impl Controller for Learned {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn preference(&self) -> u32 {
        self.inner.preference()
    }
    fn bid(&self, state: &FigureState, ctx: &ControlContext<'_>) -> u32 {
        if self.model.predicts_success(&features(state, ctx)) { BID_CAN_REACH } else { 0 }
    }
    fn activate(&mut self, state: &FigureState, ctx: &ControlContext<'_>) {
        self.inner.activate(state, ctx);
    }
    fn control(&mut self, state: &FigureState, ctx: &ControlContext<'_>, targets: &mut Targets) -> Status {
        self.inner.control(state, ctx, targets)
    }
}
