//! Editor interaction tests through egui_kittest: no window, no GPU.
#![cfg(feature = "editor")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::{Path, PathBuf};

use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use kinegraph::document;
use kinegraph::editor::EditorApp;
use kinegraph::editor::commands::{EditError, EditorCommand};
use kinegraph::graph::{GraphError, ParamPath, PortRef, Side};
use kinegraph::nodes::node::ParamValue;

fn demo_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/demo.ron")
}

/// A settings folder of its own per editor, so tests never see the user's recent files or
/// autosaves, nor each other's.
fn fresh_settings_dir() -> PathBuf {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("editor-settings-{}-{n}", std::process::id()))
}

fn harness(path: Option<&Path>) -> Harness<'static, EditorApp> {
    harness_in(path, fresh_settings_dir())
}

fn harness_in(path: Option<&Path>, settings_dir: PathBuf) -> Harness<'static, EditorApp> {
    let mut app = EditorApp::with_settings_dir(&egui::Context::default(), path, settings_dir);
    app.wait_for_evaluation();
    let mut harness =
        Harness::builder().with_size([1400.0, 860.0]).build_ui_state(|ui, app: &mut EditorApp| app.ui(ui), app);
    // Snarl lays nodes out over a couple of frames; the viewport may keep asking for
    // repaints while it plays, so step a fixed number of frames instead of `run`.
    harness.run_steps(4);
    harness
}

fn end_secs(app: &EditorApp) -> Option<ParamValue> {
    app.doc().nodes["trim"].params.get("end_secs").cloned()
}

#[test]
fn shows_the_demo_graph_with_states() {
    let harness = harness(Some(&demo_path()));
    for kind in ["clip.load", "clip.trim", "clip.resample", "mesh.load", "export.glb", "export.bvh"] {
        harness.get_by_label(kind);
    }
    let app = harness.state();
    for id in ["clip", "trim", "resample", "mesh"] {
        assert!(matches!(app.node_state(id), "ok" | "cached"), "{id}: {}", app.node_state(id));
    }
    // Exports do not run in the editor.
    assert_eq!(app.node_state("glb"), "idle");
    assert!(!app.is_dirty());
    // The status bar says how long the user waited, not only the nodes' own time.
    harness.get_by_label_contains("s wall (request 1)");
}

#[test]
fn clicking_a_node_title_opens_its_panel_and_plays_its_clip() {
    let mut harness = harness(Some(&demo_path()));
    // Snarl draws nodes in a transformed layer, so click through AccessKit rather than a pointer position.
    harness.get_by_label("resample").click_accesskit();
    harness.run_steps(3);
    assert_eq!(harness.state().selected(), Some("resample"));
    harness.get_by_role_and_label(Role::SpinButton, "fps");
    harness.get_by_label("pause");
}

#[test]
fn a_clip_pinned_for_comparison_stays_on_show_under_another_selection() {
    let mut harness = harness(Some(&demo_path()));
    harness.get_by_label("resample").click_accesskit();
    harness.run_steps(3);
    harness.get_by_label("pin to compare").click();
    harness.run_steps(2);
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(3);
    assert_eq!(harness.state().selected(), Some("trim"));
    harness.get_by_label("comparing with resample");
    for view in ["side", "top", "front", "frame"] {
        harness.get_by_label(view).click();
        harness.run_steps(1);
    }
    harness.get_by_label("unpin").click();
    harness.run_steps(2);
    assert!(harness.query_by_label("comparing with resample").is_none());
}

#[test]
fn a_param_edit_goes_through_the_reducer_and_undo_restores_it() {
    let mut harness = harness(Some(&demo_path()));
    let before = document::to_string(&harness.state().doc());
    harness.state_mut().select(Some("trim"));
    harness.run_steps(2);
    harness.get_by_label("Parameters");
    let field = harness.get_by_role_and_label(Role::SpinButton, "end_secs");
    field.click();
    harness.run_steps(2);
    harness.get_by_role_and_label(Role::SpinButton, "end_secs").type_text("0.5");
    harness.run_steps(1);
    harness.key_press(egui::Key::Enter);
    harness.run_steps(2);
    assert_eq!(end_secs(harness.state()), Some(ParamValue::Float(0.5)));
    assert!(harness.state().is_dirty());

    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(2);
    assert_eq!(document::to_string(&harness.state().doc()), before);
    assert!(!harness.state().is_dirty());

    harness.key_press_modifiers(egui::Modifiers::COMMAND | egui::Modifiers::SHIFT, egui::Key::Z);
    harness.run_steps(2);
    assert_eq!(end_secs(harness.state()), Some(ParamValue::Float(0.5)));
}

#[test]
fn a_bad_connection_is_refused_with_the_reason_shown() {
    let mut harness = harness(Some(&demo_path()));
    let before = harness.state().doc().clone();
    let connect =
        EditorCommand::Connect { from: PortRef::parse("mesh.mesh").unwrap(), to: PortRef::parse("trim.clip").unwrap() };
    let result = harness.state_mut().edit(connect);
    assert!(matches!(result, Err(EditError::Graph(GraphError::TypeMismatch { .. }))), "{result:?}");
    harness.run_steps(2);
    harness.get_by_label_contains("mesh.mesh gives a mesh, but trim.clip takes a clip");
    assert_eq!(harness.state().doc(), before);
    assert!(!harness.state().is_dirty());
}

/// Where the pin of `port` was drawn, on screen.
fn pin(harness: &Harness<'static, EditorApp>, port: &str, side: Side) -> egui::Pos2 {
    harness.state().pin_on_screen(&PortRef::parse(port).unwrap(), side).unwrap()
}

#[test]
fn dragging_a_wire_between_different_types_is_refused_by_the_connect_hook() {
    let mut harness = harness(Some(&demo_path()));
    let before = harness.state().doc().clone();
    // From the `mesh` node's output pin to the `trim` node's `clip` input pin.
    let (from, to) = (pin(&harness, "mesh.mesh", Side::Output), pin(&harness, "trim.clip", Side::Input));
    harness.drag_at(from);
    harness.run_steps(1);
    for t in [0.25, 0.5, 0.75, 1.0] {
        harness.hover_at(from + (to - from) * t);
        harness.run_steps(1);
    }
    harness.drop_at(to);
    harness.run_steps(2);
    let message = harness.state().message().map(|(m, _)| m.to_string()).unwrap_or_default();
    assert_eq!(message, "connection refused: type mismatch: mesh.mesh gives a mesh, but trim.clip takes a clip");
    harness.get_by_label_contains("Cannot connect: type mismatch: mesh.mesh gives a mesh");
    assert_eq!(harness.state().doc(), before);
}

#[test]
fn dragging_a_wire_into_an_occupied_input_replaces_it_in_one_undo_step() {
    let mut harness = harness(Some(&demo_path()));
    let before = document::to_string(&harness.state().doc());
    // `clip`'s output pin to `resample`'s input pin, which `trim` feeds.
    let (from, to) = (pin(&harness, "clip.clip", Side::Output), pin(&harness, "resample.clip", Side::Input));
    harness.drag_at(from);
    harness.run_steps(1);
    for t in [0.25, 0.5, 0.75, 1.0] {
        harness.hover_at(from + (to - from) * t);
        harness.run_steps(1);
    }
    harness.drop_at(to);
    harness.run_steps(2);
    let into: Vec<String> =
        harness.state().doc().edges.iter().filter(|e| e.to == "resample.clip").map(|e| e.from.clone()).collect();
    assert_eq!(into, ["clip.clip"]);
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(2);
    assert_eq!(document::to_string(&harness.state().doc()), before);
}

#[test]
fn adding_a_node_from_the_catalogue_menu() {
    let mut harness = harness(Some(&demo_path()));
    harness.get_by_label("Add").click();
    harness.run_steps(2);
    // The catalogue (50 kinds) scrolls inside the window; the search field narrows it.
    harness.get_by_role(Role::TextInput).type_text("constant");
    harness.run_steps(2);
    harness.get_by_label("scalar.constant").click();
    harness.run_steps(2);
    let app = harness.state();
    assert_eq!(app.doc().nodes["constant"].kind, "scalar.constant");
    assert_eq!(app.selected(), Some("constant"));
    assert!(app.is_dirty());
}

