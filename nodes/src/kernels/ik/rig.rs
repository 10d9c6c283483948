//! The articulated structure an IK solve moves: which joints turn about which axes, how
//! stiff each degree of freedom is, its limits, and which joints are end effectors.
//!
//! A rig joint's local rotation is written as Euler angles `R = Rx(a) · Ry(b) · Rz(c)`
//! ([`euler::compose`](crate::math::euler::compose) order `[X, Y, Z]`, the order
//! [`JointLimits`] are given in). Free axes are degrees of freedom (DOFs); the others keep
//! the angle the pose had. The root may also translate (three more DOFs). Joints outside
//! the rig keep their pose rotations.
//! Everything here is `f64`: the solver works to 1e-4 m and below.

use std::sync::Arc;

use glam::{DQuat, DVec3, Quat, Vec3};

use crate::math::euler::Axis;
use crate::model::{JointLimits, Skeleton};

/// Axes of a rig joint in composition order.
const AXES: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

/// One degree of freedom: a rotation about one Euler axis of one joint, or a translation of
/// the root along one world axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dof {
    /// What moves.
    pub kind: DofKind,
    /// Stiffness as in Meredith & Maddock eq. 1.6: 1 moves freely, 0 does not move.
    pub weight: f64,
    /// Lower bound (radians, or metres for translations).
    pub min: f64,
    /// Upper bound (radians, or metres for translations).
    pub max: f64,
}

/// What a [`Dof`] moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DofKind {
    /// Euler angle `axis` (0 = X, 1 = Y, 2 = Z) of skeleton joint `joint`.
    Rotation {
        /// Skeleton joint index.
        joint: usize,
        /// Euler axis index.
        axis: usize,
    },
    /// Root translation along world axis `axis`.
    Translation {
        /// World axis index.
        axis: usize,
    },
}

/// Why a rig cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RigError {
    /// A joint name that the skeleton does not have.
    #[error("no joint named `{0}` in the skeleton")]
    UnknownJoint(String),
    /// An end joint that does not descend from its chain's root.
    #[error("`{end}` is not below `{root}` in the skeleton")]
    NotAChain {
        /// Chain root name.
        root: String,
        /// Chain end name.
        end: String,
    },
    /// No end effectors or no DOFs.
    #[error("the rig has no {0}")]
    Empty(&'static str),
}

/// The structure an IK solve moves (see the module doc).
#[derive(Clone, Debug)]
pub struct IkRig {
    skeleton: Arc<Skeleton>,
    dofs: Vec<Dof>,
    /// Per skeleton joint: index of its first rotational DOF slot in `euler` of a pose, or
    /// `None` for joints outside the rig.
    rig_slot: Vec<Option<usize>>,
    effectors: Vec<usize>,
    /// Per effector, 1 on each world axis (X, Y, Z) its goal constrains and 0 on the others:
    /// multiplied into its error and its Jacobian rows.
    effector_masks: Vec<DVec3>,
    /// Per effector, the point it stands for in its joint's frame (metres; zero: the joint).
    effector_offsets: Vec<DVec3>,
    /// `moves[d * effectors + e]`: DOF `d` moves effector `e`.
    moves: Vec<bool>,
}

impl IkRig {
    /// An empty rig over `skeleton` (add chains, then effectors).
    pub fn new(skeleton: Arc<Skeleton>) -> Self {
        let joints = skeleton.len();
        IkRig {
            skeleton,
            dofs: Vec::new(),
            rig_slot: vec![None; joints],
            effectors: Vec::new(),
            effector_masks: Vec::new(),
            effector_offsets: Vec::new(),
            moves: Vec::new(),
        }
    }

    /// Joint index by name, as a typed error.
    pub fn joint(&self, name: &str) -> Result<usize, RigError> {
        self.skeleton.index_of(name).ok_or_else(|| RigError::UnknownJoint(name.to_owned()))
    }

    /// Joints from `root` down to `end`, both included, root first.
    pub fn chain_joints(&self, root: &str, end: &str) -> Result<Vec<usize>, RigError> {
        let (r, e) = (self.joint(root)?, self.joint(end)?);
        let mut path = vec![e];
        let mut j = e;
        while j != r {
            j = self.skeleton.joints()[j]
                .parent
                .ok_or_else(|| RigError::NotAChain { root: root.to_owned(), end: end.to_owned() })?;
            path.push(j);
        }
        path.reverse();
        Ok(path)
    }

