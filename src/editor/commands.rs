//! The editor's command reducer: every edit the editor can make to a [`Graph`], applied by
//! a pure function through the graph's own edits (so the editor refuses exactly what
//! `kg check` reports, with the same words) and returning its inverse, and a [`History`]
//! of those inverses for undo and redo.
//!
//! The graph stays the single source of truth: widgets emit [`EditorCommand`]s, the
//! reducer applies them, and views are rebuilt from the graph. Nothing here knows egui.
//!
//! Invariants the reducer keeps (so undo restores byte-identical files):
//! 1. A command either applies completely or leaves the graph untouched.
//! 2. `apply(inverse)` after `apply(cmd)` gives back the graph as it was, hence the same
//!    [`to_string`](crate::document::to_string) bytes.
//! 3. An input port has at most one incoming edge; connecting into an occupied input
//!    replaces the old edge in the same (single-undo) step.

use kinegraph_nodes::node::{ParamValue, Registry};

use crate::graph::{Graph, GraphError, NodeId, ParamPath, PortRef, Removal};

/// One edit of a graph.
#[derive(Clone, Debug, PartialEq)]
pub enum EditorCommand {
    /// Adds a node of `kind` called `id` at canvas position `pos` (see [`fresh_node_id`]).
    AddNode {
        /// New, unused node id.
        id: NodeId,
        /// Registered node kind, e.g. `"clip.trim"`.
        kind: String,
        /// Canvas position.
        pos: (f32, f32),
    },
    /// Renames a node; its wires, position and the graph inputs naming it follow.
    RenameNode {
        /// The node's id.
        from: NodeId,
        /// Its new id (valid and unused).
        to: NodeId,
    },
    /// Bypasses a node (it passes its inputs on instead of running) or lets it run again.
    SetBypass {
        /// The node's id.
        id: NodeId,
        /// Bypassed or not.
        bypass: bool,
    },
    /// Removes nodes with their edges, layout entries and the graph inputs that point at them.
    RemoveNodes {
        /// Ids of existing nodes.
        ids: Vec<NodeId>,
    },
    /// Puts back nodes removed by [`EditorCommand::RemoveNodes`] (its inverse), or pastes.
    RestoreNodes(Removal),
    /// Connects an output to an input, replacing whatever fed that input.
    Connect {
        /// The output.
        from: PortRef,
        /// The input.
        to: PortRef,
    },
    /// Removes one edge.
    Disconnect {
        /// The output.
        from: PortRef,
        /// The input.
        to: PortRef,
    },
    /// Sets a parameter, checked against its schema (range, type, choices).
    SetParam {
        /// The parameter.
        param: ParamPath,
        /// New value.
        value: ParamValue,
    },
    /// Removes a parameter's value so the schema default applies.
    ResetParam {
        /// The parameter.
        param: ParamPath,
    },
    /// Sets canvas positions; `None` removes a node's layout entry.
    MoveNodes {
        /// `(node id, new position)` pairs.
        moves: Vec<(NodeId, Option<(f32, f32)>)>,
    },
    /// Promotes a parameter to a graph input (`Some`) or removes the input.
    SetInput {
        /// Public input name.
        name: String,
        /// The parameter, or `None` to remove.
        target: Option<ParamPath>,
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
        let ids = |ids: &mut dyn Iterator<Item = &NodeId>| ids.map(ToString::to_string).collect::<Vec<_>>().join(", ");
        match self {
            EditorCommand::AddNode { id, .. } => format!("add {id}"),
            EditorCommand::RenameNode { from, to } => format!("rename {from} to {to}"),
            EditorCommand::SetBypass { id, bypass: true } => format!("bypass {id}"),
            EditorCommand::SetBypass { id, bypass: false } => format!("run {id}"),
            EditorCommand::RemoveNodes { ids: removed } => format!("delete {}", ids(&mut removed.iter())),
            EditorCommand::RestoreNodes(removal) => {
                format!("restore {}", ids(&mut removal.nodes.iter().map(|n| &n.id)))
            }
            EditorCommand::Connect { to, .. } => format!("connect {to}"),
            EditorCommand::Disconnect { to, .. } => format!("disconnect {to}"),
            EditorCommand::SetParam { param, .. } => format!("set {param}"),
            EditorCommand::ResetParam { param } => format!("reset {param}"),
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
    /// The edit would break a rule of the graph (the words `kg check` uses).
    #[error(transparent)]
    Graph(#[from] GraphError),
    /// Nothing to undo or redo.
    #[error("nothing to {0}")]
    NothingTo(&'static str),
    /// Pasted text is not a graph fragment.
    #[error("the clipboard holds no graph fragment: {0}")]
    BadFragment(String),
}

/// A fresh, readable node id for a new node of `kind`: the kind's last segment
/// (`"clip.trim"` → `trim`), then `trim_2`, `trim_3`, … until unused.
pub fn fresh_node_id(graph: &Graph, kind: &str) -> NodeId {
    let last = kind.rsplit('.').next().unwrap_or(kind);
    let mut base: String = last.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect();
    if base.is_empty() {
        base = "node".into();
    }
    if !graph.contains(&base) {
        return NodeId::new(base);
    }
    let free = (2..).map(|n| format!("{base}_{n}")).find(|id| !graph.contains(id)).unwrap_or(base);
    NodeId::new(free)
}

/// Applies `cmd` to `graph` and returns the command that undoes it. On error `graph` is
/// left exactly as it was.
pub fn apply(graph: &mut Graph, registry: &Registry, cmd: &EditorCommand) -> Result<EditorCommand, EditError> {
    Ok(match cmd {
        EditorCommand::AddNode { id, kind, pos } => {
            graph.add_node(registry, id.clone(), kind, *pos)?;
            EditorCommand::RemoveNodes { ids: vec![id.clone()] }
        }
        EditorCommand::RenameNode { from, to } => {
            graph.rename_node(from, to.clone())?;
            EditorCommand::RenameNode { from: to.clone(), to: from.clone() }
        }
        EditorCommand::SetBypass { id, bypass } => {
            EditorCommand::SetBypass { id: id.clone(), bypass: graph.set_bypass(id, *bypass)? }
        }
        EditorCommand::RemoveNodes { ids } => EditorCommand::RestoreNodes(graph.remove_nodes(ids)?),
        EditorCommand::RestoreNodes(removal) => {
            graph.restore(removal)?;
            EditorCommand::RemoveNodes { ids: removal.nodes.iter().map(|n| n.id.clone()).collect() }
        }
        EditorCommand::Connect { from, to } => {
            let undo_new = EditorCommand::Disconnect { from: from.clone(), to: to.clone() };
            match graph.connect(registry, from, to)? {
                Some(old) => {
                    EditorCommand::Batch(vec![undo_new, EditorCommand::Connect { from: old.from, to: old.to }])
                }
                None => undo_new,
            }
        }
        EditorCommand::Disconnect { from, to } => {
            graph.disconnect(from, to)?;
            EditorCommand::Connect { from: from.clone(), to: to.clone() }
        }
        EditorCommand::SetParam { param, value } => restore_param(param, graph.set_param(registry, param, value)?),
        EditorCommand::ResetParam { param } => restore_param(param, graph.reset_param(registry, param)?),
        EditorCommand::MoveNodes { moves } => {
            if let Some((missing, _)) = moves.iter().find(|(id, _)| !graph.contains(id.as_str())) {
                return Err(GraphError::UnknownNode { id: missing.clone(), hint: String::new() }.into());
            }
            let mut undo = Vec::with_capacity(moves.len());
            for (id, pos) in moves {
                undo.push((id.clone(), graph.set_position(id, *pos)?));
            }
            undo.reverse();
            EditorCommand::MoveNodes { moves: undo }
        }
        EditorCommand::SetInput { name, target } => {
            let old = graph.set_input(registry, name, target.as_ref())?;
            EditorCommand::SetInput { name: name.clone(), target: old }
        }
        EditorCommand::SetDescription { text } => EditorCommand::SetDescription { text: graph.set_description(text) },
        EditorCommand::Batch(cmds) => {
            let mut undo = Vec::with_capacity(cmds.len());
            for cmd in cmds {
                match apply(graph, registry, cmd) {
                    Ok(inverse) => undo.push(inverse),
                    Err(e) => {
                        // Roll back what was applied, newest first; each inverse held before.
                        for inverse in undo.iter().rev() {
                            let _ = apply(graph, registry, inverse);
                        }
                        return Err(e);
                    }
                }
            }
            undo.reverse();
            EditorCommand::Batch(undo)
        }
    })
}

fn restore_param(param: &ParamPath, old: Option<ParamValue>) -> EditorCommand {
    match old {
        Some(value) => EditorCommand::SetParam { param: param.clone(), value },
        None => EditorCommand::ResetParam { param: param.clone() },
    }
}

/// One undoable step: the command that undoes it and a label.
#[derive(Clone, Debug)]
struct Step {
    label: String,
    inverse: EditorCommand,
}

/// Undo and redo stacks over a graph, filled by [`History::apply`].
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
    pub fn apply(&mut self, graph: &mut Graph, registry: &Registry, cmd: EditorCommand) -> Result<bool, EditError> {
        let before = graph.clone();
        let inverse = apply(graph, registry, &cmd)?;
        if *graph == before {
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
        graph: &mut Graph,
        registry: &Registry,
        cmd: EditorCommand,
        coalesce: bool,
    ) -> Result<bool, EditError> {
        let joins = coalesce && self.redo.is_empty() && self.undo.last().is_some_and(|s| s.label == cmd.label());
        if !joins {
            return self.apply(graph, registry, cmd);
        }
        let before = graph.clone();
        apply(graph, registry, &cmd)?;
        Ok(*graph != before)
    }

    /// Undoes the latest step.
    pub fn undo(&mut self, graph: &mut Graph, registry: &Registry) -> Result<(), EditError> {
        let step = self.undo.pop().ok_or(EditError::NothingTo("undo"))?;
        match apply(graph, registry, &step.inverse) {
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
    pub fn redo(&mut self, graph: &mut Graph, registry: &Registry) -> Result<(), EditError> {
        let step = self.redo.pop().ok_or(EditError::NothingTo("redo"))?;
        match apply(graph, registry, &step.inverse) {
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
    use crate::document;
    use crate::graph::GraphFile;

    fn demo() -> Graph {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        GraphFile::load(&path).unwrap().graph
    }

    fn text(graph: &Graph) -> String {
        document::to_string(&graph.to_doc())
    }

    fn port(text: &str) -> PortRef {
        PortRef::parse(text).unwrap()
    }

    fn param(text: &str) -> ParamPath {
        ParamPath::parse(text).unwrap()
    }

    fn cmd_connect(from: &str, to: &str) -> EditorCommand {
        EditorCommand::Connect { from: port(from), to: port(to) }
    }

    fn graph_error(result: Result<impl std::fmt::Debug, EditError>) -> GraphError {
        match result {
            Err(EditError::Graph(e)) => e,
            other => panic!("expected a graph rule to refuse, got {other:?}"),
        }
    }

    #[test]
    fn fresh_ids_are_readable_and_unique() {
        let mut graph = demo();
        assert_eq!(fresh_node_id(&graph, "clip.trim").as_str(), "trim_2");
        assert_eq!(fresh_node_id(&graph, "scalar.constant").as_str(), "constant");
        let r = kinegraph_nodes::builtin::registry();
        apply(
            &mut graph,
            &r,
            &EditorCommand::AddNode { id: "trim_2".into(), kind: "clip.trim".into(), pos: (0.0, 0.0) },
        )
        .unwrap();
        assert_eq!(fresh_node_id(&graph, "clip.trim").as_str(), "trim_3");
    }

    #[test]
    fn every_command_undoes_to_identical_bytes() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let original = text(&graph);
        let mut history = History::new();
        let cmds = vec![
            EditorCommand::AddNode { id: "trim_2".into(), kind: "clip.trim".into(), pos: (10.0, 20.0) },
            cmd_connect("clip.clip", "trim_2.clip"),
            cmd_connect("trim_2.clip", "resample.clip"), // replaces trim.clip → resample.clip
            EditorCommand::SetParam { param: param("trim_2.end_secs"), value: ParamValue::Int(2) },
            EditorCommand::ResetParam { param: param("trim.start_secs") },
            EditorCommand::MoveNodes { moves: vec![("clip".into(), Some((5.0, 5.0))), ("trim_2".into(), None)] },
            EditorCommand::SetInput { name: "trim_end".into(), target: Some(param("trim.end_secs")) },
            EditorCommand::SetDescription { text: "edited".into() },
            EditorCommand::Disconnect { from: port("mesh.mesh"), to: port("glb.mesh") },
            EditorCommand::RemoveNodes { ids: vec!["clip".into(), "trim".into()] },
        ];
        let mut states = vec![original.clone()];
        for cmd in cmds {
            assert!(history.apply(&mut graph, &r, cmd.clone()).unwrap(), "{cmd:?} changed nothing");
            states.push(text(&graph));
        }
        // Removing `clip` dropped its edge and the `clip_path` input.
        assert!(!graph.inputs().contains_key("clip_path"));
        assert!(!graph.edges().any(|e| e.from.node.as_str() == "clip"));
        for expected in states.iter().rev().skip(1) {
            history.undo(&mut graph, &r).unwrap();
            assert_eq!(&text(&graph), expected);
        }
        assert_eq!(history.undo(&mut graph, &r), Err(EditError::NothingTo("undo")));
        for expected in states.iter().skip(1) {
            history.redo(&mut graph, &r).unwrap();
            assert_eq!(&text(&graph), expected);
        }
        assert_eq!(history.redo(&mut graph, &r), Err(EditError::NothingTo("redo")));
    }

    #[test]
    fn replacing_a_connection_is_one_step() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let before = text(&graph);
        let mut history = History::new();
        history.apply(&mut graph, &r, cmd_connect("clip.clip", "resample.clip")).unwrap();
        let into_resample: Vec<_> = graph.edges().filter(|e| e.to == port("resample.clip")).collect();
        assert_eq!(into_resample.len(), 1);
        assert_eq!(into_resample[0].from, port("clip.clip"));
        history.undo(&mut graph, &r).unwrap();
        assert_eq!(text(&graph), before);
    }

    #[test]
    fn refused_connections_say_why_and_change_nothing() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let before = graph.clone();
        let mut history = History::new();
        let err = history.apply(&mut graph, &r, cmd_connect("mesh.mesh", "trim.clip")).unwrap_err();
        assert_eq!(err.to_string(), "type mismatch: mesh.mesh gives a mesh, but trim.clip takes a clip");
        let err = graph_error(history.apply(&mut graph, &r, cmd_connect("resample.clip", "trim.clip")));
        assert!(matches!(err, GraphError::WouldCycle { .. }), "{err}");
        let err = graph_error(history.apply(&mut graph, &r, cmd_connect("trim.clip", "trim.clip")));
        assert!(matches!(err, GraphError::WouldCycle { .. }), "{err}");
        let err = graph_error(history.apply(&mut graph, &r, cmd_connect("clip.clip", "trim.clip")));
        assert!(matches!(err, GraphError::AlreadyConnected { .. }), "{err}");
        let err = history.apply(&mut graph, &r, cmd_connect("clip.nope", "trim.clip")).unwrap_err();
        assert_eq!(err.to_string(), "'clip.load' has no output 'nope'");
        let err = graph_error(history.apply(&mut graph, &r, cmd_connect("trim.clip", "clip.path")));
        assert!(matches!(err, GraphError::UnknownPort { side: crate::graph::Side::Input, .. }), "{err}");
        assert_eq!(graph, before);
        assert_eq!(history.undo_label(), None);
    }

    #[test]
    fn params_are_checked_and_canonicalised() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let set = |v: ParamValue| EditorCommand::SetParam { param: param("resample.fps"), value: v };
        let err = graph_error(apply(&mut graph, &r, &set(ParamValue::Float(-1.0))));
        assert!(matches!(err, GraphError::BadValue { .. }), "{err}");
        let err = apply(&mut graph, &r, &set(ParamValue::Text("fast".into()))).unwrap_err();
        assert!(err.to_string().contains("expected a number"), "{err}");
        apply(&mut graph, &r, &set(ParamValue::Int(30))).unwrap();
        assert_eq!(graph.node("resample").unwrap().params["fps"], ParamValue::Float(30.0));
        let bad = EditorCommand::SetParam { param: param("resample.speed"), value: ParamValue::Int(1) };
        assert!(matches!(graph_error(apply(&mut graph, &r, &bad)), GraphError::UnknownParam { .. }));
    }

    #[test]
    fn no_op_edits_are_not_recorded_and_redo_clears_on_new_edit() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let mut history = History::new();
        let same = EditorCommand::SetParam { param: param("resample.fps"), value: ParamValue::Int(24) };
        assert!(!history.apply(&mut graph, &r, same).unwrap());
        assert_eq!(history.undo_label(), None);
        history.apply(&mut graph, &r, EditorCommand::SetDescription { text: "a".into() }).unwrap();
        history.undo(&mut graph, &r).unwrap();
        assert_eq!(history.redo_label(), Some("description"));
        history.apply(&mut graph, &r, EditorCommand::SetDescription { text: "b".into() }).unwrap();
        assert_eq!(history.redo_label(), None);
    }

    #[test]
    fn a_drag_is_one_undo_step() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let before = text(&graph);
        let mut history = History::new();
        let set = |x: f64| EditorCommand::SetParam { param: param("trim.end_secs"), value: ParamValue::Float(x) };
        history.apply_coalescing(&mut graph, &r, set(0.9), false).unwrap();
        for x in [0.8, 0.7, 0.6] {
            history.apply_coalescing(&mut graph, &r, set(x), true).unwrap();
        }
        assert_eq!(graph.node("trim").unwrap().params["end_secs"], ParamValue::Float(0.6));
        history.undo(&mut graph, &r).unwrap();
        assert_eq!(text(&graph), before);
        assert_eq!(history.undo_label(), None);
        history.redo(&mut graph, &r).unwrap();
        assert_eq!(graph.node("trim").unwrap().params["end_secs"], ParamValue::Float(0.6));
    }

    #[test]
    fn a_failing_batch_leaves_the_graph_untouched() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let before = graph.clone();
        let batch = EditorCommand::Batch(vec![
            EditorCommand::AddNode { id: "c".into(), kind: "scalar.constant".into(), pos: (0.0, 0.0) },
            cmd_connect("c.value", "trim.clip"),
        ]);
        assert!(matches!(graph_error(apply(&mut graph, &r, &batch)), GraphError::TypeMismatch { .. }));
        assert_eq!(graph, before);
    }

    #[test]
    fn bad_ids_and_kinds_are_refused_by_the_id_rule_kg_check_uses() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        let add = |id: &str, kind: &str| EditorCommand::AddNode { id: id.into(), kind: kind.into(), pos: (0.0, 0.0) };
        assert!(matches!(graph_error(apply(&mut graph, &r, &add("trim", "clip.trim"))), GraphError::DuplicateId(_)));
        assert!(matches!(graph_error(apply(&mut graph, &r, &add("a b", "clip.trim"))), GraphError::BadNodeId { .. }));
        assert!(matches!(graph_error(apply(&mut graph, &r, &add(".a", "clip.trim"))), GraphError::BadNodeId { .. }));
        assert!(matches!(graph_error(apply(&mut graph, &r, &add("x", "clip.nope"))), GraphError::UnknownKind { .. }));
        let remove = EditorCommand::RemoveNodes { ids: vec!["trim".into(), "ghost".into()] };
        assert!(matches!(graph_error(apply(&mut graph, &r, &remove)), GraphError::UnknownNode { .. }));
        assert_eq!(graph, demo());
    }