#[test]
fn save_and_reload_and_saving_without_edits_changes_no_byte() {
    let dir = tempfile::tempdir().unwrap();
    // A valid but not canonically formatted copy of the demo (relative paths still work).
    let text = std::fs::read_to_string(demo_path()).unwrap().replace("    ", "  ");
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs").join(format!(".editor_test_{}.ron", std::process::id()));
    std::fs::write(&path, &text).unwrap();
    let mut harness = harness(Some(&path));
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::S);
    harness.run_steps(1);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text, "saving without edits rewrote the file");
    std::fs::remove_file(&path).unwrap();

    let copy = dir.path().join("copy.ron");
    let app = harness.state_mut();
    app.edit(EditorCommand::SetParam { param: ParamPath::parse("resample.fps").unwrap(), value: ParamValue::Int(12) })
        .unwrap();
    app.save_as(&copy);
    assert!(!app.is_dirty());
    let saved = document::to_string(&app.doc());
    assert_eq!(std::fs::read_to_string(&copy).unwrap(), saved);
    let reloaded = EditorApp::with_settings_dir(&egui::Context::default(), Some(&copy), fresh_settings_dir());
    assert_eq!(document::to_string(&reloaded.doc()), saved);
    assert!(!reloaded.is_dirty());
}

#[test]
fn a_concat_report_and_momentum_curves_are_readable_in_the_panel() {
    // The example graph reads the shared corpus; without it there is nothing to show.
    if kinegraph::nodes::corpus::shared_data().is_none() {
        return;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/one_two_punch.ron");
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("concat"));
    harness.run_steps(3);
    harness.get_by_label("Report (report)");
    harness.get_by_label("offset_secs");
    harness.get_by_label("posterior -> main");
    harness.state_mut().select(Some("momentum"));
    harness.run_steps(3);
    harness.get_by_label("Curves (curves)");
    harness.get_by_role_and_label(Role::CheckBox, "L.x (kg·m²/s)");
    harness.get_by_role_and_label(Role::CheckBox, "com.y (m)");
}

#[test]
fn copy_and_paste_carry_a_fragment_with_its_inner_wire_in_one_undo_step() {
    let mut harness = harness(Some(&demo_path()));
    let before = document::to_string(&harness.state().doc());
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    let text = harness.state_mut().copy_selection().expect("a node is selected");
    // What goes on the clipboard is graph-file text: `kg check` could read it.
    assert!(document::parse(&text, Path::new("clipboard.ron")).is_ok(), "{text}");
    harness.event(egui::Event::Paste(text));
    harness.run_steps(2);
    assert!(harness.state().doc().nodes.contains_key("trim_2"));
    assert_eq!(harness.state().selected(), Some("trim_2"));
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(2);
    assert_eq!(document::to_string(&harness.state().doc()), before);
    // Text that is no graph is refused with a message and changes nothing.
    harness.event(egui::Event::Paste("not a graph".into()));
    harness.run_steps(2);
    let (message, is_error) = harness.state().message().unwrap();
    assert!(is_error && message.starts_with("the clipboard holds no graph fragment"), "{message}");
    assert_eq!(document::to_string(&harness.state().doc()), before);
}

/// Presses Tab over the canvas and types `text` into the add menu's search.
fn search_the_tab_menu(harness: &mut Harness<'static, EditorApp>, text: &str) {
    harness.hover_at(egui::pos2(200.0, 120.0));
    harness.run_steps(1);
    harness.key_press(egui::Key::Tab);
    harness.run_steps(2);
    harness.get_by_role(Role::TextInput).type_text(text);
    harness.run_steps(2);
}

#[test]
fn tab_over_the_canvas_opens_the_add_menu_at_the_pointer() {
    let mut harness = harness(Some(&demo_path()));
    search_the_tab_menu(&mut harness, "contacts");
    harness.get_by_label("motion.contacts").click();
    harness.run_steps(3);
    assert_eq!(harness.state().doc().nodes.get("contacts").map(|n| n.kind.as_str()), Some("motion.contacts"));
    assert!(harness.query_by_label("Add node").is_none(), "the menu closes once a node is added");
}

#[test]
fn unsaved_edits_survive_a_crash_through_the_autosave() {
    let dir = tempfile::tempdir().unwrap();
    let graph = dir.path().join("demo.ron");
    std::fs::copy(demo_path(), &graph).unwrap();
    let settings = dir.path().join("settings");
    let edited = {
        let mut harness = harness_in(Some(&graph), settings.clone());
        let cmd = EditorCommand::SetParam {
            param: ParamPath::parse("trim.end_secs").unwrap(),
            value: ParamValue::Float(0.75),
        };
        harness.state_mut().edit(cmd).unwrap();
        harness.state_mut().autosave_now();
        document::to_string(&harness.state().doc())
        // Dropped without saving: the editor "crashed".
    };
    let file_before = std::fs::read(&graph).unwrap();
    let mut harness = harness_in(Some(&graph), settings.clone());
    harness.get_by_label("Recover unsaved work");
    harness.get_by_label("Restore").click();
    harness.run_steps(2);
    assert_eq!(document::to_string(&harness.state().doc()), edited);
    assert!(harness.state().is_dirty(), "restored work is unsaved until the user saves");
    assert_eq!(std::fs::read(&graph).unwrap(), file_before, "restoring writes nothing");
    harness.state_mut().save();
    drop(harness);
    // Saved: nothing left to recover, and the graph is first in the recent files.
    let harness = harness_in(Some(&graph), settings.clone());
    assert!(harness.query_by_label("Recover unsaved work").is_none());
    let recent = kinegraph::editor::files::RecentFiles::load(&settings);
    assert_eq!(recent.paths.first(), Some(&std::path::absolute(&graph).unwrap()));
}

#[test]
fn an_export_node_plays_the_clip_it_writes_with_its_skinned_mesh() {
    let mut harness = harness(Some(&demo_path()));
    // A clip node alone has no mesh: no mesh toggle.
    harness.state_mut().select(Some("resample"));
    harness.run_steps(3);
    assert!(harness.query_by_role_and_label(Role::CheckBox, "mesh").is_none());
    // The GLB export takes the clip and the mannequin's skinned mesh: both are on show.
    harness.state_mut().select(Some("glb"));
    harness.run_steps(3);
    harness.get_by_label("pause");
    harness.get_by_role_and_label(Role::CheckBox, "mesh").click();
    harness.run_steps(2);
}

/// A node added and left unwired is an error on its own; every branch that does not depend
/// on it keeps evaluating and playing.
#[test]
fn a_dangling_node_blocks_only_what_depends_on_it() {
    let mut harness = harness(Some(&demo_path()));
    let add = EditorCommand::AddNode { id: "dangling".into(), kind: "clip.trim".into(), pos: (0.0, 400.0) };
    harness.state_mut().edit(add).unwrap();
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    let app = harness.state();
    assert_eq!(app.node_state("dangling"), "error");
    for id in ["clip", "trim", "resample", "mesh"] {
        assert!(matches!(app.node_state(id), "ok" | "cached"), "{id}: {}", app.node_state(id));
    }
    harness.get_by_label("resample").click_accesskit();
    harness.run_steps(3);
    harness.get_by_label("pause");
}

/// Shift-drags a selection box on the canvas from `from` to `to` (canvas coordinates).
fn box_select(harness: &mut Harness<'static, EditorApp>, from: (f32, f32), to: (f32, f32)) {
    let (from, to) = (harness.state().canvas_to_screen(from), harness.state().canvas_to_screen(to));
    let shift = egui::Modifiers::SHIFT;
    harness.event(egui::Event::ModifiersChanged(shift));
    harness.event(egui::Event::PointerMoved(from));
    harness.run_steps(1);
    harness.event(egui::Event::PointerButton {
        pos: from,
        button: egui::PointerButton::Primary,
        pressed: true,
        modifiers: shift,
    });
    harness.run_steps(1);
    for t in [0.25, 0.5, 0.75, 1.0] {
        harness.event(egui::Event::PointerMoved(from.lerp(to, t)));
        harness.run_steps(1);
    }
    harness.event(egui::Event::PointerButton {
        pos: to,
        button: egui::PointerButton::Primary,
        pressed: false,
        modifiers: shift,
    });
    harness.run_steps(1);
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    harness.run_steps(2);
}

fn sorted(mut ids: Vec<String>) -> Vec<String> {
    ids.sort();
    ids
}

