//! `physics.simulate`: a physically simulated character under composable controllers
//! (Faloutsos 2001) on rapier3d, over the kernels in [`crate::kernels::physics`].

use std::sync::Arc;

use serde_json::json;

use crate::kernels::physics::figure::FigureError;
use crate::kernels::physics::simulate::{Script, SimError, SimParams, simulate};
use crate::kernels::physics::{PhysicsError, WorldParams};
use crate::model::{Clip, Curves, Mesh};
use crate::node::{
    FloatParam, Input, InputPathParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry, Report,
    report_of,
};

/// Registers the physics nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Simulate));
}

const CLIP: Input<Arc<Clip>> = Input::required(
    "clip",
    "The character: its skeleton becomes the articulated figure (16 bodies, de Leva masses); with `frame` set, \
     that frame is the initial pose.",
);
const MESH: Input<Arc<Mesh>> = Input::optional(
    "mesh",
    "The character's mesh, skinned to the clip's skeleton (optional): each capsule's radius is measured from the \
     skin its body carries, the pelvis becomes a pad down to the buttocks and each foot's box the shoe, so a \
     seated body rests on the stool instead of sinking into it and the shoes stand on the floor.",
);
const SCRIPT: InputPathParam = InputPathParam::new(
    "script",
    "RON script: (duration_secs, controllers: Some([..]) to restrict the pool, requests: [(controller, at_secs)], \
     pushes: [(body, direction: (x, y, z) in world axes, impulse_ns, at_secs, duration_secs)], chair: \
     Some((seat_height_m, behind_m, size_m: (width, depth))) for a stool whose front edge stands behind_m behind \
     the figure's first centre of mass). Controllers: balance, step, fall, sit, rise, relax (sit and rise need \
     the chair and a request); bodies: pelvis, abdomen, chest, head, left_/right_ thigh, shank, foot, upper_arm, \
     forearm, hand.",
    &["ron"],
);
const FRAME: IntParam = IntParam::optional(
    "frame",
    "Frame of the clip used as the initial pose; unset stands the rest pose with the feet under the hips and \
     the arms lowered.",
    0,
    10_000_000,
);
const FPS: FloatParam = FloatParam::new("fps", "Frame rate of the simulated clip.", 30.0, 1.0, 1000.0, "fps");
const DT: FloatParam =
    FloatParam::new("dt_secs", "Physics time step (stable from 1/2000 to 1/60 s).", 1.0 / 300.0, 1e-6, 1.0, "s");
const CONTACT_ITERATIONS: IntParam = IntParam::new(
    "contact_iterations",
    "Contact solver passes per physics substep. 1 (the default) lets feet that stand still creep 3–5 cm a \
     second; 4 holds them within 1 cm over 10 s for ~11 % more time. Balance, the step and the fall work with \
     either; the rise does not yet work with 4 (it lunges and the feet hop forward), and the learned \
     pre-conditions were trained with 1.",
    1,
    1,
    64,
);
const MASS: FloatParam = FloatParam::new("total_mass_kg", "Body mass of the character.", 75.0, 20.0, 300.0, "kg");

const OUT: Output<Arc<Clip>> = Output::new("clip", "The simulated motion, on the input skeleton, at `fps`.");
const CURVES: Output<Arc<Curves>> = Output::new(
    "curves",
    "Per frame: COM height (m), signed COM–support and capture point–support distances (m, negative inside the \
     support polygon), head clearance above the ground (m), kinetic energy (J).",
);
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Controller timeline (activation time, reason, end time, outcome), the figure's bodies and masses, the lowest \
     head clearance and the number of physics steps.",
);

const PROPS: Output<Arc<Mesh>> = Output::new(
    crate::node::PROPS_PORT,
    "The script's fixed objects as one unskinned mesh in world metres (the stool; empty without one), for \
     export.glb's props and the viewport.",
);

/// `physics.simulate`.
pub struct Simulate;

static SIMULATE: NodeSchema = NodeSchema {
    kind: "physics.simulate",
    category: "physics",
    doc: "Simulates the character as an articulated rigid-body figure on the ground (rapier3d) under a \
          supervisor of composable controllers (balance, protective step, protective fall, sit down on a stool \
          and rise from it, relax; Faloutsos et al. 2001), with the scripted pushes, controller requests and \
          stool. A run that blows up is a failure, never \
          a clip.",
    inputs: &[CLIP.spec(), MESH.spec()],
    outputs: &[OUT.spec(), CURVES.spec(), REPORT.spec(), PROPS.spec()],
    params: &[SCRIPT.0, FRAME.0, FPS.0, DT.0, CONTACT_ITERATIONS.0, MASS.0],
    writes_files: false,
    // 4: the optional mesh sizes the bodies.
    version: 4,
};

