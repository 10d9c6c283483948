//! Typed names inside a graph: a node id, a port of a node, a parameter of a node.
//!
//! Graph files write endpoints as `"node.port"` and parameter paths as `"node.param"`.
//! Node ids may contain dots (`"rig.left"`); port and parameter names never do, so the
//! text is split at its *last* dot. This module is the only place that splits them.

use std::borrow::Borrow;
use std::fmt;

use super::GraphError;

/// A node's id, as written in the graph file. Checked by [`NodeId::check`]. Boxed text
/// (not a `String`) keeps ids and the errors that carry them small.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(Box<str>);

/// The longest node id accepted: ids are names people read in files and on the canvas.
pub const MAX_ID_CHARS: usize = 128;

impl NodeId {
    /// Wraps `id` without checking it (files may hold ids the rules refuse; the checker
    /// reports them with their location instead of failing the load).
    pub fn new(id: impl Into<String>) -> Self {
        NodeId(id.into().into_boxed_str())
    }

    /// The id's text.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The one rule for node ids, used by `kg check` and the editor alike: non-empty, at
    /// most [`MAX_ID_CHARS`] characters, no whitespace, control characters, quotes or
    /// backslashes, and no dot at either end (so `"id.port"` splits without doubt).
    pub fn check(&self) -> Result<(), GraphError> {
        let id: &str = &self.0;
        let reason = if id.is_empty() {
            Some("it is empty")
        } else if id.chars().count() > MAX_ID_CHARS {
            Some("it is longer than 128 characters")
        } else if id.chars().any(|c| c.is_whitespace() || c.is_control()) {
            Some("it contains spaces or control characters")
        } else if id.contains(['"', '\\']) {
            Some("it contains a quote or a backslash")
        } else if id.starts_with('.') || id.ends_with('.') {
            Some("it starts or ends with a dot")
        } else {
            None
        };
        match reason {
            Some(reason) => Err(GraphError::BadNodeId { id: self.clone(), reason }),
            None => Ok(()),
        }
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Control characters never reach a terminal raw.
        write!(f, "{}", self.0.escape_debug())
    }
}

impl Borrow<str> for NodeId {
    fn borrow(&self) -> &str {
        &self.0
    }
}

impl From<&str> for NodeId {
    fn from(id: &str) -> Self {
        NodeId(id.into())
    }
}

impl From<String> for NodeId {
    fn from(id: String) -> Self {
        NodeId(id.into_boxed_str())
    }
}

/// Splits `"node.name"` at its last dot; both sides must be non-empty.
fn split_last_dot(text: &str) -> Option<(&str, &str)> {
    text.rsplit_once('.').filter(|(n, p)| !n.is_empty() && !p.is_empty())
}

/// One port of one node: `"node.port"` in files.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PortRef {
    /// The node.
    pub node: NodeId,
    /// The port's name in the node's schema.
    pub port: String,
}

impl PortRef {
    /// A port reference from its parts.
    pub fn new(node: impl Into<NodeId>, port: impl Into<String>) -> Self {
        PortRef { node: node.into(), port: port.into() }
    }

    /// The `"node.port"` text a graph file holds (unescaped, unlike `Display`).
    pub fn text(&self) -> String {
        format!("{}.{}", self.node.as_str(), self.port)
    }

    /// Parses `"node.port"`.
    pub fn parse(text: &str) -> Result<Self, GraphError> {
        split_last_dot(text)
            .map(|(node, port)| PortRef::new(node, port))
            .ok_or_else(|| GraphError::BadEndpoint { text: text.to_string() })
    }
}

impl fmt::Display for PortRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.node, self.port)
    }
}

/// One parameter of one node: `"node.param"` in files and on the command line.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ParamPath {
    /// The node.
    pub node: NodeId,
    /// The parameter's name in the node's schema.
    pub param: String,
}

impl ParamPath {
    /// A parameter path from its parts.
    pub fn new(node: impl Into<NodeId>, param: impl Into<String>) -> Self {
        ParamPath { node: node.into(), param: param.into() }
    }

    /// The `"node.param"` text a graph file holds (unescaped, unlike `Display`).
    pub fn text(&self) -> String {
        format!("{}.{}", self.node.as_str(), self.param)
    }

    /// Parses `"node.param"`.
    pub fn parse(text: &str) -> Option<Self> {
        split_last_dot(text).map(|(node, param)| ParamPath::new(node, param))
    }
}

impl fmt::Display for ParamPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.node, self.param)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn dotted_ids_split_at_the_last_dot() {
        let p = PortRef::parse("rig.left.clip").unwrap();
        assert_eq!((p.node.as_str(), p.port.as_str()), ("rig.left", "clip"));
        assert_eq!(p.to_string(), "rig.left.clip");
        let q = ParamPath::parse("a.b.fps").unwrap();
        assert_eq!((q.node.as_str(), q.param.as_str()), ("a.b", "fps"));
        assert!(PortRef::parse("noport").is_err());
        assert!(PortRef::parse(".clip").is_err());
        assert!(PortRef::parse("node.").is_err());
    }

    #[test]
    fn the_id_rule() {
        for good in ["trim", "trim_2", "rig.left", "a-b", "Ünïcode"] {
            assert!(NodeId::from(good).check().is_ok(), "{good}");
        }
        for bad in ["", "a b", "a\tb", "a\u{1b}[31m", "a\"b", "a\\b", ".a", "a.", &"x".repeat(129)] {
            assert!(NodeId::from(bad).check().is_err(), "{bad:?}");
        }
    }

    #[test]
    fn control_characters_are_escaped_when_shown() {
        assert_eq!(NodeId::from("a\u{1b}[31m").to_string(), "a\\u{1b}[31m");
    }
}
