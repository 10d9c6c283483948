//! Inverse kinematics and what is built on it: the weighted Jacobian solver and the
//! procedural walk (Meredith & Maddock), online retargeting (Choi & Ko 2000) and skeleton
//! edits to make test characters.

pub mod rig;
pub mod solve;

pub use rig::{Dof, DofKind, IkPose, IkRig, RigError};
pub use solve::{IkSolver, SolveParams, SolveReport};
pub mod gait;
pub mod retarget;
pub mod scale;

use crate::node::Registry;

/// Registers the IK family's nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(solve::IkSolve));
    registry.add(Box::new(scale::ScaleSkeleton));
    registry.add(Box::new(retarget::RetargetOnline));
    registry.add(Box::new(gait::ProceduralGait));
}
