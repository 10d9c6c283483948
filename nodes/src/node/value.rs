//! The closed set of data types that flow along edges.

use std::sync::Arc;

use crate::kernels::transition_graph::{Clusters, TransitionGraph};
use crate::model::{BarNet, BoneMap, Clip, ClipSet, Contacts, Curves, Mesh, MeshSequence, Phases, Stages};
use crate::model::{Family, FluidDomain, SampleOutcome, VolumeSequence};

pub use crate::model::report::{Report, into_report};

/// A report output from a `json!` object (anything else becomes an empty report).
pub fn report_of(value: serde_json::Value) -> Arc<Report> {
    Arc::new(into_report(value))
}

/// The type of a port. Closed: an edge is valid only between ports of the same type.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PortType {
    /// An animation clip on a skeleton.
    Clip,
    /// A triangle mesh, optionally skinned.
    Mesh,
    /// A real number.
    Scalar,
    /// A path of a file a node wrote (inside the run's output directory).
    File,
    /// Sampled curves (angular momentum, centre of mass, …).
    Curves,
    /// Motion phases of a clip.
    Phases,
    /// Foot contacts of a clip.
    Contacts,
    /// A node's structured report.
    Report,
    /// A mesh deformed per frame of a clip (baked skinning or bar-net output).
    MeshSequence,
    /// A bar-net coupled to a control mesh.
    BarNet,
    /// Named clips on one skeleton at one frame rate.
    ClipSet,
    /// Every frame of a clip set labelled with a pose cluster.
    Clusters,
    /// Pose clusters joined by the clips that pass between them.
    TransitionGraph,
    /// Which joint of one skeleton drives which joint of another.
    BoneMap,
    /// Alternating ground and flight stages of a clip, with the fitted gravity.
    Stages,
    /// A box of air with its mesh sizing and smoke sources, for `fluid.simulate`.
    FluidDomain,
    /// Smoke density, temperature and velocity on a voxel grid per frame, plus particles.
    VolumeSequence,
    /// Edits of one clip sampled over a line, grid or semicircle of one stage's placements.
    Family,
}

impl PortType {
    /// Stable lowercase name used in catalogues and messages.
    pub fn name(self) -> &'static str {
        match self {
            PortType::Clip => "clip",
            PortType::Mesh => "mesh",
            PortType::Scalar => "scalar",
            PortType::File => "file",
            PortType::Curves => "curves",
            PortType::Phases => "phases",
            PortType::Contacts => "contacts",
            PortType::Report => "report",
            PortType::MeshSequence => "mesh_sequence",
            PortType::BarNet => "bar_net",
            PortType::ClipSet => "clip_set",
            PortType::Clusters => "clusters",
            PortType::TransitionGraph => "transition_graph",
            PortType::BoneMap => "bone_map",
            PortType::Stages => "stages",
            PortType::FluidDomain => "fluid_domain",
            PortType::VolumeSequence => "volume_sequence",
            PortType::Family => "family",
        }
    }
}

/// A value on an edge. Heavy data sits behind `Arc`, so fan-out and caching copy pointers.
/// Serialisable, so the engine's on-disk cache can keep node outputs between runs.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Value {
    /// See [`PortType::Clip`].
    Clip(Arc<Clip>),
    /// See [`PortType::Mesh`].
    Mesh(Arc<Mesh>),
    /// See [`PortType::Scalar`].
    Scalar(f64),
    /// See [`PortType::File`]: the path as written, relative to the output directory.
    File(Arc<std::path::PathBuf>),
    /// See [`PortType::Curves`].
    Curves(Arc<Curves>),
    /// See [`PortType::Phases`].
    Phases(Arc<Phases>),
    /// See [`PortType::Contacts`].
    Contacts(Arc<Contacts>),
    /// See [`PortType::Report`].
    Report(Arc<Report>),
    /// See [`PortType::MeshSequence`].
    MeshSequence(Arc<MeshSequence>),
    /// See [`PortType::BarNet`].
    BarNet(Arc<BarNet>),
    /// See [`PortType::ClipSet`].
    ClipSet(Arc<ClipSet>),
    /// See [`PortType::Clusters`].
    Clusters(Arc<Clusters>),
    /// See [`PortType::TransitionGraph`].
    TransitionGraph(Arc<TransitionGraph>),
    /// See [`PortType::BoneMap`].
    BoneMap(Arc<BoneMap>),
    /// See [`PortType::Stages`].
    Stages(Arc<Stages>),
    /// See [`PortType::FluidDomain`].
    FluidDomain(Arc<FluidDomain>),
    /// See [`PortType::VolumeSequence`].
    VolumeSequence(Arc<VolumeSequence>),
    /// See [`PortType::Family`].
    Family(Arc<Family>),
}

