//! `skin.bind`: the node over binding ([`crate::kernels::skinning::bind`]).

use std::sync::Arc;

use crate::kernels::skinning::{AutoWeightParams, BindMode, bind};
use crate::model::choice::choices;
use crate::model::{Clip, Mesh};
use crate::node::{
    ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry,
};

/// Registers `skin.bind` (`skin.deform` is registered by [`super::pose_space`]).
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Bind));
}

const MESH_IN: Input<Arc<Mesh>> =
    Input::required("mesh", "The mesh to bind, modelled in the skeleton's rest pose (OBJ or glTF).");
const CLIP_IN: Input<Arc<Clip>> = Input::required("clip", "A clip whose skeleton the mesh is bound to.");
const MESH_OUT: Output<Arc<Mesh>> = Output::new("mesh", "The skinned mesh (at most 4 influences per vertex).");
choices!(BindMode { Keep = "keep", Automatic = "automatic" });
const MODE: ChoiceParam<BindMode> = ChoiceParam::new(
    "weights",
    "\"keep\" uses the mesh's own weights when it has them; \"automatic\" always computes distance-to-bone weights.",
    "keep",
);
const POWER: FloatParam = FloatParam::new(
    "falloff_power",
    "How fast a bone's influence fades with distance (higher = stiffer, narrower blend at the joints).",
    4.0,
    0.5,
    16.0,
    "",
);
const SMOOTHING: IntParam =
    IntParam::new("smoothing", "Rounds of averaging the weights with mesh neighbours (softens seams).", 2, 0, 100);

/// `skin.bind`.
pub struct Bind;

static BIND: NodeSchema = NodeSchema {
    kind: "skin.bind",
    category: "skin",
    doc: "Attaches a mesh to a skeleton. Meshes without weights get automatic ones (distance to the bones, smoothed), at most 4 joints per vertex.",
    inputs: &[MESH_IN.spec(), CLIP_IN.spec()],
    outputs: &[MESH_OUT.spec()],
    params: &[MODE.0, POWER.0, SMOOTHING.0],
    writes_files: false,
    version: 1,
};

impl Node for Bind {
    fn schema(&self) -> &'static NodeSchema {
        &BIND
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let mesh = ctx.input(&MESH_IN)?;
        let clip = ctx.input(&CLIP_IN)?;
        let mode = ctx.choice(&MODE)?;
        let params = AutoWeightParams {
            falloff_power: ctx.float(&POWER)? as f32,
            smoothing_iterations: ctx.int(&SMOOTHING)? as usize,
        };
        if mesh.positions.is_empty() {
            return Err(NodeError::input(MESH_IN.name(), "has no vertices"));
        }
        let bound =
            bind(&mesh, clip.skeleton(), mode, params).map_err(|e| NodeError::input(MESH_IN.name(), e.to_string()))?;
        ctx.set_output(&MESH_OUT, Arc::new(bound));
        Ok(())
    }
}
