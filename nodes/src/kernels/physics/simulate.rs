//! Runs a figure under the supervisor for a script: user requests and pushes at given
//! times, the simulated motion sampled as a clip, the controller timeline and curves.
//!
//! A push is an external force on one body's centre of mass, constant over
//! `duration_secs` (default 0.1 s, a shove) with `force = impulse / duration`, so the
//! impulse in N·s is what the script says whatever the time step.
//!
//! A run that blows up (a non-finite body pose, or a kinetic energy beyond
//! [`energy_bound_j`]) stops with [`SimError::BlowUp`] and its time: no clip is returned.

use glam::{Quat, Vec2, Vec3};
use serde::Deserialize;

use super::controller::{Activation, ControlContext, Supervisor, Targets};
use super::controllers;
use super::figure::{BodyRole, BodyShape, Figure, FigureError, FigureParams, Spawned, build_figure};
use super::seat::{Chair, Seat};
use super::state::FigureState;
use super::{PhysicsError, World, WorldParams, to_rapier};
use crate::cancel::Cancel;
use crate::model::fk::Transform;
use crate::model::{Clip, Skeleton};

/// A script: what the user asks for and when.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Script {
    /// Length of the run, seconds.
    pub duration_secs: f32,
    /// The controllers in the pool (default: all of [`controllers::NAMES`]).
    #[serde(default)]
    pub controllers: Option<Vec<String>>,
    /// User requests (the paper's command strings).
    #[serde(default)]
    pub requests: Vec<Request>,
    /// External pushes.
    #[serde(default)]
    pub pushes: Vec<Push>,
    /// A seat behind the figure, for the sit and rise controllers.
    #[serde(default)]
    pub chair: Option<Chair>,
}

/// A request for a controller at a time.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Request {
    /// Controller name.
    pub controller: String,
    /// When, seconds.
    pub at_secs: f32,
}

/// A push on a body.
#[derive(Clone, Debug, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Push {
    /// Body name (`"chest"`, `"pelvis"`, `"left_hand"`, …).
    pub body: String,
    /// Direction in world axes (Y up; need not be unit length).
    pub direction: [f32; 3],
    /// Impulse, N·s.
    pub impulse_ns: f32,
    /// Start, seconds.
    pub at_secs: f32,
    /// How long the force acts, seconds.
    #[serde(default = "default_push_secs")]
    pub duration_secs: f32,
}

fn default_push_secs() -> f32 {
    0.1
}

/// What is wrong with a script.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ScriptError {
    /// The run length is not positive or too long.
    #[error("duration {0} s must be within (0, 600]")]
    Duration(f32),
    /// A controller name is not known.
    #[error("unknown controller '{name}' (known: {})", known.join(", "))]
    UnknownController {
        /// The name.
        name: String,
        /// Known names.
        known: Vec<String>,
    },
    /// A push names a body the figure does not have.
    #[error("push {index}: unknown body '{name}' (bodies: {})", known.join(", "))]
    UnknownBody {
        /// Push index.
        index: usize,
        /// The name.
        name: String,
        /// The figure's bodies.
        known: Vec<String>,
    },
    /// A push or request lies outside the run.
    #[error("{what} at {at_secs} s (lasting {duration_secs} s) is outside the run of {run_secs} s")]
    OutsideRun {
        /// Which entry.
        what: String,
        /// Its start, seconds.
        at_secs: f32,
        /// Its length, seconds.
        duration_secs: f32,
        /// The run's length, seconds.
        run_secs: f32,
    },
    /// The chair's numbers are out of range.
    #[error("chair: {0}")]
    BadChair(String),
    /// A push has no direction, a bad impulse or duration.
    #[error("push {index}: {message}")]
    BadPush {
        /// Push index.
        index: usize,
        /// What is wrong.
        message: String,
    },
}

