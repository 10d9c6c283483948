//! The body mass model behind angular momentum: which joints carry how much mass, and where
//! each segment's centre of mass sits.
//!
//! Segments and their parameters follow de Leva (1996), "Adjustments to Zatsiorsky–
//! Seluyanov's segment inertia parameters", Table 4 (mass as a share of body mass; centre
//! of mass as a share of the segment's length from its named end). Joints are matched to
//! segments by name (CMU, DAZ, 3ds Max, HumanIK and Mixamo-style names); a skeleton that
//! does not match falls back to masses proportional to bone length. A RON file may replace
//! the mapping entirely.
//!
//! Every centre of mass is a fixed weighted sum of joint world positions, because bones are
//! rigid: evaluating the model per frame is a handful of multiply-adds.
//!
//! A kernel: the momentum analysis, foot contacts, body roles and retargeting all read it.

use std::collections::BTreeMap;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::model::choice::{Choice, choices};

use crate::model::Skeleton;
use crate::model::fk::rest_world;

/// Which anthropometric table to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MassTable {
    /// de Leva 1996, male subjects.
    DeLevaMale,
    /// de Leva 1996, female subjects.
    DeLevaFemale,
    /// Mass proportional to bone length, centre at each bone's middle (no name mapping).
    BoneLength,
}

choices!(MassTable { DeLevaMale = "de_leva_male", DeLevaFemale = "de_leva_female", BoneLength = "bone_length" });

/// One mass-carrying segment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Segment {
    /// Canonical name (`"left_thigh"`, `"upper_trunk"`), shared by every skeleton that maps,
    /// so two clips on different rigs can still be compared segment by segment.
    pub name: String,
    /// Mass, kilograms.
    pub mass_kg: f64,
    /// Centre of mass = Σ weight · world position of joint; weights sum to one.
    pub com_weights: Vec<(usize, f32)>,
    /// The joints that define the segment, for the report.
    pub joints: Vec<String>,
    /// How the segment was obtained (table row, fallback, override).
    pub rule: String,
}

/// Mass segments of one skeleton.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BodyModel {
    /// Total mass, kilograms (the sum of the segments').
    pub total_mass_kg: f64,
    /// How the skeleton was mapped: `"de_leva_male"`, `"de_leva_female"`, `"bone_length"`
    /// or `"override"`.
    pub method: String,
    /// The segments.
    pub segments: Vec<Segment>,
}

impl BodyModel {
    /// World centre of mass of `segment` given every joint's world position.
    #[inline]
    pub fn segment_com(&self, segment: &Segment, joint_pos_in_world: &[Vec3]) -> Vec3 {
        segment.com_weights.iter().map(|&(j, w)| joint_pos_in_world[j] * w).sum()
    }
}

/// Why a body model could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BodyError {
    /// The override names a joint the skeleton lacks.
    #[error("mass override segment '{segment}': no joint named '{joint}'{hint}")]
    UnknownJoint {
        /// Segment name.
        segment: String,
        /// Missing joint name.
        joint: String,
        /// " (did you mean …?)" or empty.
        hint: String,
    },
    /// The override is unusable.
    #[error("mass override: {0}")]
    BadOverride(String),
    /// No bone has length: nothing can carry mass.
    #[error("the skeleton has no bones with length, so no mass can be placed")]
    NoBones,
}

/// A RON file that replaces the name mapping: each segment spans two joints and carries a
/// share of the total mass.
///
/// ```ron
/// (segments: [
///     (name: "pelvis", mass_fraction: 0.14, from: "Hips", to: "LowerBack", com_fraction: 0.5),
/// ])
/// ```
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MassOverride {
    /// The segments; their mass fractions are rescaled to sum to one.
    pub segments: Vec<OverrideSegment>,
}

/// One segment of a [`MassOverride`].
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OverrideSegment {
    /// Segment name for reports.
    pub name: String,
    /// Share of the total mass (any positive scale; shares are normalised).
    pub mass_fraction: f64,
    /// Joint at the segment's start.
    pub from: String,
    /// Joint at the segment's end.
    pub to: String,
    /// Centre of mass position along `from → to`, 0..=1.
    pub com_fraction: f64,
}