/// One selection for the box, the highlight, the panel and Delete: a box over `trim` and
/// `resample` selects both, pasting selects the copies, and Delete removes the copies, never
/// the originals (it removed `trim` and broke the chain).
#[test]
fn a_pasted_selection_is_what_delete_removes() {
    let mut harness = harness(Some(&demo_path()));
    // The demo's trim is at (220, 0) and resample at (440, 0); the box touches both and no
    // other node.
    box_select(&mut harness, (300.0, 70.0), (500.0, 20.0));
    assert_eq!(sorted(harness.state().selection()), ["resample", "trim"]);
    let text = harness.state_mut().copy_selection().expect("two nodes are selected");
    harness.event(egui::Event::Paste(text));
    harness.run_steps(2);
    assert_eq!(sorted(harness.state().selection()), ["resample_2", "trim_2"]);
    assert!(matches!(harness.state().selected(), Some("resample_2" | "trim_2")));
    harness.key_press(egui::Key::Delete);
    harness.run_steps(2);
    let doc = harness.state().doc();
    assert!(!doc.nodes.contains_key("trim_2") && !doc.nodes.contains_key("resample_2"));
    assert!(doc.nodes.contains_key("trim") && doc.nodes.contains_key("resample"));
    assert!(
        harness
            .state()
            .graph()
            .has_edge(&PortRef::parse("trim.clip").unwrap(), &PortRef::parse("resample.clip").unwrap())
    );
    assert!(harness.state().selection().is_empty());
}

/// A title click selects that node alone (and shows it outlined); shift-click adds one.
#[test]
fn a_title_click_selects_one_node_and_shift_click_adds() {
    let mut harness = harness(Some(&demo_path()));
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    assert_eq!(harness.state().selection(), ["trim"]);
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::SHIFT));
    harness.get_by_label("resample").click_accesskit();
    harness.run_steps(2);
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    harness.run_steps(1);
    assert_eq!(harness.state().selection(), ["trim", "resample"]);
    assert_eq!(harness.state().selected(), Some("resample"));
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    assert_eq!(harness.state().selection(), ["trim"]);
}

fn fps(app: &EditorApp) -> Option<ParamValue> {
    app.doc().nodes["resample"].params.get("fps").cloned()
}

/// Typing "12" into fps changes nothing until Enter (the old field evaluated 1 fps, then
/// 12), then commits once: one evaluation, one undo step back to the file.
#[test]
fn a_typed_number_commits_once_on_enter() {
    let mut harness = harness(Some(&demo_path()));
    let before = document::to_string(&harness.state().doc());
    harness.state_mut().select(Some("resample"));
    harness.run_steps(2);
    let requests = harness.state().evaluations_requested();
    harness.get_by_role_and_label(Role::SpinButton, "fps").click();
    harness.run_steps(2);
    harness.get_by_role_and_label(Role::SpinButton, "fps").type_text("12");
    harness.run_steps(2);
    assert_eq!(harness.state().evaluations_requested(), requests, "nothing is evaluated while typing");
    assert!(!harness.state().is_dirty());
    harness.key_press(egui::Key::Enter);
    harness.run_steps(2);
    assert_eq!(fps(harness.state()), Some(ParamValue::Float(12.0)));
    assert_eq!(harness.state().evaluations_requested(), requests + 1);
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(2);
    assert_eq!(document::to_string(&harness.state().doc()), before, "one undo step");
}

/// Dragging fps 37 points to the right nudges it (it went from 24 to 97) and is one undo step.
#[test]
fn dragging_a_number_nudges_it_by_its_size() {
    let mut harness = harness(Some(&demo_path()));
    let before = document::to_string(&harness.state().doc());
    harness.state_mut().select(Some("resample"));
    harness.run_steps(2);
    let start = fps(harness.state()).and_then(|v| v.as_f64()).unwrap_or(0.0);
    let field = harness.get_by_role_and_label(Role::SpinButton, "fps").rect().center();
    harness.event(egui::Event::PointerMoved(field));
    harness.run_steps(1);
    let button = |pos, pressed| egui::Event::PointerButton {
        pos,
        button: egui::PointerButton::Primary,
        pressed,
        modifiers: egui::Modifiers::NONE,
    };
    harness.event(button(field, true));
    harness.run_steps(1);
    for dx in [5.0, 15.0, 25.0, 37.0] {
        harness.event(egui::Event::PointerMoved(field + egui::vec2(dx, 0.0)));
        harness.run_steps(1);
    }
    harness.event(button(field + egui::vec2(37.0, 0.0), false));
    harness.run_steps(2);
    let after = fps(harness.state()).and_then(|v| v.as_f64()).unwrap();
    println!("fps {start} → {after} over 37 points");
    assert!(after > start && after < start * 1.25, "{start} → {after}");
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(2);
    assert_eq!(document::to_string(&harness.state().doc()), before, "the drag is one undo step");
}

/// Right-clicks node `id`'s title on the canvas: the title starts about 22 points right of
/// the node's layout position and is 15 high (snarl's layer is transformed, so the place is
/// carried to the screen).
fn right_click_title(harness: &mut Harness<'static, EditorApp>, id: &str) {
    let (x, y) = harness.state().graph().layout()[id];
    let pos = harness.state().canvas_to_screen((x + 30.0, y + 9.0));
    click_at(harness, pos, egui::PointerButton::Secondary);
    harness.run_steps(1);
}

/// The display flag keeps the viewport on a node while another is selected and tuned; when
/// the displayed node loses its result, its last one stays on show, marked stale.
#[test]
fn the_displayed_node_stays_on_show_and_goes_stale_not_blank() {
    let mut harness = harness(Some(&demo_path()));
    right_click_title(&mut harness, "resample");
    harness.get_by_label("Display in viewport").click();
    harness.run_steps(2);
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    assert_eq!(harness.state().selected(), Some("trim"));
    assert_eq!(harness.state().viewed(), Some("resample"));
    harness.get_by_label("displayed");
    harness.get_by_label("pause");
    assert!(!harness.state().viewport_is_stale());
    // Cut the wire into resample: it is blocked, and its last clip stays on show, marked.
    let cut = EditorCommand::Disconnect {
        from: PortRef::parse("trim.clip").unwrap(),
        to: PortRef::parse("resample.clip").unwrap(),
    };
    harness.state_mut().edit(cut).unwrap();
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert!(harness.state().viewport_is_stale());
    harness.get_by_label("stale: resample is error; showing its last result");
    harness.get_by_label("pause");
    // Stop displaying: the viewport follows the selection again.
    right_click_title(&mut harness, "resample");
    harness.get_by_label("Stop displaying").click();
    harness.run_steps(2);
    assert_eq!(harness.state().viewed(), Some("trim"));
}

/// Enter in the Tab menu adds the first kind the search shows.
#[test]
fn enter_in_the_add_menu_adds_the_first_match() {
    let mut harness = harness(Some(&demo_path()));
    search_the_tab_menu(&mut harness, "foot_lock");
    harness.key_press(egui::Key::Enter);
    harness.run_steps(3);
    assert_eq!(harness.state().doc().nodes.get("foot_lock").map(|n| n.kind.as_str()), Some("motion.foot_lock"));
}

/// An error's text is the state's tooltip and the panel's, not a paragraph on the canvas
/// that widens the node over its neighbours.
#[test]
fn an_error_message_does_not_widen_its_node() {
    let mut harness = harness(Some(&demo_path()));
    let add = EditorCommand::AddNode { id: "dangling".into(), kind: "clip.trim".into(), pos: (220.0, 160.0) };
    harness.state_mut().edit(add).unwrap();
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(3);
    harness.get_by_label("error");
    assert!(harness.query_by_label_contains("is not connected").is_none(), "the message is not drawn on the canvas");
    harness.get_by_label("dangling").click_accesskit();
    harness.run_steps(2);
    harness.get_by_label_contains("is not connected");
}

fn contacts_output(app: &EditorApp, id: &str) -> kinegraph::nodes::model::Contacts {
    let outputs = &app.report().unwrap().outputs[id];
    outputs
        .iter()
        .flatten()
        .find_map(|v| match v {
            kinegraph::nodes::node::Value::Contacts(c) => Some((**c).clone()),
            _ => None,
        })
        .unwrap()
}

