//! Bone maps and motion transfer between skeletons of different names, proportions and rest
//! poses (a CMU capture onto a glTF character).
//!
//! Mapping: the body roles of both skeletons (by joint name where the names say, else by
//! shape: [`crate::kernels::roles`]) are paired — pelvis, the
//! spine by relative rest length between pelvis, chest and head, and per leg and arm the joints
//! above the limb (clavicle, hip joint) counted back from it, the upper, lower and end
//! joints, and the joints below the end (toes, fingers) counted on. A RON bone-map file
//! adds to or overrides the pairs.
//!
//! Transfer, in a reference pose chosen per clip ([`ReferencePose`]: its first frame by
//! default, its skeleton's rest pose, or any frame):
//! 1. Per mapped target joint, the reference alignment `A` turns the target's bones to point
//!    where the source's mapped bones point in its reference (one bone: the shortest arc; a
//!    joint with several mapped bones below it, like the pelvis: the best-fit rotation of
//!    all of them, Kabsch). Unmapped joints follow their parent rigidly.
//! 2. Each frame, a mapped target joint takes the source joint's world rotation change
//!    since the reference: `W_t(f) = W_s(f) · W_s(ref)⁻¹ · A · W_t(ref)`; unmapped joints
//!    keep their reference local rotation.
//! 3. The pelvis follows the source's pelvis path scaled by the ratio of leg lengths (or
//!    `root_scale`), the root being moved so the pelvis lands there.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::sync::Arc;

use glam::{Mat3, Quat, Vec3};
use nalgebra::Matrix3;
use serde_json::json;

use crate::formats::FormatError;
use crate::formats::bone_map::{bone_map_from_ron, bone_map_to_ron};
use crate::kernels::roles::{BodyRoles, Limb, RolesError, body_roles, roles_of};
use crate::model::bone_map::BoneMap;
use crate::model::choice::choices;
use crate::model::fk::pose_world;
use crate::model::{Clip, ClipError, Skeleton, Transform};
use crate::node::into_report;
use crate::node::{
    ChoiceParam, FloatParam, Input, InputPathParam, IntParam, Node, NodeContext, NodeError, NodeSchema, Output,
    OutputPathParam, Report, did_you_mean,
};

/// Why a bone map or a transfer failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MapError {
    /// The body parts of a skeleton could not be read from its names or its shape.
    #[error(
        "cannot read the body of the {which} skeleton in its reference pose: {why}. Set map_file to a bone map pairing the {which}'s joints (export.bone_map writes one to edit), with auto = none if the automatic pairs are wrong"
    )]
    Roles {
        /// `source` or `target`.
        which: &'static str,
        /// What was missing.
        #[source]
        why: RolesError,
    },
    /// A bone-map entry names a joint the skeleton lacks.
    #[error("the bone map names {which} joint `{name}`, which the {which} skeleton lacks{hint}")]
    UnknownJoint {
        /// `source` or `target`.
        which: &'static str,
        /// The name.
        name: String,
        /// A "did you mean" suffix, or empty.
        hint: String,
    },
    /// Nothing maps.
    #[error("no joint of the target is mapped")]
    Empty,
    /// No leg lengths to scale the pelvis path by.
    #[error(
        "the legs of the skeletons are not known, so the pelvis path cannot be scaled by leg length ({0}): map both legs' hip, knee and ankle in map_file, or set root_scale (the target's leg length over the source's)"
    )]
    NoRootScale(String),
    /// A clip without frames.
    #[error("the {0} clip has no frames")]
    NoFrames(&'static str),
    /// The reference frame asked for is past the clip's end.
    #[error("the {which} reference frame {frame} is past the clip's last frame ({last})")]
    FramePastEnd {
        /// `source` or `target`.
        which: &'static str,
        /// The frame asked for, from 0.
        frame: usize,
        /// The clip's last frame.
        last: usize,
    },
    /// The result could not be built.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// The automatic map from body roles: target joint → source joint (see the module doc).
pub fn map_by_roles(target: &Skeleton, t: &BodyRoles, source: &Skeleton, s: &BodyRoles) -> BoneMap {
    let mut pairs: Vec<(usize, usize)> = vec![(t.pelvis, s.pelvis)];
    // Spine joints below and above the chest; end sites carry no motion of their own.
    let split = |sk: &Skeleton, r: &BodyRoles| {
        let at = r.spine.iter().position(|&j| j == r.chest).unwrap_or(0);
        let real = |part: &[usize]| part.iter().copied().filter(|&j| !sk.joints()[j].end_site).collect::<Vec<_>>();
        (real(&r.spine[..=at]), real(&r.spine[at + 1..]))
    };
    let (t_lower, t_upper) = split(target, t);
    let (s_lower, s_upper) = split(source, s);
    let (t_rest, s_rest) = (target.rest_positions(), source.rest_positions());
    pairs.extend(by_length((&t_rest, t.pelvis, &t_lower), (&s_rest, s.pelvis, &s_lower)));
    pairs.extend(by_length((&t_rest, t.chest, &t_upper), (&s_rest, s.chest, &s_upper)));
    for (tl, sl) in t.legs.iter().zip(&s.legs).chain(t.arms.iter().zip(&s.arms)) {
        pairs.extend(limb_pairs(tl, sl));
    }
    let name = |sk: &Skeleton, j: usize| sk.joints()[j].name.clone();
    let joints = pairs
        .into_iter()
        .filter(|&(tj, sj)| !target.joints()[tj].end_site && !source.joints()[sj].end_site)
        .map(|(tj, sj)| (name(target, tj), name(source, sj)))
        .collect();
    BoneMap { joints }
}

/// A chain of joints below a joint `from`, with the skeleton's rest positions.
type Chain<'a> = (&'a [Vec3], usize, &'a [usize]);

/// Pairs the joints of two chains by their relative rest length along the chain from its
/// top joint.
fn by_length(target: Chain<'_>, source: Chain<'_>) -> Vec<(usize, usize)> {
    let fractions = |(rest, from, chain): Chain<'_>| {
        let mut along = Vec::with_capacity(chain.len());
        let (mut total, mut previous) = (0.0f32, from);
        for &j in chain {
            total += rest[j].distance(rest[previous]);
            along.push(total);
            previous = j;
        }
        along.iter().map(|a| if total > 0.0 { a / total } else { 1.0 }).collect::<Vec<f32>>()
    };
    let (tf, sf) = (fractions(target), fractions(source));
    let (t_chain, s_chain) = (target.2, source.2);
    t_chain
        .iter()
        .zip(&tf)
        .filter_map(|(&tj, &u)| {
            let k = (0..s_chain.len()).min_by(|&a, &b| (sf[a] - u).abs().total_cmp(&(sf[b] - u).abs()))?;
            Some((tj, s_chain[k]))
        })
        .collect()
}