/// Why a simulation failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimError {
    /// World set-up (e.g. an unstable time step).
    #[error(transparent)]
    World(#[from] PhysicsError),
    /// The skeleton cannot become a figure.
    #[error(transparent)]
    Figure(#[from] FigureError),
    /// The script is wrong.
    #[error(transparent)]
    Script(#[from] ScriptError),
    /// The initial pose is unusable.
    #[error("initial pose: {0}")]
    Pose(String),
    /// The simulation blew up.
    #[error("the simulation blew up at {time_secs:.4} s: {what}")]
    BlowUp {
        /// When it was detected, seconds.
        time_secs: f32,
        /// What was seen.
        what: String,
    },
    /// The run was cancelled.
    #[error("cancelled")]
    Cancelled,
}

/// Run settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SimParams {
    /// World stepping.
    pub world: WorldParams,
    /// Figure set-up.
    pub figure: FigureParams,
    /// The character's mesh, skinned to the skeleton: when given, the bodies' capsules, the
    /// seat pad and the feet's boxes are sized from it ([`super::skin_fit`]).
    pub mesh: Option<std::sync::Arc<crate::model::Mesh>>,
    /// Output frame rate, frames per second.
    pub fps: f64,
}

impl Default for SimParams {
    fn default() -> Self {
        SimParams { world: WorldParams::default(), figure: FigureParams::default(), mesh: None, fps: 30.0 }
    }
}

/// One sample of the curves, at the clip's frame rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time, seconds.
    pub time_secs: f32,
    /// COM height, metres.
    pub com_height_m: f32,
    /// Signed COM–support distance (negative inside), metres; the distance to the nearer
    /// sole centre when no foot is down.
    pub com_support_m: f32,
    /// Signed capture point–support distance, metres (same convention).
    pub capture_support_m: f32,
    /// Head clearance above the ground, metres.
    pub head_clearance_m: f32,
    /// Kinetic energy, joules.
    pub kinetic_energy_j: f32,
}

/// A finished run.
#[derive(Clone, Debug)]
pub struct SimResult {
    /// The simulated motion on the input skeleton.
    pub clip: Clip,
    /// Controller timeline.
    pub timeline: Vec<Activation>,
    /// Per-frame samples.
    pub samples: Vec<Sample>,
    /// The figure that was simulated.
    pub figure: Figure,
    /// The lowest head clearance over the whole run, metres.
    pub min_head_clearance_m: f32,
    /// The fastest the head came down while touching the ground
    /// ([`FigureState::head_contact_speed`]), m/s; 0 when it never touched. A head laid down
    /// gently is near 0, a limp figure's head strikes the ground at several m/s.
    pub head_impact_speed_m_s: f32,
    /// Steps simulated.
    pub steps: usize,
    /// The script's seat as placed in the world, if it had one.
    pub seat: Option<Seat>,
}

/// Checks a script against the pool and the figure.
pub fn check_script(script: &Script, figure: &Figure) -> Result<(), ScriptError> {
    let run = script.duration_secs;
    if !(run.is_finite() && run > 0.0 && run <= 600.0) {
        return Err(ScriptError::Duration(run));
    }
    let known = || controllers::NAMES.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let names = script.controllers.iter().flatten().chain(script.requests.iter().map(|r| &r.controller));
    for name in names {
        if !controllers::NAMES.contains(&name.as_str()) {
            return Err(ScriptError::UnknownController { name: name.clone(), known: known() });
        }
    }
    for (i, r) in script.requests.iter().enumerate() {
        if !(r.at_secs.is_finite() && (0.0..run).contains(&r.at_secs)) {
            return Err(ScriptError::OutsideRun {
                what: format!("request {i} ({})", r.controller),
                at_secs: r.at_secs,
                duration_secs: 0.0,
                run_secs: run,
            });
        }
    }
    if let Some(chair) = &script.chair {
        chair.check().map_err(ScriptError::BadChair)?;
    }
    for (i, p) in script.pushes.iter().enumerate() {
        if figure.body_index(&p.body).is_none() {
            return Err(ScriptError::UnknownBody {
                index: i,
                name: p.body.clone(),
                known: figure.bodies.iter().map(|b| b.name.clone()).collect(),
            });
        }
        let bad = |message: &str| ScriptError::BadPush { index: i, message: message.into() };
        if !Vec3::from_array(p.direction).is_finite() || Vec3::from_array(p.direction).length() < 1e-6 {
            return Err(bad("direction must be a non-zero vector"));
        }
        if !(p.impulse_ns.is_finite() && (0.0..=10_000.0).contains(&p.impulse_ns)) {
            return Err(bad("impulse_ns must be within 0..=10000 N·s"));
        }
        if !(p.duration_secs.is_finite() && (0.001..=10.0).contains(&p.duration_secs)) {
            return Err(bad("duration_secs must be within 0.001..=10 s"));
        }
        if !(p.at_secs.is_finite() && p.at_secs >= 0.0 && p.at_secs + p.duration_secs <= run) {
            return Err(ScriptError::OutsideRun {
                what: format!("push {i} ({})", p.body),
                at_secs: p.at_secs,
                duration_secs: p.duration_secs,
                run_secs: run,
            });
        }
    }
    Ok(())
}