/// The viewport shows the contacts the graph computed for the clip it plays, not its own
/// guess with default thresholds (which missed every contact of a 24 fps walk that showed
/// them at 30).
#[test]
fn the_viewport_shows_the_graphs_own_contacts() {
    let mut harness = harness(Some(&demo_path()));
    let app = harness.state_mut();
    // "contacts" is tuned loose enough to find the short demo's plants; the defaults find none.
    let tuned = [
        ("enter_height_m", 0.2),
        ("leave_height_m", 0.3),
        ("enter_speed_mps", 5.0),
        ("leave_speed_mps", 10.0),
        ("min_duration_secs", 0.0),
    ];
    for (id, params) in [("contacts", &tuned[..]), ("contacts_default", &[][..])] {
        let add = EditorCommand::AddNode { id: id.into(), kind: "motion.contacts".into(), pos: (660.0, 240.0) };
        app.edit(add).unwrap();
        let wire = EditorCommand::Connect {
            from: PortRef::parse("resample.clip").unwrap(),
            to: PortRef::parse(&format!("{id}.clip")).unwrap(),
        };
        app.edit(wire).unwrap();
        for (name, value) in params {
            let param = ParamPath::parse(&format!("{id}.{name}")).unwrap();
            app.edit(EditorCommand::SetParam { param, value: ParamValue::Float(*value) }).unwrap();
        }
    }
    app.select(Some("resample"));
    app.wait_for_evaluation();
    harness.run_steps(3);
    let app = harness.state();
    let (tuned, default) = (contacts_output(app, "contacts"), contacts_output(app, "contacts_default"));
    assert_ne!(tuned, default, "the tuned node finds other contacts than the defaults");
    assert_eq!(app.viewport_contacts(), Some(&tuned));
}

/// One plain wheel step up where the pointer is, through the editor's input hook (as the
/// eframe window runs it on every frame's input).
/// One wheel step of `dy` points (positive zooms in) through the editor's wheel hook.
fn wheel_step(harness: &mut Harness<'static, EditorApp>, dy: f32) {
    let mut raw = egui::RawInput::default();
    raw.events.push(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Point,
        delta: egui::vec2(0.0, dy),
        phase: egui::TouchPhase::Move,
        modifiers: egui::Modifiers::NONE,
    });
    harness.state().wheel_zooms_canvas(&harness.ctx, &mut raw);
    raw.events.into_iter().for_each(|e| harness.event(e));
    harness.run_steps(1);
}

/// The plain wheel over the canvas zooms about the pointer (it panned); the eframe window
/// runs every frame's input through `wheel_zooms_canvas`, here called by hand.
#[test]
fn the_wheel_zooms_the_canvas_at_the_pointer() {
    let mut harness = harness(Some(&demo_path()));
    let at = harness.state().canvas_to_screen((330.0, 20.0));
    harness.hover_at(at);
    harness.run_steps(1);
    let before = harness.state().canvas_to_screen((430.0, 120.0)) - at;
    wheel_step(&mut harness, 60.0);
    harness.run_steps(3);
    let after = harness.state().canvas_to_screen((430.0, 120.0)) - harness.state().canvas_to_screen((330.0, 20.0));
    let moved = harness.state().canvas_to_screen((330.0, 20.0)) - at;
    println!(
        "100 canvas units: {:.1} → {:.1} points; the point under the pointer moved {:.2}",
        before.x,
        after.x,
        moved.length()
    );
    assert!(after.x > before.x * 1.05, "zoomed in: {before:?} → {after:?}");
    assert!(moved.length() < 1.0, "about the pointer: moved {moved:?}");
}

/// An example graph that reads the shared corpus, or `None` (skipped; CI fails) without it.
fn corpus_graph(name: &str) -> Option<PathBuf> {
    kinegraph::nodes::corpus::shared_data()?;
    Some(Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs").join(name))
}

/// Moves the viewport's time slider to `secs`, as a drag or a screen reader does (the
/// slider pauses playback).
fn seek(harness: &mut Harness<'static, EditorApp>, secs: f64) {
    use egui_kittest::kittest::NodeT;
    let (target_node, target_tree) = harness.get_by_role_and_label(Role::Slider, "time").accesskit_node().locate();
    harness.event(egui::Event::AccessKitActionRequest(egui::accesskit::ActionRequest {
        action: egui::accesskit::Action::SetValue,
        target_node,
        target_tree,
        data: Some(egui::accesskit::ActionData::NumericValue(secs)),
    }));
    harness.run_steps(2);
}

fn volumes_output(app: &EditorApp, id: &str) -> std::sync::Arc<kinegraph::nodes::model::VolumeSequence> {
    app.report().unwrap().outputs[id]
        .iter()
        .flatten()
        .find_map(|v| match v {
            kinegraph::nodes::node::Value::VolumeSequence(v) => Some(v.clone()),
            _ => None,
        })
        .unwrap()
}

/// Viewing the smoke simulation of a kick draws the kicking mesh (its obstacle) and the
/// smoke's particles of the frame at the playhead, by the volumes' own frame rate.
#[test]
fn the_smoke_plays_its_particles_with_the_obstacle() {
    let Some(path) = corpus_graph("kick_through_smoke.ron") else { return };
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("smoke"));
    harness.run_steps(3);
    harness.get_by_role_and_label(Role::CheckBox, "mesh");
    let volumes = volumes_output(harness.state(), "smoke");
    for secs in [0.3, 0.8] {
        seek(&mut harness, secs);
        let frame = (secs * volumes.fps).floor() as usize;
        let particles = volumes.frames[frame].particles_m.len();
        println!("{secs} s: frame {frame} of {}, {particles} particles", volumes.frames.len());
        assert!(particles > 0, "the source has seeded particles by frame {frame}");
        let drawn = harness.state().viewport_smoke().unwrap();
        assert_eq!((drawn.frame, drawn.particles, drawn.bodies.len()), (frame, particles, 0));
        harness.get_by_label(&format!("smoke frame {frame} @ {:.0} fps", volumes.fps));
    }
}

/// Smoke without a clip (balls in a smoke column) still plays: the timeline lasts the
/// volumes' frames at their rate, and the balls are drawn where the simulation's `bodies`
/// curves put them: the light one (ball1) rises on screen, the heavy one (ball2) falls.
#[test]
fn smoke_without_a_clip_plays_for_its_frames_with_its_balls() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("graphs/ball_in_smoke.ron");
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("points"));
    harness.run_steps(3);
    let volumes = volumes_output(harness.state(), "smoke");
    let curves = match harness.state().output("smoke", "bodies") {
        Some(kinegraph::nodes::node::Value::Curves(c)) => c.clone(),
        other => panic!("smoke.bodies: {other:?}"),
    };
    let height = |ball: &str, frame: usize| curves.channel(&format!("{ball}.y")).unwrap().values[frame];
    let last = volumes.frames.len() - 1;
    let mut centres = Vec::new();
    // 0 s is frame 0; 0.9 s is frame 10 of 12 at 12 fps; past the end (5 s) the slider holds the last.
    for (secs, frame) in [(0.0, 0), (0.9, 10), (5.0, last)] {
        seek(&mut harness, secs);
        let drawn = harness.state().viewport_smoke().unwrap();
        assert_eq!((drawn.frame, drawn.particles), (frame, volumes.frames[frame].particles_m.len()));
        let on_screen: Vec<egui::Pos2> = drawn.bodies.iter().map(|b| b.unwrap()).collect();
        assert_eq!(on_screen.len(), 2);
        centres.push(on_screen);
    }
    // The curves say which way each ball went; the screen's y grows downwards.
    let (rose, fell) = (height("ball1", last) - height("ball1", 0), height("ball2", last) - height("ball2", 0));
    assert!(rose > 0.2 && fell < -0.5, "ball1 rose {rose} m, ball2 fell {fell} m");
    let (first, end) = (&centres[0], &centres[2]);
    assert!(end[0].y < first[0].y - 5.0, "ball1 drawn at {:?} then {:?}", first[0], end[0]);
    assert!(end[1].y > first[1].y + 5.0, "ball2 drawn at {:?} then {:?}", first[1], end[1]);
}