/// Reads and parses the script file, errors located at the `script` param with file, line
/// and column.
fn read_script(path: &std::path::Path) -> Result<Script, NodeError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| NodeError::param("script", format!("cannot read {}: {e}", path.display())))?;
    ron::from_str::<Script>(&text).map_err(|e| NodeError::param("script", format!("{}:{e}", path.display())))
}

/// The kernel's error, located on the param or input that caused it.
fn located(e: SimError, script: &std::path::Path) -> NodeError {
    match e {
        SimError::World(PhysicsError::UnstableTimeStep { .. }) => NodeError::param("dt_secs", e.to_string()),
        SimError::World(PhysicsError::BadParams(_)) => NodeError::kernel(e),
        SimError::Figure(FigureError::Skin(_)) => NodeError::input("mesh", e.to_string()),
        SimError::Figure(_) => NodeError::input("clip", format!("cannot become a figure: {e}")),
        SimError::Script(_) => NodeError::param("script", format!("{}: {e}", script.display())),
        SimError::Pose(_) => NodeError::param("frame", e.to_string()),
        SimError::BlowUp { .. } => NodeError::kernel(e),
        SimError::Cancelled => NodeError::Cancelled,
    }
}

impl Node for Simulate {
    fn schema(&self) -> &'static NodeSchema {
        &SIMULATE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let path = ctx.input_path(&SCRIPT)?;
        let script = read_script(&path)?;
        let fps = ctx.float(&FPS)?;
        let frames = (f64::from(script.duration_secs) * fps).max(0.0) as usize + 1;
        ctx.reserve_memory(Clip::estimated_bytes(frames, clip.joint_count()), "fps")?;
        let pose = match ctx.optional_int(&FRAME)? {
            None => None,
            Some(f) if (f as usize) < clip.frame_count() => {
                Some((clip.frame_rotations(f as usize), clip.frame_translations(f as usize)))
            }
            Some(f) => {
                return Err(NodeError::param("frame", format!("{f} is past the clip's {} frames", clip.frame_count())));
            }
        };
        let mut params = SimParams {
            world: WorldParams {
                dt_secs: ctx.float(&DT)? as f32,
                contact_iterations: ctx.int(&CONTACT_ITERATIONS)? as usize,
                ..WorldParams::default()
            },
            mesh: ctx.optional_input(&MESH)?,
            fps,
            ..SimParams::default()
        };
        params.figure.total_mass_kg = ctx.float(&MASS)?;
        let result = simulate(clip.skeleton(), pose, &script, &params, ctx.cancel()).map_err(|e| located(e, &path))?;
        let mut curves = Curves::new(fps, result.samples.len());
        let channel = |f: fn(&crate::kernels::physics::simulate::Sample) -> f32| {
            result.samples.iter().map(|s| f64::from(f(s))).collect::<Vec<f64>>()
        };
        let pushed = curves
            .push("com_height", "m", channel(|s| s.com_height_m))
            .and_then(|()| curves.push("com_support_distance", "m", channel(|s| s.com_support_m)))
            .and_then(|()| curves.push("capture_support_distance", "m", channel(|s| s.capture_support_m)))
            .and_then(|()| curves.push("head_clearance", "m", channel(|s| s.head_clearance_m)))
            .and_then(|()| curves.push("kinetic_energy", "J", channel(|s| s.kinetic_energy_j)));
        pushed.map_err(NodeError::kernel)?;
        let figure = &result.figure;
        ctx.set_output(&CURVES, Arc::new(curves));
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "timeline": result.timeline.iter().map(|a| json!({
                    "controller": a.controller,
                    "start_secs": a.start_secs,
                    "end_secs": a.end_secs,
                    "reason": a.reason,
                    "outcome": a.outcome,
                })).collect::<Vec<_>>(),
                "controllers": result.timeline.iter().map(|a| a.controller).collect::<Vec<_>>(),
                "min_head_clearance_m": result.min_head_clearance_m,
                "head_impact_speed_m_s": result.head_impact_speed_m_s,
                "physics_steps": result.steps,
                "dt_secs": params.world.dt_secs,
                "contact_iterations": params.world.contact_iterations,
                "figure": {
                    "total_mass_kg": figure.total_mass_kg,
                    "stature_m": figure.stature_m,
                    "mass_method": figure.mass_method,
                    "bodies": figure.bodies.iter().map(|b| json!({"name": b.name, "mass_kg": b.mass_kg})).collect::<Vec<_>>(),
                },
            })),
        );
        let props = result.seat.map_or_else(|| Mesh { name: "props".into(), ..Mesh::default() }, |seat| seat.mesh());
        ctx.set_output(&PROPS, Arc::new(props));
        ctx.set_output(&OUT, Arc::new(result.clip));
        Ok(())
    }
}