/// Builds the body model of `skeleton` with `total_mass_kg`, from `table`, or from
/// `override_` when given.
pub fn body_model(
    skeleton: &Skeleton,
    total_mass_kg: f64,
    table: MassTable,
    override_: Option<&MassOverride>,
) -> Result<BodyModel, BodyError> {
    let mut model = match (override_, table) {
        (Some(o), _) => from_override(skeleton, o)?,
        (None, MassTable::BoneLength) => bone_length_model(skeleton)?,
        (None, table) => match find_landmarks(skeleton) {
            Ok(landmarks) => de_leva_model(skeleton, &landmarks, table),
            Err(missing) => {
                let mut m = bone_length_model(skeleton)?;
                m.method = format!("bone_length (names not recognised: {})", missing.join(", "));
                m
            }
        },
    };
    let share: f64 = model.segments.iter().map(|s| s.mass_kg).sum();
    for s in &mut model.segments {
        s.mass_kg *= total_mass_kg / share;
    }
    model.total_mass_kg = total_mass_kg;
    Ok(model)
}

/// Named body landmarks found in a skeleton: what the mass table, contacts and alignment
/// need to know about a rig.
#[derive(Clone, Debug, PartialEq)]
pub struct Landmarks {
    /// Per side (left, right): thigh, shank, foot, upper arm, forearm, hand joints.
    pub limbs: [[usize; 6]; 2],
    /// The lowest neck joint (base of the neck).
    pub neck: usize,
    /// The head joint.
    pub head: usize,
}

impl Landmarks {
    /// The ankle joints, left then right.
    pub fn feet(&self) -> [usize; 2] {
        [self.limbs[0][2], self.limbs[1][2]]
    }

    /// The hip joints (top of each thigh), left then right.
    pub fn hips(&self) -> [usize; 2] {
        [self.limbs[0][0], self.limbs[1][0]]
    }

    /// The shoulder joints (top of each upper arm), left then right.
    pub fn shoulders(&self) -> [usize; 2] {
        [self.limbs[0][3], self.limbs[1][3]]
    }
}

/// The tip of the limb that starts at `joint`: its descendant farthest away in the rest
/// pose (a foot's toe tip), or `joint` itself when it has none.
pub fn limb_tip(skeleton: &Skeleton, joint: usize) -> usize {
    let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
    farthest_descendant(skeleton, &rest, joint)
}

const LIMB_ROLES: [&str; 6] = ["thigh", "shank", "foot", "upper_arm", "forearm", "hand"];

/// Words of a joint name that say nothing about the body part: rig prefixes (Rigify `DEF-`,
/// `ORG-`, `MCH-`; 3ds Max `Bip01`; VRM `J_Bip_`; HumanIK `Character1_`; Mixamo exported
/// with `_` for `:`), centre markers (`_C`, `_M`). Numbers are dropped too (`neck_01`,
/// Rigify's `.001` twist segments).
const NOISE_WORDS: &[&str] = &["def", "org", "mch", "bip", "j", "c", "m", "character", "mixamorig"];

/// The words of a joint name: split at `_ - . :` and spaces, at lower-to-upper case changes
/// (`UpperLegL` → Upper, Leg, L), before the last capital of a capital run followed by a
/// small letter (`RHip` → R, Hip) and between letters and digits.
fn name_words(name: &str) -> Vec<String> {
    let chars: Vec<char> = name.chars().collect();
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    for (i, &c) in chars.iter().enumerate() {
        if !c.is_ascii_alphanumeric() {
            if !word.is_empty() {
                words.push(std::mem::take(&mut word));
            }
            continue;
        }
        if let Some(&prev) = word.chars().last().as_ref() {
            let next = chars.get(i + 1).copied().unwrap_or(' ');
            let camel = prev.is_ascii_lowercase() && c.is_ascii_uppercase();
            let acronym_end = prev.is_ascii_uppercase() && c.is_ascii_uppercase() && next.is_ascii_lowercase();
            let digits = prev.is_ascii_digit() != c.is_ascii_digit();
            if camel || acronym_end || digits {
                words.push(std::mem::take(&mut word));
            }
        }
        word.push(c);
    }
    if !word.is_empty() {
        words.push(word);
    }
    words
}

