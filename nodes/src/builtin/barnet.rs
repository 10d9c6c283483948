//! Bar-net driven deformation (force density method, Schek 1974; bar-net driven skinning):
//! `barnet.build` makes a net from a control mesh, `barnet.deform` solves its equilibrium
//! each frame while its fixed nodes follow the skinned control mesh.
//!
//! Equilibrium of free node i: Σ_bars(i,j) q_ij (x_i − x_j) = p_i. Split into free and fixed
//! nodes, per axis: (CᵀQC) x = p − CᵀQC_f x_f. The matrix depends only on the bars and
//! their force densities, never on the loads or the fixed positions, so it is factored once
//! (sparse Cholesky) and every frame is three triangular solves. The same matrix serves all
//! three axes: an axis's displacement depends only on that axis's loads (the paper's axis
//! independence), and solutions add (superposition).

use std::collections::BTreeSet;
use std::sync::Arc;

use faer::Side;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMat, Triplet};
use glam::{Vec3, Vec3A};

use crate::kernels::pose_vector::pose_vector;
use crate::kernels::skinning::{
    SkinError, blend_matrices, check_skin, clip_skinning_matrices, joint_named, lbs_frame, rest_normals,
};
use crate::kernels::wrap as wrap_kernel;
use crate::model::{BarNet, BarNetError, Clip, Mesh, MeshSequence};
use crate::node::{FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Registry, TextParam};

/// Registers `barnet.build`, `barnet.deform` and `deform.wrap`.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Build));
    registry.add(Box::new(DeformNet));
    registry.add(Box::new(Wrap));
}

