//! Transition synthesis (Peng et al. 2007, "Run-Time Phase"):
//!
//! 1. Locate the node pair: the clusters nearest to the source's last frame and to the
//!    target's first frame.
//! 2. Pick one candidate path with probability ∝ 1/cost (seeded).
//! 3. Chain greedily: for each edge of the path take the passage (not longer than a
//!    limit) whose first frame is nearest the motion's last frame, and join it where the
//!    distance grid between the motion's last 10 frames and the passage's first 25 is
//!    smallest; the target is joined the same way at the end. Each join turns and moves
//!    the incoming frames so heading and floor position match at the join, and blends over
//!    the frames of the motion after the join point (the root's position by a smoothstep
//!    weight, so its velocity does not jump where the blend ends).
//! 4. No candidate path: a greedy walk over the cluster medoids (centre frames) from the
//!    source's cluster to the target's, each step to the nearest medoid that is closer to
//!    the target than the current one; its two halves are averaged into control poses C1,
//!    C2 and the transition follows two Bézier pieces P0–A–C1–M and M–C2–B–P3 (M midway
//!    between C1 and C2, so the curve is C1-continuous; A and B set from the source's last
//!    and the target's first joint velocities, so it is C1 at its ends too), evaluated
//!    on quaternions with de Casteljau slerps, over D(P0, P3)/σ frames (eq. 2).

use glam::{Quat, Vec3};
use rand::Rng;

use crate::kernels::transition_graph::cluster::nearest_centre;
use crate::kernels::transition_graph::distance::{PoseFeatures, heading_yaw, rotation_vector};
use crate::kernels::transition_graph::graph::{EdgeClip, TransitionGraph};
use crate::math::{quat_normalize_or_identity, slerp_short, smoothstep};
use crate::model::{Clip, ClipError, FrameRange};

/// Settings of transition synthesis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SynthesisParams {
    /// Frames at the end of the motion searched for a join (the paper's 10).
    pub window_out_frames: usize,
    /// Frames at the start of the incoming clip searched for a join (the paper's 25).
    pub window_in_frames: usize,
    /// Passages longer than this are used only when an edge has no shorter one.
    pub max_clip_frames: usize,
    /// σ of eq. 2: pose distance covered per frame by the Bézier fallback.
    pub sigma_per_frame: f64,
    /// Bounds of the fallback's length, frames.
    pub min_fallback_frames: usize,
    /// Upper bound of the fallback's length, frames.
    pub max_fallback_frames: usize,
}

impl Default for SynthesisParams {
    fn default() -> Self {
        SynthesisParams {
            window_out_frames: 10,
            window_in_frames: 25,
            max_clip_frames: 60,
            sigma_per_frame: 0.05,
            min_fallback_frames: 4,
            max_fallback_frames: 60,
        }
    }
}

/// Frame-major local transforms read in place from a clip or a motion.
#[derive(Clone, Copy, Debug)]
pub struct Frames<'a> {
    joints: usize,
    fps: f64,
    rotations: &'a [Quat],
    translations: &'a [Vec3],
}

impl<'a> Frames<'a> {
    /// The frames of `clip`.
    pub fn of_clip(clip: &'a Clip) -> Frames<'a> {
        Frames {
            joints: clip.joint_count(),
            fps: clip.fps(),
            rotations: clip.rotations(),
            translations: clip.translations(),
        }
    }

    /// Frame count.
    pub fn frame_count(&self) -> usize {
        self.rotations.len() / self.joints.max(1)
    }

    fn rot(&self, f: usize) -> &'a [Quat] {
        &self.rotations[f * self.joints..(f + 1) * self.joints]
    }

    fn trans(&self, f: usize) -> &'a [Vec3] {
        &self.translations[f * self.joints..(f + 1) * self.joints]
    }

    /// Features of frames `range` (velocities from neighbouring frames of these frames).
    fn features(&self, layout: &PoseFeatures, range: std::ops::Range<usize>) -> PoseFeatures {
        let mut f = layout.clone_empty();
        f.push_frames(self.rotations, self.translations, self.joints, self.fps, range);
        f
    }
}

