//! The node canvas: an egui-snarl view rebuilt from the document after every change.
//!
//! Snarl keeps its own graph, but it is only a view: the viewer never edits it. Wiring,
//! unwiring, adding and deleting nodes become [`EditorCommand`]s for the reducer, and
//! [`Canvas::sync`] then brings the view back in line with the document (node ids are kept
//! across syncs so snarl's selection survives edits).

use std::collections::BTreeMap;

use egui::emath::TSTransform;
use egui::{Color32, Pos2, RichText, Ui};
use egui_snarl::ui::{AnyPins, PinInfo, PinWireInfo, SnarlPin, SnarlStyle, SnarlViewer, SnarlWidget};
use egui_snarl::{InPin, InPinId, NodeId, OutPin, OutPinId, Snarl};
use kinegraph_nodes::node::{NodeSchema, PortSpec, PortType, Registry};

use super::commands::{EditorCommand, fresh_node_id};
use crate::engine::{FacePort, SubgraphFace};
use crate::graph::{Graph, PortRef, Side};

/// The outline of selected nodes.
pub(crate) const SELECTED: Color32 = Color32::from_rgb(255, 200, 60);
/// The mark of the node the viewport displays.
pub(crate) const DISPLAYED: Color32 = Color32::from_rgb(90, 160, 255);
/// Edge and state colour of a bypassed node.
const BYPASSED: Color32 = Color32::from_rgb(200, 130, 230);

/// What the canvas marks on nodes besides their state.
#[derive(Clone, Copy)]
pub(crate) struct Marks<'a> {
    /// The selection (outlined).
    pub(crate) selection: &'a [String],
    /// The node with the display flag.
    pub(crate) displayed: Option<&'a str>,
}

/// The canvas' egui id (snarl keeps its view and selection under it, per [`Canvas::view`]).
const CANVAS_ID: &str = "kg_canvas";

/// What the editor shows as a node's state.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Badge {
    /// Not evaluated (exports, or nothing ran yet).
    Idle,
    /// Evaluating now.
    Running,
    /// Evaluated.
    Ok,
    /// Reused from the cache.
    Cached,
    /// Failed, with why.
    Error(String),
    /// Not run because something upstream failed.
    Blocked(String),
    /// The run was cancelled by a newer edit.
    Cancelled,
    /// Bypassed: it passed its inputs on.
    Bypassed,
}

impl Badge {
    /// Short text and colour.
    pub(crate) fn label(&self) -> (&'static str, Color32) {
        match self {
            Badge::Idle => ("idle", Color32::GRAY),
            Badge::Running => ("running", Color32::from_rgb(90, 160, 255)),
            Badge::Ok => ("ok", Color32::from_rgb(90, 200, 110)),
            Badge::Cached => ("cached", Color32::from_rgb(60, 150, 90)),
            Badge::Error(_) => ("error", Color32::from_rgb(235, 80, 70)),
            Badge::Blocked(_) => ("blocked", Color32::from_rgb(230, 160, 60)),
            Badge::Cancelled => ("cancelled", Color32::GRAY),
            Badge::Bypassed => ("bypassed", BYPASSED),
        }
    }

    /// The message that goes with an error or a block.
    pub(crate) fn message(&self) -> Option<&str> {
        match self {
            Badge::Error(m) | Badge::Blocked(m) => Some(m),
            _ => None,
        }
    }
}

/// The colour of a port type (pins and wires).
pub(crate) fn type_color(ty: PortType) -> Color32 {
    match ty {
        PortType::Clip => Color32::from_rgb(80, 170, 255),
        PortType::Mesh => Color32::from_rgb(240, 150, 60),
        PortType::Scalar => Color32::from_rgb(120, 210, 120),
        PortType::File => Color32::from_rgb(200, 120, 220),
        PortType::Curves => Color32::from_rgb(250, 240, 110),
        PortType::Phases => Color32::from_rgb(230, 110, 110),
        PortType::Contacts => Color32::from_rgb(110, 200, 200),
        PortType::Report => Color32::from_rgb(215, 215, 215),
        PortType::MeshSequence => Color32::from_rgb(240, 200, 60),
        PortType::BarNet => Color32::from_rgb(160, 160, 160),
        PortType::ClipSet => Color32::from_rgb(40, 120, 220),
        PortType::Clusters => Color32::from_rgb(150, 110, 230),
        PortType::TransitionGraph => Color32::from_rgb(90, 200, 160),
        PortType::BoneMap => Color32::from_rgb(200, 160, 90),
        PortType::Stages => Color32::from_rgb(255, 130, 180),
        PortType::FluidDomain => Color32::from_rgb(120, 200, 255),
        PortType::VolumeSequence => Color32::from_rgb(200, 200, 230),
        PortType::Family => Color32::from_rgb(255, 170, 110),
    }
}

/// A small filled circle (the default fonts have no bullet glyph).
pub(crate) fn dot(ui: &mut Ui, color: Color32) -> egui::Response {
    let (rect, response) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
    ui.painter().circle_filled(rect.center(), 4.0, color);
    response
}

/// The snarl view of a document.
#[derive(Default)]
pub(crate) struct Canvas {
    snarl: Snarl<String>,
    ids: BTreeMap<String, NodeId>,
    /// Where the last sync put each node: a node away from it was dragged.
    synced: BTreeMap<NodeId, Pos2>,
    /// Where nodes the file gives no position were placed ([`layered_layout`]), by id.
    auto_placed: BTreeMap<String, Pos2>,
    /// The add-node menu's search.
    pub(crate) search: CatalogueSearch,
    /// The node being renamed in its menu, and the name typed so far.
    renaming: Option<(String, String)>,
    /// Where the Tab add-node menu is open (screen).
    add_at: Option<Pos2>,
    /// Canvas (graph) space → screen, as last drawn.
    to_screen: TSTransform,
    /// The canvas' screen area, as last drawn (none before the first draw).
    rect: Option<egui::Rect>,
    /// Which view of the graph snarl shows: a new number is a fresh snarl state (a graph
    /// opened).
    view: u64,
    /// Each node's extent (graph space) as last drawn: what framing fits.
    extents: BTreeMap<String, egui::Rect>,
    /// Graph area to show on the next draw (Home, F, a graph opened).
    frame_next: Option<egui::Rect>,
    /// Frames left in which every node is framed again once all are measured and their
    /// extent changed (a graph opened: snarl's own first view fits node corners, not their
    /// widths, and nodes open up, or titles shrink, at the zoom the fit gives).
    fitting_frames: u8,
    /// The extent of all nodes the last fit framed.
    fitted: Option<egui::Rect>,
    /// Where snarl drew each pin on the last draw (graph space).
    placed: PlacedPins,
}

