//! Loading clips and meshes from files by extension, with the warnings found. A kernel:
//! `clip.load`, `mesh.load` and the clip-set loader of the transitions read files with it.

use std::path::Path;

use crate::formats::bvh::{BvhReadOptions, read_bvh_file};
use crate::formats::gltf::{GltfReadOptions, read_gltf_file};
use crate::formats::{FormatError, FormatErrorKind, Loaded};
use crate::model::{Clip, Mesh};

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