/// The ground and flight stages of a jump are shaded on the curves of the node that finds
/// them and of the momentum splines fitted to them.
#[test]
fn stages_are_shaded_on_the_curve_plots() {
    let Some(path) = corpus_graph("jump_stages.ron") else { return };
    let mut harness = harness(Some(&path));
    let stages = harness.state().report().unwrap().outputs["stages"]
        .iter()
        .flatten()
        .find_map(|v| match v {
            kinegraph::nodes::node::Value::Stages(s) => Some(s.clone()),
            _ => None,
        })
        .unwrap();
    assert!(stages.stages.len() >= 3, "a jump: ground, flight, ground");
    let expected: Vec<(&str, f64, f64)> = stages
        .stages
        .iter()
        .map(|s| {
            let name = if s.kind == kinegraph::nodes::model::StageKind::Flight { "flight" } else { "ground" };
            (name, s.frames.start as f64 / stages.fps, s.frames.end as f64 / stages.fps)
        })
        .collect();
    for (node, port) in [("stages", "curves"), ("splines", "curves")] {
        harness.state_mut().select(Some(node));
        harness.run_steps(3);
        let bands: Vec<(&str, f64, f64)> = (harness.state().plot_bands(node, port).unwrap().iter())
            .map(|b| (b.name.as_str(), b.start_secs, b.end_secs))
            .collect();
        assert_eq!(bands, expected, "{node}.{port}");
    }
}

/// The controllers' activations of a physics simulation are labelled time ranges in the
/// panel and bands on its curves: one per activation, in the report's order of controllers,
/// tiling the simulated clip's time.
#[test]
fn the_controller_timeline_is_shown_as_labelled_ranges() {
    let Some(path) = corpus_graph("push_and_recover.ron") else { return };
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("simulate"));
    harness.run_steps(3);
    let app = harness.state();
    let outputs = &app.report().unwrap().outputs["simulate"];
    let (mut controllers, mut duration) = (Vec::new(), 0.0);
    for value in outputs.iter().flatten() {
        match value {
            kinegraph::nodes::node::Value::Report(r) => {
                controllers = r["controllers"].as_array().unwrap().iter().map(|c| c.as_str().unwrap()).collect();
            }
            kinegraph::nodes::node::Value::Clip(c) => duration = c.frame_count() as f64 / c.fps(),
            _ => {}
        }
    }
    let bands = app.plot_bands("simulate", "curves").unwrap();
    println!("{:?}", bands.iter().map(|b| (&b.name, b.start_secs, b.end_secs)).collect::<Vec<_>>());
    assert!(controllers.len() >= 2, "push_and_recover hands over from balance: {controllers:?}");
    assert_eq!(bands.iter().map(|b| b.name.as_str()).collect::<Vec<_>>(), controllers);
    assert_eq!(bands[0].start_secs, 0.0);
    for pair in bands.windows(2) {
        assert!((pair[1].start_secs - pair[0].end_secs).abs() < 1e-6, "no gap between activations: {pair:?}");
    }
    let end = bands.last().unwrap().end_secs;
    assert!((end - duration).abs() <= 1.0 / 30.0 + 1e-6, "the last ends with the clip ({duration} s): {end} s");
    harness.get_by_label("Controller timeline");
    harness.get_by_label_contains(&format!("{}: 0.000 – ", controllers[0]));
}

/// The stool a simulated character sits on is drawn with the clip, whether the simulation
/// or the export that writes it is on show; not for a node without props.
#[test]
fn the_stool_is_drawn_with_the_sitting_character() {
    let Some(path) = corpus_graph("sit_and_rise.ron") else { return };
    let mut harness = harness(Some(&path));
    for (node, triangles) in [("simulate", 12), ("glb", 12), ("character", 0)] {
        harness.state_mut().select(Some(node));
        harness.run_steps(3);
        assert_eq!(harness.state().viewport_props(), triangles, "{node}");
    }
}

/// Home fits the graph again after zooming, as when it was opened.
#[test]
fn home_frames_the_whole_graph_again() {
    let mut harness = harness(Some(&demo_path()));
    let opened = (harness.state().canvas_to_screen((0.0, 0.0)), harness.state().canvas_to_screen((100.0, 0.0)));
    harness.hover_at(harness.state().canvas_to_screen((330.0, 20.0)));
    harness.run_steps(1);
    wheel_step(&mut harness, 60.0);
    harness.run_steps(2);
    assert_ne!(harness.state().canvas_to_screen((100.0, 0.0)), opened.1, "zoomed");
    harness.key_press(egui::Key::Home);
    harness.run_steps(4);
    let framed = (harness.state().canvas_to_screen((0.0, 0.0)), harness.state().canvas_to_screen((100.0, 0.0)));
    assert!((framed.0 - opened.0).length() < 0.5 && (framed.1 - opened.1).length() < 0.5, "{framed:?} vs {opened:?}");
}

/// Down moves the add menu's highlight to the next kind it shows, and Enter adds that one.
#[test]
fn arrow_keys_pick_in_the_add_menu() {
    use egui_kittest::kittest::NodeT as _;
    let mut harness = harness(Some(&demo_path()));
    search_the_tab_menu(&mut harness, "motion.con");
    let registry = kinegraph::nodes::builtin::registry();
    // The kinds the menu shows, in its order (the canvas' titles are labels, not buttons).
    let shown: Vec<String> = harness
        .get_all_by_role(Role::Button)
        .filter_map(|n| n.accesskit_node().label())
        .filter(|l| registry.get(l).is_some())
        .collect();
    assert!(shown.len() >= 2, "{shown:?}");
    let before: Vec<String> = harness.state().doc().nodes.keys().cloned().collect();
    harness.key_press(egui::Key::ArrowDown);
    harness.run_steps(1);
    harness.key_press(egui::Key::Enter);
    harness.run_steps(3);
    let added: Vec<String> = harness
        .state()
        .doc()
        .nodes
        .iter()
        .filter(|(id, _)| !before.contains(id))
        .map(|(_, n)| n.kind.clone())
        .collect();
    assert_eq!(added, [shown[1].clone()], "{shown:?}");
}

/// A temporary folder holding the shipped walk (30 fps, 2 s) as `walk.bvh` and graph file
/// `name` with `text`.
fn in_walk_folder(name: &str, text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    std::fs::copy(assets.join("mannequin_walk.bvh"), dir.path().join("walk.bvh")).unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

/// A stage used as a subgraph: trim to 1 s, resample to 24 fps, `clip` in and out, the
/// end time promoted as `end`.
const CLEAN_STAGE: &str = r#"(format: "kinegraph.graph", version: 3,
 description: "trim and resample",
 inputs: { "end": "trim.end_secs" },
 nodes: {
   "trim": (kind: "clip.trim", params: { "end_secs": 1.0 }),
   "resample": (kind: "clip.resample", params: { "fps": 24.0 }),
 },
 edges: [ (from: "trim.clip", to: "resample.clip") ],
 layout: { "trim": (0.0, 0.0), "resample": (300.0, 0.0) },
 ports: ( inputs: { "clip": ["trim.clip"] }, outputs: { "clip": "resample.clip" } ))"#;

/// A folder with `staged.ron`: the shipped walk (30 fps, 2 s) → subgraph `clean`
/// (`stages/clean.ron`) → contacts, and a mesh node to wire wrongly.
fn staged_graph() -> (tempfile::TempDir, PathBuf) {
    let (dir, graph) = in_walk_folder(
        "staged.ron",
        r#"(format: "kinegraph.graph", version: 3,
 nodes: {
   "load": (kind: "clip.load", params: { "path": "walk.bvh" }),
   "clean": (kind: "graph.subgraph", params: { "file": "stages/clean.ron" }),
   "contacts": (kind: "motion.contacts"),
   "mesh": (kind: "mesh.load", params: { "path": "mannequin.glb" }),
 },
 edges: [ (from: "load.clip", to: "clean.clip"), (from: "clean.clip", to: "contacts.clip") ],
 layout: { "load": (0.0, 0.0), "clean": (300.0, 0.0), "contacts": (600.0, 0.0), "mesh": (0.0, 200.0) })"#,
    );
    let assets = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
    std::fs::copy(assets.join("mannequin.glb"), dir.path().join("mannequin.glb")).unwrap();
    std::fs::create_dir_all(dir.path().join("stages")).unwrap();
    std::fs::write(dir.path().join("stages/clean.ron"), CLEAN_STAGE).unwrap();
    (dir, graph)
}

fn clip_at(app: &EditorApp, id: &str, port: &str) -> std::sync::Arc<kinegraph::nodes::model::Clip> {
    match app.output(id, port) {
        Some(kinegraph::nodes::node::Value::Clip(c)) => c.clone(),
        other => panic!("{id}.{port}: {other:?}"),
    }
}

