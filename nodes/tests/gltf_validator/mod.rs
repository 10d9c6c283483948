//! The Khronos glTF Validator for the glTF tests: run through `tests/tools/validate_gltf.mjs`
//! with `node`, looked for in `$KG_GLTF_VALIDATOR_DIR`, else where `.ci/run` installs it
//! (`${KG_TOOLS_DIR:-$HOME/.cache/kinegraph-tools}/khronos-validator`). Missing node or
//! validator: the calling test fails when `CI` is set and skips validation otherwise.

#![allow(clippy::unwrap_used)] // test code: a failed unwrap is a failed test

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
