//! Example-based skinning after Rhee, Lewis & Neumann 2006 (weighted pose space
//! deformation of Kurihara & Miyata 2004): `skin.deform` (SSD, PSD, WPSD) and
//! `skin.fit_weights` (joint weights by NNLS from sample poses).
//!
//! Notation (DESIGN §4): v₀ rest vertex, T_jᵏ joint j's skinning matrix at sample pose k,
//! v_k the sample's vertex. Displacements live in the rest space:
//! d_k = (Σ_j w_j T_jᵏ)⁻¹ v_k − v₀, and a pose p deforms as
//! v = Σ_j w_j T_j (v₀ + Σ_k r_k(p) d_k), with Gaussian radial basis functions solved so
//! that r_k(p_i) = δ_ki.

use std::sync::Arc;

use glam::{Affine3A, Vec3, Vec3A};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use crate::kernels::pose_vector::pose_vector;
use crate::kernels::skinning::{
    SkinError, blend_matrices, check_skin, clip_skinning_matrices, deform_lbs, rest_normals, top_four,
};
use crate::math::nnls::nnls;
use crate::model::choice::choices;
use crate::model::{Clip, Mesh, MeshSequence, Skeleton, Skin};
use crate::node::{
    ChoiceParam, FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Registry,
};

/// Registers `skin.deform` and `skin.fit_weights`.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(Deform));
    registry.add(Box::new(FitWeights));
}

/// Vertices per rayon task (see `kernels::skinning::VERTEX_CHUNK`; WPSD does more work per vertex).
const VERTEX_CHUNK: usize = 512;

/// Ridge added to the RBF system so nearly coincident samples cannot make it singular;
/// small enough that samples are still reproduced to well under a micrometre.
const RBF_RIDGE: f64 = 1e-9;

/// Pose distances (radians) below this count as "all samples look the same" for a vertex.
const DEGENERATE_DISTANCE_RAD: f64 = 1e-6;

/// Why a pose-space deformation cannot be built or run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseSpaceError {
    /// The skin is unusable.
    #[error(transparent)]
    Skin(#[from] SkinError),
    /// The samples do not fit the mesh.
    #[error("{0}")]
    Samples(String),
}

/// How each vertex measures the distance between poses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoseDistance {
    /// PSD: every joint counts the same for every vertex.
    Uniform,
    /// WPSD as in the paper: joint j's term is weighted by the vertex's weight for j.
    JointWeight,
    /// WPSD where a vertex's weight for joint j also weights j's children: a bone's shape
    /// (a biceps on the upper arm) changes with the joint at its far end (the elbow), which
    /// the paper's weighting cannot see. The default.
    JointAndChildren,
}

/// Settings of the pose-space model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseSpaceParams {
    /// Distance used by the radial basis functions.
    pub distance: PoseDistance,
    /// Gaussian width as a multiple of the mean distance between samples (default 1).
    pub width_scale: f64,
    /// Principal poses kept after PCA of the displacements; 0 keeps all samples.
    pub principal_poses: usize,
}

impl Default for PoseSpaceParams {
    fn default() -> Self {
        PoseSpaceParams { distance: PoseDistance::JointAndChildren, width_scale: 1.0, principal_poses: 0 }
    }
}

/// Per vertex RBF data: the sparse joint weighting of its distance, its Gaussian width and
/// the inverse of its RBF matrix (row-major K × K), or `None` when no sample differs.
struct VertexRbf {
    relevance: Vec<(u16, f32)>,
    inv_two_sigma_sq: f32,
    lambda: Option<Vec<f32>>,
}

/// A trained pose-space deformer.
pub struct PoseSpaceModel {
    samples: usize,
    /// Entries of a pose vector (the samples' skeleton joints).
    joints: usize,
    sample_poses: Vec<Vec<Vec3>>,
    /// Displacement basis, `components × vertices` (rest space, metres).
    basis: Vec<Vec3>,
    /// `samples × components`: sample k's displacement is `mean + Σ_m coeffs[k][m] basis_m`.
    coeffs: Vec<f32>,
    components: usize,
    mean: Vec<Vec3>,
    /// One entry (shared by all vertices) for PSD, one per vertex for WPSD.
    rbf: Vec<VertexRbf>,
}

