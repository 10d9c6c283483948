//! Inverse kinematics and what is built on it: the weighted Jacobian solver (Meredith &
//! Maddock), online retargeting (Choi & Ko 2000) and skeleton edits to make test characters.

pub mod rig;
pub mod solve;

pub use rig::{Dof, DofKind, IkPose, IkRig, RigError};
pub use solve::{IkSolver, SolveParams, SolveReport};
pub mod foot_lock;
pub mod map;
pub mod retarget;
pub mod roles;
pub mod scale;

use crate::node::Registry;

/// Registers the IK family's nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(solve::IkSolve));
    registry.add(Box::new(scale::ScaleSkeleton));
    registry.add(Box::new(retarget::RetargetOnline));
    registry.add(Box::new(foot_lock::FootLock));
    registry.add(Box::new(map::MapSkeleton));
    registry.add(Box::new(map::ExportBoneMap));
}