/// A subgraph node shows its file's ports as pins (it showed none, and its wires ended
/// nowhere), its state is its inner nodes', and its output is the stage's: 24 fps, 1 s,
/// where the walk it takes is 30 fps, 2 s.
#[test]
fn a_subgraph_node_shows_its_files_ports_state_and_output() {
    let (_dir, path) = staged_graph();
    let mut harness = harness(Some(&path));
    assert_eq!(harness.state().node_state("clean"), "ok");
    // The clip arriving at contacts comes out of the subgraph's pin.
    let out = clip_at(harness.state(), "clean", "clip");
    assert_eq!(out.fps(), 24.0);
    assert!((out.duration_secs() - 1.0).abs() < 1e-9, "{}", out.duration_secs());
    assert_eq!(clip_at(harness.state(), "load", "clip").fps(), 30.0);
    assert_eq!(harness.state().node_state("contacts"), "ok");
    // Its panel names the file, shows the promoted parameter with the file's value and
    // the ports, and it plays in the viewport.
    harness.get_by_label("clean").click_accesskit();
    harness.run_steps(3);
    harness.get_by_label_contains("stages/clean.ron");
    harness.get_by_label("trim and resample");
    harness.get_by_role_and_label(Role::SpinButton, "end");
    harness.get_by_label("pause");
    // Setting the promoted parameter on the node changes what comes out.
    let set = EditorCommand::SetParam { param: ParamPath::parse("clean.end").unwrap(), value: ParamValue::Float(0.5) };
    harness.state_mut().edit(set).unwrap();
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert!((clip_at(harness.state(), "clean", "clip").duration_secs() - 0.5).abs() < 1e-9);
}

/// Wiring a mesh into the subgraph's clip input is refused in the editor with the words
/// `kg check` gives for the same wire written in the file.
#[test]
fn a_wrong_wire_into_a_subgraph_is_refused_as_kg_check_refuses_it() {
    let (dir, path) = staged_graph();
    let mut harness = harness(Some(&path));
    let (from, to) = (PortRef::parse("mesh.mesh").unwrap(), PortRef::parse("clean.clip").unwrap());
    let refused = harness.state_mut().edit(EditorCommand::Connect { from, to }).unwrap_err().to_string();
    assert!(!harness.state().is_dirty());
    // The same wire in the file, checked as `kg check` does.
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(r#"(from: "load.clip", to: "clean.clip")"#, r#"(from: "mesh.mesh", to: "clean.clip")"#);
    let written = dir.path().join("wrong.ron");
    std::fs::write(&written, text).unwrap();
    let loaded = kinegraph::graph::GraphFile::load(&written).unwrap();
    let checked = kinegraph::engine::compile_file(&loaded, &kinegraph::nodes::builtin::registry()).err().unwrap();
    let words: Vec<&str> = checked.diagnostics.iter().map(|d| d.message.as_str()).collect();
    assert!(words.iter().any(|w| refused.contains(w)), "editor: {refused}\nkg check: {words:?}");
    assert!(refused.contains("mesh.mesh gives a mesh, but clean.clip takes a clip"), "{refused}");
}

/// Opening the subgraph edits its file in the editor, evaluated inside the graph it was
/// opened from (alone, its trim would have no clip); an unsaved change shows there at
/// once, and going back asks, saves the file, and the graph picks the change up.
#[test]
fn an_opened_subgraph_is_evaluated_in_its_graph_and_saved_on_the_way_back() {
    let (dir, path) = staged_graph();
    let mut harness = harness(Some(&path));
    right_click_title(&mut harness, "clean");
    harness.get_by_label("Open subgraph").click();
    harness.run_steps(2);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    let stage = dir.path().join("stages/clean.ron");
    assert_eq!(harness.state().path(), Some(stage.as_path()));
    assert_eq!(harness.state().subgraph_path(), [("staged.ron".to_string(), "clean".to_string())]);
    assert!(matches!(harness.state().node_state("trim"), "ok" | "cached"), "{}", harness.state().node_state("trim"));
    assert_eq!(clip_at(harness.state(), "trim", "clip").fps(), 30.0, "the walk, trimmed, arrives");
    // An unsaved edit inside is evaluated in the outer graph.
    let set =
        EditorCommand::SetParam { param: ParamPath::parse("resample.fps").unwrap(), value: ParamValue::Float(12.0) };
    harness.state_mut().edit(set).unwrap();
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert_eq!(clip_at(harness.state(), "resample", "clip").fps(), 12.0);
    assert_eq!(std::fs::read_to_string(&stage).unwrap(), CLEAN_STAGE, "not saved yet");
    // Back asks about the unsaved edit; saving writes the file and returns.
    harness.get_by_label("Back").click();
    harness.run_steps(2);
    harness.get_by_label("Save and go back").click();
    harness.run_steps(2);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert_eq!(harness.state().path(), Some(path.as_path()));
    assert!(harness.state().subgraph_path().is_empty());
    assert_eq!(harness.state().selected(), Some("clean"));
    assert!(!harness.state().is_dirty());
    let saved = kinegraph::graph::GraphFile::load(&stage).unwrap();
    assert_eq!(saved.graph.node("resample").unwrap().params.get("fps"), Some(&ParamValue::Float(12.0)));
    assert_eq!(clip_at(harness.state(), "clean", "clip").fps(), 12.0);
}

/// Collapsing `load` and `trim` of a flat pipeline into `stages/front.ron` changes nothing
/// it computes (the resampled clip is equal, frame for frame), the file's relative input
/// path is rewritten for its folder, the graph input on `trim` now sets the new node, and
/// undo gives back the flat graph byte for byte.
#[test]
fn collapsing_a_selection_into_a_subgraph_changes_no_result() {
    let (dir, path) = in_walk_folder(
        "flat.ron",
        r#"(format: "kinegraph.graph", version: 3,
 inputs: { "end": "trim.end_secs" },
 nodes: {
   "load": (kind: "clip.load", params: { "path": "walk.bvh" }),
   "trim": (kind: "clip.trim", params: { "end_secs": 1.5 }),
   "resample": (kind: "clip.resample", params: { "fps": 24.0 }),
 },
 edges: [ (from: "load.clip", to: "trim.clip"), (from: "trim.clip", to: "resample.clip") ],
 layout: { "load": (0.0, 0.0), "trim": (300.0, 0.0), "resample": (600.0, 0.0) })"#,
    );
    let mut harness = harness(Some(&path));
    let flat = document::to_string(&harness.state().doc());
    let before = clip_at(harness.state(), "resample", "clip");
    harness.get_by_label("load").click_accesskit();
    harness.run_steps(2);
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::SHIFT));
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    harness.event(egui::Event::ModifiersChanged(egui::Modifiers::NONE));
    harness.run_steps(1);
    assert_eq!(sorted(harness.state().selection()), ["load", "trim"]);
    let file = dir.path().join("stages/front.ron");
    std::fs::create_dir_all(file.parent().unwrap()).unwrap();
    harness.state_mut().collapse_selection(&file);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(3);

    let doc = harness.state().doc();
    assert_eq!(doc.nodes.keys().cloned().collect::<Vec<_>>(), ["front", "resample"]);
    assert_eq!(doc.nodes["front"].params.get("file"), Some(&ParamValue::Text("stages/front.ron".into())));
    assert_eq!(doc.inputs.get("end").map(String::as_str), Some("front.end"));
    let stage = kinegraph::graph::GraphFile::load(&file).unwrap().graph;
    assert_eq!(stage.node("load").unwrap().params.get("path"), Some(&ParamValue::Text("../walk.bvh".into())));
    assert_eq!(stage.ports().outputs.keys().cloned().collect::<Vec<_>>(), ["clip"]);
    assert!(stage.ports().inputs.is_empty());
    assert_eq!(harness.state().node_state("front"), "ok", "{:?}", harness.state().message());
    assert_eq!(*clip_at(harness.state(), "resample", "clip"), *before);
    // The promoted input still drives the trim, now through the subgraph.
    let set = EditorCommand::SetParam { param: ParamPath::parse("front.end").unwrap(), value: ParamValue::Float(0.5) };
    harness.state_mut().edit(set).unwrap();
    harness.state_mut().wait_for_evaluation();
    assert!((clip_at(harness.state(), "resample", "clip").duration_secs() - 0.5).abs() < 1e-9);
    harness.state_mut().undo();
    harness.state_mut().undo();
    assert_eq!(document::to_string(&harness.state().doc()), flat);
}