/// A bound on the kinetic energy a sane run can reach, joules: ten times the energy of
/// the figure falling its own stature plus ten times what the pushes can give (an impulse
/// J on a body of mass m gives at most J²/2m).
pub fn energy_bound_j(figure: &Figure, pushes: &[Push], gravity_m_s2: f32) -> f32 {
    let fall = figure.total_mass_kg * gravity_m_s2 * figure.stature_m;
    let pushes: f32 = pushes
        .iter()
        .filter_map(|p| {
            figure.body_index(&p.body).map(|b| p.impulse_ns * p.impulse_ns / (2.0 * figure.bodies[b].mass_kg))
        })
        .sum();
    10.0 * (fall + pushes)
}

/// A figure standing in a world, posed, with its standing targets.
pub struct Stage {
    /// The figure.
    pub figure: Figure,
    /// The world.
    pub world: World,
    /// Its bodies and joints in the world.
    pub spawned: Spawned,
    /// Targets that hold the initial pose.
    pub stand: Targets,
}

/// Builds the figure for `skeleton`, puts it in a world with a ground at `y = 0` and poses
/// it in the local joint `pose` (rotations, translations; when `None`, the rest skeleton in
/// [`Targets::standing`]), its lowest sole corner on the ground. The pose's root position
/// sets where it stands.
pub fn stage(skeleton: &Skeleton, pose: Option<(&[Quat], &[Vec3])>, params: &SimParams) -> Result<Stage, SimError> {
    let figure = build_figure(skeleton, &params.figure, params.mesh.as_deref())?;
    let mut world = World::new(params.world)?;
    world.add_ground(0.0, figure.friction);
    let spawned = figure.spawn(&mut world, skeleton, Vec3::new(0.0, -figure.rest_sole_y_m, 0.0));
    // One step without gravity lets rapier set the articulation's root from the bodies.
    let gravity = world.inner.gravity;
    world.inner.gravity = rapier3d::math::Vector::ZERO;
    world.step();
    world.inner.gravity = gravity;
    let mut stand = Targets::standing(&figure);
    let (root_rot, root_pos) = if let Some((rotations, translations)) = pose {
        if rotations.len() != skeleton.len() || translations.len() != skeleton.len() {
            return Err(SimError::Pose(format!(
                "{} joints posed, the skeleton has {}",
                rotations.len(),
                skeleton.len()
            )));
        }
        let (rot, pos) = figure.body_poses(skeleton, rotations, translations);
        for (i, body) in figure.bodies.iter().enumerate() {
            if let Some(p) = body.parent {
                stand.set_relative(&figure, i, rot[p].inverse() * rot[i]);
            }
        }
        (rot[0], pos[0])
    } else {
        let state = FigureState::read(&figure, &world, &spawned, params.world.gravity_m_s2, 0.0);
        (Quat::IDENTITY, state.body_pos[0])
    };
    set_pose(&figure, &mut world, &spawned, &stand, root_rot, root_pos)?;
    // Drop it onto the ground: the lowest sole corner at y = 0.
    let state = FigureState::read(&figure, &world, &spawned, params.world.gravity_m_s2, 0.0);
    let lowest = lowest_sole(&figure, &state);
    set_pose(&figure, &mut world, &spawned, &stand, root_rot, root_pos - Vec3::Y * lowest)?;
    stand.apply(&figure, &mut world, &spawned);
    Ok(Stage { figure, world, spawned, stand })
}