    /// Frees the rotation axes `free` (X, Y, Z) of `joint` with stiffness `weight`, limited
    /// by the skeleton's joint limits if it has some. A joint already in the rig is left.
    pub fn add_joint(&mut self, joint: usize, free: [bool; 3], weight: f64) {
        if self.rig_slot[joint].is_some() {
            return;
        }
        self.rig_slot[joint] = Some(self.rig_joint_count());
        let limits = self.skeleton.joints()[joint].limits;
        for (axis, _) in free.iter().enumerate().filter(|(_, f)| **f) {
            let (min, max) = limits_of(limits, axis);
            self.dofs.push(Dof { kind: DofKind::Rotation { joint, axis }, weight, min, max });
        }
    }

    /// Every joint from `root` to the parent of `end` turns about all three axes (the end
    /// joint itself does not move its own position).
    pub fn add_chain(&mut self, root: &str, end: &str, weight: f64) -> Result<(), RigError> {
        let path = self.chain_joints(root, end)?;
        for &j in &path[..path.len() - 1] {
            self.add_joint(j, [true; 3], weight);
        }
        Ok(())
    }

    /// Lets the root translate freely along the three world axes.
    pub fn add_root_translation(&mut self, weight: f64) {
        for axis in 0..3 {
            let kind = DofKind::Translation { axis };
            if !self.dofs.iter().any(|d| d.kind == kind) {
                self.dofs.push(Dof { kind, weight, min: f64::NEG_INFINITY, max: f64::INFINITY });
            }
        }
    }

    /// Adds an end effector (its world position is a task); returns its index.
    pub fn add_effector(&mut self, joint: usize) -> usize {
        self.add_effector_on_axes(joint, [true; 3])
    }

    /// Adds an end effector whose goal constrains only the world `axes` (X, Y, Z) given,
    /// e.g. `[true, false, true]` for a position on the ground plane; returns its index.
    pub fn add_effector_on_axes(&mut self, joint: usize, axes: [bool; 3]) -> usize {
        self.effectors.push(joint);
        self.effector_masks.push(DVec3::from(axes.map(f64::from)));
        self.effector_offsets.push(DVec3::ZERO);
        self.effectors.len() - 1
    }

    /// Makes effector `e` the point `offset` (metres, in its joint's frame) instead of the
    /// joint itself: a point the joint carries but no joint marks, such as the end of a shin
    /// whose foot hangs elsewhere in the hierarchy. Can change between solves.
    pub fn set_effector_offset(&mut self, e: usize, offset: DVec3) {
        self.effector_offsets[e] = offset;
    }

    /// World position of effector `e` given the rig's world transforms `world`.
    #[inline]
    pub fn effector_position(&self, e: usize, world: &[(DQuat, DVec3)]) -> DVec3 {
        let (rotation, position) = world[self.effectors[e]];
        let offset = self.effector_offsets[e];
        if offset == DVec3::ZERO { position } else { position + rotation * offset }
    }

    /// Per effector, 1 on the world axes its goal constrains and 0 on the others.
    pub fn effector_masks(&self) -> &[DVec3] {
        &self.effector_masks
    }

    /// Finishes the rig: precomputes which DOF moves which effector.
    pub fn finish(mut self) -> Result<Self, RigError> {
        if self.effectors.is_empty() {
            return Err(RigError::Empty("end effector"));
        }
        if self.dofs.is_empty() {
            return Err(RigError::Empty("free joint"));
        }
        let joints = self.skeleton.joints();
        let is_ancestor_or_self = |a: usize, mut j: usize| loop {
            if j == a {
                return true;
            }
            match joints[j].parent {
                Some(p) => j = p,
                None => return false,
            }
        };
        self.moves = self
            .dofs
            .iter()
            .flat_map(|d| {
                self.effectors.iter().map(move |&e| match d.kind {
                    DofKind::Rotation { joint, .. } => is_ancestor_or_self(joint, e),
                    DofKind::Translation { .. } => true,
                })
            })
            .collect();
        Ok(self)
    }

    /// The skeleton.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// The DOFs, in Jacobian column order.
    pub fn dofs(&self) -> &[Dof] {
        &self.dofs
    }

    /// Mutable DOFs (to change weights or limits between solves).
    pub fn dofs_mut(&mut self) -> &mut [Dof] {
        &mut self.dofs
    }

    /// End-effector joints, in task order.
    pub fn effectors(&self) -> &[usize] {
        &self.effectors
    }

    /// Number of rig joints (joints with Euler angles in a pose).
    fn rig_joint_count(&self) -> usize {
        self.rig_slot.iter().flatten().count()
    }

    /// True when DOF `d` moves effector `e`.
    #[inline]
    pub fn moves(&self, d: usize, e: usize) -> bool {
        self.moves[d * self.effectors.len() + e]
    }

