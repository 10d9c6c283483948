//! Body roles of a humanoid skeleton read from its shape, not its joint names: which joints
//! are the pelvis, the spine, and the upper, lower and end joints of each leg and arm. Joint
//! names differ between every rig (`LeftUpLeg`, `lThigh`, `leg_joint_L_1`), the shape of a
//! standing biped does not.
//!
//! On a reference pose standing upright (Y up):
//! 1. The feet are the lowest leaf joint and the lowest other leaf in the body's lowest
//!    quarter that splits from it high above the ground (more than 30 % of the body's
//!    height): toes of one foot split at the ankle. Their lowest common ancestor is the
//!    pelvis.
//! 2. The head is the highest leaf; the spine is the path from the pelvis to it. The head
//!    must stand above the pelvis (within about 45° of straight up), or the body is not a
//!    standing biped (a quadruped) and is refused.
//! 3. The arms are the two leaves farthest from where they leave the spine (three joints or
//!    more below it), splitting from
//!    each other on the spine; the lower of the two split points of the arms is the chest.
//! 4. Along each limb (from the spine or pelvis to its leaf) the end joint is where the
//!    limb branches (a hand into fingers), the lower and upper joints the two above it;
//!    a limb without branches has its upper, lower and end joints start the two longest
//!    consecutive bones (thigh and shin, upper arm and forearm).
//! 5. Forward is where the leaves below the ankles (toes) point, unless the knees are
//!    clearly bent the other way (the leaf is a heel, as in CesiumMan); left is up × forward.
//!
//! A kernel: skeleton mapping, foot contacts and retargeting all find the feet with it.

use glam::Vec3;

use crate::kernels::body::{Landmarks, find_landmarks_detached, found_by_name, limb_tip};
use crate::model::Skeleton;
use crate::model::fk::rest_world;

/// One leg or arm: its joints from the spine (or pelvis) out to its tip.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Limb {
    /// Joints from the one after the spine or pelvis to the leaf, in order.
    pub chain: Vec<usize>,
    /// Index in `chain` of the upper joint (hip or shoulder).
    pub upper: usize,
    /// Index in `chain` of the lower joint (knee or elbow): after the upper one, with any
    /// segments a rig splits the upper bone into between them (Rigify's `DEF-thigh.L.001`).
    pub lower: usize,
    /// Index in `chain` of the end joint (ankle or wrist), after the lower one.
    pub end: usize,
}

impl Limb {
    /// A limb whose upper, lower and end joints follow each other in `chain` from `upper`.
    pub fn consecutive(chain: Vec<usize>, upper: usize) -> Limb {
        Limb { chain, upper, lower: upper + 1, end: upper + 2 }
    }

    /// The upper, lower and end joints (hip, knee, ankle or shoulder, elbow, wrist).
    pub fn joints(&self) -> [usize; 3] {
        [self.chain[self.upper], self.chain[self.lower], self.chain[self.end]]
    }
}

/// The body roles of a skeleton (see the module doc).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BodyRoles {
    /// Where the legs split.
    pub pelvis: usize,
    /// Where the arms split from the spine.
    pub chest: usize,
    /// From the joint after the pelvis up to the head's leaf.
    pub spine: Vec<usize>,
    /// Left, right.
    pub legs: [Limb; 2],
    /// Left, right.
    pub arms: [Limb; 2],
}

impl BodyRoles {
    /// Mean leg length, hip to knee to ankle (metres), with joint `j` at `position(j)`.
    pub fn leg_length_m(&self, position: impl Fn(usize) -> Vec3) -> f32 {
        mean_limb_length_m(self.legs.each_ref().map(Limb::joints), position)
    }
}

/// The body roles read from `skeleton`'s rest pose.
pub fn rest_roles(skeleton: &Skeleton) -> Result<BodyRoles, RolesError> {
    let rest: Vec<Vec3> = rest_world(skeleton).iter().map(|t| t.translation).collect();
    roles_of(skeleton, &rest)
}

