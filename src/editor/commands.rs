//! The editor's command reducer: every edit the editor can make to a [`GraphDoc`], applied
//! by a pure function that checks it against the node schemas and returns its inverse, and
//! a [`History`] of those inverses for undo and redo.
//!
//! The document stays the single source of truth: widgets emit [`EditorCommand`]s, the
//! reducer applies them, and views are rebuilt from the document. Nothing here knows egui.
//!
//! Invariants the reducer keeps (so undo restores byte-identical files):
//! 1. A command either applies completely or leaves the document untouched.
//! 2. `apply(inverse)` after `apply(cmd)` gives back the document as it was, up to the
//!    order of `edges` (which files sort), hence the same
//!    [`to_string`](crate::document::to_string) bytes.
//! 3. An input port has at most one incoming edge; connecting into an occupied input
//!    replaces the old edge in the same (single-undo) step.

use std::collections::{BTreeMap, BTreeSet};

use kinegraph_nodes::node::{NodeSchema, ParamValue, PortType, Registry};

use crate::document::{EdgeDoc, GraphDoc, NodeDoc, split_endpoint};

/// A node removed by [`EditorCommand::RemoveNodes`], kept whole so it can be put back.
#[derive(Clone, Debug, PartialEq)]
pub struct RemovedNode {
    /// Node id.
    pub id: String,
    /// The node as it was.
    pub node: NodeDoc,
    /// Its canvas position, if it had one.
    pub pos: Option<(f32, f32)>,
}

/// One edit of a graph document. Endpoints are `"node.port"` strings as in graph files.
#[derive(Clone, Debug, PartialEq)]
pub enum EditorCommand {
    /// Adds a node of `kind` called `id` at canvas position `pos` (see [`fresh_node_id`]).
    AddNode {
        /// New, unused node id.
        id: String,
        /// Registered node kind, e.g. `"clip.trim"`.
        kind: String,
        /// Canvas position.
        pos: (f32, f32),
    },
    /// Removes nodes with their edges, layout entries and the graph inputs that point at them.
    RemoveNodes {
        /// Ids of existing nodes.
        ids: Vec<String>,
    },
    /// Puts back nodes removed by [`EditorCommand::RemoveNodes`] (its inverse).
    RestoreNodes {
        /// The nodes, as they were.
        nodes: Vec<RemovedNode>,
        /// The edges that touched them.
        edges: Vec<EdgeDoc>,
        /// The graph inputs that pointed at them, `(name, "node.param")`.
        inputs: Vec<(String, String)>,
    },
    /// Connects an output to an input, replacing whatever fed that input.
    Connect {
        /// `"node.output"`.
        from: String,
        /// `"node.input"`.
        to: String,
    },
    /// Removes one edge.
    Disconnect {
        /// `"node.output"`.
        from: String,
        /// `"node.input"`.
        to: String,
    },
    /// Sets a parameter, checked against its schema (range, type, choices).
    SetParam {
        /// Node id.
        node: String,
        /// Parameter name.
        param: String,
        /// New value.
        value: ParamValue,
    },
    /// Removes a parameter's value so the schema default applies.
    ResetParam {
        /// Node id.
        node: String,
        /// Parameter name.
        param: String,
    },
    /// Sets canvas positions; `None` removes a node's layout entry.
    MoveNodes {
        /// `(node id, new position)` pairs.
        moves: Vec<(String, Option<(f32, f32)>)>,
    },
    /// Promotes a parameter to a graph input (`Some("node.param")`) or removes the input.
    SetInput {
        /// Public input name.
        name: String,
        /// `"node.param"`, or `None` to remove.
        target: Option<String>,
    },
    /// Replaces the graph's description.
    SetDescription {
        /// New text.
        text: String,
    },
    /// Several commands as one undo step, applied in order (all or none).
    Batch(Vec<EditorCommand>),
}