    /// A pose of this rig from one frame's local rotations and translations.
    pub fn pose_from(&self, rotations: &[Quat], translations: &[Vec3]) -> IkPose {
        let mut pose = IkPose {
            rotations: vec![DQuat::IDENTITY; rotations.len()],
            translations: vec![DVec3::ZERO; translations.len()],
            euler: vec![[0.0; 3]; self.rig_joint_count()],
        };
        self.fill_pose(rotations, translations, &mut pose);
        pose
    }

    /// Overwrites `pose` (of this rig) with one frame's local rotations and translations,
    /// without allocating.
    pub fn fill_pose(&self, rotations: &[Quat], translations: &[Vec3], pose: &mut IkPose) {
        for (d, q) in pose.rotations.iter_mut().zip(rotations) {
            *d = q.as_dquat();
        }
        for (d, t) in pose.translations.iter_mut().zip(translations) {
            *d = t.as_dvec3();
        }
        self.set_euler_from_rotations(pose);
    }

    /// Re-reads a pose's Euler angles from its rotations (after changing rotations).
    pub fn set_euler_from_rotations(&self, pose: &mut IkPose) {
        for (j, slot) in self.rig_slot.iter().enumerate() {
            if let Some(s) = slot {
                let (a, b, c) = pose.rotations[j].to_euler(glam::EulerRot::XYZ);
                pose.euler[*s] = [a, b, c];
            }
        }
    }

    /// Value of DOF `d` in `pose`.
    #[inline]
    pub fn dof_value(&self, pose: &IkPose, d: usize) -> f64 {
        match self.dofs[d].kind {
            DofKind::Rotation { joint, axis } => pose.euler[self.slot(joint)][axis],
            DofKind::Translation { axis } => pose.translations[0][axis],
        }
    }

    /// Sets DOF `d` of `pose` to `value` clamped to its limits.
    #[inline]
    pub fn set_dof(&self, pose: &mut IkPose, d: usize, value: f64) {
        let dof = &self.dofs[d];
        let v = value.clamp(dof.min, dof.max);
        match dof.kind {
            DofKind::Rotation { joint, axis } => pose.euler[self.slot(joint)][axis] = v,
            DofKind::Translation { axis } => pose.translations[0][axis] = v,
        }
    }

    #[inline]
    fn slot(&self, joint: usize) -> usize {
        self.rig_slot[joint].unwrap_or(0)
    }

    /// Forward kinematics of `pose` into `world` (one transform per joint).
    pub fn forward(&self, pose: &IkPose, world: &mut [(DQuat, DVec3)]) {
        for (j, joint) in self.skeleton.joints().iter().enumerate() {
            let (parent_rot, parent_pos) = joint.parent.map_or((DQuat::IDENTITY, DVec3::ZERO), |p| world[p]);
            let local = match self.rig_slot[j] {
                Some(s) => euler_rotation(pose.euler[s]),
                None => pose.rotations[j],
            };
            let pos = parent_pos + parent_rot * pose.translations[j];
            world[j] = (parent_rot * local, pos);
        }
    }

    /// The world axis and pivot of every rotational DOF into `axes` (one per DOF;
    /// translations get their world axis and a zero pivot), from `world` as
    /// [`IkRig::forward`] left it for `pose`. With `R = P·Rx(a)·Ry(b)·Rz(c)` the X axis is
    /// `P·X`, the Y axis `P·Rx(a)·Y = P·(0, cos a, sin a)` and the Z axis `R·Z` (`Rz` keeps
    /// Z), so the axes take one sine and cosine per joint (of `a`) and nothing more.
    pub fn dof_axes(&self, pose: &IkPose, world: &[(DQuat, DVec3)], axes: &mut [(DVec3, DVec3)]) {
        for (d, dof) in self.dofs.iter().enumerate() {
            axes[d] = match dof.kind {
                DofKind::Rotation { joint, axis } => {
                    let parent_rot = self.skeleton.joints()[joint].parent.map_or(DQuat::IDENTITY, |p| world[p].0);
                    let direction = match axis {
                        0 => parent_rot * DVec3::X,
                        1 => {
                            let (sin_a, cos_a) = pose.euler[self.slot(joint)][0].sin_cos();
                            parent_rot * DVec3::new(0.0, cos_a, sin_a)
                        }
                        _ => world[joint].0 * DVec3::Z,
                    };
                    (direction, world[joint].1)
                }
                DofKind::Translation { axis } => (AXES[axis].unit().as_dvec3(), DVec3::ZERO),
            };
        }
    }