/// Why an equilibrium cannot be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    /// The net itself is unusable.
    #[error(transparent)]
    Net(#[from] BarNetError),
    /// The control mesh's skin is unusable.
    #[error(transparent)]
    Skin(#[from] SkinError),
    /// The sparse factorisation failed (cannot happen for a valid net: its matrix is
    /// positive definite; reported rather than assumed).
    #[error("the bar-net's equilibrium matrix could not be factored: {0}")]
    Factor(String),
    /// Inputs of the wrong size.
    #[error("{0}")]
    Size(String),
}

/// A factored force-density system: build once per net, then [`FdmSolver::solve`] per
/// load case, or [`FdmSolver::refactor`] for new force densities on the same bars.
pub struct FdmSolver {
    /// Node → index among the free nodes (`u32::MAX` for fixed nodes).
    free_index: Vec<u32>,
    free_nodes: Vec<usize>,
    bars: Vec<[u32; 2]>,
    symbolic: SymbolicLlt<usize>,
    llt: Llt<usize, f64>,
    force_density: Vec<f64>,
}

/// The (CᵀQC) matrix of the free nodes, as full symmetric triplets in a fixed order (so
/// the sparsity pattern is the same for any force densities).
fn assemble(
    free_index: &[u32],
    bars: &[[u32; 2]],
    q: &[f64],
    n_free: usize,
) -> Result<SparseColMat<usize, f64>, SolveError> {
    let mut triplets = Vec::with_capacity(n_free + 2 * bars.len());
    let mut diagonal = vec![0.0f64; n_free];
    for (&[a, b], &q) in bars.iter().zip(q) {
        let (fa, fb) = (free_index[a as usize], free_index[b as usize]);
        if fa != u32::MAX {
            diagonal[fa as usize] += q;
        }
        if fb != u32::MAX {
            diagonal[fb as usize] += q;
        }
        if fa != u32::MAX && fb != u32::MAX {
            triplets.push(Triplet::new(fa as usize, fb as usize, -q));
            triplets.push(Triplet::new(fb as usize, fa as usize, -q));
        }
    }
    triplets.extend(diagonal.iter().enumerate().map(|(i, d)| Triplet::new(i, i, *d)));
    SparseColMat::try_new_from_triplets(n_free, n_free, &triplets).map_err(|e| SolveError::Factor(format!("{e:?}")))
}

impl FdmSolver {
    /// Assembles and factors the net's equilibrium matrix (symbolic analysis + numbers).
    pub fn new(net: &BarNet) -> Result<Self, SolveError> {
        let mut free_index = vec![u32::MAX; net.node_count()];
        let mut free_nodes = Vec::new();
        for (i, &f) in net.free.iter().enumerate() {
            if f {
                free_index[i] = free_nodes.len() as u32;
                free_nodes.push(i);
            }
        }
        let matrix = assemble(&free_index, &net.bars, &net.force_density, free_nodes.len())?;
        let symbolic =
            SymbolicLlt::try_new(matrix.symbolic(), Side::Lower).map_err(|e| SolveError::Factor(format!("{e:?}")))?;
        let llt = Llt::try_new_with_symbolic(symbolic.clone(), matrix.as_ref(), Side::Lower)
            .map_err(|e| SolveError::Factor(format!("{e:?}")))?;
        Ok(FdmSolver {
            free_index,
            free_nodes,
            bars: net.bars.clone(),
            symbolic,
            llt,
            force_density: net.force_density.clone(),
        })
    }

    /// New force densities on the same bars: only the numeric factorisation is redone.
    pub fn refactor(&mut self, force_density: &[f64]) -> Result<(), SolveError> {
        if force_density.len() != self.bars.len() || force_density.iter().any(|q| !(q.is_finite() && *q > 0.0)) {
            return Err(SolveError::Size(format!("{} positive force densities needed", self.bars.len())));
        }
        let matrix = assemble(&self.free_index, &self.bars, force_density, self.free_nodes.len())?;
        self.llt = Llt::try_new_with_symbolic(self.symbolic.clone(), matrix.as_ref(), Side::Lower)
            .map_err(|e| SolveError::Factor(format!("{e:?}")))?;
        self.force_density = force_density.to_vec();
        Ok(())
    }

    /// The free nodes, in the order loads and solutions use.
    pub fn free_nodes(&self) -> &[usize] {
        &self.free_nodes
    }

    /// Loads (N, one per free node) that hold the net in equilibrium at `positions_m` (one
    /// per node): p_i = Σ_j q_ij (x_i − x_j).
    pub fn equilibrium_loads(&self, positions_m: &[Vec3]) -> Vec<Vec3> {
        let mut loads = vec![Vec3::ZERO; self.free_nodes.len()];
        for (&[a, b], &q) in self.bars.iter().zip(&self.force_density) {
            let d = (positions_m[a as usize] - positions_m[b as usize]) * q as f32;
            if let Some(l) = loads.get_mut(self.free_index[a as usize] as usize) {
                *l += d;
            }
            if let Some(l) = loads.get_mut(self.free_index[b as usize] as usize) {
                *l -= d;
            }
        }
        loads
    }

    /// Solves for the free nodes' positions (metres, free-node order) under `loads_n` (one
    /// per free node) with the fixed nodes at `positions_m` (one per node; free entries
    /// are ignored).
    pub fn solve(&self, loads_n: &[Vec3], positions_m: &[Vec3]) -> Result<Vec<Vec3>, SolveError> {
        let n = self.free_nodes.len();
        if loads_n.len() != n || positions_m.len() != self.free_index.len() {
            return Err(SolveError::Size(format!(
                "{} loads and {} positions given; the net has {n} free and {} total nodes",
                loads_n.len(),
                positions_m.len(),
                self.free_index.len()
            )));
        }
        let mut rhs = faer::Mat::<f64>::zeros(n, 3);
        for (i, l) in loads_n.iter().enumerate() {
            for axis in 0..3 {
                rhs[(i, axis)] = f64::from(l[axis]);
            }
        }
        // −CᵀQC_f x_f: a bar from free a to fixed b pulls a towards b with q·x_b.
        for (&[a, b], &q) in self.bars.iter().zip(&self.force_density) {
            let (fa, fb) = (self.free_index[a as usize], self.free_index[b as usize]);
            for (free, fixed) in [(fa, b), (fb, a)] {
                if free != u32::MAX && self.free_index[fixed as usize] == u32::MAX {
                    let x = positions_m[fixed as usize];
                    for axis in 0..3 {
                        rhs[(free as usize, axis)] += q * f64::from(x[axis]);
                    }
                }
            }
        }
        faer::linalg::solvers::Solve::solve_in_place(&self.llt, rhs.as_mut());
        Ok((0..n).map(|i| Vec3::new(rhs[(i, 0)] as f32, rhs[(i, 1)] as f32, rhs[(i, 2)] as f32)).collect())
    }
}

/// A square `side × side` net in the XY plane, `spacing_m` apart, border fixed, force
/// densities cycling through 1, 1.5, … 3 N/m: the net the tests and benchmarks share.
pub fn square_grid_net(side: usize, spacing_m: f32) -> Result<BarNet, BarNetError> {
    let positions =
        (0..side * side).map(|i| Vec3::new((i % side) as f32, (i / side) as f32, 0.0) * spacing_m).collect();
    let mut bars = Vec::new();
    for i in 0..side * side {
        if i % side + 1 < side {
            bars.push([i as u32, i as u32 + 1]);
        }
        if i / side + 1 < side {
            bars.push([i as u32, (i + side) as u32]);
        }
    }
    let q = (0..bars.len()).map(|b| 1.0 + (b % 5) as f64 * 0.5).collect();
    let border = |i: usize| i.is_multiple_of(side) || i / side == 0 || i % side == side - 1 || i / side == side - 1;
    let free = (0..side * side).map(|i| !border(i)).collect();
    BarNet::new(Arc::new(Mesh { positions, ..Mesh::default() }), bars, q, free)
}

/// Which nodes of the control mesh are free.
#[derive(Clone, Debug, PartialEq)]
pub enum Selection {
    /// Vertices whose strongest skin weight is this joint.
    Joint(String),
    /// Vertices inside an axis-aligned box (min, max corners, metres).
    Box(Vec3, Vec3),
    /// These vertex indices.
    Indices(Vec<usize>),
}

impl Selection {
    /// Parses `joint NAME`, `box x0 y0 z0 x1 y1 z1` or `indices 0 3 5-9`.
    pub fn parse(text: &str) -> Result<Selection, String> {
        let mut words = text.split_whitespace();
        let kind = words.next().unwrap_or("");
        let rest: Vec<&str> = words.collect();
        match kind {
            "joint" if rest.len() == 1 => Ok(Selection::Joint(rest[0].to_string())),
            "box" => {
                let v: Vec<f32> =
                    rest.iter().map(|w| w.parse::<f32>()).collect::<Result<_, _>>().map_err(|e| format!("box: {e}"))?;
                if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
                    return Err("box needs six finite numbers: min x y z, then max x y z (metres)".into());
                }
                Ok(Selection::Box(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5])))
            }
            "indices" if !rest.is_empty() => {
                let mut out = Vec::new();
                for w in rest {
                    let bad = || format!("'{w}' is not an index or a range like 5-9");
                    match w.split_once('-') {
                        Some((a, b)) => {
                            let (a, b): (usize, usize) = (a.parse().map_err(|_| bad())?, b.parse().map_err(|_| bad())?);
                            if b < a || b - a > 10_000_000 {
                                return Err(bad());
                            }
                            out.extend(a..=b);
                        }
                        None => out.push(w.parse().map_err(|_| bad())?),
                    }
                }
                Ok(Selection::Indices(out))
            }
            _ => Err(format!("'{text}' is not 'joint NAME', 'box x0 y0 z0 x1 y1 z1' or 'indices 0 3 5-9'")),
        }
    }

    /// The free flag per vertex of `mesh`.
    pub fn flags(&self, mesh: &Mesh) -> Result<Vec<bool>, String> {
        let n = mesh.positions.len();
        match self {
            Selection::Joint(name) => {
                let skin = mesh.skin.as_ref().ok_or("selecting by joint needs a skinned control mesh")?;
                let j = joint_named(&skin.skeleton, name).map_err(|e| e.to_string())?;
                Ok((0..n)
                    .map(|v| {
                        let (strongest, weight) = skin.heaviest_joint(v);
                        strongest == j && weight > 0.0
                    })
                    .collect())
            }
            Selection::Box(lo, hi) => {
                Ok(mesh.positions.iter().map(|p| p.cmpge(lo.min(*hi)).all() && p.cmple(hi.max(*lo)).all()).collect())
            }
            Selection::Indices(indices) => {
                let mut flags = vec![false; n];
                for &i in indices {
                    *flags.get_mut(i).ok_or_else(|| format!("index {i} is past the mesh's {n} vertices"))? = true;
                }
                Ok(flags)
            }
        }
    }
}

