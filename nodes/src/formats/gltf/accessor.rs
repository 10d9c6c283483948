//! Checked decoding of glTF accessors into plain numbers.
//!
//! Steps: 1. look up the accessor, its buffer view and buffer (index errors name the JSON
//! path holding the bad index); 2. check that the last element ends inside the view and
//! the view inside the buffer *before* allocating anything sized by `count`; 3. read every
//! component little-endian, applying `normalized` integer scaling; 4. apply sparse
//! substitution (indices and values views checked the same way); 5. reject non-finite
//! floats. The result is always `count × components` `f64` values, which hold every glTF
//! component type (including `u32` indices) exactly.

use gltf_json::accessor::{ComponentType, Type};
use gltf_json::validation::Checked;

use crate::formats::error::FormatErrorKind as Kind;

use super::document::Document;

/// Largest number of values an accessor without a buffer view (sparse-only, zero base) may
/// claim; such an accessor has no data bounding its `count`.
const MAX_UNBACKED_VALUES: u64 = 1 << 26;

/// An accessor's values, `count` elements of `components` numbers each (matrices
/// column-major), normalised integers already scaled to `[0, 1]` or `[-1, 1]`.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Decoded {
    /// Number of elements.
    pub count: usize,
    /// Numbers per element (1 for SCALAR, 4 for VEC4, 16 for MAT4).
    pub components: usize,
    /// The values, element-major.
    pub values: Vec<f64>,
    /// The component type as stored in the file.
    pub component_type: ComponentType,
}

impl Decoded {
    /// Element `i` as a slice of `components` numbers.
    pub fn element(&self, i: usize) -> &[f64] {
        &self.values[i * self.components..(i + 1) * self.components]
    }
}

/// Bytes per component.
fn component_size(t: ComponentType) -> usize {
    match t {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

/// `(columns, rows)` of an element type; vectors and scalars are one column.
fn shape(t: Type) -> (usize, usize) {
    match t {
        Type::Scalar => (1, 1),
        Type::Vec2 => (1, 2),
        Type::Vec3 => (1, 3),
        Type::Vec4 => (1, 4),
        Type::Mat2 => (2, 2),
        Type::Mat3 => (3, 3),
        Type::Mat4 => (4, 4),
    }
}

/// Reads one component at `bytes[0..size]`.
fn read_component(bytes: &[u8], t: ComponentType, normalized: bool) -> f64 {
    let b = |n: usize| bytes.get(n).copied().unwrap_or(0);
    match t {
        ComponentType::I8 => {
            let v = b(0) as i8 as f64;
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        ComponentType::U8 => {
            let v = b(0) as f64;
            if normalized { v / 255.0 } else { v }
        }
        ComponentType::I16 => {
            let v = i16::from_le_bytes([b(0), b(1)]) as f64;
            if normalized { (v / 32767.0).max(-1.0) } else { v }
        }
        ComponentType::U16 => {
            let v = u16::from_le_bytes([b(0), b(1)]) as f64;
            if normalized { v / 65535.0 } else { v }
        }
        ComponentType::U32 => u32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f64,
        ComponentType::F32 => f32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f64,
    }
}

/// Layout of one element in a buffer: column stride (matrix columns are 4-byte aligned)
/// and total size.
struct ElementLayout {
    columns: usize,
    rows: usize,
    size: usize,
    column_stride: usize,
    element_size: usize,
}

impl ElementLayout {
    fn new(t: Type, c: ComponentType) -> Self {
        let (columns, rows) = shape(t);
        let size = component_size(c);
        let column_bytes = rows * size;
        let column_stride = if columns > 1 { column_bytes.div_ceil(4) * 4 } else { column_bytes };
        ElementLayout { columns, rows, size, column_stride, element_size: column_stride * columns }
    }
}

/// A checked byte range inside a buffer view: the view's bytes plus its stride.
struct ViewSlice<'a> {
    bytes: &'a [u8],
    stride: Option<usize>,
}

/// Resolves buffer view `view_index`, checking it lies inside its buffer. `at` is the JSON
/// path holding the view index.
fn view_slice<'a>(doc: &'a Document, view_index: usize, at: &str) -> Result<ViewSlice<'a>, super::ReadError> {
    let view = doc.root.buffer_views.get(view_index).ok_or_else(|| {
        super::ReadError::new(at, Kind::Structure, format!("buffer view {view_index} does not exist"))
    })?;
    let view_path = format!("/bufferViews/{view_index}");
    let buffer_index = view.buffer.value();
    let data = doc.buffers.get(buffer_index).ok_or_else(|| {
        super::ReadError::new(
            format!("{view_path}/buffer"),
            Kind::Structure,
            format!("buffer {buffer_index} does not exist"),
        )
    })?;
    let offset = view.byte_offset.map(|o| o.0).unwrap_or(0);
    let length = view.byte_length.0;
    let end = offset.checked_add(length).filter(|&e| e <= data.len() as u64).ok_or_else(|| {
        super::ReadError::new(
            &view_path,
            Kind::Truncated,
            format!(
                "view bytes {offset}..{} run past the end of buffer {buffer_index} ({} bytes)",
                offset.saturating_add(length),
                data.len()
            ),
        )
    })?;
    let stride = view.byte_stride.map(|s| s.0);
    Ok(ViewSlice { bytes: &data[offset as usize..end as usize], stride })
}

