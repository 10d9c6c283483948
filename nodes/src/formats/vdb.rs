//! OpenVDB writer: float and vec3 grids on a uniform voxel lattice, one `.vdb` file.
//!
//! No maintained Rust crate writes VDB (vdb-rs reads only), so this module writes the
//! format itself, following OpenVDB's `io/Archive.cc`, `tree/RootNode.h`,
//! `tree/InternalNode.h`, `tree/LeafNode.h` and `io/Compression.h` at file version 224
//! (OpenVDB 10): what Blender, Houdini and the Debian `python3-openvdb` read.
//!
//! Layout (little endian; strings are a u32 length and bytes):
//! 1. header: magic `0x56444220` (i64), file version 224 (u32), library 10.0 (2 × u32),
//!    "has grid offsets" (1 byte, 1), a 36-character UUID, file metadata (u32 count 0),
//!    grid count (u32);
//! 2. per grid: the descriptor (name, tree type `Tree_float_5_4_3` / `Tree_vec3s_5_4_3`,
//!    instance parent ""), three i64 offsets (grid start, buffers start, grid end), the
//!    compression flags (u32, `COMPRESS_ACTIVE_MASK` = 2), grid metadata (`name`, and
//!    `class` = "fog volume" for float grids; metadata values are a u32 size and bytes), the transform
//!    (`UniformScaleMap`: scale, voxel size, 1/scale, 1/scale², 1/(2 scale) as f64 triples),
//!    the topology and the buffers;
//! 3. topology: buffer count (u32 1), the root (background, tile count 0, child count, then
//!    per child its origin and topology), 5-level internal nodes (32³ children of 128³
//!    voxels), 4-level internal nodes (16³ leaves), leaves (8³ voxels). An internal node
//!    writes its child mask, its value mask (empty: no active tiles), a metadata byte 0 ("no
//!    inactive values other than the background") with no values, then its children; a leaf
//!    writes its value mask.
//! 4. buffers, leaf by leaf in the same order: value mask, metadata byte 0, the active values.
//!
//! Voxels whose value is exactly zero (the background) are inactive and not stored; slots
//! inside a node are numbered x slowest, z fastest, and children in increasing slot order.

use std::collections::BTreeMap;

use glam::IVec3;

/// OpenVDB's magic number ("VDB " as an i64).
const MAGIC: i64 = 0x5644_4220;
/// File format version written (OpenVDB 10's).
const FILE_VERSION: u32 = 224;
/// `io::COMPRESS_ACTIVE_MASK`: only active values are stored; no zip, no blosc.
const COMPRESS_ACTIVE_MASK: u32 = 2;
/// Metadata byte of a node whose inactive values are all the background.
const NO_MASK_OR_INACTIVE_VALS: u8 = 0;

/// One grid's values, one per voxel of a [`crate::model::volume::VoxelGrid`].
#[derive(Debug, Clone, Copy)]
pub enum GridValues<'a> {
    /// Scalars (density, temperature).
    Float(&'a [f32]),
    /// Vectors (velocity).
    Vec3(&'a [[f32; 3]]),
}

/// A named grid to write.
#[derive(Debug, Clone, Copy)]
pub struct VdbGrid<'a> {
    /// Grid name (Blender looks for `density`, `temperature`, `velocity`).
    pub name: &'a str,
    /// The values, in the lattice's array order.
    pub values: GridValues<'a>,
}

/// A voxel value as OpenVDB stores it.
trait Voxel: Copy {
    const TREE_TYPE: &'static str;
    fn is_background(&self) -> bool;
    fn put(&self, out: &mut Vec<u8>);
    fn zero() -> Self;
}

impl Voxel for f32 {
    const TREE_TYPE: &'static str = "Tree_float_5_4_3";
    fn is_background(&self) -> bool {
        *self == 0.0
    }
    fn put(&self, out: &mut Vec<u8>) {
        out.extend(self.to_le_bytes());
    }
    fn zero() -> Self {
        0.0
    }
}

impl Voxel for [f32; 3] {
    const TREE_TYPE: &'static str = "Tree_vec3s_5_4_3";
    fn is_background(&self) -> bool {
        self.iter().all(|v| *v == 0.0)
    }
    fn put(&self, out: &mut Vec<u8>) {
        for v in self {
            out.extend(v.to_le_bytes());
        }
    }
    fn zero() -> Self {
        [0.0; 3]
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend(v.to_le_bytes());
}

fn put_string(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len() as u32);
    out.extend(s.as_bytes());
}

/// A node mask of `bits` bits as OpenVDB saves it: u64 words, bit `i` in word `i / 64`.
fn put_mask(out: &mut Vec<u8>, words: &[u64]) {
    for w in words {
        out.extend(w.to_le_bytes());
    }
}

fn set_bit(words: &mut [u64], i: usize) {
    words[i / 64] |= 1 << (i % 64);
}

/// Slot of the child holding `c` in a node of `2^log2_dim` children per axis, each child
/// covering `2^child_log2` voxels per axis (x slowest).
fn slot(c: IVec3, log2_dim: u32, child_log2: u32) -> usize {
    let m = (1i32 << (log2_dim + child_log2)) - 1;
    let axis = |v: i32| ((v & m) >> child_log2) as usize;
    (axis(c.x) << (2 * log2_dim)) | (axis(c.y) << log2_dim) | axis(c.z)
}

struct Leaf<T> {
    mask: [u64; 8],
    values: Vec<T>,
}