/// The unique edges of a triangle mesh, sorted (the bars).
pub fn mesh_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut edges = BTreeSet::new();
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if a != b {
                edges.insert([a.min(b), a.max(b)]);
            }
        }
    }
    edges.into_iter().collect()
}

/// A bar-net on `control`: bars from its edges, free nodes from `selection`, force density
/// `q` on bars between free nodes and `boundary_q` on bars touching a fixed node (the
/// seam where the muscle meets the rest of the skin).
pub fn build(control: Arc<Mesh>, selection: &Selection, q: f64, boundary_q: f64) -> Result<BarNet, String> {
    let free = selection.flags(&control)?;
    let bars = mesh_edges(&control.triangles);
    let force_density =
        bars.iter().map(|&[a, b]| if free[a as usize] && free[b as usize] { q } else { boundary_q }).collect();
    BarNet::new(control, bars, force_density, free).map_err(|e| e.to_string())
}

/// How loads act on the free nodes of a net in `barnet.deform`.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadParams {
    /// Joint whose flexion drives the bulge load; `None` for constant loads only.
    pub driver: Option<usize>,
    /// Flexion (radians) where the bulge starts.
    pub ramp_start_rad: f32,
    /// Flexion (radians) of the full bulge.
    pub ramp_full_rad: f32,
    /// Outward load per free node at full flexion, newtons.
    pub bulge_n: f32,
    /// Constant outward load per free node, newtons.
    pub pressure_n: f32,
}

