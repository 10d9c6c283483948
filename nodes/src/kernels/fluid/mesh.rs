//! The tetrahedral mesh the fluid lives on (Klingner et al. 2006, §3–4): nodes, positively
//! oriented tetrahedra, their unique faces with adjacency, and the dual geometry the
//! discretisation needs (tet and face circumcentres, face areas and normals, dual lengths).
//!
//! Conventions: metres, f64, right-handed, Y up. Face `f` has a unit normal pointing from
//! its first tet `face_tets[f][0]` into its second (`face_tets[f][1]`, [`NO_TET`] on the
//! boundary, where the normal points out of the fluid).

use glam::DVec3;

/// Dual lengths above −this × √(face area) count as Delaunay: cospherical ties (a box's
/// corners) give two tets the same circumcentre up to rounding.
pub const DUAL_TOLERANCE: f64 = 1e-9;

/// Marks "no tetrahedron" on the outside of a boundary face.
pub const NO_TET: u32 = u32::MAX;

/// Why a mesh cannot be built from the given nodes and tetrahedra.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// A tet names a node index past the end of the node list.
    #[error("tetrahedron {tet} names node {node}, but there are only {nodes} nodes")]
    NodeIndex {
        /// Tet index.
        tet: usize,
        /// The bad node index.
        node: u32,
        /// Number of nodes.
        nodes: usize,
    },
    /// A tet with (numerically) zero volume: no circumcentre.
    #[error("tetrahedron {tet} is flat (volume {volume_m3:e} m³)")]
    Degenerate {
        /// Tet index.
        tet: usize,
        /// Its volume.
        volume_m3: f64,
    },
    /// More than two tets share one face: not a manifold tetrahedralisation.
    #[error("face {nodes:?} is shared by more than two tetrahedra")]
    NonManifold {
        /// The face's node indices.
        nodes: [u32; 3],
    },
    /// An obstacle reaches outside the domain box.
    #[error("obstacle {obstacle} reaches outside the domain box (vertex {vertex} at {position_m} m)")]
    ObstacleOutside {
        /// Obstacle index.
        obstacle: usize,
        /// First vertex outside.
        vertex: usize,
        /// Its position.
        position_m: glam::DVec3,
    },
    /// An obstacle's surface is not closed and consistently oriented.
    #[error("obstacle {obstacle} is not a closed surface: edge {edge:?} has no opposite twin")]
    ObstacleNotClosed {
        /// Obstacle index.
        obstacle: usize,
        /// The open (or wrongly oriented) edge.
        edge: [u32; 2],
    },
    /// The requested resolution needs more tets than `max_tets` allows.
    #[error("the mesh needs about {tets} tetrahedra, more than max_tets = {max_tets}")]
    TooManyTets {
        /// Estimated or actual tet count.
        tets: usize,
        /// The limit.
        max_tets: usize,
    },
    /// The mesher failed or returned nothing usable.
    #[error("mesher failed: {0}")]
    Mesher(String),
}

/// Quality figures of one mesh, as a mesher reports them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshStats {
    /// Number of tetrahedra.
    pub tet_count: usize,
    /// Number of nodes.
    pub node_count: usize,
    /// Smallest dihedral angle over all tets, degrees.
    pub min_dihedral_deg: f64,
    /// Largest circumradius / shortest-edge ratio over all tets (1/√(8/3)·… ≈ 0.612 for a
    /// regular tet).
    pub max_radius_edge_ratio: f64,
    /// Interior faces whose two tet circumcentres are in reverse normal order (dual length
    /// below −[`DUAL_TOLERANCE`]·√area): 0 on a Delaunay mesh.
    pub non_delaunay_faces: usize,
    /// Interior faces whose dual length is below `projection::MIN_DUAL_FRACTION`·√area
    /// (non-Delaunay or nearly cospherical): the pressure solve clamps them.
    pub clamped_dual_faces: usize,
}