/// Pairs two limbs: the upper, lower and end joints, the joints above counted back from the
/// upper joint, the joints below counted on from the end; segments a rig splits a bone into
/// (between the upper and lower, or lower and end joints) pair up only where both limbs have
/// as many, and otherwise follow their bone unpaired.
fn limb_pairs(t: &Limb, s: &Limb) -> Vec<(usize, usize)> {
    let above = t.chain[..t.upper].iter().rev().zip(s.chain[..s.upper].iter().rev());
    let mut pairs: Vec<(usize, usize)> = above.map(|(&a, &b)| (a, b)).collect();
    for (tr, sr) in
        [(&t.chain[t.upper..t.lower], &s.chain[s.upper..s.lower]), (&t.chain[t.lower..t.end], &s.chain[s.lower..s.end])]
    {
        let n = if tr.len() == sr.len() { tr.len() } else { 1 };
        pairs.extend(tr.iter().zip(sr).take(n).map(|(&a, &b)| (a, b)));
    }
    pairs.extend(t.chain[t.end..].iter().zip(&s.chain[s.end..]).map(|(&a, &b)| (a, b)));
    pairs
}

/// A bone map resolved to joint indices: `(target joint, source joint)` pairs.
fn resolve(map: &BoneMap, target: &Skeleton, source: &Skeleton) -> Result<Vec<(usize, usize)>, MapError> {
    let find = |sk: &Skeleton, which: &'static str, name: &str| {
        sk.index_of(name).ok_or_else(|| MapError::UnknownJoint {
            which,
            name: name.to_owned(),
            hint: did_you_mean(name, sk.joints().iter().map(|j| j.name.as_str())),
        })
    };
    let mut pairs = map
        .joints
        .iter()
        .map(|(t, s)| Ok((find(target, "target", t)?, find(source, "source", s)?)))
        .collect::<Result<Vec<_>, MapError>>()?;
    pairs.sort_unstable();
    if pairs.is_empty() {
        return Err(MapError::Empty);
    }
    Ok(pairs)
}

/// The pose of a clip in which the two skeletons of a transfer are aligned.
///
/// Both clips should stand alike in their reference poses (two T-poses, or the same frame of
/// a motion): the aligned bones' directions are matched, but a twist about a bone or a bent
/// elbow that only one of them has is carried into every frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ReferencePose {
    /// The clip's first frame: a capture's or an animation's opening pose.
    #[default]
    FirstFrame,
    /// The skeleton's rest pose: a BVH's OFFSETs with no rotation (the T-pose of the CMU
    /// captures), a glTF's or FBX's node transforms (a Mixamo character's bind T-pose), or
    /// its skin's bind pose when `character.load` rests it there (`rest_pose: bind`).
    Rest,
    /// A frame of the clip, from 0 (the frame a named animation stands in its T-pose).
    Frame(usize),
}