/// The param curve from flexion to bulge: 0 before `start`, 1 after `full`, smoothstep
/// between (so the bulge eases in and out rather than kinking).
pub fn bulge_ramp(angle_rad: f32, start: f32, full: f32) -> f32 {
    let span = full - start;
    if span.abs() < 1e-6 {
        return if angle_rad >= full { 1.0 } else { 0.0 };
    }
    let t = ((angle_rad - start) / span).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Bar-net deformation over a clip: per frame, the control mesh is skinned (LBS); fixed
/// nodes take the skinned positions; the loads that held the rest shape are carried along
/// by each node's skinning transform; an outward load along the skinned normal (constant
/// pressure plus the driver joint's bulge) is added; the free nodes are solved.
///
/// A net moved rigidly reproduces the rigid motion (the carried rest loads balance
/// exactly), so the net changes shape only where skinning bends it or loads push it.
pub fn deform_net(net: &BarNet, clip: &Arc<Clip>, loads: &LoadParams) -> Result<MeshSequence, SolveError> {
    let control = &net.control;
    let skin = control.skin.as_ref().ok_or(SkinError::NotSkinned)?;
    let n = control.positions.len();
    check_skin(skin, clip.skeleton(), n)?;
    let solver = FdmSolver::new(net)?;
    let rest_loads = solver.equilibrium_loads(&control.positions);
    let normals0 = rest_normals(control);
    let joints = clip.joint_count();
    let matrices = clip_skinning_matrices(clip, skin);
    let mut positions = vec![Vec3::ZERO; n * clip.frame_count()];
    let mut normals = Vec::with_capacity(n * clip.frame_count());
    let mut skinned_normals = vec![Vec3::ZERO; n];
    for f in 0..clip.frame_count() {
        let m = &matrices[f * joints..(f + 1) * joints];
        let out = &mut positions[f * n..(f + 1) * n];
        lbs_frame(&control.positions, &normals0, skin, m, out, &mut skinned_normals);
        let ramp = match loads.driver {
            Some(j) => {
                let angle = pose_vector(clip.skeleton(), clip.frame_rotations(f)).get(j).map_or(0.0, |r| r.length());
                bulge_ramp(angle, loads.ramp_start_rad, loads.ramp_full_rad)
            }
            None => 0.0,
        };
        let outward = loads.pressure_n + loads.bulge_n * ramp;
        let frame_loads: Vec<Vec3> = solver
            .free_nodes()
            .iter()
            .zip(&rest_loads)
            .map(|(&v, p0)| {
                let blend = blend_matrices(m, &skin.joints[v], &skin.weights[v]);
                Vec3::from(blend.matrix3.mul_vec3a(Vec3A::from(*p0))) + skinned_normals[v] * outward
            })
            .collect();
        let solved = solver.solve(&frame_loads, out)?;
        for (&v, x) in solver.free_nodes().iter().zip(solved) {
            out[v] = x;
        }
        normals.extend(Mesh::compute_normals(out, &control.triangles));
    }
    MeshSequence::new(control.clone(), clip.clone(), positions, normals).map_err(|e| SolveError::Size(e.to_string()))
}

/// Wrap deformer (kernel in [`crate::kernels::wrap`]): each vertex of `fine` (modelled over
/// `control.rest` at rest) keeps its place relative to the nearest control triangle.
pub fn wrap(fine: &Arc<Mesh>, control: &MeshSequence) -> Result<MeshSequence, String> {
    let triangles = &control.rest.triangles;
    let bindings = wrap_kernel::bind(&fine.positions, &control.rest.positions, triangles).map_err(|e| e.to_string())?;
    let n = fine.positions.len();
    let mut positions = vec![Vec3::ZERO; n * control.frame_count()];
    let mut normals = Vec::with_capacity(n * control.frame_count());
    let mut scratch = wrap_kernel::WrapScratch::default();
    for (f, out) in positions.chunks_exact_mut(n.max(1)).enumerate().take(control.frame_count()) {
        wrap_kernel::deform_frame(&bindings, control.frame_positions(f), triangles, &mut scratch, out);
        normals.extend(Mesh::compute_normals(out, &fine.triangles));
    }
    let mut rest_fine = (**fine).clone();
    rest_fine.skin = None;
    MeshSequence::new(Arc::new(rest_fine), control.clip.clone(), positions, normals).map_err(|e| e.to_string())
}

const CONTROL_IN: Input<Arc<Mesh>> =
    Input::required("mesh", "The control mesh (low resolution, skinned when it will follow a skeleton).");
const NET_OUT: Output<Arc<BarNet>> =
    Output::new("net", "The bar-net: the mesh's edges as bars, with free and fixed nodes.");
const FREE: TextParam = TextParam::new(
    "free",
    "Which vertices move freely (the muscle): 'joint NAME' (vertices mostly bound to that joint), 'box x0 y0 z0 x1 y1 z1' (metres) or 'indices 0 3 5-9'. All others stay fixed to the skin.",
    "",
);
const Q: FloatParam = FloatParam::new(
    "force_density",
    "Force density of bars between free vertices, newtons per metre: higher is tauter (less bulge).",
    1.0,
    1e-6,
    1e6,
    "N/m",
);
const BOUNDARY_Q: FloatParam = FloatParam::optional(
    "boundary_force_density",
    "Force density of bars touching a fixed vertex (the muscle's seam), N/m; unset uses force_density.",
    1e-6,
    1e6,
    "N/m",
);

/// `barnet.build`.
pub struct Build;

static BUILD: NodeSchema = NodeSchema {
    kind: "barnet.build",
    category: "skin",
    doc: "Makes a bar-net from a control mesh: every edge becomes a bar, the selected vertices are free to bulge and the rest follow the skin.",
    inputs: &[CONTROL_IN.spec()],
    outputs: &[NET_OUT.spec()],
    params: &[FREE.0, Q.0, BOUNDARY_Q.0],
    writes_files: false,
    version: 1,
};

impl Node for Build {
    fn schema(&self) -> &'static NodeSchema {
        &BUILD
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let control = ctx.input(&CONTROL_IN)?;
        let selection = Selection::parse(ctx.text_param(&FREE)?).map_err(|m| NodeError::param(FREE.0.name, m))?;
        let q = ctx.float(&Q)?;
        let boundary_q = ctx.optional_float(&BOUNDARY_Q)?.unwrap_or(q);
        let net = build(control, &selection, q, boundary_q).map_err(|m| NodeError::param(FREE.0.name, m))?;
        ctx.set_output(&NET_OUT, Arc::new(net));
        Ok(())
    }
}

