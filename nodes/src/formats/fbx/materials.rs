//! FBX materials as kinegraph's (glTF's) metallic-roughness [`Material`]s, with their
//! textures' images, so a character read from FBX exports looking as it did.
//!
//! The values come from ufbx's PBR view of each material, which maps every FBX shading
//! model (legacy Lambert/Phong, 3ds Max/Maya/Arnold PBR) onto one set of maps:
//! - base colour: `base_color` × `base_factor`; when a texture is connected (and kept) the
//!   factor is white × `base_factor`, since DCCs let a connected texture replace the colour
//!   (glTF multiplies the two);
//! - metalness and roughness where ufbx has values (Phong: roughness = 1 − √shininess / 10,
//!   as Blender's importer does); legacy materials have no metalness and are dielectric
//!   (0); without a roughness the surface is taken as matte (1), what a Lambert material is;
//! - emission `emission_color` × `emission_factor` (a connected texture replaces the colour),
//!   above 1 carried by the emission strength;
//! - opacity: the PBR opacity, else a legacy material's `Opacity` property, else
//!   1 − `TransparencyFactor` × the mean transparent colour; below 1 the material blends;
//!   an opacity map becomes the base colour image's alpha (`channels.rs`) and blends;
//! - the normal map, and the ambient occlusion map (glTF reads its red channel, a grey
//!   map's value);
//! - a PBR material's (3ds Max, Arnold, Maya) roughness and metalness maps, combined into
//!   glTF's one metallic-roughness image (`channels.rs`; a glossiness map inverted); a
//!   connected map replaces the value, so the factors become 1. A legacy material's
//!   "roughness" texture is a shininess map and is not used.
//!
//! Colours are taken as linear, as stored, which is what Blender's importer does. Other
//! textures (bump, specular, layered extras) are left out with a warning naming them.
//!
//! Texture images are the FBX's embedded bytes, else a file beside the FBX (its relative
//! name, then the bare file name of its relative or absolute name: FBX files often carry
//! absolute paths of the machine that wrote them). Like the glTF reader, files outside the
//! FBX's folder are not read. A texture found nowhere, or neither PNG nor JPEG (all glTF
//! takes), is left out with a warning: FBX files commonly point at textures that did not
//! travel with them, and the mesh is still worth loading.

use std::collections::HashMap;
use std::path::{Component, Path};
use std::sync::Arc;

use super::channels::{self, Channel};
use crate::model::{AlphaMode, Image, Material, Sampler, Texture};

/// Opacity below which a material is drawn alpha-blended.
const OPAQUE: f64 = 0.999;

/// Converts ufbx materials once each, sharing images between them.
pub(super) struct MaterialReader<'a> {
    /// The FBX file, named in warnings and whose folder holds external textures.
    file: &'a Path,
    /// Converted materials by ufbx element id.
    materials: HashMap<u32, Material>,
    /// Per ufbx texture element id: its image, or why it was left out.
    textures: HashMap<u32, Result<Arc<Image>, String>>,
}

impl<'a> MaterialReader<'a> {
    pub(super) fn new(file: &'a Path) -> Self {
        MaterialReader { file, materials: HashMap::new(), textures: HashMap::new() }
    }

    /// `material` as a [`Material`]; the first time, warnings say what was left out.
    pub(super) fn material(&mut self, material: &ufbx::Material, warnings: &mut Vec<String>) -> Material {
        if let Some(m) = self.materials.get(&material.element.element_id) {
            return m.clone();
        }
        let converted = self.convert(material, warnings);
        self.materials.insert(material.element.element_id, converted.clone());
        converted
    }