/// A pin: an output or an input of a snarl node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PinKey {
    Out(OutPinId),
    In(InPinId),
}

/// Pin centres (graph space) as snarl placed them, in drawing order: snarl decides where
/// pins go after the viewer has drawn their rows, so they are noted as they are drawn.
type PlacedPins = std::rc::Rc<std::cell::RefCell<Vec<(PinKey, Pos2)>>>;

/// A pin that notes where snarl draws it.
struct NotedPin {
    info: PinInfo,
    key: PinKey,
    placed: PlacedPins,
}

impl SnarlPin for NotedPin {
    fn draw(
        self,
        snarl_style: &SnarlStyle,
        style: &egui::Style,
        rect: egui::Rect,
        painter: &egui::Painter,
    ) -> PinWireInfo {
        self.placed.borrow_mut().push((self.key, rect.center()));
        SnarlPin::draw(self.info, snarl_style, style, rect, painter)
    }
}

impl Canvas {
    /// Brings the view in line with `graph`: nodes added and removed, positions and wires reset.
    pub(crate) fn sync(&mut self, graph: &Graph, registry: &Registry, faces: &Faces) {
        let gone: Vec<(String, NodeId)> =
            self.ids.iter().filter(|(id, _)| !graph.contains(id)).map(|(i, n)| (i.clone(), *n)).collect();
        for (id, nid) in gone {
            self.snarl.remove_node(nid);
            self.ids.remove(&id);
        }
        // A node the file does not place keeps the place it was first given (a move, then its
        // undo, puts it back there).
        if graph
            .nodes()
            .keys()
            .any(|id| !graph.layout().contains_key(id) && !self.auto_placed.contains_key(id.as_str()))
        {
            for (id, pos) in layered_layout(graph) {
                self.auto_placed.entry(id.to_string()).or_insert(pos);
            }
        }
        self.auto_placed.retain(|id, _| graph.contains(id));
        for id in graph.nodes().keys() {
            let pos = graph.layout().get(id).map(|&(x, y)| Pos2::new(x, y));
            let pos = pos.or_else(|| self.auto_placed.get(id.as_str()).copied()).unwrap_or(Pos2::ZERO);
            let id = id.as_str();
            match self.ids.get(id) {
                Some(&nid) => {
                    if let Some(info) = self.snarl.get_node_info_mut(nid) {
                        info.pos = pos;
                    }
                }
                None => {
                    let nid = self.snarl.insert_node(pos, id.to_string());
                    self.ids.insert(id.to_string(), nid);
                }
            }
        }
        self.synced = self.snarl.nodes_pos_ids().map(|(nid, pos, _)| (nid, pos)).collect();
        let wires: Vec<(OutPinId, InPinId)> = self.snarl.wires().collect();
        for (out, inp) in wires {
            self.snarl.disconnect(out, inp);
        }
        for edge in graph.edges() {
            if let (Some(out), Some(inp)) =
                (self.out_pin(graph, registry, faces, &edge.from), self.in_pin(graph, registry, faces, &edge.to))
            {
                self.snarl.connect(out, inp);
            }
        }
    }

    fn out_pin(&self, graph: &Graph, registry: &Registry, faces: &Faces, port: &PortRef) -> Option<OutPinId> {
        let node = port.node.as_str();
        let output = Face::of(graph, registry, faces, node)?.index(Side::Output, &port.port)?;
        Some(OutPinId { node: *self.ids.get(node)?, output })
    }

    fn in_pin(&self, graph: &Graph, registry: &Registry, faces: &Faces, port: &PortRef) -> Option<InPinId> {
        let node = port.node.as_str();
        let input = Face::of(graph, registry, faces, node)?.index(Side::Input, &port.port)?;
        Some(InPinId { node: *self.ids.get(node)?, input })
    }