const NET_IN: Input<Arc<BarNet>> =
    Input::required("net", "The bar-net (its control mesh must be skinned to the clip's skeleton).");
const CLIP_IN: Input<Arc<Clip>> = Input::required("clip", "The motion that drives the control mesh.");
const SEQ_OUT: Output<Arc<MeshSequence>> = Output::new("sequence", "The control mesh per frame, with the net's bulge.");
const DRIVER: TextParam = TextParam::new(
    "driver",
    "Joint whose bend drives the bulge (e.g. the forearm joint for a biceps); empty for none.",
    "",
);
const RAMP_START: FloatParam =
    FloatParam::new("bulge_start", "Bend of the driver joint where the bulge starts, radians.", 0.2, 0.0, 3.2, "rad");
const RAMP_FULL: FloatParam =
    FloatParam::new("bulge_full", "Bend of the driver joint at full bulge, radians.", 2.0, 0.0, 3.2, "rad");
const BULGE: FloatParam =
    FloatParam::new("bulge_load", "Outward load on each free vertex at full bulge, newtons.", 0.05, -100.0, 100.0, "N");
const PRESSURE: FloatParam =
    FloatParam::new("pressure", "Constant outward load on each free vertex, newtons.", 0.0, -100.0, 100.0, "N");

/// `barnet.deform`.
pub struct DeformNet;

static DEFORM_NET: NodeSchema = NodeSchema {
    kind: "barnet.deform",
    category: "skin",
    doc: "Skins the bar-net's control mesh over a clip and lets its free vertices settle under the bar forces and loads each frame; a joint's bend can drive a bulge (elbow flexion → biceps).",
    inputs: &[NET_IN.spec(), CLIP_IN.spec()],
    outputs: &[SEQ_OUT.spec()],
    params: &[DRIVER.0, RAMP_START.0, RAMP_FULL.0, BULGE.0, PRESSURE.0],
    writes_files: false,
    version: 1,
};