impl EditorCommand {
    /// A short label for menus and tooltips ("Undo connect trim.clip").
    pub fn label(&self) -> String {
        match self {
            EditorCommand::AddNode { id, .. } => format!("add {id}"),
            EditorCommand::RemoveNodes { ids } => format!("delete {}", ids.join(", ")),
            EditorCommand::RestoreNodes { nodes, .. } => {
                format!("restore {}", nodes.iter().map(|n| n.id.as_str()).collect::<Vec<_>>().join(", "))
            }
            EditorCommand::Connect { to, .. } => format!("connect {to}"),
            EditorCommand::Disconnect { to, .. } => format!("disconnect {to}"),
            EditorCommand::SetParam { node, param, .. } => format!("set {node}.{param}"),
            EditorCommand::ResetParam { node, param } => format!("reset {node}.{param}"),
            EditorCommand::MoveNodes { moves } => format!("move {} node(s)", moves.len()),
            EditorCommand::SetInput { name, .. } => format!("graph input {name}"),
            EditorCommand::SetDescription { .. } => "description".into(),
            EditorCommand::Batch(cmds) => cmds.first().map(EditorCommand::label).unwrap_or_else(|| "nothing".into()),
        }
    }
}

/// Why an edit was refused. The message is shown to the user as is (e.g. as the tooltip
/// of a refused connection).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EditError {
    /// The node id does not exist.
    #[error("there is no node '{0}'")]
    UnknownNode(String),
    /// The kind is not registered.
    #[error("unknown node kind '{0}'")]
    UnknownKind(String),
    /// The id is already used.
    #[error("a node called '{0}' already exists")]
    DuplicateId(String),
    /// The id is not usable.
    #[error("'{0}' is not a usable node id: use letters, digits and '_' only")]
    BadId(String),
    /// An endpoint is not `"node.port"`.
    #[error("'{0}' is not \"node.port\"")]
    BadEndpoint(String),
    /// The node has no such port on that side.
    #[error("'{kind}' has no {side} '{port}'")]
    UnknownPort {
        /// Node kind.
        kind: String,
        /// `"input"` or `"output"`.
        side: &'static str,
        /// Port name.
        port: String,
    },
    /// The two ports carry different types.
    #[error("{from} gives a {from_ty}, but {to} takes a {to_ty}")]
    TypeMismatch {
        /// Source endpoint.
        from: String,
        /// Its type name.
        from_ty: &'static str,
        /// Destination endpoint.
        to: String,
        /// Its type name.
        to_ty: &'static str,
    },
    /// The edge would close a loop.
    #[error("connecting {from} to {to} would make a cycle: a node cannot depend on its own output")]
    Cycle {
        /// Source endpoint.
        from: String,
        /// Destination endpoint.
        to: String,
    },
    /// The edge exists already.
    #[error("{from} is already connected to {to}")]
    AlreadyConnected {
        /// Source endpoint.
        from: String,
        /// Destination endpoint.
        to: String,
    },
    /// The edge to remove does not exist.
    #[error("{from} is not connected to {to}")]
    NotConnected {
        /// Source endpoint.
        from: String,
        /// Destination endpoint.
        to: String,
    },
    /// The node kind has no such parameter.
    #[error("'{kind}' has no parameter '{param}'")]
    UnknownParam {
        /// Node kind.
        kind: String,
        /// Parameter name.
        param: String,
    },
    /// The value does not fit the parameter.
    #[error("{node}.{param}: {message}")]
    BadValue {
        /// Node id.
        node: String,
        /// Parameter name.
        param: String,
        /// What is accepted.
        message: String,
    },
    /// Nothing to undo or redo.
    #[error("nothing to {0}")]
    NothingTo(&'static str),
    /// Pasted text is not a graph fragment.
    #[error("the clipboard holds no graph fragment: {0}")]
    BadFragment(String),
}

