//! `generate.mannequin`: the node over the generated figure in [`crate::kernels::mannequin`].

use std::sync::Arc;

use crate::kernels::mannequin::{mannequin_clip, mannequin_mesh};
use crate::model::{Clip, Mesh};
use crate::node::{FloatParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry};

/// Registers the mannequin generator.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Mannequin));
}

const FRAMES: IntParam = IntParam::new("frames", "Number of frames.", 48, 1, 100_000);
const FPS: FloatParam = FloatParam::new("fps", "Frame rate, frames per second.", 24.0, 1.0, 1000.0, "fps");
const CYCLES: FloatParam = FloatParam::new("cycles", "Swing cycles over the clip.", 1.0, 0.0, 1000.0, "");
const SPEED: FloatParam = FloatParam::new("speed", "Forward travel speed, metres per second.", 1.2, 0.0, 20.0, "m/s");
const CLIP_OUT: Output<Arc<Clip>> = Output::new("clip", "The mannequin's motion.");
const MESH_OUT: Output<Arc<Mesh>> = Output::new("mesh", "The mannequin's skinned box mesh, in the rest pose.");

/// `generate.mannequin`.
pub struct Mannequin;

static MANNEQUIN: NodeSchema = NodeSchema {
    kind: "generate.mannequin",
    category: "generate",
    doc: "A synthetic 1.7 m humanoid with swinging limbs and a skinned box mesh, for demos and tests (not a gait model).",
    inputs: &[],
    outputs: &[CLIP_OUT.spec(), MESH_OUT.spec()],
    params: &[FRAMES.0, FPS.0, CYCLES.0, SPEED.0],
    writes_files: false,
    version: 1,
};

impl Node for Mannequin {
    fn schema(&self) -> &'static NodeSchema {
        &MANNEQUIN
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = mannequin_clip(
            ctx.int(&FRAMES)? as usize,
            ctx.float(&FPS)?,
            ctx.float(&CYCLES)? as f32,
            ctx.float(&SPEED)? as f32,
        )
        .map_err(NodeError::kernel)?;
        let mesh = mannequin_mesh(clip.skeleton().clone(), 0.04);
        ctx.set_output(&CLIP_OUT, Arc::new(clip));
        ctx.set_output(&MESH_OUT, Arc::new(mesh));
        Ok(())
    }
}