/// Which body side a joint name names, and the rest of the name, lowercase, without
/// namespace, rig prefixes, numbers and separators: `mixamorig:LeftUpLeg`,
/// `Character1_LeftUpLeg`, `lThigh`, `L_Femur`, `thigh_l` (Unreal), `DEF-thigh.L` (Rigify),
/// `Bip01 L Thigh` (3ds Max), `J_Bip_L_UpperLeg` (VRM), `UpperLegL` (game rigs) all read as
/// (left, "upleg" / "thigh" / "femur" / "upperleg").
fn side_and_role(name: &str) -> (Option<usize>, String) {
    // Namespaces: "mixamorig:LeftArm".
    let name = name.rsplit(':').next().unwrap_or(name);
    let mut side = None;
    let mut role = String::new();
    for word in name_words(name) {
        let lower = word.to_ascii_lowercase();
        if lower.chars().all(|c| c.is_ascii_digit()) || NOISE_WORDS.contains(&lower.as_str()) {
            continue;
        }
        let found = match lower.as_str() {
            "l" | "left" => Some((0, "")),
            "r" | "right" => Some((1, "")),
            // All lower case: "leftupleg".
            w if w.starts_with("left") => Some((0, &w[4..])),
            w if w.starts_with("right") => Some((1, &w[5..])),
            _ => None,
        };
        match found {
            Some((s, rest)) if side.is_none() => {
                side = Some(s);
                role.push_str(rest);
            }
            _ => role.push_str(&lower),
        }
    }
    (side, role)
}

/// Role names by priority: an earlier word wins over a later one on the same side.
fn limb_role_words(role: usize) -> &'static [&'static str] {
    match role {
        0 => &["upleg", "thigh", "upperleg", "femur", "hip"],
        1 => &["leg", "shin", "lowerleg", "calf", "knee", "tibia"],
        2 => &["foot", "ankle"],
        3 => &["arm", "shldr", "upperarm", "humerus", "shoulder"],
        4 => &["forearm", "lowerarm", "elbow", "radius"],
        _ => &["hand", "wrist"],
    }
}

/// The joint playing limb `role` (index into [`LIMB_ROLES`]) on `side` (0 left, 1 right).
fn find_role(
    joints: &[crate::model::Joint],
    parsed: &[(Option<usize>, String)],
    side: usize,
    role: usize,
) -> Option<usize> {
    limb_role_words(role).iter().find_map(|word| {
        (0..joints.len()).find(|&j| !joints[j].end_site && parsed[j].0 == Some(side) && parsed[j].1 == *word)
    })
}

/// The first pair of a limb chain where a joint is not below the previous one, as a message.
/// With `detached_end`, the last joint (a foot or hand) may hang elsewhere in the hierarchy
/// (IK-style game rigs parent the feet to the root) as long as it is not above the joint
/// before it.
fn chain_order_problem(skeleton: &Skeleton, side: usize, chain: &[usize], detached_end: bool) -> Option<String> {
    let joints = skeleton.joints();
    let last = chain.len().saturating_sub(2);
    let in_order = |k: usize, pair: &[usize]| {
        skeleton.is_ancestor(pair[0], pair[1])
            || (detached_end && k == last && pair[0] != pair[1] && !skeleton.is_ancestor(pair[1], pair[0]))
    };
    chain.windows(2).enumerate().find(|(k, pair)| !in_order(*k, pair)).map(|(_, pair)| {
        format!("{} chain order ({} above {})", ["left", "right"][side], joints[pair[0]].name, joints[pair[1]].name)
    })
}

/// Finds the leg joints by name: per side (left, right) thigh, shank and foot (ankle), or
/// lists the roles it could not find. Unlike [`find_landmarks`] it needs no arms or head.
pub fn find_legs(skeleton: &Skeleton) -> Result<[[usize; 3]; 2], Vec<String>> {
    let joints = skeleton.joints();
    let parsed: Vec<(Option<usize>, String)> = joints.iter().map(|j| side_and_role(&j.name)).collect();
    let mut missing = Vec::new();
    let mut legs = [[0usize; 3]; 2];
    for (side, slots) in legs.iter_mut().enumerate() {
        for (role, slot) in slots.iter_mut().enumerate() {
            match find_role(joints, &parsed, side, role) {
                Some(j) => *slot = j,
                None => missing.push(format!("{} {}", ["left", "right"][side], LIMB_ROLES[role])),
            }
        }
    }
    if missing.is_empty() {
        missing.extend((0..2).filter_map(|side| chain_order_problem(skeleton, side, &legs[side], false)));
    }
    if missing.is_empty() { Ok(legs) } else { Err(missing) }
}

