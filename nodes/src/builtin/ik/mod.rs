//! Inverse kinematics and what is built on it: the weighted Jacobian solver (Meredith &
//! Maddock), online retargeting (Choi & Ko 2000) and skeleton edits to make test characters.

pub mod rig;
pub mod solve;

pub use rig::{Dof, DofKind, IkPose, IkRig, RigError};
pub use solve::{IkSolver, SolveParams, SolveReport};
pub mod retarget;
pub mod scale;