/// A pose's local rotations and translations, one per joint: borrowed from a clip's frame or
/// built from the rest pose.
pub type Locals<'c> = (Cow<'c, [Quat]>, Cow<'c, [Vec3]>);

impl ReferencePose {
    /// Local rotations and translations of `clip`'s skeleton in this pose.
    pub fn locals<'c>(self, clip: &'c Clip, which: &'static str) -> Result<Locals<'c>, MapError> {
        let frame = match self {
            ReferencePose::Rest => {
                let joints = clip.skeleton().joints();
                return Ok((
                    joints.iter().map(|j| j.rest_rotation).collect(),
                    joints.iter().map(|j| j.rest_offset).collect(),
                ));
            }
            ReferencePose::FirstFrame => 0,
            ReferencePose::Frame(f) => f,
        };
        match clip.frame_count() {
            0 => Err(MapError::NoFrames(which)),
            n if frame >= n => Err(MapError::FramePastEnd { which, frame, last: n - 1 }),
            _ => Ok((Cow::Borrowed(clip.frame_rotations(frame)), Cow::Borrowed(clip.frame_translations(frame)))),
        }
    }

    /// World transforms of `clip`'s joints in this pose.
    pub fn world(self, clip: &Clip, which: &'static str) -> Result<Vec<Transform>, MapError> {
        let (rotations, translations) = self.locals(clip, which)?;
        let mut world = vec![Transform::IDENTITY; clip.joint_count()];
        pose_world(clip.skeleton(), &rotations, &translations, &mut world);
        Ok(world)
    }
}

/// The reference poses of both clips of a transfer.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct References {
    /// The motion's.
    pub source: ReferencePose,
    /// The character's.
    pub target: ReferencePose,
}

/// The body roles of a clip's skeleton ([`roles_of`]: by name, else by its shape in the
/// reference `pose`).
pub fn clip_roles(clip: &Clip, pose: ReferencePose, which: &'static str) -> Result<BodyRoles, MapError> {
    roles_of(clip.skeleton(), &positions(&pose.world(clip, which)?)).map_err(|why| MapError::Roles { which, why })
}

/// The body roles of a skeleton posed at `world`, read from its shape only.
pub fn shape_roles(skeleton: &Skeleton, world: &[Transform], which: &'static str) -> Result<BodyRoles, MapError> {
    body_roles(skeleton, &positions(world)).map_err(|why| MapError::Roles { which, why: why.into() })
}

fn positions(world: &[Transform]) -> Vec<Vec3> {
    world.iter().map(|t| t.translation).collect()
}

/// The body roles of both skeletons of a transfer, read once.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Bodies {
    /// The character receiving the motion.
    pub target: BodyRoles,
    /// The motion's skeleton.
    pub source: BodyRoles,
}

impl Bodies {
    /// The body roles of `target`'s and `source`'s skeletons in their first frames.
    pub fn of(target: &Clip, source: &Clip) -> Result<Bodies, MapError> {
        Bodies::in_poses(target, source, References::default())
    }

    /// The body roles of `target`'s and `source`'s skeletons ([`clip_roles`]) in the
    /// reference poses.
    pub fn in_poses(target: &Clip, source: &Clip, references: References) -> Result<Bodies, MapError> {
        Ok(Bodies {
            target: clip_roles(target, references.target, "target")?,
            source: clip_roles(source, references.source, "source")?,
        })
    }
}

/// The rotation that best turns the unit directions `from` onto `to` (Kabsch, through the SVD
/// of their 3×3 correlation); the shortest arc for a single pair, identity for none.
fn best_rotation(pairs: &[(Vec3, Vec3)]) -> Quat {
    match pairs {
        [] => Quat::IDENTITY,
        [(a, b)] => Quat::from_rotation_arc(*a, *b),
        _ => {
            let mut h = Matrix3::<f64>::zeros();
            for (a, b) in pairs {
                let (a, b) = (a.as_dvec3(), b.as_dvec3());
                h += nalgebra::Vector3::new(b.x, b.y, b.z) * nalgebra::Vector3::new(a.x, a.y, a.z).transpose();
            }
            let svd = h.svd(true, true);
            let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else { return Quat::IDENTITY };
            let d = (u * v_t).determinant().signum();
            let r = u * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, d)) * v_t;
            let m = Mat3::from_cols(
                Vec3::new(r[(0, 0)] as f32, r[(1, 0)] as f32, r[(2, 0)] as f32),
                Vec3::new(r[(0, 1)] as f32, r[(1, 1)] as f32, r[(2, 1)] as f32),
                Vec3::new(r[(0, 2)] as f32, r[(1, 2)] as f32, r[(2, 2)] as f32),
            );
            Quat::from_mat3(&m)
        }
    }
}