/// upper origin → lower slot → leaf slot → leaf.
type Tree<T> = BTreeMap<[i32; 3], BTreeMap<usize, BTreeMap<usize, Leaf<T>>>>;

fn build_tree<T: Voxel>(grid: &crate::model::volume::VoxelGrid, values: &[T]) -> Tree<T> {
    let mut tree: Tree<T> = BTreeMap::new();
    for (n, v) in values.iter().enumerate().take(grid.len()) {
        if v.is_background() {
            continue;
        }
        let c = grid.coord(n);
        let upper = c & IVec3::splat(!4095);
        let leaf = tree
            .entry(upper.to_array())
            .or_default()
            .entry(slot(c, 5, 7))
            .or_default()
            .entry(slot(c, 4, 3))
            .or_insert_with(|| Leaf { mask: [0; 8], values: vec![T::zero(); 512] });
        let i = slot(c, 3, 0);
        set_bit(&mut leaf.mask, i);
        leaf.values[i] = *v;
    }
    tree
}

fn write_grid<T: Voxel>(out: &mut Vec<u8>, name: &str, voxel_m: f64, tree: &Tree<T>) {
    put_string(out, name);
    put_string(out, T::TREE_TYPE);
    put_string(out, "");
    let offsets_at = out.len();
    out.extend([0u8; 24]);
    let grid_pos = out.len() as i64;
    put_u32(out, COMPRESS_ACTIVE_MASK);
    // Grid metadata: readers take the grid's name from here (not from the descriptor); the
    // class tells renderers a float grid is a fog volume.
    let is_float = T::TREE_TYPE == f32::TREE_TYPE;
    put_u32(out, if is_float { 2 } else { 1 });
    if is_float {
        put_string(out, "class");
        put_string(out, "string");
        put_string(out, "fog volume");
    }
    put_string(out, "name");
    put_string(out, "string");
    put_string(out, name);
    put_string(out, "UniformScaleMap");
    for v in [voxel_m, voxel_m, 1.0 / voxel_m, 1.0 / (voxel_m * voxel_m), 0.5 / voxel_m] {
        for _ in 0..3 {
            out.extend(v.to_le_bytes());
        }
    }
    // Topology.
    put_u32(out, 1);
    T::zero().put(out);
    put_u32(out, 0);
    put_u32(out, tree.len() as u32);
    for (origin, lowers) in tree {
        for v in origin {
            out.extend(v.to_le_bytes());
        }
        let mut child_mask = vec![0u64; 32 * 32 * 32 / 64];
        lowers.keys().for_each(|&s| set_bit(&mut child_mask, s));
        put_mask(out, &child_mask);
        put_mask(out, &vec![0u64; child_mask.len()]);
        out.push(NO_MASK_OR_INACTIVE_VALS);
        for leaves in lowers.values() {
            let mut child_mask = vec![0u64; 16 * 16 * 16 / 64];
            leaves.keys().for_each(|&s| set_bit(&mut child_mask, s));
            put_mask(out, &child_mask);
            put_mask(out, &vec![0u64; child_mask.len()]);
            out.push(NO_MASK_OR_INACTIVE_VALS);
            for leaf in leaves.values() {
                put_mask(out, &leaf.mask);
            }
        }
    }
    // Buffers.
    let block_pos = out.len() as i64;
    for leaf in tree.values().flat_map(|lowers| lowers.values()).flat_map(|leaves| leaves.values()) {
        put_mask(out, &leaf.mask);
        out.push(NO_MASK_OR_INACTIVE_VALS);
        for (i, v) in leaf.values.iter().enumerate() {
            if leaf.mask[i / 64] & (1 << (i % 64)) != 0 {
                v.put(out);
            }
        }
    }
    let end_pos = out.len() as i64;
    for (k, pos) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        out[offsets_at + 8 * k..offsets_at + 8 * k + 8].copy_from_slice(&pos.to_le_bytes());
    }
}

/// The bytes of a `.vdb` file holding `grids` on the lattice `grid`.
pub fn write_vdb(grid: &crate::model::volume::VoxelGrid, grids: &[VdbGrid<'_>]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend(MAGIC.to_le_bytes());
    put_u32(&mut out, FILE_VERSION);
    put_u32(&mut out, 10);
    put_u32(&mut out, 0);
    out.push(1);
    // A UUID from the content, so equal volumes give equal files.
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut mix = |bytes: &[u8]| {
        for b in bytes {
            hash = (hash ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    for g in grids {
        mix(g.name.as_bytes());
        match g.values {
            GridValues::Float(v) => v.iter().for_each(|x| mix(&x.to_le_bytes())),
            GridValues::Vec3(v) => v.iter().flatten().for_each(|x| mix(&x.to_le_bytes())),
        }
    }
    let uuid = format!(
        "{:08x}-{:04x}-4{:03x}-8{:03x}-{:012x}",
        hash >> 32,
        (hash >> 16) & 0xffff,
        hash & 0xfff,
        (hash >> 4) & 0xfff,
        hash & 0xffff_ffff_ffff
    );
    out.extend(uuid.as_bytes());
    put_u32(&mut out, 0);
    put_u32(&mut out, grids.len() as u32);
    let voxel_m = f64::from(grid.voxel_m);
    for g in grids {
        match g.values {
            GridValues::Float(v) => write_grid(&mut out, g.name, voxel_m, &build_tree(grid, v)),
            GridValues::Vec3(v) => write_grid(&mut out, g.name, voxel_m, &build_tree(grid, v)),
        }
    }
    out
}