/// A tetrahedral mesh with its Delaunay dual geometry, ready for the fluid discretisation.
#[derive(Debug, Clone, PartialEq)]
pub struct TetMesh {
    /// Node positions, metres.
    pub nodes_m: Vec<DVec3>,
    /// Tets as node indices, positively oriented ((b−a)·((c−a)×(d−a)) > 0).
    pub tets: Vec<[u32; 4]>,
    /// Tet volumes, m³.
    pub tet_volume_m3: Vec<f64>,
    /// Tet circumcentres (pressure sample points), metres.
    pub tet_circumcentre_m: Vec<DVec3>,
    /// Tet circumradii, metres.
    pub tet_circumradius_m: Vec<f64>,
    /// Per tet, the face opposite each local vertex.
    pub tet_faces: Vec<[u32; 4]>,
    /// Per tet and local face: +1 when the face normal points out of this tet, −1 otherwise.
    pub tet_face_sign: Vec<[f64; 4]>,
    /// Faces as node indices, ordered so that (b−a)×(c−a) points along the face normal.
    pub faces: Vec<[u32; 3]>,
    /// The two tets of each face, normal pointing from the first into the second;
    /// the second is [`NO_TET`] on the boundary.
    pub face_tets: Vec<[u32; 2]>,
    /// Unit face normals.
    pub face_normal: Vec<DVec3>,
    /// Face areas, m².
    pub face_area_m2: Vec<f64>,
    /// Face circumcentres (velocity sample points), metres.
    pub face_circumcentre_m: Vec<DVec3>,
    /// Signed dual length along the normal, metres: (c_b − c_a)·n between the two tet
    /// circumcentres, or (x_f − c_a)·n from the tet circumcentre to the face circumcentre on
    /// the boundary. Positive on a Delaunay mesh (interior faces).
    pub face_dual_length_m: Vec<f64>,
}