    fn convert(&mut self, material: &ufbx::Material, warnings: &mut Vec<String>) -> Material {
        let name = material.element.name.to_string();
        let pbr = &material.pbr;
        let features = &material.features;
        // With glossiness in place of roughness ufbx moves the map (and its value) there.
        let glossy = features.roughness_as_glossiness.enabled;
        let roughness_map = if glossy { &pbr.glossiness } else { &pbr.roughness };
        let mut kept = Vec::new();
        let mut texture = |map: &ufbx::MaterialMap, slot: &str, w: &mut Vec<String>| {
            let t = map.texture.as_ref().filter(|_| map.texture_enabled)?;
            kept.push(t.element.element_id);
            self.texture(t, &name, slot, w)
        };
        let base_color_texture = texture(&pbr.base_color, "base colour", warnings);
        let normal_texture = texture(&pbr.normal_map, "normal map", warnings);
        let emissive_texture = texture(&pbr.emission_color, "emission", warnings);
        let occlusion_texture = texture(&pbr.ambient_occlusion, "ambient occlusion", warnings);
        let opacity_texture = texture(&pbr.opacity, "opacity", warnings);
        // A legacy (Lambert/Phong) material's "roughness" texture is a shininess map: only
        // PBR shading models have roughness and metalness maps.
        let (roughness_texture, metalness_texture) = if features.pbr.enabled {
            (texture(roughness_map, "roughness", warnings), texture(&pbr.metalness, "metalness", warnings))
        } else {
            (None, None)
        };
        for t in material.textures.iter() {
            if !kept.contains(&t.texture.element.element_id) {
                warnings.push(format!(
                    "{}: material '{name}': texture '{}' on {} is not kept (base colour, opacity, normal, \
                     emission, occlusion, and a PBR material's roughness and metalness are)",
                    self.file.display(),
                    file_label(&t.texture),
                    t.material_prop
                ));
            }
        }

        let base_factor = pbr.base_factor.value_vec4.x;
        // A texture left out gives way to the colour the material states.
        let base = if base_color_texture.is_some() { [1.0; 3] } else { rgb(&pbr.base_color) };
        let opacity = if opacity_texture.is_some() { 1.0 } else { opacity(material).clamp(0.0, 1.0) };
        let emission_factor = pbr.emission_factor.value_vec4.x;
        let emission = if emissive_texture.is_some() { [1.0; 3] } else { rgb(&pbr.emission_color) };
        let emission = emission.map(|c| (c * emission_factor).max(0.0));
        let strongest = emission.iter().copied().fold(1.0, f64::max);
        let roughness = match (glossy, pbr.glossiness.has_value, pbr.roughness.has_value) {
            (true, true, _) => 1.0 - pbr.glossiness.value_vec4.x,
            (false, _, true) => pbr.roughness.value_vec4.x,
            _ => 1.0,
        };
        let metallic = if pbr.metalness.has_value { pbr.metalness.value_vec4.x } else { 0.0 };
        let unit = |v: f64| if v.is_finite() { v.clamp(0.0, 1.0) as f32 } else { 0.0 };
        let [r, g, b] = base.map(|c| unit(c * base_factor));
        let mut combine = |what: &str, combined: Result<Image, String>, sampler: Sampler| match combined {
            Ok(image) => Some(Texture { image: Arc::new(image), sampler }),
            Err(why) => {
                warnings.push(format!("{}: material '{name}': {what} left out: {why}", self.file.display()));
                None
            }
        };
        // A connected map replaces the value it stands for (as in the DCCs): the combined
        // image carries the values, the factors are 1.
        let (metallic_roughness_texture, metallic, roughness) = match (&roughness_texture, &metalness_texture) {
            (None, None) => (None, metallic, roughness),
            (r, m) => {
                let combined = channels::metallic_roughness(
                    format!("{name}_metallic_roughness.png"),
                    channel(r.as_ref(), glossy, roughness),
                    channel(m.as_ref(), false, metallic),
                );
                let sampler = r.as_ref().or(m.as_ref()).map(|t| t.sampler).unwrap_or_default();
                let packed = combine("the roughness and metalness maps, combined,", combined, sampler);
                if packed.is_some() { (packed, 1.0, 1.0) } else { (None, metallic, roughness) }
            }
        };
        let base_color_texture = match &opacity_texture {
            None => base_color_texture,
            Some(alpha) => {
                let combined = channels::with_opacity(
                    format!("{name}_base_color_opacity.png"),
                    base_color_texture.as_ref().map(|t| &*t.image),
                    &alpha.image,
                );
                let sampler = base_color_texture.as_ref().unwrap_or(alpha).sampler;
                combine("the opacity map, as the base colour's alpha,", combined, sampler).or(base_color_texture)
            }
        };
        Material {
            name: Some(name.clone()),
            base_color_factor: [r, g, b, unit(opacity)],
            base_color_texture,
            metallic_factor: unit(metallic),
            roughness_factor: unit(roughness),
            metallic_roughness_texture,
            normal_texture,
            occlusion_texture,
            emissive_factor: emission.map(|c| unit(c / strongest)),
            emissive_texture,
            emissive_strength: if strongest.is_finite() { strongest as f32 } else { 1.0 },
            alpha_mode: if opacity < OPAQUE || opacity_texture.is_some() {
                AlphaMode::Blend
            } else {
                AlphaMode::Opaque
            },
            ..Material::default()
        }
    }

