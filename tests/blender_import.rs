//! Exports open in Blender: runs Blender's own glTF and volume importers headless on what
//! `kg` writes. Needs `KG_BLENDER`, a Blender binary (CI installs Debian's Blender 3.4), and
//! for Blender 3.4 beside a system numpy ≥ 1.24 `KG_BLENDER_PYTHONPATH`, a folder holding a
//! numpy < 1.24 (its glTF importer uses `np.bool`). Skips without `KG_BLENDER`.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::process::Command;

/// Headless Blender from `KG_BLENDER` running `script` (in tests/tools) on `args`, with
/// `KG_BLENDER_PYTHONPATH` as its PYTHONPATH only (the system's own Python tools keep their
/// numpy). None, after saying so, without `KG_BLENDER`.
fn blender(script: &str) -> Option<Command> {
    let Some(binary) = std::env::var_os("KG_BLENDER").filter(|b| !b.is_empty()) else {
        eprintln!("skipping: set KG_BLENDER to a Blender binary to run the import check");
        return None;
    };
    let mut command = Command::new(binary);
    command.args([
        "-b",
        "--factory-startup",
        "--python",
        &format!("{}/tests/tools/{script}", env!("CARGO_MANIFEST_DIR")),
        "--",
    ]);
    if let Some(path) = std::env::var_os("KG_BLENDER_PYTHONPATH") {
        command.env("PYTHONPATH", path);
    }
    Some(command)
}

#[test]
fn exported_glbs_import_into_blender_as_armatures() {
    let Some(mut blender) = blender("blender_import.py") else { return };
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
    let out = blender.args(files.iter().map(|(f, _, _)| f)).output().unwrap();
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
    let Some(mut blender) = blender("blender_import.py") else { return };
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
    let out = blender.args(pairs.iter().flat_map(|(a, b)| [a, b])).output().unwrap();
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

/// The smoke example opens in Blender where it belongs: its VDB sequence (written Z up) and
/// its character GLB, imported by Blender's own importers, share one floor and one set of
/// axes. Read through Blender's marching cubes of the grids, frame by frame: the fluid fills
/// the graph's box turned into Blender's axes ((x, y, z) → (x, −z, y)); the character stands
/// on the fluid's floor inside it; the hole the body leaves in the warm air lies within the
/// body; the smoke column holds the source and its top climbs along Blender's up axis.
/// Opt-in as above, and needs the shared corpus (the kick).
#[test]
fn the_smoke_example_lines_up_with_its_character_in_blender() {
    let Some(mut blender) = blender("blender_smoke.py") else { return };
    if kinegraph::nodes::corpus::shared_data().is_none() {
        return;
    }
    let root = env!("CARGO_MANIFEST_DIR");
    let dir = tempfile::tempdir().unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_kg"))
        .args(["run", "graphs/kick_through_smoke.ron", "--out", dir.path().to_str().unwrap()])
        .current_dir(root)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let out_dir = dir.path().join("kick_through_smoke");
    let out = blender.arg(out_dir.join("character.glb")).arg(&out_dir).arg("12").output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<serde_json::Value> =
        stdout.lines().filter(|l| l.starts_with('{')).map(|l| serde_json::from_str(l).unwrap()).collect();
    let header = &lines[0];
    assert_eq!(header["sequence"], true, "{header}");
    assert_eq!(header["frames"], 12, "{header}");
    for (grid, kind) in [("density", "FLOAT"), ("temperature", "FLOAT"), ("velocity", "VECTOR_FLOAT")] {
        assert_eq!(header["grids"][grid], kind, "{header}");
    }

    // The graph's box (size 3 × 2.4 × 3 m on the floor, centred on x and z) and its smoke
    // source (0, 0.3, 0.6), radius 0.25 m, in Blender's axes.
    let turn = |[x, y, z]: [f64; 3]| [x, -z, y];
    let (box_lo, box_hi) = (turn([-1.5, 0.0, 1.5]), turn([1.5, 2.4, -1.5]));
    let source = turn([0.0, 0.3, 0.6]);
    let corner = |b: &serde_json::Value, side: usize| -> [f64; 3] {
        std::array::from_fn(|a| b[side][a].as_f64().unwrap_or_else(|| panic!("{b}")))
    };
    let mut holes_checked = 0;
    let mut column_tops = Vec::new();
    for frame in &lines[1..] {
        let f = frame["frame"].as_u64().unwrap();
        println!("frame {f}: {frame}");
        let character = &frame["character"];
        if f == 0 {
            continue; // Before the first step: no warm air yet.
        }
        let (fluid_lo, fluid_hi) = (corner(&frame["fluid"], 0), corner(&frame["fluid"], 1));
        let (char_lo, char_hi) = (corner(character, 0), corner(character, 1));
        for a in 0..3 {
            // Blender's surface lies up to a voxel (0.1 m) and a half beyond the outer voxel centres.
            assert!((fluid_lo[a] - box_lo[a]).abs() < 0.2, "frame {f}: fluid from {fluid_lo:?}, box from {box_lo:?}");
            assert!((fluid_hi[a] - box_hi[a]).abs() < 0.2, "frame {f}: fluid to {fluid_hi:?}, box to {box_hi:?}");
            assert!(char_lo[a] > fluid_lo[a] && char_hi[a] < fluid_hi[a], "frame {f}: character outside the fluid");
        }
        assert!(
            (char_lo[2] - fluid_lo[2]).abs() < 0.15,
            "frame {f}: feet at {} m, fluid floor {} m",
            char_lo[2],
            fluid_lo[2]
        );
        let column = &frame["column"];
        let (column_lo, column_hi) = (corner(column, 0), corner(column, 1));
        assert!((0..3).all(|a| column_lo[a] < source[a] && source[a] < column_hi[a]), "frame {f}: column {column}");
        column_tops.push(column_hi[2]);
        // Once the warm air has filled the box (from frame 6; before, still air leaves voids
        // of its own), the only hole in it is the body.
        if f >= 6 {
            let (hole_lo, hole_hi) = (corner(&frame["hole"], 0), corner(&frame["hole"], 1));
            assert!(
                (0..3).all(|a| hole_lo[a] > char_lo[a] - 0.15 && hole_hi[a] < char_hi[a] + 0.15),
                "frame {f}: hole {hole_lo:?}..{hole_hi:?} outside the body {char_lo:?}..{char_hi:?}"
            );
            assert!(hole_hi[2] - hole_lo[2] > 1.2, "frame {f}: hole {hole_lo:?}..{hole_hi:?} is not the body");
            holes_checked += 1;
        }
    }
    assert_eq!(holes_checked, 6);
    // The warm smoke rises along Blender's z: its top climbs from the first step to the last.
    let (first, last) = (column_tops[0], column_tops[column_tops.len() - 1]);
    assert!(last > first + 0.05, "the column's top went from {first} to {last} m in z");
}
