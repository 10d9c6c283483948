//! `generate.arm`: the node over the generated figure in [`crate::kernels::arm`].

use std::sync::Arc;

use crate::kernels::arm::{SAMPLE_POSES, arm_clip, arm_flex_clip, arm_mesh};
use crate::model::{Clip, Mesh};
use crate::node::{FloatParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry};

/// Registers `generate.arm`.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Arm));
}

const FRAMES: IntParam = IntParam::new("frames", "Frames of the flexing clip.", 48, 2, 100_000);
const FPS: FloatParam = FloatParam::new("fps", "Frame rate, frames per second.", 24.0, 1.0, 1000.0, "fps");
const RINGS: IntParam = IntParam::new("rings", "Rings of vertices along the arm (mesh resolution).", 24, 2, 10_000);
const SEGMENTS: IntParam = IntParam::new("segments", "Vertices around each ring.", 12, 3, 10_000);
const CLIP_OUT: Output<Arc<Clip>> =
    Output::new("clip", "One flex: the elbow bends to 2.4 rad and back while the shoulder lifts and the wrist twists.");
const POSES_OUT: Output<Arc<Clip>> =
    Output::new("poses", "Eight sample poses (one per frame) spanning the flex, for training pose-space deformers.");
const MESH_OUT: Output<Arc<Mesh>> =
    Output::new("mesh", "The arm mesh in the rest pose (unskinned: bind it with skin.bind).");

/// `generate.arm`.
pub struct Arm;

static ARM: NodeSchema = NodeSchema {
    kind: "generate.arm",
    category: "generate",
    doc: "A synthetic arm (upper arm and forearm with a biceps swell) held out along +X, a flexing clip and sample poses, for skinning demos and tests.",
    inputs: &[],
    outputs: &[CLIP_OUT.spec(), POSES_OUT.spec(), MESH_OUT.spec()],
    params: &[FRAMES.0, FPS.0, RINGS.0, SEGMENTS.0],
    writes_files: false,
    version: 1,
};

impl Node for Arm {
    fn schema(&self) -> &'static NodeSchema {
        &ARM
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let fps = ctx.float(&FPS)?;
        let clip = arm_flex_clip(ctx.int(&FRAMES)? as usize, fps).map_err(NodeError::kernel)?;
        let poses = arm_clip(&SAMPLE_POSES, fps).map_err(NodeError::kernel)?;
        let (rings, segments) = (ctx.int(&RINGS)? as usize, ctx.int(&SEGMENTS)? as usize);
        ctx.reserve_memory(Mesh::estimated_bytes(rings * segments + 2, 2 * rings * segments), RINGS.0.name)?;
        let mesh = arm_mesh(rings, segments);
        ctx.set_output(&CLIP_OUT, Arc::new(clip));
        ctx.set_output(&POSES_OUT, Arc::new(poses));
        ctx.set_output(&MESH_OUT, Arc::new(mesh));
        Ok(())
    }
}
