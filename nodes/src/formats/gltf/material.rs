//! glTF materials both ways: reading the file's metallic-roughness materials with their
//! textures, samplers and images (GLB buffer views, `data:` URIs or files beside the
//! glTF), and writing them into a GLB with every image embedded once in the binary chunk.
//!
//! Only what viewers draw from TEXCOORD_0 is kept: a texture read through another UV set,
//! an image that is neither PNG nor JPEG, and material extensions other than
//! KHR_materials_specular (factors) and KHR_materials_emissive_strength are dropped with a
//! warning. A missing image file is an error naming it: a character exported without its
//! texture would look different from its source, which `character.load` promises not to do.

use std::path::Path;
use std::sync::Arc;

use gltf_json as json;
use json::validation::Checked::{self, Valid};

use crate::formats::error::FormatErrorKind as Kind;
use crate::model::{AlphaMode, Image, Material, Sampler, Specular, Texture};

use super::ReadError;
use super::accessor::view_bytes;
use super::builder::GlbBuilder;
use super::document::{Document, decode_data_uri, load_external};

const KHR_SPECULAR: &str = "KHR_materials_specular";
const KHR_EMISSIVE_STRENGTH: &str = "KHR_materials_emissive_strength";

/// Reads every material of the file, by material index. `file` locates external images.
pub(crate) fn read_materials(
    doc: &Document,
    file: &Path,
    warnings: &mut Vec<String>,
) -> Result<Vec<Material>, ReadError> {
    let root = &doc.root;
    for name in &root.extensions_used {
        let material_related = ["KHR_materials_", "KHR_texture_", "EXT_texture_"].iter().any(|p| name.starts_with(p));
        if material_related && name != KHR_SPECULAR && name != KHR_EMISSIVE_STRENGTH {
            warnings.push(format!("material extension {name} is not kept; materials are read without it"));
        }
    }
    let mut reader = TextureReader { doc, file, images: vec![None; root.images.len()] };
    let mut out = Vec::with_capacity(root.materials.len());
    for (i, m) in root.materials.iter().enumerate() {
        let at = format!("/materials/{i}");
        let pbr = &m.pbr_metallic_roughness;
        let name = m.name.clone();
        let label = name.clone().unwrap_or_else(|| format!("material {i}"));
        let mut texture = |index: Option<(usize, u32)>, slot: &str, w: &mut Vec<String>| match index {
            Some((t, tex_coord)) => reader.texture(t, tex_coord, &format!("{at}/{slot}"), &label, w),
            None => Ok(None),
        };
        let info = |i: &Option<json::texture::Info>| i.as_ref().map(|i| (i.index.value(), i.tex_coord));
        let base_color_texture = texture(info(&pbr.base_color_texture), "baseColorTexture", warnings)?;
        let metallic_roughness_texture =
            texture(info(&pbr.metallic_roughness_texture), "metallicRoughnessTexture", warnings)?;
        let normal = m.normal_texture.as_ref().map(|n| (n.index.value(), n.tex_coord));
        let normal_texture = texture(normal, "normalTexture", warnings)?;
        let occlusion = m.occlusion_texture.as_ref().map(|o| (o.index.value(), o.tex_coord));
        let occlusion_texture = texture(occlusion, "occlusionTexture", warnings)?;
        let emissive_texture = texture(info(&m.emissive_texture), "emissiveTexture", warnings)?;
        let extensions = m.extensions.as_ref();
        let specular = extensions.and_then(|e| e.specular.as_ref()).map(|s| {
            if s.specular_texture.is_some() || s.specular_color_texture.is_some() {
                warnings.push(format!("material '{label}': specular textures are not kept (factors are)"));
            }
            Specular { factor: s.specular_factor.0, color_factor: s.specular_color_factor.0 }
        });
        let alpha_mode = match m.alpha_mode {
            Valid(json::material::AlphaMode::Mask) => AlphaMode::Mask { cutoff: m.alpha_cutoff.map_or(0.5, |c| c.0) },
            Valid(json::material::AlphaMode::Blend) => AlphaMode::Blend,
            _ => AlphaMode::Opaque,
        };
        let material = Material {
            name,
            base_color_factor: pbr.base_color_factor.0,
            base_color_texture,
            metallic_factor: pbr.metallic_factor.0,
            roughness_factor: pbr.roughness_factor.0,
            metallic_roughness_texture,
            normal_texture,
            normal_scale: m.normal_texture.as_ref().map_or(1.0, |n| n.scale),
            occlusion_texture,
            occlusion_strength: m.occlusion_texture.as_ref().map_or(1.0, |o| o.strength.0),
            emissive_factor: m.emissive_factor.0,
            emissive_texture,
            emissive_strength: extensions
                .and_then(|e| e.emissive_strength.as_ref())
                .map_or(1.0, |s| s.emissive_strength.0),
            specular,
            alpha_mode,
            double_sided: m.double_sided,
        };
        let cutoff = match material.alpha_mode {
            AlphaMode::Mask { cutoff } => cutoff,
            _ => 0.5,
        };
        let scalars = [
            cutoff,
            material.metallic_factor,
            material.roughness_factor,
            material.normal_scale,
            material.occlusion_strength,
            material.emissive_strength,
        ];
        let mut factors = material.base_color_factor.iter().chain(&material.emissive_factor).chain(&scalars);
        if factors.any(|v| !v.is_finite()) {
            return Err(ReadError::new(at, Kind::Value, "a material factor is not a finite number"));
        }
        out.push(material);
    }
    Ok(out)
}

