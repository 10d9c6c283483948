//! Triangle meshes and their skin bindings.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};

use super::material::{Material, MaterialRange};
use super::skeleton::Skeleton;

/// Per-vertex joint influences and the bind pose of a skinned mesh.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Skin {
    /// The skeleton the joint indices refer to.
    pub skeleton: Arc<Skeleton>,
    /// Up to four joint indices per vertex (into `skeleton`).
    pub joints: Vec<[u16; 4]>,
    /// Matching weights per vertex, each row summing to one.
    pub weights: Vec<[f32; 4]>,
    /// Per skeleton joint: the inverse of its world transform in the bind pose (metres).
    pub inverse_bind_matrices: Vec<Mat4>,
}

impl Skin {
    /// The joint vertex `v` is bound to most, with its weight: what "the vertex belongs to
    /// that joint" means for soles, bar-net selections and physics shapes.
    pub fn heaviest_joint(&self, v: usize) -> (usize, f32) {
        let (joints, weights) = (&self.joints[v], &self.weights[v]);
        let k = (0..4).max_by(|&a, &b| weights[a].total_cmp(&weights[b])).unwrap_or(0);
        (usize::from(joints[k]), weights[k])
    }
}

/// A triangle mesh (metres, Y up), optionally skinned.
#[derive(Clone, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Mesh {
    /// Name from the source file.
    pub name: String,
    /// Vertex positions (metres).
    pub positions: Vec<Vec3>,
    /// Unit vertex normals, one per position.
    pub normals: Vec<Vec3>,
    /// Texture coordinates, one per position, when the source had them.
    pub uvs: Option<Vec<Vec2>>,
    /// Counter-clockwise triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Skin binding, if the mesh deforms with a skeleton.
    pub skin: Option<Skin>,
    /// Surface materials, referred to by `material_ranges`.
    #[serde(default)]
    pub materials: Vec<Material>,
    /// Which material each run of triangles uses, covering every triangle in order; empty
    /// when the mesh has no materials (drawn with the viewer's default).
    #[serde(default)]
    pub material_ranges: Vec<MaterialRange>,
    /// The source meshes this one was merged from (a character's body, joints, eyes…), in
    /// order, covering every vertex and triangle, so an export writes them back as separate
    /// objects; empty when the mesh is one object.
    #[serde(default)]
    pub parts: Vec<MeshPart>,
}

/// A source mesh inside a merged [`Mesh`]: a run of its vertices and a run of its triangles
/// that index only those vertices.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct MeshPart {
    /// The source mesh's name.
    pub name: String,
    /// The name of the object (glTF node) that held it in the source, when it had one:
    /// what a viewer lists, which may differ from the mesh's own name.
    #[serde(default)]
    pub object: Option<String>,
    /// Index of its first vertex in the merged mesh.
    pub first_vertex: usize,
    /// How many vertices it has.
    pub vertex_count: usize,
    /// Index of its first triangle in the merged mesh.
    pub first_triangle: usize,
    /// How many triangles it has.
    pub triangle_count: usize,
}

impl Mesh {
    /// Bytes a skinned mesh of this size holds (positions, normals, UVs, four joints and
    /// weights per vertex, triangles): the estimate nodes check before building one.
    pub fn estimated_bytes(vertices: usize, triangles: usize) -> u64 {
        const PER_VERTEX: u64 = 12 + 12 + 8 + 8 + 16;
        (vertices as u64).saturating_mul(PER_VERTEX).saturating_add((triangles as u64).saturating_mul(12))
    }