/// Limb joints of `roles` that are not below the joint before them in their limb (an IK
/// rig's feet parented to the root), with that joint: `(joint, the limb joint it follows)`.
pub fn detached_joints(skeleton: &Skeleton, roles: &BodyRoles) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = roles
        .legs
        .iter()
        .chain(&roles.arms)
        .flat_map(|l| l.chain.windows(2).map(|w| (w[1], w[0])))
        .filter(|&(j, p)| !skeleton.is_ancestor(p, j))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// The target's leg length over the source's, the target's legs found through `map` from
/// the source's (read by name or shape): for a hand-written map on a rig whose body cannot be
/// read.
fn leg_ratio_through_map(source: &Clip, target: &Clip, map: &BoneMap, refs: References) -> Result<f64, MapError> {
    let roles = clip_roles(source, refs.source, "source").map_err(|e| MapError::NoRootScale(e.to_string()))?;
    let (s_ref, t_ref) = (refs.source.world(source, "source")?, refs.target.world(target, "target")?);
    let (s_sk, t_sk) = (source.skeleton(), target.skeleton());
    let mut missing = Vec::new();
    let (mut s_len, mut t_len) = (0.0f32, 0.0f32);
    for leg in &roles.legs {
        let joints = leg.joints();
        let mapped: Vec<Option<usize>> = joints
            .iter()
            .map(|&sj| {
                let name = &s_sk.joints()[sj].name;
                let t = map.joints.iter().find(|(_, s)| *s == name).and_then(|(t, _)| t_sk.index_of(t));
                if t.is_none() {
                    missing.push(name.clone());
                }
                t
            })
            .collect();
        if let [Some(a), Some(b), Some(c)] = mapped[..] {
            let [sa, sb, sc] = joints.map(|j| s_ref[j].translation);
            s_len += sa.distance(sb) + sb.distance(sc);
            t_len += t_ref[a].translation.distance(t_ref[b].translation)
                + t_ref[b].translation.distance(t_ref[c].translation);
        }
    }
    if !missing.is_empty() || s_len <= 1e-6 {
        return Err(MapError::NoRootScale(format!("no target joint is mapped to the source's {}", missing.join(", "))));
    }
    Ok(f64::from(t_len / s_len))
}

/// A motion carried onto another skeleton.
#[derive(Clone, Debug)]
pub struct Transferred {
    /// The source's motion on the target skeleton, at the source's frame rate.
    pub clip: Clip,
    /// Target joints no source joint drives (they keep their reference angles).
    pub unmapped: Vec<String>,
    /// Factor applied to the pelvis path.
    pub root_scale: f64,
}

/// How a motion is carried over, beyond the bone map.
#[derive(Clone, Copy, Debug, Default)]
pub struct TransferOptions<'a> {
    /// The body roles of both skeletons: the pelvis pair and the leg-length ratio.
    pub bodies: Option<&'a Bodies>,
    /// Factor on the pelvis path, replacing the leg-length ratio.
    pub root_scale: Option<f64>,
    /// The poses the skeletons are aligned in.
    pub references: References,
}