    /// Draws the canvas; returns the commands the user asked for and, when a connection
    /// was refused, why.
    pub(crate) fn show(
        &mut self,
        ui: &mut Ui,
        graph: &Graph,
        registry: &Registry,
        faces: &Faces,
        badges: &BTreeMap<String, Badge>,
        marks: Marks<'_>,
    ) -> CanvasOutput {
        self.level_of_detail(ui.max_rect());
        let id = self.widget_id();
        let mut viewer = Viewer {
            graph,
            registry,
            faces,
            badges,
            marks,
            zoom: self.to_screen.scaling,
            frame: self.frame_next.take().map(|r| (r, ui.max_rect())),
            search: &mut self.search,
            renaming: &mut self.renaming,
            placed: self.placed.clone(),
            out: CanvasOutput::default(),
        };
        self.placed.borrow_mut().clear();
        let mut style = SnarlStyle::new();
        style.collapsible = Some(false);
        style.centering = Some(true);
        // Pins sit on the frame's edge, as in Blender. (Inside the frame, snarl 0.12
        // reserves each output pin's room to the right of its row, so every further output
        // row shifted right by a pin and its label ran under the pin: "repo" for "report".)
        style.pin_placement = Some(egui_snarl::ui::PinPlacement::Edge);
        // Snarl's own highlight follows only its own selection; the editor's is drawn by
        // `node_frame` from the one selection model.
        style.select_style = Some(egui_snarl::ui::SelectionStyle {
            margin: egui::Margin::ZERO,
            rounding: egui::CornerRadius::ZERO,
            fill: Color32::TRANSPARENT,
            stroke: egui::Stroke::NONE,
        });
        self.rect = Some(ui.max_rect());
        SnarlWidget::new().id(id).style(style).show(&mut self.snarl, &mut viewer, ui);
        let mut out = viewer.out;
        self.to_screen = out.to_screen;
        self.extents = std::mem::take(&mut out.extents);
        if self.fitting_frames > 0 && graph.nodes().keys().all(|id| self.extents.contains_key(id.as_str())) {
            self.fitting_frames -= 1;
            let all = self.extents.values().fold(egui::Rect::NOTHING, |a, r| a.union(*r));
            if self.fitted.is_none_or(|f| (f.min - all.min).length() + (f.max - all.max).length() > 0.5) {
                self.fitted = Some(all);
                self.frame(&[]);
                ui.ctx().request_repaint();
            }
        }
        self.tab_menu(ui, graph, registry, &mut out);
        out.selected = egui_snarl::ui::get_selected_nodes(self.widget_id(), ui.ctx())
            .into_iter()
            .filter_map(|nid| self.snarl.get_node(nid).cloned())
            .collect();
        out.selected.sort();
        // A finished drag becomes one MoveNodes command.
        if !ui.input(|i| i.pointer.primary_down()) {
            let moves: Vec<(crate::graph::NodeId, Option<(f32, f32)>)> = self
                .snarl
                .nodes_pos_ids()
                .filter(|(nid, pos, _)| self.synced.get(nid).is_none_or(|s| (*s - *pos).length() > 0.01))
                .map(|(_, pos, id)| (id.as_str().into(), Some((pos.x.round(), pos.y.round()))))
                .collect();
            if !moves.is_empty() {
                out.commands.push(EditorCommand::MoveNodes { moves });
            }
        }
        out
    }
}

/// A node's id as its title (text of `size` points at a readable zoom): zoomed out past [`DETAIL_ZOOM`] it grows (up to
/// [`TITLE_GROWTH`] times) against the zoom, so ids stay readable in an overview instead of
/// shrinking until their letters drop out.
fn title_text(id: &str, zoom: f32, size: f32) -> RichText {
    let growth = (DETAIL_ZOOM / zoom.max(1e-3)).clamp(1.0, TITLE_GROWTH);
    RichText::new(id).strong().size(size * growth)
}
/// How much a title may grow when zoomed out.
const TITLE_GROWTH: f32 = 2.5;

/// The view that shows graph `area` (with a margin) centred in `screen`, at a zoom within the
/// canvas' range.
fn fitting(area: egui::Rect, screen: egui::Rect) -> TSTransform {
    let area = area.expand(FRAME_MARGIN);
    let scaling = (screen.width() / area.width()).min(screen.height() / area.height()).clamp(MIN_ZOOM, 1.0);
    TSTransform::new(screen.center().to_vec2() - area.center().to_vec2() * scaling, scaling)
}

/// How many frames after a graph opens its fit may be redone as its nodes settle.
const FIT_FRAMES: u8 = 6;

/// Graph units kept around framed nodes.
const FRAME_MARGIN: f32 = 40.0;
/// The canvas' farthest zoom (snarl's default minimum scale).
const MIN_ZOOM: f32 = 0.2;

/// Canvas distance between the columns and rows of [`layered_layout`] (points at 1:1).
const COLUMN: f32 = 300.0;
const ROW: f32 = 150.0;

/// Places the nodes a graph file gives no position: in columns by the longest path from the
/// nodes nothing feeds (each node right of every node feeding it, so wires run left to
/// right), in id order down a column, below every node the file places.
fn layered_layout(graph: &Graph) -> BTreeMap<crate::graph::NodeId, Pos2> {
    let unplaced: Vec<&crate::graph::NodeId> =
        graph.nodes().keys().filter(|id| !graph.layout().contains_key(*id)).collect();
    if unplaced.is_empty() {
        return BTreeMap::new();
    }
    let mut column: BTreeMap<&crate::graph::NodeId, usize> = graph.nodes().keys().map(|id| (id, 0)).collect();
    // Longest path by relaxation; a cycle (a broken file) stops after one pass per node.
    for _ in 0..graph.nodes().len() {
        let mut moved = false;
        for e in graph.edges() {
            let next = column.get(&e.from.node).map_or(0, |c| c + 1);
            if let Some(c) = column.get_mut(&e.to.node)
                && *c < next
            {
                *c = next;
                moved = true;
            }
        }
        if !moved {
            break;
        }
    }
    let top = graph.layout().values().map(|p| p.1 + ROW).fold(0.0_f32, f32::max);
    let mut rows: BTreeMap<usize, usize> = BTreeMap::new();
    unplaced
        .into_iter()
        .map(|id| {
            let c = column[id];
            let row = rows.entry(c).or_default();
            *row += 1;
            (id.clone(), Pos2::new(c as f32 * COLUMN, top + (*row - 1) as f32 * ROW))
        })
        .collect()
}

/// Below this zoom node text is too small to read: nodes show their header only.
const DETAIL_ZOOM: f32 = 0.45;
/// A generous bound on a node's size in canvas units, to tell whether it is on screen.
const NODE_EXTENT: egui::Vec2 = egui::vec2(420.0, 320.0);

impl Canvas {
    /// Level of detail: snarl lays out every node every frame, on screen or not, so only the
    /// nodes on screen at a readable zoom are open (pins and body); the others are collapsed
    /// to their header (wires still reach them). Decided on the last frame's view.
    fn level_of_detail(&mut self, screen: egui::Rect) {
        let readable = self.to_screen.scaling >= DETAIL_ZOOM;
        let view = screen.expand(64.0);
        let nodes: Vec<(NodeId, Pos2)> = self.snarl.nodes_pos_ids().map(|(nid, pos, _)| (nid, pos)).collect();
        for (nid, pos) in nodes {
            let on_screen = view.intersects(self.to_screen * egui::Rect::from_min_size(pos, NODE_EXTENT));
            let open = readable && on_screen;
            if self.snarl.get_node_info(nid).is_some_and(|n| n.open != open) {
                self.snarl.open_node(nid, open);
            }
        }
    }