/// Solves the RBF weights' matrix Λ = (Φ + ridge·I)⁻¹ for the sample distances `d`
/// (K × K, radians); `None` when all distances vanish.
fn rbf_inverse(d: &DMatrix<f64>, width_scale: f64) -> (f32, Option<Vec<f32>>) {
    let k = d.nrows();
    let pairs = (k * k.saturating_sub(1)) as f64;
    let mean = if pairs > 0.0 { d.sum() / pairs } else { 0.0 };
    if mean < DEGENERATE_DISTANCE_RAD || k == 0 {
        return (0.0, None);
    }
    let sigma = mean * width_scale.max(1e-6);
    let inv = 1.0 / (2.0 * sigma * sigma);
    let phi =
        DMatrix::from_fn(k, k, |i, j| (-d[(i, j)] * d[(i, j)] * inv).exp() + if i == j { RBF_RIDGE } else { 0.0 });
    let lambda = phi.clone().cholesky().map(|c| c.inverse()).or_else(|| phi.try_inverse());
    match lambda {
        Some(l) => (inv as f32, Some((0..k * k).map(|e| l[(e / k, e % k)] as f32).collect())),
        None => (0.0, None),
    }
}

/// Working memory of [`PoseSpaceModel::deform_frame`] for one mesh, made once by
/// [`PoseSpaceModel::scratch`] and reused for every frame, so evaluation allocates nothing.
#[derive(Clone, Debug)]
pub struct PoseSpaceScratch {
    /// `‖p_j − p_kj‖²` per sample `k` and joint `j` (sample-major).
    terms: Vec<f32>,
    /// The RBF weights shared by every vertex (PSD), then their kernel values (K each).
    shared: Vec<f32>,
    /// Per vertex chunk: RBF weights `r`, kernel values `φ` (K each) and PCA coefficients.
    chunks: Vec<f32>,
}

impl PoseSpaceModel {
    /// Trains on `samples` (frames = sample poses, positions = the desired shapes) for the
    /// skinned `mesh`: displacements per sample, optional PCA, and RBF systems (global for
    /// PSD, per vertex for WPSD).
    pub fn train(mesh: &Mesh, samples: &MeshSequence, params: PoseSpaceParams) -> Result<Self, PoseSpaceError> {
        let skin = mesh.skin.as_ref().ok_or(SkinError::NotSkinned)?;
        let n = mesh.positions.len();
        check_skin(skin, samples.clip.skeleton(), n)?;
        if samples.vertex_count() != n {
            return Err(PoseSpaceError::Samples(format!(
                "the samples have {} vertices, the mesh {n}",
                samples.vertex_count()
            )));
        }
        let k = samples.frame_count();
        if k == 0 {
            return Err(PoseSpaceError::Samples("there are no sample poses".into()));
        }
        let skeleton = samples.clip.skeleton();
        let joints = skeleton.len();
        let sample_poses: Vec<Vec<Vec3>> =
            (0..k).map(|f| pose_vector(skeleton, samples.clip.frame_rotations(f))).collect();
        let matrices = clip_skinning_matrices(&samples.clip, skin);
        // d_k = (Σ w T)⁻¹ v_k − v₀; a singular blend (weights cancelling) gives no displacement.
        let mut displacements = vec![Vec3::ZERO; k * n];
        displacements.par_chunks_mut(n).enumerate().for_each(|(f, out)| {
            let m = &matrices[f * joints..(f + 1) * joints];
            let target = samples.frame_positions(f);
            for v in 0..n {
                let blend = blend_matrices(m, &skin.joints[v], &skin.weights[v]);
                if blend.matrix3.determinant().abs() > 1e-8 {
                    let back = blend.inverse().transform_point3a(Vec3A::from(target[v]));
                    out[v] = Vec3::from(back) - mesh.positions[v];
                }
            }
        });
        let (mean, basis, coeffs, components) = compress(&displacements, k, n, params.principal_poses);

        let sample_distance = |relevance: &[(u16, f32)]| {
            DMatrix::from_fn(k, k, |a, b| {
                relevance
                    .iter()
                    .map(|&(j, r)| {
                        f64::from(r)
                            * f64::from((sample_poses[a][j as usize] - sample_poses[b][j as usize]).length_squared())
                    })
                    .sum::<f64>()
                    .sqrt()
            })
        };
        let rbf: Vec<VertexRbf> = match params.distance {
            PoseDistance::Uniform => {
                let relevance: Vec<(u16, f32)> = (0..joints as u16).map(|j| (j, 1.0)).collect();
                let (inv_two_sigma_sq, lambda) = rbf_inverse(&sample_distance(&relevance), params.width_scale);
                vec![VertexRbf { relevance, inv_two_sigma_sq, lambda }]
            }
            distance => (0..n)
                .into_par_iter()
                .map(|v| {
                    let relevance = vertex_relevance(skeleton, &skin.joints[v], &skin.weights[v], distance);
                    let (inv_two_sigma_sq, lambda) = rbf_inverse(&sample_distance(&relevance), params.width_scale);
                    VertexRbf { relevance, inv_two_sigma_sq, lambda }
                })
                .collect(),
        };
        Ok(PoseSpaceModel { samples: k, joints, sample_poses, basis, coeffs, components, mean, rbf })
    }

