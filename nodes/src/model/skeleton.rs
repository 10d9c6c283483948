//! Joint hierarchies.

use std::collections::BTreeMap;

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::math::euler::Axis;

/// One channel of a BVH `CHANNELS` line, kept so a clip read from BVH writes back with the
/// same layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Channel {
    /// Translation along an axis (file units, converted to metres on load).
    Position(Axis),
    /// Rotation about an axis (degrees in the file, radians in memory).
    Rotation(Axis),
}

/// Per-joint range of motion, radians, as Euler angles about the joint's local X, Y, Z.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLimits {
    /// Lower bound per axis (radians).
    pub min: Vec3,
    /// Upper bound per axis (radians).
    pub max: Vec3,
}

/// One joint of a [`Skeleton`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Joint {
    /// Unique name (as in the source file).
    pub name: String,
    /// Index of the parent joint; `None` for a root. Parents always come first.
    pub parent: Option<usize>,
    /// Rest translation from the parent joint, metres, in the parent's frame.
    pub rest_offset: Vec3,
    /// Rest rotation relative to the parent (identity for BVH; glTF nodes may have one).
    pub rest_rotation: Quat,
    /// Optional range of motion.
    pub limits: Option<JointLimits>,
    /// BVH channel layout this joint was read with; empty when the source had none
    /// (glTF, generated skeletons) and for end sites.
    pub channels: Vec<Channel>,
    /// True for a BVH `End Site`: a leaf marker with no channels of its own, kept so end
    /// effectors (toe tips, head top) have positions.
    pub end_site: bool,
}

impl Joint {
    /// A plain joint with identity rest rotation, no limits and no channel layout.
    pub fn new(name: impl Into<String>, parent: Option<usize>, rest_offset: Vec3) -> Self {
        Joint {
            name: name.into(),
            parent,
            rest_offset,
            rest_rotation: Quat::IDENTITY,
            limits: None,
            channels: Vec::new(),
            end_site: false,
        }
    }
}

/// Why a joint list is not a valid skeleton.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkeletonError {
    /// No joints at all.
    #[error("the skeleton has no joints")]
    Empty,
    /// Two joints share a name.
    #[error("duplicate joint name '{name}' (joints {first} and {second})")]
    DuplicateName {
        /// The repeated name.
        name: String,
        /// Index of the first joint with that name.
        first: usize,
        /// Index of the second.
        second: usize,
    },
    /// A parent index does not come before its child.
    #[error("joint '{name}' (index {index}) has parent index {parent}, which does not come before it")]
    ParentOrder {
        /// Joint name.
        name: String,
        /// Joint index.
        index: usize,
        /// Offending parent index.
        parent: usize,
    },
    /// A rest offset or rotation is NaN or infinite, or an offset is beyond
    /// ±[`super::MAX_COORDINATE_M`].
    #[error("joint '{name}' has a non-finite or out-of-range rest transform (offsets must stay within ±1e6 m)")]
    NonFinite {
        /// Joint name.
        name: String,
    },
}

/// A joint hierarchy in parent-before-child order, with a name index.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<Joint>", into = "Vec<Joint>")]
pub struct Skeleton {
    joints: Vec<Joint>,
    by_name: BTreeMap<String, usize>,
}

impl TryFrom<Vec<Joint>> for Skeleton {
    type Error = SkeletonError;
    fn try_from(joints: Vec<Joint>) -> Result<Self, SkeletonError> {
        Skeleton::new(joints)
    }
}

impl From<Skeleton> for Vec<Joint> {
    fn from(s: Skeleton) -> Self {
        s.joints
    }
}

impl Skeleton {
    /// Checks ordering, names and finiteness, then builds the name index.
    pub fn new(joints: Vec<Joint>) -> Result<Self, SkeletonError> {
        if joints.is_empty() {
            return Err(SkeletonError::Empty);
        }
        let mut by_name = BTreeMap::new();
        for (index, joint) in joints.iter().enumerate() {
            if let Some(parent) = joint.parent
                && parent >= index
            {
                return Err(SkeletonError::ParentOrder { name: joint.name.clone(), index, parent });
            }
            if !super::coordinate_in_range(joint.rest_offset) || !joint.rest_rotation.is_finite() {
                return Err(SkeletonError::NonFinite { name: joint.name.clone() });
            }
            if let Some(&first) = by_name.get(&joint.name) {
                return Err(SkeletonError::DuplicateName { name: joint.name.clone(), first, second: index });
            }
            by_name.insert(joint.name.clone(), index);
        }
        Ok(Skeleton { joints, by_name })
    }

