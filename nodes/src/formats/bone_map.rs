//! The bone-map RON file (`kinegraph.bone_map`): reading it with located errors, and
//! writing it. The map itself is plain data in [`crate::model::BoneMap`]; the file lives
//! here so the model knows no file format.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::formats::{FormatError, FormatErrorKind, Location};
use crate::model::BoneMap;

/// Stable `format` field of a bone-map file.
pub const BONE_MAP_FORMAT: &str = "kinegraph.bone_map";
/// Version written; files of other versions are refused.
pub const BONE_MAP_VERSION: u32 = 1;

/// The file as written: `(format: "kinegraph.bone_map", version: 1, joints: { … })`.
#[derive(Serialize, Deserialize)]
struct BoneMapFile {
    format: String,
    version: u32,
    /// Target joint name → source joint name.
    joints: BTreeMap<String, String>,
}

/// `map` as a RON file: sorted, one pair a line, so it diffs and edits well.
pub fn bone_map_to_ron(map: &BoneMap) -> String {
    let file = BoneMapFile { format: BONE_MAP_FORMAT.into(), version: BONE_MAP_VERSION, joints: map.joints.clone() };
    ron::ser::to_string_pretty(&file, ron::ser::PrettyConfig::default()).unwrap_or_default() + "\n"
}

/// Reads a bone-map file's text; errors name `path` and the line.
pub fn bone_map_from_ron(text: &str, path: &Path) -> Result<BoneMap, FormatError> {
    let file: BoneMapFile = ron::from_str(text).map_err(|e| {
        let location = Location::Line { line: e.span.start.line, column: Some(e.span.start.col) };
        FormatError::new(path, location, FormatErrorKind::Syntax, e.code.to_string())
    })?;
    if file.format != BONE_MAP_FORMAT {
        return Err(FormatError::file(
            path,
            FormatErrorKind::Unsupported,
            format!("format is `{}`, not `{BONE_MAP_FORMAT}`", file.format),
        ));
    }
    if file.version != BONE_MAP_VERSION {
        return Err(FormatError::file(
            path,
            FormatErrorKind::Unsupported,
            format!("bone-map version {} is not supported (this kinegraph reads {BONE_MAP_VERSION})", file.version),
        ));
    }
    Ok(BoneMap { joints: file.joints })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_map_reads_back_and_bad_files_name_their_line() {
        let map = BoneMap {
            joints: [("leg_joint_L_1", "LeftUpLeg"), ("Skeleton_torso_joint_1", "Hips")]
                .into_iter()
                .map(|(a, b)| (a.to_owned(), b.to_owned()))
                .collect(),
        };
        let text = bone_map_to_ron(&map);
        assert!(text.contains("\"leg_joint_L_1\": \"LeftUpLeg\""), "{text}");
        assert_eq!(bone_map_from_ron(&text, Path::new("m.ron")).unwrap(), map);

        let broken = "(\n  format: \"kinegraph.bone_map\",\n  version: 1,\n  joints: { \"a\" \"b\" },\n)";
        let e = bone_map_from_ron(broken, Path::new("m.ron")).unwrap_err();
        assert!(matches!(e.location, Location::Line { line: 4, .. }), "{e}");
        assert!(e.to_string().starts_with("m.ron:4:"), "{e}");

        let newer = text.replace("version: 1", "version: 2");
        assert!(bone_map_from_ron(&newer, Path::new("m.ron")).unwrap_err().to_string().contains("version 2"));
        let other = text.replace("kinegraph.bone_map", "kinegraph.graph");
        assert!(bone_map_from_ron(&other, Path::new("m.ron")).unwrap_err().to_string().contains("kinegraph.graph"));
    }
}
