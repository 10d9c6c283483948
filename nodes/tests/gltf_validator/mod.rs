//! The Khronos glTF Validator for the glTF tests: run through `tests/tools/validate_gltf.mjs`
//! with `node`, looked for in `$KG_GLTF_VALIDATOR_DIR`, else where `.ci/run` installs it
//! (`${KG_TOOLS_DIR:-$HOME/.cache/kinegraph-tools}/khronos-validator`). Missing node or
//! validator: the calling test fails when `CI` is set and skips validation otherwise.

//! Also the independent reading of a file's node hierarchy and skins with the `gltf` crate
//! that several glTF tests pose vertices with.

#![allow(clippy::unwrap_used)] // test code: a failed unwrap is a failed test
#![allow(dead_code)] // each test binary that includes this module uses part of it

use std::path::{Path, PathBuf};
use std::process::Command;

/// The validator's folder and the script that runs it, or `None` (outside CI) without them.
fn validator() -> Option<(PathBuf, PathBuf)> {
    // The same folder `.ci/run` installs into, so a developer who ran it once is set up.
    let tools = || {
        std::env::var_os("KG_TOOLS_DIR")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|home| Path::new(&home).join(".cache/kinegraph-tools")))
    };
    let dir = std::env::var_os("KG_GLTF_VALIDATOR_DIR")
        .map(PathBuf::from)
        .or_else(|| tools().map(|t| t.join("khronos-validator")))
        .unwrap_or_default();
    let script = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/tools/validate_gltf.mjs"));
    let node_ok = Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    if node_ok && dir.join("node_modules/gltf-validator").is_dir() {
        return Some((dir, script));
    }
    let why = format!("node or gltf-validator missing (looked in {}; set KG_GLTF_VALIDATOR_DIR)", dir.display());
    assert!(std::env::var_os("CI").is_none(), "{why}; CI requires the validator");
    eprintln!("skipping validation: {why}");
    None
}

/// Runs the validator on `files`, panicking with its report on any error.
pub fn validate_gltf(files: &[PathBuf]) {
    let Some((dir, script)) = validator() else {
        return;
    };
    let out = Command::new("node").arg(&script).args(files).env("KG_GLTF_VALIDATOR_DIR", dir).output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    eprintln!("{report}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "validator reported errors:\n{report}");
    assert_eq!(report.matches("errors=0").count(), files.len(), "{report}");
}

/// World matrices of every node of a `gltf` document whose nodes take local transforms
/// `local` (by node index), from the default scene's roots.
pub fn node_worlds(doc: &gltf::Document, local: &[glam::Mat4]) -> Vec<glam::Mat4> {
    let mut world = vec![glam::Mat4::IDENTITY; local.len()];
    let mut stack: Vec<(gltf::Node<'_>, glam::Mat4)> =
        doc.default_scene().unwrap().nodes().map(|n| (n, glam::Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        world[node.index()] = parent * local[node.index()];
        stack.extend(node.children().map(|c| (c, world[node.index()])));
    }
    world
}

/// World matrices of every node in the file's own rest pose (its nodes' transforms).
pub fn rest_worlds(doc: &gltf::Document) -> Vec<glam::Mat4> {
    let local: Vec<glam::Mat4> = doc.nodes().map(|n| glam::Mat4::from_cols_array_2d(&n.transform().matrix())).collect();
    node_worlds(doc, &local)
}

/// The inverse bind matrices of `skin`, per joint, as the file stores them.
pub fn inverse_bind_matrices(skin: &gltf::Skin<'_>, buffers: &[gltf::buffer::Data]) -> Vec<glam::Mat4> {
    let ibms = skin.reader(|b| Some(&buffers[b.index()])).read_inverse_bind_matrices().unwrap();
    ibms.map(|m| glam::Mat4::from_cols_array_2d(&m)).collect()
}

/// Per joint of `skin`, the matrix that takes a bind-pose vertex to where the joints'
/// `world` matrices put it: world · inverse bind matrix, read from the file.
pub fn skin_matrices(skin: &gltf::Skin<'_>, buffers: &[gltf::buffer::Data], world: &[glam::Mat4]) -> Vec<glam::Mat4> {
    skin.joints().zip(inverse_bind_matrices(skin, buffers)).map(|(j, ibm)| world[j.index()] * ibm).collect()
}
