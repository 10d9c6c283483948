//! Inside and outside of closed triangle surfaces.

use glam::DVec3;

/// Winding number of the surface (`triangles` over `positions`, counter-clockwise seen from
/// outside) around `p`: ≈ 1 inside a closed surface, ≈ 0 outside, by the van
/// Oosterom–Strackee solid angle of each triangle. It reads the geometry, not the indices,
/// so a box whose faces have their own vertices counts as closed; a surface with holes
/// gives fractions (the generalised winding number), read with a ½ threshold.
pub fn winding_number(positions: &[DVec3], triangles: &[[u32; 3]], p: DVec3) -> f64 {
    let mut total = 0.0;
    for t in triangles {
        let [a, b, c] = t.map(|i| positions.get(i as usize).copied().unwrap_or(DVec3::ZERO) - p);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let numerator = a.dot(b.cross(c));
        let denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        total += 2.0 * numerator.atan2(denominator);
    }
    total / (4.0 * std::f64::consts::PI)
}
