//! Fluid volumes as they travel between nodes: the simulation domain a `fluid.domain` node
//! describes, and the `volume_sequence` a `fluid.simulate` node produces (per frame, smoke
//! density, temperature and velocity on a regular voxel lattice, plus the marker particles).
//! Metres, seconds, kelvin; Y up.

use glam::{IVec3, Vec3};

/// A sphere that emits smoke: every step, the fluid inside it is set to `density` and
/// `temperature_k`, and `particles_per_step` marker particles are seeded in it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SmokeSource {
    /// Centre, metres.
    pub centre_m: [f64; 3],
    /// Radius, metres.
    pub radius_m: f64,
    /// Smoke density set inside, kg/m³ of smoke (any concentration unit).
    pub density: f64,
    /// Temperature set inside, K.
    pub temperature_k: f64,
    /// Marker particles seeded per step.
    pub particles_per_step: usize,
}

/// The sizing field μ(x) = k0 + kd·d(x) + ks·s(x) + kω·ω(x) of Klingner et al. (2006, §6):
/// the wanted edge length at x, from the distance to the nearest obstacle d (m), the smoke
/// density s and the vorticity magnitude ω (1/s). Negative ks, kω refine where there is
/// smoke or swirl; the result is clamped to [`Sizing::min_edge_m`, `Sizing::max_edge_m`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sizing {
    /// k0: edge length at an obstacle's surface in still, clear fluid, metres.
    pub k0_m: f64,
    /// kd: growth of the edge length with distance from the obstacles (m per m).
    pub kd: f64,
    /// ks: change of the edge length per unit smoke density (m per kg/m³).
    pub ks_m: f64,
    /// kω: change of the edge length per unit vorticity (m per 1/s).
    pub kw_m_s: f64,
    /// Smallest edge length, metres.
    pub min_edge_m: f64,
    /// Largest edge length, metres.
    pub max_edge_m: f64,
}

impl Sizing {
    /// μ at a point with obstacle distance `d_m`, smoke density `s` and vorticity `w_1_s`.
    pub fn edge_m(&self, d_m: f64, s: f64, w_1_s: f64) -> f64 {
        (self.k0_m + self.kd * d_m + self.ks_m * s + self.kw_m_s * w_1_s).clamp(self.min_edge_m, self.max_edge_m)
    }
}

/// What `fluid.simulate` fills with smoke: an axis-aligned box of air.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FluidDomain {
    /// Lower corner, metres.
    pub min_m: [f64; 3],
    /// Upper corner, metres.
    pub max_m: [f64; 3],
    /// The mesh's sizing field.
    pub sizing: Sizing,
    /// TetGen's radius–edge bound for the box's own quality mesh.
    pub max_radius_edge_ratio: f64,
    /// Refuse steps whose mesh would need more tets.
    pub max_tets: usize,
    /// Whether the top face (largest y) is open (pressure 0 outside) instead of a wall.
    pub open_top: bool,
    /// Smoke sources.
    pub sources: Vec<SmokeSource>,
    /// Buoyancy: downward pull per unit smoke density, m/s² per (kg/m³).
    pub buoyancy_alpha: f64,
    /// Buoyancy: upward push per kelvin above ambient, m/s² per K.
    pub buoyancy_beta: f64,
    /// Ambient temperature, K.
    pub ambient_k: f64,
    /// Edge of one voxel of the output volumes, metres.
    pub voxel_m: f64,
}

/// The voxel lattice of a volume sequence: voxel (i, j, k) of the arrays is centred at
/// (`origin` + (i, j, k)) · `voxel_m` (so the lattice is the one OpenVDB's uniform scale
/// transform describes, and files of one sequence align).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VoxelGrid {
    /// Index of the first voxel.
    pub origin: IVec3,
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Voxel edge, metres.
    pub voxel_m: f32,
}

impl VoxelGrid {
    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Whether the grid holds no voxel.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Array index of local voxel (i, j, k): x fastest.
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    /// Global (OpenVDB) coordinate of the voxel at array index `n`.
    pub fn coord(&self, n: usize) -> IVec3 {
        let i = n % self.dims[0];
        let j = (n / self.dims[0]) % self.dims[1];
        let k = n / (self.dims[0] * self.dims[1]);
        self.origin + IVec3::new(i as i32, j as i32, k as i32)
    }

    /// Centre of the voxel at array index `n`, metres.
    pub fn centre_m(&self, n: usize) -> Vec3 {
        self.coord(n).as_vec3() * self.voxel_m
    }

    /// Array index of the voxel holding the point `p_m` (metres), if it is on the grid: the
    /// inverse of [`VoxelGrid::centre_m`].
    pub fn index_at(&self, p_m: Vec3) -> Option<usize> {
        let local = (p_m / self.voxel_m).round().as_ivec3() - self.origin;
        let inside = (0..3).all(|a| local[a] >= 0 && (local[a] as usize) < self.dims[a]);
        inside.then(|| self.index(local.x as usize, local.y as usize, local.z as usize))
    }