/// Lowest sole corner, metres.
fn lowest_sole(figure: &Figure, state: &FigureState) -> f32 {
    let mut lowest = f32::INFINITY;
    for (i, body) in figure.bodies.iter().enumerate() {
        if let (BodyRole::Foot, BodyShape::Box { centre, half_extents, rotation }) = (body.role, body.shape) {
            for sx in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    let c = centre + rotation * Vec3::new(sx * half_extents.x, -half_extents.y, sz * half_extents.z);
                    lowest = lowest.min((state.body_pos[i] + state.body_rot[i] * c).y);
                }
            }
        }
    }
    lowest
}

/// Sets the articulation's coordinates: the root at (`root_rot`, `root_pos`), every joint
/// at its target, velocities zero.
fn set_pose(
    figure: &Figure,
    world: &mut World,
    spawned: &Spawned,
    pose: &Targets,
    root_rot: Quat,
    root_pos: Vec3,
) -> Result<(), SimError> {
    let w = &mut world.inner;
    let Some(link) = w.multibody_joints.rigid_body_link(spawned.handles[0]).copied() else {
        return Err(SimError::Pose("the figure is not an articulation".into()));
    };
    let Some(mb) = w.multibody_joints.get_multibody_mut(link.multibody) else {
        return Err(SimError::Pose("the figure is not an articulation".into()));
    };
    let mut disp = vec![0.0f32; mb.ndofs()];
    // The root's free joint: translation then rotation vector, relative to where it is.
    let root = mb.root().joint();
    let c = root.coords();
    let now_rot = super::rot_from_rapier(root.joint_rot());
    let d = root_pos - Vec3::new(c[0], c[1], c[2]);
    let r = (root_rot * now_rot.inverse()).to_scaled_axis();
    disp[..6].copy_from_slice(&[d.x, d.y, d.z, r.x, r.y, r.z]);
    for (i, body) in figure.bodies.iter().enumerate() {
        let Some(h) = spawned.joints[i] else { continue };
        let Some(link) = w.multibody_joints.get(h).and_then(|(mb, l)| mb.link(l)) else { continue };
        let (assembly, coords, n) = (link.assembly_id(), link.joint().coords(), link.joint().ndofs());
        let want = pose.angles[i];
        match body.kind {
            super::figure::JointKind::Hinge { .. } if n == 1 => disp[assembly] = want[0] - coords[3],
            super::figure::JointKind::Ball { .. } if n == 3 => {
                // Spherical coordinates integrate: joint_rot ← exp(d)·joint_rot. From the
                // current rotation to the target one.
                let now = super::rot_from_rapier(link.joint().joint_rot());
                let target = Quat::from_scaled_axis(Vec3::from_array(want));
                let dv = (target * now.inverse()).to_scaled_axis();
                disp[assembly..assembly + 3].copy_from_slice(&[dv.x, dv.y, dv.z]);
            }
            _ => {}
        }
    }
    let Some(mb) = w.multibody_joints.get_multibody_mut(link.multibody) else { return Ok(()) };
    mb.apply_displacements(&disp);
    mb.generalized_velocity_mut().fill(0.0);
    mb.forward_kinematics(&w.bodies, false);
    mb.update_rigid_bodies(&mut w.bodies, false);
    Ok(())
}