/// Frame-major local transforms being assembled, on the graph's skeleton.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    joints: usize,
    fps: f64,
    rotations: Vec<Quat>,
    translations: Vec<Vec3>,
}

impl Motion {
    /// The frames of `clip`, copied.
    pub fn of_clip(clip: &Clip) -> Motion {
        Motion {
            joints: clip.joint_count(),
            fps: clip.fps(),
            rotations: clip.rotations().to_vec(),
            translations: clip.translations().to_vec(),
        }
    }

    /// Makes room for `frames` more frames.
    pub fn reserve(&mut self, frames: usize) {
        self.rotations.reserve(frames * self.joints);
        self.translations.reserve(frames * self.joints);
    }

    /// The frames, read in place.
    pub fn frames(&self) -> Frames<'_> {
        Frames { joints: self.joints, fps: self.fps, rotations: &self.rotations, translations: &self.translations }
    }

    /// Frame count.
    pub fn frame_count(&self) -> usize {
        self.frames().frame_count()
    }

    /// The first `frames` frames of a corpus passage in playing order (reversed when it
    /// plays backwards); all of them when `frames` exceeds its length.
    fn of_passage(graph: &TransitionGraph, clip: &EdgeClip, frames: usize) -> Motion {
        let source = &graph.clusters.clip_set.clips()[clip.run.clip as usize].clip;
        let count = frames.min(clip.run.len());
        let (start, end) = (clip.run.start as usize, clip.run.end as usize);
        let order: Box<dyn Iterator<Item = usize>> =
            if clip.backward { Box::new((end - count..end).rev()) } else { Box::new(start..start + count) };
        let j = source.joint_count();
        let mut m = Motion {
            joints: j,
            fps: source.fps(),
            rotations: Vec::with_capacity(count * j),
            translations: Vec::with_capacity(count * j),
        };
        for f in order {
            m.rotations.extend_from_slice(source.frame_rotations(f));
            m.translations.extend_from_slice(source.frame_translations(f));
        }
        m
    }

    /// The motion as a clip on `like`'s skeleton.
    pub fn into_clip(self, like: &Clip) -> Result<Clip, ClipError> {
        Clip::new(like.skeleton().clone(), self.fps, self.rotations, self.translations, like.import_scale)
    }
}

/// Appends `incoming` to `out` at the minimum of the distance grid between `out`'s last
/// `window_out_frames` and `incoming`'s first `window_in_frames`, turning and moving
/// `incoming` to match heading and floor position there and blending over the overlap.
/// Returns the output frame where blending started.
fn join(out: &mut Motion, incoming: Frames<'_>, layout: &PoseFeatures, p: &SynthesisParams) -> usize {
    let n = out.frame_count();
    let (m, w) = (p.window_out_frames.clamp(1, n), p.window_in_frames.clamp(1, incoming.frame_count()));
    let tail = out.frames().features(layout, n - m..n);
    let head = incoming.features(layout, 0..w);
    // The first cell of least distance, in row order. The cell joining the motion's last
    // frame to the incoming first frame bounds the minimum from the start, so the other
    // comparisons can stop as soon as they pass it.
    let corner = tail.distance_to(m - 1, &head, 0);
    let above_corner = f32::from_bits(corner.to_bits() + 1);
    let mut best = (0, 0, f32::INFINITY);
    for a in 0..m {
        for b in 0..w {
            let d = tail.distance_below(a, &head, b, best.2.min(above_corner));
            if d < best.2 && d < above_corner {
                best = (a, b, d);
            }
        }
    }
    let (i, j) = (n - m + best.0, best.1);
    let placement = Placement::new(incoming, j, out.rotations[i * out.joints], out.translations[i * out.joints]);
    let overlap = n - i;
    let last = incoming.frame_count() - 1;
    let joints = out.joints;
    for k in 0..overlap {
        let beta = (k + 1) as f32 / (overlap + 1) as f32;
        // The root's position takes a C1 weight: a straight ramp switched it from the blend's
        // velocity to the incoming's in one frame, a 1.04 m/s jump on walk_punch_kick where
        // a walk's root, still moving, was blended with a punch standing at the join. The
        // joints keep the straight ramp: planted feet then move evenly through the window,
        // slowly enough to stay one plant for the foot clean-up after it (with smoothstep
        // weights they sped up mid-window, the plant split, and a foot jumped 7.7 cm).
        let beta_root = smoothstep(f64::from(beta)) as f32;
        let g = (j + k).min(last);
        let (root_rotation, root_position) = placement.root(incoming, g);
        let at = (i + k) * joints;
        for joint in 0..joints {
            let (rb, tb) = if joint == 0 {
                (root_rotation, root_position)
            } else {
                (incoming.rotations[g * joints + joint], incoming.translations[g * joints + joint])
            };
            out.rotations[at + joint] = slerp_short(out.rotations[at + joint], rb, beta);
            let weight = if joint == 0 { beta_root } else { beta };
            out.translations[at + joint] = out.translations[at + joint].lerp(tb, weight);
        }
    }
    append_placed(out, incoming, (j + overlap).min(incoming.frame_count()), &placement);
    i
}

