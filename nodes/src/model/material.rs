//! Surface materials of meshes: glTF 2.0's metallic-roughness model, which is what
//! characters arrive in and what viewers draw. Texture images keep the source file's
//! encoded bytes (PNG, JPEG), not decoded, so a re-export embeds exactly what was read; the
//! one exception is FBX's separate grey maps, which glTF reads as channels of one image
//! (`formats/fbx/channels.rs` combines them into a new PNG).

use std::sync::Arc;

/// An encoded texture image.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Image {
    /// Name from the source file, if any.
    pub name: Option<String>,
    /// `image/png` or `image/jpeg`.
    pub mime_type: String,
    /// The encoded file bytes, as read (or as `formats/fbx/channels.rs` combined them).
    #[serde(with = "serde_bytes")]
    pub bytes: Vec<u8>,
}

impl Image {
    /// The MIME type of encoded image `bytes` by their signature; `None` for anything but
    /// PNG and JPEG (the two formats core glTF allows).
    pub fn sniff_mime(bytes: &[u8]) -> Option<&'static str> {
        if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some("image/png")
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Some("image/jpeg")
        } else {
            None
        }
    }
}

/// How a texture is filtered and wrapped, as glTF's (OpenGL) constants: filters 9728
/// NEAREST, 9729 LINEAR, 9984–9987 mipmapped; wraps 33071 CLAMP_TO_EDGE, 33648
/// MIRRORED_REPEAT, 10497 REPEAT. Unset filters leave the choice to the viewer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Sampler {
    /// Magnification filter.
    pub mag_filter: Option<u32>,
    /// Minification filter.
    pub min_filter: Option<u32>,
    /// Wrapping along U.
    pub wrap_s: u32,
    /// Wrapping along V.
    pub wrap_t: u32,
}

impl Default for Sampler {
    /// glTF's default: viewer-chosen filtering, repeating in both directions.
    fn default() -> Self {
        Sampler { mag_filter: None, min_filter: None, wrap_s: 10_497, wrap_t: 10_497 }
    }
}

/// A texture a material samples with the mesh's UVs (TEXCOORD_0).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Texture {
    /// The image, shared between textures that use the same one.
    pub image: Arc<Image>,
    /// Filtering and wrapping.
    pub sampler: Sampler,
}

/// How a material's alpha is used.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum AlphaMode {
    /// Alpha ignored.
    #[default]
    Opaque,
    /// Drawn where alpha ≥ the cutoff, not drawn elsewhere.
    Mask {
        /// The cutoff (0–1).
        cutoff: f32,
    },
    /// Alpha-blended.
    Blend,
}

/// A metallic-roughness material. Colours and factors are linear, as in glTF; texture
/// colours are multiplied by the factors.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    /// Name from the source file, if any.
    pub name: Option<String>,
    /// Base colour RGBA.
    pub base_color_factor: [f32; 4],
    /// Base colour texture (sRGB).
    pub base_color_texture: Option<Texture>,
    /// Metalness, 0–1.
    pub metallic_factor: f32,
    /// Roughness, 0–1.
    pub roughness_factor: f32,
    /// Roughness (G) and metalness (B) texture.
    pub metallic_roughness_texture: Option<Texture>,
    /// Tangent-space normal map.
    pub normal_texture: Option<Texture>,
    /// Scale of the normal map's X and Y.
    pub normal_scale: f32,
    /// Ambient occlusion texture (R).
    pub occlusion_texture: Option<Texture>,
    /// How much occlusion applies, 0–1.
    pub occlusion_strength: f32,
    /// Emitted RGB.
    pub emissive_factor: [f32; 3],
    /// Emission texture (sRGB).
    pub emissive_texture: Option<Texture>,
    /// Multiplier of the emission (KHR_materials_emissive_strength), 1 when absent.
    pub emissive_strength: f32,
    /// Specular layer (KHR_materials_specular), when the source had one.
    pub specular: Option<Specular>,
    /// Alpha use.
    pub alpha_mode: AlphaMode,
    /// Whether back faces are drawn.
    pub double_sided: bool,
}

/// KHR_materials_specular's factors (its textures are not kept).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Specular {
    /// Strength of the specular reflection.
    pub factor: f32,
    /// F0 colour of the specular reflection (linear RGB).
    pub color_factor: [f32; 3],
}

impl Default for Material {
    /// glTF's default material: white, fully metallic and rough, opaque, one-sided.
    fn default() -> Self {
        Material {
            name: None,
            base_color_factor: [1.0; 4],
            base_color_texture: None,
            metallic_factor: 1.0,
            roughness_factor: 1.0,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            occlusion_texture: None,
            occlusion_strength: 1.0,
            emissive_factor: [0.0; 3],
            emissive_texture: None,
            emissive_strength: 1.0,
            specular: None,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
        }
    }
}

impl Material {
    /// The material with its factors only (for a mesh without UVs to sample textures with).
    pub fn without_textures(&self) -> Material {
        Material {
            base_color_texture: None,
            metallic_roughness_texture: None,
            normal_texture: None,
            occlusion_texture: None,
            emissive_texture: None,
            ..self.clone()
        }
    }

    /// The textures the material uses, in a fixed order (base colour, metallic-roughness,
    /// normal, occlusion, emissive).
    pub fn textures(&self) -> impl Iterator<Item = &Texture> {
        [
            &self.base_color_texture,
            &self.metallic_roughness_texture,
            &self.normal_texture,
            &self.occlusion_texture,
            &self.emissive_texture,
        ]
        .into_iter()
        .flatten()
    }
}

/// A run of consecutive triangles of a mesh drawn with one material.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MaterialRange {
    /// Index of the run's first triangle.
    pub first_triangle: usize,
    /// Number of triangles.
    pub triangle_count: usize,
    /// Index into the mesh's materials; `None` draws with the viewer's default material.
    pub material: Option<usize>,
}