/// Runs `script` on a figure built from `skeleton`, starting in `pose` (see [`stage`]).
/// `cancel` is polled once per output frame.
pub fn simulate(
    skeleton: &std::sync::Arc<Skeleton>,
    pose: Option<(&[Quat], &[Vec3])>,
    script: &Script,
    params: &SimParams,
    cancel: Cancel<'_>,
) -> Result<SimResult, SimError> {
    if !(params.fps.is_finite() && (1.0..=1000.0).contains(&params.fps)) {
        return Err(SimError::Pose(format!("frame rate {} fps must be within 1..=1000", params.fps)));
    }
    let Stage { figure, mut world, spawned, stand } = stage(skeleton, pose, params)?;
    check_script(script, &figure)?;
    let g = params.world.gravity_m_s2;
    let names: Vec<&str> = match &script.controllers {
        Some(list) => list.iter().map(String::as_str).collect(),
        None => controllers::NAMES.to_vec(),
    };
    let mut supervisor = Supervisor::new(controllers::pool_of(&names));
    let state0 = FigureState::read(&figure, &world, &spawned, g, 0.0);
    let mut ctx = context(&figure, &stand, &state0, g);
    if let Some(chair) = &script.chair {
        let seat = chair.place(state0.com_xz(), controllers::facing(&state0, &ctx).0);
        // A seat under a sole would stand the box through the foot.
        if state0.support.iter().any(|c| seat.over(Vec3::new(c.x, 0.0, c.y), 0.0)) {
            return Err(ScriptError::BadChair(format!(
                "behind_m {} puts the seat under the feet; place its front edge behind the heels",
                chair.behind_m
            ))
            .into());
        }
        seat.add_to(&mut world, figure.friction);
        ctx.seat = Some(seat);
    }
    let bound = energy_bound_j(&figure, &script.pushes, g);
    let dt = world.dt_secs();
    let steps = (script.duration_secs / dt).round() as usize;
    let frames = (f64::from(script.duration_secs) * params.fps).floor() as usize + 1;
    let mut targets = stand.clone();
    let mut requests: Vec<&Request> = script.requests.iter().collect();
    requests.sort_by(|a, b| a.at_secs.total_cmp(&b.at_secs));
    let mut next_request = 0;
    let mut body_frames: Vec<(Vec<Quat>, Vec<Vec3>)> = Vec::with_capacity(frames);
    let mut samples = Vec::with_capacity(frames);
    let mut min_head = f32::INFINITY;
    let mut head_impact = 0.0f32;
    let push_bodies: Vec<usize> = script.pushes.iter().filter_map(|p| figure.body_index(&p.body)).collect();
    for step in 0..=steps {
        let t = step as f32 * dt;
        let state = FigureState::read(&figure, &world, &spawned, g, t);
        if let Some(what) = blown_up(&state, bound) {
            return Err(SimError::BlowUp { time_secs: t, what });
        }
        min_head = min_head.min(state.head_clearance_m);
        if let Some(speed) = state.head_contact_speed() {
            head_impact = head_impact.max(speed);
        }
        while body_frames.len() < frames && f64::from(t) + 0.5 * f64::from(dt) >= body_frames.len() as f64 / params.fps
        {
            cancel.check().map_err(|_| SimError::Cancelled)?;
            body_frames.push((state.body_rot.clone(), state.body_pos.clone()));
            samples.push(sample(&state));
        }
        if step == steps {
            break;
        }
        while next_request < requests.len() && requests[next_request].at_secs <= t {
            supervisor.request(&requests[next_request].controller, t);
            next_request += 1;
        }
        supervisor.step(&state, &ctx, &mut targets);
        targets.apply(&figure, &mut world, &spawned);
        apply_pushes(&mut world, &spawned, &script.pushes, &push_bodies, t);
        world.step();
    }
    supervisor.finish(script.duration_secs);
    while body_frames.len() < frames {
        // Rounding left the last frame out: repeat the final pose.
        let last = body_frames.last().cloned().unwrap_or_default();
        body_frames.push(last);
        samples.push(samples.last().copied().unwrap_or(Sample {
            time_secs: 0.0,
            com_height_m: 0.0,
            com_support_m: 0.0,
            capture_support_m: 0.0,
            head_clearance_m: 0.0,
            kinetic_energy_j: 0.0,
        }));
    }
    let clip = clip_of(&figure, skeleton, &body_frames, params.fps).map_err(|e| SimError::Pose(e.to_string()))?;
    let seat = ctx.seat;
    Ok(SimResult {
        clip,
        timeline: supervisor.timeline,
        samples,
        figure,
        min_head_clearance_m: min_head,
        head_impact_speed_m_s: head_impact,
        steps,
        seat,
    })
}