/// The turn about the vertical and the move on the floor that give frame `frame` of a
/// motion the heading of `root_rotation` and the floor position of `root_position_m`.
struct Placement {
    turn: Quat,
    pivot_m: Vec3,
    floor_m: Vec3,
}

impl Placement {
    fn new(motion: Frames<'_>, frame: usize, root_rotation: Quat, root_position_m: Vec3) -> Placement {
        let pivot = motion.trans(frame)[0];
        Placement {
            turn: Quat::from_rotation_y(heading_yaw(root_rotation) - heading_yaw(motion.rot(frame)[0])),
            pivot_m: Vec3::new(pivot.x, 0.0, pivot.z),
            floor_m: Vec3::new(root_position_m.x, 0.0, root_position_m.z),
        }
    }

    /// Placed root rotation and translation (metres) of frame `frame` of `motion`.
    fn root(&self, motion: Frames<'_>, frame: usize) -> (Quat, Vec3) {
        let (r, t) = (motion.rot(frame)[0], motion.trans(frame)[0]);
        (self.turn * r, self.turn * (t - self.pivot_m) + self.floor_m)
    }
}

/// Appends frames `from..` of `incoming` to `out`, placed.
fn append_placed(out: &mut Motion, incoming: Frames<'_>, from: usize, placement: &Placement) {
    let (n, joints) = (out.frame_count(), out.joints);
    out.rotations.extend_from_slice(&incoming.rotations[from * joints..]);
    out.translations.extend_from_slice(&incoming.translations[from * joints..]);
    for (k, f) in (from..incoming.frame_count()).enumerate() {
        let (r, t) = placement.root(incoming, f);
        out.rotations[(n + k) * joints] = r;
        out.translations[(n + k) * joints] = t;
    }
}

/// What one transition did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TransitionInfo {
    /// Cluster of the source's last frame.
    pub source_cluster: u32,
    /// Cluster of the target's first frame.
    pub target_cluster: u32,
    /// Candidate paths between them.
    pub candidates: usize,
    /// The path followed (clusters), empty for the fallback.
    pub path: Vec<u32>,
    /// Its transition cost (eq. 1); 0 when the clusters coincide; none for the fallback.
    pub cost: Option<f64>,
    /// Whether the Bézier fallback was used.
    pub fallback: bool,
    /// Medoid walk of the fallback (clusters).
    pub medoid_walk: Vec<u32>,
    /// Output frames from the first join (or fallback start) to where the target plays on its own.
    pub frames: FrameRange,
}

/// The cluster nearest frame `frame` of `motion`.
fn locate(graph: &TransitionGraph, motion: Frames<'_>, frame: usize) -> u32 {
    let c = &graph.clusters;
    nearest_centre(&c.features, &c.centres, &motion.features(&c.features, frame..frame + 1), 0).0
}