/// Smallest of the six dihedral angles of the tet `p`, degrees: 70.5° for a regular tet,
/// near 0° for a sliver (four nearly coplanar nodes), 0° for a flat one. The angle at the
/// edge shared by the faces opposite nodes k and l is π less the angle between their outward
/// normals.
pub fn min_dihedral_deg(p: [DVec3; 4]) -> f64 {
    let outward = |k: usize| {
        let [a, b, c] = [(k + 1) % 4, (k + 2) % 4, (k + 3) % 4].map(|j| p[j]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        if (p[k] - a).dot(n) > 0.0 { -n } else { n }
    };
    let normals: [DVec3; 4] = std::array::from_fn(outward);
    let mut smallest: f64 = 180.0;
    for k in 0..4 {
        for l in k + 1..4 {
            let cos = (-normals[k].dot(normals[l])).clamp(-1.0, 1.0);
            smallest = smallest.min(cos.acos().to_degrees());
        }
    }
    if normals.contains(&DVec3::ZERO) { 0.0 } else { smallest }
}

/// Circumcentre of the tet (a, b, c, d); `None` when it is flat.
pub fn tet_circumcentre(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> Option<DVec3> {
    let (u, v, w) = (b - a, c - a, d - a);
    let det = 2.0 * u.dot(v.cross(w));
    let scale = u.length_squared().max(v.length_squared()).max(w.length_squared());
    if det.abs() <= 1e-14 * scale * scale.sqrt() {
        return None;
    }
    let num = u.length_squared() * v.cross(w) + v.length_squared() * w.cross(u) + w.length_squared() * u.cross(v);
    Some(a + num / det)
}

/// Circumcentre of the triangle (a, b, c); `None` when it is flat.
pub fn triangle_circumcentre(a: DVec3, b: DVec3, c: DVec3) -> Option<DVec3> {
    let (u, v) = (b - a, c - a);
    let n = u.cross(v);
    let nn = n.length_squared();
    if nn <= 1e-28 * u.length_squared().max(v.length_squared()).powi(2) {
        return None;
    }
    Some(a + (u.length_squared() * v.cross(n) + v.length_squared() * n.cross(u)) / (2.0 * nn))
}

/// Signed volume of the tet (a, b, c, d), m³: positive when (b−a, c−a, d−a) is right-handed.
pub fn signed_volume(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    (b - a).dot((c - a).cross(d - a)) / 6.0
}

/// Local vertex indices of the face opposite local vertex `k`.
const OPPOSITE: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

impl TetMesh {
    /// Builds the mesh and its dual geometry from nodes and tets (any orientation).
    ///
    /// Steps: 1. orient every tet positively; 2. collect the four faces of every tet, sort
    /// them by node triple and pair equal ones (deterministic, no hashing); 3. per face,
    /// orient the normal out of its first tet, compute area and circumcentre; 4. per tet,
    /// circumcentre and radius; 5. dual lengths.
    pub fn new(nodes_m: Vec<DVec3>, mut tets: Vec<[u32; 4]>) -> Result<TetMesh, MeshError> {
        let n = nodes_m.len();
        let mut tet_volume_m3 = Vec::with_capacity(tets.len());
        let mut tet_circumcentre_m = Vec::with_capacity(tets.len());
        let mut tet_circumradius_m = Vec::with_capacity(tets.len());
        for (t, tet) in tets.iter_mut().enumerate() {
            if let Some(&bad) = tet.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::NodeIndex { tet: t, node: bad, nodes: n });
            }
            let p = tet.map(|i| nodes_m[i as usize]);
            let mut volume = signed_volume(p[0], p[1], p[2], p[3]);
            if volume < 0.0 {
                tet.swap(2, 3);
                volume = -volume;
            }
            let centre =
                tet_circumcentre(p[0], p[1], p[2], p[3]).ok_or(MeshError::Degenerate { tet: t, volume_m3: volume })?;
            if volume <= 0.0 {
                return Err(MeshError::Degenerate { tet: t, volume_m3: volume });
            }
            tet_volume_m3.push(volume);
            tet_circumcentre_m.push(centre);
            tet_circumradius_m.push((centre - p[0]).length());
        }

        // Every (sorted face key, tet, local face) once; equal keys end up adjacent.
        let mut halves: Vec<([u32; 3], u32, u8)> = Vec::with_capacity(tets.len() * 4);
        for (t, tet) in tets.iter().enumerate() {
            for (k, opposite) in OPPOSITE.iter().enumerate() {
                let mut key = opposite.map(|l| tet[l]);
                key.sort_unstable();
                halves.push((key, t as u32, k as u8));
            }
        }
        halves.sort_unstable();

        let mut mesh = TetMesh {
            tet_faces: vec![[0; 4]; tets.len()],
            tet_face_sign: vec![[1.0; 4]; tets.len()],
            nodes_m,
            tets,
            tet_volume_m3,
            tet_circumcentre_m,
            tet_circumradius_m,
            faces: Vec::new(),
            face_tets: Vec::new(),
            face_normal: Vec::new(),
            face_area_m2: Vec::new(),
            face_circumcentre_m: Vec::new(),
            face_dual_length_m: Vec::new(),
        };
        let mut i = 0;
        while i < halves.len() {
            let (key, ta, ka) = halves[i];
            let mut j = i + 1;
            while j < halves.len() && halves[j].0 == key {
                j += 1;
            }
            if j - i > 2 {
                return Err(MeshError::NonManifold { nodes: key });
            }
            let f = mesh.faces.len() as u32;
            let tet_a = mesh.tets[ta as usize];
            // OPPOSITE lists each face counter-clockwise seen from outside a positive tet.
            let nodes = OPPOSITE[ka as usize].map(|l| tet_a[l]);
            let p = nodes.map(|v| mesh.nodes_m[v as usize]);
            let cross = (p[1] - p[0]).cross(p[2] - p[0]);
            let area = 0.5 * cross.length();
            let normal = cross.try_normalize().ok_or(MeshError::Degenerate { tet: ta as usize, volume_m3: 0.0 })?;
            let centre = triangle_circumcentre(p[0], p[1], p[2])
                .ok_or(MeshError::Degenerate { tet: ta as usize, volume_m3: 0.0 })?;
            mesh.tet_faces[ta as usize][ka as usize] = f;
            mesh.tet_face_sign[ta as usize][ka as usize] = 1.0;
            let second = if j - i == 2 {
                let (_, tb, kb) = halves[i + 1];
                mesh.tet_faces[tb as usize][kb as usize] = f;
                mesh.tet_face_sign[tb as usize][kb as usize] = -1.0;
                tb
            } else {
                NO_TET
            };
            let ca = mesh.tet_circumcentre_m[ta as usize];
            let dual = if second == NO_TET {
                (centre - ca).dot(normal)
            } else {
                (mesh.tet_circumcentre_m[second as usize] - ca).dot(normal)
            };
            mesh.faces.push(nodes);
            mesh.face_tets.push([ta, second]);
            mesh.face_normal.push(normal);
            mesh.face_area_m2.push(area);
            mesh.face_circumcentre_m.push(centre);
            mesh.face_dual_length_m.push(dual);
            i = j;
        }
        Ok(mesh)
    }

    /// Number of tets.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// Whether face `f` lies on the boundary of the fluid.
    pub fn is_boundary(&self, f: usize) -> bool {
        self.face_tets[f][1] == NO_TET
    }

    /// Total volume, m³.
    pub fn volume_m3(&self) -> f64 {
        self.tet_volume_m3.iter().sum()
    }

    /// Centroid (barycentre) of tet `t`.
    pub fn tet_centroid(&self, t: usize) -> DVec3 {
        self.tets[t].iter().map(|&i| self.nodes_m[i as usize]).sum::<DVec3>() * 0.25
    }

    /// Outward unit normals and areas of tet `t`'s four faces (opposite each local vertex).
    pub fn outward_faces(&self, t: usize) -> [(DVec3, f64, usize); 4] {
        let faces = self.tet_faces[t];
        let signs = self.tet_face_sign[t];
        std::array::from_fn(|k| {
            let f = faces[k] as usize;
            (self.face_normal[f] * signs[k], self.face_area_m2[f], f)
        })
    }

    /// Smallest of tet `t`'s six dihedral angles, degrees ([`min_dihedral_deg`]).
    pub fn min_dihedral_deg(&self, t: usize) -> f64 {
        min_dihedral_deg(self.tets[t].map(|i| self.nodes_m[i as usize]))
    }

    /// Quality figures: tet count, min dihedral angle, max radius–edge ratio, non-Delaunay
    /// interior faces.
    pub fn stats(&self) -> MeshStats {
        let mut min_dihedral = f64::INFINITY;
        let mut max_ratio: f64 = 0.0;
        for t in 0..self.tets.len() {
            min_dihedral = min_dihedral.min(self.min_dihedral_deg(t));
            let p = self.tets[t].map(|i| self.nodes_m[i as usize]);
            let mut shortest = f64::INFINITY;
            for k in 0..4 {
                for l in k + 1..4 {
                    shortest = shortest.min((p[k] - p[l]).length());
                }
            }
            max_ratio = max_ratio.max(self.tet_circumradius_m[t] / shortest);
        }
        let non_delaunay = (0..self.faces.len())
            .filter(|&f| {
                !self.is_boundary(f) && self.face_dual_length_m[f] < -DUAL_TOLERANCE * self.face_area_m2[f].sqrt()
            })
            .count();
        let clamped = (0..self.faces.len())
            .filter(|&f| {
                !self.is_boundary(f)
                    && self.face_dual_length_m[f] < super::projection::MIN_DUAL_FRACTION * self.face_area_m2[f].sqrt()
            })
            .count();
        MeshStats {
            clamped_dual_faces: clamped,
            tet_count: self.tets.len(),
            node_count: self.nodes_m.len(),
            min_dihedral_deg: if min_dihedral.is_finite() { min_dihedral } else { 0.0 },
            max_radius_edge_ratio: max_ratio,
            non_delaunay_faces: non_delaunay,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn regular_corner_tet_has_known_circumcentre_and_faces() {
        // The corner tet (0, e_x, e_y, e_z): circumcentre (½, ½, ½) by symmetry, volume 1/6.
        let nodes = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        let mesh = TetMesh::new(nodes, vec![[0, 2, 1, 3]]).expect("mesh");
        assert!((mesh.tet_circumcentre_m[0] - DVec3::splat(0.5)).length() < 1e-15);
        assert!((mesh.tet_volume_m3[0] - 1.0 / 6.0).abs() < 1e-15);
        assert_eq!(mesh.faces.len(), 4);
        // The slanted face x+y+z=1 has area √3/2 and circumcentre (⅓, ⅓, ⅓).
        let slanted = (0..4).find(|&f| mesh.face_normal[f].x > 0.1).expect("slanted face");
        assert!((mesh.face_area_m2[slanted] - 3f64.sqrt() / 2.0).abs() < 1e-14);
        assert!((mesh.face_circumcentre_m[slanted] - DVec3::splat(1.0 / 3.0)).length() < 1e-15);
        assert!((mesh.face_normal[slanted] - DVec3::splat(1.0 / 3f64.sqrt())).length() < 1e-15);
        // All normals point out of the single tet.
        for f in 0..4 {
            assert!((mesh.face_circumcentre_m[f] - mesh.tet_centroid(0)).dot(mesh.face_normal[f]) > 0.0);
        }
    }

    #[test]
    fn dihedral_angles_of_known_tets() {
        // Regular tet: every dihedral angle is acos(1/3) = 70.53°.
        let regular = [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ];
        assert!((min_dihedral_deg(regular) - (1.0f64 / 3.0).acos().to_degrees()).abs() < 1e-12);
        // Corner tet: 90° at the three axis edges, acos(1/√3) = 54.74° at the slanted ones.
        let corner = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        assert!((min_dihedral_deg(corner) - (1.0 / 3f64.sqrt()).acos().to_degrees()).abs() < 1e-12);
        // A sliver: a unit square's corners lifted ±h alternately. At a square's edge, the
        // other two nodes seen along it are at (±4h²/s, 1, ±2h/s), s = 1 + 4h², so the angle
        // is 2·atan(2h/√s), about 4h rad.
        let h = 1e-3;
        let sliver =
            [DVec3::new(0.0, 0.0, h), DVec3::new(1.0, 0.0, -h), DVec3::new(1.0, 1.0, h), DVec3::new(0.0, 1.0, -h)];
        let expected = 2.0 * (2.0 * h / (1.0 + 4.0 * h * h).sqrt()).atan();
        assert!((min_dihedral_deg(sliver) - expected.to_degrees()).abs() < 1e-9);
        // Flat: 0.
        assert_eq!(min_dihedral_deg([DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)]), 0.0);
    }

    #[test]
    fn flat_tet_is_refused() {
        let nodes = vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 0.0)];
        assert!(matches!(TetMesh::new(nodes, vec![[0, 1, 2, 3]]), Err(MeshError::Degenerate { .. })));
    }
}
