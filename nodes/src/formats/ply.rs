//! PLY point clouds (binary little endian, `float x y z` per vertex): marker particles per
//! frame, which Blender, Houdini and MeshLab read.

/// The bytes of a binary PLY file holding `points_m` (metres) as vertices; `up` names the
/// up axis in the header's comment.
pub fn write_points_ply(points_m: &[[f32; 3]], up: &str) -> Vec<u8> {
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment kinegraph smoke particles, metres, {up} up\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points_m.len()
    );
    let mut out = Vec::with_capacity(header.len() + 12 * points_m.len());
    out.extend(header.as_bytes());
    for p in points_m.iter().flatten() {
        out.extend(p.to_le_bytes());
    }
    out
}
