//! Loading clips from files and exporting them.

use std::sync::Arc;

use std::path::Path;

use crate::formats::bvh::{BvhReadOptions, read_bvh_file, write_bvh};
use crate::formats::gltf::{GltfReadOptions, read_gltf_file, write_glb};
use crate::formats::{FormatError, FormatErrorKind, Loaded};
use crate::model::{Clip, Mesh};
use crate::node::{
    ChoiceParam, FloatParam, Input, InputPathParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output,
    OutputPathParam, Registry,
};

/// Registers the clip I/O nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(LoadClip));
    registry.add(Box::new(ExportBvh));
    registry.add(Box::new(ExportGlb));
}

/// How to read a clip file.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClipLoadOptions {
    /// BVH only: metres per file unit; `None` detects it.
    pub metres_per_unit: Option<f64>,
    /// glTF only: which animation (default the first).
    pub animation: Option<usize>,
    /// glTF only: sampling rate; `None` infers it from the key spacing.
    pub sample_fps: Option<f64>,
    /// BVH only: the file's up axis; Z-up files are turned to kinegraph's Y up.
    pub up_axis: UpAxis,
}

/// Which axis points up in a source file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum UpAxis {
    /// Y up (kinegraph's own convention, and most BVH exporters').
    #[default]
    Y,
    /// Z up (some MakeHuman and 3ds Max exports).
    Z,
}

/// A rest pose much taller along Z than along Y, and tallest along Z, is probably Z-up.
fn looks_z_up(clip: &Clip) -> bool {
    let e = clip.skeleton().rest_extent();
    e.z >= e.max_element() && e.z > 1.5 * e.y
}

/// Reads a clip from a BVH, glTF or GLB file (by extension), with the warnings found,
/// including the unit a BVH was taken to be in.
pub fn load_clip(path: &Path, options: ClipLoadOptions) -> Result<Loaded<Clip>, FormatError> {
    let ext = crate::formats::extension(path);
    match ext.as_str() {
        "bvh" => {
            let loaded = read_bvh_file(path, BvhReadOptions { metres_per_unit: options.metres_per_unit })?;
            let (clip, stats) = loaded.value;
            let mut warnings = loaded.warnings;
            if clip.import_scale.detected {
                let unit = clip.import_scale.unit.map(|u| u.name()).unwrap_or("?");
                warnings.push(format!(
                    "{}: detected unit '{unit}' ({} m per unit) from a rest extent of {:.3} file units; set metres_per_unit to override",
                    path.display(),
                    clip.import_scale.metres_per_unit,
                    stats.rest_extent_file_units
                ));
            }
            let clip = match options.up_axis {
                UpAxis::Z => clip
                    .rotated(glam::Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2))
                    .map_err(|e| FormatError::file(path, FormatErrorKind::Value, e.to_string()))?,
                UpAxis::Y => {
                    if looks_z_up(&clip) {
                        warnings.push(format!(
                            "{}: the skeleton is tallest along Z, so the file looks Z-up; set up_axis to \"z\" to convert",
                            path.display()
                        ));
                    }
                    clip
                }
            };
            Ok(Loaded { value: clip, warnings })
        }
        "gltf" | "glb" => {
            let gltf_options =
                GltfReadOptions { animation: options.animation, skin: None, sample_fps: options.sample_fps };
            let loaded = read_gltf_file(path, &gltf_options)?;
            let mut warnings = loaded.warnings;
            if options.metres_per_unit.is_some() {
                warnings.push("metres_per_unit is ignored for glTF, which is in metres by specification".into());
            }
            let asset = loaded.value;
            let wanted = options.animation.unwrap_or(0);
            let clip = match asset.clips.into_iter().find(|c| c.animation_index == wanted) {
                Some(c) => c.clip,
                None if options.animation.is_none() => {
                    let skeleton = asset.skeleton.ok_or_else(|| {
                        FormatError::file(
                            path,
                            FormatErrorKind::Structure,
                            "the file has neither animations nor a skeleton",
                        )
                    })?;
                    warnings.push("the file has no animation: loaded its rest pose as a one-frame clip".into());
                    Clip::rest_pose(skeleton, 30.0, 1)
                        .map_err(|e| FormatError::file(path, FormatErrorKind::Value, e.to_string()))?
                }
                None => {
                    return Err(FormatError::file(
                        path,
                        FormatErrorKind::Structure,
                        format!("the file has no animation {wanted}"),
                    ));
                }
            };
            Ok(Loaded { value: clip, warnings })
        }
        _ => Err(FormatError::file(path, FormatErrorKind::Unsupported, "expected a .bvh, .gltf or .glb file")),
    }
}

