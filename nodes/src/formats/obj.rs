//! Wavefront OBJ meshes, read with tobj (triangulated, one index per vertex).
//!
//! Steps: 1. parse with tobj (materials are not read: kinegraph has no use for them);
//! 2. on a parse error, find the first offending line ourselves so the error is located;
//! 3. one [`Mesh`] per object/group, positions scaled to metres, normals computed when the
//! file has none, UVs flipped to glTF's convention (`v` down, origin top-left);
//! 4. warn when the size suggests the file is not in the unit assumed.

use std::io::BufReader;
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::formats::error::{FormatError, FormatErrorKind as Kind, Loaded, Location};
use crate::model::Mesh;
use crate::model::units::detect_unit;

/// Meshes larger than this (file units, read as metres) draw a unit warning: few
/// characters or props are taller than a house.
const SUSPICIOUS_EXTENT_M: f64 = 3.0;

/// Reads every object of an OBJ file as a triangle mesh.
///
/// `metres_per_unit` scales positions (e.g. `0.01` for centimetres); `None` takes the
/// file to be in metres and warns when a mesh is larger than 3 m, naming the unit its
/// size suggests (`base.obj`, ~17 units tall, suggests decimetres).
pub fn read_obj_file(path: &Path, metres_per_unit: Option<f64>) -> Result<Loaded<Vec<Mesh>>, FormatError> {
    let bytes = std::fs::read(path).map_err(|e| FormatError::io(path, &e))?;
    read_obj(&bytes, path, metres_per_unit)
}

/// Parses OBJ `bytes`; `path` names the file in errors.
pub fn read_obj(bytes: &[u8], path: &Path, metres_per_unit: Option<f64>) -> Result<Loaded<Vec<Mesh>>, FormatError> {
    if let Some(s) = metres_per_unit
        && !(s.is_finite() && s > 0.0)
    {
        return Err(FormatError::file(
            path,
            Kind::Value,
            format!("metres per unit must be positive and finite, got {s}"),
        ));
    }
    // tobj turns a relative index past the start (`f 1/-50 …` with four UVs) into a huge
    // unsigned one and multiplies it unchecked: with overflow checks that panics, without them
    // it can wrap to a small index and read the wrong UV. Faces are checked here first.
    if let Some(line) = find_bad_line(bytes, Records::FaceIndices) {
        return Err(FormatError::new(
            path,
            Location::Line { line, column: None },
            Kind::Structure,
            "OBJ: a face refers to a vertex, UV or normal not defined before it",
        ));
    }
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    let mut reader = BufReader::new(bytes);
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| Ok((Vec::new(), Default::default())))
        .map_err(|e| map_tobj_error(e, bytes, path))?;

    let scale = metres_per_unit.unwrap_or(1.0) as f32;
    let mut warnings = Vec::new();
    let mut meshes = Vec::with_capacity(models.len());
    for model in models {
        let m = model.mesh;
        let positions: Vec<Vec3> = m.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2]) * scale).collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(FormatError::file(
                path,
                Kind::Value,
                format!("object '{}' has a non-finite vertex position", model.name),
            ));
        }
        let n = positions.len();
        let triangles: Vec<[u32; 3]> = m.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        if triangles.is_empty() {
            warnings.push(format!("object '{}' has no faces; skipped", model.name));
            continue;
        }
        if triangles.iter().flatten().any(|&i| i as usize >= n) {
            return Err(FormatError::file(
                path,
                Kind::Structure,
                format!("object '{}' has a face index past its vertices", model.name),
            ));
        }
        let file_normals: Vec<Vec3> = m.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let normals = if file_normals.len() == n && file_normals.iter().all(|v| v.is_finite()) {
            file_normals.into_iter().map(|v| v.try_normalize().unwrap_or(Vec3::Y)).collect()
        } else {
            Mesh::compute_normals(&positions, &triangles)
        };
        if m.texcoords.iter().any(|c| !c.is_finite()) {
            return Err(FormatError::file(
                path,
                Kind::Value,
                format!("object '{}' has a non-finite texture coordinate", model.name),
            ));
        }
        let uvs = (m.texcoords.len() == 2 * n && n > 0)
            .then(|| m.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect::<Vec<_>>());
        let mesh = Mesh { name: model.name, positions, normals, uvs, triangles, ..Mesh::default() };
        if metres_per_unit.is_none()
            && let Some((lo, hi)) = mesh.bounds()
        {
            let extent = (hi - lo).max_element() as f64;
            if extent > SUSPICIOUS_EXTENT_M {
                let guess = detect_unit(extent);
                warnings.push(format!(
                    "object '{}' is {extent:.1} units across, {extent:.1} m if the file is in metres; \
                     it may be in {} (pass metres per unit {})",
                    mesh.name,
                    guess.name(),
                    guess.metres()
                ));
            }
        }
        meshes.push(mesh);
    }
    if meshes.is_empty() {
        return Err(FormatError::file(path, Kind::Structure, "no faces in the file"));
    }
    Ok(Loaded { value: meshes, warnings })
}