    /// Number of principal poses (displacement components) kept.
    pub fn components(&self) -> usize {
        self.components
    }

    /// RBF weights r_k at a pose for one vertex's RBF data, into `out`; `phi` is scratch
    /// space of the same length (one per thread, so the hot loop never allocates).
    fn weights(&self, rbf: &VertexRbf, terms: &[f32], phi: &mut [f32], out: &mut [f32]) {
        let k = self.samples;
        let Some(lambda) = &rbf.lambda else {
            // No sample differs under this vertex's distance: their average is the best guess.
            out.iter_mut().for_each(|r| *r = 1.0 / k as f32);
            return;
        };
        for (i, p) in phi.iter_mut().enumerate() {
            let terms = &terms[i * self.joints..(i + 1) * self.joints];
            let gamma_sq: f32 = rbf.relevance.iter().map(|&(j, w)| w * terms[j as usize]).sum();
            *p = (-gamma_sq * rbf.inv_two_sigma_sq).exp();
        }
        for (row, r) in out.iter_mut().enumerate() {
            *r = lambda[row * k..(row + 1) * k].iter().zip(phi.iter()).map(|(l, p)| l * p).sum();
        }
    }

    /// Working memory for deforming a mesh of `vertices` vertices with this model.
    pub fn scratch(&self, vertices: usize) -> PoseSpaceScratch {
        let k = self.samples;
        PoseSpaceScratch {
            terms: vec![0.0; k * self.joints],
            shared: vec![0.0; 2 * k],
            chunks: vec![0.0; vertices.div_ceil(VERTEX_CHUNK) * self.chunk_scratch()],
        }
    }

    /// Floats of scratch one vertex chunk uses: `r`, `φ` and the PCA coefficients.
    fn chunk_scratch(&self) -> usize {
        2 * self.samples + self.components
    }

