//! Turning file bytes into a validated glTF JSON tree plus resolved buffers.
//!
//! Steps: 1. a `glTF` magic means GLB: split header, JSON chunk and BIN chunk, checking
//! every announced length against the bytes present; otherwise the bytes are JSON;
//! 2. deserialize with gltf-json; 3. run gltf-json's validation (index ranges, missing
//! fields) and report the first problem with its JSON path; 4. resolve each buffer: the
//! GLB BIN chunk, a `data:` URI (base64) or a file relative to the glTF file (absolute
//! paths, `..`, URL schemes and links that resolve outside the file's folder are refused;
//! images are resolved the same way, but only when materials are read); 5. check each
//! buffer holds `byteLength` bytes.

use std::path::{Component, Path};

use base64::Engine as _;
use gltf_json::validation::{Error as ValidationError, Validate};

use crate::formats::error::FormatErrorKind as Kind;

use super::ReadError;

const GLB_MAGIC: &[u8; 4] = b"glTF";
const CHUNK_JSON: u32 = 0x4E4F_534A;
const CHUNK_BIN: u32 = 0x004E_4942;

/// A parsed glTF document with its buffers' bytes.
pub(crate) struct Document {
    /// The JSON tree.
    pub root: gltf_json::Root,
    /// Bytes of every buffer, by buffer index.
    pub buffers: Vec<Vec<u8>>,
    /// Oddities that did not stop loading.
    pub warnings: Vec<String>,
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at + 4)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB into its JSON and optional BIN chunk.
fn split_glb(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), ReadError> {
    let truncated = |what: &str| ReadError::file(Kind::Truncated, format!("GLB truncated: {what}"));
    let version = u32_at(bytes, 4).ok_or_else(|| truncated("no complete 12-byte header"))?;
    let length = u32_at(bytes, 8).ok_or_else(|| truncated("no complete 12-byte header"))? as usize;
    if version != 2 {
        return Err(ReadError::file(Kind::Unsupported, format!("GLB version {version}; only glTF 2.0 is supported")));
    }
    if length > bytes.len() {
        return Err(truncated(&format!("header announces {length} bytes, file has {}", bytes.len())));
    }
    let bytes = &bytes[..length];
    let mut at = 12;
    let mut json = None;
    let mut bin = None;
    while at < bytes.len() {
        let chunk_length = u32_at(bytes, at).ok_or_else(|| truncated("incomplete chunk header"))? as usize;
        let chunk_type = u32_at(bytes, at + 4).ok_or_else(|| truncated("incomplete chunk header"))?;
        let start = at + 8;
        let end = start
            .checked_add(chunk_length)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| truncated(&format!("chunk at byte {at} announces {chunk_length} bytes past the end")))?;
        match chunk_type {
            CHUNK_JSON if json.is_none() => json = Some(&bytes[start..end]),
            CHUNK_BIN if json.is_some() && bin.is_none() => bin = Some(&bytes[start..end]),
            _ => {}
        }
        at = end;
    }
    let json = json.ok_or_else(|| ReadError::file(Kind::Structure, "GLB has no JSON chunk"))?;
    Ok((json, bin))
}

/// Converts gltf-json's `accessors[3].bufferView` into `/accessors/3/bufferView`.
fn json_pointer(path: &str) -> String {
    let mut out = String::with_capacity(path.len() + 2);
    let path = path.split(" = ").next().unwrap_or(path);
    for c in path.chars() {
        match c {
            '.' | '[' => out.push('/'),
            ']' | '"' => {}
            c => out.push(c),
        }
    }
    if !out.starts_with('/') {
        out.insert(0, '/');
    }
    out
}

/// Decodes a `data:` URI's payload; `None` when it is not base64.
pub(crate) fn decode_data_uri(uri: &str) -> Option<Result<Vec<u8>, base64::DecodeError>> {
    let rest = uri.strip_prefix("data:")?;
    let (meta, payload) = rest.split_once(',')?;
    if !meta.ends_with(";base64") {
        return None;
    }
    Some(base64::engine::general_purpose::STANDARD.decode(payload.trim()))
}