/// Maps a tobj error to a located [`FormatError`], finding the offending line when the
/// error names a record type.
fn map_tobj_error(e: tobj::LoadError, bytes: &[u8], path: &Path) -> FormatError {
    let kind = match e {
        tobj::LoadError::OpenFileFailed | tobj::LoadError::ReadError => Kind::Io,
        tobj::LoadError::FaceVertexOutOfBounds
        | tobj::LoadError::FaceTexCoordOutOfBounds
        | tobj::LoadError::FaceNormalOutOfBounds
        | tobj::LoadError::FaceColorOutOfBounds
        | tobj::LoadError::InvalidPolygon => Kind::Structure,
        _ => Kind::Syntax,
    };
    let location = match find_bad_line(bytes, Records::All) {
        Some(line) => Location::Line { line, column: None },
        None => Location::File,
    };
    FormatError::new(path, location, kind, format!("OBJ: {e}"))
}

/// Which records [`find_bad_line`] checks.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Records {
    /// Only that each face index names a vertex, UV or normal defined before it.
    FaceIndices,
    /// Also that `v`/`vt`/`vn` records hold the right number of finite numbers.
    All,
}

/// First line (1-based) whose face (or `l` record) refers to a vertex, UV or normal not
/// defined so far or,
/// with [`Records::All`], whose `v`/`vn`/`vt`/`f` record does not parse.
fn find_bad_line(bytes: &[u8], records: Records) -> Option<usize> {
    let text = String::from_utf8_lossy(bytes);
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    let floats_ok = |rest: &[&str], lo: usize, hi: usize| {
        records == Records::FaceIndices
            || (rest.len() >= lo && rest.len() <= hi && rest.iter().all(|t| t.parse::<f64>().is_ok_and(f64::is_finite)))
    };
    let index_ok = |tok: &str, count: i64| -> bool {
        if tok.is_empty() {
            return true;
        }
        match tok.parse::<i64>() {
            Ok(i) if i > 0 => i <= count,
            Ok(i) if i < 0 => i >= -count,
            Ok(_) => false,
            // Not a number: tobj reports that, located by the full scan.
            Err(_) => records == Records::FaceIndices,
        }
    };
    for (n, line) in text.lines().enumerate() {
        let mut tokens = line.split_whitespace();
        let Some(key) = tokens.next() else { continue };
        let rest: Vec<&str> = tokens.collect();
        let ok = match key {
            "v" => {
                v += 1;
                floats_ok(&rest, 3, 7)
            }
            "vt" => {
                vt += 1;
                floats_ok(&rest, 1, 3)
            }
            "vn" => {
                vn += 1;
                floats_ok(&rest, 3, 3)
            }
            // tobj reads `l` records as faces too (three or more corners make a polygon).
            "f" | "l" => {
                (rest.len() >= 3 || key == "l" || records == Records::FaceIndices)
                    && rest.iter().all(|corner| {
                        let mut parts = corner.split('/');
                        let pv = parts.next().unwrap_or("");
                        let pt = parts.next().unwrap_or("");
                        let pn = parts.next().unwrap_or("");
                        (!pv.is_empty() || records == Records::FaceIndices)
                            && index_ok(pv, v)
                            && index_ok(pt, vt)
                            && index_ok(pn, vn)
                    })
            }
            _ => true,
        };
        if !ok {
            return Some(n + 1);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const QUAD: &str =
        "o quad\nv 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3 4/4\n";

    #[test]
    fn quad_is_triangulated_with_computed_normals_and_flipped_uvs() {
        let loaded = read_obj(QUAD.as_bytes(), Path::new("quad.obj"), None).unwrap();
        assert_eq!(loaded.value.len(), 1);
        let mesh = &loaded.value[0];
        assert_eq!(mesh.name, "quad");
        assert_eq!(mesh.triangles.len(), 2);
        assert_eq!(mesh.positions.len(), 4);
        for n in &mesh.normals {
            assert!((*n - Vec3::Y).length() < 1e-6, "{n}");
        }
        let uvs = mesh.uvs.as_ref().unwrap();
        assert_eq!(uvs[0], Vec2::new(0.0, 1.0));
        assert_eq!(uvs[2], Vec2::new(1.0, 0.0));
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    }

    #[test]
    fn scale_applies_and_large_meshes_warn_about_units() {
        let big = QUAD.replace("v 1 0 0", "v 170 0 0");
        let scaled = read_obj(big.as_bytes(), Path::new("big.obj"), Some(0.01)).unwrap();
        assert!((scaled.value[0].positions[1].x - 1.7).abs() < 1e-6);
        assert!(scaled.warnings.is_empty());
        let unscaled = read_obj(big.as_bytes(), Path::new("big.obj"), None).unwrap();
        assert!(unscaled.warnings.iter().any(|w| w.contains("cm")), "{:?}", unscaled.warnings);
    }

    #[test]
    fn parse_errors_name_the_line() {
        let bad = "v 0 0 0\nv 1 0 0\nv 1 x 0\nf 1 2 3\n";
        let err = read_obj(bad.as_bytes(), Path::new("bad.obj"), None).unwrap_err();
        assert_eq!(err.location, Location::Line { line: 3, column: None }, "{err}");
        let out_of_range = "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n";
        let err = read_obj(out_of_range.as_bytes(), Path::new("oob.obj"), None).unwrap_err();
        assert_eq!(err.location, Location::Line { line: 4, column: None }, "{err}");
        assert_eq!(err.kind, Kind::Structure);
    }

    /// Found by the `obj_reader` fuzz target: relative indices before the first record
    /// reached tobj's unchecked index arithmetic (a panic with overflow checks, a wrong UV
    /// without); `i64::MIN` overflowed our own check's negation.
    #[test]
    fn relative_indices_before_the_start_are_located_errors() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n";
        for face in [
            "f 1/-50 2/1 3/1",
            "l 1 2/1 3/-50",
            "f 1//-9223372036854775808 2//1 3//1",
            "f -9223372036854775808 2 3",
            "f 1/-2 2/1 3/1",
        ] {
            let text = format!("{tri}{face}\n");
            let err = read_obj(text.as_bytes(), Path::new("rel.obj"), None).unwrap_err();
            assert_eq!(err.location, Location::Line { line: 6, column: None }, "{face}: {err}");
            assert_eq!(err.kind, Kind::Structure, "{face}");
        }
        // The same relative indices in range still load.
        let ok = format!("{tri}f -3/-1/-1 -2/-1/-1 -1/-1/-1\n");
        assert_eq!(read_obj(ok.as_bytes(), Path::new("rel.obj"), None).unwrap().value[0].triangles.len(), 1);
    }

    #[test]
    fn non_finite_texture_coordinates_are_refused() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nf 1/1 2/1 3/1\n";
        let err = read_obj(text.as_bytes(), Path::new("nan.obj"), None).unwrap_err();
        assert!(err.to_string().contains("non-finite texture coordinate"), "{err}");
    }
}