    /// Deforms one frame: positions by `v = M (v₀ + d(p))`. `scratch` comes from
    /// [`PoseSpaceModel::scratch`] for this mesh.
    pub fn deform_frame(
        &self,
        mesh: &Mesh,
        skin: &Skin,
        pose: &[Vec3],
        matrices: &[Affine3A],
        positions_m: &mut [Vec3],
        scratch: &mut PoseSpaceScratch,
    ) {
        let k = self.samples;
        for (terms, sample) in scratch.terms.chunks_exact_mut(self.joints).zip(&self.sample_poses) {
            for ((t, a), b) in terms.iter_mut().zip(pose).zip(sample) {
                *t = (*a - *b).length_squared();
            }
        }
        let terms = scratch.terms.as_slice();
        let shared = (self.rbf.len() == 1).then(|| {
            let (r, phi) = scratch.shared.split_at_mut(k);
            self.weights(&self.rbf[0], terms, phi, r);
            &*r
        });
        let n = mesh.positions.len();
        let per_chunk = self.chunk_scratch();
        positions_m.par_chunks_mut(VERTEX_CHUNK).zip(scratch.chunks.par_chunks_mut(per_chunk)).enumerate().for_each(
            |(chunk, (out, work))| {
                let (r, rest) = work.split_at_mut(k);
                let (phi, c) = rest.split_at_mut(k);
                for (i, p) in out.iter_mut().enumerate() {
                    let v = chunk * VERTEX_CHUNK + i;
                    let r: &[f32] = match shared {
                        Some(shared) => shared,
                        None => {
                            self.weights(&self.rbf[v], terms, phi, r);
                            r
                        }
                    };
                    c.iter_mut().for_each(|x| *x = 0.0);
                    let mut r_sum = 0.0;
                    for (s, rs) in r.iter().enumerate() {
                        r_sum += rs;
                        for (m, cm) in c.iter_mut().enumerate() {
                            *cm += rs * self.coeffs[s * self.components + m];
                        }
                    }
                    let mut d = self.mean[v] * r_sum;
                    for (m, cm) in c.iter().enumerate() {
                        d += self.basis[m * n + v] * *cm;
                    }
                    let blend = blend_matrices(matrices, &skin.joints[v], &skin.weights[v]);
                    *p = blend.transform_point3(mesh.positions[v] + d);
                }
            },
        );
    }
}

/// The sparse joint weighting of one vertex's pose distance.
fn vertex_relevance(
    skeleton: &Skeleton,
    joints: &[u16; 4],
    weights: &[f32; 4],
    distance: PoseDistance,
) -> Vec<(u16, f32)> {
    let mut out: Vec<(u16, f32)> = Vec::with_capacity(8);
    let mut add = |j: u16, w: f32| match out.iter_mut().find(|e| e.0 == j) {
        Some(e) => e.1 += w,
        None => out.push((j, w)),
    };
    for (&j, &w) in joints.iter().zip(weights) {
        if w <= 0.0 {
            continue;
        }
        add(j, w);
        if distance == PoseDistance::JointAndChildren {
            for c in skeleton.children(j as usize) {
                add(c as u16, w);
            }
        }
    }
    out
}

/// PCA of the displacements (K samples × 3n values): returns `(mean, basis, coeffs,
/// components)`. With `keep = 0` or `keep ≥ K` no compression is done (mean zero, basis
/// the displacements themselves, coefficients the identity), so samples are reproduced
/// exactly.
fn compress(displacements: &[Vec3], k: usize, n: usize, keep: usize) -> (Vec<Vec3>, Vec<Vec3>, Vec<f32>, usize) {
    if keep == 0 || keep >= k {
        let coeffs = (0..k * k).map(|e| if e / k == e % k { 1.0 } else { 0.0 }).collect();
        return (vec![Vec3::ZERO; n], displacements.to_vec(), coeffs, k);
    }
    let mut mean = vec![Vec3::ZERO; n];
    for s in 0..k {
        for v in 0..n {
            mean[v] += displacements[s * n + v] / k as f32;
        }
    }
    let centred = |s: usize, v: usize| displacements[s * n + v] - mean[v];
    // The K × K Gram matrix is small, so its eigenvectors give the principal components
    // without forming the 3n × 3n covariance.
    let gram = DMatrix::from_fn(k, k, |a, b| (0..n).map(|v| f64::from(centred(a, v).dot(centred(b, v)))).sum::<f64>());
    let eigen = gram.symmetric_eigen();
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let mut basis = vec![Vec3::ZERO; keep * n];
    let mut coeffs = vec![0f32; k * keep];
    for (m, &e) in order.iter().take(keep).enumerate() {
        let value = eigen.eigenvalues[e].max(0.0);
        let norm = value.sqrt();
        if norm < 1e-12 {
            continue;
        }
        let u: DVector<f64> = eigen.eigenvectors.column(e).into_owned();
        for v in 0..n {
            basis[m * n + v] = (0..k).map(|s| centred(s, v) * u[s] as f32).fold(Vec3::ZERO, |a, b| a + b) / norm as f32;
        }
        for s in 0..k {
            coeffs[s * keep + m] = (u[s] * norm) as f32;
        }
    }
    (mean, basis, coeffs, keep)
}