/// A fresh, readable node id for a new node of `kind`: the kind's last segment
/// (`"clip.trim"` → `trim`), then `trim_2`, `trim_3`, … until unused.
pub fn fresh_node_id(doc: &GraphDoc, kind: &str) -> String {
    let last = kind.rsplit('.').next().unwrap_or(kind);
    let mut base: String = last.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect();
    if base.is_empty() {
        base = "node".into();
    }
    if !doc.nodes.contains_key(&base) {
        return base;
    }
    (2..).map(|n| format!("{base}_{n}")).find(|id| !doc.nodes.contains_key(id)).unwrap_or(base)
}

fn schema_of(doc: &GraphDoc, registry: &Registry, id: &str) -> Result<&'static NodeSchema, EditError> {
    let node = doc.nodes.get(id).ok_or_else(|| EditError::UnknownNode(id.to_string()))?;
    registry.get(&node.kind).map(|n| n.schema()).ok_or_else(|| EditError::UnknownKind(node.kind.clone()))
}

/// The type of output `endpoint` (`"node.output"`).
pub fn output_type(doc: &GraphDoc, registry: &Registry, endpoint: &str) -> Result<PortType, EditError> {
    let (node, port) = split_endpoint(endpoint).ok_or_else(|| EditError::BadEndpoint(endpoint.into()))?;
    let schema = schema_of(doc, registry, node)?;
    schema.output(port).map(|p| p.ty).ok_or_else(|| EditError::UnknownPort {
        kind: schema.kind.into(),
        side: "output",
        port: port.into(),
    })
}

/// The type of input `endpoint` (`"node.input"`).
pub fn input_type(doc: &GraphDoc, registry: &Registry, endpoint: &str) -> Result<PortType, EditError> {
    let (node, port) = split_endpoint(endpoint).ok_or_else(|| EditError::BadEndpoint(endpoint.into()))?;
    let schema = schema_of(doc, registry, node)?;
    schema.input(port).map(|p| p.ty).ok_or_else(|| EditError::UnknownPort {
        kind: schema.kind.into(),
        side: "input",
        port: port.into(),
    })
}

/// Whether `from → to` may be connected: both ports exist, their types match, and the
/// edge closes no cycle. An occupied input is fine (connecting replaces its edge).
pub fn check_connect(doc: &GraphDoc, registry: &Registry, from: &str, to: &str) -> Result<(), EditError> {
    let from_ty = output_type(doc, registry, from)?;
    let to_ty = input_type(doc, registry, to)?;
    if from_ty != to_ty {
        return Err(EditError::TypeMismatch {
            from: from.into(),
            from_ty: from_ty.name(),
            to: to.into(),
            to_ty: to_ty.name(),
        });
    }
    if doc.edges.iter().any(|e| e.from == from && e.to == to) {
        return Err(EditError::AlreadyConnected { from: from.into(), to: to.into() });
    }
    let (src, dst) = match (split_endpoint(from), split_endpoint(to)) {
        (Some((s, _)), Some((d, _))) => (s, d),
        _ => return Err(EditError::BadEndpoint(from.into())),
    };
    if reaches(doc, dst, src) {
        return Err(EditError::Cycle { from: from.into(), to: to.into() });
    }
    Ok(())
}

/// True when `target` is `start` or downstream of it along the document's edges.
fn reaches(doc: &GraphDoc, start: &str, target: &str) -> bool {
    let mut seen = BTreeSet::new();
    let mut stack = vec![start];
    while let Some(node) = stack.pop() {
        if node == target {
            return true;
        }
        if !seen.insert(node) {
            continue;
        }
        for edge in &doc.edges {
            if let (Some((s, _)), Some((d, _))) = (split_endpoint(&edge.from), split_endpoint(&edge.to))
                && s == node
            {
                stack.push(d);
            }
        }
    }
    false
}