    /// Writes the pose's rig-joint rotations back as quaternions (f32, for a clip).
    pub fn rotations_of(&self, pose: &IkPose, out: &mut [Quat]) {
        for (j, q) in out.iter_mut().enumerate() {
            *q = match self.rig_slot[j] {
                Some(s) => euler_rotation(pose.euler[s]).as_quat(),
                None => pose.rotations[j].as_quat(),
            };
        }
    }
}

/// `Rx(a)·Ry(b)·Rz(c)` as the product of the three half-angle quaternions, the first two
/// multiplied out by hand (they have two zero components each).
#[inline]
fn euler_rotation([a, b, c]: [f64; 3]) -> DQuat {
    let (sx, cx) = (0.5 * a).sin_cos();
    let (sy, cy) = (0.5 * b).sin_cos();
    let (sz, cz) = (0.5 * c).sin_cos();
    DQuat::from_xyzw(sx * cy, cx * sy, sx * sy, cx * cy) * DQuat::from_xyzw(0.0, 0.0, sz, cz)
}

/// Bounds of one Euler axis from optional joint limits (unbounded without).
fn limits_of(limits: Option<JointLimits>, axis: usize) -> (f64, f64) {
    match limits {
        Some(l) => (f64::from(l.min[axis]), f64::from(l.max[axis])),
        None => (f64::NEG_INFINITY, f64::INFINITY),
    }
}

/// The state an IK solve changes: every joint's local rotation and translation, plus the
/// Euler angles of the rig joints (which take precedence over their rotations).
#[derive(Debug, PartialEq)]
pub struct IkPose {
    /// Local rotation per skeleton joint (used for joints outside the rig).
    pub rotations: Vec<DQuat>,
    /// Local translation per skeleton joint, metres (the root's is its world position).
    pub translations: Vec<DVec3>,
    /// Euler angles `[X, Y, Z]` (radians) per rig joint.
    pub euler: Vec<[f64; 3]>,
}

/// Written out so that `clone_from` reuses the buffers (the derived one allocates anew),
/// which keeps the per-solve scratch poses allocation-free.
impl Clone for IkPose {
    fn clone(&self) -> Self {
        IkPose { rotations: self.rotations.clone(), translations: self.translations.clone(), euler: self.euler.clone() }
    }

    fn clone_from(&mut self, source: &Self) {
        self.rotations.clone_from(&source.rotations);
        self.translations.clone_from(&source.translations);
        self.euler.clone_from(&source.euler);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Joint;

    #[test]
    fn euler_rotation_is_the_composition_of_the_three_axis_rotations() {
        for angles in [[0.0, 0.0, 0.0], [0.3, -0.4, 0.9], [-3.0, 1.5, 2.9], [1e-9, -2.2, 0.0]] {
            let [a, b, c] = angles;
            let expected = DQuat::from_rotation_x(a) * DQuat::from_rotation_y(b) * DQuat::from_rotation_z(c);
            let got = euler_rotation(angles);
            assert!((got - expected).length() < 1e-15, "{angles:?}: {got:?} vs {expected:?}");
        }
    }

    #[test]
    fn euler_axes_match_a_hand_built_frame() {
        // One joint rotated by (a, b, c): the Z DOF axis must be Rx(a)·Ry(b)·Z.
        let skeleton = Arc::new(
            Skeleton::new(vec![Joint::new("a", None, Vec3::ZERO), Joint::new("b", Some(0), Vec3::Y)]).unwrap(),
        );
        let mut rig = IkRig::new(skeleton);
        rig.add_joint(0, [true; 3], 1.0);
        rig.add_effector(1);
        let rig = rig.finish().unwrap();
        let mut pose = rig.pose_from(&[Quat::IDENTITY; 2], &[Vec3::ZERO, Vec3::Y]);
        pose.euler[0] = [0.3, -0.4, 0.9];
        let mut world = [(DQuat::IDENTITY, DVec3::ZERO); 2];
        let mut axes = [(DVec3::ZERO, DVec3::ZERO); 3];
        rig.forward(&pose, &mut world);
        rig.dof_axes(&pose, &world, &mut axes);
        let (ca, sa) = (0.3f64.cos(), 0.3f64.sin());
        let (cb, sb) = ((-0.4f64).cos(), (-0.4f64).sin());
        // Rx(a) · Ry(b) · (0,0,1) = Rx(a) · (sb, 0, cb) = (sb, -sa cb, ca cb)
        let expected = DVec3::new(sb, -sa * cb, ca * cb);
        assert!((axes[2].0 - expected).length() < 1e-12, "{:?}", axes[2].0);
        assert!((axes[1].0 - DVec3::new(0.0, ca, sa)).length() < 1e-12);
    }
}