    #[test]
    fn a_dotted_node_id_is_edited_like_any_other() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        apply(
            &mut graph,
            &r,
            &EditorCommand::AddNode { id: "rig.left".into(), kind: "clip.trim".into(), pos: (0.0, 0.0) },
        )
        .unwrap();
        apply(&mut graph, &r, &cmd_connect("clip.clip", "rig.left.clip")).unwrap();
        apply(&mut graph, &r, &cmd_connect("rig.left.clip", "resample.clip")).unwrap();
        assert!(graph.has_edge(&port("rig.left.clip"), &port("resample.clip")));
        let reread = Graph::from_doc(&document::parse(&text(&graph), "x.ron".as_ref()).unwrap().doc).unwrap();
        assert_eq!(reread, graph, "the dotted id survives a save and a load");
    }

    /// A rename carries the graph inputs that name the node, and its undo gives the same
    /// file back; a taken or malformed id is refused with the graph unchanged.
    #[test]
    fn a_rename_carries_inputs_and_undoes_exactly() {
        let r = kinegraph_nodes::builtin::registry();
        let mut graph = demo();
        apply(&mut graph, &r, &EditorCommand::SetInput { name: "end".into(), target: Some(param("trim.end_secs")) })
            .unwrap();
        let before = text(&graph);
        let rename = |to: &str| EditorCommand::RenameNode { from: "trim".into(), to: to.into() };
        assert!(matches!(graph_error(apply(&mut graph, &r, &rename("resample"))), GraphError::DuplicateId(_)));
        assert!(matches!(graph_error(apply(&mut graph, &r, &rename("a b"))), GraphError::BadNodeId { .. }));
        assert_eq!(text(&graph), before);
        let undo = apply(&mut graph, &r, &rename("cut")).unwrap();
        assert_eq!(graph.inputs()["end"], param("cut.end_secs"));
        assert!(graph.has_edge(&port("cut.clip"), &port("resample.clip")));
        apply(&mut graph, &r, &undo).unwrap();
        assert_eq!(text(&graph), before);
    }
}