impl Node for DeformNet {
    fn schema(&self) -> &'static NodeSchema {
        &DEFORM_NET
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let net = ctx.input(&NET_IN)?;
        let clip = ctx.input(&CLIP_IN)?;
        let name = ctx.text_param(&DRIVER)?.trim().to_string();
        let driver = if name.is_empty() {
            None
        } else {
            Some(joint_named(clip.skeleton(), &name).map_err(|e| NodeError::param(DRIVER.0.name, e.to_string()))?)
        };
        let loads = LoadParams {
            driver,
            ramp_start_rad: ctx.float(&RAMP_START)? as f32,
            ramp_full_rad: ctx.float(&RAMP_FULL)? as f32,
            bulge_n: ctx.float(&BULGE)? as f32,
            pressure_n: ctx.float(&PRESSURE)? as f32,
        };
        let vertices = net.control.positions.len();
        ctx.reserve_memory(MeshSequence::estimated_bytes(clip.frame_count(), vertices), CLIP_IN.name())?;
        let seq = deform_net(&net, &clip, &loads).map_err(|e| match e {
            SolveError::Skin(e) => NodeError::input(NET_IN.name(), e.to_string()),
            other => NodeError::kernel(other),
        })?;
        ctx.set_output(&SEQ_OUT, Arc::new(seq));
        Ok(())
    }
}

const FINE_IN: Input<Arc<Mesh>> =
    Input::required("mesh", "The detailed mesh, modelled over the control mesh's rest shape.");
const CONTROL_SEQ_IN: Input<Arc<MeshSequence>> =
    Input::required("control", "The deformed control mesh per frame (e.g. from barnet.deform or skin.deform).");
const WRAP_OUT: Output<Arc<MeshSequence>> = Output::new("sequence", "The detailed mesh following the control mesh.");

/// `deform.wrap`.
pub struct Wrap;

static WRAP: NodeSchema = NodeSchema {
    kind: "deform.wrap",
    category: "skin",
    doc: "Makes a detailed mesh follow a deformed control mesh: each vertex sticks to the nearest control triangle, keeping its offset.",
    inputs: &[FINE_IN.spec(), CONTROL_SEQ_IN.spec()],
    outputs: &[WRAP_OUT.spec()],
    params: &[],
    writes_files: false,
    version: 1,
};

impl Node for Wrap {
    fn schema(&self) -> &'static NodeSchema {
        &WRAP
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let fine = ctx.input(&FINE_IN)?;
        let control = ctx.input(&CONTROL_SEQ_IN)?;
        let bytes = MeshSequence::estimated_bytes(control.frame_count(), fine.positions.len());
        ctx.reserve_memory(bytes, CONTROL_SEQ_IN.name())?;
        let seq = wrap(&fine, &control).map_err(|m| NodeError::input(CONTROL_SEQ_IN.name(), m))?;
        ctx.set_output(&WRAP_OUT, Arc::new(seq));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::kernels::arm::{SAMPLE_POSES, arm_clip, arm_flex_clip, arm_mesh};
    use crate::kernels::skinning::{AutoWeightParams, BindMode, bind, deform_lbs};

    /// A net from explicit nodes and bars (no triangles needed by the solver).
    fn net(positions: Vec<Vec3>, bars: Vec<[u32; 2]>, q: Vec<f64>, free: Vec<bool>) -> BarNet {
        let mesh = Mesh { positions, ..Mesh::default() };
        BarNet::new(Arc::new(mesh), bars, q, free).unwrap()
    }

    fn grid(n: usize) -> BarNet {
        square_grid_net(n, 1.0).unwrap()
    }

    fn loads(count: usize, seed: f32) -> Vec<Vec3> {
        (0..count)
            .map(|i| {
                Vec3::new((i as f32 * 0.7 + seed).sin(), (i as f32 * 1.3 + seed).cos(), (i as f32 * 0.3 * seed).sin())
            })
            .collect()
    }

    #[test]
    fn one_free_node_between_four_fixed_ones_matches_the_hand_solution() {
        // Σ q_j (x − x_j) = p  ⇒  x = (p + Σ q_j x_j) / Σ q_j = ((1,2,3) + (−1,−1,0)) / 10.
        let positions = vec![Vec3::ZERO, Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y];
        let n = net(
            positions.clone(),
            vec![[0, 1], [0, 2], [0, 3], [0, 4]],
            vec![1.0, 2.0, 3.0, 4.0],
            vec![true, false, false, false, false],
        );
        let solver = FdmSolver::new(&n).unwrap();
        let x = solver.solve(&[Vec3::new(1.0, 2.0, 3.0)], &positions).unwrap();
        assert!((x[0] - Vec3::new(0.0, 0.1, 0.3)).length() < 1e-6, "{:?}", x[0]);
    }