/// Mean length of two limbs given as their upper, lower and end joints (e.g. hip, knee
/// and ankle), joint `j` at `position(j)`.
pub fn mean_limb_length_m(limbs: [[usize; 3]; 2], position: impl Fn(usize) -> Vec3) -> f32 {
    let length = |[a, b, c]: [usize; 3]| {
        let [a, b, c] = [a, b, c].map(&position);
        a.distance(b) + b.distance(c)
    };
    0.5 * (length(limbs[0]) + length(limbs[1]))
}

/// Why the body roles could not be read from a skeleton's shape.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ShapeError {
    /// The positions do not match the skeleton's joints.
    #[error("no pose to read it from")]
    NoPose,
    /// The skeleton has no joints.
    #[error("no joints")]
    NoJoints,
    /// The lowest and highest leaves are at one height.
    #[error("a flat skeleton (no height between its lowest and highest joints)")]
    Flat,
    /// No second foot splits from the first above the knees.
    #[error("only one leg (no second low leaf splitting from the first above the knees)")]
    OneLeg,
    /// No second foot, neither splitting above the knees nor hanging from the root.
    #[error("only one leg (no second low leaf splitting from the first above the knees, nor hanging from the root)")]
    NoSecondFoot,
    /// The feet hang from the root, but no joint stands above them as a knee.
    #[error("the feet hang from the root but no knee stands above them")]
    NoKnee,
    /// A knee found above a foot is not below the pelvis.
    #[error("a knee is not below the pelvis")]
    KneeNotBelowPelvis,
    /// A knee hangs straight from the pelvis.
    #[error("a knee hangs straight from the pelvis (no thigh)")]
    NoThigh,
    /// A foot is not below the root.
    #[error("a foot is not below the root")]
    FootNotBelowRoot,
    /// The top joint is not below the pelvis in the hierarchy.
    #[error("the head is not above the pelvis in the hierarchy")]
    HeadNotAbovePelvis,
    /// The top joint leans too far from straight above the pelvis (degrees).
    #[error(
        "the body is not upright (the top joint is {degrees:.0}° from straight above the pelvis): not a standing biped, e.g. a quadruped"
    )]
    NotUpright {
        /// Angle between the pelvis-to-top direction and straight up, degrees.
        degrees: f32,
    },
    /// No leaf leaves the spine.
    #[error("no arms (no leaf leaving the spine)")]
    NoArms,
    /// Only one leaf leaves the spine as an arm.
    #[error("only one arm")]
    OneArm,
    /// A limb's tip does not hang below where it should start.
    #[error("the {limb} is not below the body")]
    LimbNotBelowBody {
        /// `leg` or `arm`.
        limb: &'static str,
    },
    /// A limb has fewer than three joints.
    #[error("the {limb} has fewer than three joints")]
    ShortLimb {
        /// `leg` or `arm`.
        limb: &'static str,
    },
    /// The toes do not point forward of the ankles, so left and right are unknown.
    #[error("no facing (the toes do not point forward of the ankles)")]
    NoFacing,
}

/// What the joint names did not give.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NamesMiss {
    /// Some body parts are named by no joint.
    #[error("by joint name, found {}; missing {}", list_or_nothing(.found), .missing.join(", "))]
    Missing {
        /// Body parts found by name.
        found: Vec<String>,
        /// Body parts no joint names.
        missing: Vec<String>,
    },
    /// Every part is named, but the named limbs do not hang from one body.
    #[error("the named limbs do not hang from one body")]
    Disconnected,
}

fn names_then(by_name: &Option<NamesMiss>) -> String {
    by_name.as_ref().map_or_else(String::new, |miss| format!("{miss}; by shape, "))
}

impl From<ShapeError> for RolesError {
    fn from(by_shape: ShapeError) -> Self {
        RolesError { by_name: None, by_shape }
    }
}

fn list_or_nothing(names: &[String]) -> String {
    if names.is_empty() { "nothing".to_owned() } else { names.join(", ") }
}