    /// The texture `t` used as `slot` of material `material`, or `None` with a warning.
    fn texture(
        &mut self,
        t: &ufbx::Texture,
        material: &str,
        slot: &str,
        warnings: &mut Vec<String>,
    ) -> Option<Texture> {
        // A layered texture draws its file textures blended; only the first is kept.
        let file_texture = t.file_textures.first().map_or(t, |f| &**f);
        if t.file_textures.len() > 1 {
            warnings.push(format!(
                "{}: material '{material}': {slot} texture '{}' is layered; only its first layer '{}' is kept",
                self.file.display(),
                t.element.name,
                file_label(file_texture)
            ));
        }
        if file_texture.has_uv_transform {
            warnings.push(format!(
                "{}: material '{material}': {slot} texture '{}' has a UV transform, which is not applied",
                self.file.display(),
                file_label(file_texture)
            ));
        }
        let id = file_texture.element.element_id;
        let image = match self.textures.get(&id) {
            Some(read) => read.clone(),
            None => {
                let folder = self.file.parent().unwrap_or(Path::new(""));
                // Texture elements that hold the same image (one file, two materials) share it.
                let read = texture_image(&TextureSource::of(file_texture), folder).map(|image| {
                    let same = self.textures.values().flatten().find(|i| i.bytes == image.bytes);
                    same.cloned().unwrap_or_else(|| Arc::new(image))
                });
                self.textures.insert(id, read.clone());
                read
            }
        };
        let image = match image {
            Ok(image) => image,
            Err(why) => {
                warnings.push(format!(
                    "{}: material '{material}': {slot} texture '{}' left out: {why}",
                    self.file.display(),
                    file_label(file_texture)
                ));
                return None;
            }
        };
        let wrap = |w: ufbx::WrapMode| match w {
            ufbx::WrapMode::Repeat => 10_497,
            ufbx::WrapMode::Clamp => 33_071,
        };
        let sampler =
            Sampler { wrap_s: wrap(file_texture.wrap_u), wrap_t: wrap(file_texture.wrap_v), ..Sampler::default() };
        Some(Texture { image, sampler })
    }
}

/// The channel a map's texture gives, or its value where it has none.
fn channel(texture: Option<&Texture>, invert: bool, value: f64) -> Channel<'_> {
    match texture {
        Some(t) => Channel::Map { image: &t.image, invert },
        None => Channel::Constant(value),
    }
}

/// A map's colour (RGB) as stored.
fn rgb(map: &ufbx::MaterialMap) -> [f64; 3] {
    [map.value_vec4.x, map.value_vec4.y, map.value_vec4.z]
}

/// How opaque `material` is, 0–1 (see the module doc).
fn opacity(material: &ufbx::Material) -> f64 {
    if material.pbr.opacity.has_value {
        return material.pbr.opacity.value_vec4.x;
    }
    if let Some(p) = ufbx::find_prop(&material.element.props, "Opacity") {
        return p.value_vec4.x;
    }
    let fbx = &material.fbx;
    let [r, g, b] = rgb(&fbx.transparency_color);
    1.0 - fbx.transparency_factor.value_vec4.x * (r + g + b) / 3.0
}

/// The name a warning gives a texture: its file name as the FBX states it, else its own.
fn file_label(t: &ufbx::Texture) -> String {
    [&t.relative_filename, &t.absolute_filename, &t.element.name]
        .into_iter()
        .find(|s| !s.is_empty())
        .map_or_else(String::new, |s| s.to_string())
}

/// Where a texture's encoded bytes may be.
#[derive(Clone, Copy, Debug)]
struct TextureSource<'a> {
    /// The image's name: the bare file name, else the texture's own.
    name: &'a str,
    /// Bytes embedded in the FBX (empty when none).
    embedded: &'a [u8],
    /// The file name relative to the FBX, as stated.
    relative: &'a str,
    /// The absolute file name, as stated (often of another machine).
    absolute: &'a str,
}

impl<'a> TextureSource<'a> {
    fn of(t: &'a ufbx::Texture) -> Self {
        let embedded: &[u8] =
            if t.content.is_empty() { t.video.as_ref().map_or(&[], |v| &v.content) } else { &t.content };
        let (relative, absolute): (&str, &str) = (&t.relative_filename, &t.absolute_filename);
        let name = [bare_name(relative), bare_name(absolute), &t.element.name].into_iter().find(|n| !n.is_empty());
        TextureSource { name: name.unwrap_or_default(), embedded, relative, absolute }
    }
}