/// A click of `button` at `pos` (screen), as the pointer gives it.
fn click_at(harness: &mut Harness<'static, EditorApp>, pos: egui::Pos2, button: egui::PointerButton) {
    harness.event(egui::Event::PointerMoved(pos));
    harness.run_steps(1);
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton { pos, button, pressed, modifiers: egui::Modifiers::NONE });
        harness.run_steps(1);
    }
}

/// A click on a curve plot takes the viewport to that time, paused: a click further right
/// is later, and both fall inside the 2 s walk the curves were computed from.
#[test]
fn a_click_on_a_curve_plot_moves_the_viewport_there() {
    use egui_kittest::kittest::NodeT as _;
    let (_dir, path) = in_walk_folder(
        "momentum.ron",
        r#"(format: "kinegraph.graph", version: 3,
 nodes: {
   "load": (kind: "clip.load", params: { "path": "walk.bvh" }),
   "momentum": (kind: "motion.angular_momentum"),
 },
 edges: [ (from: "load.clip", to: "momentum.clip") ],
 layout: { "load": (0.0, 0.0), "momentum": (300.0, 0.0) })"#,
    );
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("momentum"));
    harness.run_steps(3);
    // The plot is drawn right below its channel toggles.
    let toggles = harness
        .get_all_by_role(Role::CheckBox)
        .filter(|n| n.accesskit_node().label().is_some_and(|l| l.contains('(')))
        .map(|n| n.rect())
        .reduce(|a, b| a.union(b))
        .unwrap();
    let y = toggles.bottom() + 90.0;
    let mut times = Vec::new();
    for x in [toggles.left() + 120.0, toggles.left() + 240.0] {
        click_at(&mut harness, egui::pos2(x, y), egui::PointerButton::Primary);
        harness.run_steps(2);
        let (secs, playing) = harness.state().viewport_time();
        assert!(!playing, "a click pauses");
        times.push(secs);
    }
    assert!(0.0 < times[0] && times[0] < times[1] && times[1] <= 2.0, "{times:?}");
}

/// An input file parameter has a browse button that opens a file picker in the folder of
/// the file it names; a picked file is written relative to the graph's folder, as graph
/// files keep paths.
#[test]
fn a_path_param_is_browsed_for_and_kept_relative() {
    let (dir, path) = staged_graph();
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("load"));
    harness.run_steps(2);
    harness.get_by_label("…").click();
    harness.run_steps(3);
    harness.get_by_label_contains("Open File");
    // What the picker hands back for a file in a subfolder is stored relative.
    let picked = dir.path().join("stages").join("walk.bvh");
    std::fs::copy(dir.path().join("walk.bvh"), &picked).unwrap();
    harness.state_mut().set_path_param(ParamPath::parse("load.path").unwrap(), &picked);
    assert_eq!(
        harness.state().doc().nodes["load"].params.get("path"),
        Some(&ParamValue::Text("stages/walk.bvh".into()))
    );
}

/// Zoomed out as far as the canvas goes (a fifth of full size), node titles grow against the zoom, so an
/// overview keeps readable ids: on screen at least twice the size plain text would have.
#[test]
fn titles_stay_readable_zoomed_far_out() {
    let mut harness = harness(Some(&demo_path()));
    let centre = harness.state().canvas_to_screen((300.0, 100.0));
    harness.hover_at(centre);
    harness.run_steps(1);
    let zoom = |h: &Harness<'static, EditorApp>| {
        (h.state().canvas_to_screen((100.0, 0.0)).x - h.state().canvas_to_screen((0.0, 0.0)).x) / 100.0
    };
    for _ in 0..40 {
        if zoom(&harness) < 0.201 {
            break;
        }
        wheel_step(&mut harness, -60.0);
    }
    harness.run_steps(3);
    let z = zoom(&harness);
    assert!(z < 0.201, "zoomed out to {z} (the canvas stops at 0.2)");
    let plain = egui::TextStyle::Body.resolve(&egui::Style::default()).size * z;
    let title = harness.get_by_label("resample").rect().height();
    assert!(title >= 2.0 * plain, "title {title:.1} px high at zoom {z:.3}; plain text would be {plain:.1}");
}

/// A row of nodes wider than the canvas at 1:1, with long ids.
fn wide_graph() -> (tempfile::TempDir, PathBuf) {
    let ids =
        ["load_the_walk", "trim_the_start", "resample_for_export", "trim_again_longer_name", "final_resample_step"];
    let mut nodes = String::new();
    let mut edges = String::new();
    let mut layout = String::new();
    for (i, id) in ids.iter().enumerate() {
        let (kind, params) = match i {
            0 => ("clip.load", r#"params: { "path": "walk.bvh" }"#),
            1 | 3 => ("clip.trim", ""),
            _ => ("clip.resample", ""),
        };
        nodes += &format!("\"{id}\": (kind: \"{kind}\", {params}),\n");
        layout += &format!("\"{id}\": ({}.0, 0.0),\n", i * 300);
        if i > 0 {
            edges += &format!("(from: \"{}.clip\", to: \"{id}.clip\"),\n", ids[i - 1]);
        }
    }
    in_walk_folder(
        "wide.ron",
        &format!(
            "(format: \"kinegraph.graph\", version: 3, nodes: {{ {nodes} }}, edges: [ {edges} ], layout: {{ {layout} }})"
        ),
    )
}

/// A graph opens with every node whole in view (the first view fitted node corners, so the
/// last node's body hung off the right edge), and F fits the selected node: it fills more of
/// the canvas, centred.
#[test]
fn a_graph_opens_fitted_whole_and_f_frames_the_selection() {
    let (_dir, path) = wide_graph();
    let mut harness = harness(Some(&path));
    harness.run_steps(3);
    let app = harness.state();
    for id in app.graph().nodes().keys() {
        let (node, canvas) = app.node_on_screen(id.as_str()).unwrap();
        assert!(canvas.contains_rect(node), "{id}: {node:?} outside the canvas {canvas:?}");
    }
    let before = app.node_on_screen("trim_the_start").unwrap().0;
    harness.get_by_label("trim_the_start").click_accesskit();
    harness.run_steps(2);
    harness.key_press(egui::Key::F);
    harness.run_steps(3);
    let (node, canvas) = harness.state().node_on_screen("trim_the_start").unwrap();
    assert!(node.width() > 1.3 * before.width(), "zoomed onto it (up to 1:1): {before:?} → {node:?}");
    assert!((node.center() - canvas.center()).length() < 2.0, "centred: {node:?} in {canvas:?}");
    assert!(canvas.contains_rect(node));
}

/// The node menu renames a node: its wires, position and selection follow, and undo gives
/// the file back byte for byte.
#[test]
fn a_node_is_renamed_from_its_menu_with_its_wires() {
    let mut harness = harness(Some(&demo_path()));
    let before = document::to_string(&harness.state().doc());
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    right_click_title(&mut harness, "trim");
    harness.get_by_role(Role::TextInput).focus();
    harness.run_steps(1);
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness.run_steps(1);
    harness.get_by_role(Role::TextInput).type_text("first_second");
    harness.run_steps(1);
    harness.key_press(egui::Key::Enter);
    harness.run_steps(3);
    let doc = harness.state().doc();
    assert!(
        doc.nodes.get("first_second").is_some_and(|n| n.kind == "clip.trim") && !doc.nodes.contains_key("trim"),
        "{:?}",
        doc.nodes.keys().collect::<Vec<_>>()
    );
    let wires: Vec<(String, String)> = doc.edges.iter().map(|e| (e.from.clone(), e.to.clone())).collect();
    assert!(wires.contains(&("clip.clip".into(), "first_second.clip".into())), "{wires:?}");
    assert!(wires.contains(&("first_second.clip".into(), "resample.clip".into())), "{wires:?}");
    assert!(doc.layout.contains_key("first_second"));
    assert_eq!(harness.state().selection(), ["first_second"]);
    harness.state_mut().wait_for_evaluation();
    assert!(matches!(harness.state().node_state("resample"), "ok" | "cached"));
    harness.state_mut().undo();
    assert_eq!(document::to_string(&harness.state().doc()), before);
}

/// The viewport marks the synthesised transitions of a sequence under its timeline, where
/// the sequence's report puts them (output frames at the clip's own frame rate).
#[test]
fn transitions_are_marked_under_the_timeline() {
    let Some(path) = corpus_graph("walk_punch_kick.ron") else { return };
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("sequence"));
    harness.run_steps(3);
    let app = harness.state();
    let fps = clip_at(app, "sequence", "clip").fps();
    let report = match app.output("sequence", "report") {
        Some(kinegraph::nodes::node::Value::Report(r)) => r.clone(),
        other => panic!("{other:?}"),
    };
    let expected: Vec<(f64, f64)> = report
        .get("transitions")
        .unwrap()
        .as_array()
        .unwrap()
        .iter()
        .map(|t| (t["frames"]["start"].as_f64().unwrap() / fps, t["frames"]["end"].as_f64().unwrap() / fps))
        .collect();
    assert!(expected.len() >= 2, "walk → punch → kick joins twice: {expected:?}");
    let marked: Vec<(f64, f64)> =
        app.viewport_bands().iter().filter(|b| b.name == "transition").map(|b| (b.start_secs, b.end_secs)).collect();
    assert_eq!(marked.len(), expected.len());
    for (m, e) in marked.iter().zip(&expected) {
        assert!((m.0 - e.0).abs() < 1e-9 && (m.1 - e.1).abs() < 1e-9, "{m:?} vs {e:?}");
    }
}

