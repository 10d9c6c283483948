//! Buffer and accessor bookkeeping for writing GLB: every accessor gets its own 4-byte
//! aligned buffer view in the single binary buffer, so strides and alignment never need
//! thought at the call site.

use std::borrow::Cow;
use std::io::Write;

use gltf_json as json;
use json::accessor::{ComponentType, GenericComponentType, Type};
use json::buffer::Target;
use json::validation::Checked::Valid;
use json::validation::USize64;

/// Collects the JSON tree and the binary chunk of a GLB being written.
pub(crate) struct GlbBuilder {
    /// The document under construction.
    pub root: json::Root,
    bin: Vec<u8>,
}

/// A primitive's vertex attributes: semantic → accessor.
pub(crate) type Attributes =
    std::collections::BTreeMap<json::validation::Checked<json::mesh::Semantic>, json::Index<json::Accessor>>;

/// Whether an accessor records its per-component `min`/`max` (required for POSITION and
/// animation inputs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Bounds {
    /// Write `min` and `max`.
    Record,
    /// Leave them out.
    Omit,
}

fn components(t: Type) -> usize {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

impl GlbBuilder {
    /// An empty document with `generator` in its asset block.
    pub fn new(generator: &str) -> Self {
        let mut root = json::Root::default();
        root.asset.generator = Some(generator.to_string());
        GlbBuilder { root, bin: Vec::new() }
    }

    /// Appends `bytes` as a new buffer view (4-byte aligned).
    pub fn push_view(&mut self, bytes: &[u8], target: Option<Target>) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: target.map(Valid),
        })
    }

    fn push_accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        component_type: ComponentType,
        type_: Type,
        target: Option<Target>,
        min_max: Option<(Vec<f64>, Vec<f64>)>,
    ) -> json::Index<json::Accessor> {
        let view = self.push_view(bytes, target);
        let (min, max) = match min_max {
            Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(GenericComponentType(component_type)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(type_),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// An `f32` accessor of `type_` elements from `values` (element-major).
    pub fn accessor_f32(
        &mut self,
        values: &[f32],
        type_: Type,
        target: Option<Target>,
        bounds: Bounds,
    ) -> json::Index<json::Accessor> {
        let c = components(type_);
        let count = values.len() / c;
        let min_max = (bounds == Bounds::Record).then(|| {
            let mut lo = vec![f64::INFINITY; c];
            let mut hi = vec![f64::NEG_INFINITY; c];
            for e in values.chunks_exact(c) {
                for i in 0..c {
                    lo[i] = lo[i].min(e[i] as f64);
                    hi[i] = hi[i].max(e[i] as f64);
                }
            }
            (lo, hi)
        });
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.push_accessor(&bytes, count, ComponentType::F32, type_, target, min_max)
    }

    /// A `u16` accessor of `type_` elements.
    pub fn accessor_u16(&mut self, values: &[u16], type_: Type, target: Option<Target>) -> json::Index<json::Accessor> {
        let count = values.len() / components(type_);
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.push_accessor(&bytes, count, ComponentType::U16, type_, target, None)
    }

    /// A `u32` scalar accessor (triangle indices).
    pub fn accessor_u32(&mut self, values: &[u32], target: Option<Target>) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.push_accessor(&bytes, values.len(), ComponentType::U32, Type::Scalar, target, None)
    }

    /// A one-primitive triangle mesh from `attributes` and `triangles` (see
    /// [`GlbBuilder::triangle_primitive`]), with optional morph `targets` and their default
    /// `weights`.
    pub fn triangle_mesh(
        &mut self,
        name: &str,
        attributes: Attributes,
        triangles: &[[u32; 3]],
        vertices: usize,
        targets: Option<Vec<json::mesh::MorphTarget>>,
        weights: Option<Vec<f32>>,
    ) -> json::Index<json::Mesh> {
        let primitive = self.triangle_primitive(attributes, triangles, vertices, None, targets);
        self.mesh(name, vec![primitive], weights)
    }

    /// A triangle primitive: writes the index accessor (`u16` when `vertices` fit, else
    /// `u32`) for `triangles` over the accessors in `attributes`.
    pub fn triangle_primitive(
        &mut self,
        attributes: Attributes,
        triangles: &[[u32; 3]],
        vertices: usize,
        material: Option<json::Index<json::Material>>,
        targets: Option<Vec<json::mesh::MorphTarget>>,
    ) -> json::mesh::Primitive {
        let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
        let indices = if vertices <= u16::MAX as usize {
            let small: Vec<u16> = flat.iter().map(|&i| i as u16).collect();
            self.accessor_u16(&small, Type::Scalar, Some(Target::ElementArrayBuffer))
        } else {
            self.accessor_u32(&flat, Some(Target::ElementArrayBuffer))
        };
        json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices: Some(indices),
            material,
            mode: Valid(json::mesh::Mode::Triangles),
            targets,
        }
    }

    /// A mesh of `primitives`.
    pub fn mesh(
        &mut self,
        name: &str,
        primitives: Vec<json::mesh::Primitive>,
        weights: Option<Vec<f32>>,
    ) -> json::Index<json::Mesh> {
        self.root.push(json::Mesh {
            extensions: Default::default(),
            extras: Default::default(),
            name: Some(name.to_string()),
            primitives,
            weights,
        })
    }

    /// Closes the document: the JSON chunk serialised, the binary chunk padded, the total
    /// length checked against GLB's 4 GiB limit.
    pub fn finish(mut self) -> Result<GlbChunks, String> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        if !self.bin.is_empty() {
            self.root.buffers.push(json::Buffer {
                byte_length: USize64::from(self.bin.len()),
                extensions: Default::default(),
                extras: Default::default(),
                name: None,
                uri: None,
            });
        }
        let json = json::serialize::to_vec(&self.root).map_err(|e| e.to_string())?;
        let padded = |n: usize| n.div_ceil(4) * 4;
        let length = 12 + 8 + padded(json.len()) + if self.bin.is_empty() { 0 } else { 8 + self.bin.len() };
        let length =
            u32::try_from(length).map_err(|_| format!("GLB of {length} bytes exceeds the 4 GiB format limit"))?;
        Ok(GlbChunks { json, bin: self.bin, length })
    }
}

/// A finished GLB's two chunks, written out by streaming ([`GlbChunks::write_to`]) so an
/// export does not hold a second copy of its binary chunk.
#[derive(Clone, Debug)]
pub struct GlbChunks {
    json: Vec<u8>,
    bin: Vec<u8>,
    /// Total file length (bytes), already checked to fit GLB's `u32`.
    length: u32,
}

impl GlbChunks {
    fn glb(&self) -> gltf::binary::Glb<'_> {
        gltf::binary::Glb {
            header: gltf::binary::Header { magic: *b"glTF", version: 2, length: self.length },
            json: Cow::Borrowed(&self.json),
            bin: (!self.bin.is_empty()).then_some(Cow::Borrowed(&self.bin[..])),
        }
    }

    /// Writes the GLB file's bytes into `sink`.
    pub fn write_to(&self, sink: &mut dyn Write) -> std::io::Result<()> {
        self.glb().to_writer(sink).map_err(std::io::Error::other)
    }

    /// The GLB file's bytes.
    pub fn into_bytes(self) -> Vec<u8> {
        let mut bytes = Vec::with_capacity(self.length as usize);
        // Writing into memory cannot fail.
        let _ = self.write_to(&mut bytes);
        bytes
    }
}