/// The bytes of buffer view `view_index` (an embedded image), bounds-checked; `at` is the
/// JSON path holding the view index.
pub(crate) fn view_bytes<'a>(doc: &'a Document, view_index: usize, at: &str) -> Result<&'a [u8], super::ReadError> {
    Ok(view_slice(doc, view_index, at)?.bytes)
}

/// Decodes `count` elements starting `offset` bytes into `view`, checking bounds first.
#[allow(clippy::too_many_arguments)]
fn decode_elements(
    view: &ViewSlice<'_>,
    offset: u64,
    count: usize,
    layout: &ElementLayout,
    component_type: ComponentType,
    normalized: bool,
    at: &str,
    out: &mut Vec<f64>,
) -> Result<(), super::ReadError> {
    if count == 0 {
        return Ok(());
    }
    let stride = view.stride.unwrap_or(layout.element_size);
    if stride < layout.element_size {
        return Err(super::ReadError::new(
            at,
            Kind::Structure,
            format!("byte stride {stride} is smaller than the element size {}", layout.element_size),
        ));
    }
    let needed = (count as u64 - 1)
        .checked_mul(stride as u64)
        .and_then(|n| n.checked_add(offset))
        .and_then(|n| n.checked_add(layout.element_size as u64));
    match needed {
        Some(n) if n <= view.bytes.len() as u64 => {}
        _ => {
            return Err(super::ReadError::new(
                at,
                Kind::Truncated,
                format!(
                    "{count} elements of {} bytes (stride {stride}, offset {offset}) run past the end of their {}-byte buffer view",
                    layout.element_size,
                    view.bytes.len()
                ),
            ));
        }
    }
    out.reserve(count * layout.columns * layout.rows);
    for i in 0..count {
        let base = offset as usize + i * stride;
        for c in 0..layout.columns {
            for r in 0..layout.rows {
                let at_byte = base + c * layout.column_stride + r * layout.size;
                out.push(read_component(&view.bytes[at_byte..at_byte + layout.size], component_type, normalized));
            }
        }
    }
    Ok(())
}