/// Why the body roles could not be read: what the joint names lacked, when they were
/// tried ([`roles_of`]), and why the shape did not give them.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}{by_shape}", names_then(.by_name))]
pub struct RolesError {
    /// What the names lacked; `None` when only the shape was read ([`body_roles`]).
    pub by_name: Option<NamesMiss>,
    /// Why the shape failed.
    #[source]
    pub by_shape: ShapeError,
}

/// Reads the body roles of `skeleton` posed at `pos_in_world` (one position per joint),
/// or says which part of the body it could not find.
pub fn body_roles(skeleton: &Skeleton, pos_in_world: &[Vec3]) -> Result<BodyRoles, ShapeError> {
    let joints = skeleton.joints();
    let n = joints.len();
    if pos_in_world.len() != n {
        return Err(ShapeError::NoPose);
    }
    let mut children = vec![0usize; n];
    for j in joints {
        if let Some(p) = j.parent {
            children[p] += 1;
        }
    }
    let leaves: Vec<usize> = (0..n).filter(|&j| children[j] == 0).collect();
    let by_height = |a: &&usize, b: &&usize| pos_in_world[**a].y.total_cmp(&pos_in_world[**b].y);
    let lowest = *leaves.iter().min_by(by_height).ok_or(ShapeError::NoJoints)?;
    let highest = *leaves.iter().max_by(by_height).ok_or(ShapeError::NoJoints)?;
    let height = pos_in_world[highest].y - pos_in_world[lowest].y;
    if height <= 0.0 {
        return Err(ShapeError::Flat);
    }
    let other_foot = leaves
        .iter()
        .filter(|&&l| {
            let above_ground = |j: usize| pos_in_world[j].y - pos_in_world[lowest].y;
            above_ground(l) < 0.25 * height && above_ground(common_ancestor(skeleton, lowest, l)) > 0.3 * height
        })
        .min_by(by_height)
        .copied();
    let detached = match other_foot {
        Some(_) => None,
        None => Some(detached_legs(skeleton, pos_in_world, &leaves, lowest, highest, height)?),
    };
    let pelvis = match (&detached, other_foot) {
        (Some((pelvis, _)), _) => *pelvis,
        (None, Some(other)) => common_ancestor(skeleton, lowest, other),
        (None, None) => return Err(ShapeError::OneLeg),
    };
    let spine = path_below(skeleton, pelvis, highest).ok_or(ShapeError::HeadNotAbovePelvis)?;
    // A person stands: the head is well above the pelvis, not ahead of it (a quadruped).
    let up = (pos_in_world[highest] - pos_in_world[pelvis]).normalize_or_zero().y;
    if up < 0.7 {
        return Err(ShapeError::NotUpright { degrees: up.clamp(-1.0, 1.0).acos().to_degrees() });
    }
    // Arms: leaves leaving the spine, farthest from where they leave it.
    let leaves_spine_at = |l: usize| spine.iter().rev().copied().find(|&s| skeleton.is_ancestor(s, l));
    let reach = |l: usize| leaves_spine_at(l).map_or(0.0, |s| pos_in_world[l].distance(pos_in_world[s]));
    let candidates: Vec<usize> = leaves
        .iter()
        .copied()
        .filter(|&l| l != highest && !spine.contains(&l))
        .filter(|&l| {
            // An arm has a shoulder, an elbow and a wrist below where it leaves the spine.
            leaves_spine_at(l).and_then(|s| path_below(skeleton, s, l)).is_some_and(|p| p.len() >= 3)
        })
        .collect();
    let farthest = |from: &[usize]| from.iter().copied().max_by(|&a, &b| reach(a).total_cmp(&reach(b)));
    let arm_a = farthest(&candidates).ok_or(ShapeError::NoArms)?;
    let others: Vec<usize> =
        candidates.iter().copied().filter(|&l| spine.contains(&common_ancestor(skeleton, arm_a, l))).collect();
    let arm_b = farthest(&others).ok_or(ShapeError::OneArm)?;
    let splits = [arm_a, arm_b].map(|l| leaves_spine_at(l).unwrap_or(pelvis));
    let chest = if spine.iter().position(|&s| s == splits[0]) < spine.iter().position(|&s| s == splits[1]) {
        splits[0]
    } else {
        splits[1]
    };

    let limb = |from: usize, leaf: usize, limb: &'static str| -> Result<Limb, ShapeError> {
        let chain = path_below(skeleton, from, leaf).ok_or(ShapeError::LimbNotBelowBody { limb })?;
        // A hand with fingers (or a foot with toes) is where the chain branches.
        if let Some(end) = chain.iter().position(|&j| children[j] >= 2).filter(|&e| e >= 2) {
            return Ok(Limb::consecutive(chain, end - 2));
        }
        let bone = |j: usize| joints[j].parent.map_or(0.0, |p| pos_in_world[j].distance(pos_in_world[p]));
        let upper = (0..chain.len().saturating_sub(2))
            .max_by(|&a, &b| {
                (bone(chain[a + 1]) + bone(chain[a + 2])).total_cmp(&(bone(chain[b + 1]) + bone(chain[b + 2])))
            })
            .ok_or(ShapeError::ShortLimb { limb })?;
        Ok(Limb::consecutive(chain, upper))
    };
    let legs = match (detached, other_foot) {
        (Some((_, legs)), _) => legs,
        (None, Some(other)) => [limb(pelvis, lowest, "leg")?, limb(pelvis, other, "leg")?],
        (None, None) => return Err(ShapeError::OneLeg),
    };
    let arms = [limb(splits[0], arm_a, "arm")?, limb(splits[1], arm_b, "arm")?];

    // Sides: left is up × forward; forward is where the leaves below the ankles point
    // (toes), unless the knees clearly bend the other way (the leaf is a heel).
    let toes: Vec3 = legs
        .iter()
        .map(|l| (pos_in_world[*l.chain.last().unwrap_or(&0)] - pos_in_world[l.joints()[2]]).with_y(0.0))
        .sum();
    let knees: Vec3 = legs
        .iter()
        .map(|l| {
            let [hip, knee, ankle] = l.joints().map(|j| pos_in_world[j]);
            (knee - 0.5 * (hip + ankle)).with_y(0.0)
        })
        .sum();
    let bent = knees.length() > 0.02 * height;
    let forward = if bent && knees.dot(toes) < 0.0 { -toes } else { toes };
    let left = Vec3::Y.cross(forward).normalize_or_zero();
    if left == Vec3::ZERO {
        return Err(ShapeError::NoFacing);
    }
    let leftness = |l: &Limb| pos_in_world[l.joints()[2]].dot(left);
    let sided = |[a, b]: [Limb; 2]| if leftness(&a) >= leftness(&b) { [a, b] } else { [b, a] };
    Ok(BodyRoles { pelvis, chest, spine, legs: sided(legs), arms: sided(arms) })
}