/// The image of `source`: its embedded bytes, else the first file found in `folder` (the
/// FBX's) under the relative name (`\` read as `/`) or the bare file name of either name;
/// `Err` says why there is none.
fn texture_image(source: &TextureSource<'_>, folder: &Path) -> Result<Image, String> {
    let (bytes, from) = if source.embedded.is_empty() {
        // Files written on Windows name folders with `\`.
        let relative = source.relative.replace('\\', "/");
        let mut candidates = vec![relative.as_str(), bare_name(source.relative), bare_name(source.absolute)];
        candidates.retain(|c| !c.is_empty());
        candidates.dedup();
        if candidates.is_empty() {
            return Err("not embedded, and no file name".into());
        }
        let mut tried = Vec::new();
        let found = candidates.iter().find_map(|name| match file_in(folder, name) {
            Ok(bytes) => Some((bytes, format!("file '{name}' beside the FBX"))),
            Err(why) => {
                tried.push(why);
                None
            }
        });
        found.ok_or_else(|| format!("not embedded, and no file beside the FBX ({})", tried.join("; ")))?
    } else {
        (source.embedded.to_vec(), "embedded content".to_owned())
    };
    let Some(mime) = Image::sniff_mime(&bytes) else {
        return Err(format!("its {from} is neither PNG nor JPEG (glTF takes only those)"));
    };
    let name = Some(source.name).filter(|n| !n.is_empty()).map(str::to_owned);
    Ok(Image { name, mime_type: mime.to_owned(), bytes })
}

/// The last component of a file name written with `/` or `\\` separators.
fn bare_name(name: &str) -> &str {
    name.rsplit(['/', '\\']).next().unwrap_or(name)
}

/// The file `name` in `folder`, refused when it would leave the folder (absolute, `..`, or a
/// link pointing out), as the glTF reader refuses.
fn file_in(folder: &Path, name: &str) -> Result<Vec<u8>, String> {
    let relative = Path::new(name);
    if relative.is_absolute() || relative.components().any(|c| !matches!(c, Component::Normal(_) | Component::CurDir)) {
        return Err(format!("'{name}' leaves the FBX's folder"));
    }
    let folder = if folder.as_os_str().is_empty() { Path::new(".") } else { folder };
    let full = folder.join(relative);
    let io = |e: std::io::Error| format!("'{}': {e}", full.display());
    let real_folder = std::fs::canonicalize(folder).map_err(io)?;
    let real = std::fs::canonicalize(&full).map_err(io)?;
    if !real.starts_with(&real_folder) {
        return Err(format!("'{name}' links to {}, outside the FBX's folder", real.display()));
    }
    std::fs::read(&real).map_err(io)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const JPEG: &[u8] = &[0xFF, 0xD8, 0xFF, 0xE0, 0, 0x10, b'J', b'F', b'I', b'F', 0xFF, 0xD9];

    fn source<'a>(embedded: &'a [u8], relative: &'a str, absolute: &'a str) -> TextureSource<'a> {
        TextureSource { name: "tex", embedded, relative, absolute }
    }

    #[test]
    fn embedded_bytes_come_first_and_must_be_png_or_jpeg() {
        let image = texture_image(&source(JPEG, "no/such.jpg", ""), Path::new("/nonexistent")).unwrap();
        assert_eq!((image.mime_type.as_str(), image.bytes.as_slice()), ("image/jpeg", JPEG));
        let err = texture_image(&source(b"DDS \x7c\0\0\0", "", ""), Path::new(".")).unwrap_err();
        assert_eq!(err, "its embedded content is neither PNG nor JPEG (glTF takes only those)");
    }

    #[test]
    fn files_are_looked_for_beside_the_fbx_only() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("skin.jpg"), JPEG).unwrap();
        std::fs::write(dir.path().join("notes.txt"), b"hello").unwrap();
        // Another machine's absolute path: found by its bare file name.
        let image = texture_image(&source(&[], "", r"C:\Users\artist\maps\skin.jpg"), dir.path()).unwrap();
        assert_eq!(image.bytes, JPEG);
        // A relative name that leaves the folder is not followed, but its file name is.
        let image = texture_image(&source(&[], "../../elsewhere/skin.jpg", ""), dir.path()).unwrap();
        assert_eq!(image.bytes, JPEG);
        let err = texture_image(&source(&[], "textures/missing.png", "/abs/missing.png"), dir.path()).unwrap_err();
        assert!(err.starts_with("not embedded, and no file beside the FBX ("), "{err}");
        assert!(err.contains("textures/missing.png") && err.contains("missing.png': "), "{err}");
        let err = texture_image(&source(&[], "notes.txt", ""), dir.path()).unwrap_err();
        assert_eq!(err, "its file 'notes.txt' beside the FBX is neither PNG nor JPEG (glTF takes only those)");
        assert_eq!(texture_image(&source(&[], "", ""), dir.path()).unwrap_err(), "not embedded, and no file name");
    }
}
