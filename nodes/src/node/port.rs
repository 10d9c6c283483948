//! Typed port declarations: each port is one constant used by both the schema and `eval`.

use std::marker::PhantomData;

use super::value::{PortType, PortValue};

/// The port that carries a scene's fixed objects (physics.simulate's output; export.glb's
/// and motion.quality's input); the editor's viewport draws the mesh found there. It lives
/// with the contract so the families that share it need not import each other or the registry.
pub const PROPS_PORT: &str = "props";

/// What the schema (catalogue, validator, editor) knows of a port.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct PortSpec {
    /// Stable name, persisted in graph files (`"clip"`).
    pub name: &'static str,
    /// Data type.
    #[serde(rename = "type")]
    pub ty: PortType,
    /// Tooltip text for animators.
    pub doc: &'static str,
    /// Inputs only: whether the node refuses to run without it.
    pub required: bool,
}

/// A typed input port.
pub struct Input<T> {
    spec: PortSpec,
    _type: PhantomData<fn() -> T>,
}

impl<T: PortValue> Input<T> {
    /// A required input.
    pub const fn required(name: &'static str, doc: &'static str) -> Self {
        Input { spec: PortSpec { name, ty: T::TYPE, doc, required: true }, _type: PhantomData }
    }

    /// An optional input.
    pub const fn optional(name: &'static str, doc: &'static str) -> Self {
        Input { spec: PortSpec { name, ty: T::TYPE, doc, required: false }, _type: PhantomData }
    }

    /// The schema entry.
    pub const fn spec(&self) -> PortSpec {
        self.spec
    }

    /// The port name.
    pub const fn name(&self) -> &'static str {
        self.spec.name
    }
}

/// A typed output port.
pub struct Output<T> {
    spec: PortSpec,
    _type: PhantomData<fn() -> T>,
}

impl<T: PortValue> Output<T> {
    /// Declares an output.
    pub const fn new(name: &'static str, doc: &'static str) -> Self {
        Output { spec: PortSpec { name, ty: T::TYPE, doc, required: false }, _type: PhantomData }
    }

    /// The schema entry.
    pub const fn spec(&self) -> PortSpec {
        self.spec
    }

    /// The port name.
    pub const fn name(&self) -> &'static str {
        self.spec.name
    }
}
