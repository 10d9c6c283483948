//! `kg inspect`: what is in a motion or mesh file.

use std::path::Path;

use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::formats::fbx::{FbxReadOptions, read_fbx_file};
use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf_file};
use kinegraph_nodes::formats::obj::read_obj_file;
use kinegraph_nodes::model::{Clip, Mesh};
use serde_json::{Value, json};

use super::EXIT_INVALID;

fn clip_facts(clip: &Clip) -> Value {
    let s = clip.skeleton();
    let extent = s.rest_extent();
    json!({
        "joints": s.joints().iter().filter(|j| !j.end_site).count(),
        "end_sites": s.joints().iter().filter(|j| j.end_site).count(),
        "root": s.joints().first().map(|j| j.name.clone()),
        "frames": clip.frame_count(),
        "fps": clip.fps(),
        "duration_secs": clip.duration_secs(),
        "rest_extent_m": [extent.x, extent.y, extent.z],
    })
}

fn mesh_facts(mesh: &Mesh) -> Value {
    let bounds = mesh.bounds().map(|(lo, hi)| json!({"min": [lo.x, lo.y, lo.z], "max": [hi.x, hi.y, hi.z]}));
    json!({
        "name": mesh.name,
        "vertices": mesh.positions.len(),
        "triangles": mesh.triangles.len(),
        "uvs": mesh.uvs.is_some(),
        "skinned_joints": mesh.skin.as_ref().map(|s| s.skeleton.len()),
        "bounds_m": bounds,
    })
}

/// Facts about `path` as JSON, or the located error text.
pub fn inspect(path: &Path) -> Result<Value, String> {
    let ext = kinegraph_nodes::formats::extension(path);
    match ext.as_str() {
        "bvh" => {
            let loaded = read_bvh_file(path, BvhReadOptions::default()).map_err(|e| e.to_string())?;
            let (clip, stats) = &loaded.value;
            let mut facts = clip_facts(clip);
            facts["format"] = json!("bvh");
            facts["frame_time_secs"] = json!(stats.frame_time_secs);
            facts["channels"] = json!(clip.skeleton().joints().iter().map(|j| j.channels.len()).sum::<usize>());
            facts["unit"] = json!(clip.import_scale.unit.map(|u| u.name()));
            facts["metres_per_unit"] = json!(clip.import_scale.metres_per_unit);
            facts["unit_detected"] = json!(clip.import_scale.detected);
            facts["rest_extent_file_units"] = json!(stats.rest_extent_file_units);
            facts["warnings"] = json!(loaded.warnings);
            Ok(facts)
        }
        "gltf" | "glb" => {
            let loaded = read_gltf_file(path, &GltfReadOptions::default()).map_err(|e| e.to_string())?;
            let asset = &loaded.value;
            Ok(json!({
                "format": ext,
                "skeleton_joints": asset.skeleton.as_ref().map(|s| s.len()),
                "animations": asset.clips.iter().map(|c| {
                    let mut f = clip_facts(&c.clip);
                    f["name"] = json!(c.name);
                    f["index"] = json!(c.animation_index);
                    f
                }).collect::<Vec<_>>(),
                "meshes": asset.meshes.iter().map(mesh_facts).collect::<Vec<_>>(),
                "warnings": loaded.warnings,
            }))
        }
        "fbx" => {
            let loaded = read_fbx_file(path, &FbxReadOptions::default()).map_err(|e| e.to_string())?;
            let asset = &loaded.value;
            Ok(json!({
                "format": "fbx",
                "skeleton_joints": asset.skeleton.len(),
                "root_joint": asset.skeleton.joints().first().map(|j| j.name.clone()),
                "source_metres_per_unit": asset.source.metres_per_unit,
                "source_up_axis": asset.source.up_axis,
                "source_fps": asset.source.fps,
                "takes": asset.clips.iter().map(|c| {
                    let mut f = clip_facts(&c.clip);
                    f["name"] = json!(c.name);
                    f["index"] = json!(c.take_index);
                    f["take_duration_secs"] = json!(c.duration_secs);
                    f
                }).collect::<Vec<_>>(),
                "summary": asset.describe(),
                "warnings": loaded.warnings,
            }))
        }
        "obj" => {
            let loaded = read_obj_file(path, None).map_err(|e| e.to_string())?;
            Ok(json!({
                "format": "obj",
                "meshes": loaded.value.iter().map(mesh_facts).collect::<Vec<_>>(),
                "warnings": loaded.warnings,
            }))
        }
        _ => Err(format!("{}: kg inspect reads .bvh, .gltf, .glb, .fbx and .obj files", path.display())),
    }
}

fn print_human(path: &Path, facts: &Value) {
    outln!("{}", path.display());
    if let Value::Object(map) = facts {
        for (key, value) in map {
            match value {
                Value::Array(items) if items.iter().all(Value::is_object) && !items.is_empty() => {
                    outln!("  {key}:");
                    for item in items {
                        outln!("    - {item}");
                    }
                }
                Value::Array(items) if key == "warnings" => {
                    for w in items {
                        outln!("  warning: {}", w.as_str().unwrap_or_default());
                    }
                }
                other => outln!("  {key}: {other}"),
            }
        }
    }
}

pub(super) fn inspect_command(path: &Path, json: bool) -> u8 {
    match inspect(path) {
        Ok(facts) => {
            if json {
                outln!("{facts}");
            } else {
                print_human(path, &facts);
            }
            0
        }
        Err(e) => {
            errln!("{e}");
            EXIT_INVALID
        }
    }
}