    /// A canvas for another document: nothing of this one's kept, and a view fitted to the
    /// new graph once its nodes are measured.
    pub(crate) fn replaced(&self) -> Canvas {
        Canvas { view: self.view + 1, fitting_frames: FIT_FRAMES, ..Canvas::default() }
    }

    /// Fits nodes `ids` (every node when empty), as last drawn, in the canvas on the next draw.
    pub(crate) fn frame(&mut self, ids: &[String]) {
        let rect = self
            .extents
            .iter()
            .filter(|(id, _)| ids.is_empty() || ids.contains(id))
            .fold(egui::Rect::NOTHING, |all, (_, r)| all.union(*r));
        if rect.is_positive() {
            self.frame_next = Some(rect);
        }
    }

    fn widget_id(&self) -> egui::Id {
        egui::Id::new(CANVAS_ID).with(self.view)
    }

    /// Node `id`'s extent on screen, as last drawn.
    pub(crate) fn node_rect(&self, id: &str) -> Option<egui::Rect> {
        self.extents.get(id).map(|r| self.to_screen * *r)
    }

    /// Where port `port` (on `side`) was drawn last, on screen.
    pub(crate) fn pin_on_screen(
        &self,
        graph: &Graph,
        registry: &Registry,
        faces: &Faces,
        port: &PortRef,
        side: Side,
    ) -> Option<Pos2> {
        let key = match side {
            Side::Output => PinKey::Out(self.out_pin(graph, registry, faces, port)?),
            Side::Input => PinKey::In(self.in_pin(graph, registry, faces, port)?),
        };
        let placed = self.placed.borrow();
        placed.iter().find(|(k, _)| *k == key).map(|(_, pos)| self.to_screen * *pos)
    }

    /// The canvas' screen area, as last drawn.
    pub(crate) fn rect(&self) -> Option<egui::Rect> {
        self.rect
    }

    /// Where canvas point `pos` is on screen, as last drawn.
    pub(crate) fn to_screen(&self, pos: Pos2) -> Pos2 {
        self.to_screen * pos
    }

    /// Opens the add-node menu at `screen_pos` when that is over the canvas (the Tab key).
    pub(crate) fn open_add_menu(&mut self, screen_pos: Pos2) {
        if self.rect.is_some_and(|r| r.contains(screen_pos)) {
            self.add_at = Some(screen_pos);
        }
    }

    /// The add-node menu opened by [`Canvas::open_add_menu`]; the node lands where it opened.
    fn tab_menu(&mut self, ui: &mut Ui, graph: &Graph, registry: &Registry, out: &mut CanvasOutput) {
        let Some(at) = self.add_at else { return };
        let area = egui::Area::new(egui::Id::new("kg_tab_add")).fixed_pos(at).order(egui::Order::Foreground).show(
            ui.ctx(),
            |ui| {
                egui::Frame::popup(ui.style())
                    .show(ui, |ui| {
                        ui.label("Add node");
                        egui::ScrollArea::vertical()
                            .max_height(360.0)
                            .show(ui, |ui| catalogue_menu(ui, registry, &mut self.search, |_| true))
                            .inner
                    })
                    .inner
            },
        );
        let closed = ui.input(|i| i.key_pressed(egui::Key::Escape)) || area.response.clicked_elsewhere();
        if let Some(kind) = area.inner {
            let pos = self.to_screen.inverse() * at;
            out.commands.push(EditorCommand::AddNode {
                id: fresh_node_id(graph, kind),
                kind: kind.into(),
                pos: (pos.x, pos.y),
            });
            self.search.clear();
            self.add_at = None;
        } else if closed {
            self.add_at = None;
        }
    }
}

/// What the user did on the canvas this frame.
#[derive(Default)]
pub(crate) struct CanvasOutput {
    /// Edits, in order.
    pub(crate) commands: Vec<EditorCommand>,
    /// Why a connection was refused.
    pub(crate) refused: Option<String>,
    /// Ids of the nodes snarl has selected (box-select, shift-click), sorted.
    pub(crate) selected: Vec<String>,
    /// The node whose title was clicked, and whether shift was held (add to the selection).
    pub(crate) clicked: Option<(String, bool)>,
    /// The node whose display flag was toggled in its menu.
    pub(crate) display: Option<String>,
    /// The node to duplicate, from its menu.
    pub(crate) duplicate: Option<String>,
    /// The subgraph node to open for editing, from its menu or a double-click on its title.
    pub(crate) open: Option<String>,
    /// Canvas (graph) space → screen, as drawn this frame.
    pub(crate) to_screen: TSTransform,
    /// Each drawn node's extent in graph space (header and pin rows).
    pub(crate) extents: BTreeMap<String, egui::Rect>,
}

/// The faces of a graph's subgraph nodes, by node id, as read from their files.
pub(crate) type Faces = BTreeMap<crate::graph::NodeId, SubgraphFace>;

/// A node's ports as the canvas shows them: its kind's schema, or the face of its subgraph
/// file.
#[derive(Clone, Copy)]
pub(crate) enum Face<'a> {
    Kind(&'static NodeSchema),
    Subgraph(&'a SubgraphFace),
}

/// One port as drawn.
pub(crate) struct Pin<'a> {
    pub(crate) name: &'a str,
    pub(crate) ty: PortType,
    pub(crate) required: bool,
    pub(crate) doc: &'a str,
}