/// Carries `source`'s motion onto `target`'s skeleton through `map` (see the module doc).
/// Without `options.bodies` the topmost mapped pair carries the path, and the ratio is that
/// of the source's legs and the target joints `map` pairs with them (or `root_scale`).
pub fn transfer(
    source: &Clip,
    target: &Clip,
    map: &BoneMap,
    options: &TransferOptions<'_>,
) -> Result<Transferred, MapError> {
    let TransferOptions { bodies, root_scale, references: refs } = *options;
    let (t_sk, s_sk) = (target.skeleton(), source.skeleton());
    let pairs = resolve(map, t_sk, s_sk)?;
    let (s_ref, t_ref) = (refs.source.world(source, "source")?, refs.target.world(target, "target")?);
    let (t_ref_rotations, t_ref_translations) = refs.target.locals(target, "target")?;
    let scale = match (root_scale, bodies) {
        (Some(s), _) => s,
        (None, Some(b)) => {
            let s_len = b.source.leg_length_m(|j| s_ref[j].translation);
            if s_len > 1e-6 { f64::from(b.target.leg_length_m(|j| t_ref[j].translation) / s_len) } else { 1.0 }
        }
        (None, None) => leg_ratio_through_map(source, target, map, refs)?,
    };
    // The pelvis pair carries the path: from the body roles, or else the topmost mapped joint.
    let pelvis = bodies.map_or(pairs[0], |b| (b.target.pelvis, b.source.pelvis));
    let n = t_sk.len();
    let mut driver: Vec<Option<usize>> = vec![None; n];
    for &(t, s) in &pairs {
        driver[t] = Some(s);
    }
    // The nearest mapped ancestor of each target joint.
    let mut mapped_above: Vec<Option<usize>> = vec![None; n];
    for (j, joint) in t_sk.joints().iter().enumerate() {
        mapped_above[j] = joint.parent.and_then(|p| if driver[p].is_some() { Some(p) } else { mapped_above[p] });
    }
    // Limb joints hanging elsewhere than below the joint before them in the limb (an IK
    // rig's feet under the root) follow that joint: for the alignment and for their place.
    let detached = bodies.map(|b| detached_joints(t_sk, &b.target)).unwrap_or_default();
    let mut follows: Vec<Option<usize>> = vec![None; n];
    for &(j, p) in &detached {
        follows[j] = Some(p);
    }
    // 1. Reference alignment per joint.
    let mut links: Vec<Vec<(Vec3, Vec3)>> = vec![Vec::new(); n];
    for c in 0..n {
        let above = follows[c].filter(|&p| driver[p].is_some()).or(mapped_above[c]);
        let (Some(cs), Some(t)) = (driver[c], above) else { continue };
        let Some(ts) = driver[t] else { continue };
        let (dt, ds) = (t_ref[c].translation - t_ref[t].translation, s_ref[cs].translation - s_ref[ts].translation);
        if let (Some(dt), Some(ds)) = (dt.try_normalize(), ds.try_normalize()) {
            links[t].push((dt, ds));
        }
    }
    let mut align = vec![Quat::IDENTITY; n];
    // Twice: a detached joint may come before the joint it follows in the skeleton's order.
    for _ in 0..if detached.is_empty() { 1 } else { 2 } {
        for j in 0..n {
            let inherited = follows[j].or(t_sk.joints()[j].parent).map_or(Quat::IDENTITY, |p| align[p]);
            align[j] = if driver[j].is_some() && !links[j].is_empty() { best_rotation(&links[j]) } else { inherited };
        }
    }
    // Where each detached joint sits in the frame of the joint it follows, in the reference.
    let held: Vec<(usize, usize, Vec3)> = detached
        .iter()
        .map(|&(j, p)| (j, p, t_ref[p].rotation.inverse() * (t_ref[j].translation - t_ref[p].translation)))
        .collect();
    // Per mapped joint: W_t(f) = W_s(f) · offset, offset = W_s(ref)⁻¹ · A · W_t(ref).
    let offset: Vec<Quat> = (0..n)
        .map(|j| match driver[j] {
            Some(s) => s_ref[s].rotation.inverse() * align[j] * t_ref[j].rotation,
            None => Quat::IDENTITY,
        })
        .collect();
    let frames = source.frame_count();
    let mut rotations = Vec::with_capacity(frames * n);
    let mut translations = Vec::with_capacity(frames * n);
    let mut s_world = vec![Transform::IDENTITY; source.joint_count()];
    let mut t_world = vec![Transform::IDENTITY; n];
    let mut world_rot = vec![Quat::IDENTITY; n];
    for f in 0..frames {
        pose_world(s_sk, source.frame_rotations(f), source.frame_translations(f), &mut s_world);
        let start = rotations.len();
        for (j, joint) in t_sk.joints().iter().enumerate() {
            let parent_rot = joint.parent.map_or(Quat::IDENTITY, |p| world_rot[p]);
            let local = match driver[j] {
                Some(s) => parent_rot.inverse() * s_world[s].rotation * offset[j],
                None => t_ref_rotations[j],
            };
            world_rot[j] = parent_rot * local;
            rotations.push(local);
        }
        translations.extend_from_slice(&t_ref_translations);
        // 3. Root moved so the pelvis follows the scaled source pelvis.
        pose_world(t_sk, &rotations[start..], &translations[start..], &mut t_world);
        let goal = s_world[pelvis.1].translation * scale as f32;
        translations[start] += goal - t_world[pelvis.0].translation;
        // Detached joints are put where the joint they follow carries them.
        for &(j, p, offset) in &held {
            pose_world(t_sk, &rotations[start..], &translations[start..], &mut t_world);
            let goal = t_world[p].transform_point(offset);
            translations[start + j] = match t_sk.joints()[j].parent {
                Some(q) => t_world[q].rotation.inverse() * (goal - t_world[q].translation),
                None => goal,
            };
        }
    }
    let unmapped = (0..n)
        .filter(|&j| driver[j].is_none() && !t_sk.joints()[j].end_site)
        .map(|j| t_sk.joints()[j].name.clone())
        .collect();
    let clip = Clip::new(t_sk.clone(), source.fps(), rotations, translations, target.import_scale)?;
    Ok(Transferred { clip, unmapped, root_scale: scale })
}