/// The index of one of `costs` (at least one), drawn with probability proportional to
/// 1 / cost (Peng: cheaper paths are taken more often, every candidate sometimes).
fn pick_by_inverse_cost(costs: impl Iterator<Item = f64> + Clone, rng: &mut impl Rng) -> usize {
    let weight = |c: f64| 1.0 / c.max(1e-9);
    let total: f64 = costs.clone().map(weight).sum();
    let mut pick = rng.gen_range(0.0..total);
    let mut chosen = 0;
    for (k, c) in costs.enumerate() {
        chosen = k;
        pick -= weight(c);
        if pick < 0.0 {
            break;
        }
    }
    chosen
}

/// Appends a transition and then `target` to `out`, which must be on the graph's skeleton
/// and frame rate and hold at least one frame, as must `target`.
pub fn append_transition(
    graph: &TransitionGraph,
    out: &mut Motion,
    target: Frames<'_>,
    params: &SynthesisParams,
    rng: &mut impl Rng,
) -> TransitionInfo {
    let layout = &graph.clusters.features;
    let s = locate(graph, out.frames(), out.frame_count() - 1);
    let t = locate(graph, target, 0);
    let table = graph.paths_from(s);
    let candidates = &table.paths[t as usize];
    let mut info = TransitionInfo {
        source_cluster: s,
        target_cluster: t,
        candidates: candidates.len(),
        path: Vec::new(),
        cost: None,
        fallback: false,
        medoid_walk: Vec::new(),
        frames: FrameRange::new(0, 0),
    };
    let chosen = if s == t {
        Some((vec![s], 0.0))
    } else if candidates.is_empty() {
        None
    } else {
        let index = pick_by_inverse_cost(candidates.iter().map(|c| c.cost), rng);
        Some((candidates[index].nodes.clone(), candidates[index].cost))
    };
    let Some((path, cost)) = chosen else {
        info.fallback = true;
        info.medoid_walk = medoid_walk(graph, s, t);
        let start = out.frame_count();
        let inserted = bezier_fallback(graph, out, target, &info.medoid_walk, params);
        info.frames = FrameRange::new(start, start + inserted);
        return info;
    };
    let mut first_join = None;
    for pair in path.windows(2) {
        let Some(edge) = graph.edge(pair[0], pair[1]) else { continue };
        let short: Vec<&EdgeClip> = edge.clips.iter().filter(|c| c.run.len() <= params.max_clip_frames).collect();
        let pool: Vec<&EdgeClip> = if short.is_empty() { edge.clips.iter().collect() } else { short };
        let last = out.frames().features(layout, out.frame_count() - 1..out.frame_count());
        // The passage whose first frame (velocity from its first two) is nearest.
        let mut best: Option<(&EdgeClip, f32)> = None;
        for c in pool {
            let bound = best.map_or(f32::INFINITY, |b| b.1);
            let d = last.distance_below(0, &Motion::of_passage(graph, c, 2).frames().features(layout, 0..1), 0, bound);
            if d < bound {
                best = Some((c, d));
            }
        }
        if let Some((clip, _)) = best {
            let at = join(out, Motion::of_passage(graph, clip, usize::MAX).frames(), layout, params);
            first_join.get_or_insert(at);
        }
    }
    let before = out.frame_count();
    let at = join(out, target, layout, params);
    info.path = path;
    info.cost = Some(cost);
    info.frames = FrameRange::new(first_join.unwrap_or(at), before);
    info
}

/// Greedy walk over medoids from `s` to `t`: from the current cluster, among the clusters
/// not yet visited and nearer to `t` than the current one, step to the nearest.
pub fn medoid_walk(graph: &TransitionGraph, s: u32, t: u32) -> Vec<u32> {
    let c = &graph.clusters;
    let d = |a: u32, b: u32| c.features.distance(c.centres[a as usize], c.centres[b as usize]);
    let mut walk = vec![s];
    let mut current = s;
    while current != t {
        let to_target = d(current, t);
        current = (0..c.cluster_count() as u32)
            .filter(|&n| n != current && !walk.contains(&n) && d(n, t) < to_target)
            .min_by(|&a, &b| d(current, a).total_cmp(&d(current, b)).then(a.cmp(&b)))
            .unwrap_or(t);
        walk.push(current);
    }
    walk
}

