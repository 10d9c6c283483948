//! The editor window (`kg edit`): menu bar, canvas, parameter panel, viewport and status
//! bar around one document, its undo history and the evaluation worker.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use egui::{Key, Modifiers, RichText, Ui};
use kinegraph_nodes::model::{Clip, Contacts};
use kinegraph_nodes::node::PROPS_PORT;
use kinegraph_nodes::node::{Registry, Value};

use super::canvas::{Badge, Canvas, Face, Faces, Marks};
use super::commands::{EditError, EditorCommand, History};
use super::files::{self, Autosave, RecentFiles, default_settings_dir};
use super::fragment;
use super::panel::{self, PanelState};
use super::results::{self, ResultsState};
use super::viewport::{Motion, ShownMesh, SmokeDrawn, Viewport};
use super::worker::{Worker, WorkerMessage};
use crate::document;
use crate::engine::{Engine, GraphErrors, NodeStatus, RunReport};
use crate::graph::{Graph, GraphFile, NodeId, ParamPath, PortRef, Side};

/// What the file dialog is open for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Prompt {
    Open,
    SaveAs,
    /// The file to collapse the selection into.
    Collapse,
}

/// How often unsaved edits are autosaved (seconds).
const AUTOSAVE_SECS: f64 = 30.0;

/// The editor: one document, its history, views and the evaluation worker.
pub struct EditorApp {
    registry: Registry,
    graph: Graph,
    path: Option<PathBuf>,
    /// `to_string` of the document as last opened or saved: dirty is "differs from this".
    clean_text: String,
    dirty: bool,
    history: History,
    /// The faces of the graph's subgraph nodes, read from their files.
    faces: Faces,
    /// The subgraph nodes and files `faces` was read for; none to read them afresh.
    face_files: Option<Vec<(NodeId, String)>>,
    /// The graphs the document was opened from as a subgraph, outermost first.
    parents: Vec<Parent>,
    /// Going back from a subgraph with unsaved edits: the question is open.
    leaving: bool,
    canvas: Canvas,
    worker: Worker,
    badges: BTreeMap<String, Badge>,
    report: Option<RunReport>,
    /// Problems that name no node (graph inputs), from the latest validation.
    graph_problems: Vec<String>,
    /// The selection, one model for the canvas highlight, the panel and every edit of the
    /// selection; its last node is the active one, whose panel is shown.
    selection: Vec<String>,
    /// Snarl's own selection as last seen: a change there is a box-select or shift-click.
    snarl_selection: Vec<String>,
    /// The node with the display flag: the viewport plays it whatever is selected.
    displayed: Option<String>,
    /// The last motion the viewport played, with its node: kept on show, marked stale,
    /// while that node has no result (an error, a block, an edit evaluating).
    last_shown: Option<(String, Motion)>,
    panel: PanelState,
    results: ResultsState,
    viewport: Viewport,
    message: Option<(String, bool)>,
    refusal: Option<(String, f64)>,
    /// The file dialog and what it is open for.
    dialog: egui_file_dialog::FileDialog,
    prompt: Option<Prompt>,
    /// The dialog picking an input file or folder for a parameter (any file type), and the
    /// parameter.
    browse_dialog: egui_file_dialog::FileDialog,
    browsing: Option<ParamPath>,
    /// Recent files and autosaves live here.
    settings_dir: PathBuf,
    recent: RecentFiles,
    /// Editor time of the last autosave, and the text it wrote.
    autosaved: (f64, String),
    /// Unsaved work found from an earlier session, offered back to the user.
    recovery: Option<Autosave>,
    title: String,
    frame_ms: f32,
    /// When the newest evaluation was asked for, and how long (wall, seconds) the last
    /// finished one took from that moment: what the user waited, cache hits and queueing
    /// included (the report's own time counts the nodes only).
    submitted: Instant,
    waited_secs: Option<f64>,
    /// The last fragment copied in the editor (the system clipboard gets it too).
    clipboard: Option<String>,
}

impl EditorApp {
    /// An editor on `path` (or an empty graph) keeping recent files and autosaves in the
    /// user's settings folder (see [`default_settings_dir`]); `ctx` is woken by the worker.
    pub fn new(ctx: &egui::Context, path: Option<&Path>) -> Self {
        Self::with_settings_dir(ctx, path, default_settings_dir())
    }

    /// An editor keeping recent files and autosaves in `settings_dir`.
    pub fn with_settings_dir(ctx: &egui::Context, path: Option<&Path>, settings_dir: PathBuf) -> Self {
        Self::with_engine(ctx, path, settings_dir, Engine::new(kinegraph_nodes::builtin::registry()))
    }

    /// An editor evaluating with `engine` (e.g. one with a cache folder).
    pub fn with_engine(ctx: &egui::Context, path: Option<&Path>, settings_dir: PathBuf, engine: Engine) -> Self {
        let wake_ctx = ctx.clone();
        let worker = Worker::spawn(engine, Arc::new(move || wake_ctx.request_repaint()));
        let mut app = EditorApp {
            registry: kinegraph_nodes::builtin::registry(),
            graph: Graph::new(),
            path: None,
            clean_text: document::to_string(&Graph::new().to_doc()),
            dirty: false,
            history: History::new(),
            faces: Faces::new(),
            face_files: None,
            parents: Vec::new(),
            leaving: false,
            canvas: Canvas::default(),
            worker,
            badges: BTreeMap::new(),
            report: None,
            graph_problems: Vec::new(),
            selection: Vec::new(),
            snarl_selection: Vec::new(),
            displayed: None,
            last_shown: None,
            panel: PanelState::default(),
            results: ResultsState::default(),
            viewport: Viewport::default(),
            message: None,
            refusal: None,
            dialog: egui_file_dialog::FileDialog::new()
                .add_file_filter_extensions("graphs (.ron)", vec!["ron"])
                .default_file_filter("graphs (.ron)")
                .add_save_extension("graph", "ron")
                .default_save_extension("graph"),
            prompt: None,
            browse_dialog: egui_file_dialog::FileDialog::new(),
            browsing: None,
            recent: RecentFiles::load(&settings_dir),
            settings_dir,
            autosaved: (0.0, String::new()),
            recovery: None,
            title: String::new(),
            frame_ms: 0.0,
            submitted: Instant::now(),
            waited_secs: None,
            clipboard: None,
        };
        match path {
            Some(p) => app.open(p),
            None => {
                app.document_replaced();
                app.recovery = files::recoverable(&app.settings_dir, None, &app.clean_text);
            }
        }
        app
    }

    /// The graph being edited.
    pub fn graph(&self) -> &Graph {
        &self.graph
    }

    /// The graph being edited in its file form, as Save would write it.
    pub fn doc(&self) -> document::GraphDoc {
        self.graph.to_doc()
    }

    /// The file the document is saved to, if any.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// True when the document differs from the file.
    pub fn is_dirty(&self) -> bool {
        self.dirty
    }

    /// The node whose panel is shown.
    pub fn selected(&self) -> Option<&str> {
        self.selection.last().map(String::as_str)
    }

    /// Shows node `id`'s panel (as clicking it on the canvas does).
    pub fn select(&mut self, id: Option<&str>) {
        self.selection = id.filter(|id| self.graph.contains(id)).map(str::to_string).into_iter().collect();
    }

