//! The motion data model: skeletons, clips, meshes, skins, forward kinematics and units.

pub mod barnet;
pub mod bone_map;
pub mod choice;
pub mod clip;
pub mod clip_set;
pub mod curves;
pub mod family;
pub mod fk;
pub mod intervals;
pub mod material;
pub mod mesh;
pub mod mesh_sequence;
pub mod names;
pub mod report;
pub mod skeleton;
pub mod stages;
pub mod units;
pub mod volume;

pub use clip::{Clip, ClipError};
pub use clip_set::{ClipSet, ClipSetError, NamedClip};

/// Largest coordinate (metres) a joint offset or translation may have. Real scenes stay far
/// below it; the bound keeps sums along joint chains finite in f32, so forward kinematics
/// can never produce infinities from finite input.
pub const MAX_COORDINATE_M: f32 = 1e6;

/// True when every component of `v` is finite and within ±[`MAX_COORDINATE_M`].
pub fn coordinate_in_range(v: glam::Vec3) -> bool {
    v.is_finite() && v.abs().max_element() <= MAX_COORDINATE_M
}
pub use barnet::{BarNet, BarNetError};
pub use bone_map::BoneMap;
pub use curves::{CurveChannel, Curves, CurvesError};
pub use family::{Family, FamilyKind, FamilySample, SampleOutcome};
pub use fk::{ClipPoses, Transform, forward_kinematics};
pub use intervals::{Contacts, FootContacts, FrameRange, Phases};
pub use material::{AlphaMode, Image, Material, MaterialRange, Sampler, Specular, Texture};
pub use mesh::{Mesh, MeshPart, Skin};
pub use mesh_sequence::{MeshSequence, MeshSequenceError};
pub use report::{Report, into_report};
pub use skeleton::{Channel, Joint, JointLimits, Skeleton, SkeletonError};
pub use stages::{Stage, StageKind, Stages};
pub use units::{ImportScale, LengthUnit};
pub use volume::{BodyPose, BodyShape, FluidDomain, VolumeSequence};