    /// All joints, parents first.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// Number of joints (end sites included).
    pub fn len(&self) -> usize {
        self.joints.len()
    }

    /// Always false: a skeleton has at least one joint.
    pub fn is_empty(&self) -> bool {
        self.joints.is_empty()
    }

    /// The same skeleton with every rest offset multiplied by `factor` (a unit change).
    pub fn scaled(&self, factor: f32) -> Result<Skeleton, SkeletonError> {
        let joints = self.joints.iter().map(|j| Joint { rest_offset: j.rest_offset * factor, ..j.clone() }).collect();
        Skeleton::new(joints)
    }

    /// Whether `other` has the same joint names and parents in the same order (clips and
    /// skins of one rig, whatever their rest offsets).
    pub fn same_hierarchy(&self, other: &Skeleton) -> bool {
        self.len() == other.len()
            && self.joints.iter().zip(&other.joints).all(|(a, b)| a.name == b.name && a.parent == b.parent)
    }

    /// Index of the joint called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.by_name.get(name).copied()
    }

    /// True when `ancestor` is a strict ancestor of `joint` (out-of-range indices are not).
    pub fn is_ancestor(&self, ancestor: usize, joint: usize) -> bool {
        let mut j = joint;
        while let Some(p) = self.joints.get(j).and_then(|x| x.parent) {
            if p == ancestor {
                return true;
            }
            j = p;
        }
        false
    }

    /// Children of joint `index`, in order.
    pub fn children(&self, index: usize) -> impl Iterator<Item = usize> + '_ {
        self.joints.iter().enumerate().filter(move |(_, j)| j.parent == Some(index)).map(|(i, _)| i)
    }

    /// Joint positions in the rest pose (metres, model space), from offsets and rest
    /// rotations only.
    pub fn rest_positions(&self) -> Vec<Vec3> {
        super::fk::rest_world(self).into_iter().map(|t| t.translation).collect()
    }

    /// Rest height of the root above the lowest joint (metres): how far the legs hold it up,
    /// the measure by which a motion's root path is carried between skeletons.
    pub fn root_height(&self) -> f32 {
        let rest = self.rest_positions();
        let lowest = rest.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        rest.first().map_or(0.0, |root| root.y - lowest)
    }

    /// How much longer `other`'s legs hold its root up than this skeleton's do
    /// (`other.root_height() / self.root_height()`): the factor a root path is scaled by when
    /// a motion moves from this skeleton to `other`. `None` when either height is (near) zero.
    pub fn root_height_ratio(&self, other: &Skeleton) -> Option<f32> {
        let (own, theirs) = (self.root_height(), other.root_height());
        (own > 1e-6 && theirs > 1e-6).then(|| theirs / own)
    }

    /// Axis-aligned size of the rest pose (metres): the extent used for unit detection and
    /// relative tolerances.
    pub fn rest_extent(&self) -> Vec3 {
        let positions = self.rest_positions();
        let (lo, hi) = positions
            .iter()
            .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        hi - lo
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_empty_duplicate_and_misordered() {
        assert_eq!(Skeleton::new(vec![]), Err(SkeletonError::Empty));
        let dup = vec![Joint::new("a", None, Vec3::ZERO), Joint::new("a", Some(0), Vec3::X)];
        assert!(matches!(Skeleton::new(dup), Err(SkeletonError::DuplicateName { .. })));
        let order = vec![Joint::new("a", Some(1), Vec3::ZERO), Joint::new("b", None, Vec3::X)];
        assert!(matches!(Skeleton::new(order), Err(SkeletonError::ParentOrder { .. })));
        let nan = vec![Joint::new("a", None, Vec3::NAN)];
        assert!(matches!(Skeleton::new(nan), Err(SkeletonError::NonFinite { .. })));
    }

    #[test]
    fn rest_positions_accumulate_offsets_through_rest_rotations() {
        let mut root = Joint::new("root", None, Vec3::new(0.0, 1.0, 0.0));
        root.rest_rotation = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let s = Skeleton::new(vec![root, Joint::new("tip", Some(0), Vec3::X)]).unwrap();
        let p = s.rest_positions();
        assert!((p[1] - Vec3::new(0.0, 2.0, 0.0)).length() < 1e-6);
        assert_eq!(s.index_of("tip"), Some(1));
        assert_eq!(s.children(0).collect::<Vec<_>>(), vec![1]);
    }
}