    /// Fits the whole graph in the canvas (Home; also done when a graph is opened).
    pub fn frame_all(&mut self) {
        self.canvas.frame(&[]);
    }

    /// Fits the selection in the canvas (F), or the whole graph when nothing is selected.
    pub fn frame_selection(&mut self) {
        self.canvas.frame(&self.selection);
    }

    /// Where a point of the canvas (graph coordinates, as in a graph file's `layout`) is on
    /// screen, as last drawn.
    pub fn canvas_to_screen(&self, pos: (f32, f32)) -> egui::Pos2 {
        self.canvas.to_screen(egui::Pos2::new(pos.0, pos.1))
    }

    /// Where a node's pin was drawn last, on screen.
    pub fn pin_on_screen(&self, port: &PortRef, side: Side) -> Option<egui::Pos2> {
        self.canvas.pin_on_screen(&self.graph, &self.registry, &self.faces, port, side)
    }

    /// Node `id`'s area on screen and the canvas' area, as last drawn.
    pub fn node_on_screen(&self, id: &str) -> Option<(egui::Rect, egui::Rect)> {
        Some((self.canvas.node_rect(id)?, self.canvas.rect()?))
    }

    /// How many evaluations the editor has asked for since it opened (one per edit that
    /// changed the document).
    pub fn evaluations_requested(&self) -> u64 {
        self.worker.latest_request()
    }

    /// The latest evaluation's report (outputs included), if one came in.
    pub fn report(&self) -> Option<&RunReport> {
        self.report.as_ref()
    }

    /// The time the viewport shows (seconds) and whether it is playing.
    pub fn viewport_time(&self) -> (f64, bool) {
        (self.viewport.time_secs(), self.viewport.is_playing())
    }

    /// The foot contacts the viewport shows with its clip, if any.
    pub fn viewport_contacts(&self) -> Option<&Contacts> {
        self.viewport.contacts()
    }

    /// The bands (phases, stages) shaded behind the curve plot of `node`'s output `port`
    /// when the panel last drew it.
    pub fn plot_bands(&self, node: &str, port: &str) -> Option<&[results::Band]> {
        self.results.bands(node, port)
    }

    /// The smoke frame the viewport drew last and its particles on screen, if it drew smoke.
    pub fn viewport_smoke(&self) -> Option<SmokeDrawn> {
        self.viewport.smoke_drawn()
    }

    /// How many triangles of props (a stool) the viewport filled in its last draw.
    pub fn viewport_props(&self) -> usize {
        self.viewport.props_drawn()
    }

    /// Where the viewport last drew the centre of mass at its time (screen), if it did.
    pub fn viewport_com(&self) -> Option<egui::Pos2> {
        self.viewport.com_drawn()
    }

    /// Over the canvas the plain mouse wheel zooms at the pointer, as in other node editors
    /// (egui's canvas zooms on Ctrl+wheel and pans on the wheel): wheel events over the
    /// canvas get that modifier before egui reads them. Elsewhere the wheel scrolls.
    pub fn wheel_zooms_canvas(&self, ctx: &egui::Context, raw: &mut egui::RawInput) {
        let Some(canvas) = self.canvas.rect() else { return };
        let mut pointer = ctx.input(|i| i.pointer.latest_pos());
        for event in &mut raw.events {
            match event {
                egui::Event::PointerMoved(pos) => pointer = Some(*pos),
                egui::Event::MouseWheel { modifiers, .. }
                    if modifiers.is_none() && pointer.is_some_and(|p| canvas.contains(p)) =>
                {
                    *modifiers = Modifiers::COMMAND;
                }
                _ => {}
            }
        }
    }