/// Which deformation `skin.deform` runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeformMethod {
    /// Linear blend skinning (SSD).
    Lbs,
    /// Pose space deformation with the given settings.
    PoseSpace(PoseSpaceParams),
}

/// Deforms `mesh` over `clip` by LBS, or by PSD/WPSD trained on `samples`.
pub fn deform(
    mesh: &Arc<Mesh>,
    clip: &Arc<Clip>,
    samples: Option<&MeshSequence>,
    method: DeformMethod,
) -> Result<MeshSequence, PoseSpaceError> {
    let DeformMethod::PoseSpace(params) = method else {
        return Ok(deform_lbs(mesh, clip)?);
    };
    let samples = samples.ok_or_else(|| PoseSpaceError::Samples("PSD and WPSD need sample poses".into()))?;
    let skin = mesh.skin.as_ref().ok_or(SkinError::NotSkinned)?;
    check_skin(skin, clip.skeleton(), mesh.positions.len())?;
    let model = PoseSpaceModel::train(mesh, samples, params)?;
    let n = mesh.positions.len();
    let joints = clip.joint_count();
    let matrices = clip_skinning_matrices(clip, skin);
    let mut positions = vec![Vec3::ZERO; n * clip.frame_count()];
    let mut normals = Vec::with_capacity(n * clip.frame_count());
    let mut scratch = model.scratch(n);
    for f in 0..clip.frame_count() {
        let pose = pose_vector(clip.skeleton(), clip.frame_rotations(f));
        let out = &mut positions[f * n..(f + 1) * n];
        model.deform_frame(mesh, skin, &pose, &matrices[f * joints..(f + 1) * joints], out, &mut scratch);
        normals.extend(if mesh.triangles.is_empty() {
            rest_normals(mesh)
        } else {
            Mesh::compute_normals(out, &mesh.triangles)
        });
    }
    MeshSequence::new(mesh.clone(), clip.clone(), positions, normals)
        .map_err(|e| PoseSpaceError::Samples(e.to_string()))
}

/// Fitted joint weights and how well they explain the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedWeights {
    /// Up to four joints per vertex.
    pub joints: Vec<[u16; 4]>,
    /// Matching normalised weights.
    pub weights: Vec<[f32; 4]>,
    /// Root-mean-square distance (metres) between the samples and LBS with the fitted
    /// weights, over all samples and vertices.
    pub rms_error_m: f64,
}