    /// Area-weighted vertex normals from the triangles; vertices no triangle touches (or
    /// touched only by degenerate triangles) get +Y rather than NaN.
    pub fn compute_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; positions.len()];
        for tri in triangles {
            let [a, b, c] = tri.map(|i| i as usize);
            let (Some(pa), Some(pb), Some(pc)) = (positions.get(a), positions.get(b), positions.get(c)) else {
                continue;
            };
            let n = (*pb - *pa).cross(*pc - *pa);
            for i in [a, b, c] {
                normals[i] += n;
            }
        }
        normals.into_iter().map(|n| n.try_normalize().unwrap_or(Vec3::Y)).collect()
    }

    /// Appends a box given by its eight corners (`corner(i)`: bit 0, 1 and 2 of `i` pick
    /// the far end along the box's first, second and third edge; the edges right-handed)
    /// as six faces of four vertices each, so every face keeps its own normal and, when the
    /// mesh has UVs, the unit square.
    pub fn push_box(&mut self, corner: impl Fn(usize) -> Vec3) {
        const FACES: [[usize; 4]; 6] =
            [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        for face in FACES {
            let base = self.positions.len() as u32;
            let p = face.map(&corner);
            let normal = (p[1] - p[0]).cross(p[2] - p[0]).try_normalize().unwrap_or(Vec3::Y);
            self.positions.extend(p);
            self.normals.extend([normal; 4]);
            if let Some(uvs) = &mut self.uvs {
                uvs.extend([Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)]);
            }
            self.triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        }
    }

    /// Index of `material` in the mesh's materials, adding it when no equal one is there
    /// (merged meshes that share a source material share one entry).
    pub fn material_index(&mut self, material: &Material) -> usize {
        match self.materials.iter().position(|m| m == material) {
            Some(i) => i,
            None => {
                self.materials.push(material.clone());
                self.materials.len() - 1
            }
        }
    }

    /// Records that the next `triangle_count` triangles after those already covered by
    /// ranges use `material` (merged into the last run when it has the same material).
    pub fn push_material_range(&mut self, material: Option<usize>, triangle_count: usize) {
        let first_triangle = self.material_ranges.last().map_or(0, |r| r.first_triangle + r.triangle_count);
        match self.material_ranges.last_mut() {
            Some(last) if last.material == material => last.triangle_count += triangle_count,
            _ if triangle_count > 0 => {
                self.material_ranges.push(MaterialRange { first_triangle, triangle_count, material })
            }
            _ => {}
        }
    }

    /// Appends `part`'s materials and ranges after the triangles already covered, its
    /// material indices remapped into this mesh's list. Call once per merged part, in the
    /// order its triangles were appended.
    pub fn append_materials_of(&mut self, part: &Mesh) {
        let map: Vec<usize> = part.materials.iter().map(|m| self.material_index(m)).collect();
        if part.material_ranges.is_empty() {
            self.push_material_range(None, part.triangles.len());
        }
        for r in &part.material_ranges {
            self.push_material_range(r.material.and_then(|m| map.get(m).copied()), r.triangle_count);
        }
    }

    /// Drops ranges that carry no material at all, so a mesh without materials keeps the
    /// plain single-material form.
    pub fn drop_empty_material_ranges(&mut self) {
        if self.material_ranges.iter().all(|r| r.material.is_none()) {
            self.material_ranges.clear();
        }
    }

    /// Checks that the ranges cover every triangle once, in order, with valid material
    /// indices; the message says what is wrong.
    pub fn check_material_ranges(&self) -> Result<(), String> {
        if self.material_ranges.is_empty() {
            return Ok(());
        }
        let mut next = 0;
        for (k, r) in self.material_ranges.iter().enumerate() {
            if r.first_triangle != next {
                return Err(format!("material range {k} starts at triangle {}, expected {next}", r.first_triangle));
            }
            if let Some(m) = r.material.filter(|&m| m >= self.materials.len()) {
                return Err(format!("material range {k} uses material {m} of {}", self.materials.len()));
            }
            next += r.triangle_count;
        }
        if next != self.triangles.len() {
            return Err(format!("material ranges cover {next} of {} triangles", self.triangles.len()));
        }
        Ok(())
    }

    /// Records that the vertices and triangles appended since the parts already recorded
    /// came from the source mesh `name`, held by the object named `object`.
    pub fn push_part(&mut self, name: &str, object: Option<&str>) {
        let (first_vertex, first_triangle) = self
            .parts
            .last()
            .map_or((0, 0), |p| (p.first_vertex + p.vertex_count, p.first_triangle + p.triangle_count));
        self.parts.push(MeshPart {
            name: name.to_owned(),
            object: object.map(str::to_owned),
            first_vertex,
            vertex_count: self.positions.len().saturating_sub(first_vertex),
            first_triangle,
            triangle_count: self.triangles.len().saturating_sub(first_triangle),
        });
    }

    /// The objects an export writes: the parts, or the whole mesh under its own name when
    /// it has none.
    pub fn objects(&self) -> Vec<MeshPart> {
        if !self.parts.is_empty() {
            return self.parts.clone();
        }
        vec![MeshPart {
            name: self.name.clone(),
            object: None,
            first_vertex: 0,
            vertex_count: self.positions.len(),
            first_triangle: 0,
            triangle_count: self.triangles.len(),
        }]
    }

    /// Checks that the parts cover every vertex and triangle once, in order, and that each
    /// part's triangles use only its own vertices; the message says what is wrong.
    pub fn check_parts(&self) -> Result<(), String> {
        if self.parts.is_empty() {
            return Ok(());
        }
        let (mut vertex, mut triangle) = (0, 0);
        for p in &self.parts {
            if p.first_vertex != vertex || p.first_triangle != triangle {
                return Err(format!(
                    "part '{}' starts at vertex {} and triangle {}, expected {vertex} and {triangle}",
                    p.name, p.first_vertex, p.first_triangle
                ));
            }
            let vertices = p.first_vertex..p.first_vertex + p.vertex_count;
            let triangles = self.triangles.get(p.first_triangle..p.first_triangle + p.triangle_count);
            let Some(triangles) = triangles else {
                return Err(format!("part '{}' runs past the {} triangles", p.name, self.triangles.len()));
            };
            if let Some(t) = triangles.iter().position(|t| t.iter().any(|&i| !vertices.contains(&(i as usize)))) {
                return Err(format!(
                    "part '{}' triangle {} uses a vertex outside its vertices {}..{}",
                    p.name,
                    p.first_triangle + t,
                    vertices.start,
                    vertices.end
                ));
            }
            vertex = vertices.end;
            triangle += p.triangle_count;
        }
        if vertex != self.positions.len() || triangle != self.triangles.len() {
            return Err(format!(
                "parts cover {vertex} of {} vertices and {triangle} of {} triangles",
                self.positions.len(),
                self.triangles.len()
            ));
        }
        Ok(())
    }

    /// Axis-aligned bounds `(min, max)` of the positions, `None` when empty.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_a_ccw_quad_point_up_and_degenerate_ones_stay_finite() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 0.0, -1.0), Vec3::ZERO];
        let normals = Mesh::compute_normals(&positions, &[[0, 1, 2], [0, 2, 3], [4, 4, 4]]);
        for n in &normals[..4] {
            assert!((*n - Vec3::Y).length() < 1e-6);
        }
        assert_eq!(normals[4], Vec3::Y);
    }

    /// Three parts merged: A (2 triangles of `skin`, then 1 of `cloth`), B (no materials, 2
    /// triangles) and C (1 of its own `cloth`, equal to A's): hand-counted runs, `cloth`
    /// stored once, B's triangles on the default material.
    #[test]
    fn merged_parts_remap_and_share_materials() {
        use crate::model::{Material, MaterialRange};
        let named = |n: &str| Material { name: Some(n.into()), ..Material::default() };
        let part = |triangles: usize, materials: Vec<Material>, ranges: Vec<(usize, usize, Option<usize>)>| Mesh {
            triangles: vec![[0, 0, 0]; triangles],
            materials,
            material_ranges: ranges
                .into_iter()
                .map(|(first_triangle, triangle_count, material)| MaterialRange {
                    first_triangle,
                    triangle_count,
                    material,
                })
                .collect(),
            ..Mesh::default()
        };
        let a = part(3, vec![named("skin"), named("cloth")], vec![(0, 2, Some(0)), (2, 1, Some(1))]);
        let b = part(2, vec![], vec![]);
        let c = part(1, vec![named("cloth")], vec![(0, 1, Some(0))]);
        let mut merged = Mesh::default();
        for p in [&a, &b, &c] {
            merged.triangles.extend_from_slice(&p.triangles);
            merged.append_materials_of(p);
        }
        merged.drop_empty_material_ranges();
        assert_eq!(merged.materials, vec![named("skin"), named("cloth")]);
        let runs: Vec<_> =
            merged.material_ranges.iter().map(|r| (r.first_triangle, r.triangle_count, r.material)).collect();
        assert_eq!(runs, vec![(0, 2, Some(0)), (2, 1, Some(1)), (3, 2, None), (5, 1, Some(1))]);
        assert_eq!(merged.check_material_ranges(), Ok(()));
        // Without any material the ranges go, and a miscount is named.
        let mut plain = Mesh::default();
        plain.triangles.extend_from_slice(&b.triangles);
        plain.append_materials_of(&b);
        plain.drop_empty_material_ranges();
        assert!(plain.material_ranges.is_empty());
        merged.triangles.pop();
        assert_eq!(merged.check_material_ranges(), Err("material ranges cover 6 of 5 triangles".into()));
    }

    /// Two source meshes appended one after the other (a quad of 4 vertices and 2
    /// triangles, then a triangle of 3): hand-counted runs, and each way of breaking them is
    /// named.
    #[test]
    fn parts_record_appended_meshes_and_broken_ones_are_named() {
        let mut mesh = Mesh::default();
        mesh.positions.extend([Vec3::ZERO; 4]);
        mesh.triangles.extend([[0, 1, 2], [0, 2, 3]]);
        mesh.push_part("quad", Some("lid"));
        mesh.positions.extend([Vec3::ZERO; 3]);
        mesh.triangles.push([4, 5, 6]);
        mesh.push_part("tri", None);
        let runs: Vec<_> =
            mesh.parts.iter().map(|p| (p.first_vertex, p.vertex_count, p.first_triangle, p.triangle_count)).collect();
        assert_eq!(runs, vec![(0, 4, 0, 2), (4, 3, 2, 1)]);
        assert_eq!(mesh.check_parts(), Ok(()));
        assert_eq!(mesh.objects(), mesh.parts);
        let mut crossing = mesh.clone();
        crossing.triangles[2] = [3, 5, 6];
        assert_eq!(crossing.check_parts(), Err("part 'tri' triangle 2 uses a vertex outside its vertices 4..7".into()));
        let mut short = mesh.clone();
        short.positions.push(Vec3::ZERO);
        assert_eq!(short.check_parts(), Err("parts cover 7 of 8 vertices and 3 of 3 triangles".into()));
        // Without parts the mesh is one object under its own name.
        let whole = Mesh { name: "body".into(), parts: Vec::new(), ..mesh };
        let objects = whole.objects();
        assert_eq!(objects.len(), 1);
        assert_eq!((objects[0].name.as_str(), objects[0].vertex_count, objects[0].triangle_count), ("body", 7, 3));
    }
}