    /// The same lattice turned by [`y_up_to_z_up`], and for each of its voxels (array
    /// order) the index of the voxel of `self` that lands there. A rotation of the index
    /// lattice, so values are moved, never interpolated.
    pub fn z_up(&self) -> (VoxelGrid, Vec<usize>) {
        let [nx, ny, nz] = self.dims;
        let o = self.origin;
        // Voxel (i, j, k) goes to (i, nz − 1 − k, j) of the new grid, whose first voxel is
        // the turned corner (ox, −(oz + nz − 1), oy).
        let turned = VoxelGrid {
            origin: IVec3::new(o.x, -(o.z + nz as i32 - 1), o.y),
            dims: [nx, nz, ny],
            voxel_m: self.voxel_m,
        };
        let mut from = Vec::with_capacity(self.len());
        for c in 0..ny {
            for b in 0..nz {
                for a in 0..nx {
                    from.push(self.index(a, c, nz - 1 - b));
                }
            }
        }
        (turned, from)
    }
}

/// The axis change Blender's glTF importer makes, from Y up to Z up: (x, y, z) → (x, −z, y).
/// Files written with it line up in Blender with characters exported as GLB.
pub fn y_up_to_z_up(p: [f32; 3]) -> [f32; 3] {
    [p[0], -p[2], p[1]]
}

/// One frame of a volume sequence: values per voxel of the sequence's grid (0 outside the
/// fluid), the marker particles and the free bodies.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeFrame {
    /// Smoke density per voxel.
    pub density: Vec<f32>,
    /// Temperature above ambient per voxel, K.
    pub temperature_k: Vec<f32>,
    /// Velocity per voxel, m/s.
    pub velocity_m_s: Vec<[f32; 3]>,
    /// Marker particle positions, metres.
    pub particles_m: Vec<[f32; 3]>,
    /// The free rigid bodies in the smoke at this frame (none without any), for display.
    #[serde(default)]
    pub bodies: Vec<BodyPose>,
}

/// The shape of a free rigid body in the smoke.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum BodyShape {
    /// A sphere of this radius, metres.
    Ball {
        /// Radius, metres.
        radius_m: f32,
    },
    /// A cube of this edge length, metres.
    Cube {
        /// Edge length, metres.
        edge_m: f32,
    },
}

/// A free rigid body where it is at one frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BodyPose {
    /// Its shape and size.
    pub shape: BodyShape,
    /// Centre, metres.
    pub centre_m: [f32; 3],
    /// Rotation from the body's axes to the world's, quaternion x, y, z, w.
    pub rotation_xyzw: [f32; 4],
}

/// Smoke volumes per frame at a frame rate, on one voxel grid.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeSequence {
    /// The voxel lattice every frame uses.
    pub grid: VoxelGrid,
    /// Frames per second.
    pub fps: f64,
    /// The frames.
    pub frames: Vec<VolumeFrame>,
}

impl VolumeSequence {
    /// Facts for reports and regression expectations: frames, voxels, smoke totals.
    pub fn summary(&self) -> serde_json::Value {
        let cell = f64::from(self.grid.voxel_m).powi(3);
        let mass: Vec<f64> =
            self.frames.iter().map(|f| f.density.iter().map(|&d| f64::from(d)).sum::<f64>() * cell).collect();
        serde_json::json!({
            "frames": self.frames.len(),
            "fps": self.fps,
            "grid": self.grid.dims,
            "voxel_m": self.grid.voxel_m,
            "smoke_mass_last_frame": mass.last().copied().unwrap_or(0.0),
            "particles_last_frame": self.frames.last().map_or(0, |f| f.particles_m.len()),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every voxel of the turned lattice is centred where the voxel it takes its value from
    /// is, turned; the grid keeps its voxel count and size.
    #[test]
    fn a_turned_lattice_puts_each_voxel_at_its_turned_centre() {
        let grid = VoxelGrid { origin: IVec3::new(-3, 1, 2), dims: [4, 3, 5], voxel_m: 0.1 };
        let (turned, from) = grid.z_up();
        assert_eq!(turned.dims, [4, 5, 3]);
        let mut seen = vec![false; grid.len()];
        for (n, &source) in from.iter().enumerate() {
            let [x, y, z] = grid.centre_m(source).to_array();
            // Blender's glTF axis change written out by hand: x stays, −z becomes y, y becomes z.
            assert!((turned.centre_m(n) - Vec3::new(x, -z, y)).length() < 1e-6, "voxel {n}");
            seen[source] = true;
        }
        assert!(seen.iter().all(|s| *s), "every voxel is carried over once");
        assert_eq!(y_up_to_z_up([1.0, 2.0, 3.0]), [1.0, -3.0, 2.0]);
    }

    #[test]
    fn a_point_near_a_voxel_centre_finds_that_voxel_and_points_off_the_grid_none() {
        let grid = VoxelGrid { origin: IVec3::new(-3, 0, 2), dims: [4, 3, 2], voxel_m: 0.1 };
        for n in 0..grid.len() {
            // Anywhere within the voxel's half-width of its centre.
            let p = grid.centre_m(n) + Vec3::new(0.04, -0.04, 0.03);
            assert_eq!(grid.index_at(p), Some(n), "voxel {n} at {}", grid.centre_m(n));
        }
        // The centres one voxel beyond each face (x: -0.4 and 0.1 m; y: -0.1 and 0.3; z: 0.1 and 0.4).
        for p in
            [[-0.4, 0.0, 0.2], [0.1, 0.0, 0.2], [-0.3, -0.1, 0.2], [-0.3, 0.3, 0.2], [-0.3, 0.0, 0.1], [-0.3, 0.0, 0.4]]
        {
            assert_eq!(grid.index_at(Vec3::from(p)), None, "{p:?}");
        }
    }
}