/// The body roles of `skeleton` from its joint names when they name every limb (CMU, DAZ,
/// 3ds Max, HumanIK, Mixamo, Blender styles), else from its shape posed at `pos_in_world`
/// (any naming); or why neither works.
///
/// Names may put a foot or hand elsewhere in the hierarchy than below its knee or elbow (an
/// IK-style game rig hangs the feet off the root): that limb's `chain` then runs from the
/// pelvis to the knee, on to the foot and its toes, in body order rather than parenthood.
pub fn roles_of(skeleton: &Skeleton, pos_in_world: &[Vec3]) -> Result<BodyRoles, RolesError> {
    let by_name = match find_landmarks_detached(skeleton) {
        Ok(landmarks) => match named_roles(skeleton, &landmarks) {
            Some(roles) => return Ok(roles),
            None => NamesMiss::Disconnected,
        },
        Err(missing) => NamesMiss::Missing { found: found_by_name(skeleton), missing },
    };
    body_roles(skeleton, pos_in_world).map_err(|by_shape| RolesError { by_name: Some(by_name), by_shape })
}

/// The body roles from joints found by name ([`crate::kernels::body::find_landmarks`]):
/// the pelvis splits the thighs, the chest the upper arms, the spine runs to the head's tip,
/// each limb from its split to the tip below its end joint.
fn named_roles(skeleton: &Skeleton, landmarks: &Landmarks) -> Option<BodyRoles> {
    let [left, right] = landmarks.limbs;
    let pelvis = common_ancestor(skeleton, left[0], right[0]);
    let chest = common_ancestor(skeleton, left[3], right[3]);
    let spine = path_below(skeleton, pelvis, limb_tip(skeleton, landmarks.head))?;
    let limb = |from: usize, [upper, lower, end]: [usize; 3]| {
        let tip = limb_tip(skeleton, end);
        let chain = if skeleton.is_ancestor(lower, end) {
            path_below(skeleton, from, tip)?
        } else {
            // A detached end: down to the lower joint, then the end and what hangs below it.
            let mut chain = path_below(skeleton, from, lower)?;
            chain.push(end);
            chain.extend(path_below(skeleton, end, tip)?);
            chain
        };
        let at = |joint: usize| chain.iter().position(|&j| j == joint);
        let (upper, lower, end) = (at(upper)?, at(lower)?, at(end)?);
        (upper < lower && lower < end).then_some(Limb { chain, upper, lower, end })
    };
    let three = |slots: &[usize; 6], first: usize| [slots[first], slots[first + 1], slots[first + 2]];
    Some(BodyRoles {
        pelvis,
        chest,
        spine,
        legs: [limb(pelvis, three(&left, 0))?, limb(pelvis, three(&right, 0))?],
        arms: [limb(chest, three(&left, 3))?, limb(chest, three(&right, 3))?],
    })
}

