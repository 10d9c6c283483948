//! Loading clips from files and exporting them.

use std::sync::Arc;

use crate::formats::Loaded;
use crate::formats::bvh::{BvhUnit, BvhWriteOptions, write_bvh_to};
use crate::formats::gltf::{DEFAULT_ANIMATION_NAME, GlbAnimation, build_glb_animations};
use crate::kernels::load::{ClipLoadOptions, LeadingTPose, UpAxis, load_clip};
use crate::kernels::resample::resample;
use crate::model::choice::choices;
use crate::model::{Clip, Mesh};
use crate::node::{
    ChoiceParam, FloatParam, Input, InputPathParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output,
    OutputPathParam, Registry, TextParam,
};

/// Registers the clip I/O nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(LoadClip));
    registry.add(Box::new(ExportBvh));
    registry.add(Box::new(ExportGlb));
}

const PATH: InputPathParam = InputPathParam::new(
    "path",
    "Motion file to read: BVH, glTF/GLB or FBX (converted to metres, Y up; Mixamo downloads work as they are). Relative paths start at the graph file's folder.",
    &["bvh", "gltf", "glb", "fbx"],
);
const SCALE: FloatParam = FloatParam::optional(
    "metres_per_unit",
    "Scale override: metres per file unit (0.01 for centimetres). Unset detects the unit from the skeleton's size and reports it.",
    1e-6,
    1e6,
    "m",
);
const ANIMATION: IntParam = IntParam::optional(
    "animation",
    "Which animation of a glTF file, or take of an FBX file, to load (0 = first).",
    0,
    10_000,
);
const SAMPLE_FPS: FloatParam = FloatParam::optional(
    "sample_fps",
    "glTF and FBX: frame rate to sample the animation at; unset infers it from the key spacing (glTF) or uses the file's frame rate (FBX).",
    1.0,
    1000.0,
    "fps",
);
choices!(UpAxis { Y = "y", Z = "z" });
const UP_AXIS: ChoiceParam<UpAxis> = ChoiceParam::new(
    "up_axis",
    "BVH only: the axis that points up in the file; \"z\" converts a Z-up file to Y up.",
    "y",
);
choices!(LeadingTPose { Drop = "drop", Keep = "keep" });
const T_POSE: ChoiceParam<LeadingTPose> = ChoiceParam::new(
    "t_pose",
    "A T-pose before the motion (cgspeed's CMU conversions put one in frame 0): \"drop\" removes that frame, with a warning, so the clip does not start with a pop; \"keep\" keeps every frame of the file.",
    "drop",
);
const CLIP_OUT: Output<Arc<Clip>> = Output::new("clip", "The loaded clip, in metres and seconds.");

/// `clip.load`: reads a clip from a file.
pub struct LoadClip;

static LOAD_CLIP: NodeSchema = NodeSchema {
    kind: "clip.load",
    category: "io",
    doc: "Loads an animation clip from a BVH, glTF or FBX file, converting it to metres, Y up (and by default without the T-pose cgspeed's CMU conversions put before the motion).",
    inputs: &[],
    outputs: &[CLIP_OUT.spec()],
    params: &[PATH.0, SCALE.0, ANIMATION.0, SAMPLE_FPS.0, UP_AXIS.0, T_POSE.0],
    writes_files: false,
    version: 2,
};

impl Node for LoadClip {
    fn schema(&self) -> &'static NodeSchema {
        &LOAD_CLIP
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let path = ctx.input_path(&PATH)?;
        let options = ClipLoadOptions {
            metres_per_unit: ctx.optional_float(&SCALE)?,
            animation: ctx.optional_int(&ANIMATION)?.map(|a| a as usize),
            sample_fps: ctx.optional_float(&SAMPLE_FPS)?,
            up_axis: ctx.choice(&UP_AXIS)?,
            max_clip_bytes: Some(ctx.memory_limit_bytes()),
            t_pose: ctx.choice(&T_POSE)?,
        };
        let Loaded { value: clip, warnings } = load_clip(&path, options)?;
        ctx.warn_all(warnings);
        ctx.set_output(&CLIP_OUT, Arc::new(clip));
        Ok(())
    }
}

const CLIP_IN: Input<Arc<Clip>> = Input::required("clip", "The clip to write.");
const FILE_OUT: Output<Arc<std::path::PathBuf>> =
    Output::new("file", "The written file, relative to the output folder.");
const BVH_FILE: OutputPathParam =
    OutputPathParam::new("file", "Where to write, relative to the run's output folder.", "bvh", "clip.bvh");
choices!(BvhUnit { AsRead = "as_read", Centimetre = "cm", Metre = "m" });
const BVH_UNIT: ChoiceParam<BvhUnit> = ChoiceParam::new(
    "unit",
    "Length unit of the file: \"as_read\" keeps the unit the clip was loaded in (metres for glTF or generated clips), \"cm\" centimetres, \"m\" metres.",
    "as_read",
);
const BVH_FPS: FloatParam = FloatParam::optional(
    "fps",
    "Frame rate of the file: the clip is resampled to it first (same duration; rotations slerped). Unset keeps the clip's rate.",
    1.0,
    1000.0,
    "fps",
);

/// `export.bvh`: writes a clip as BVH.
pub struct ExportBvh;

