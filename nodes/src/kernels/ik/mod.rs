//! Inverse kinematics the node families share: the rig (degrees of freedom, stiffness,
//! limits, effectors), the weighted Jacobian solver (Meredith & Maddock) and the foot lock
//! built on it (the IK clean-up after a blend or a retarget).

pub mod foot_lock;
pub mod reach;
pub mod rig;
pub mod solve;

pub use rig::{Dof, DofKind, IkPose, IkRig, RigError};
pub use solve::{IkSolver, SolveParams, SolveReport, Weighting};