impl<'a> Face<'a> {
    /// The face of node `id`; none for an unknown kind or a subgraph whose file cannot be read.
    pub(crate) fn of(graph: &Graph, registry: &Registry, faces: &'a Faces, id: &str) -> Option<Face<'a>> {
        let node = graph.node(id)?;
        match faces.get(id) {
            Some(face) => Some(Face::Subgraph(face)),
            None => registry.get(&node.kind).map(|n| Face::Kind(n.schema())),
        }
    }

    /// How many ports it has on `side`.
    pub(crate) fn count(self, side: Side) -> usize {
        match (self, side) {
            (Face::Kind(s), Side::Input) => s.inputs.len(),
            (Face::Kind(s), Side::Output) => s.outputs.len(),
            (Face::Subgraph(f), Side::Input) => f.inputs.len(),
            (Face::Subgraph(f), Side::Output) => f.outputs.len(),
        }
    }

    /// Its `index`th port on `side`.
    pub(crate) fn pin(self, side: Side, index: usize) -> Option<Pin<'a>> {
        let kind_pin = |p: &'static PortSpec| Pin { name: p.name, ty: p.ty, required: p.required, doc: p.doc };
        let face_pin = |p: &'a FacePort| Pin { name: &p.name, ty: p.ty, required: p.required, doc: p.doc };
        match (self, side) {
            (Face::Kind(s), Side::Input) => s.inputs.get(index).map(kind_pin),
            (Face::Kind(s), Side::Output) => s.outputs.get(index).map(kind_pin),
            (Face::Subgraph(f), Side::Input) => f.inputs.get(index).map(face_pin),
            (Face::Subgraph(f), Side::Output) => f.outputs.get(index).map(face_pin),
        }
    }

    /// Its ports on `side`, in order.
    pub(crate) fn pins(self, side: Side) -> impl Iterator<Item = Pin<'a>> {
        (0..self.count(side)).filter_map(move |i| self.pin(side, i))
    }

    /// The index of its port `name` on `side`.
    fn index(self, side: Side, name: &str) -> Option<usize> {
        self.pins(side).position(|p| p.name == name)
    }
}

struct Viewer<'a> {
    graph: &'a Graph,
    registry: &'a Registry,
    faces: &'a Faces,
    /// The canvas' scale (screen points per graph unit) as last drawn.
    zoom: f32,
    /// Graph area to fit in the screen rect given with it, this draw.
    frame: Option<(egui::Rect, egui::Rect)>,
    badges: &'a BTreeMap<String, Badge>,
    marks: Marks<'a>,
    search: &'a mut CatalogueSearch,
    renaming: &'a mut Option<(String, String)>,
    placed: PlacedPins,
    out: CanvasOutput,
}

impl<'a> Viewer<'a> {
    /// Adds `rect` (graph space) to node `id`'s extent.
    fn measure(&mut self, id: &str, rect: egui::Rect) {
        // Called per pin per frame: the id is copied only the first time.
        match self.out.extents.get_mut(id) {
            Some(extent) => *extent = extent.union(rect),
            None => {
                self.out.extents.insert(id.to_string(), rect);
            }
        }
    }

    fn face(&self, id: &str) -> Option<Face<'a>> {
        Face::of(self.graph, self.registry, self.faces, id)
    }

    fn endpoint(&self, node: NodeId, side: Side, index: usize, snarl: &Snarl<String>) -> Option<PortRef> {
        let id = snarl.get_node(node)?;
        let pin = self.face(id)?.pin(side, index)?;
        Some(PortRef::new(id.as_str(), pin.name))
    }

    fn endpoint_out(&self, pin: &OutPin, snarl: &Snarl<String>) -> Option<PortRef> {
        self.endpoint(pin.id.node, Side::Output, pin.id.output, snarl)
    }

    fn endpoint_in(&self, pin: &InPin, snarl: &Snarl<String>) -> Option<PortRef> {
        self.endpoint(pin.id.node, Side::Input, pin.id.input, snarl)
    }
}