    /// The state badge text of node `id` (`"ok"`, `"error"`, …).
    pub fn node_state(&self, id: &str) -> &'static str {
        self.badges.get(id).map_or("idle", |b| b.label().0)
    }

    /// The status-bar message, if any, and whether it is an error.
    pub fn message(&self) -> Option<(&str, bool)> {
        self.message.as_ref().map(|(m, e)| (m.as_str(), *e))
    }

    /// Applies an edit through the reducer and history, as every widget does.
    pub fn edit(&mut self, cmd: EditorCommand) -> Result<bool, EditError> {
        self.edit_coalescing(cmd, false)
    }

    fn edit_coalescing(&mut self, cmd: EditorCommand, coalesce: bool) -> Result<bool, EditError> {
        let renamed = match &cmd {
            EditorCommand::RenameNode { from, to } => Some((from.to_string(), to.to_string())),
            _ => None,
        };
        let result = self
            .check_subgraph_wires(&cmd)
            .and_then(|()| self.history.apply_coalescing(&mut self.graph, &self.registry, cmd, coalesce));
        // A renamed node stays selected and displayed under its new name.
        if let (Ok(true), Some((from, to))) = (&result, renamed) {
            for id in self.selection.iter_mut().chain(self.displayed.as_mut()) {
                if *id == from {
                    id.clone_from(&to);
                }
            }
        }
        match &result {
            Ok(true) => self.document_changed(),
            Ok(false) => {}
            Err(e) => self.message = Some((e.to_string(), true)),
        }
        result
    }

    /// A wire to or from a subgraph node must fit the port its file shows (the graph's own
    /// rules leave those ports to the file): refused here with the words a run would use.
    fn check_subgraph_wires(&self, cmd: &EditorCommand) -> Result<(), EditError> {
        match cmd {
            EditorCommand::Connect { from, to } => {
                Ok(crate::engine::check_face_types(&self.graph, &self.registry, &self.faces, from, to)?)
            }
            EditorCommand::Batch(cmds) => cmds.iter().try_for_each(|c| self.check_subgraph_wires(c)),
            _ => Ok(()),
        }
    }

    /// The value node `id`'s output `port` gave in the latest evaluation, as the panel and
    /// the viewport show it (a subgraph node's through the port its file shows).
    pub fn output(&self, id: &str, port: &str) -> Option<&Value> {
        self.output_value(&PortRef::new(id, port))
    }

    /// The selected nodes (clicked, box-selected, shift-clicked, pasted or added), which
    /// the canvas highlights and Delete, Copy, Cut and Duplicate act on.
    pub fn selection(&self) -> Vec<String> {
        self.selection.clone()
    }

    /// Copies the selection as a graph fragment (see [`fragment`]); returns its text.
    pub fn copy_selection(&mut self) -> Option<String> {
        let text = fragment::copy(&self.graph, &self.selection())?;
        self.message = Some((format!("copied {}", self.selection().join(", ")), false));
        self.clipboard = Some(text.clone());
        Some(text)
    }

    /// Pastes a graph fragment as one undoable edit and selects the pasted nodes.
    pub fn paste_text(&mut self, text: &str) {
        match fragment::paste(&self.graph, &self.registry, text) {
            Ok((cmd, ids)) => {
                if self.edit(cmd).is_ok() {
                    let names: Vec<String> = ids.iter().map(ToString::to_string).collect();
                    self.message = Some((format!("pasted {}", names.join(", ")), false));
                    self.selection = names;
                }
            }
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    /// Pastes a copy of the selection beside it (the system clipboard is left alone).
    pub fn duplicate_selection(&mut self) {
        if let Some(text) = fragment::copy(&self.graph, &self.selection()) {
            self.paste_text(&text);
        }
    }

    /// Deletes the selection as one undoable edit.
    pub fn delete_selection(&mut self) {
        let ids = self.selection();
        if !ids.is_empty() {
            let _ = self.edit(EditorCommand::RemoveNodes { ids: ids.into_iter().map(NodeId::from).collect() });
        }
    }

    /// Bypasses the selected nodes, or lets them run again when all of them are bypassed:
    /// one undo step. Subgraph nodes are left as they are (their file's nodes can be).
    pub fn toggle_bypass_selection(&mut self) {
        let ids: Vec<NodeId> = self
            .selection()
            .into_iter()
            .map(NodeId::from)
            .filter(|id| self.graph.node(id.as_str()).is_some_and(|n| n.kind != document::SUBGRAPH_KIND))
            .collect();
        let bypass = !ids.iter().all(|id| self.graph.node(id.as_str()).is_some_and(|n| n.bypass));
        let commands: Vec<EditorCommand> = ids.into_iter().map(|id| EditorCommand::SetBypass { id, bypass }).collect();
        if !commands.is_empty() {
            let _ = self.edit(EditorCommand::Batch(commands));
        }
    }

    /// Moves the selection into a new subgraph file `file` (never one that exists) and puts
    /// a node using it in its place, wired as the selection was: one undo step (the file
    /// stays when it is undone).
    pub fn collapse_selection(&mut self, file: &Path) {
        if file.exists() {
            self.message = Some((format!("{} exists: collapse into a new file", file.display()), true));
            return;
        }
        let ids: Vec<NodeId> = self.selection.iter().map(|s| NodeId::from(s.as_str())).collect();
        let stem = file.file_stem().map_or("subgraph".into(), |s| s.to_string_lossy().into_owned());
        let id = super::commands::fresh_node_id(&self.graph, &stem);
        let collapsed =
            super::collapse::collapse(&self.graph, &self.registry, &ids, id.clone(), &self.base_dir(), file);
        let done = collapsed.map_err(|e| e.to_string()).and_then(|c| {
            document::save_file(&c.file.to_doc(), file).map_err(|e| e.to_string())?;
            Ok(c.command)
        });
        match done {
            Ok(command) => {
                if self.edit(command).is_ok() {
                    self.selection = vec![id.to_string()];
                    self.message = Some((format!("collapsed into {} ({})", id, file.display()), false));
                }
            }
            Err(e) => self.message = Some((format!("cannot collapse: {e}"), true)),
        }
    }

    /// Undoes the latest edit.
    pub fn undo(&mut self) {
        match self.history.undo(&mut self.graph, &self.registry) {
            Ok(()) => self.document_changed(),
            Err(e) => self.message = Some((e.to_string(), false)),
        }
    }

    /// Redoes the latest undone edit.
    pub fn redo(&mut self) {
        match self.history.redo(&mut self.graph, &self.registry) {
            Ok(()) => self.document_changed(),
            Err(e) => self.message = Some((e.to_string(), false)),
        }
    }

    /// Opens a graph file, replacing the document (and forgetting the history).
    pub fn open(&mut self, path: &Path) {
        if self.inside_subgraph() {
            return;
        }
        match GraphFile::load(path) {
            Ok(loaded) => {
                self.graph = loaded.graph;
                self.path = Some(path.to_path_buf());
                self.clean_text = document::to_string(&self.graph.to_doc());
                self.history.clear();
                self.message = Some((format!("opened {}", path.display()), false));
                self.document_replaced();
                self.remember(path);
                self.recovery = files::recoverable(&self.settings_dir, Some(path), &self.clean_text);
            }
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    /// Saves to the current file. Without edits since the last open or save nothing is
    /// written, so the file keeps every byte.
    pub fn save(&mut self) {
        match self.path.clone() {
            None => self.open_dialog(Prompt::SaveAs),
            Some(_) if !self.dirty => self.message = Some(("no changes to save".into(), false)),
            Some(path) => self.save_as(&path),
        }
    }

    /// Saves to `path` (atomically) and makes it the current file.
    pub fn save_as(&mut self, path: &Path) {
        match document::save_file(&self.graph.to_doc(), path) {
            Ok(()) => {
                files::discard_autosave(&self.settings_dir, self.path.as_deref());
                self.path = Some(path.to_path_buf());
                self.clean_text = document::to_string(&self.graph.to_doc());
                self.dirty = false;
                self.message = Some((format!("saved {}", path.display()), false));
                self.remember(path);
            }
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    /// Puts `path` first in the recent files (a settings folder that cannot be written
    /// costs the list, not the edit: the status bar says so).
    fn remember(&mut self, path: &Path) {
        if let Err(e) = self.recent.touch(&self.settings_dir, path) {
            self.message = Some((format!("recent files not saved: {e}"), true));
        }
    }

    /// Writes the unsaved document to its autosave now (also done every 30 s,
    /// `AUTOSAVE_SECS`, while there are unsaved edits, and when the window closes).
    pub fn autosave_now(&mut self) {
        // The graphs a subgraph was opened from keep their unsaved edits too.
        for parent in &self.parents {
            let text = document::to_string(&parent.graph.to_doc());
            if text != parent.clean_text
                && let Err(e) = files::write_autosave(&self.settings_dir, parent.path.as_deref(), &text)
            {
                self.message = Some((format!("autosave failed: {e}"), true));
            }
        }
        if !self.dirty {
            return;
        }
        let text = document::to_string(&self.graph.to_doc());
        if text == self.autosaved.1 {
            return;
        }
        match files::write_autosave(&self.settings_dir, self.path.as_deref(), &text) {
            Ok(()) => self.autosaved.1 = text,
            Err(e) => self.message = Some((format!("autosave failed: {e}"), true)),
        }
    }

    fn autosave_tick(&mut self, ctx: &egui::Context) {
        let now = ctx.input(|i| i.time);
        if self.dirty && now - self.autosaved.0 >= AUTOSAVE_SECS {
            self.autosaved.0 = now;
            self.autosave_now();
        }
        if self.dirty {
            ctx.request_repaint_after(std::time::Duration::from_secs_f64(AUTOSAVE_SECS));
        }
    }

    fn open_dialog(&mut self, prompt: Prompt) {
        if let Some(dir) = self.path.as_deref().and_then(Path::parent) {
            self.dialog.config_mut().initial_directory = std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf());
        }
        match prompt {
            Prompt::Open => self.dialog.pick_file(),
            Prompt::SaveAs | Prompt::Collapse => self.dialog.save_file(),
        }
        self.prompt = Some(prompt);
    }

    fn file_dialog(&mut self, ctx: &egui::Context) {
        let Some(prompt) = self.prompt else { return };
        self.dialog.update(ctx);
        if let Some(path) = self.dialog.take_picked() {
            self.prompt = None;
            match prompt {
                Prompt::Open => self.open(&path),
                Prompt::SaveAs => self.save_as(&path),
                Prompt::Collapse => self.collapse_selection(&path),
            }
        } else if !matches!(self.dialog.state(), egui_file_dialog::DialogState::Open) {
            self.prompt = None;
        }
    }

    /// Opens the browse dialog for an input file or folder parameter, in the folder its
    /// current value is in (else the graph's).
    fn browse(&mut self, param: ParamPath, folder: bool) {
        let current = self.graph.node(param.node.as_str()).and_then(|n| match n.params.get(&param.param) {
            Some(kinegraph_nodes::node::ParamValue::Text(t)) => Some(self.base_dir().join(t)),
            _ => None,
        });
        let dir = current.as_deref().and_then(|p| if folder { Some(p) } else { p.parent() }).map(Path::to_path_buf);
        let dir = dir.filter(|d| d.is_dir()).unwrap_or_else(|| self.base_dir());
        self.browse_dialog.config_mut().initial_directory = std::path::absolute(&dir).unwrap_or(dir);
        if folder {
            self.browse_dialog.pick_directory();
        } else {
            self.browse_dialog.pick_file();
        }
        self.browsing = Some(param);
    }

    /// The browse dialog: a picked path is set relative to the graph's folder.
    fn browse_dialog(&mut self, ctx: &egui::Context) {
        let Some(param) = self.browsing.clone() else { return };
        self.browse_dialog.update(ctx);
        if let Some(path) = self.browse_dialog.take_picked() {
            self.browsing = None;
            self.set_path_param(param, &path);
        } else if !matches!(self.browse_dialog.state(), egui_file_dialog::DialogState::Open) {
            self.browsing = None;
        }
    }

    /// Sets a file or folder parameter to `path`, written relative to the graph's folder (as
    /// graph files keep them, so the graph moves with its data).
    pub fn set_path_param(&mut self, param: ParamPath, path: &Path) {
        let text = crate::farm::plan::relative_to(path, &self.base_dir());
        let _ = self.edit(EditorCommand::SetParam { param, value: kinegraph_nodes::node::ParamValue::Text(text) });
    }

    /// Offers unsaved work from an earlier session back: restore it (unsaved, so the file
    /// is untouched until the user saves) or discard it.
    fn recovery_window(&mut self, ctx: &egui::Context) {
        let Some(save) = &self.recovery else { return };
        let what = save.source.as_ref().map_or("an untitled graph".into(), |p| p.display().to_string());
        let mut choice = None;
        egui::Window::new("Recover unsaved work").collapsible(false).resizable(false).show(ctx, |ui| {
            ui.label(format!("Edits to {what} were not saved when the editor last closed."));
            ui.horizontal(|ui| {
                if ui.button("Restore").clicked() {
                    choice = Some(true);
                }
                if ui.button("Discard").clicked() {
                    choice = Some(false);
                }
            });
        });
        let Some(restore) = choice else { return };
        let Some(save) = self.recovery.take() else { return };
        if !restore {
            files::discard_autosave(&self.settings_dir, self.path.as_deref());
            return;
        }
        match GraphFile::parse(&save.text, &files::autosave_path(&self.settings_dir, self.path.as_deref())) {
            Ok(loaded) => {
                self.graph = loaded.graph;
                self.history.clear();
                self.document_replaced();
                self.message = Some(("restored unsaved work: save to keep it".into(), false));
            }
            Err(e) => self.message = Some((format!("the autosave could not be read: {e}"), true)),
        }
    }

    fn document_replaced(&mut self) {
        self.selection.clear();
        self.displayed = None;
        self.last_shown = None;
        self.badges.clear();
        self.report = None;
        self.canvas = self.canvas.replaced();
        self.snarl_selection.clear();
        self.face_files = None;
        self.document_changed();
    }

    /// The folder the document's relative paths (input files, subgraph files) resolve against.
    fn base_dir(&self) -> PathBuf {
        dir_of(self.path.as_deref())
    }

    fn document_changed(&mut self) {
        self.dirty = document::to_string(&self.graph.to_doc()) != self.clean_text;
        // Faces are read from disk only when the subgraph nodes or their files change (not
        // on every param edit or drag step), and afresh for every document.
        let files = subgraph_files(&self.graph);
        if self.face_files.as_ref() != Some(&files) {
            self.faces = subgraph_faces(&files, &self.registry, &self.base_dir());
            self.face_files = Some(files);
        }
        self.canvas.sync(&self.graph, &self.registry, &self.faces);
        self.selection.retain(|id| self.graph.contains(id));
        self.badges.retain(|id, _| self.graph.contains(id));
        self.submit();
        self.submitted = Instant::now();
    }

    /// Asks the worker for an evaluation of the document; inside a subgraph, of the graph it
    /// was opened from (outermost first), with the unsaved edits of every level, so the
    /// subgraph's nodes show what they compute there.
    fn submit(&mut self) {
        let Some(outermost) = self.parents.first() else {
            self.worker.submit(self.graph.clone(), self.base_dir());
            return;
        };
        let levels = self.parents.iter().skip(1).map(|p| (&p.path, &p.graph)).chain([(&self.path, &self.graph)]);
        let unsaved = levels.filter_map(|(path, graph)| Some((path.clone()?, graph.clone()))).collect();
        let base_dir = dir_of(outermost.path.as_deref());
        self.worker.submit_with(outermost.graph.clone(), base_dir, unsaved);
    }

    /// How the outermost graph names the nodes of the document: `node/` per subgraph level
    /// opened (empty at the top).
    fn scope_prefix(&self) -> String {
        self.parents.iter().map(|p| format!("{}/", p.node)).collect()
    }

    /// Node `id` of the document as the evaluated (outermost) graph names it.
    fn scoped(&self, id: &str) -> String {
        format!("{}{id}", self.scope_prefix())
    }

    /// The document's name for evaluated node `name`; none for a node outside the subgraph
    /// being edited.
    fn local(&self, name: &str) -> Option<String> {
        name.strip_prefix(&self.scope_prefix()).map(str::to_string)
    }

    /// Opens subgraph node `id`'s file for editing in place of the document, which is kept
    /// (unsaved edits and undo history too) until [`EditorApp::back`]. The subgraph is
    /// evaluated inside the graph it was opened from.
    pub fn open_subgraph(&mut self, id: &str) {
        let Some(path) = self.faces.get(id).map(|f| f.path.clone()) else {
            self.message = Some((format!("{id} is not a subgraph whose file can be read"), true));
            return;
        };
        match GraphFile::load(&path) {
            Ok(loaded) => {
                let parent = Parent {
                    path: self.path.replace(path.clone()),
                    graph: std::mem::replace(&mut self.graph, loaded.graph),
                    clean_text: std::mem::take(&mut self.clean_text),
                    history: std::mem::take(&mut self.history),
                    node: id.to_string(),
                };
                self.parents.push(parent);
                self.clean_text = document::to_string(&self.graph.to_doc());
                self.message = Some((format!("editing subgraph {id} ({}); Back returns", path.display()), false));
                self.document_replaced();
            }
            Err(e) => self.message = Some((e.to_string(), true)),
        }
    }

    /// True (and the status bar says to go back first) while a subgraph is open: the
    /// graphs it was opened from may hold unsaved edits another document would drop.
    fn inside_subgraph(&mut self) -> bool {
        let Some(outermost) = self.parents.first() else { return false };
        let name = file_name(outermost.path.as_deref());
        self.message = Some((format!("go Back to {name} first: a subgraph of it is open"), true));
        true
    }

    /// The subgraph levels open, outermost first: `(file name, node opened)`.
    pub fn subgraph_path(&self) -> Vec<(String, String)> {
        self.parents.iter().map(|p| (file_name(p.path.as_deref()), p.node.clone())).collect()
    }

    /// Goes back to the graph the subgraph was opened from. With unsaved edits it asks
    /// first (save them, discard them, or stay); `Some(save)` answers that question.
    pub fn back(&mut self, answer: Option<bool>) {
        if self.parents.is_empty() {
            return;
        }
        match answer {
            None if self.dirty => {
                self.leaving = true;
                return;
            }
            Some(true) => {
                self.save();
                if self.dirty {
                    return;
                }
            }
            _ => {}
        }
        self.leaving = false;
        let Some(parent) = self.parents.pop() else { return };
        self.path = parent.path;
        self.graph = parent.graph;
        self.clean_text = parent.clean_text;
        self.history = parent.history;
        self.document_replaced();
        self.selection = vec![parent.node];
    }

    /// Asks what to do with a subgraph's unsaved edits when going back.
    fn leaving_window(&mut self, ctx: &egui::Context) {
        if !self.leaving {
            return;
        }
        let mut answer = None;
        let name = file_name(self.path.as_deref());
        egui::Window::new("Unsaved subgraph").collapsible(false).resizable(false).show(ctx, |ui| {
            ui.label(format!("{name} has unsaved edits, which every graph using it would see."));
            ui.horizontal(|ui| {
                if ui.button("Save and go back").clicked() {
                    answer = Some(Some(true));
                }
                if ui.button("Discard and go back").clicked() {
                    answer = Some(Some(false));
                }
                if ui.button("Stay").clicked() {
                    answer = Some(None);
                }
            });
        });
        match answer {
            Some(None) => self.leaving = false,
            Some(choice) => self.back(choice),
            None => {}
        }
    }

    /// Takes in what the worker reported since the last frame.
    pub fn poll_worker(&mut self) {
        while let Some(message) = self.worker.poll() {
            self.take_message(message);
        }
    }

    /// Blocks until the evaluation of the latest edit is in (tests and screenshots).
    pub fn wait_for_evaluation(&mut self) {
        self.poll_worker();
        if let Some(message) = self.worker.wait() {
            self.take_message(message);
        }
    }

    fn take_message(&mut self, message: WorkerMessage) {
        self.take_message_unrolled(message);
        self.roll_up_subgraph_badges();
    }

    /// A subgraph node shows its inner nodes' (`id/…`) state: an error or a block if one
    /// has it, running while one runs, ok (cached) when all are. A problem with the node
    /// itself (its file) stays on it.
    fn roll_up_subgraph_badges(&mut self) {
        for id in self.faces.keys().map(|id| id.as_str()) {
            if matches!(self.badges.get(id), Some(Badge::Error(_))) {
                continue;
            }
            let prefix = format!("{id}/");
            let inner: Vec<(&String, &Badge)> =
                self.badges.range(prefix.clone()..).take_while(|(k, _)| k.starts_with(&prefix)).collect();
            let Some(rolled) = roll_up(&inner) else { continue };
            self.badges.insert(id.to_string(), rolled);
        }
    }

    fn take_message_unrolled(&mut self, message: WorkerMessage) {
        if matches!(message, WorkerMessage::Done { .. } | WorkerMessage::Invalid(_)) {
            self.waited_secs = Some(self.submitted.elapsed().as_secs_f64());
        }
        match message {
            WorkerMessage::Done { report, problems, left_out } => {
                self.graph_problems.clear();
                self.badges.clear();
                for (id, node) in &report.nodes {
                    if let Some(id) = self.local(id) {
                        self.badges.insert(id, badge_of(node.status, node.error.clone()));
                    }
                }
                self.report = Some(report);
                if let Some(problems) = problems {
                    self.show_problems(problems);
                }
                // Left out for being downstream of an invalid node: blocked, as after a failure.
                let left_out: Vec<String> = left_out.iter().filter_map(|id| self.local(id)).collect();
                for id in left_out {
                    self.badges
                        .entry(id)
                        .or_insert_with(|| Badge::Blocked("blocked: an upstream node is invalid".into()));
                }
            }
            WorkerMessage::Invalid(errors) => {
                self.report = None;
                self.badges.clear();
                self.graph_problems.clear();
                self.show_problems(errors);
            }
            WorkerMessage::Started { node } => {
                if let Some(node) = self.local(&node) {
                    self.badges.insert(node, Badge::Running);
                }
            }
            WorkerMessage::Finished { node, status } => {
                if let Some(node) = self.local(&node) {
                    self.badges.insert(node, badge_of(status, None));
                }
            }
        }
    }

    /// Validation problems as error badges on the nodes they name (the graph's own in the
    /// status bar).
    fn show_problems(&mut self, errors: GraphErrors) {
        for d in errors.diagnostics {
            let Some(node) = d.node else {
                self.graph_problems.push(d.message);
                continue;
            };
            let Some(node) = self.local(&node) else {
                self.graph_problems.push(format!("outside this subgraph, {node}: {}", d.message));
                continue;
            };
            let text = match d.item {
                Some(item) => format!("{item}: {}", d.message),
                None => d.message,
            };
            match self.badges.get_mut(&node) {
                Some(Badge::Error(m)) => {
                    m.push('\n');
                    m.push_str(&text);
                }
                _ => {
                    self.badges.insert(node, Badge::Error(text));
                }
            }
        }
    }

    /// What the viewport plays for the selected node: its clip (or its mesh sequence's
    /// clip), or, for a node that outputs neither (an export, a smoke simulation), the clip
    /// it takes; with the mesh sequence it outputs, or a skinned mesh it outputs or takes;
    /// the smoke it outputs or takes; and the props it outputs or takes.
    fn selected_motion(&self) -> Motion {
        let Some(id) = self.viewed() else { return Motion::default() };
        let outputs: Vec<&Value> = self.output_values(id).into_iter().filter_map(|(_, v)| v).collect();
        let inputs = self.input_values(id);
        let moving = |v: &&Value| matches!(v, Value::Clip(_) | Value::MeshSequence(_));
        let played = if outputs.iter().any(moving) { &outputs } else { &inputs };
        let sequence = played.iter().find_map(|v| match v {
            Value::MeshSequence(s) => Some(s.clone()),
            _ => None,
        });
        let clip = played
            .iter()
            .find_map(|v| match v {
                Value::Clip(c) => Some(c.clone()),
                _ => None,
            })
            .or_else(|| sequence.as_ref().map(|s| s.clip.clone()));
        let skinned = outputs.iter().chain(&inputs).find_map(|v| match v {
            Value::Mesh(m) if m.skin.is_some() => Some(m.clone()),
            _ => None,
        });
        let smoke = outputs.iter().chain(&inputs).find_map(|v| match v {
            Value::VolumeSequence(s) => Some(s.clone()),
            _ => None,
        });
        let bands = results::time_bands(&outputs, &inputs);
        let com = outputs.iter().chain(&inputs).find_map(|v| match v {
            Value::Curves(c) if c.channel("com.x").is_some() => Some(c.clone()),
            _ => None,
        });
        let mesh = sequence.map(ShownMesh::Baked).or(skinned.map(ShownMesh::Skinned));
        // Props by port name: other unskinned meshes (a rest mesh being bound, a control
        // mesh) are not part of the scene.
        let props_in = self.graph.edges().filter(|e| e.to.node.as_str() == id && e.to.port.as_str() == PROPS_PORT);
        let props = (self.output_values(id).into_iter().filter(|(name, _)| *name == PROPS_PORT).find_map(|(_, v)| v))
            .or_else(|| props_in.filter_map(|e| self.output_value(&e.from)).next())
            .and_then(|v| match v {
                Value::Mesh(m) => Some(m.clone()),
                _ => None,
            });
        Motion { clip, mesh, smoke, bands, com, props }
    }

    /// The time ranges marked under the viewport's timeline for the node it plays.
    pub fn viewport_bands(&self) -> Vec<results::Band> {
        self.selected_motion().bands
    }

    /// The node the viewport plays: the one with the display flag, else the active one.
    pub fn viewed(&self) -> Option<&str> {
        self.displayed.as_deref().filter(|id| self.graph.contains(id)).or(self.selected())
    }

    /// True when the viewport shows a result older than the document (see `last_shown`).
    pub fn viewport_is_stale(&self) -> bool {
        self.viewed()
            .is_some_and(|id| self.selected_motion().is_empty() && self.last_shown.as_ref().is_some_and(|s| s.0 == id))
    }

    /// The viewport: the viewed node's motion, or its last good one marked stale.
    fn viewport(&mut self, ui: &mut Ui) {
        let viewed = self.viewed().map(str::to_string);
        let mut motion = self.selected_motion();
        if let Some(id) = &viewed {
            if !motion.is_empty() {
                self.last_shown = Some((id.clone(), motion.clone()));
            } else if let Some((shown, last)) = self.last_shown.as_ref().filter(|s| &s.0 == id) {
                let state = self.node_state(shown);
                ui.colored_label(
                    egui::Color32::from_rgb(230, 160, 60),
                    format!("stale: {shown} is {state}; showing its last result"),
                );
                motion = last.clone();
            }
        }
        let title = viewed.unwrap_or_default();
        let contacts = motion.clip.as_ref().and_then(|c| self.graph_contacts(c));
        self.viewport.show(ui, &title, motion, contacts.as_ref());
    }

    /// The foot contacts the graph itself computed from `clip` (a node fed this very clip
    /// that outputs contacts), so the viewport's contact rings and strips never disagree
    /// with the graph's `motion.contacts`.
    fn graph_contacts(&self, clip: &Arc<Clip>) -> Option<Arc<Contacts>> {
        self.graph.nodes().keys().find_map(|id| {
            let contacts = self.output_values(id.as_str()).into_iter().find_map(|(_, v)| match v? {
                Value::Contacts(c) => Some(c.clone()),
                _ => None,
            })?;
            let fed =
                self.input_values(id.as_str()).into_iter().any(|v| matches!(v, Value::Clip(c) if Arc::ptr_eq(c, clip)));
            fed.then_some(contacts)
        })
    }

    /// The values arriving at node `id`'s inputs from the last evaluation.
    fn input_values(&self, id: &str) -> Vec<&Value> {
        self.graph.edges().filter(|e| e.to.node.as_str() == id).filter_map(|e| self.output_value(&e.from)).collect()
    }

    /// Node `id`'s outputs from the last evaluation, by port name, in port order.
    fn output_values(&self, id: &str) -> Vec<(&str, Option<&Value>)> {
        let Some(face) = Face::of(&self.graph, &self.registry, &self.faces, id) else { return Vec::new() };
        face.pins(Side::Output).map(|p| (p.name, self.output_value(&PortRef::new(id, p.name)))).collect()
    }

    /// The value at output `port` from the last evaluation; a subgraph node's output is the
    /// one of the inner node it leads to (`id/inner`).
    fn output_value(&self, port: &PortRef) -> Option<&Value> {
        let report = self.report.as_ref()?;
        let inner;
        let port = match self.faces.get(&port.node) {
            Some(face) => {
                let source = face.port(&port.port, Side::Output)?.inner.first()?;
                inner = PortRef::new(format!("{}/{}", port.node.as_str(), source.node.as_str()), source.port.as_str());
                &inner
            }
            None => port,
        };
        report.output(&self.registry, &PortRef::new(self.scoped(port.node.as_str()), port.port.as_str()))
    }

    /// Draws one frame of the editor into `ui` (the whole window).
    pub fn ui(&mut self, ui: &mut Ui) {
        let started = Instant::now();
        self.poll_worker();
        self.shortcuts(ui);
        self.update_title(ui.ctx());

        egui::Panel::top("kg_menu").show(ui, |ui| self.menu_bar(ui));
        egui::Panel::bottom("kg_status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::right("kg_panel").resizable(true).default_size(420.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.panel(ui));
        });
        egui::Panel::bottom("kg_viewport").resizable(true).default_size(380.0).show(ui, |ui| self.viewport(ui));
        egui::CentralPanel::default().show(ui, |ui| self.canvas(ui));
        self.file_dialog(ui.ctx());
        self.browse_dialog(ui.ctx());
        self.recovery_window(ui.ctx());
        self.leaving_window(ui.ctx());
        self.autosave_tick(ui.ctx());
        self.refusal_tooltip(ui);
        self.frame_ms = started.elapsed().as_secs_f32() * 1e3;
    }

    fn shortcuts(&mut self, ui: &mut Ui) {
        let typing = ui.ctx().egui_wants_keyboard_input();
        if !typing && ui.input_mut(|i| i.consume_key(Modifiers::NONE, Key::Tab)) {
            // Before any widget is drawn, so Tab opens the add menu instead of moving focus.
            if let Some(pos) = ui.input(|i| i.pointer.hover_pos()) {
                self.canvas.open_add_menu(pos);
            }
        }
        let (redo, undo, save) = ui.input_mut(|i| {
            (
                i.consume_key(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z)
                    || i.consume_key(Modifiers::COMMAND, Key::Y),
                i.consume_key(Modifiers::COMMAND, Key::Z),
                i.consume_key(Modifiers::COMMAND, Key::S),
            )
        });
        if redo && !typing {
            self.redo();
        } else if undo && !typing {
            self.undo();
        }
        if save {
            self.save();
        }
        if typing {
            return;
        }
        let (delete, duplicate, home, frame, bypass) = ui.input_mut(|i| {
            (
                i.key_pressed(Key::Delete) || i.key_pressed(Key::Backspace),
                i.consume_key(Modifiers::COMMAND, Key::D),
                i.consume_key(Modifiers::NONE, Key::Home),
                i.consume_key(Modifiers::NONE, Key::F),
                i.consume_key(Modifiers::NONE, Key::B),
            )
        });
        if bypass {
            self.toggle_bypass_selection();
        }
        if home {
            self.frame_all();
        }
        if frame {
            self.frame_selection();
        }
        let clipboard: Vec<egui::Event> = ui.input(|i| {
            i.events
                .iter()
                .filter(|e| matches!(e, egui::Event::Copy | egui::Event::Cut | egui::Event::Paste(_)))
                .cloned()
                .collect()
        });
        for event in clipboard {
            match event {
                egui::Event::Copy | egui::Event::Cut => {
                    if let Some(text) = self.copy_selection() {
                        ui.ctx().copy_text(text);
                        if event == egui::Event::Cut {
                            self.delete_selection();
                        }
                    }
                }
                egui::Event::Paste(text) => self.paste_text(&text),
                _ => {}
            }
        }
        if duplicate {
            self.duplicate_selection();
        }
        if delete {
            self.delete_selection();
        }
    }

    fn update_title(&mut self, ctx: &egui::Context) {
        let name = file_name(self.path.as_deref());
        let title = format!("{name}{} — kinegraph", if self.dirty { " •" } else { "" });
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
    }

    fn menu_bar(&mut self, ui: &mut Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("New").clicked() && !self.inside_subgraph() {
                    self.graph = Graph::new();
                    self.path = None;
                    self.clean_text = document::to_string(&self.graph.to_doc());
                    self.history.clear();
                    self.document_replaced();
                    ui.close();
                }
                if ui.button("Open…").clicked() {
                    self.open_dialog(Prompt::Open);
                    ui.close();
                }
                ui.menu_button("Open recent", |ui| {
                    if self.recent.paths.is_empty() {
                        ui.label(RichText::new("no recent files").weak());
                    }
                    for path in self.recent.paths.clone() {
                        if ui.button(path.display().to_string()).clicked() {
                            self.open(&path);
                            ui.close();
                        }
                    }
                });
                if ui.button("Save").clicked() {
                    self.save();
                    ui.close();
                }
                if ui.button("Save as…").clicked() {
                    self.open_dialog(Prompt::SaveAs);
                    ui.close();
                }
            });
            ui.menu_button("Edit", |ui| {
                let undo = self.history.undo_label().map(|l| format!("Undo {l}"));
                if ui.add_enabled(undo.is_some(), egui::Button::new(undo.as_deref().unwrap_or("Undo"))).clicked() {
                    self.undo();
                    ui.close();
                }
                let redo = self.history.redo_label().map(|l| format!("Redo {l}"));
                if ui.add_enabled(redo.is_some(), egui::Button::new(redo.as_deref().unwrap_or("Redo"))).clicked() {
                    self.redo();
                    ui.close();
                }
                ui.separator();
                let any = !self.selection().is_empty();
                if ui.add_enabled(any, egui::Button::new("Copy")).on_hover_text("Ctrl+C: as graph-file text").clicked()
                {
                    if let Some(text) = self.copy_selection() {
                        ui.ctx().copy_text(text);
                    }
                    ui.close();
                }
                let pasted = self.clipboard.clone();
                if ui.add_enabled(pasted.is_some(), egui::Button::new("Paste")).on_hover_text("Ctrl+V").clicked() {
                    if let Some(text) = pasted {
                        self.paste_text(&text);
                    }
                    ui.close();
                }
                if ui.add_enabled(any, egui::Button::new("Duplicate")).on_hover_text("Ctrl+D").clicked() {
                    self.duplicate_selection();
                    ui.close();
                }
                if ui.add_enabled(any, egui::Button::new("Delete")).on_hover_text("Delete").clicked() {
                    self.delete_selection();
                    ui.close();
                }
                ui.separator();
                let collapse = egui::Button::new("Collapse into subgraph…");
                if ui
                    .add_enabled(any, collapse)
                    .on_hover_text("move the selection into a new graph file used as one node")
                    .clicked()
                {
                    self.open_dialog(Prompt::Collapse);
                    ui.close();
                }
            });
            ui.menu_button("Add", |ui| {
                if let Some(kind) = super::canvas::catalogue_menu(ui, &self.registry, &mut self.canvas.search, |_| true)
                {
                    let id = super::commands::fresh_node_id(&self.graph, kind);
                    let y = self.graph.layout().values().map(|p| p.1).fold(0.0_f32, f32::max) + 140.0;
                    let _ = self.edit(EditorCommand::AddNode { id: id.clone(), kind: kind.into(), pos: (0.0, y) });
                    self.selection = vec![id.as_str().to_string()];
                    self.canvas.search.clear();
                    ui.close();
                }
            });
            if !self.parents.is_empty() {
                if ui.button("Back").on_hover_text("to the graph this subgraph was opened from").clicked() {
                    self.back(None);
                }
                for (file, node) in self.subgraph_path() {
                    ui.label(RichText::new(format!("{file} › {node} ›")).weak());
                }
            }
            let name = self.path.as_ref().map_or("untitled".into(), |p| p.display().to_string());
            ui.label(RichText::new(format!("{name}{}", if self.dirty { " •" } else { "" })).weak());
        });
    }

    fn status_bar(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            if self.worker.running() {
                let waiting = self.submitted.elapsed().as_secs_f64();
                ui.label(format!("evaluating… {waiting:.1} s (request {})", self.worker.latest_request()));
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
            } else {
                let waited = self.waited_secs.map_or(String::new(), |s| format!(" in {s:.2} s wall"));
                ui.label(format!("evaluated{waited} (request {})", self.worker.latest_request()));
            }
            if let Some(r) = &self.report {
                ui.label(RichText::new(format!("nodes {:.1} ms", r.seconds * 1e3)).weak());
            }
            ui.separator();
            ui.label(RichText::new(format!("frame {:.1} ms", self.frame_ms)).weak());
            for p in &self.graph_problems {
                ui.separator();
                ui.colored_label(egui::Color32::from_rgb(235, 80, 70), p);
            }
            if let Some((m, is_error)) = &self.message {
                ui.separator();
                let color = if *is_error { egui::Color32::from_rgb(235, 80, 70) } else { ui.visuals().text_color() };
                ui.colored_label(color, m);
            }
        });
    }

    fn panel(&mut self, ui: &mut Ui) {
        let Some(id) = self.selected().map(str::to_string) else {
            ui.heading("No node selected");
            ui.label(
                "Click a node's title to select it and edit its parameters (shift-click adds to the \
                 selection, which is outlined). Right-click the canvas (or press Tab) \
                 to add nodes, or drop a wire on empty canvas to add a node already connected; \
                 right-click a node's title for its menu. Shift-drag a box to select several; Ctrl+C, \
                 Ctrl+V and Ctrl+D copy, paste and duplicate them as graph-file text. \
                 Double-click the canvas or press Home to fit the graph in view, F to fit the selection.",
            );
            if !self.graph.description().is_empty() {
                ui.separator();
                ui.label(self.graph.description());
            }
            return;
        };
        let badge = self.badges.get(&id).cloned().unwrap_or(Badge::Idle);
        let report = self.report.as_ref().and_then(|r| r.nodes.get(&self.scoped(&id))).cloned();
        let face = self.faces.get(id.as_str());
        if face.is_some() && ui.button("Open subgraph").on_hover_text("edit its file here; Back returns").clicked() {
            self.open_subgraph(&id);
            return;
        }
        let edits = panel::show(ui, &mut self.panel, &self.graph, &self.registry, face, &id, &badge, report.as_ref());
        for e in edits {
            let _ = self.edit_coalescing(e.command, e.coalesce);
        }
        if let Some((param, folder)) = self.panel.browse.take() {
            self.browse(param, folder);
        }
        // Owned (each value is a shared pointer), as the panel state is borrowed mutably.
        let outputs: Vec<(String, Option<Value>)> =
            self.output_values(&id).into_iter().map(|(name, v)| (name.to_string(), v.cloned())).collect();
        if outputs.iter().any(|(_, v)| v.is_some()) {
            ui.separator();
            let inputs: Vec<Value> = self.input_values(&id).into_iter().cloned().collect();
            self.results.playhead = self.viewport.time_secs();
            results::show(ui, &mut self.results, &id, &outputs, &inputs);
            if let Some(secs) = self.results.seek.take() {
                self.viewport.seek(secs);
            }
        }
    }

    fn canvas(&mut self, ui: &mut Ui) {
        let marks = Marks { selection: &self.selection, displayed: self.displayed.as_deref() };
        let out = self.canvas.show(ui, &self.graph, &self.registry, &self.faces, &self.badges, marks);
        if let Some(id) = out.display {
            self.displayed = if self.displayed.as_ref() == Some(&id) { None } else { Some(id) };
        }
        if let Some(id) = out.duplicate {
            self.selection = vec![id];
            self.duplicate_selection();
        }
        if let Some(id) = out.open {
            self.open_subgraph(&id);
            return;
        }
        if let Some(reason) = out.refused {
            self.message = Some((format!("connection refused: {reason}"), true));
            self.refusal = Some((reason, ui.input(|i| i.time)));
        }
        // Snarl's selection changes only by box-select, shift-click and ctrl-click: what was
        // added there is added here, what was taken out is taken out.
        if out.selected != self.snarl_selection {
            self.selection.retain(|id| out.selected.contains(id) || !self.snarl_selection.contains(id));
            for id in &out.selected {
                if !self.snarl_selection.contains(id) && !self.selection.contains(id) {
                    self.selection.push(id.clone());
                }
            }
            self.snarl_selection = out.selected;
        }
        // A click on a title selects that node alone; with shift it is added (made active).
        if let Some((id, add)) = out.clicked {
            if !add {
                self.selection.clear();
            }
            self.selection.retain(|s| *s != id);
            self.selection.push(id);
        }
        for cmd in out.commands {
            let _ = self.edit(cmd);
        }
    }

    fn refusal_tooltip(&mut self, ui: &mut Ui) {
        let Some((reason, since)) = &self.refusal else { return };
        let now = ui.input(|i| i.time);
        if now - since > 4.0 {
            self.refusal = None;
            return;
        }
        let pos = ui.input(|i| i.pointer.latest_pos()).unwrap_or_default() + egui::vec2(12.0, 12.0);
        egui::Area::new(egui::Id::new("kg_refusal")).fixed_pos(pos).order(egui::Order::Tooltip).show(ui.ctx(), |ui| {
            egui::Frame::popup(ui.style()).show(ui, |ui| {
                ui.colored_label(egui::Color32::from_rgb(235, 80, 70), format!("Cannot connect: {reason}"));
            });
        });
        ui.ctx().request_repaint();
    }
}