/// A full pose in heading-free form: root height (m), root rotation with its heading
/// removed, every other joint's local rotation.
#[derive(Clone, Debug, PartialEq)]
struct Pose {
    height_m: f32,
    rotations: Vec<Quat>,
}

fn heading_free(rotations: &[Quat], root_position_m: Vec3) -> Pose {
    let mut rotations = rotations.to_vec();
    rotations[0] = Quat::from_rotation_y(-heading_yaw(rotations[0])) * rotations[0];
    Pose { height_m: root_position_m.y, rotations }
}

/// The pose at frame `frame` of `motion`, heading-free.
fn pose_of(motion: Frames<'_>, frame: usize) -> Pose {
    heading_free(motion.rot(frame), motion.trans(frame)[0])
}

/// The average of poses: mean height, per joint the normalised sum of sign-aligned
/// quaternions (close to the rotation mean for the nearby poses of a walk half).
fn average(poses: &[Pose]) -> Pose {
    let mut out = poses[0].clone();
    out.height_m = poses.iter().map(|p| p.height_m).sum::<f32>() / poses.len() as f32;
    for (k, q) in out.rotations.iter_mut().enumerate() {
        let reference = *q;
        let sum = poses.iter().fold(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0), |acc, p| {
            let r = p.rotations[k];
            acc + if r.dot(reference) < 0.0 { -r } else { r }
        });
        *q = quat_normalize_or_identity(sum);
    }
    out
}

/// The largest rotation (radians) a velocity control point adds to a pose: keeps every
/// de Casteljau slerp well inside the short arc.
const MAX_LEAD_RAD: f32 = 2.0;

/// `to` carried on by `frames` more frames of the motion that went from `from` to `to` in
/// one frame (per joint the same rotation again, at most [`MAX_LEAD_RAD`]; the height
/// likewise). As a cubic Bézier's second control point over a piece of 3 × `frames`
/// frames it makes the curve leave `to` at the speed the motion arrived with.
fn carried_on(from: &Pose, to: &Pose, frames: f32) -> Pose {
    let rotations = from
        .rotations
        .iter()
        .zip(&to.rotations)
        .map(|(a, b)| {
            let lead = rotation_vector(*a, *b) * frames;
            *b * Quat::from_scaled_axis(lead.clamp_length_max(MAX_LEAD_RAD))
        })
        .collect();
    Pose { height_m: to.height_m + (to.height_m - from.height_m) * frames, rotations }
}

/// Cubic Bézier on poses at `s` ∈ [0, 1] by de Casteljau with slerps: writes the joint
/// rotations into `rotations` and returns the height (m).
fn cubic(points: [&Pose; 4], s: f32, rotations: &mut [Quat]) -> f32 {
    let [a, b, c, d] = points;
    let lerp = |x: f32, y: f32| x + (y - x) * s;
    for (k, r) in rotations.iter_mut().enumerate() {
        let (p, q, u, v) = (a.rotations[k], b.rotations[k], c.rotations[k], d.rotations[k]);
        let (pq, qu, uv) = (slerp_short(p, q, s), slerp_short(q, u, s), slerp_short(u, v, s));
        *r = slerp_short(slerp_short(pq, qu, s), slerp_short(qu, uv, s), s);
    }
    let (ab, bc, cd) = (lerp(a.height_m, b.height_m), lerp(b.height_m, c.height_m), lerp(c.height_m, d.height_m));
    lerp(lerp(ab, bc), lerp(bc, cd))
}