/// Decodes accessor `index`. `referenced_at` is the JSON path that named the accessor,
/// used when the index itself is out of range.
pub(crate) fn decode(doc: &Document, index: usize, referenced_at: &str) -> Result<Decoded, super::ReadError> {
    let path = format!("/accessors/{index}");
    let accessor = doc.root.accessors.get(index).ok_or_else(|| {
        super::ReadError::new(referenced_at, Kind::Structure, format!("accessor {index} does not exist"))
    })?;
    let (Checked::Valid(component_type), Checked::Valid(type_)) = (&accessor.component_type, &accessor.type_) else {
        return Err(super::ReadError::new(&path, Kind::Value, "unknown componentType or type"));
    };
    let component_type = component_type.0;
    let type_ = *type_;
    let layout = ElementLayout::new(type_, component_type);
    let components = layout.columns * layout.rows;
    let count_claim = accessor.count.0;
    let count = usize::try_from(count_claim)
        .map_err(|_| super::ReadError::new(format!("{path}/count"), Kind::Value, "count too large"))?;

    let mut values = Vec::new();
    match accessor.buffer_view {
        Some(view_index) => {
            let view = view_slice(doc, view_index.value(), &format!("{path}/bufferView"))?;
            let offset = accessor.byte_offset.map(|o| o.0).unwrap_or(0);
            decode_elements(&view, offset, count, &layout, component_type, accessor.normalized, &path, &mut values)?;
        }
        None => {
            if count_claim.saturating_mul(components as u64) > MAX_UNBACKED_VALUES {
                return Err(super::ReadError::new(
                    format!("{path}/count"),
                    Kind::Unsupported,
                    format!("{count_claim} elements without a buffer view is more than kinegraph accepts"),
                ));
            }
            if accessor.sparse.is_none() {
                return Err(super::ReadError::new(
                    format!("{path}/bufferView"),
                    Kind::Structure,
                    "accessor has neither bufferView nor sparse",
                ));
            }
            values = vec![0.0; count * components];
        }
    }

    if let Some(sparse) = &accessor.sparse {
        let sparse_path = format!("{path}/sparse");
        let sparse_count = usize::try_from(sparse.count.0).unwrap_or(usize::MAX);
        if sparse_count > count {
            return Err(super::ReadError::new(
                format!("{sparse_path}/count"),
                Kind::Structure,
                format!("{} sparse entries for an accessor of {count} elements", sparse.count.0),
            ));
        }
        let Checked::Valid(index_type) = &sparse.indices.component_type else {
            return Err(super::ReadError::new(
                format!("{sparse_path}/indices/componentType"),
                Kind::Value,
                "unknown index type",
            ));
        };
        let index_type = index_type.0;
        if !matches!(index_type, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) {
            return Err(super::ReadError::new(
                format!("{sparse_path}/indices/componentType"),
                Kind::Value,
                "sparse indices must be unsigned",
            ));
        }
        let index_view =
            view_slice(doc, sparse.indices.buffer_view.value(), &format!("{sparse_path}/indices/bufferView"))?;
        let index_view = ViewSlice { bytes: index_view.bytes, stride: None };
        let mut indices = Vec::new();
        decode_elements(
            &index_view,
            sparse.indices.byte_offset.0,
            sparse_count,
            &ElementLayout::new(Type::Scalar, index_type),
            index_type,
            false,
            &format!("{sparse_path}/indices"),
            &mut indices,
        )?;
        let value_view =
            view_slice(doc, sparse.values.buffer_view.value(), &format!("{sparse_path}/values/bufferView"))?;
        let value_view = ViewSlice { bytes: value_view.bytes, stride: None };
        let mut sparse_values = Vec::new();
        decode_elements(
            &value_view,
            sparse.values.byte_offset.0,
            sparse_count,
            &layout,
            component_type,
            accessor.normalized,
            &format!("{sparse_path}/values"),
            &mut sparse_values,
        )?;
        let mut previous: Option<usize> = None;
        for (k, &raw) in indices.iter().enumerate() {
            let target = raw as usize;
            if target >= count || previous.is_some_and(|p| target <= p) {
                return Err(super::ReadError::new(
                    format!("{sparse_path}/indices"),
                    Kind::Structure,
                    format!("sparse index {k} is {target}: indices must increase and stay below {count}"),
                ));
            }
            previous = Some(target);
            values[target * components..(target + 1) * components]
                .copy_from_slice(&sparse_values[k * components..(k + 1) * components]);
        }
    }

    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(super::ReadError::new(
            &path,
            Kind::Value,
            format!("element {} holds a non-finite value", i / components.max(1)),
        ));
    }
    Ok(Decoded { count, components, values, component_type })
}
