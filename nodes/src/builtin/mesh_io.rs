//! Loading meshes and writing baked mesh sequences.

use std::sync::Arc;

use crate::formats::gltf::write_sequence_glb;
use crate::formats::{FormatError, FormatErrorKind, Loaded};
use crate::kernels::load::{Character, RestPose, load_character_resting, load_meshes};
use crate::model::{Clip, Mesh, MeshSequence};
use crate::node::{
    ChoiceParam, FloatParam, Input, InputPathParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output,
    OutputPathParam, Registry,
};
use crate::node::{Report, into_report};

/// Registers the mesh nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(LoadMesh));
    registry.add(Box::new(LoadCharacter));
    registry.add(Box::new(ExportSequence));
}

const PATH: InputPathParam = InputPathParam::new(
    "path",
    "Mesh file to read: OBJ, or glTF/GLB (skinned meshes keep their skin). Relative paths start at the graph file's folder.",
    &["obj", "gltf", "glb"],
);
const SCALE: FloatParam = FloatParam::optional(
    "metres_per_unit",
    "OBJ only: metres per file unit (0.01 for centimetres). Unset reads metres and warns when the size suggests another unit.",
    1e-6,
    1e6,
    "m",
);
const INDEX: IntParam = IntParam::new("index", "Which mesh of the file to output (0 = first).", 0, 0, 100_000);
const MESH_OUT: Output<Arc<Mesh>> = Output::new("mesh", "The mesh, in metres.");

/// `mesh.load`: reads one mesh from a file.
pub struct LoadMesh;

static LOAD_MESH: NodeSchema = NodeSchema {
    kind: "mesh.load",
    category: "io",
    doc: "Loads a triangle mesh from an OBJ or glTF file; normals are computed when the file has none.",
    inputs: &[],
    outputs: &[MESH_OUT.spec()],
    params: &[PATH.0, SCALE.0, INDEX.0],
    writes_files: false,
    version: 1,
};

impl Node for LoadMesh {
    fn schema(&self) -> &'static NodeSchema {
        &LOAD_MESH
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let path = ctx.input_path(&PATH)?;
        let Loaded { value: meshes, warnings } = load_meshes(&path, ctx.optional_float(&SCALE)?)?;
        ctx.warn_all(warnings);
        let index = ctx.int(&INDEX)? as usize;
        let count = meshes.len();
        let mesh = meshes.into_iter().nth(index).ok_or_else(|| {
            FormatError::file(
                &path,
                FormatErrorKind::Structure,
                format!("has {count} meshes, so there is no mesh {index}"),
            )
        })?;
        ctx.set_output(&MESH_OUT, Arc::new(mesh));
        Ok(())
    }
}

const CHARACTER_PATH: InputPathParam = InputPathParam::new(
    "path",
    "glTF, GLB or FBX file of a rigged character (a Mixamo download with its skin). Relative paths start at the graph file's folder.",
    &["gltf", "glb", "fbx"],
);
const REST_POSE: ChoiceParam<RestPose> = ChoiceParam::new(
    "rest_pose",
    "The pose the skeleton rests in (skeleton.map's 'rest' reference, the mesh's rest shape): 'nodes', the file's node \
     transforms; 'bind', the skin's bind pose (where the inverse bind matrices put each joint, the pose the mesh was \
     bound in).",
    "nodes",
);
const ANIMATION: IntParam = IntParam::new(
    "animation",
    "Which animation (FBX: take) of the file to output as the clip (0 = first).",
    0,
    0,
    100_000,
);
const CHARACTER_CLIP: Output<Arc<Clip>> = Output::new(
    "clip",
    "The character's skeleton moving through the chosen animation (its rest pose when the file has none).",
);
const CHARACTER_MESH: Output<Arc<Mesh>> = Output::new(
    "mesh",
    "Every mesh of the scene as one mesh skinned to the skeleton, in its rest pose, metres: skinned meshes keep their weights, meshes parented to a bone move rigidly with it; each triangle keeps its material, and each source mesh stays a named part that export.glb writes as its own object.",
);
const CHARACTER_REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Each source mesh: its name, vertex count and how it is bound (skinned or rigid to a joint); the materials; whether the file's inverse bind matrices were kept.",
);