/// The controllers' context for a figure standing in `state0` (its initial state): the
/// standing COM height is the initial one, the leg length the hip's height above its sole;
/// no seat.
pub fn context<'a>(
    figure: &'a Figure,
    stand: &'a Targets,
    state0: &FigureState,
    gravity_m_s2: f32,
) -> ControlContext<'a> {
    let (thigh, foot) = (
        figure.bodies.iter().position(|b| b.role == BodyRole::Thigh),
        figure.bodies.iter().position(|b| b.role == BodyRole::Foot),
    );
    let leg_length_m = match (thigh, foot) {
        (Some(t), Some(f)) => state0.body_pos[t].y - state0.sole_centre[figure.bodies[f].side.unwrap_or(0).min(1)].y,
        _ => 0.5 * figure.stature_m,
    };
    ControlContext { figure, gravity_m_s2, standing_com_height_m: state0.com.y, leg_length_m, stand, seat: None }
}

/// Sets the external forces for the step that starts at `t`: each push acting then puts
/// its force (impulse / duration, N) on its body (`bodies[i]` is push `i`'s figure body);
/// every other force of the previous step is cleared.
pub fn apply_pushes(world: &mut World, spawned: &Spawned, pushes: &[Push], bodies: &[usize], t: f32) {
    for &h in &spawned.handles {
        world.inner.bodies[h].reset_forces(false);
    }
    for (p, &b) in pushes.iter().zip(bodies) {
        if t >= p.at_secs && t < p.at_secs + p.duration_secs {
            let force = Vec3::from_array(p.direction).normalize_or_zero() * (p.impulse_ns / p.duration_secs);
            world.inner.bodies[spawned.handles[b]].add_force(to_rapier(force), true);
        }
    }
}

/// What makes a state blown up, if anything: a non-finite body pose, or a kinetic energy
/// that is not finite or above `bound_j` (see [`energy_bound_j`]).
pub fn blown_up(state: &FigureState, bound_j: f32) -> Option<String> {
    if !(state.body_pos.iter().all(|p| p.is_finite()) && state.body_rot.iter().all(|q| q.is_finite())) {
        return Some("a body pose is not finite (NaN)".into());
    }
    if !state.kinetic_energy_j.is_finite() || state.kinetic_energy_j > bound_j {
        return Some(format!("kinetic energy {:.1} J exceeds the bound {bound_j:.1} J", state.kinetic_energy_j));
    }
    None
}

fn sample(state: &FigureState) -> Sample {
    let no_support = |d: f32, p: Vec2| {
        if d.is_finite() {
            d
        } else {
            state.sole_centre.iter().map(|s| p.distance(Vec2::new(s.x, s.z))).fold(f32::INFINITY, f32::min)
        }
    };
    Sample {
        time_secs: state.time_secs,
        com_height_m: state.com.y,
        com_support_m: no_support(state.com_support_distance_m, state.com_xz()),
        capture_support_m: no_support(state.capture_distance_m, state.capture_point),
        head_clearance_m: state.head_clearance_m,
        kinetic_energy_j: state.kinetic_energy_j,
    }
}

/// The clip of the bodies' poses: each joint's world transform from its body, turned into
/// local rotations; non-root joints keep their rest offsets (the bodies are rigid), roots
/// take their world position.
fn clip_of(
    figure: &Figure,
    skeleton: &std::sync::Arc<Skeleton>,
    frames: &[(Vec<Quat>, Vec<Vec3>)],
    fps: f64,
) -> Result<Clip, crate::model::ClipError> {
    let joints = skeleton.joints();
    let mut rotations = Vec::with_capacity(frames.len() * joints.len());
    let mut translations = Vec::with_capacity(frames.len() * joints.len());
    for (rot, pos) in frames {
        let world: Vec<Transform> = figure.joint_world(skeleton, rot, pos);
        for (j, joint) in joints.iter().enumerate() {
            match joint.parent {
                Some(p) => {
                    rotations
                        .push(crate::math::quat_normalize_or_identity(world[p].rotation.inverse() * world[j].rotation));
                    translations.push(joint.rest_offset);
                }
                None => {
                    rotations.push(world[j].rotation);
                    translations.push(world[j].translation);
                }
            }
        }
    }
    Clip::new(skeleton.clone(), fps, rotations, translations, crate::model::ImportScale::METRES)
}
