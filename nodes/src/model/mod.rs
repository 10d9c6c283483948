//! The motion data model: skeletons, clips, meshes, skins, forward kinematics and units.

pub mod clip;
pub mod fk;
pub mod mesh;
pub mod skeleton;
pub mod units;

pub use clip::{Clip, ClipError};
pub use fk::{ClipPoses, Transform, forward_kinematics};
pub use mesh::{Mesh, Skin};
pub use skeleton::{Channel, Joint, JointLimits, Skeleton, SkeletonError};
pub use units::{ImportScale, LengthUnit};