/// A subgraph node's file is a parameter like any input file: pointing it at another stage
/// gives the node that stage's ports at once, a wire from a port the new file lacks is an
/// error on the node naming the ports it has, and rewired it runs.
#[test]
fn a_subgraph_nodes_file_is_edited_in_its_panel() {
    let (dir, path) = staged_graph();
    std::fs::write(
        dir.path().join("stages/slow.ron"),
        CLEAN_STAGE.replace(r#"outputs: { "clip": "resample.clip" }"#, r#"outputs: { "slow": "resample.clip" }"#),
    )
    .unwrap();
    let mut harness = harness(Some(&path));
    harness.get_by_label("clean").click_accesskit();
    harness.run_steps(3);
    let field = harness.get_by_role_and_label(Role::TextInput, "file");
    field.focus();
    harness.run_steps(1);
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness.get_by_role_and_label(Role::TextInput, "file").type_text("stages/slow.ron");
    harness.key_press(egui::Key::Enter);
    harness.run_steps(2);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert_eq!(
        harness.state().doc().nodes["clean"].params.get("file"),
        Some(&ParamValue::Text("stages/slow.ron".into()))
    );
    // The old wire from `clean.clip` now names a port the file does not show: the node says so.
    assert_eq!(harness.state().node_state("clean"), "error");
    harness.get_by_label_contains("has no output 'clip'; it shows slow");
    // Rewired from the new pin, it runs.
    let (old, new) = (PortRef::parse("clean.clip").unwrap(), PortRef::parse("clean.slow").unwrap());
    let contacts = PortRef::parse("contacts.clip").unwrap();
    let rewire = EditorCommand::Batch(vec![
        EditorCommand::Disconnect { from: old, to: contacts.clone() },
        EditorCommand::Connect { from: new, to: contacts },
    ]);
    harness.state_mut().edit(rewire).unwrap();
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert_eq!(clip_at(harness.state(), "clean", "slow").fps(), 24.0);
    assert!(matches!(harness.state().node_state("contacts"), "ok" | "cached"));
}

/// Bypass from the node menu: the node passes its clip on (so what follows gets the whole
/// clip, not the trimmed second), shows `bypassed`, is saved as such; B on the selection
/// lets it run again, and undo bypasses it once more.
#[test]
fn a_bypassed_node_passes_its_input_through_and_b_toggles_it() {
    let mut harness = harness(Some(&demo_path()));
    let whole = clip_at(harness.state(), "clip", "clip").duration_secs();
    let trimmed = clip_at(harness.state(), "resample", "clip").duration_secs();
    assert!((trimmed - 1.0).abs() < 0.05 && whole > 1.5, "trimmed {trimmed} s of {whole} s");
    right_click_title(&mut harness, "trim");
    harness.get_by_label("Bypass").click();
    harness.run_steps(1);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    let app = harness.state();
    assert_eq!(app.node_state("trim"), "bypassed");
    assert!(app.doc().nodes["trim"].bypass);
    let passed = clip_at(app, "resample", "clip").duration_secs();
    assert!((passed - whole).abs() < 0.05, "resample got {passed} s, the whole clip is {whole} s");
    // B with trim selected lets it run again.
    harness.get_by_label("trim").click_accesskit();
    harness.run_steps(2);
    harness.key_press(egui::Key::B);
    harness.run_steps(1);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert!(!harness.state().doc().nodes["trim"].bypass);
    assert!((clip_at(harness.state(), "resample", "clip").duration_secs() - trimmed).abs() < 1e-9);
    // One undo step puts the bypass back.
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    harness.run_steps(1);
    harness.state_mut().wait_for_evaluation();
    harness.run_steps(2);
    assert!(harness.state().doc().nodes["trim"].bypass);
    assert_eq!(harness.state().node_state("trim"), "bypassed");
}

/// Output labels end in one column clear of their pins, however many outputs a node has
/// (every output row after the first shifted right by a pin's width, so `report`, third
/// on `skeleton.map`, ran under its pin and read "repo").
#[test]
fn output_labels_end_in_one_column_clear_of_their_pins() {
    let graph = r#"(format: "kinegraph.graph", version: 2,
 nodes: { "map": (kind: "skeleton.map") }, layout: { "map": (0.0, 0.0) })"#;
    let (_dir, path) = in_walk_folder("map.ron", graph);
    let mut harness = harness(Some(&path));
    harness.run_steps(4);
    // "map" is also the node's title, further left: the output label is the rightmost.
    let right = |label: &str| harness.get_all_by_label(label).map(|n| n.rect().right()).fold(f32::MIN, f32::max);
    let (clip, map, report) = (right("clip"), right("map"), right("report"));
    assert!((clip - map).abs() < 0.5 && (clip - report).abs() < 0.5, "label ends: {clip}, {map}, {report}");
    // The pins sit on the node's right edge (the frame, just outside its content): a
    // label must end at least a pin's radius (5.4 px) before the content's edge.
    let content_right = harness.state().node_on_screen("map").unwrap().0.right();
    assert!(report < content_right - 5.4, "report ends at {report}, the node's content at {content_right}");
}

/// Text and path fields are wide enough to read a path or a body list (they were drawn
/// 100 px wide, the width their grid column had, whatever their content).
#[test]
fn text_fields_are_wide_enough_to_read() {
    let (_dir, path) = staged_graph();
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("load"));
    harness.run_steps(3);
    let width = harness.get_by_role_and_label(Role::TextInput, "path").rect().width();
    assert!(width >= 200.0, "the path field is {width} px wide");
}

/// The centre of mass's path is drawn with the clip a stages node plays, its dot where the
/// node's own curves put it: at the flight's apex it is drawn higher than at the start of
/// the jump and than at the landing.
#[test]
fn the_centre_of_mass_is_drawn_where_the_stages_curves_put_it() {
    let Some(path) = corpus_graph("jump_stages.ron") else { return };
    let mut harness = harness(Some(&path));
    harness.state_mut().select(Some("stages"));
    harness.run_steps(3);
    let curves = match harness.state().output("stages", "curves") {
        Some(kinegraph::nodes::node::Value::Curves(c)) => c.clone(),
        other => panic!("stages.curves: {other:?}"),
    };
    let values = |name: &str| curves.channel(name).unwrap().values.clone();
    let (height, flight) = (values("com.y"), values("flight"));
    let in_flight: Vec<usize> = (0..flight.len()).filter(|&f| flight[f] > 0.5).collect();
    let apex = *in_flight.iter().max_by(|a, b| height[**a].total_cmp(&height[**b])).unwrap();
    let landed = in_flight.last().unwrap() + 1;
    let drawn_at = |harness: &mut Harness<'static, EditorApp>, frame: usize| {
        // The middle of the frame, so the slider's rounding cannot pick its neighbour.
        seek(harness, (frame as f64 + 0.5) / curves.fps());
        harness.state().viewport_com().unwrap()
    };
    let (start, top, end) = (drawn_at(&mut harness, 0), drawn_at(&mut harness, apex), drawn_at(&mut harness, landed));
    println!(
        "com.y {:.3} / {:.3} / {:.3} m drawn at y {} / {} / {}",
        height[0], height[apex], height[landed], start.y, top.y, end.y
    );
    assert!(height[apex] > height[0] + 0.1 && height[apex] > height[landed] + 0.1);
    assert!(top.y < start.y - 5.0 && top.y < end.y - 5.0, "apex drawn at {top:?}, start {start:?}, landing {end:?}");
}