    #[test]
    fn a_loaded_chain_matches_the_hand_solution() {
        // Fixed 0 — free 1 — free 2 — fixed 3 along X, q = 1. Unloaded, the free nodes sit at
        // x = 1, 2. A load of 3 N in y on node 1: 2y₁ − y₂ = 3, 2y₂ − y₁ = 0 ⇒ y = (2, 1).
        let positions = vec![Vec3::ZERO, Vec3::new(5.0, 5.0, 5.0), Vec3::new(-4.0, 0.0, 1.0), Vec3::new(3.0, 0.0, 0.0)];
        let n = net(positions.clone(), vec![[0, 1], [1, 2], [2, 3]], vec![1.0; 3], vec![false, true, true, false]);
        let solver = FdmSolver::new(&n).unwrap();
        let x = solver.solve(&[Vec3::ZERO, Vec3::ZERO], &positions).unwrap();
        assert!((x[0] - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-6 && (x[1] - Vec3::new(2.0, 0.0, 0.0)).length() < 1e-6);
        let x = solver.solve(&[Vec3::new(0.0, 3.0, 0.0), Vec3::ZERO], &positions).unwrap();
        assert!((x[0] - Vec3::new(1.0, 2.0, 0.0)).length() < 1e-5 && (x[1] - Vec3::new(2.0, 1.0, 0.0)).length() < 1e-5);
    }

    #[test]
    fn displacements_superpose_and_axes_are_independent() {
        let n = grid(12);
        let solver = FdmSolver::new(&n).unwrap();
        let fixed = &n.control.positions;
        let count = n.free_count();
        let base = solver.solve(&vec![Vec3::ZERO; count], fixed).unwrap();
        let (p1, p2) = (loads(count, 1.0), loads(count, 2.0));
        let both: Vec<Vec3> = p1.iter().zip(&p2).map(|(a, b)| *a + *b).collect();
        let (x1, x2, x12) =
            (solver.solve(&p1, fixed).unwrap(), solver.solve(&p2, fixed).unwrap(), solver.solve(&both, fixed).unwrap());
        for i in 0..count {
            let sum = (x1[i] - base[i]) + (x2[i] - base[i]);
            assert!(((x12[i] - base[i]) - sum).length() < 1e-4, "node {i}");
        }
        // Changing only the x loads leaves every y and z untouched.
        let x_only: Vec<Vec3> = p1.iter().map(|p| Vec3::new(p.x * 5.0 - 1.0, p.y, p.z)).collect();
        let xs = solver.solve(&x_only, fixed).unwrap();
        for i in 0..count {
            assert!((xs[i].y - x1[i].y).abs() < 1e-6 && (xs[i].z - x1[i].z).abs() < 1e-6);
            assert!((xs[i].x - x1[i].x).abs() > 1e-6 || (p1[i].x * 4.0 - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn refactoring_with_new_force_densities_equals_a_fresh_build() {
        let mut n = grid(8);
        let mut solver = FdmSolver::new(&n).unwrap();
        let q: Vec<f64> = (0..n.bars.len()).map(|b| 0.5 + (b % 3) as f64).collect();
        solver.refactor(&q).unwrap();
        n.force_density = q;
        let fresh = FdmSolver::new(&n).unwrap();
        let p = loads(n.free_count(), 3.0);
        let (a, b) = (solver.solve(&p, &n.control.positions).unwrap(), fresh.solve(&p, &n.control.positions).unwrap());
        assert!(a.iter().zip(&b).all(|(x, y)| (*x - *y).length() < 1e-6));
        assert!(solver.refactor(&[1.0]).is_err());
    }

    #[test]
    fn invalid_nets_are_refused() {
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y];
        let mesh = Arc::new(Mesh { positions, ..Mesh::default() });
        // Node 2 is free but no bar reaches it from a fixed node.
        let floating = BarNet::new(mesh.clone(), vec![[0, 1]], vec![1.0], vec![false, true, true]);
        assert!(matches!(floating, Err(BarNetError::Floating { count: 1, example: 2 })));
        assert!(matches!(
            BarNet::new(mesh.clone(), vec![[0, 3]], vec![1.0], vec![false, true, false]),
            Err(BarNetError::BadBar { .. })
        ));
        assert!(matches!(
            BarNet::new(mesh.clone(), vec![[0, 1]], vec![-1.0], vec![false, true, false]),
            Err(BarNetError::BadForceDensity { .. })
        ));
        assert!(matches!(BarNet::new(mesh, vec![[0, 1]], vec![1.0], vec![false; 3]), Err(BarNetError::NoFreeNode)));
    }

    #[test]
    fn selections_parse_and_report_bad_text() {
        assert_eq!(Selection::parse("indices 1 4-6").unwrap(), Selection::Indices(vec![1, 4, 5, 6]));
        assert!(matches!(Selection::parse("box 0 0 0 1 1 1").unwrap(), Selection::Box(..)));
        assert_eq!(Selection::parse("joint upper_arm").unwrap(), Selection::Joint("upper_arm".into()));
        for bad in ["", "box 1 2", "indices x", "indices 5-2", "joint"] {
            assert!(Selection::parse(bad).is_err(), "{bad}");
        }
        let mesh = arm_mesh(6, 6);
        assert!(Selection::Indices(vec![1000]).flags(&mesh).is_err());
        assert!(Selection::Joint("upper_arm".into()).flags(&mesh).is_err()); // not skinned
    }

    /// The bound arm, its biceps net and the flex clip.
    pub(crate) fn arm_net() -> (Arc<Mesh>, BarNet) {
        let clip = arm_flex_clip(8, 24.0).unwrap();
        let mesh = Arc::new(
            bind(&arm_mesh(24, 12), clip.skeleton(), BindMode::Automatic, AutoWeightParams::default()).unwrap(),
        );
        let biceps = Selection::Box(Vec3::new(0.11, 1.34, 0.012), Vec3::new(0.31, 1.46, 0.1));
        let net = build(mesh.clone(), &biceps, 1.0, 1.0).unwrap();
        (mesh, net)
    }

    #[test]
    fn a_rigidly_moved_net_moves_rigidly_and_flexion_bulges_the_biceps() {
        let (mesh, net) = arm_net();
        // Whole-arm rotation at the root: only the root moves, so LBS is rigid and the
        // carried rest loads must keep the net exactly on it.
        let skeleton = mesh.skin.as_ref().unwrap().skeleton.clone();
        let offsets: Vec<Vec3> = skeleton.joints().iter().map(|j| j.rest_offset).collect();
        let mut rotations = vec![glam::Quat::IDENTITY; skeleton.len()];
        rotations[0] = glam::Quat::from_rotation_y(0.9) * glam::Quat::from_rotation_x(0.4);
        let rigid = Arc::new(Clip::new(skeleton, 24.0, rotations, offsets, crate::model::ImportScale::METRES).unwrap());
        let loads =
            LoadParams { driver: Some(2), ramp_start_rad: 0.2, ramp_full_rad: 2.0, bulge_n: 0.05, pressure_n: 0.0 };
        let by_net = deform_net(&net, &rigid, &loads).unwrap();
        let by_lbs = deform_lbs(&mesh, &rigid).unwrap();
        for (a, b) in by_net.frame_positions(0).iter().zip(by_lbs.frame_positions(0)) {
            assert!((*a - *b).length() < 1e-5);
        }
        // Elbow flexed to 2.4 rad: free nodes move away from the upper-arm axis.
        let flexed = Arc::new(arm_clip(&[SAMPLE_POSES[3]], 24.0).unwrap());
        let by_net = deform_net(&net, &flexed, &loads).unwrap();
        let by_lbs = deform_lbs(&mesh, &flexed).unwrap();
        let mut outward = 0.0f32;
        for (v, free) in net.free.iter().enumerate() {
            if *free {
                outward = outward
                    .max((by_net.frame_positions(0)[v] - by_lbs.frame_positions(0)[v]).dot(by_lbs.frame_normals(0)[v]));
            }
        }
        assert!(outward > 0.005, "biceps bulge {outward} m");
    }

    #[test]
    fn wrapping_a_mesh_on_its_own_control_reproduces_the_control_motion() {
        let (mesh, _) = arm_net();
        let clip = Arc::new(arm_clip(&SAMPLE_POSES, 24.0).unwrap());
        let control = deform_lbs(&mesh, &clip).unwrap();
        let mut fine = (*mesh).clone();
        fine.skin = None;
        let wrapped = wrap(&Arc::new(fine), &control).unwrap();
        for f in 0..clip.frame_count() {
            for (a, b) in wrapped.frame_positions(f).iter().zip(control.frame_positions(f)) {
                assert!((*a - *b).length() < 1e-4);
            }
        }
    }
}