impl Value {
    /// This value's port type.
    pub fn port_type(&self) -> PortType {
        match self {
            Value::Clip(_) => PortType::Clip,
            Value::Mesh(_) => PortType::Mesh,
            Value::Scalar(_) => PortType::Scalar,
            Value::File(_) => PortType::File,
            Value::Curves(_) => PortType::Curves,
            Value::Phases(_) => PortType::Phases,
            Value::Contacts(_) => PortType::Contacts,
            Value::Report(_) => PortType::Report,
            Value::MeshSequence(_) => PortType::MeshSequence,
            Value::BarNet(_) => PortType::BarNet,
            Value::ClipSet(_) => PortType::ClipSet,
            Value::Clusters(_) => PortType::Clusters,
            Value::TransitionGraph(_) => PortType::TransitionGraph,
            Value::BoneMap(_) => PortType::BoneMap,
            Value::Stages(_) => PortType::Stages,
            Value::FluidDomain(_) => PortType::FluidDomain,
            Value::VolumeSequence(_) => PortType::VolumeSequence,
            Value::Family(_) => PortType::Family,
        }
    }

    /// Bytes of this value's sample arrays (poses, vertices, skin, curve samples, voxels,
    /// particles), what `kg run --json` reports per node so a user sees what a graph will
    /// cost. Metadata and small values count 0; a mesh sequence counts its own per-frame
    /// vertices, not the rest mesh and clip it shares with the nodes that made them.
    pub fn array_bytes(&self) -> u64 {
        fn bytes<T>(items: &[T]) -> u64 {
            std::mem::size_of_val(items) as u64
        }
        let clip = |c: &Clip| bytes(c.rotations()) + bytes(c.translations());
        match self {
            Value::Clip(c) => clip(c),
            Value::Mesh(m) => {
                let skin = m.skin.as_ref().map_or(0, |s| bytes(&s.joints) + bytes(&s.weights));
                bytes(&m.positions) + bytes(&m.normals) + m.uvs.as_deref().map_or(0, bytes) + bytes(&m.triangles) + skin
            }
            Value::MeshSequence(s) => {
                2 * (s.vertex_count() * s.frame_count() * std::mem::size_of::<glam::Vec3>()) as u64
            }
            Value::ClipSet(set) => set.clips().iter().map(|c| clip(&c.clip)).sum(),
            Value::Family(f) => f
                .samples
                .iter()
                .map(|s| match &s.outcome {
                    SampleOutcome::Solved(c) => clip(c),
                    SampleOutcome::Failed(_) => 0,
                })
                .sum(),
            Value::Curves(c) => c.channels().iter().map(|ch| bytes(&ch.values)).sum(),
            Value::VolumeSequence(v) => v
                .frames
                .iter()
                .map(|f| bytes(&f.density) + bytes(&f.temperature_k) + bytes(&f.velocity_m_s) + bytes(&f.particles_m))
                .sum(),
            _ => 0,
        }
    }
}

/// A Rust type that travels on a port of one [`PortType`].
pub trait PortValue: Sized {
    /// The port type carrying this Rust type.
    const TYPE: PortType;
    /// Extracts the payload when `value` has the right type.
    fn from_value(value: &Value) -> Option<Self>;
    /// Wraps the payload.
    fn into_value(self) -> Value;
}

/// Implements [`PortValue`] for the payload of one `Value` variant.
macro_rules! port_value {
    ($payload:ty, $variant:ident) => {
        impl PortValue for $payload {
            const TYPE: PortType = PortType::$variant;
            fn from_value(value: &Value) -> Option<Self> {
                match value {
                    Value::$variant(v) => Some(v.clone()),
                    _ => None,
                }
            }
            fn into_value(self) -> Value {
                Value::$variant(self)
            }
        }
    };
}

port_value!(Arc<Clip>, Clip);
port_value!(Arc<Mesh>, Mesh);
port_value!(f64, Scalar);
port_value!(Arc<std::path::PathBuf>, File);
port_value!(Arc<Curves>, Curves);
port_value!(Arc<Phases>, Phases);
port_value!(Arc<Contacts>, Contacts);
port_value!(Arc<Report>, Report);
port_value!(Arc<MeshSequence>, MeshSequence);
port_value!(Arc<BarNet>, BarNet);
port_value!(Arc<ClipSet>, ClipSet);
port_value!(Arc<Clusters>, Clusters);
port_value!(Arc<TransitionGraph>, TransitionGraph);
port_value!(Arc<BoneMap>, BoneMap);
port_value!(Arc<Stages>, Stages);
port_value!(Arc<FluidDomain>, FluidDomain);
port_value!(Arc<VolumeSequence>, VolumeSequence);
port_value!(Arc<Family>, Family);