/// The legs of a rig that hangs its feet off a root near the ground (IK-style game rigs),
/// read from positions: the second foot is the lowest other leaf whose branch leaves the
/// first's on the way to the head; each foot's top joint is where its branch starts; its knee
/// is the lowest joint of the rest of the body 10–45 % of the body's height above the foot's
/// top and within 5 % of the height of it horizontally; the pelvis is where the knees'
/// branches split. Each leg's chain runs pelvis → knee, then the foot's branch.
fn detached_legs(
    skeleton: &Skeleton,
    pos: &[Vec3],
    leaves: &[usize],
    lowest: usize,
    highest: usize,
    height: f32,
) -> Result<(usize, [Limb; 2]), ShapeError> {
    let low = |j: usize| pos[j].y - pos[lowest].y;
    let other = leaves
        .iter()
        .copied()
        .filter(|&l| l != lowest && low(l) < 0.25 * height)
        .filter(|&l| {
            let split = common_ancestor(skeleton, lowest, l);
            split == highest || skeleton.is_ancestor(split, highest)
        })
        .min_by(|&a, &b| pos[a].y.total_cmp(&pos[b].y))
        .ok_or(ShapeError::NoSecondFoot)?;
    let split = common_ancestor(skeleton, lowest, other);
    let foot_top = |leaf: usize| path_below(skeleton, split, leaf).and_then(|p| p.first().copied());
    let feet = [foot_top(lowest).ok_or(ShapeError::NoSecondFoot)?, foot_top(other).ok_or(ShapeError::NoSecondFoot)?];
    let under_a_foot = |j: usize| feet.iter().any(|&f| j == f || skeleton.is_ancestor(f, j));
    let knee = |foot: usize| {
        (0..skeleton.len())
            .filter(|&j| !under_a_foot(j) && j != split && !skeleton.is_ancestor(j, split))
            .filter(|&j| {
                let up = pos[j].y - pos[foot].y;
                (0.1 * height..0.45 * height).contains(&up) && (pos[j] - pos[foot]).with_y(0.0).length() < 0.05 * height
            })
            .min_by(|&a, &b| pos[a].y.total_cmp(&pos[b].y))
    };
    let knees = [knee(feet[0]), knee(feet[1])];
    let [Some(ka), Some(kb)] = knees else {
        return Err(ShapeError::NoKnee);
    };
    let pelvis = common_ancestor(skeleton, ka, kb);
    let leg = |knee: usize, leaf: usize| -> Result<Limb, ShapeError> {
        let mut chain = path_below(skeleton, pelvis, knee).ok_or(ShapeError::KneeNotBelowPelvis)?;
        let upper = chain.len().checked_sub(2).ok_or(ShapeError::NoThigh)?;
        chain.extend(path_below(skeleton, split, leaf).ok_or(ShapeError::FootNotBelowRoot)?);
        Ok(Limb::consecutive(chain, upper))
    };
    Ok((pelvis, [leg(ka, lowest)?, leg(kb, other)?]))
}

