//! Exports open in Blender: runs Blender's own glTF importer headless on what `kg` writes.
//! Opt-in (Blender is large): set `KG_BLENDER` to a Blender binary (and, for Blender 3.4
//! with a system numpy ≥ 1.24, `PYTHONPATH` to a numpy < 1.24). Skips otherwise.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::process::Command;

#[test]
fn exported_glbs_import_into_blender_as_armatures() {
    let Some(blender) = std::env::var_os("KG_BLENDER") else {
        eprintln!("skipping: set KG_BLENDER to a Blender binary to run the import check");
        return;
    };
    let root = env!("CARGO_MANIFEST_DIR");
    let dir = tempfile::tempdir().unwrap();
    let kg = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_kg")).args(args).current_dir(root).output().unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    kg(&["run", "graphs/demo.ron", "--out", dir.path().to_str().unwrap()]);
    let mut files = vec![(dir.path().join("mannequin_walk.glb"), 20, true)];
    if let Some(data) = kinegraph::nodes::corpus::shared_data() {
        let glb = dir.path().join("cmu_02_02.glb");
        kg(&["convert", data.join("bvh/cmu/02_02.bvh").to_str().unwrap(), glb.to_str().unwrap()]);
        files.push((glb, 38, false));
    }
    let mut args = vec![
        "-b".to_string(),
        "--factory-startup".into(),
        "--python".into(),
        format!("{root}/tests/tools/blender_import.py"),
        "--".into(),
    ];
    args.extend(files.iter().map(|(f, _, _)| f.to_string_lossy().into_owned()));
    let out = Command::new(blender).args(&args).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    for (file, bones, skinned) in files {
        let line = stdout.lines().find(|l| l.starts_with(file.to_str().unwrap())).unwrap_or_else(|| panic!("{stdout}"));
        assert!(line.contains("armatures=1"), "{line}");
        assert!(line.contains(&format!("bones={bones}")), "{line}");
        assert_eq!(line.contains("skinned=1"), skinned, "{line}");
    }
}

/// Characters exported whole (`character.load` → `export.glb`) import into Blender like their
/// source files do, read by the same importer: the same mesh objects (count and names, every
/// one skinned), bones, materials, images and faces.
/// Opt-in as above, and needs the shared corpus.
#[test]
fn exported_characters_import_into_blender_like_their_sources() {
    let Some(blender) = std::env::var_os("KG_BLENDER") else {
        eprintln!("skipping: set KG_BLENDER to a Blender binary to run the import check");
        return;
    };
    let Some(data) = kinegraph::nodes::corpus::shared_data() else { return };
    let root = env!("CARGO_MANIFEST_DIR");
    let dir = tempfile::tempdir().unwrap();
    let mut pairs = Vec::new();
    for (graph, source, export) in [
        ("graphs/walk_on_xbot.ron", "gltf/Xbot.glb", "walk_on_xbot.glb"),
        ("graphs/run_on_xbot.ron", "gltf/Xbot.glb", "run_on_xbot.glb"),
        ("graphs/walk_on_cesium_man.ron", "gltf/CesiumMan.glb", "walk_on_cesium_man.glb"),
        ("graphs/run_on_cesium_man.ron", "gltf/CesiumMan.glb", "run_on_cesium_man.glb"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_kg"))
            .args(["run", graph, "--out", dir.path().to_str().unwrap()])
            .current_dir(root)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        pairs.push((data.join(source), dir.path().join(export)));
    }
    let mut args: Vec<String> =
        ["-b", "--factory-startup", "--python", &format!("{root}/tests/tools/blender_import.py"), "--"]
            .map(String::from)
            .to_vec();
    args.extend(pairs.iter().flat_map(|(a, b)| [a, b]).map(|p| p.to_string_lossy().into_owned()));
    let out = Command::new(blender).args(&args).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let field = |file: &std::path::Path, key: &str| -> String {
        let line = stdout.lines().find(|l| l.starts_with(file.to_str().unwrap())).unwrap_or_else(|| panic!("{stdout}"));
        let at = line.find(&format!(" {key}=")).unwrap_or_else(|| panic!("{key} in {line}")) + key.len() + 2;
        line[at..].split_whitespace().next().unwrap_or_default().to_string()
    };
    println!("{}", stdout.lines().filter(|l| l.contains(".glb:")).collect::<Vec<_>>().join("\n"));
    for (source, export) in &pairs {
        assert_eq!(field(export, "armatures"), "1");
        assert_eq!(field(export, "skinned"), field(export, "meshes"), "{}", export.display());
        for key in ["meshes", "mesh_names", "bones", "materials", "images", "faces"] {
            assert_eq!(
                field(export, key),
                field(source, key),
                "{key}: {} against {}",
                export.display(),
                source.display()
            );
        }
    }
}