static EXPORT_BVH: NodeSchema = NodeSchema {
    kind: "export.bvh",
    category: "io",
    doc: "Writes a clip as a BVH file, by default in the unit it was read in and at its frame rate, keeping each joint's channel layout and writing end sites as End Site blocks. The root's OFFSET is zero and its channels carry its whole position, so every reader puts the hips in the same place.",
    inputs: &[CLIP_IN.spec()],
    outputs: &[FILE_OUT.spec()],
    params: &[BVH_FILE.0, BVH_UNIT.0, BVH_FPS.0],
    writes_files: true,
    // 2: zero root OFFSET, `_EndSite` leaves as End Sites, unit and frame rate.
    version: 2,
};

impl Node for ExportBvh {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_BVH
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP_IN)?;
        let unit = ctx.choice(&BVH_UNIT)?;
        let clip = match ctx.optional_float(&BVH_FPS)? {
            Some(fps) => Arc::new(resample(&clip, fps).map_err(|e| NodeError::param(BVH_FPS.0.name, e.to_string()))?),
            None => clip,
        };
        let mut warnings = Vec::new();
        let relative = ctx.write_output_with(&BVH_FILE, |out| {
            warnings = write_bvh_to(&clip, BvhWriteOptions { unit }, out)?;
            Ok(())
        })?;
        ctx.warn_all(warnings);
        ctx.set_output(&FILE_OUT, Arc::new(relative));
        Ok(())
    }
}

const MESH_IN: Input<Arc<Mesh>> = Input::optional(
    "mesh",
    "A mesh skinned to the clip's skeleton, written with the animation and its materials and textures (optional).",
);
const PROPS_IN: Input<Arc<Mesh>> = Input::optional(
    crate::node::PROPS_PORT,
    "Fixed objects of the scene, written where they stand (world metres): e.g. physics.simulate's stool (optional).",
);
const MORE_CLIPS: [Input<Arc<Clip>>; 3] = [
    Input::optional("clip_2", "A second animation of the same skeleton, written beside the first (optional)."),
    Input::optional("clip_3", "A third animation of the same skeleton (optional)."),
    Input::optional("clip_4", "A fourth animation of the same skeleton (optional)."),
];
const NAME: TextParam = TextParam::new("name", "Name of the clip's animation in the file.", DEFAULT_ANIMATION_NAME);
const MORE_NAMES: [TextParam; 3] = [
    TextParam::new("name_2", "Name of clip_2's animation.", "clip_2"),
    TextParam::new("name_3", "Name of clip_3's animation.", "clip_3"),
    TextParam::new("name_4", "Name of clip_4's animation.", "clip_4"),
];
const GLB_FILE: OutputPathParam =
    OutputPathParam::new("file", "Where to write, relative to the run's output folder.", "glb", "clip.glb");

/// `export.glb`: writes clips (and optionally their skinned mesh) as binary glTF.
pub struct ExportGlb;

static EXPORT_GLB: NodeSchema = NodeSchema {
    kind: "export.glb",
    category: "io",
    doc: "Writes a clip as a binary glTF (.glb): the skeleton as a node hierarchy with its animation, up to three more clips of the same skeleton as further named animations, plus a skinned mesh when one is connected, each of its parts (a character's source meshes) its own named object on the one skin, one primitive per material with its textures embedded, and the scene's fixed objects (props) where they stand.",
    inputs: &[
        CLIP_IN.spec(),
        MESH_IN.spec(),
        MORE_CLIPS[0].spec(),
        MORE_CLIPS[1].spec(),
        MORE_CLIPS[2].spec(),
        PROPS_IN.spec(),
    ],
    outputs: &[FILE_OUT.spec()],
    params: &[GLB_FILE.0, NAME.0, MORE_NAMES[0].0, MORE_NAMES[1].0, MORE_NAMES[2].0],
    writes_files: true,
    // 2: materials and textures, several named animations.
    // 3: each part of the mesh (a character's source meshes) its own mesh and node.
    // 4: the props input.
    version: 4,
};

impl Node for ExportGlb {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_GLB
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP_IN)?;
        let mesh = ctx.optional_input(&MESH_IN)?;
        let props = ctx.optional_input(&PROPS_IN)?;
        if props.as_ref().is_some_and(|p| p.skin.is_some()) {
            return Err(NodeError::input(
                PROPS_IN.name(),
                "is skinned: props are written where they stand; connect an unskinned mesh (a skinned one goes to mesh)"
                    .to_owned(),
            ));
        }
        let mut clips = vec![(ctx.text_param(&NAME)?.to_owned(), clip)];
        for (input, param) in MORE_CLIPS.iter().zip(&MORE_NAMES) {
            if let Some(more) = ctx.optional_input(input)? {
                let name = ctx.text_param(param)?.to_owned();
                if clips.iter().any(|(n, _)| *n == name) {
                    return Err(NodeError::param(
                        param.0.name,
                        format!("another animation is already named '{name}'; give each a different name"),
                    ));
                }
                if !more.skeleton().same_hierarchy(clips[0].1.skeleton()) {
                    return Err(NodeError::input(
                        input.spec().name,
                        "moves another skeleton than clip (joint names or parents differ)".to_owned(),
                    ));
                }
                clips.push((name, more));
            }
        }
        let animations: Vec<GlbAnimation<'_>> = clips.iter().map(|(name, clip)| GlbAnimation { name, clip }).collect();
        let built = build_glb_animations(&animations, mesh.as_deref(), props.as_deref())?;
        ctx.warn_all(built.warnings);
        let relative = ctx.write_output_with(&GLB_FILE, |out| built.value.write_to(out))?;
        ctx.set_output(&FILE_OUT, Arc::new(relative));
        Ok(())
    }
}