const SOURCE: Input<Arc<Clip>> = Input::required("source", "The motion to carry over (e.g. a CMU capture).");
const TARGET: Input<Arc<Clip>> = Input::required(
    "target",
    "A clip on the character to animate (e.g. clip.load of its glTF, with the animation that holds its reference pose): its skeleton receives the motion.",
);
const MAPPED: Output<Arc<Clip>> = Output::new("clip", "The source's motion on the target's skeleton.");
const MAP_OUT: Output<Arc<BoneMap>> =
    Output::new("map", "The bone map used (target joint → source joint), for export.bone_map.");
const REPORT: Output<Arc<Report>> =
    Output::new("report", "The pairs, the target joints left unmapped, the body parts found and the root scale.");
const MAP_FILE: InputPathParam = InputPathParam::optional(
    "map_file",
    "A bone-map RON file (see export.bone_map); its pairs are added to the automatic ones and win over them.",
    &["ron"],
);
choices! {
    /// Where `skeleton.map` finds pairs before the bone-map file's.
    enum AutoPairs { Body = "body", None = "none" }
}
const AUTO: ChoiceParam<AutoPairs> = ChoiceParam::new(
    "auto",
    "How pairs are found before the file's: from the body's shape (legs, arms, spine — any naming), or none (the file only).",
    "body",
);
const ROOT_SCALE: FloatParam = FloatParam::optional(
    "root_scale",
    "Factor on the pelvis path. Unset: the target's leg length over the source's.",
    1e-3,
    1e3,
    "",
);

choices! {
    /// A `*_reference` choice: [`ReferencePose`] without its frame, which a param of its own gives.
    enum Reference { FirstFrame = "first_frame", Rest = "rest", Frame = "frame" }
}
const SOURCE_REFERENCE: ChoiceParam<Reference> = ChoiceParam::new(
    "source_reference",
    "The source's pose the skeletons are aligned in: its first frame, its skeleton's rest pose (a BVH's T-pose), or source_frame. Pick the pose that stands like the target's reference.",
    "first_frame",
);
const SOURCE_FRAME: IntParam = IntParam::new(
    "source_frame",
    "The source's reference frame (from 0) when source_reference is frame.",
    0,
    0,
    1_000_000_000,
);
const TARGET_REFERENCE: ChoiceParam<Reference> = ChoiceParam::new(
    "target_reference",
    "The target's pose the skeletons are aligned in: its first frame, its skeleton's rest pose (a Mixamo character's bind T-pose; character.load's rest_pose picks the node transforms or the skin's bind pose), or target_frame.",
    "first_frame",
);
const TARGET_FRAME: IntParam = IntParam::new(
    "target_frame",
    "The target's reference frame (from 0) when target_reference is frame.",
    0,
    0,
    1_000_000_000,
);

/// The reference pose a choice param and its frame param name.
fn reference_param(
    ctx: &NodeContext<'_>,
    choice: &ChoiceParam<Reference>,
    frame: &IntParam,
) -> Result<ReferencePose, NodeError> {
    Ok(match ctx.choice(choice)? {
        Reference::Rest => ReferencePose::Rest,
        Reference::Frame => ReferencePose::Frame(usize::try_from(ctx.int(frame)?).unwrap_or(usize::MAX)),
        Reference::FirstFrame => ReferencePose::FirstFrame,
    })
}

/// `skeleton.map`.
pub struct MapSkeleton;

static MAP_SKELETON: NodeSchema = NodeSchema {
    kind: "skeleton.map",
    category: "ik",
    doc: "Carries a motion onto a character with other joint names, proportions and rest pose: joints are paired by body part (or a bone-map file), each takes its source joint's turning, the pelvis path is scaled by leg length.",
    inputs: &[SOURCE.spec(), TARGET.spec()],
    outputs: &[MAPPED.spec(), MAP_OUT.spec(), REPORT.spec()],
    params: &[MAP_FILE.0, AUTO.0, ROOT_SCALE.0, SOURCE_REFERENCE.0, SOURCE_FRAME.0, TARGET_REFERENCE.0, TARGET_FRAME.0],
    writes_files: false,
    version: 1,
};

