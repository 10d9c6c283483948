//! Wrap deformer (`deform.wrap`): a detailed mesh follows a coarse control mesh.
//!
//! Binding attaches each fine vertex to the closest point of its nearest control triangle
//! (barycentric coordinates) and keeps its offset in that triangle's orthonormal frame;
//! every frame replays the offset on the deformed triangle. The nearest triangle is found
//! through a bounding-volume hierarchy (parry3d's `TriMesh`, in the tree through rapier3d),
//! so binding costs O(V log T) rather than the O(V·T) of a scan: a 100 k-vertex mesh on a
//! control mesh of thousands of triangles binds in well under a second. A frame computes
//! each control triangle's frame once, then each fine vertex is a few multiply-adds.
//!
//! Units are the meshes' own (metres in kinegraph).

use glam::Vec3;
use rapier3d::parry::bounding_volume::Aabb;
use rapier3d::parry::query::PointQueryWithLocation;
use rapier3d::parry::shape::TriMesh;
use rayon::prelude::*;

use crate::kernels::physics::{from_rapier, to_rapier};

/// Why a mesh cannot be wrapped.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WrapError {
    /// The control mesh has no triangle with a non-zero area.
    #[error("the control mesh has no triangles with an area")]
    NoTriangles,
    /// A fine or control vertex is NaN or infinite.
    #[error("{mesh} vertex {vertex} is not finite")]
    NotFinite {
        /// "fine" or "control".
        mesh: &'static str,
        /// The vertex index.
        vertex: usize,
    },
}

/// One fine vertex's attachment to the control mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrapBinding {
    /// Control triangle index.
    pub triangle: u32,
    /// Barycentric coordinates of the closest point on that triangle.
    pub barycentric: Vec3,
    /// Offset from the closest point, in the triangle's frame.
    pub local_offset: Vec3,
}

/// An orthonormal frame of a triangle (edge ab, normal, their cross), `None` if degenerate.
pub fn triangle_frame(a: Vec3, b: Vec3, c: Vec3) -> Option<[Vec3; 3]> {
    let e = (b - a).try_normalize()?;
    let n = (b - a).cross(c - a).try_normalize()?;
    Some([e, n, e.cross(n)])
}

/// Barycentric coordinates of the point of triangle abc closest to `p` (Ericson,
/// Real-Time Collision Detection §5.1.5: the Voronoi regions of the vertices, edges, face).
pub fn closest_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return Vec3::X;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return Vec3::Y;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return Vec3::new(1.0 - t, t, 0.0);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return Vec3::Z;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return Vec3::new(1.0 - t, 0.0, t);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Vec3::new(0.0, 1.0 - t, t);
    }
    let denominator = va + vb + vc;
    if denominator.abs() < 1e-20 {
        return Vec3::X;
    }
    let (v, w) = (vb / denominator, vc / denominator);
    Vec3::new(1.0 - v - w, v, w)
}

/// Binds every fine vertex to the nearest non-degenerate triangle of the control mesh at
/// rest (`control_positions`, `control_triangles`).
pub fn bind(
    fine_positions: &[Vec3],
    control_positions: &[Vec3],
    control_triangles: &[[u32; 3]],
) -> Result<Vec<WrapBinding>, WrapError> {
    let finite = |mesh, positions: &[Vec3]| match positions.iter().position(|p| !p.is_finite()) {
        Some(vertex) => Err(WrapError::NotFinite { mesh, vertex }),
        None => Ok(()),
    };
    finite("fine", fine_positions)?;
    finite("control", control_positions)?;
    let corners = |t: &[u32; 3]| t.map(|i| control_positions.get(i as usize).copied());
    // Only triangles with a frame can carry an offset; the index keeps their original numbers.
    let kept: Vec<u32> = (0..control_triangles.len() as u32)
        .filter(|&t| match corners(&control_triangles[t as usize]) {
            [Some(a), Some(b), Some(c)] => triangle_frame(a, b, c).is_some(),
            _ => false,
        })
        .collect();
    if kept.is_empty() {
        return Err(WrapError::NoTriangles);
    }
    let index = TriMesh::new(
        control_positions.iter().map(|&p| to_rapier(p)).collect(),
        kept.iter().map(|&t| control_triangles[t as usize]).collect(),
    )
    .map_err(|_| WrapError::NoTriangles)?;
    Ok(fine_positions
        .par_iter()
        .map(|&p| {
            // The hierarchy gives the smallest distance; the triangles within it (plus
            // rounding) are then ranked by our own closest point, ties to the lowest index,
            // so the choice is the one a scan of every triangle makes.
            let (nearest, _) = index.project_local_point_and_get_location(to_rapier(p), false);
            let reach = (p - from_rapier(nearest.point)).length() * (1.0 + 1e-4) + 1e-6;
            let window = Aabb::new(to_rapier(p - Vec3::splat(reach)), to_rapier(p + Vec3::splat(reach)));
            let mut best = (f32::INFINITY, u32::MAX, Vec3::X);
            for candidate in index.bvh().intersect_aabb(&window) {
                let triangle = kept[candidate as usize];
                let [a, b, c] = control_triangles[triangle as usize].map(|i| control_positions[i as usize]);
                let w = closest_barycentric(p, a, b, c);
                let d = (p - (a * w.x + b * w.y + c * w.z)).length_squared();
                if d < best.0 || (d == best.0 && triangle < best.1) {
                    best = (d, triangle, w);
                }
            }
            let (_, triangle, barycentric) = best;
            let [a, b, c] = control_triangles[triangle as usize].map(|i| control_positions[i as usize]);
            let [e, n, s] = triangle_frame(a, b, c).unwrap_or([Vec3::X, Vec3::Y, Vec3::Z]);
            let offset = p - (a * barycentric.x + b * barycentric.y + c * barycentric.z);
            WrapBinding { triangle, barycentric, local_offset: Vec3::new(offset.dot(e), offset.dot(n), offset.dot(s)) }
        })
        .collect())
}