/// Joint weights per vertex by NNLS (Rhee et al. eq. 10–11): find w ≥ 0 minimising
/// Σ_k ‖v_k − Σ_j w_j T_jᵏ v₀‖² over the samples, normalise to sum one and keep the four
/// largest ("principal joints"); end sites are not candidates. `inverse_bind` gives T_jᵏ; the samples' clip supplies the
/// poses. Samples should differ in every joint that matters (at least as many poses as
/// degrees of freedom, the paper advises), otherwise joints that never move are
/// indistinguishable and share the weight.
pub fn fit_weights(
    rest_positions: &[Vec3],
    inverse_bind: &[glam::Mat4],
    samples: &MeshSequence,
) -> Result<FittedWeights, PoseSpaceError> {
    let n = rest_positions.len();
    if samples.vertex_count() != n {
        return Err(PoseSpaceError::Samples(format!(
            "the samples have {} vertices, the mesh {n}",
            samples.vertex_count()
        )));
    }
    let k = samples.frame_count();
    let joints = samples.clip.joint_count();
    if k == 0 || inverse_bind.len() != joints {
        return Err(PoseSpaceError::Samples(format!(
            "need sample poses and one inverse bind matrix per joint ({} for {joints} joints, {k} samples)",
            inverse_bind.len()
        )));
    }
    let skin_like = Skin {
        skeleton: samples.clip.skeleton().clone(),
        joints: Vec::new(),
        weights: Vec::new(),
        inverse_bind_matrices: inverse_bind.to_vec(),
    };
    let matrices = clip_skinning_matrices(&samples.clip, &skin_like);
    // End sites move exactly with their parent: as extra columns they would only split
    // the parent's weight between two identical candidates.
    let candidates: Vec<usize> = (0..joints).filter(|&j| !samples.clip.skeleton().joints()[j].end_site).collect();
    // Per vertex: its four joints and weights, and its squared error summed over samples.
    type FittedRow = (([u16; 4], [f32; 4]), f64);
    let rows: Vec<Result<FittedRow, PoseSpaceError>> = (0..n)
        .into_par_iter()
        .map(|v| {
            let a = DMatrix::from_fn(3 * k, candidates.len(), |row, c| {
                let moved = matrices[(row / 3) * joints + candidates[c]].transform_point3(rest_positions[v]);
                f64::from(moved[row % 3])
            });
            let b = DVector::from_fn(3 * k, |row, _| f64::from(samples.frame_positions(row / 3)[v][row % 3]));
            let solution = nnls(&a, &b).map_err(|e| PoseSpaceError::Samples(format!("vertex {v}: {e}")))?;
            let mut dense = vec![0f32; joints];
            for (c, w) in candidates.iter().zip(solution.x.iter()) {
                dense[*c] = *w as f32;
            }
            let (js, ws) = top_four(&dense, 0);
            let mut err = 0.0;
            for s in 0..k {
                let m = &matrices[s * joints..(s + 1) * joints];
                let p = blend_matrices(m, &js, &ws).transform_point3(rest_positions[v]);
                err += f64::from((p - samples.frame_positions(s)[v]).length_squared());
            }
            Ok(((js, ws), err))
        })
        .collect();
    let mut out = FittedWeights { joints: Vec::with_capacity(n), weights: Vec::with_capacity(n), rms_error_m: 0.0 };
    let mut total = 0.0;
    for row in rows {
        let ((js, ws), err) = row?;
        out.joints.push(js);
        out.weights.push(ws);
        total += err;
    }
    out.rms_error_m = (total / (n * k).max(1) as f64).sqrt();
    Ok(out)
}

const MESH_IN: Input<Arc<Mesh>> = Input::required("mesh", "The skinned mesh, in its rest pose.");
const CLIP_IN: Input<Arc<Clip>> = Input::required("clip", "The motion to deform the mesh with.");
const SAMPLES_IN: Input<Arc<MeshSequence>> = Input::optional(
    "samples",
    "PSD/WPSD only: example shapes of the mesh at sample poses (each frame a pose), e.g. from barnet.deform or sculpts.",
);
const SEQ_OUT: Output<Arc<MeshSequence>> = Output::new("sequence", "The deformed mesh at every frame of the clip.");
choices! {
    /// The `method` choice of `skin.deform`.
    enum Method { Lbs = "lbs", Psd = "psd", Wpsd = "wpsd" }
}
const METHOD: ChoiceParam<Method> = ChoiceParam::new(
    "method",
    "\"lbs\": linear blend skinning (fast; elbows collapse). \"psd\": pose space deformation from the samples. \"wpsd\": weighted PSD, where each vertex compares poses only on the joints that move it (better between samples).",
    "lbs",
);
choices! {
    /// The WPSD weightings `skin.deform` offers (uniform is plain PSD's).
    enum WpsdDistance { JointAndChildren = "joint_and_children", Joint = "joint" }
}
const DISTANCE: ChoiceParam<WpsdDistance> = ChoiceParam::new(
    "wpsd_distance",
    "WPSD only: \"joint_and_children\" also counts the joint at the far end of a vertex's bone (a biceps sees the elbow); \"joint\" is the paper's weighting.",
    "joint_and_children",
);
const WIDTH: FloatParam = FloatParam::new(
    "rbf_width",
    "Width of the Gaussian pose blending, as a multiple of the mean distance between samples (larger = smoother, reaches further).",
    1.0,
    0.05,
    20.0,
    "",
);
const PRINCIPAL: IntParam = IntParam::new(
    "principal_poses",
    "Principal poses kept after PCA of the sample displacements (0 = all samples, exact at the samples).",
    0,
    0,
    1000,
);