/// Resolves textures and reads each image once.
struct TextureReader<'a> {
    doc: &'a Document,
    file: &'a Path,
    /// Per image index: the image once read (`Some(None)`: not PNG or JPEG).
    images: Vec<Option<Option<Arc<Image>>>>,
}

impl TextureReader<'_> {
    /// Texture `index` of the file used through UV set `tex_coord` at JSON path `at`.
    fn texture(
        &mut self,
        index: usize,
        tex_coord: u32,
        at: &str,
        material: &str,
        warnings: &mut Vec<String>,
    ) -> Result<Option<Texture>, ReadError> {
        let root = &self.doc.root;
        let Some(texture) = root.textures.get(index) else {
            return Err(ReadError::new(
                format!("{at}/index"),
                Kind::Structure,
                format!("texture {index} does not exist"),
            ));
        };
        if tex_coord != 0 {
            warnings.push(format!(
                "material '{material}': {at} reads UV set {tex_coord}; only TEXCOORD_0 is kept, so the texture is dropped"
            ));
            return Ok(None);
        }
        let sampler = match texture.sampler {
            None => Sampler::default(),
            Some(s) => {
                let Some(s) = root.samplers.get(s.value()) else {
                    return Err(ReadError::new(
                        format!("/textures/{index}/sampler"),
                        Kind::Structure,
                        format!("sampler {} does not exist", s.value()),
                    ));
                };
                let gl = |c: &Checked<json::texture::WrappingMode>| match c {
                    Valid(w) => w.as_gl_enum(),
                    Checked::Invalid => Sampler::default().wrap_s,
                };
                Sampler {
                    mag_filter: s.mag_filter.as_ref().and_then(|f| match f {
                        Valid(f) => Some(f.as_gl_enum()),
                        Checked::Invalid => None,
                    }),
                    min_filter: s.min_filter.as_ref().and_then(|f| match f {
                        Valid(f) => Some(f.as_gl_enum()),
                        Checked::Invalid => None,
                    }),
                    wrap_s: gl(&s.wrap_s),
                    wrap_t: gl(&s.wrap_t),
                }
            }
        };
        let source = texture.source.value();
        let image = match self.images.get(source) {
            None => {
                return Err(ReadError::new(
                    format!("/textures/{index}/source"),
                    Kind::Structure,
                    format!("image {source} does not exist"),
                ));
            }
            Some(Some(read)) => read.clone(),
            Some(None) => {
                let read = self.read_image(source, warnings)?;
                self.images[source] = Some(read.clone());
                read
            }
        };
        Ok(image.map(|image| Texture { image, sampler }))
    }

    /// Image `k`'s bytes from its buffer view, data URI or file; `None` (with a warning)
    /// when they are neither PNG nor JPEG.
    fn read_image(&self, k: usize, warnings: &mut Vec<String>) -> Result<Option<Arc<Image>>, ReadError> {
        let image = &self.doc.root.images[k];
        let at = format!("/images/{k}");
        let bytes = match (&image.buffer_view, &image.uri) {
            (Some(view), _) => view_bytes(self.doc, view.value(), &format!("{at}/bufferView"))?.to_vec(),
            (None, Some(uri)) => match decode_data_uri(uri) {
                Some(Ok(bytes)) => bytes,
                Some(Err(e)) => {
                    return Err(ReadError::new(format!("{at}/uri"), Kind::Syntax, format!("bad base64 data URI: {e}")));
                }
                None if uri.starts_with("data:") => {
                    return Err(ReadError::new(format!("{at}/uri"), Kind::Unsupported, "data URI is not base64"));
                }
                None => load_external(uri, &format!("{at}/uri"), "image", self.file)?,
            },
            (None, None) => {
                return Err(ReadError::new(at, Kind::Structure, "image has neither bufferView nor uri"));
            }
        };
        let Some(mime) = Image::sniff_mime(&bytes) else {
            warnings.push(format!("image {k} is neither PNG nor JPEG; textures using it are dropped"));
            return Ok(None);
        };
        Ok(Some(Arc::new(Image { name: image.name.clone(), mime_type: mime.to_owned(), bytes })))
    }
}