fn valid_id(id: &str) -> bool {
    !id.is_empty() && id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// Applies `cmd` to `doc` and returns the command that undoes it. On error `doc` is left
/// exactly as it was.
pub fn apply(doc: &mut GraphDoc, registry: &Registry, cmd: &EditorCommand) -> Result<EditorCommand, EditError> {
    match cmd {
        EditorCommand::AddNode { id, kind, pos } => {
            if !valid_id(id) {
                return Err(EditError::BadId(id.clone()));
            }
            if doc.nodes.contains_key(id) {
                return Err(EditError::DuplicateId(id.clone()));
            }
            if registry.get(kind).is_none() {
                return Err(EditError::UnknownKind(kind.clone()));
            }
            doc.nodes.insert(id.clone(), NodeDoc { kind: kind.clone(), params: BTreeMap::new() });
            doc.layout.insert(id.clone(), *pos);
            Ok(EditorCommand::RemoveNodes { ids: vec![id.clone()] })
        }
        EditorCommand::RemoveNodes { ids } => {
            let wanted: BTreeSet<&str> = ids.iter().map(String::as_str).collect();
            if let Some(missing) = wanted.iter().find(|id| !doc.nodes.contains_key(**id)) {
                return Err(EditError::UnknownNode((*missing).to_string()));
            }
            let touches = |endpoint: &str| split_endpoint(endpoint).is_some_and(|(n, _)| wanted.contains(n));
            let mut nodes = Vec::new();
            for id in &wanted {
                if let Some(node) = doc.nodes.remove(*id) {
                    let pos = doc.layout.remove(*id);
                    nodes.push(RemovedNode { id: (*id).to_string(), node, pos });
                }
            }
            let (edges, kept): (Vec<EdgeDoc>, Vec<EdgeDoc>) =
                std::mem::take(&mut doc.edges).into_iter().partition(|e| touches(&e.from) || touches(&e.to));
            doc.edges = kept;
            let inputs: Vec<(String, String)> =
                doc.inputs.iter().filter(|(_, t)| touches(t)).map(|(n, t)| (n.clone(), t.clone())).collect();
            for (name, _) in &inputs {
                doc.inputs.remove(name);
            }
            Ok(EditorCommand::RestoreNodes { nodes, edges, inputs })
        }
        EditorCommand::RestoreNodes { nodes, edges, inputs } => {
            if let Some(n) = nodes.iter().find(|n| doc.nodes.contains_key(&n.id)) {
                return Err(EditError::DuplicateId(n.id.clone()));
            }
            for n in nodes {
                doc.nodes.insert(n.id.clone(), n.node.clone());
                if let Some(pos) = n.pos {
                    doc.layout.insert(n.id.clone(), pos);
                }
            }
            // Put edges back where they were in order-insensitive terms: files sort edges on save.
            doc.edges.extend(edges.iter().cloned());
            for (name, target) in inputs {
                doc.inputs.insert(name.clone(), target.clone());
            }
            Ok(EditorCommand::RemoveNodes { ids: nodes.iter().map(|n| n.id.clone()).collect() })
        }
        EditorCommand::Connect { from, to } => {
            check_connect(doc, registry, from, to)?;
            let old = doc.edges.iter().position(|e| &e.to == to);
            let replaced = old.map(|i| doc.edges.remove(i));
            doc.edges.push(EdgeDoc { from: from.clone(), to: to.clone() });
            let undo_new = EditorCommand::Disconnect { from: from.clone(), to: to.clone() };
            Ok(match replaced {
                Some(old) => {
                    EditorCommand::Batch(vec![undo_new, EditorCommand::Connect { from: old.from, to: old.to }])
                }
                None => undo_new,
            })
        }
        EditorCommand::Disconnect { from, to } => {
            let Some(i) = doc.edges.iter().position(|e| &e.from == from && &e.to == to) else {
                return Err(EditError::NotConnected { from: from.clone(), to: to.clone() });
            };
            doc.edges.remove(i);
            Ok(EditorCommand::Connect { from: from.clone(), to: to.clone() })
        }
        EditorCommand::SetParam { node, param, value } => {
            let schema = schema_of(doc, registry, node)?;
            let spec = schema
                .param(param)
                .ok_or_else(|| EditError::UnknownParam { kind: schema.kind.into(), param: param.clone() })?;
            let value = spec.check(value).map_err(|message| EditError::BadValue {
                node: node.clone(),
                param: param.clone(),
                message,
            })?;
            let params = &mut doc.nodes.get_mut(node).ok_or_else(|| EditError::UnknownNode(node.clone()))?.params;
            Ok(restore_param(node, param, params.insert(param.clone(), value)))
        }
        EditorCommand::ResetParam { node, param } => {
            let schema = schema_of(doc, registry, node)?;
            if schema.param(param).is_none() {
                return Err(EditError::UnknownParam { kind: schema.kind.into(), param: param.clone() });
            }
            let params = &mut doc.nodes.get_mut(node).ok_or_else(|| EditError::UnknownNode(node.clone()))?.params;
            Ok(restore_param(node, param, params.remove(param)))
        }
        EditorCommand::MoveNodes { moves } => {
            if let Some((missing, _)) = moves.iter().find(|(id, _)| !doc.nodes.contains_key(id)) {
                return Err(EditError::UnknownNode(missing.clone()));
            }
            let mut undo = Vec::with_capacity(moves.len());
            for (id, pos) in moves {
                let old = match pos {
                    Some(p) => doc.layout.insert(id.clone(), *p),
                    None => doc.layout.remove(id),
                };
                undo.push((id.clone(), old));
            }
            undo.reverse();
            Ok(EditorCommand::MoveNodes { moves: undo })
        }
        EditorCommand::SetInput { name, target } => {
            if let Some(target) = target {
                let (node, param) = split_endpoint(target).ok_or_else(|| EditError::BadEndpoint(target.clone()))?;
                let schema = schema_of(doc, registry, node)?;
                if schema.param(param).is_none() {
                    return Err(EditError::UnknownParam { kind: schema.kind.into(), param: param.into() });
                }
            }
            let old = match target {
                Some(t) => doc.inputs.insert(name.clone(), t.clone()),
                None => doc.inputs.remove(name),
            };
            Ok(EditorCommand::SetInput { name: name.clone(), target: old })
        }
        EditorCommand::SetDescription { text } => {
            let old = std::mem::replace(&mut doc.description, text.clone());
            Ok(EditorCommand::SetDescription { text: old })
        }
        EditorCommand::Batch(cmds) => {
            let mut undo = Vec::with_capacity(cmds.len());
            for cmd in cmds {
                match apply(doc, registry, cmd) {
                    Ok(inverse) => undo.push(inverse),
                    Err(e) => {
                        // Roll back what was applied, newest first; each inverse held before.
                        for inverse in undo.iter().rev() {
                            let _ = apply(doc, registry, inverse);
                        }
                        return Err(e);
                    }
                }
            }
            undo.reverse();
            Ok(EditorCommand::Batch(undo))
        }
    }
}

fn restore_param(node: &str, param: &str, old: Option<ParamValue>) -> EditorCommand {
    match old {
        Some(value) => EditorCommand::SetParam { node: node.into(), param: param.into(), value },
        None => EditorCommand::ResetParam { node: node.into(), param: param.into() },
    }
}

/// One undoable step: the command that undoes it and a label.
#[derive(Clone, Debug)]
struct Step {
    label: String,
    inverse: EditorCommand,
}

/// Undo and redo stacks over a document, filled by [`History::apply`].
#[derive(Clone, Debug, Default)]
pub struct History {
    undo: Vec<Step>,
    redo: Vec<Step>,
}

impl History {
    /// An empty history.
    pub fn new() -> Self {
        History::default()
    }

    /// Applies `cmd`, records its inverse and clears the redo stack. Returns whether the
    /// document changed (an edit that changes nothing, such as setting a parameter to
    /// the value it has, is not recorded).
    pub fn apply(&mut self, doc: &mut GraphDoc, registry: &Registry, cmd: EditorCommand) -> Result<bool, EditError> {
        let before = doc.clone();
        let inverse = apply(doc, registry, &cmd)?;
        if *doc == before {
            return Ok(false);
        }
        self.undo.push(Step { label: cmd.label(), inverse });
        self.redo.clear();
        Ok(true)
    }

    /// Like [`History::apply`], but when `coalesce` is set and the latest step has the same
    /// label (the same parameter, say) and nothing was undone since, the edit joins that
    /// step: a whole slider drag undoes in one go, back to the value before the drag.
    pub fn apply_coalescing(
        &mut self,
        doc: &mut GraphDoc,
        registry: &Registry,
        cmd: EditorCommand,
        coalesce: bool,
    ) -> Result<bool, EditError> {
        let joins = coalesce && self.redo.is_empty() && self.undo.last().is_some_and(|s| s.label == cmd.label());
        if !joins {
            return self.apply(doc, registry, cmd);
        }
        let before = doc.clone();
        apply(doc, registry, &cmd)?;
        Ok(*doc != before)
    }

    /// Undoes the latest step.
    pub fn undo(&mut self, doc: &mut GraphDoc, registry: &Registry) -> Result<(), EditError> {
        let step = self.undo.pop().ok_or(EditError::NothingTo("undo"))?;
        match apply(doc, registry, &step.inverse) {
            Ok(redo) => {
                self.redo.push(Step { label: step.label, inverse: redo });
                Ok(())
            }
            Err(e) => {
                self.undo.push(step);
                Err(e)
            }
        }
    }

    /// Redoes the latest undone step.
    pub fn redo(&mut self, doc: &mut GraphDoc, registry: &Registry) -> Result<(), EditError> {
        let step = self.redo.pop().ok_or(EditError::NothingTo("redo"))?;
        match apply(doc, registry, &step.inverse) {
            Ok(undo) => {
                self.undo.push(Step { label: step.label, inverse: undo });
                Ok(())
            }
            Err(e) => {
                self.redo.push(step);
                Err(e)
            }
        }
    }

    /// Label of the step [`History::undo`] would undo.
    pub fn undo_label(&self) -> Option<&str> {
        self.undo.last().map(|s| s.label.as_str())
    }

    /// Label of the step [`History::redo`] would redo.
    pub fn redo_label(&self) -> Option<&str> {
        self.redo.last().map(|s| s.label.as_str())
    }

    /// Forgets every step (after opening another file).
    pub fn clear(&mut self) {
        self.undo.clear();
        self.redo.clear();
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::document::{self, to_string};

    fn demo() -> GraphDoc {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        document::load_file(&path).unwrap().doc
    }

    fn cmd_connect(from: &str, to: &str) -> EditorCommand {
        EditorCommand::Connect { from: from.into(), to: to.into() }
    }

    #[test]
    fn fresh_ids_are_readable_and_unique() {
        let mut doc = demo();
        assert_eq!(fresh_node_id(&doc, "clip.trim"), "trim_2");
        assert_eq!(fresh_node_id(&doc, "scalar.constant"), "constant");
        let r = kinegraph_nodes::builtin::registry();
        apply(&mut doc, &r, &EditorCommand::AddNode { id: "trim_2".into(), kind: "clip.trim".into(), pos: (0.0, 0.0) })
            .unwrap();
        assert_eq!(fresh_node_id(&doc, "clip.trim"), "trim_3");
    }

    #[test]
    fn every_command_undoes_to_identical_bytes() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let original = to_string(&doc);
        let mut history = History::new();
        let cmds = vec![
            EditorCommand::AddNode { id: "trim_2".into(), kind: "clip.trim".into(), pos: (10.0, 20.0) },
            cmd_connect("clip.clip", "trim_2.clip"),
            cmd_connect("trim_2.clip", "resample.clip"), // replaces trim.clip → resample.clip
            EditorCommand::SetParam { node: "trim_2".into(), param: "end_secs".into(), value: ParamValue::Int(2) },
            EditorCommand::ResetParam { node: "trim".into(), param: "start_secs".into() },
            EditorCommand::MoveNodes { moves: vec![("clip".into(), Some((5.0, 5.0))), ("trim_2".into(), None)] },
            EditorCommand::SetInput { name: "trim_end".into(), target: Some("trim.end_secs".into()) },
            EditorCommand::SetDescription { text: "edited".into() },
            EditorCommand::Disconnect { from: "mesh.mesh".into(), to: "glb.mesh".into() },
            EditorCommand::RemoveNodes { ids: vec!["clip".into(), "trim".into()] },
        ];
        let mut states = vec![original.clone()];
        for cmd in cmds {
            assert!(history.apply(&mut doc, &r, cmd.clone()).unwrap(), "{cmd:?} changed nothing");
            states.push(to_string(&doc));
        }
        // Removing `clip` dropped its edge and the `clip_path` input.
        assert!(!doc.inputs.contains_key("clip_path"));
        assert!(!doc.edges.iter().any(|e| e.from.starts_with("clip.")));
        for expected in states.iter().rev().skip(1) {
            history.undo(&mut doc, &r).unwrap();
            assert_eq!(&to_string(&doc), expected);
        }
        assert_eq!(history.undo(&mut doc, &r), Err(EditError::NothingTo("undo")));
        for expected in states.iter().skip(1) {
            history.redo(&mut doc, &r).unwrap();
            assert_eq!(&to_string(&doc), expected);
        }
        assert_eq!(history.redo(&mut doc, &r), Err(EditError::NothingTo("redo")));
    }

    #[test]
    fn replacing_a_connection_is_one_step() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let before = to_string(&doc);
        let mut history = History::new();
        history.apply(&mut doc, &r, cmd_connect("clip.clip", "resample.clip")).unwrap();
        let into_resample: Vec<&EdgeDoc> = doc.edges.iter().filter(|e| e.to == "resample.clip").collect();
        assert_eq!(into_resample.len(), 1);
        assert_eq!(into_resample[0].from, "clip.clip");
        history.undo(&mut doc, &r).unwrap();
        assert_eq!(to_string(&doc), before);
    }

    #[test]
    fn refused_connections_say_why_and_change_nothing() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let before = doc.clone();
        let mut history = History::new();
        let err = history.apply(&mut doc, &r, cmd_connect("mesh.mesh", "trim.clip")).unwrap_err();
        assert_eq!(err.to_string(), "mesh.mesh gives a mesh, but trim.clip takes a clip");
        let err = history.apply(&mut doc, &r, cmd_connect("resample.clip", "trim.clip")).unwrap_err();
        assert!(matches!(err, EditError::Cycle { .. }), "{err}");
        let err = history.apply(&mut doc, &r, cmd_connect("trim.clip", "trim.clip")).unwrap_err();
        assert!(matches!(err, EditError::Cycle { .. }), "{err}");
        let err = history.apply(&mut doc, &r, cmd_connect("clip.clip", "trim.clip")).unwrap_err();
        assert!(matches!(err, EditError::AlreadyConnected { .. }), "{err}");
        let err = history.apply(&mut doc, &r, cmd_connect("clip.nope", "trim.clip")).unwrap_err();
        assert_eq!(err.to_string(), "'clip.load' has no output 'nope'");
        let err = history.apply(&mut doc, &r, cmd_connect("trim.clip", "clip.path")).unwrap_err();
        assert!(matches!(err, EditError::UnknownPort { side: "input", .. }), "{err}");
        assert_eq!(doc, before);
        assert_eq!(history.undo_label(), None);
    }

    #[test]
    fn params_are_checked_and_canonicalised() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let set = |v: ParamValue| EditorCommand::SetParam { node: "resample".into(), param: "fps".into(), value: v };
        let err = apply(&mut doc, &r, &set(ParamValue::Float(-1.0))).unwrap_err();
        assert!(matches!(err, EditError::BadValue { .. }), "{err}");
        let err = apply(&mut doc, &r, &set(ParamValue::Text("fast".into()))).unwrap_err();
        assert!(err.to_string().contains("expected a number"), "{err}");
        apply(&mut doc, &r, &set(ParamValue::Int(30))).unwrap();
        assert_eq!(doc.nodes["resample"].params["fps"], ParamValue::Float(30.0));
        let bad = EditorCommand::SetParam { node: "resample".into(), param: "speed".into(), value: ParamValue::Int(1) };
        assert!(matches!(apply(&mut doc, &r, &bad), Err(EditError::UnknownParam { .. })));
    }

    #[test]
    fn no_op_edits_are_not_recorded_and_redo_clears_on_new_edit() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let mut history = History::new();
        let same = EditorCommand::SetParam { node: "resample".into(), param: "fps".into(), value: ParamValue::Int(24) };
        assert!(!history.apply(&mut doc, &r, same).unwrap());
        assert_eq!(history.undo_label(), None);
        history.apply(&mut doc, &r, EditorCommand::SetDescription { text: "a".into() }).unwrap();
        history.undo(&mut doc, &r).unwrap();
        assert_eq!(history.redo_label(), Some("description"));
        history.apply(&mut doc, &r, EditorCommand::SetDescription { text: "b".into() }).unwrap();
        assert_eq!(history.redo_label(), None);
    }

    #[test]
    fn a_drag_is_one_undo_step() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let before = to_string(&doc);
        let mut history = History::new();
        let set = |x: f64| EditorCommand::SetParam {
            node: "trim".into(),
            param: "end_secs".into(),
            value: ParamValue::Float(x),
        };
        history.apply_coalescing(&mut doc, &r, set(0.9), false).unwrap();
        for x in [0.8, 0.7, 0.6] {
            history.apply_coalescing(&mut doc, &r, set(x), true).unwrap();
        }
        assert_eq!(doc.nodes["trim"].params["end_secs"], ParamValue::Float(0.6));
        history.undo(&mut doc, &r).unwrap();
        assert_eq!(to_string(&doc), before);
        assert_eq!(history.undo_label(), None);
        history.redo(&mut doc, &r).unwrap();
        assert_eq!(doc.nodes["trim"].params["end_secs"], ParamValue::Float(0.6));
    }

    #[test]
    fn a_failing_batch_leaves_the_document_untouched() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let before = doc.clone();
        let batch = EditorCommand::Batch(vec![
            EditorCommand::AddNode { id: "c".into(), kind: "scalar.constant".into(), pos: (0.0, 0.0) },
            cmd_connect("c.value", "trim.clip"),
        ]);
        assert!(matches!(apply(&mut doc, &r, &batch), Err(EditError::TypeMismatch { .. })));
        assert_eq!(doc, before);
    }

    #[test]
    fn bad_ids_and_kinds_are_refused() {
        let r = kinegraph_nodes::builtin::registry();
        let mut doc = demo();
        let add = |id: &str, kind: &str| EditorCommand::AddNode { id: id.into(), kind: kind.into(), pos: (0.0, 0.0) };
        assert!(matches!(apply(&mut doc, &r, &add("trim", "clip.trim")), Err(EditError::DuplicateId(_))));
        assert!(matches!(apply(&mut doc, &r, &add("a b", "clip.trim")), Err(EditError::BadId(_))));
        assert!(matches!(apply(&mut doc, &r, &add("a.b", "clip.trim")), Err(EditError::BadId(_))));
        assert!(matches!(apply(&mut doc, &r, &add("x", "clip.nope")), Err(EditError::UnknownKind(_))));
        let remove = EditorCommand::RemoveNodes { ids: vec!["trim".into(), "ghost".into()] };
        assert!(matches!(apply(&mut doc, &r, &remove), Err(EditError::UnknownNode(_))));
        assert_eq!(doc, demo());
    }
}