/// `skin.deform`.
pub struct Deform;

static DEFORM: NodeSchema = NodeSchema {
    kind: "skin.deform",
    category: "skin",
    doc: "Deforms a skinned mesh over a clip by linear blend skinning, pose space deformation (PSD) or weighted PSD trained on example shapes; outputs the baked mesh per frame.",
    inputs: &[MESH_IN.spec(), CLIP_IN.spec(), SAMPLES_IN.spec()],
    outputs: &[SEQ_OUT.spec()],
    params: &[METHOD.0, DISTANCE.0, WIDTH.0, PRINCIPAL.0],
    writes_files: false,
    version: 1,
};

impl Node for Deform {
    fn schema(&self) -> &'static NodeSchema {
        &DEFORM
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let mesh = ctx.input(&MESH_IN)?;
        let clip = ctx.input(&CLIP_IN)?;
        let samples = ctx.optional_input(&SAMPLES_IN)?;
        let params = PoseSpaceParams {
            distance: match ctx.choice(&DISTANCE)? {
                WpsdDistance::Joint => PoseDistance::JointWeight,
                WpsdDistance::JointAndChildren => PoseDistance::JointAndChildren,
            },
            width_scale: ctx.float(&WIDTH)?,
            principal_poses: ctx.int(&PRINCIPAL)? as usize,
        };
        let method = match ctx.choice(&METHOD)? {
            Method::Psd => DeformMethod::PoseSpace(PoseSpaceParams { distance: PoseDistance::Uniform, ..params }),
            Method::Wpsd => DeformMethod::PoseSpace(params),
            Method::Lbs => DeformMethod::Lbs,
        };
        if matches!(method, DeformMethod::PoseSpace(_)) && samples.is_none() {
            return Err(NodeError::input(SAMPLES_IN.name(), "must be connected for psd and wpsd"));
        }
        if matches!(method, DeformMethod::Lbs) && samples.is_some() {
            ctx.warn("samples are ignored by method lbs");
        }
        ctx.reserve_memory(MeshSequence::estimated_bytes(clip.frame_count(), mesh.positions.len()), CLIP_IN.name())?;
        let seq = deform(&mesh, &clip, samples.as_deref(), method).map_err(|e| match e {
            PoseSpaceError::Skin(e) => NodeError::input(MESH_IN.name(), e.to_string()),
            PoseSpaceError::Samples(m) => NodeError::input(SAMPLES_IN.name(), m),
        })?;
        ctx.set_output(&SEQ_OUT, Arc::new(seq));
        Ok(())
    }
}

const FIT_MESH_IN: Input<Arc<Mesh>> =
    Input::required("mesh", "The skinned mesh in its rest pose (its bind supplies the skeleton and bind pose).");
const FIT_SAMPLES_IN: Input<Arc<MeshSequence>> = Input::required(
    "samples",
    "Example shapes at sample poses (each frame a pose); use poses that differ in every joint.",
);
const FIT_MESH_OUT: Output<Arc<Mesh>> =
    Output::new("mesh", "The mesh with fitted weights (4 principal joints per vertex).");
const RMS_OUT: Output<f64> = Output::new(
    "rms_error_m",
    "Root-mean-square distance (m) between the samples and skinning with the fitted weights.",
);

/// `skin.fit_weights`.
pub struct FitWeights;

static FIT_WEIGHTS: NodeSchema = NodeSchema {
    kind: "skin.fit_weights",
    category: "skin",
    doc: "Computes skin weights from example shapes by non-negative least squares, normalised and reduced to the 4 strongest joints per vertex.",
    inputs: &[FIT_MESH_IN.spec(), FIT_SAMPLES_IN.spec()],
    outputs: &[FIT_MESH_OUT.spec(), RMS_OUT.spec()],
    params: &[],
    writes_files: false,
    version: 1,
};