/// Per-frame scratch: each control triangle's corners and frame, computed once per frame.
#[derive(Default)]
pub struct WrapScratch {
    triangles: Vec<([Vec3; 3], [Vec3; 3])>,
}

/// Fine vertex positions for one frame of the control mesh (`control_positions` deformed,
/// same topology as at binding), written into `out` (one per binding).
pub fn deform_frame(
    bindings: &[WrapBinding],
    control_positions: &[Vec3],
    control_triangles: &[[u32; 3]],
    scratch: &mut WrapScratch,
    out: &mut [Vec3],
) {
    scratch.triangles.clear();
    scratch.triangles.extend(control_triangles.iter().map(|t| {
        let [a, b, c] = t.map(|i| control_positions.get(i as usize).copied().unwrap_or(Vec3::ZERO));
        ([a, b, c], triangle_frame(a, b, c).unwrap_or([Vec3::X, Vec3::Y, Vec3::Z]))
    }));
    let triangles = &scratch.triangles;
    const CHUNK: usize = 4096;
    out.par_chunks_mut(CHUNK).zip(bindings.par_chunks(CHUNK)).for_each(|(out, bindings)| {
        for (o, b) in out.iter_mut().zip(bindings) {
            let ([pa, pb, pc], [e, n, s]) = triangles[b.triangle as usize];
            let (w, d) = (b.barycentric, b.local_offset);
            *o = pa * w.x + pb * w.y + pc * w.z + e * d.x + n * d.y + s * d.z;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hierarchy finds the triangle a scan of every triangle finds (the first of the
    /// nearest: the scan is the independent search), for points on, near and far from a
    /// bumpy sheet with a degenerate triangle in it; and replaying the binding on the rest
    /// mesh gives back the points.
    #[test]
    fn binding_finds_the_nearest_triangle_a_full_scan_finds() {
        let side = 12usize;
        let mut positions = Vec::new();
        for i in 0..=side {
            for j in 0..=side {
                let (x, z) = (i as f32 * 0.1, j as f32 * 0.1);
                positions.push(Vec3::new(x, 0.05 * (7.0 * x).sin() * (5.0 * z).cos(), z));
            }
        }
        let at = |i: usize, j: usize| (i * (side + 1) + j) as u32;
        let mut triangles = Vec::new();
        for i in 0..side {
            for j in 0..side {
                triangles.push([at(i, j), at(i, j + 1), at(i + 1, j)]);
                triangles.push([at(i + 1, j), at(i, j + 1), at(i + 1, j + 1)]);
            }
        }
        triangles.push([0, 0, 1]);
        let mut state = 0x9e37_79b9_u32;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        let points: Vec<Vec3> =
            (0..500).map(|_| Vec3::new(random() * 1.6 - 0.2, random() * 0.6 - 0.3, random() * 1.6 - 0.2)).collect();
        let bindings = bind(&points, &positions, &triangles).unwrap();
        let distance = |p: Vec3, t: usize| {
            let [a, b, c] = triangles[t].map(|i| positions[i as usize]);
            let w = closest_barycentric(p, a, b, c);
            (p - (a * w.x + b * w.y + c * w.z)).length_squared()
        };
        for (p, b) in points.iter().zip(&bindings) {
            let scanned = (0..triangles.len() - 1).map(|t| distance(*p, t)).fold(f32::INFINITY, f32::min);
            let first = (0..triangles.len() - 1).find(|&t| distance(*p, t) == scanned).unwrap();
            assert_eq!(b.triangle as usize, first, "{p}: {b:?}, the scan's first nearest is {first} at {scanned}");
        }
        let mut out = vec![Vec3::ZERO; points.len()];
        deform_frame(&bindings, &positions, &triangles, &mut WrapScratch::default(), &mut out);
        for (p, q) in points.iter().zip(&out) {
            assert!((*p - *q).length() < 1e-5, "{p} came back as {q}");
        }
    }

    /// A rigid motion of the control mesh moves the bound points rigidly (the offsets live
    /// in the triangles' frames): compared with the motion applied to the points directly.
    #[test]
    fn a_rigid_motion_of_the_control_mesh_moves_the_points_rigidly() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)];
        let triangles = [[0, 2, 1], [1, 2, 3]];
        let points = [Vec3::new(0.3, 0.2, 0.4), Vec3::new(0.9, -0.1, 0.8), Vec3::new(1.4, 0.3, -0.2)];
        let bindings = bind(&points, &positions, &triangles).unwrap();
        let motion = glam::Affine3A::from_rotation_translation(
            glam::Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 1.1),
            Vec3::new(0.5, 2.0, -1.0),
        );
        let moved: Vec<Vec3> = positions.iter().map(|&p| motion.transform_point3(p)).collect();
        let mut out = vec![Vec3::ZERO; points.len()];
        deform_frame(&bindings, &moved, &triangles, &mut WrapScratch::default(), &mut out);
        for (p, q) in points.iter().zip(&out) {
            assert!((motion.transform_point3(*p) - *q).length() < 1e-5, "{p}: {q}");
        }
    }

    /// A control triangle stretched and tilted (not a rigid motion), solved by hand: a
    /// point 0.3 below the face's middle keeps its barycentric place and its height along the
    /// new unit normal; a point 0.4 beyond edge ab keeps its distance along the new in-plane
    /// direction away from that edge. Triangle a = 0, b = x, c = z (normal −y); b goes to
    /// (2, 0, 0), c to (0, 0.5, 1): new normal (0, −2, 1)/√5, in-plane (0, −1, −2)/√5.
    #[test]
    fn offsets_replay_in_the_deformed_triangles_frame_as_solved_by_hand() {
        let triangles = [[0, 1, 2]];
        let rest = [Vec3::ZERO, Vec3::X, Vec3::Z];
        let points = [Vec3::new(0.25, -0.3, 0.25), Vec3::new(0.5, 0.0, -0.4)];
        let bindings = bind(&points, &rest, &triangles).unwrap();
        assert!((bindings[0].barycentric - Vec3::new(0.5, 0.25, 0.25)).length() < 1e-6, "{:?}", bindings[0]);
        assert!((bindings[1].barycentric - Vec3::new(0.5, 0.5, 0.0)).length() < 1e-6, "{:?}", bindings[1]);
        let deformed = [Vec3::ZERO, Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.5, 1.0)];
        let mut out = [Vec3::ZERO; 2];
        deform_frame(&bindings, &deformed, &triangles, &mut WrapScratch::default(), &mut out);
        let root5 = 5.0f32.sqrt();
        let expected = [
            Vec3::new(0.5, 0.125, 0.25) + 0.3 * Vec3::new(0.0, -2.0, 1.0) / root5,
            Vec3::new(1.0, 0.0, 0.0) + 0.4 * Vec3::new(0.0, -1.0, -2.0) / root5,
        ];
        for (got, want) in out.iter().zip(expected) {
            assert!((*got - want).length() < 1e-6, "{got} vs {want}");
        }
    }

    #[test]
    fn degenerate_or_non_finite_meshes_are_refused() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        assert_eq!(bind(&[Vec3::Y], &positions, &[[0, 1, 2]]), Err(WrapError::NoTriangles));
        assert_eq!(bind(&[Vec3::Y], &positions, &[]), Err(WrapError::NoTriangles));
        let good = vec![Vec3::ZERO, Vec3::X, Vec3::Z];
        assert_eq!(bind(&[Vec3::NAN], &good, &[[0, 2, 1]]), Err(WrapError::NotFinite { mesh: "fine", vertex: 0 }));
    }
}