impl SnarlViewer<String> for Viewer<'_> {
    fn title(&mut self, node: &String) -> String {
        let kind = self.graph.node(node).map(|n| n.kind.as_str()).unwrap_or("?");
        format!("{node} · {kind}")
    }

    fn show_header(
        &mut self,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<String>,
    ) {
        let Some(info) = snarl.get_node_info(node) else { return };
        let (id, open) = (&info.value, info.open);
        self.measure(id, ui.max_rect());
        let badge = self.badges.get(id).unwrap_or(&Badge::Idle);
        let (text, color) = badge.label();
        ui.horizontal(|ui| {
            let body = egui::TextStyle::Body.resolve(ui.style()).size;
            let title = ui.add(egui::Label::new(title_text(id, self.zoom, body)).sense(egui::Sense::click()));
            let title = title
                .on_hover_text("click to select and edit its parameters; shift-click to add; right-click for its menu");
            if title.clicked() {
                self.out.clicked = Some((id.clone(), ui.input(|i| i.modifiers.shift)));
            }
            if title.double_clicked() && self.faces.contains_key(id.as_str()) {
                self.out.open = Some(id.clone());
            }
            title.context_menu(|ui| self.node_menu(ui, id));
            if self.marks.displayed == Some(id.as_str()) {
                ui.label(RichText::new("displayed").color(DISPLAYED).small())
                    .on_hover_text("the viewport plays this node whatever is selected");
            }
            // A collapsed node (off screen, or zoomed out) shows its id and state colour only.
            if open {
                ui.label(RichText::new(self.graph.node(id).map_or("", |n| n.kind.as_str())).weak());
            }
            // The state is a word and a dot; an error's text is their tooltip (and in the
            // panel), so a long message never widens the node over its neighbours' wires.
            let tip = badge.message().unwrap_or(text);
            dot(ui, color).on_hover_text(tip);
            if open {
                ui.label(RichText::new(text).color(color)).on_hover_text(tip);
            }
        });
    }

    /// Selected nodes get a bright outline.
    fn node_frame(
        &mut self,
        default: egui::Frame,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        snarl: &Snarl<String>,
    ) -> egui::Frame {
        let Some(id) = snarl.get_node(node) else { return default };
        // A bypassed node is dimmed and edged in the bypass colour, as in Houdini.
        let frame = match self.graph.node(id) {
            Some(n) if n.bypass => {
                default.fill(default.fill.gamma_multiply(0.45)).stroke(egui::Stroke::new(1.5, BYPASSED))
            }
            _ => default,
        };
        if self.marks.selection.contains(id) { frame.stroke(egui::Stroke::new(2.5, SELECTED)) } else { frame }
    }

    fn inputs(&mut self, node: &String) -> usize {
        self.face(node).map_or(0, |f| f.count(Side::Input))
    }

    fn outputs(&mut self, node: &String) -> usize {
        self.face(node).map_or(0, |f| f.count(Side::Output))
    }

    fn show_input(
        &mut self,
        pin: &InPin,
        ui: &mut Ui,
        snarl: &mut Snarl<String>,
    ) -> impl egui_snarl::ui::SnarlPin + 'static {
        if let Some(id) = snarl.get_node(pin.id.node) {
            self.measure(id, ui.max_rect());
        }
        let port =
            snarl.get_node(pin.id.node).and_then(|id| self.face(id)).and_then(|f| f.pin(Side::Input, pin.id.input));
        let info =
            port_pin(
                ui,
                port,
                false,
                |p| if p.required { p.name.to_string() } else { format!("{} (optional)", p.name) },
            );
        NotedPin { info, key: PinKey::In(pin.id), placed: self.placed.clone() }
    }

    fn show_output(
        &mut self,
        pin: &OutPin,
        ui: &mut Ui,
        snarl: &mut Snarl<String>,
    ) -> impl egui_snarl::ui::SnarlPin + 'static {
        if let Some(id) = snarl.get_node(pin.id.node) {
            self.measure(id, ui.max_rect());
        }
        let port =
            snarl.get_node(pin.id.node).and_then(|id| self.face(id)).and_then(|f| f.pin(Side::Output, pin.id.output));
        NotedPin {
            info: port_pin(ui, port, true, |p| p.name.to_string()),
            key: PinKey::Out(pin.id),
            placed: self.placed.clone(),
        }
    }

    fn connect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<String>) {
        let (Some(from), Some(to)) = (self.endpoint_out(from, snarl), self.endpoint_in(to, snarl)) else { return };
        match crate::engine::check_connect(self.graph, self.registry, self.faces, &from, &to) {
            Ok(()) => self.out.commands.push(EditorCommand::Connect { from, to }),
            Err(e) => self.out.refused = Some(e.to_string()),
        }
    }

    fn disconnect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<String>) {
        if let (Some(from), Some(to)) = (self.endpoint_out(from, snarl), self.endpoint_in(to, snarl)) {
            self.out.commands.push(EditorCommand::Disconnect { from, to });
        }
    }

    fn drop_inputs(&mut self, pin: &InPin, snarl: &mut Snarl<String>) {
        let Some(to) = self.endpoint_in(pin, snarl) else { return };
        let cmds: Vec<EditorCommand> = self
            .graph
            .edges()
            .filter(|e| e.to == to)
            .map(|e| EditorCommand::Disconnect { from: e.from.clone(), to: e.to.clone() })
            .collect();
        if !cmds.is_empty() {
            self.out.commands.push(EditorCommand::Batch(cmds));
        }
    }

    fn drop_outputs(&mut self, pin: &OutPin, snarl: &mut Snarl<String>) {
        let Some(from) = self.endpoint_out(pin, snarl) else { return };
        let cmds: Vec<EditorCommand> = self
            .graph
            .edges()
            .filter(|e| e.from == from)
            .map(|e| EditorCommand::Disconnect { from: e.from.clone(), to: e.to.clone() })
            .collect();
        if !cmds.is_empty() {
            self.out.commands.push(EditorCommand::Batch(cmds));
        }
    }

    fn has_graph_menu(&mut self, _pos: Pos2, _snarl: &mut Snarl<String>) -> bool {
        true
    }

    fn show_graph_menu(&mut self, pos: Pos2, ui: &mut Ui, _snarl: &mut Snarl<String>) {
        ui.label("Add node");
        if let Some(kind) = catalogue_menu(ui, self.registry, self.search, |_| true) {
            let id = fresh_node_id(self.graph, kind);
            self.out.commands.push(EditorCommand::AddNode { id, kind: kind.to_string(), pos: (pos.x, pos.y) });
            self.search.clear();
            ui.close();
        }
    }

    fn has_dropped_wire_menu(&mut self, _src_pins: AnyPins, _snarl: &mut Snarl<String>) -> bool {
        true
    }

    /// A wire dropped on empty canvas offers the kinds that can take it (or feed it) and
    /// adds the chosen node already connected, as one undo step.
    fn show_dropped_wire_menu(&mut self, pos: Pos2, ui: &mut Ui, src_pins: AnyPins, snarl: &mut Snarl<String>) {
        let (node, side, index) = match src_pins {
            AnyPins::Out(pins) => {
                let Some(pin) = pins.first() else { return };
                (pin.node, Side::Output, pin.output)
            }
            AnyPins::In(pins) => {
                let Some(pin) = pins.first() else { return };
                (pin.node, Side::Input, pin.input)
            }
        };
        let Some(id) = snarl.get_node(node) else { return };
        let Some(port) = self.face(id).and_then(|f| f.pin(side, index)) else { return };
        let (endpoint, ty, from_output) = (PortRef::new(id.as_str(), port.name), port.ty, side == Side::Output);
        ui.label(format!("Add a node that {} a {}", if from_output { "takes" } else { "gives" }, ty.name()));
        let picked = catalogue_menu(ui, self.registry, self.search, |s| facing_port(s, ty, from_output).is_some());
        if let Some(cmd) =
            picked.and_then(|kind| add_connected(self.graph, self.registry, &endpoint, ty, from_output, kind, pos))
        {
            self.out.commands.push(cmd);
            self.search.clear();
            ui.close();
        }
    }

    fn current_transform(&mut self, to_global: &mut TSTransform, _snarl: &mut Snarl<String>) {
        if let Some((area, screen)) = self.frame {
            *to_global = fitting(area, screen);
        }
        self.out.to_screen = *to_global;
    }

    fn has_node_menu(&mut self, _node: &String) -> bool {
        true
    }

    fn show_node_menu(
        &mut self,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<String>,
    ) {
        if let Some(id) = snarl.get_node(node) {
            self.node_menu(ui, id);
        }
    }
}