impl Node for MapSkeleton {
    fn schema(&self) -> &'static NodeSchema {
        &MAP_SKELETON
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let source = ctx.input(&SOURCE)?;
        let target = ctx.input(&TARGET)?;
        let failed = |e: MapError| match e {
            MapError::Roles { which: "source", .. } | MapError::NoFrames("source") => {
                NodeError::input("source", e.to_string())
            }
            MapError::FramePastEnd { which: "source", .. } => NodeError::param("source_frame", e.to_string()),
            MapError::FramePastEnd { .. } => NodeError::param("target_frame", e.to_string()),
            MapError::UnknownJoint { .. } | MapError::Empty => NodeError::param("map_file", e.to_string()),
            MapError::NoRootScale(_) => NodeError::param("root_scale", e.to_string()),
            e => NodeError::input("target", e.to_string()),
        };
        let root_scale = ctx.optional_float(&ROOT_SCALE)?;
        let auto = ctx.choice(&AUTO)? == AutoPairs::Body;
        let references = References {
            source: reference_param(ctx, &SOURCE_REFERENCE, &SOURCE_FRAME)?,
            target: reference_param(ctx, &TARGET_REFERENCE, &TARGET_FRAME)?,
        };
        // The body roles are read once: for the automatic pairs, the pelvis and the scale.
        let bodies = match Bodies::in_poses(&target, &source, references) {
            Ok(b) => Some(b),
            Err(e) if auto => return Err(failed(e)),
            Err(_) => None,
        };
        let mut map = BoneMap::default();
        let mut roles = BTreeMap::new();
        if let Some(b) = &bodies {
            if auto {
                map = map_by_roles(target.skeleton(), &b.target, source.skeleton(), &b.source);
            }
            roles.insert("target", roles_json(target.skeleton(), &b.target));
            roles.insert("source", roles_json(source.skeleton(), &b.source));
        }
        if let Some(path) = ctx.optional_input_path(&MAP_FILE)? {
            let text = std::fs::read_to_string(&path).map_err(|e| FormatError::io(&path, &e))?;
            map.joints.extend(bone_map_from_ron(&text, &path)?.joints);
        }
        let options = TransferOptions { bodies: bodies.as_ref(), root_scale, references };
        let out = transfer(&source, &target, &map, &options).map_err(failed)?;
        if !out.unmapped.is_empty() {
            ctx.warn(format!(
                "{} target joints have no source joint and keep their reference angles: {}",
                out.unmapped.len(),
                out.unmapped.join(", ")
            ));
        }
        ctx.set_output(
            &REPORT,
            Arc::new(into_report(json!({
                "pairs": map.joints.len(),
                "map": map.joints,
                "unmapped": out.unmapped,
                "root_scale": out.root_scale,
                "body": roles,
            }))),
        );
        ctx.set_output(&MAPPED, Arc::new(out.clip));
        ctx.set_output(&MAP_OUT, Arc::new(map));
        Ok(())
    }
}

/// The body parts found, by joint name, for the report.
fn roles_json(skeleton: &Skeleton, roles: &BodyRoles) -> serde_json::Value {
    let name = |j: usize| skeleton.joints()[j].name.clone();
    let limb = |l: &Limb| l.joints().map(name);
    json!({
        "pelvis": name(roles.pelvis),
        "chest": name(roles.chest),
        "legs": [limb(&roles.legs[0]), limb(&roles.legs[1])],
        "arms": [limb(&roles.arms[0]), limb(&roles.arms[1])],
    })
}

const MAP_IN: Input<Arc<BoneMap>> = Input::required("map", "The bone map to save (skeleton.map).");
const FILE_OUT: Output<Arc<std::path::PathBuf>> = Output::new("file", "The file written.");
const MAP_FILE_OUT: OutputPathParam =
    OutputPathParam::new("file", "Where to write, relative to the run's output folder.", "ron", "bone_map.ron");

/// `export.bone_map`.
pub struct ExportBoneMap;

static EXPORT_BONE_MAP: NodeSchema = NodeSchema {
    kind: "export.bone_map",
    category: "io",
    doc: "Saves a bone map as a RON file (one `target: source` pair a line) to edit by hand and reuse through skeleton.map's map_file.",
    inputs: &[MAP_IN.spec()],
    outputs: &[FILE_OUT.spec()],
    params: &[MAP_FILE_OUT.0],
    writes_files: true,
    version: 1,
};

impl Node for ExportBoneMap {
    fn schema(&self) -> &'static NodeSchema {
        &EXPORT_BONE_MAP
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let map = ctx.input(&MAP_IN)?;
        let relative = ctx.write_output(&MAP_FILE_OUT, bone_map_to_ron(&map).as_bytes())?;
        ctx.set_output(&FILE_OUT, Arc::new(relative));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::mannequin::mannequin_clip;
    use crate::model::forward_kinematics;