/// Percent-decodes a relative URI into a path string.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && let Some(h) = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(h);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Reads the file `uri` names relative to `file` (a buffer or an image, `what`); `at` is
/// the JSON path of the URI.
pub(crate) fn load_external(uri: &str, at: &str, what: &str, file: &Path) -> Result<Vec<u8>, ReadError> {
    let at = at.to_owned();
    if uri.contains("://") || uri.starts_with("file:") {
        return Err(ReadError::new(
            at,
            Kind::Unsupported,
            format!("{what} URI '{uri}' is a URL; only relative file names are read"),
        ));
    }
    let relative = percent_decode(uri);
    let relative_path = Path::new(&relative);
    if relative_path.is_absolute()
        || relative_path.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir))
    {
        return Err(ReadError::new(
            at,
            Kind::Unsupported,
            format!("{what} URI '{uri}' leaves the glTF file's folder (absolute or '..'); refusing to read it"),
        ));
    }
    let dir = match file.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let full = dir.join(relative_path);
    let io = |e: std::io::Error| ReadError::new(at.clone(), Kind::Io, format!("{what} file '{}': {e}", full.display()));
    // Links inside the folder may point anywhere: compare where the file really is.
    let real_dir = std::fs::canonicalize(dir).map_err(io)?;
    let real = std::fs::canonicalize(&full).map_err(io)?;
    if !real.starts_with(&real_dir) {
        return Err(ReadError::new(
            at.clone(),
            Kind::Unsupported,
            format!(
                "{what} URI '{uri}' resolves through a link to {}, outside the glTF file's folder; refusing to read it",
                real.display()
            ),
        ));
    }
    std::fs::read(&real).map_err(io)
}