/// Finds the landmark joints by name, or lists the roles it could not find.
pub fn find_landmarks(skeleton: &Skeleton) -> Result<Landmarks, Vec<String>> {
    landmarks_by_name(skeleton, false)
}

/// [`find_landmarks`], also accepting feet and hands that hang elsewhere in the hierarchy
/// than below their knee or elbow (IK-style game rigs parent the feet to the root): their
/// limb is then read by position, not by parenthood ([`crate::kernels::roles`]).
pub fn find_landmarks_detached(skeleton: &Skeleton) -> Result<Landmarks, Vec<String>> {
    landmarks_by_name(skeleton, true)
}

/// The body parts found by joint name, as `left thigh = UpperLegL` lines for messages that
/// say what was found and what was not.
pub fn found_by_name(skeleton: &Skeleton) -> Vec<String> {
    let joints = skeleton.joints();
    let parsed: Vec<(Option<usize>, String)> = joints.iter().map(|j| side_and_role(&j.name)).collect();
    let mut found = Vec::new();
    for side in 0..2 {
        for (role, what) in LIMB_ROLES.iter().enumerate() {
            if let Some(j) = find_role(joints, &parsed, side, role) {
                found.push(format!("{} {what} = {}", ["left", "right"][side], joints[j].name));
            }
        }
    }
    for (what, pred) in [("neck", &(|r: &str| r.contains("neck")) as &dyn Fn(&str) -> bool), ("head", &|r| r == "head")]
    {
        if let Some(j) = (0..joints.len()).find(|&j| !joints[j].end_site && pred(&parsed[j].1)) {
            found.push(format!("{what} = {}", joints[j].name));
        }
    }
    found
}

fn landmarks_by_name(skeleton: &Skeleton, detached_ends: bool) -> Result<Landmarks, Vec<String>> {
    let joints = skeleton.joints();
    let parsed: Vec<(Option<usize>, String)> = joints.iter().map(|j| side_and_role(&j.name)).collect();
    let mut missing = Vec::new();
    let mut limbs = [[0usize; 6]; 2];
    for (side, slots) in limbs.iter_mut().enumerate() {
        for (role, slot) in slots.iter_mut().enumerate() {
            match find_role(joints, &parsed, side, role) {
                Some(j) => *slot = j,
                None => missing.push(format!("{} {}", ["left", "right"][side], LIMB_ROLES[role])),
            }
        }
    }
    let central = |pred: &dyn Fn(&str) -> bool| (0..joints.len()).find(|&j| !joints[j].end_site && pred(&parsed[j].1));
    let neck = central(&|r| r.contains("neck"));
    let head = central(&|r| r == "head");
    if neck.is_none() {
        missing.push("neck".into());
    }
    if head.is_none() {
        missing.push("head".into());
    }
    // Each limb joint must sit below the previous one, or the names lied.
    if missing.is_empty() {
        for (side, slots) in limbs.iter().enumerate() {
            if let Some(problem) =
                [&slots[0..3], &slots[3..6]].iter().find_map(|c| chain_order_problem(skeleton, side, c, detached_ends))
            {
                missing.push(problem);
                break;
            }
        }
    }
    match (neck, head, missing.is_empty()) {
        (Some(neck), Some(head), true) => Ok(Landmarks { limbs, neck, head }),
        _ => Err(missing),
    }
}

/// The descendant of `joint` farthest from it in the rest pose (a limb's tip), or `joint`.
fn farthest_descendant(skeleton: &Skeleton, rest: &[Vec3], joint: usize) -> usize {
    (joint..skeleton.len())
        .filter(|&d| d == joint || skeleton.is_ancestor(joint, d))
        .max_by(|&a, &b| rest[a].distance_squared(rest[joint]).total_cmp(&rest[b].distance_squared(rest[joint])))
        .unwrap_or(joint)
}

/// The child of `joint` nearest to it in the rest pose with some length, or `joint`.
fn nearest_child(skeleton: &Skeleton, rest: &[Vec3], joint: usize) -> usize {
    skeleton
        .children(joint)
        .filter(|&c| rest[c].distance(rest[joint]) > 1e-6)
        .min_by(|&a, &b| rest[a].distance_squared(rest[joint]).total_cmp(&rest[b].distance_squared(rest[joint])))
        .unwrap_or(joint)
}

