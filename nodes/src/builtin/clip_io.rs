//! Loading clips from files and exporting them.

use std::sync::Arc;

use crate::formats::bvh::{BvhReadOptions, read_bvh_file, write_bvh};
use crate::model::Clip;
use crate::node::{
    FloatParam, Input, InputPathParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, OutputPathParam,
    Registry,
};

/// Registers the clip I/O nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(LoadClip));
    registry.add(Box::new(ExportBvh));
}

const PATH: InputPathParam = InputPathParam::new(
    "path",
    "Motion file to read: BVH, or glTF/GLB. Relative paths start at the graph file's folder.",
    &["bvh"],
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
const CLIP_OUT: Output<Arc<Clip>> = Output::new("clip", "The loaded clip, in metres and seconds.");

/// `clip.load`: reads a clip from a file.
pub struct LoadClip;

static LOAD_CLIP: NodeSchema = NodeSchema {
    kind: "clip.load",
    category: "io",
    doc: "Loads an animation clip from a BVH or glTF file, converting it to metres, Y up.",
    inputs: &[],
    outputs: &[CLIP_OUT.spec()],
    params: &[PATH.0, SCALE.0, ANIMATION.0],
    writes_files: false,
};

impl Node for LoadClip {
    fn schema(&self) -> &'static NodeSchema {
        &LOAD_CLIP
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let path = ctx.input_path(&PATH)?;
        let options = BvhReadOptions { metres_per_unit: ctx.optional_float(&SCALE)? };
        let loaded = read_bvh_file(&path, options)?;
        let (clip, stats) = loaded.value;
        ctx.warn_all(loaded.warnings);
        if clip.import_scale.detected {
            let unit = clip.import_scale.unit.map(|u| u.name()).unwrap_or("?");
            ctx.warn(format!(
                "{}: detected unit '{unit}' ({} m per unit) from a rest extent of {:.3} file units; set metres_per_unit to override",
                path.display(),
                clip.import_scale.metres_per_unit,
                stats.rest_extent_file_units
            ));
        }
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