/// The folder of a graph file (relative paths resolve against it); the working folder for
/// an untitled graph.
fn dir_of(path: Option<&Path>) -> PathBuf {
    path.and_then(Path::parent).map(Path::to_path_buf).or_else(|| std::env::current_dir().ok()).unwrap_or_default()
}

/// A graph file's name for menus, `untitled` without a file.
fn file_name(path: Option<&Path>) -> String {
    path.and_then(Path::file_name).map_or("untitled".into(), |n| n.to_string_lossy().into_owned())
}

/// A graph a subgraph was opened from, kept whole to come back to.
struct Parent {
    path: Option<PathBuf>,
    graph: Graph,
    clean_text: String,
    history: History,
    /// The subgraph node that was opened.
    node: String,
}

/// `graph`'s subgraph nodes and the files they name (relative to the graph's folder).
fn subgraph_files(graph: &Graph) -> Vec<(NodeId, String)> {
    graph
        .nodes()
        .iter()
        .filter(|(_, n)| n.kind == document::SUBGRAPH_KIND)
        .filter_map(|(id, n)| match n.params.get(document::SUBGRAPH_FILE_PARAM) {
            Some(kinegraph_nodes::node::ParamValue::Text(file)) => Some((id.clone(), file.clone())),
            _ => None,
        })
        .collect()
}