/// A point as weights over joints: `(1 − t)·a + t·b`.
fn lerp_weights(a: &[(usize, f32)], b: &[(usize, f32)], t: f64) -> Vec<(usize, f32)> {
    let mut merged: BTreeMap<usize, f64> = BTreeMap::new();
    for &(j, w) in a {
        *merged.entry(j).or_default() += f64::from(w) * (1.0 - t);
    }
    for &(j, w) in b {
        *merged.entry(j).or_default() += f64::from(w) * t;
    }
    merged.into_iter().filter(|(_, w)| w.abs() > 1e-9).map(|(j, w)| (j, w as f32)).collect()
}

/// de Leva (1996) Table 4 rows: (segment, mass share %, centre of mass % from the
/// proximal end) for male and female subjects. Head: from the vertex; hand: from the wrist
/// towards the third knuckle; foot: from the heel (applied from the ankle here).
const DE_LEVA_LIMBS: [(&str, [f64; 2], [f64; 2]); 6] = [
    ("thigh", [14.16, 14.78], [40.95, 36.12]),
    ("shank", [4.33, 4.81], [44.59, 44.16]),
    ("foot", [1.37, 1.29], [44.15, 40.14]),
    ("upper_arm", [2.71, 2.55], [57.72, 57.54]),
    ("forearm", [1.62, 1.38], [45.74, 45.59]),
    ("hand", [0.61, 0.56], [79.00, 74.74]),
];
const DE_LEVA_HEAD: ([f64; 2], [f64; 2]) = ([6.94, 6.68], [59.76, 58.94]);
/// Trunk thirds from the neck down: (segment, mass %, start and end as shares of the
/// neck–hip length, centre of mass % from the segment's top), male then female.
/// (segment, mass %, start share, end share, centre of mass % from the top).
type TrunkRow = (&'static str, f64, f64, f64, f64);
const DE_LEVA_TRUNK: [[TrunkRow; 3]; 2] = [
    [
        ("upper_trunk", 15.96, 0.0, 0.3209, 50.66),
        ("middle_trunk", 16.33, 0.3209, 0.7261, 45.02),
        ("lower_trunk", 11.17, 0.7261, 1.0, 61.15),
    ],
    [
        ("upper_trunk", 15.45, 0.0, 0.2692, 50.50),
        ("middle_trunk", 14.65, 0.2692, 0.6571, 45.12),
        ("lower_trunk", 12.47, 0.6571, 1.0, 49.20),
    ],
];

fn de_leva_model(skeleton: &Skeleton, lm: &Landmarks, table: MassTable) -> BodyModel {
    let sex = usize::from(table == MassTable::DeLevaFemale);
    let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
    let names = skeleton.joints();
    let point = |j: usize| vec![(j, 1.0f32)];
    let mut segments = Vec::new();
    let table_name = if sex == 0 { "de Leva 1996 male" } else { "de Leva 1996 female" };
    for (side, slots) in lm.limbs.iter().enumerate() {
        for (role, &(segment, mass, com)) in DE_LEVA_LIMBS.iter().enumerate() {
            let proximal = slots[role];
            let distal = match role {
                0 | 1 | 3 | 4 => slots[role + 1],
                2 => farthest_descendant(skeleton, &rest, proximal),
                _ => nearest_child(skeleton, &rest, proximal),
            };
            segments.push(Segment {
                name: format!("{}_{segment}", ["left", "right"][side]),
                mass_kg: mass[sex],
                com_weights: lerp_weights(&point(proximal), &point(distal), com[sex] / 100.0),
                joints: vec![names[proximal].name.clone(), names[distal].name.clone()],
                rule: format!("{table_name} {segment}"),
            });
        }
    }
    // Head: from the vertex (the head's farthest descendant; one head length above the
    // neck when the head has none) towards the neck.
    let tip = farthest_descendant(skeleton, &rest, lm.head);
    let vertex = if tip == lm.head { lerp_weights(&point(lm.neck), &point(lm.head), 2.0) } else { point(tip) };
    segments.push(Segment {
        name: "head".into(),
        mass_kg: DE_LEVA_HEAD.0[sex],
        com_weights: lerp_weights(&vertex, &point(lm.neck), DE_LEVA_HEAD.1[sex] / 100.0),
        joints: vec![names[tip].name.clone(), names[lm.neck].name.clone()],
        rule: format!("{table_name} head"),
    });
    // Trunk: the spine polyline from the neck down to the middle of the hips, cut in
    // thirds by de Leva's segment lengths.
    let mid_hip = lerp_weights(&point(lm.limbs[0][0]), &point(lm.limbs[1][0]), 0.5);
    let mut chain = vec![lm.neck];
    while let Some(p) = names[*chain.last().unwrap_or(&lm.neck)].parent {
        if names[p].parent.is_none() {
            break; // the root sits at the pelvis; the mid-hip point ends the polyline
        }
        chain.push(p);
    }
    let mut polyline: Vec<(Vec<(usize, f32)>, Vec3)> = chain.iter().map(|&j| (point(j), rest[j])).collect();
    let mid_hip_rest = (rest[lm.limbs[0][0]] + rest[lm.limbs[1][0]]) * 0.5;
    polyline.push((mid_hip, mid_hip_rest));
    let at = |u: f64| polyline_point(&polyline, u);
    for &(segment, mass, top, bottom, com) in &DE_LEVA_TRUNK[sex] {
        segments.push(Segment {
            name: segment.into(),
            mass_kg: mass,
            com_weights: lerp_weights(&at(top), &at(bottom), com / 100.0),
            joints: chain.iter().map(|&j| names[j].name.clone()).collect(),
            rule: format!("{table_name} {segment} (share {top:.3}..{bottom:.3} of the neck–hip line)"),
        });
    }
    BodyModel { total_mass_kg: 0.0, method: MassTable::NAMES[sex].into(), segments }
}

/// The point at arc-length share `u` (0 = first point) of a polyline given as joint weights
/// with rest positions; the shares stay valid in every pose because bones are rigid.
fn polyline_point(points: &[(Vec<(usize, f32)>, Vec3)], u: f64) -> Vec<(usize, f32)> {
    let lengths: Vec<f64> = points.windows(2).map(|w| f64::from(w[0].1.distance(w[1].1))).collect();
    let total: f64 = lengths.iter().sum();
    let mut target = u.clamp(0.0, 1.0) * total;
    for (i, len) in lengths.iter().enumerate() {
        if target <= *len || i + 1 == lengths.len() {
            let t = if *len > 1e-9 { (target / len).clamp(0.0, 1.0) } else { 0.0 };
            return lerp_weights(&points[i].0, &points[i + 1].0, t);
        }
        target -= len;
    }
    points.first().map(|p| p.0.clone()).unwrap_or_default()
}

/// Every bone (joint → child) carries mass in proportion to its rest length, centred at
/// its middle: a neutral default for skeletons whose names mean nothing to the table.
fn bone_length_model(skeleton: &Skeleton) -> Result<BodyModel, BodyError> {
    let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
    let names = skeleton.joints();
    let segments: Vec<Segment> = (0..skeleton.len())
        .flat_map(|j| skeleton.children(j).map(move |c| (j, c)))
        .filter_map(|(j, c)| {
            let length = f64::from(rest[j].distance(rest[c]));
            (length > 1e-6).then(|| Segment {
                name: format!("{}→{}", names[j].name, names[c].name),
                mass_kg: length,
                com_weights: lerp_weights(&[(j, 1.0)], &[(c, 1.0)], 0.5),
                joints: vec![names[j].name.clone(), names[c].name.clone()],
                rule: "bone length".into(),
            })
        })
        .collect();
    if segments.is_empty() {
        return Err(BodyError::NoBones);
    }
    Ok(BodyModel { total_mass_kg: 0.0, method: "bone_length".into(), segments })
}

fn from_override(skeleton: &Skeleton, o: &MassOverride) -> Result<BodyModel, BodyError> {
    let find = |segment: &str, joint: &str| {
        skeleton.index_of(joint).ok_or_else(|| BodyError::UnknownJoint {
            segment: segment.into(),
            joint: joint.into(),
            hint: crate::model::names::did_you_mean(joint, skeleton.joints().iter().map(|j| j.name.as_str())),
        })
    };
    if o.segments.is_empty() {
        return Err(BodyError::BadOverride("it lists no segments".into()));
    }
    let mut segments = Vec::new();
    for s in &o.segments {
        if !(s.mass_fraction.is_finite() && s.mass_fraction > 0.0) {
            return Err(BodyError::BadOverride(format!("segment '{}' needs a positive mass_fraction", s.name)));
        }
        if !(0.0..=1.0).contains(&s.com_fraction) {
            return Err(BodyError::BadOverride(format!("segment '{}': com_fraction must be within 0..=1", s.name)));
        }
        let (a, b) = (find(&s.name, &s.from)?, find(&s.name, &s.to)?);
        segments.push(Segment {
            name: s.name.clone(),
            mass_kg: s.mass_fraction,
            com_weights: lerp_weights(&[(a, 1.0)], &[(b, 1.0)], s.com_fraction),
            joints: vec![s.from.clone(), s.to.clone()],
            rule: "override".into(),
        });
    }
    Ok(BodyModel { total_mass_kg: 0.0, method: "override".into(), segments })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Joint;

    #[test]
    fn side_and_role_reads_common_conventions() {
        let cases = [
            ("LeftUpLeg", Some(0), "upleg"),
            ("RightForeArm", Some(1), "forearm"),
            ("lThigh", Some(0), "thigh"),
            ("rShldr", Some(1), "shldr"),
            ("Character1_LeftArm", Some(0), "arm"),
            ("mixamorig:RightHand", Some(1), "hand"),
            ("L_Femur", Some(0), "femur"),
            ("thigh.L", Some(0), "thigh"),
            // Issue 18: the naming families of game and DCC rigs.
            ("thigh_l", Some(0), "thigh"),
            ("calf_r", Some(1), "calf"),
            ("upperarm_l", Some(0), "upperarm"),
            ("neck_01", None, "neck"),
            ("DEF-thigh.L", Some(0), "thigh"),
            ("DEF-thigh.L.001", Some(0), "thigh"),
            ("DEF-upper_arm.R", Some(1), "upperarm"),
            ("LeftUpperLeg", Some(0), "upperleg"),
            ("UpperLegL", Some(0), "upperleg"),
            ("LowerLegR", Some(1), "lowerleg"),
            ("FootL", Some(0), "foot"),
            ("Bip01 L Thigh", Some(0), "thigh"),
            ("Bip01 R Forearm", Some(1), "forearm"),
            ("J_Bip_L_UpperLeg", Some(0), "upperleg"),
            ("Head_M", None, "head"),
            ("mixamorig_LeftUpLeg", Some(0), "upleg"),
            ("RHipJoint", Some(1), "hipjoint"),
            ("leg_joint_L_1", Some(0), "legjoint"),
            ("leftupleg", Some(0), "upleg"),
            ("LowerBack", None, "lowerback"),
            ("lhand", None, "lhand"),
            ("Head", None, "head"),
        ];
        for (name, side, role) in cases {
            assert_eq!(side_and_role(name), (side, role.to_string()), "{name}");
        }
    }

    /// A stick figure with CMU-style names.
    pub(crate) fn stick_figure() -> Skeleton {
        let mut joints = vec![Joint::new("Hips", None, Vec3::new(0.0, 1.0, 0.0))];
        let add = |name: &str, parent: usize, offset: Vec3, joints: &mut Vec<Joint>| {
            joints.push(Joint::new(name, Some(parent), offset));
            joints.len() - 1
        };
        for (side, x) in [("Left", 0.1f32), ("Right", -0.1)] {
            let hip = add(&format!("{side}UpLeg"), 0, Vec3::new(x, 0.0, 0.0), &mut joints);
            let knee = add(&format!("{side}Leg"), hip, Vec3::new(0.0, -0.45, 0.0), &mut joints);
            let ankle = add(&format!("{side}Foot"), knee, Vec3::new(0.0, -0.45, 0.0), &mut joints);
            add(&format!("{side}Toe"), ankle, Vec3::new(0.0, -0.05, 0.2), &mut joints);
        }
        let spine = add("Spine", 0, Vec3::new(0.0, 0.25, 0.0), &mut joints);
        let neck = add("Neck", spine, Vec3::new(0.0, 0.3, 0.0), &mut joints);
        let head = add("Head", neck, Vec3::new(0.0, 0.1, 0.0), &mut joints);
        add("HeadTop", head, Vec3::new(0.0, 0.15, 0.0), &mut joints);
        for (side, x) in [("Left", 1.0f32), ("Right", -1.0)] {
            let shoulder = add(&format!("{side}Arm"), neck, Vec3::new(0.18 * x, 0.0, 0.0), &mut joints);
            let elbow = add(&format!("{side}ForeArm"), shoulder, Vec3::new(0.3 * x, 0.0, 0.0), &mut joints);
            let wrist = add(&format!("{side}Hand"), elbow, Vec3::new(0.25 * x, 0.0, 0.0), &mut joints);
            add(&format!("{side}Finger"), wrist, Vec3::new(0.08 * x, 0.0, 0.0), &mut joints);
        }
        Skeleton::new(joints).unwrap()
    }

    #[test]
    fn de_leva_mapping_places_the_thigh_centre_by_hand() {
        let skeleton = stick_figure();
        let model = body_model(&skeleton, 70.0, MassTable::DeLevaMale, None).unwrap();
        assert_eq!(model.method, "de_leva_male");
        assert_eq!(model.segments.len(), 16);
        let total: f64 = model.segments.iter().map(|s| s.mass_kg).sum();
        assert!((total - 70.0).abs() < 1e-9);
        let thigh = model.segments.iter().find(|s| s.name == "left_thigh").unwrap();
        assert!((thigh.mass_kg - 0.1416 * 70.0).abs() < 1e-9);
        let rest: Vec<Vec3> = rest_world(&skeleton).iter().map(|t| t.translation).collect();
        // Hip at (0.1, 1.0, 0), knee 0.45 m below: 40.95 % down the thigh.
        let com = model.segment_com(thigh, &rest);
        assert!((com - Vec3::new(0.1, 1.0 - 0.4095 * 0.45, 0.0)).length() < 1e-5, "{com}");
        // The upper trunk starts at the neck (y = 1.55) and spans 32.09 % of the 0.55 m
        // neck–mid-hip line; its centre is half way down it.
        let upper = model.segments.iter().find(|s| s.name == "upper_trunk").unwrap();
        let want = 1.55 - 0.5066 * 0.3209 * 0.55;
        assert!((model.segment_com(upper, &rest).y - want as f32).abs() < 1e-5);
    }

    #[test]
    fn unknown_names_fall_back_to_bone_length_and_say_why() {
        let joints = vec![
            Joint::new("a", None, Vec3::ZERO),
            Joint::new("b", Some(0), Vec3::new(0.0, 1.0, 0.0)),
            Joint::new("c", Some(1), Vec3::new(0.0, 3.0, 0.0)),
        ];
        let skeleton = Skeleton::new(joints).unwrap();
        let model = body_model(&skeleton, 10.0, MassTable::DeLevaMale, None).unwrap();
        assert!(model.method.starts_with("bone_length (names not recognised"));
        let masses: Vec<f64> = model.segments.iter().map(|s| s.mass_kg).collect();
        assert!((masses[0] - 2.5).abs() < 1e-9 && (masses[1] - 7.5).abs() < 1e-9, "{masses:?}");
    }

    #[test]
    fn override_replaces_the_mapping_and_names_bad_joints() {
        let skeleton = stick_figure();
        let text = r#"(segments: [
            (name: "legs", mass_fraction: 1.0, from: "LeftUpLeg", to: "LeftFoot", com_fraction: 0.5),
            (name: "rest", mass_fraction: 3.0, from: "Hips", to: "Neck", com_fraction: 0.0),
        ])"#;
        let o: MassOverride = ron::from_str(text).unwrap();
        let model = body_model(&skeleton, 80.0, MassTable::DeLevaMale, Some(&o)).unwrap();
        assert_eq!(model.method, "override");
        assert!((model.segments[0].mass_kg - 20.0).abs() < 1e-9);
        let bad: MassOverride = ron::from_str(
            r#"(segments: [(name: "x", mass_fraction: 1.0, from: "LeftUpLg", to: "Neck", com_fraction: 0.5)])"#,
        )
        .unwrap();
        let err = body_model(&skeleton, 80.0, MassTable::DeLevaMale, Some(&bad)).unwrap_err();
        assert!(err.to_string().contains("did you mean 'LeftUpLeg'"), "{err}");
    }
}