/// The Bézier fallback: appends the interpolated frames, then `target` placed at the
/// source's last heading and floor position. Returns the number of interpolated frames.
///
/// The curve has two cubic pieces, P0–A–C1–M and M–C2–B–P3 (P0 the source's last pose,
/// P3 the target's first, C1 and C2 the averaged halves of the medoid walk, M midway
/// between C1 and C2 so the pieces meet with equal velocity). A and B come from the end
/// velocities — P0 carried on by a sixth of the transition's frames at the source's last
/// per-frame velocity, P3 carried back likewise at the target's first — so the curve
/// leaves the source and enters the target at their own joint angular velocities instead
/// of with a jump (the paper's quadratic pieces start and stop at rest).
fn bezier_fallback(
    graph: &TransitionGraph,
    out: &mut Motion,
    target: Frames<'_>,
    walk: &[u32],
    p: &SynthesisParams,
) -> usize {
    let c = &graph.clusters;
    let last = out.frame_count() - 1;
    let medoid = |n: u32| {
        let (clip, frame) = c.locate(c.centres[n as usize]);
        let clip = &c.clip_set.clips()[clip].clip;
        heading_free(clip.frame_rotations(frame), clip.frame_translations(frame)[0])
    };
    let half = walk.len().div_ceil(2);
    let c1 = average(&walk[..half].iter().map(|&n| medoid(n)).collect::<Vec<_>>());
    let c2 = average(&walk[half..].iter().map(|&n| medoid(n)).collect::<Vec<_>>());
    let mid = Pose {
        height_m: 0.5 * (c1.height_m + c2.height_m),
        rotations: c1.rotations.iter().zip(&c2.rotations).map(|(a, b)| slerp_short(*a, *b, 0.5)).collect(),
    };
    let (p0, p3) = (pose_of(out.frames(), last), pose_of(target, 0));
    let layout = &c.features;
    let d = out.frames().features(layout, last..last + 1).distance_to(0, &target.features(layout, 0..1), 0);
    let frames = ((f64::from(d) / p.sigma_per_frame).round() as usize)
        .clamp(p.min_fallback_frames.max(2), p.max_fallback_frames);
    let lead = frames as f32 / 6.0;
    let a = carried_on(&pose_of(out.frames(), last.saturating_sub(1)), &p0, lead);
    let b = carried_on(&pose_of(target, 1.min(target.frame_count() - 1)), &p3, lead);
    let (root_rotation, root_position) = (out.rotations[last * out.joints], out.translations[last * out.joints]);
    let heading = Quat::from_rotation_y(heading_yaw(root_rotation));
    let joints = out.joints;
    out.rotations.reserve((frames - 1 + target.frame_count()) * joints);
    out.translations.reserve((frames - 1 + target.frame_count()) * joints);
    for k in 1..frames {
        let u = k as f32 / frames as f32;
        let at = out.rotations.len();
        out.rotations.extend_from_within(last * joints..(last + 1) * joints);
        out.translations.extend_from_within(last * joints..(last + 1) * joints);
        let rotations = &mut out.rotations[at..];
        let height_m = if u < 0.5 {
            cubic([&p0, &a, &c1, &mid], 2.0 * u, rotations)
        } else {
            cubic([&mid, &c2, &b, &p3], 2.0 * u - 1.0, rotations)
        };
        rotations[0] = heading * rotations[0];
        out.translations[at] = Vec3::new(root_position.x, height_m, root_position.z);
    }
    append_placed(out, target, 0, &Placement::new(target, 0, root_rotation, root_position));
    frames - 1
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// Paths of cost 1, 2 and 4 are taken with probabilities 4/7, 2/7 and 1/7 (1/cost,
    /// normalised by hand): 70,000 draws within a chi-square bound (2 degrees of freedom,
    /// 13.8 is the 0.1 % tail), and a path of cost 0 is not divided by zero.
    #[test]
    fn paths_are_chosen_in_proportion_to_one_over_their_cost() {
        let costs = [1.0, 2.0, 4.0];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let draws = 70_000;
        let mut counts = [0usize; 3];
        for _ in 0..draws {
            counts[pick_by_inverse_cost(costs.iter().copied(), &mut rng)] += 1;
        }
        let expected = [4.0, 2.0, 1.0].map(|share| share / 7.0 * draws as f64);
        let chi2: f64 = counts.iter().zip(expected).map(|(&o, e)| (o as f64 - e).powi(2) / e).sum();
        println!("counts {counts:?}, expected {expected:?}, chi² {chi2:.2}");
        assert!(chi2 < 13.8, "counts {counts:?} against {expected:?}: chi² {chi2}");
        let free = (0..100).filter(|_| pick_by_inverse_cost([0.0, 1.0].into_iter(), &mut rng) == 0).count();
        assert!(free > 95, "a free path taken {free} times in 100");
    }
}