impl Viewer<'_> {
    /// The menu of node `id` (right-click on its title or frame).
    fn node_menu(&mut self, ui: &mut Ui, id: &str) {
        ui.horizontal(|ui| {
            ui.label("Rename");
            if self.renaming.as_ref().is_none_or(|(n, _)| n != id) {
                *self.renaming = Some((id.to_string(), id.to_string()));
            }
            let Some((_, text)) = self.renaming.as_mut() else { return };
            let field = ui.add(egui::TextEdit::singleline(text).desired_width(140.0)).on_hover_text("Enter renames");
            if field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                if text.as_str() != id {
                    self.out.commands.push(EditorCommand::RenameNode { from: id.into(), to: text.as_str().into() });
                }
                *self.renaming = None;
                ui.close();
            }
        });
        let display = if self.marks.displayed == Some(id) { "Stop displaying" } else { "Display in viewport" };
        if ui.button(display).on_hover_text("the viewport plays this node whatever is selected").clicked() {
            self.out.display = Some(id.to_string());
            ui.close();
        }
        if self.faces.contains_key(id)
            && ui.button("Open subgraph").on_hover_text("edit its file (double-click the title)").clicked()
        {
            self.out.open = Some(id.to_string());
            ui.close();
        }
        let bypassed = self.graph.node(id).is_some_and(|n| n.bypass);
        if !self.faces.contains_key(id) {
            let (label, tip) = if bypassed {
                ("Stop bypassing", "run the node again (B)")
            } else {
                ("Bypass", "skip the node: each output passes on an input of its type (B)")
            };
            if ui.button(label).on_hover_text(tip).clicked() {
                self.out.commands.push(EditorCommand::SetBypass { id: id.into(), bypass: !bypassed });
                ui.close();
            }
        }
        if ui.button("Duplicate").clicked() {
            self.out.duplicate = Some(id.to_string());
            ui.close();
        }
        if ui.button("Delete").clicked() {
            self.out.commands.push(EditorCommand::RemoveNodes { ids: vec![id.into()] });
            ui.close();
        }
    }
}

/// What is typed into the add-node menu's search, and which of the kinds it shows is
/// highlighted (the arrow keys move it, Enter adds it).
#[derive(Default)]
pub(crate) struct CatalogueSearch {
    text: String,
    highlight: usize,
}

impl CatalogueSearch {
    /// Empties the search (after a node was added).
    pub(crate) fn clear(&mut self) {
        *self = CatalogueSearch::default();
    }
}

/// A focused search box over the node catalogue grouped by category, narrowed to the kinds
/// `accepts` and filtered by the search text (kind, category or doc text); returns the kind
/// clicked, or the highlighted one on Enter (Up and Down move the highlight).
pub(crate) fn catalogue_menu(
    ui: &mut Ui,
    registry: &Registry,
    search: &mut CatalogueSearch,
    accepts: impl Fn(&NodeSchema) -> bool,
) -> Option<&'static str> {
    let field = ui.add(
        egui::TextEdit::singleline(&mut search.text)
            .hint_text("search… (arrows pick, Enter adds)")
            .desired_width(180.0),
    );
    let enter = field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
    let (down, up) = ui.input(|i| (i.key_pressed(egui::Key::ArrowDown), i.key_pressed(egui::Key::ArrowUp)));
    if field.changed() {
        search.highlight = 0;
    }
    field.request_focus();
    let needle = search.text.trim().to_lowercase();
    let mut groups: BTreeMap<&str, Vec<&'static NodeSchema>> = BTreeMap::new();
    for node in registry.iter() {
        let s = node.schema();
        let hit = accepts(s)
            && (needle.is_empty()
                || s.kind.contains(&needle)
                || s.category.contains(&needle)
                || s.doc.to_lowercase().contains(&needle));
        if hit {
            groups.entry(s.category).or_default().push(s);
        }
    }
    let shown = groups.values().map(Vec::len).sum::<usize>();
    if down {
        search.highlight = (search.highlight + 1).min(shown.saturating_sub(1));
    }
    if up {
        search.highlight = search.highlight.saturating_sub(1);
    }
    let mut picked = if enter { groups.values().flatten().nth(search.highlight).map(|s| s.kind) } else { None };
    // The catalogue is taller than a laptop screen: the list scrolls under the search field.
    let max_height = ui.ctx().content_rect().height() * 0.7;
    egui::ScrollArea::vertical().max_height(max_height).show(ui, |ui| {
        let mut index = 0;
        for (category, schemas) in groups {
            ui.label(RichText::new(category).small().weak());
            for s in schemas {
                let highlighted = index == search.highlight;
                let button = ui.add(egui::Button::new(s.kind).selected(highlighted)).on_hover_text(s.doc);
                if highlighted && (down || up) {
                    button.scroll_to_me(None);
                }
                if button.clicked() {
                    picked = Some(s.kind);
                }
                index += 1;
            }
        }
    });
    picked
}

/// The first port of type `ty` on the side of `schema` that faces a dropped wire: its
/// inputs when the wire comes from an output, else its outputs.
fn facing_port(schema: &NodeSchema, ty: PortType, from_output: bool) -> Option<&'static str> {
    let ports = if from_output { schema.inputs } else { schema.outputs };
    ports.iter().find(|p| p.ty == ty).map(|p| p.name)
}