impl Node for FitWeights {
    fn schema(&self) -> &'static NodeSchema {
        &FIT_WEIGHTS
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let mesh = ctx.input(&FIT_MESH_IN)?;
        let samples = ctx.input(&FIT_SAMPLES_IN)?;
        let skin = mesh
            .skin
            .as_ref()
            .ok_or_else(|| NodeError::input(FIT_MESH_IN.name(), SkinError::NotSkinned.to_string()))?;
        check_skin(skin, samples.clip.skeleton(), mesh.positions.len())
            .map_err(|e| NodeError::input(FIT_SAMPLES_IN.name(), e.to_string()))?;
        let fitted = fit_weights(&mesh.positions, &skin.inverse_bind_matrices, &samples)
            .map_err(|e| NodeError::input(FIT_SAMPLES_IN.name(), e.to_string()))?;
        let mut out = (*mesh).clone();
        out.skin = Some(Skin { joints: fitted.joints, weights: fitted.weights, ..skin.clone() });
        ctx.set_output(&FIT_MESH_OUT, Arc::new(out));
        ctx.set_output(&RMS_OUT, fitted.rms_error_m);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;
    use crate::kernels::arm::arm_clip;
    use glam::Mat4;

    /// Known weights over three joints, sample shapes made by a plain LBS sum written here;
    /// the fit must find the weights again.
    #[test]
    fn nnls_recovers_known_weights_from_synthetic_samples() {
        let poses: Vec<(f32, f32, f32)> = (0..10)
            .map(|i| {
                let t = i as f32;
                ((0.7 * t).sin() * 0.8, 1.2 + (1.3 * t).cos(), (0.4 * t + 1.0).sin())
            })
            .collect();
        let clip = Arc::new(arm_clip(&poses, 24.0).unwrap());
        let skeleton = clip.skeleton().clone();
        let rest = crate::model::fk::rest_world(&skeleton);
        let inverse_bind: Vec<Mat4> = rest.iter().map(|t| t.to_mat4().inverse()).collect();
        let rest_positions: Vec<Vec3> = (0..30)
            .map(|i| {
                Vec3::new(
                    0.06 + 0.02 * i as f32,
                    1.4 + 0.03 * ((i % 3) as f32 - 1.0),
                    0.04 * ((i % 2) as f32 * 2.0 - 1.0),
                )
            })
            .collect();
        let known: Vec<[f32; 5]> = (0..30)
            .map(|i| {
                let a = (i as f32 / 29.0).clamp(0.0, 1.0);
                let raw = [0.0, (1.0 - a) * (1.0 - a), 2.0 * a * (1.0 - a), a * a, 0.0];
                let sum: f32 = raw.iter().sum();
                raw.map(|w| w / sum)
            })
            .collect();
        let poses_fk = crate::model::forward_kinematics(&clip);
        let mut positions = Vec::new();
        for f in 0..clip.frame_count() {
            for (v, p) in rest_positions.iter().enumerate() {
                let mut sum = Vec3::ZERO;
                for j in 0..skeleton.len() {
                    let t = poses_fk.frame(f)[j];
                    let m = Mat4::from_rotation_translation(t.rotation, t.translation) * inverse_bind[j];
                    sum += known[v][j] * m.transform_point3(*p);
                }
                positions.push(sum);
            }
        }
        let rest_mesh = Arc::new(Mesh { positions: rest_positions.clone(), ..Mesh::default() });
        let normals = vec![Vec3::Y; positions.len()];
        let samples = MeshSequence::new(rest_mesh, clip, positions, normals).unwrap();
        let fitted = fit_weights(&rest_positions, &inverse_bind, &samples).unwrap();
        assert!(fitted.rms_error_m < 1e-5, "{}", fitted.rms_error_m);
        for (v, expected) in known.iter().enumerate() {
            let mut dense = [0f32; 5];
            for (j, w) in fitted.joints[v].iter().zip(&fitted.weights[v]) {
                dense[*j as usize] += w;
            }
            for (j, (got, want)) in dense.iter().zip(expected).enumerate() {
                assert!((got - want).abs() < 2e-3, "vertex {v} joint {j}: {got} vs {want}");
            }
        }
    }
}