/// Every mesh primitive's attributes name an accessor that exists. gltf-json 1.4.1's own
/// validation reads the POSITION accessor by its index before checking that index, so an
/// out-of-range one panicked (found by the `gltf_loader` fuzz target); checked here first.
fn check_attribute_indices(root: &gltf_json::Root) -> Result<(), ReadError> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, accessor) in &primitive.attributes {
                if accessor.value() >= root.accessors.len() {
                    let name = match semantic {
                        gltf_json::validation::Checked::Valid(s) => s.to_string(),
                        gltf_json::validation::Checked::Invalid => "?".into(),
                    };
                    return Err(ReadError::new(
                        format!("/meshes/{m}/primitives/{p}/attributes/{name}"),
                        Kind::Structure,
                        "index out of range",
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Parses `bytes` (GLB or JSON glTF); `file` resolves external buffers.
pub(crate) fn load(bytes: &[u8], file: &Path) -> Result<Document, ReadError> {
    let (json, bin) = if bytes.starts_with(GLB_MAGIC) {
        split_glb(bytes)?
    } else if bytes.len() >= 4 && bytes[..4].eq_ignore_ascii_case(GLB_MAGIC) {
        return Err(ReadError::file(Kind::Syntax, "bad GLB magic"));
    } else {
        (bytes, None)
    };
    let json = json.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(json);
    let root: gltf_json::Root = serde_json::from_slice(json).map_err(|e| {
        let kind = if e.is_eof() { Kind::Truncated } else { Kind::Syntax };
        ReadError::file(kind, format!("JSON line {} column {}: {e}", e.line(), e.column()))
    })?;

    check_attribute_indices(&root)?;
    let mut warnings = Vec::new();
    let mut first_error: Option<ReadError> = None;
    root.validate(&root, gltf_json::Path::new, &mut |path: &dyn Fn() -> gltf_json::Path, err: ValidationError| {
        let p = path();
        if err == ValidationError::Unsupported && p.as_str().starts_with("extensionsRequired") {
            warnings.push(format!("required extension not understood, ignored: {p}"));
            return;
        }
        // Many exporters omit POSITION bounds; kinegraph does not need them.
        if err == ValidationError::Missing
            && (p.as_str().ends_with("POSITION\"].min") || p.as_str().ends_with("POSITION\"].max"))
        {
            if !warnings.iter().any(|w| w.starts_with("POSITION accessor")) {
                warnings.push(format!("POSITION accessor without min/max ({})", json_pointer(p.as_str())));
            }
            return;
        }
        if first_error.is_none() {
            let kind = match err {
                ValidationError::IndexOutOfBounds | ValidationError::Missing => Kind::Structure,
                ValidationError::Invalid | ValidationError::Oversize => Kind::Value,
                ValidationError::Unsupported => Kind::Unsupported,
            };
            let message = match err {
                ValidationError::IndexOutOfBounds => "index out of range",
                ValidationError::Invalid => "invalid value",
                ValidationError::Missing => "required value missing",
                ValidationError::Oversize => "size exceeds system limits",
                ValidationError::Unsupported => "unsupported",
            };
            first_error = Some(ReadError::new(json_pointer(p.as_str()), kind, message));
        }
    });
    if let Some(e) = first_error {
        return Err(e);
    }

    let mut buffers = Vec::with_capacity(root.buffers.len());
    for (index, buffer) in root.buffers.iter().enumerate() {
        let data = match &buffer.uri {
            None => match (index, bin) {
                (0, Some(bin)) => bin.to_vec(),
                _ => {
                    return Err(ReadError::new(
                        format!("/buffers/{index}"),
                        Kind::Structure,
                        "buffer has no uri and is not the GLB binary chunk",
                    ));
                }
            },
            Some(uri) => match decode_data_uri(uri) {
                Some(Ok(data)) => data,
                Some(Err(e)) => {
                    return Err(ReadError::new(
                        format!("/buffers/{index}/uri"),
                        Kind::Syntax,
                        format!("bad base64 data URI: {e}"),
                    ));
                }
                None if uri.starts_with("data:") => {
                    return Err(ReadError::new(
                        format!("/buffers/{index}/uri"),
                        Kind::Unsupported,
                        "data URI is not base64",
                    ));
                }
                None => load_external(uri, &format!("/buffers/{index}/uri"), "buffer", file)?,
            },
        };
        if (data.len() as u64) < buffer.byte_length.0 {
            return Err(ReadError::new(
                format!("/buffers/{index}/byteLength"),
                Kind::Truncated,
                format!("buffer announces {} bytes but holds {}", buffer.byte_length.0, data.len()),
            ));
        }
        buffers.push(data);
    }
    Ok(Document { root, buffers, warnings })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_paths_become_json_pointers() {
        assert_eq!(json_pointer("accessors[3].bufferView"), "/accessors/3/bufferView");
        assert_eq!(
            json_pointer("meshes[0].primitives[1].attributes[\"POSITION\"]"),
            "/meshes/0/primitives/1/attributes/POSITION"
        );
    }

    #[cfg(unix)]
    #[test]
    fn a_buffer_linked_out_of_the_folder_is_refused_and_one_inside_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let secret = dir.path().join("secret.bin");
        std::fs::write(&secret, b"other file's bytes").unwrap();
        let model_dir = dir.path().join("model");
        std::fs::create_dir_all(model_dir.join("sub")).unwrap();
        std::fs::write(model_dir.join("sub/real.bin"), b"mesh").unwrap();
        std::os::unix::fs::symlink(&secret, model_dir.join("data.bin")).unwrap();
        std::os::unix::fs::symlink(dir.path(), model_dir.join("up")).unwrap();
        std::os::unix::fs::symlink("sub/real.bin", model_dir.join("inside.bin")).unwrap();
        let file = model_dir.join("model.gltf");
        for uri in ["data.bin", "up/secret.bin"] {
            let err = load_external(uri, "/buffers/1/uri", "buffer", &file).unwrap_err();
            assert_eq!(err.path, "/buffers/1/uri", "{uri}");
            assert!(err.message.contains(uri) && err.message.contains("outside"), "{}", err.message);
        }
        assert_eq!(load_external("inside.bin", "/buffers/0/uri", "buffer", &file).unwrap(), b"mesh");
        assert_eq!(load_external("sub/real.bin", "/buffers/0/uri", "buffer", &file).unwrap(), b"mesh");
    }

    #[test]
    fn external_buffers_may_not_climb_out_or_be_absolute() {
        let file = Path::new("/tmp/model.gltf");
        for uri in ["../secret.bin", "/etc/passwd", "a/../../b.bin", "http://example.com/a.bin"] {
            let err = load_external(uri, "/buffers/2/uri", "buffer", file).unwrap_err();
            assert_eq!(err.path, "/buffers/2/uri", "{uri}");
            assert!(err.message.contains(uri), "{}", err.message);
        }
    }
}