/// One undo step that adds a node of `kind` at `pos` and wires it to `endpoint`, the port
/// a wire was dragged from (an output when `from_output`).
fn add_connected(
    graph: &Graph,
    registry: &Registry,
    endpoint: &PortRef,
    ty: PortType,
    from_output: bool,
    kind: &str,
    pos: Pos2,
) -> Option<EditorCommand> {
    let facing = facing_port(registry.get(kind)?.schema(), ty, from_output)?;
    let id = fresh_node_id(graph, kind);
    let new_end = PortRef::new(id.clone(), facing);
    let (from, to) = if from_output { (endpoint.clone(), new_end) } else { (new_end, endpoint.clone()) };
    Some(EditorCommand::Batch(vec![
        EditorCommand::AddNode { id, kind: kind.to_string(), pos: (pos.x, pos.y) },
        EditorCommand::Connect { from, to },
    ]))
}

/// Space between an output's label and its pin, which snarl draws over the label's end.
const OUTPUT_PIN_CLEARANCE: f32 = 14.0;

/// A port's label (with its type and doc as tooltip) and its pin, coloured by type; an
/// output's label (laid out from the right) keeps clear of the pin.
fn port_pin(ui: &mut Ui, port: Option<Pin<'_>>, output: bool, label: impl Fn(&Pin<'_>) -> String) -> PinInfo {
    match port {
        Some(p) => {
            if output {
                ui.add_space(OUTPUT_PIN_CLEARANCE);
            }
            // Never wrapped or elided: the node grows to its ports' names.
            ui.add(egui::Label::new(label(&p)).extend()).on_hover_ui(|ui| {
                ui.label(format!("{} — {}", p.ty.name(), p.doc));
            });
            PinInfo::circle().with_fill(type_color(p.ty))
        }
        None => PinInfo::circle(),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::editor::commands::apply;
    use crate::graph::GraphFile;

    fn port(text: &str) -> PortRef {
        PortRef::parse(text).unwrap()
    }

    #[test]
    fn a_dropped_wire_adds_a_node_wired_on_the_matching_side() {
        let registry = kinegraph_nodes::builtin::registry();
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        let mut doc = GraphFile::load(&path).unwrap().graph;
        // From an output: the new node's clip input takes it.
        let cmd = add_connected(
            &doc,
            &registry,
            &port("clip.clip"),
            PortType::Clip,
            true,
            "motion.contacts",
            Pos2::new(5.0, 6.0),
        )
        .unwrap();
        apply(&mut doc, &registry, &cmd).unwrap();
        assert_eq!(doc.node("contacts").unwrap().kind, "motion.contacts");
        assert_eq!(doc.layout()["contacts"], (5.0, 6.0));
        assert!(doc.has_edge(&port("clip.clip"), &port("contacts.clip")));
        // From an input: the new node's output feeds it (replacing what fed it).
        let cmd =
            add_connected(&doc, &registry, &port("resample.clip"), PortType::Clip, false, "clip.trim", Pos2::ZERO)
                .unwrap();
        apply(&mut doc, &registry, &cmd).unwrap();
        assert!(doc.has_edge(&port("trim_2.clip"), &port("resample.clip")));
        // A kind with no port of the wire's type is neither offered nor wired.
        let load_mesh = registry.get("mesh.load").unwrap().schema();
        assert!(facing_port(load_mesh, PortType::Clip, true).is_none());
        assert!(
            add_connected(&doc, &registry, &port("clip.clip"), PortType::Clip, true, "mesh.load", Pos2::ZERO).is_none()
        );
    }

    /// A graph file without `layout` opens with every wire running left to right and no two
    /// nodes in one place (it opened as one column with tangled wires).
    #[test]
    fn a_graph_without_layout_opens_in_columns_along_its_wires() {
        let registry = kinegraph_nodes::builtin::registry();
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/skinning_arm.ron");
        let doc = GraphFile::load(&path).unwrap().graph;
        assert!(doc.layout().is_empty());
        let mut canvas = Canvas::default();
        canvas.sync(&doc, &registry, &Faces::new());
        let pos = |id: &str| canvas.snarl.get_node_info(canvas.ids[id]).unwrap().pos;
        for e in doc.edges() {
            assert!(pos(e.from.node.as_str()).x < pos(e.to.node.as_str()).x, "{} → {}", e.from, e.to);
        }
        let mut places: Vec<(i64, i64)> =
            doc.nodes().keys().map(|id| (pos(id.as_str()).x as i64, pos(id.as_str()).y as i64)).collect();
        places.sort_unstable();
        places.dedup();
        assert_eq!(places.len(), doc.nodes().len());
    }

    #[test]
    fn only_nodes_on_screen_at_a_readable_zoom_are_open() {
        let registry = kinegraph_nodes::builtin::registry();
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron");
        let doc = GraphFile::load(&path).unwrap().graph;
        let mut canvas = Canvas::default();
        canvas.sync(&doc, &registry, &Faces::new());
        let open = |c: &Canvas, id: &str| c.snarl.get_node_info(c.ids[id]).unwrap().open;
        let screen = egui::Rect::from_min_size(Pos2::ZERO, egui::vec2(400.0, 300.0));
        // 1:1, the view at the origin: `clip` (at 0, 0) is on screen, `glb` (at 660, 80)
        // starts past the right edge and its 64 px margin (464 px).
        canvas.level_of_detail(screen);
        assert!(open(&canvas, "clip") && !open(&canvas, "glb"));
        // Panned 300 px left: `glb` starts at 360 px, `clip`'s extent still reaches 120 px.
        canvas.to_screen = TSTransform::new(egui::vec2(-300.0, 0.0), 1.0);
        canvas.level_of_detail(screen);
        assert!(open(&canvas, "clip") && open(&canvas, "glb"));
        // Panned far away: neither.
        canvas.to_screen = TSTransform::new(egui::vec2(-1500.0, 0.0), 1.0);
        canvas.level_of_detail(screen);
        assert!(!open(&canvas, "glb") && !open(&canvas, "clip"));
        // Zoomed out below the readable zoom: everything is collapsed, wherever it is.
        canvas.to_screen = TSTransform::from_scaling(0.3);
        canvas.level_of_detail(screen);
        assert!(doc.nodes().keys().all(|id| !open(&canvas, id.as_str())));
    }
}