/// The deepest joint that is `a` or `b` or an ancestor of both.
fn common_ancestor(skeleton: &Skeleton, a: usize, b: usize) -> usize {
    let mut x = a;
    loop {
        if x == b || skeleton.is_ancestor(x, b) {
            return x;
        }
        match skeleton.joints()[x].parent {
            Some(p) => x = p,
            None => return x,
        }
    }
}

/// The joints strictly below `top` down to `leaf` (included), top first, when `leaf`
/// lies under `top`.
fn path_below(skeleton: &Skeleton, top: usize, leaf: usize) -> Option<Vec<usize>> {
    let mut path = Vec::new();
    let mut j = leaf;
    while j != top {
        path.push(j);
        j = skeleton.joints()[j].parent?;
    }
    path.reverse();
    Some(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::mannequin::mannequin_skeleton;

    #[test]
    fn the_mannequin_roles_match_its_names() {
        let sk = mannequin_skeleton().unwrap();
        let roles = body_roles(&sk, &sk.rest_positions()).unwrap();
        let name = |j: usize| sk.joints()[j].name.as_str();
        let names = |l: &Limb| l.joints().map(name);
        assert_eq!(name(roles.pelvis), "Hips");
        assert_eq!(name(roles.chest), "Chest");
        assert_eq!(names(&roles.legs[0]), ["LeftUpLeg", "LeftLeg", "LeftFoot"]);
        assert_eq!(names(&roles.legs[1]), ["RightUpLeg", "RightLeg", "RightFoot"]);
        assert_eq!(names(&roles.arms[0]), ["LeftArm", "LeftForeArm", "LeftHand"]);
        assert_eq!(names(&roles.arms[1]), ["RightArm", "RightForeArm", "RightHand"]);
        assert_eq!(
            roles.spine.iter().map(|&j| name(j)).collect::<Vec<_>>(),
            ["Spine", "Chest", "Neck", "Head", "HeadTop"]
        );
    }

    #[test]
    fn a_skeleton_turned_to_face_another_way_keeps_its_sides() {
        let sk = mannequin_skeleton().unwrap();
        let turn = glam::Quat::from_rotation_y(2.5);
        let rest: Vec<Vec3> = sk.rest_positions().iter().map(|p| turn * *p).collect();
        let roles = body_roles(&sk, &rest).unwrap();
        assert_eq!(sk.joints()[roles.legs[0].joints()[0]].name, "LeftUpLeg");
        assert_eq!(sk.joints()[roles.arms[1].joints()[2]].name, "RightHand");
    }

    #[test]
    fn a_one_legged_or_flat_skeleton_is_refused_with_the_reason() {
        let sk = mannequin_skeleton().unwrap();
        let mut rest = sk.rest_positions();
        for p in &mut rest {
            p.y = 0.0;
        }
        assert_eq!(body_roles(&sk, &rest).unwrap_err(), ShapeError::Flat);
        let one_leg = Skeleton::new(sk.joints()[..16].to_vec()).unwrap();
        assert!(body_roles(&one_leg, &one_leg.rest_positions()).unwrap_err().to_string().contains("one leg"));
    }
}