/// Adds `materials` to the document (images embedded in the binary chunk, each image,
/// sampler and texture written once); returns their indices in order.
pub(crate) fn write_materials(b: &mut GlbBuilder, materials: &[Material]) -> Vec<json::Index<json::Material>> {
    let mut images: Vec<(Arc<Image>, json::Index<json::Image>)> = Vec::new();
    let mut samplers: Vec<(Sampler, json::Index<json::texture::Sampler>)> = Vec::new();
    let mut textures: Vec<((usize, usize), json::Index<json::Texture>)> = Vec::new();
    let mut texture = |b: &mut GlbBuilder, t: &Option<Texture>| -> Option<json::Index<json::Texture>> {
        let t = t.as_ref()?;
        let image = match images.iter().position(|(i, _)| Arc::ptr_eq(i, &t.image) || *i == t.image) {
            Some(k) => k,
            None => {
                let view = b.push_view(&t.image.bytes, None);
                let index = b.root.push(json::Image {
                    buffer_view: Some(view),
                    mime_type: Some(json::image::MimeType(t.image.mime_type.clone())),
                    name: t.image.name.clone(),
                    uri: None,
                    extensions: Default::default(),
                    extras: Default::default(),
                });
                images.push((t.image.clone(), index));
                images.len() - 1
            }
        };
        let sampler = match samplers.iter().position(|(s, _)| *s == t.sampler) {
            Some(k) => k,
            None => {
                let s = &t.sampler;
                let index = b.root.push(json::texture::Sampler {
                    mag_filter: s.mag_filter.and_then(mag_filter).map(Valid),
                    min_filter: s.min_filter.and_then(min_filter).map(Valid),
                    wrap_s: Valid(wrapping(s.wrap_s)),
                    wrap_t: Valid(wrapping(s.wrap_t)),
                    ..Default::default()
                });
                samplers.push((t.sampler, index));
                samplers.len() - 1
            }
        };
        if let Some((_, index)) = textures.iter().find(|(key, _)| *key == (image, sampler)) {
            return Some(*index);
        }
        let index = b.root.push(json::Texture {
            name: None,
            sampler: Some(samplers[sampler].1),
            source: images[image].1,
            extensions: Default::default(),
            extras: Default::default(),
        });
        textures.push(((image, sampler), index));
        Some(index)
    };
    let info = |index: json::Index<json::Texture>| json::texture::Info {
        index,
        tex_coord: 0,
        extensions: Default::default(),
        extras: Default::default(),
    };
    let mut out = Vec::with_capacity(materials.len());
    let (mut uses_specular, mut uses_strength) = (false, false);
    for m in materials {
        let base_color_texture = texture(b, &m.base_color_texture).map(info);
        let metallic_roughness_texture = texture(b, &m.metallic_roughness_texture).map(info);
        let normal_texture = texture(b, &m.normal_texture).map(|index| json::material::NormalTexture {
            index,
            scale: m.normal_scale,
            tex_coord: 0,
            extensions: Default::default(),
            extras: Default::default(),
        });
        let occlusion_texture = texture(b, &m.occlusion_texture).map(|index| json::material::OcclusionTexture {
            index,
            strength: json::material::StrengthFactor(m.occlusion_strength),
            tex_coord: 0,
            extensions: Default::default(),
            extras: Default::default(),
        });
        let emissive_texture = texture(b, &m.emissive_texture).map(info);
        let mut extensions = json::extensions::material::Material::default();
        if let Some(s) = m.specular {
            uses_specular = true;
            extensions.specular = Some(json::extensions::material::Specular {
                specular_factor: json::extensions::material::SpecularFactor(s.factor),
                specular_texture: None,
                specular_color_factor: json::extensions::material::SpecularColorFactor(s.color_factor),
                specular_color_texture: None,
                extras: Default::default(),
            });
        }
        if m.emissive_strength != 1.0 {
            uses_strength = true;
            extensions.emissive_strength = Some(json::extensions::material::EmissiveStrength {
                emissive_strength: json::extensions::material::EmissiveStrengthFactor(m.emissive_strength),
            });
        }
        let has_extensions = extensions.specular.is_some() || extensions.emissive_strength.is_some();
        let (alpha_mode, alpha_cutoff) = match m.alpha_mode {
            AlphaMode::Opaque => (json::material::AlphaMode::Opaque, None),
            AlphaMode::Mask { cutoff } => (json::material::AlphaMode::Mask, Some(json::material::AlphaCutoff(cutoff))),
            AlphaMode::Blend => (json::material::AlphaMode::Blend, None),
        };
        out.push(b.root.push(json::Material {
            alpha_cutoff,
            alpha_mode: Valid(alpha_mode),
            double_sided: m.double_sided,
            name: m.name.clone(),
            pbr_metallic_roughness: json::material::PbrMetallicRoughness {
                base_color_factor: json::material::PbrBaseColorFactor(m.base_color_factor),
                base_color_texture,
                metallic_factor: json::material::StrengthFactor(m.metallic_factor),
                roughness_factor: json::material::StrengthFactor(m.roughness_factor),
                metallic_roughness_texture,
                ..Default::default()
            },
            normal_texture,
            occlusion_texture,
            emissive_texture,
            emissive_factor: json::material::EmissiveFactor(m.emissive_factor),
            extensions: has_extensions.then_some(extensions),
            ..Default::default()
        }));
    }
    for (used, name) in [(uses_specular, KHR_SPECULAR), (uses_strength, KHR_EMISSIVE_STRENGTH)] {
        if used && !b.root.extensions_used.iter().any(|e| e == name) {
            b.root.extensions_used.push(name.to_owned());
        }
    }
    out
}

fn mag_filter(gl: u32) -> Option<json::texture::MagFilter> {
    use json::texture::MagFilter::*;
    [Nearest, Linear].into_iter().find(|f| f.as_gl_enum() == gl)
}

fn min_filter(gl: u32) -> Option<json::texture::MinFilter> {
    use json::texture::MinFilter::*;
    [Nearest, Linear, NearestMipmapNearest, LinearMipmapNearest, NearestMipmapLinear, LinearMipmapLinear]
        .into_iter()
        .find(|f| f.as_gl_enum() == gl)
}

/// glTF's wrapping mode for a GL constant; unknown ones repeat (glTF's default).
fn wrapping(gl: u32) -> json::texture::WrappingMode {
    use json::texture::WrappingMode::*;
    [ClampToEdge, MirroredRepeat, Repeat].into_iter().find(|w| w.as_gl_enum() == gl).unwrap_or(Repeat)
}