/// The faces of the subgraph nodes `files` whose files can be read (relative to `base_dir`);
/// one that cannot is left out, and the run reports why on its node.
fn subgraph_faces(files: &[(NodeId, String)], registry: &kinegraph_nodes::node::Registry, base_dir: &Path) -> Faces {
    files
        .iter()
        .filter_map(|(id, file)| crate::engine::face(&base_dir.join(file), registry).ok().map(|f| (id.clone(), f)))
        .collect()
}

/// One state for several inner nodes: the first error, else the first block, else running
/// while any runs, else ok (cached when all were); none when there are none or they differ
/// otherwise (cancelled, idle).
fn roll_up(inner: &[(&String, &Badge)]) -> Option<Badge> {
    if inner.is_empty() {
        return None;
    }
    let named = |id: &str, m: &str| format!("{id}: {m}");
    if let Some((id, b)) = inner.iter().find(|(_, b)| matches!(b, Badge::Error(_))) {
        return Some(Badge::Error(named(id, b.message().unwrap_or("failed"))));
    }
    if let Some((id, b)) = inner.iter().find(|(_, b)| matches!(b, Badge::Blocked(_))) {
        return Some(Badge::Blocked(named(id, b.message().unwrap_or("blocked"))));
    }
    if inner.iter().any(|(_, b)| **b == Badge::Running) {
        return Some(Badge::Running);
    }
    if inner.iter().all(|(_, b)| **b == Badge::Cached) {
        return Some(Badge::Cached);
    }
    inner.iter().all(|(_, b)| matches!(b, Badge::Ok | Badge::Cached | Badge::Bypassed)).then_some(Badge::Ok)
}