/// `character.load`: a whole rigged character from one glTF/GLB or FBX scene.
pub struct LoadCharacter;

static LOAD_CHARACTER: NodeSchema = NodeSchema {
    kind: "character.load",
    category: "io",
    doc: "Loads a rigged character from a glTF/GLB or FBX scene: its skeleton and animation, and every mesh merged into one skinned mesh (meshes attached to bones follow them rigidly) with each part's material, UVs and textures (FBX: converted to metallic-roughness, embedded textures kept), ready for export.glb. A texture image file missing beside the glTF is an error naming it; an FBX texture neither embedded nor beside the file is left out with a warning.",
    inputs: &[],
    outputs: &[CHARACTER_CLIP.spec(), CHARACTER_MESH.spec(), CHARACTER_REPORT.spec()],
    params: &[CHARACTER_PATH.0, ANIMATION.0, REST_POSE.0],
    writes_files: false,
    // 2: materials, textures and UVs kept; the file's inverse bind matrices when they fit.
    // 3: the mesh remembers its source meshes as parts (export.glb writes them apart).
    // 4: FBX materials and textures read.
    version: 4,
};

impl Node for LoadCharacter {
    fn schema(&self) -> &'static NodeSchema {
        &LOAD_CHARACTER
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let path = ctx.input_path(&CHARACTER_PATH)?;
        let animation = usize::try_from(ctx.int(&ANIMATION)?).unwrap_or(0);
        let Loaded { value: Character { clip, mesh, parts, file_inverse_bind_matrices }, warnings } =
            load_character_resting(&path, animation, ctx.choice(&REST_POSE)?)?;
        ctx.warn_all(warnings);
        let parts: Vec<_> = parts
            .iter()
            .map(|p| serde_json::json!({ "mesh": p.name, "vertices": p.vertices, "binding": p.binding }))
            .collect();
        ctx.set_output(
            &CHARACTER_REPORT,
            Arc::new(into_report(serde_json::json!({
                "joints": clip.joint_count(),
                "frames": clip.frame_count(),
                "vertices": mesh.positions.len(),
                "meshes": parts,
                "materials": mesh.materials.iter().map(|m| m.name.clone().unwrap_or_default()).collect::<Vec<_>>(),
                "inverse_bind_matrices": if file_inverse_bind_matrices { "the file's (they fit the rest pose)" } else { "computed from the rest pose" },
            }))),
        );
        ctx.set_output(&CHARACTER_CLIP, Arc::new(clip));
        ctx.set_output(&CHARACTER_MESH, Arc::new(mesh));
        Ok(())
    }
}

const SEQUENCE_IN: Input<Arc<MeshSequence>> = Input::required("sequence", "The deformed mesh per frame.");
const FILE_OUT: Output<Arc<std::path::PathBuf>> =
    Output::new("file", "The written file, relative to the output folder.");
const GLB_FILE: OutputPathParam =
    OutputPathParam::new("file", "Where to write, relative to the run's output folder.", "glb", "sequence.glb");

/// `export.mesh_sequence`: writes a baked mesh sequence as GLB morph-target animation.
pub struct ExportSequence;

static EXPORT_SEQUENCE: NodeSchema = NodeSchema {
    kind: "export.mesh_sequence",
    category: "io",
    doc: "Writes a baked mesh animation (PSD, WPSD, bar-net) as binary glTF: every frame a morph target, played by a weights animation. For plain skinning, export.glb writes the lighter skinned mesh + skeleton animation instead.",
    inputs: &[SEQUENCE_IN.spec()],
    outputs: &[FILE_OUT.spec()],
    params: &[GLB_FILE.0],
    writes_files: true,
    version: 1,
};

impl Node for ExportSequence {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_SEQUENCE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let sequence = ctx.input(&SEQUENCE_IN)?;
        let written = write_sequence_glb(&sequence)?;
        ctx.warn_all(written.warnings);
        let relative = ctx.write_output(&GLB_FILE, &written.value)?;
        ctx.set_output(&FILE_OUT, Arc::new(relative));
        Ok(())
    }
}