/// Reads meshes from an OBJ, glTF or GLB file (by extension).
pub fn load_meshes(path: &Path, metres_per_unit: Option<f64>) -> Result<Loaded<Vec<Mesh>>, FormatError> {
    let ext = crate::formats::extension(path);
    match ext.as_str() {
        "obj" => crate::formats::obj::read_obj_file(path, metres_per_unit),
        "gltf" | "glb" => {
            let loaded = read_gltf_file(path, &GltfReadOptions::default())?;
            Ok(Loaded { value: loaded.value.meshes, warnings: loaded.warnings })
        }
        _ => Err(FormatError::file(path, FormatErrorKind::Unsupported, "expected a .obj, .gltf or .glb file")),
    }
}

const PATH: InputPathParam = InputPathParam::new(
    "path",
    "Motion file to read: BVH, or glTF/GLB. Relative paths start at the graph file's folder.",
    &["bvh", "gltf", "glb"],
);
const SCALE: FloatParam = FloatParam::optional(
    "metres_per_unit",
    "Scale override: metres per file unit (0.01 for centimetres). Unset detects the unit from the skeleton's size and reports it.",
    1e-6,
    1e6,
    "m",
);
const ANIMATION: IntParam =
    IntParam::optional("animation", "Which animation of a glTF file to load (0 = first).", 0, 10_000);
const SAMPLE_FPS: FloatParam = FloatParam::optional(
    "sample_fps",
    "glTF only: frame rate to sample the animation at; unset infers it from the key spacing.",
    1.0,
    1000.0,
    "fps",
);
const UP_AXIS: ChoiceParam = ChoiceParam::new(
    "up_axis",
    "BVH only: the axis that points up in the file; \"z\" converts a Z-up file to Y up.",
    &["y", "z"],
    "y",
);
const CLIP_OUT: Output<Arc<Clip>> = Output::new("clip", "The loaded clip, in metres and seconds.");

/// `clip.load`: reads a clip from a file.
pub struct LoadClip;

static LOAD_CLIP: NodeSchema = NodeSchema {
    kind: "clip.load",
    category: "io",
    doc: "Loads an animation clip from a BVH or glTF file, converting it to metres, Y up.",
    inputs: &[],
    outputs: &[CLIP_OUT.spec()],
    params: &[PATH.0, SCALE.0, ANIMATION.0, SAMPLE_FPS.0, UP_AXIS.0],
    writes_files: false,
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
            up_axis: if ctx.choice(&UP_AXIS)? == "z" { UpAxis::Z } else { UpAxis::Y },
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

/// `export.bvh`: writes a clip as BVH.
pub struct ExportBvh;

static EXPORT_BVH: NodeSchema = NodeSchema {
    kind: "export.bvh",
    category: "io",
    doc: "Writes a clip as a BVH file in the unit it was read in, keeping each joint's channel layout.",
    inputs: &[CLIP_IN.spec()],
    outputs: &[FILE_OUT.spec()],
    params: &[BVH_FILE.0],
    writes_files: true,
};

impl Node for ExportBvh {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_BVH
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP_IN)?;
        let written = write_bvh(&clip);
        ctx.warn_all(written.warnings);
        let relative = ctx.write_output(&BVH_FILE, written.value.as_bytes())?;
        ctx.set_output(&FILE_OUT, Arc::new(relative));
        Ok(())
    }
}

const MESH_IN: Input<Arc<Mesh>> =
    Input::optional("mesh", "A mesh skinned to the clip's skeleton, written with the animation (optional).");
const GLB_FILE: OutputPathParam =
    OutputPathParam::new("file", "Where to write, relative to the run's output folder.", "glb", "clip.glb");

/// `export.glb`: writes a clip (and optionally its skinned mesh) as binary glTF.
pub struct ExportGlb;

static EXPORT_GLB: NodeSchema = NodeSchema {
    kind: "export.glb",
    category: "io",
    doc: "Writes a clip as a binary glTF (.glb): the skeleton as a node hierarchy with its animation, plus a skinned mesh when one is connected.",
    inputs: &[CLIP_IN.spec(), MESH_IN.spec()],
    outputs: &[FILE_OUT.spec()],
    params: &[GLB_FILE.0],
    writes_files: true,
};

impl Node for ExportGlb {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_GLB
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP_IN)?;
        let mesh = ctx.optional_input(&MESH_IN)?;
        let written = write_glb(&clip, mesh.as_deref())?;
        ctx.warn_all(written.warnings);
        let relative = ctx.write_output(&GLB_FILE, &written.value)?;
        ctx.set_output(&FILE_OUT, Arc::new(relative));
        Ok(())
    }
}