fn badge_of(status: NodeStatus, message: Option<String>) -> Badge {
    match status {
        NodeStatus::Ok => Badge::Ok,
        NodeStatus::Cached => Badge::Cached,
        NodeStatus::Error => Badge::Error(message.unwrap_or_else(|| "failed".into())),
        NodeStatus::Blocked => Badge::Blocked(message.unwrap_or_else(|| "blocked upstream".into())),
        NodeStatus::Cancelled => Badge::Cancelled,
        NodeStatus::Bypassed => Badge::Bypassed,
    }
}

impl eframe::App for EditorApp {
    fn ui(&mut self, ui: &mut Ui, _frame: &mut eframe::Frame) {
        EditorApp::ui(self, ui);
    }

    fn raw_input_hook(&mut self, ctx: &egui::Context, raw_input: &mut egui::RawInput) {
        self.wheel_zooms_canvas(ctx, raw_input);
    }

    /// Closing with unsaved edits keeps them in the autosave, offered back next time.
    fn on_exit(&mut self, _gl: Option<&eframe::glow::Context>) {
        self.autosave_now();
    }
}

/// Why the editor could not start.
#[derive(Debug, thiserror::Error)]
#[error("the editor could not start: {0}")]
pub struct StartError(String);

/// Opens the editor window on `graph` (or an empty graph), evaluating with `engine`, and
/// returns when it closes.
pub fn run(graph: Option<PathBuf>, engine: Engine) -> Result<(), StartError> {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_inner_size([1400.0, 860.0]).with_title("kinegraph"),
        renderer: eframe::Renderer::Glow,
        ..Default::default()
    };
    eframe::run_native(
        "kinegraph",
        options,
        Box::new(move |cc| {
            Ok(Box::new(EditorApp::with_engine(&cc.egui_ctx, graph.as_deref(), default_settings_dir(), engine)))
        }),
    )
    .map_err(|e| StartError(e.to_string()))
}