    #[test]
    fn kabsch_recovers_a_known_rotation_and_one_pair_is_the_shortest_arc() {
        let q = Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.3, 0.2);
        let dirs = [Vec3::X, Vec3::new(0.0, 0.6, 0.8), Vec3::new(-0.6, 0.0, 0.8)];
        let pairs: Vec<(Vec3, Vec3)> = dirs.iter().map(|d| (*d, q * *d)).collect();
        assert!(best_rotation(&pairs).angle_between(q) < 1e-5);
        let one = best_rotation(&[(Vec3::X, Vec3::Y)]);
        assert!((one * Vec3::X - Vec3::Y).length() < 1e-6);
        assert!((one.to_axis_angle().1 - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
    }

    #[test]
    fn a_clip_mapped_onto_its_own_skeleton_is_unchanged() {
        let clip = mannequin_clip(40, 30.0, 1.0, 1.2).unwrap();
        let bodies = Bodies::of(&clip, &clip).unwrap();
        let map = map_by_roles(clip.skeleton(), &bodies.target, clip.skeleton(), &bodies.source);
        // Every joint maps to itself (end sites aside, the mannequin has none).
        assert_eq!(map.joints.len(), clip.joint_count());
        assert!(map.joints.iter().all(|(t, s)| t == s));
        let out =
            transfer(&clip, &clip, &map, &TransferOptions { bodies: Some(&bodies), ..Default::default() }).unwrap();
        assert!((out.root_scale - 1.0).abs() < 1e-6);
        let (a, b) = (forward_kinematics(&clip), forward_kinematics(&out.clip));
        for f in 0..clip.frame_count() {
            for j in 0..clip.joint_count() {
                assert!((a.position(f, j) - b.position(f, j)).length() < 1e-5, "frame {f} joint {j}");
            }
        }
    }

    #[test]
    fn a_character_in_another_rest_pose_points_its_bones_like_the_source() {
        // Target: the mannequin 1.3× larger, its first frame turned 90° about Y with the arms
        // raised sideways. Each of its bones must point where the source's does.
        let source = mannequin_clip(30, 30.0, 1.0, 1.2).unwrap();
        let big = Arc::new(source.skeleton().scaled(1.3).unwrap());
        let n = big.len();
        let mut rot = vec![Quat::IDENTITY; n];
        rot[0] = Quat::from_rotation_y(std::f32::consts::FRAC_PI_2);
        for (name, angle) in [("LeftArm", 1.2f32), ("RightArm", -1.2)] {
            rot[big.index_of(name).unwrap()] = Quat::from_rotation_z(angle);
        }
        let tr: Vec<Vec3> = big.joints().iter().map(|j| j.rest_offset).collect();
        let target = Clip::new(big, 30.0, rot, tr, crate::model::ImportScale::METRES).unwrap();
        let bodies = Bodies::of(&target, &source).unwrap();
        let map = map_by_roles(target.skeleton(), &bodies.target, source.skeleton(), &bodies.source);
        let out =
            transfer(&source, &target, &map, &TransferOptions { bodies: Some(&bodies), ..Default::default() }).unwrap();
        assert!((out.root_scale - 1.3).abs() < 1e-4, "{}", out.root_scale);
        let (a, b) = (forward_kinematics(&source), forward_kinematics(&out.clip));
        let sk = source.skeleton();
        for f in 0..source.frame_count() {
            for j in 1..n {
                let p = sk.joints()[j].parent.unwrap();
                let da = (a.position(f, j) - a.position(f, p)).normalize_or_zero();
                let db = (b.position(f, j) - b.position(f, p)).normalize_or_zero();
                assert!(da.angle_between(db) < 1e-3, "frame {f} bone {}", sk.joints()[j].name);
            }
            // The pelvis path is the source's, scaled.
            assert!((b.position(f, 0) - 1.3 * a.position(f, 0)).length() < 1e-4);
        }
    }

    #[test]
    fn map_entries_naming_missing_joints_are_refused_with_a_hint() {
        let clip = mannequin_clip(5, 30.0, 1.0, 1.0).unwrap();
        let map = BoneMap { joints: [("LeftLeg".to_owned(), "LeftLegg".to_owned())].into_iter().collect() };
        let e =
            transfer(&clip, &clip, &map, &TransferOptions { root_scale: Some(1.0), ..Default::default() }).unwrap_err();
        assert!(e.to_string().contains("did you mean 'LeftLeg'"), "{e}");
        assert_eq!(
            transfer(
                &clip,
                &clip,
                &BoneMap::default(),
                &TransferOptions { root_scale: Some(1.0), ..Default::default() }
            )
            .unwrap_err(),
            MapError::Empty
        );
    }
}
