//! The closed set of data types that flow along edges.

use std::sync::Arc;

use crate::model::{BarNet, Clip, Mesh, MeshSequence};

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
    /// A mesh deformed per frame of a clip (baked skinning or bar-net output).
    MeshSequence,
    /// A bar-net coupled to a control mesh.
    BarNet,
}

impl PortType {
    /// Stable lowercase name used in catalogues and messages.
    pub fn name(self) -> &'static str {
        match self {
            PortType::Clip => "clip",
            PortType::Mesh => "mesh",
            PortType::Scalar => "scalar",
            PortType::File => "file",
            PortType::MeshSequence => "mesh_sequence",
            PortType::BarNet => "bar_net",
        }
    }
}

/// A value on an edge. Heavy data sits behind `Arc`, so fan-out and caching copy pointers.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// See [`PortType::Clip`].
    Clip(Arc<Clip>),
    /// See [`PortType::Mesh`].
    Mesh(Arc<Mesh>),
    /// See [`PortType::Scalar`].
    Scalar(f64),
    /// See [`PortType::File`]: the path as written, relative to the output directory.
    File(Arc<std::path::PathBuf>),
    /// See [`PortType::MeshSequence`].
    MeshSequence(Arc<MeshSequence>),
    /// See [`PortType::BarNet`].
    BarNet(Arc<BarNet>),
}

impl Value {
    /// This value's port type.
    pub fn port_type(&self) -> PortType {
        match self {
            Value::Clip(_) => PortType::Clip,
            Value::Mesh(_) => PortType::Mesh,
            Value::Scalar(_) => PortType::Scalar,
            Value::File(_) => PortType::File,
            Value::MeshSequence(_) => PortType::MeshSequence,
            Value::BarNet(_) => PortType::BarNet,
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

impl PortValue for Arc<Clip> {
    const TYPE: PortType = PortType::Clip;
    fn from_value(value: &Value) -> Option<Self> {
        match value {
            Value::Clip(c) => Some(c.clone()),
            _ => None,
        }
    }
    fn into_value(self) -> Value {
        Value::Clip(self)
    }
}

impl PortValue for Arc<Mesh> {
    const TYPE: PortType = PortType::Mesh;
    fn from_value(value: &Value) -> Option<Self> {
        match value {
            Value::Mesh(m) => Some(m.clone()),
            _ => None,
        }
    }
    fn into_value(self) -> Value {
        Value::Mesh(self)
    }
}

impl PortValue for f64 {
    const TYPE: PortType = PortType::Scalar;
    fn from_value(value: &Value) -> Option<Self> {
        match value {
            Value::Scalar(v) => Some(*v),
            _ => None,
        }
    }
    fn into_value(self) -> Value {
        Value::Scalar(self)
    }
}

impl PortValue for Arc<std::path::PathBuf> {
    const TYPE: PortType = PortType::File;
    fn from_value(value: &Value) -> Option<Self> {
        match value {
            Value::File(p) => Some(p.clone()),
            _ => None,
        }
    }
    fn into_value(self) -> Value {
        Value::File(self)
    }
}

impl PortValue for Arc<MeshSequence> {
    const TYPE: PortType = PortType::MeshSequence;
    fn from_value(value: &Value) -> Option<Self> {
        match value {
            Value::MeshSequence(s) => Some(s.clone()),
            _ => None,
        }
    }
    fn into_value(self) -> Value {
        Value::MeshSequence(self)
    }
}

impl PortValue for Arc<BarNet> {
    const TYPE: PortType = PortType::BarNet;
    fn from_value(value: &Value) -> Option<Self> {
        match value {
            Value::BarNet(n) => Some(n.clone()),
            _ => None,
        }
    }
    fn into_value(self) -> Value {
        Value::BarNet(self)
    }
}
