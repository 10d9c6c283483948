//! The parameter panel of the selected node: its doc text, ports, parameters with their
//! ranges and units, and its state from the latest run. Edits come back as commands: a
//! typed number or text commits on Enter or focus loss (one evaluation, one undo step), a
//! drag is one undo step.

use egui::{RichText, Ui};
use kinegraph_nodes::node::{ParamKind, ParamSpec, ParamValue, Registry};

use super::canvas::{Badge, Face, dot, type_color};
use super::commands::EditorCommand;
use crate::engine::{NodeReport, SubgraphFace};
use crate::graph::{Graph, ParamPath, Side};

/// A parameter edit and whether it continues the previous one (a drag in progress), so
/// a whole drag is one undo step.
pub(crate) struct PanelEdit {
    /// The edit.
    pub(crate) command: EditorCommand,
    /// Merge with the previous step of the same label.
    pub(crate) coalesce: bool,
}

/// Text being typed into path fields, kept until Enter or focus loss, and a file asked for.
#[derive(Default)]
pub(crate) struct PanelState {
    /// An input file or folder parameter whose browse button was pressed, and whether it
    /// takes a folder.
    pub(crate) browse: Option<(ParamPath, bool)>,
    /// `(node, param, text)` of the field being edited.
    editing: Option<(String, String, String)>,
    /// Width of text and path fields this frame, points: what the panel leaves beside the
    /// names and buttons (a grid cell only offers the width its column had before).
    text_width: f32,
}

/// Narrowest and widest text and path fields, points: a relative path to a corpus file
/// fits the widest.
const TEXT_WIDTH: std::ops::RangeInclusive<f32> = 160.0..=360.0;

/// The panel's width beside a text field: the names' column and the browse and reset buttons.
const BESIDE_TEXT: f32 = 170.0;

/// How much a number changes per point dragged: 0.5 % of its size, so a drag moves fps 24
/// by about 0.1 per point and a radius of 0.5 by 0.0025, kept between a millionth and a
/// five-hundredth of the param's range (an unbounded range counts as ±1e6).
fn drag_speed(value: f64, min: f64, max: f64) -> f64 {
    let range = max.min(1e6) - min.max(-1e6);
    (value.abs() * 5e-3).clamp(range * 1e-6, range / 500.0).max(1e-6)
}

/// A parameter as the panel shows it: its name, spec and the value shown.
type ParamShown<'a> = (&'a str, &'static ParamSpec, Option<&'a ParamValue>);

/// Draws the panel for node `id`; `face` is its file's when it is a subgraph node.
#[allow(clippy::too_many_arguments)]
pub(crate) fn show(
    ui: &mut Ui,
    state: &mut PanelState,
    graph: &Graph,
    registry: &Registry,
    face: Option<&SubgraphFace>,
    id: &str,
    badge: &Badge,
    report: Option<&NodeReport>,
) -> Vec<PanelEdit> {
    let mut edits = Vec::new();
    let Some(node) = graph.node(id) else { return edits };
    ui.heading(id);
    // (name, spec, value shown) per parameter: a subgraph's are its file's graph inputs,
    // shown with the value the file gives them until the node sets its own.
    let (params, ports): (Vec<ParamShown<'_>>, Face<'_>) = match face {
        Some(face) => {
            ui.label(RichText::new(format!("{} · {}", node.kind, face.path.display())).weak());
            ui.label(&face.description);
            let file = &crate::engine::FILE_PARAM_SPEC;
            let params = std::iter::once((file.name, file, node.params.get(file.name)))
                .chain(
                    face.params
                        .iter()
                        .map(|p| (p.name.as_str(), p.spec, node.params.get(&p.name).or(p.value.as_ref()))),
                )
                .collect();
            (params, Face::Subgraph(face))
        }
        None => {
            let Some(schema) = registry.get(&node.kind).map(|n| n.schema()) else {
                let what = if node.kind == crate::document::SUBGRAPH_KIND {
                    "its subgraph file cannot be read (see its state)".to_string()
                } else {
                    format!("unknown node kind '{}'", node.kind)
                };
                ui.colored_label(egui::Color32::RED, what);
                return edits;
            };
            ui.label(RichText::new(format!("{} · {}", schema.kind, schema.category)).weak());
            ui.label(schema.doc);
            (schema.params.iter().map(|p| (p.name, p, node.params.get(p.name))).collect(), Face::Kind(schema))
        }
    };
    let (text, color) = badge.label();
    ui.horizontal(|ui| {
        ui.label("State:");
        ui.label(RichText::new(text).color(color).strong());
        if let Some(r) = report
            && r.seconds > 0.0
        {
            ui.label(RichText::new(format!("{:.1} ms", r.seconds * 1e3)).weak());
        }
        if face.is_none() {
            let mut bypass = node.bypass;
            let tip = "skip the node: each output passes on an input of its type (B)";
            if ui.checkbox(&mut bypass, "Bypass").on_hover_text(tip).changed() {
                edits.push(PanelEdit { command: EditorCommand::SetBypass { id: id.into(), bypass }, coalesce: false });
            }
        }
    });
    if let Some(message) = badge.message() {
        ui.label(RichText::new(message).color(color));
    }
    for warning in report.map(|r| r.warnings.as_slice()).unwrap_or_default() {
        ui.label(RichText::new(format!("warning: {warning}")).color(egui::Color32::from_rgb(230, 190, 60)));
    }
    ui.separator();
    if !params.is_empty() {
        ui.label(RichText::new("Parameters").strong());
    }
    state.text_width = (ui.available_width() - BESIDE_TEXT).clamp(*TEXT_WIDTH.start(), *TEXT_WIDTH.end());
    egui::Grid::new("params").num_columns(3).striped(true).show(ui, |ui| {
        for (name, spec, value) in params {
            // A subgraph's file has no default to go back to.
            let resettable = node.params.contains_key(name) && !std::ptr::eq(spec, &crate::engine::FILE_PARAM_SPEC);
            param_row(ui, state, id, name, spec, value, resettable, &mut edits);
            ui.end_row();
        }
    });
    ui.separator();
    for (title, side) in [("Inputs", Side::Input), ("Outputs", Side::Output)] {
        if ports.count(side) == 0 {
            continue;
        }
        ui.label(RichText::new(title).strong());
        for p in ports.pins(side) {
            ui.horizontal_wrapped(|ui| {
                dot(ui, type_color(p.ty));
                ui.label(RichText::new(p.name).color(type_color(p.ty)));
                ui.label(RichText::new(p.ty.name()).weak());
                ui.label(p.doc);
            });
        }
    }
    edits
}

/// One parameter's row: its name, a field for `value` (the value shown: set, or the
/// default), and a reset button when the node sets it (`is_set`).
#[allow(clippy::too_many_arguments)]
fn param_row(
    ui: &mut Ui,
    state: &mut PanelState,
    id: &str,
    name: &str,
    spec: &'static ParamSpec,
    set: Option<&ParamValue>,
    is_set: bool,
    edits: &mut Vec<PanelEdit>,
) {
    let name_label = ui.label(name).on_hover_text(spec.doc);
    let set_cmd = |value: ParamValue| EditorCommand::SetParam { param: ParamPath::new(id, name), value };
    match spec.kind {
        ParamKind::Float { default, min, max, unit } => {
            let current = set.and_then(ParamValue::as_f64).or(default);
            match current {
                Some(mut x) => {
                    let speed = drag_speed(x, min, max);
                    let r = ui
                        .add(
                            egui::DragValue::new(&mut x)
                                .range(min..=max)
                                .speed(speed)
                                .update_while_editing(false)
                                .suffix(if unit.is_empty() { String::new() } else { format!(" {unit}") }),
                        )
                        .labelled_by(name_label.id);
                    let r = r.on_hover_text(format!("{}\nrange {min} ..= {max} {unit}", spec.doc));
                    if r.changed() {
                        edits.push(PanelEdit {
                            command: set_cmd(ParamValue::Float(x)),
                            coalesce: r.dragged() && !r.drag_started(),
                        });
                    }
                }
                None => {
                    if ui.button("auto — set").on_hover_text(spec.doc).clicked() {
                        let x = if min <= 0.0 && max >= 0.0 { 0.0 } else { min };
                        edits.push(PanelEdit { command: set_cmd(ParamValue::Float(x)), coalesce: false });
                    }
                }
            }
        }
        ParamKind::Int { default, min, max } => match set.and_then(ParamValue::as_f64).map(|x| x as i64).or(default) {
            Some(mut i) => {
                let speed = drag_speed(i as f64, min as f64, max as f64).max(0.05);
                let r = ui
                    .add(egui::DragValue::new(&mut i).range(min..=max).speed(speed).update_while_editing(false))
                    .labelled_by(name_label.id);
                let r = r.on_hover_text(format!("{}\nrange {min} ..= {max}", spec.doc));
                if r.changed() {
                    edits.push(PanelEdit {
                        command: set_cmd(ParamValue::Int(i)),
                        coalesce: r.dragged() && !r.drag_started(),
                    });
                }
            }
            None => {
                if ui.button("auto — set").on_hover_text(spec.doc).clicked() {
                    edits.push(PanelEdit { command: set_cmd(ParamValue::Int(min.max(0))), coalesce: false });
                }
            }
        },
        ParamKind::Choice { choices, default } => {
            let current = match set {
                Some(ParamValue::Text(s)) => s.as_str(),
                _ => default,
            };
            egui::ComboBox::from_id_salt(("choice", id, name)).selected_text(current).show_ui(ui, |ui| {
                for choice in choices {
                    if ui.selectable_label(*choice == current, *choice).clicked() && *choice != current {
                        edits.push(PanelEdit {
                            command: set_cmd(ParamValue::Text((*choice).to_string())),
                            coalesce: false,
                        });
                    }
                }
            });
        }
        ParamKind::InputPath { .. }
        | ParamKind::InputFolder { .. }
        | ParamKind::OutputPath { .. }
        | ParamKind::Text { .. } => {
            let stored = match set {
                Some(ParamValue::Text(s)) => s.clone(),
                _ => spec.default_value().map(|v| v.to_string().trim_matches('"').to_string()).unwrap_or_default(),
            };
            // One grid cell for the field and its browse button: in a grid each widget
            // takes a column of its own.
            ui.horizontal(|ui| {
                let editing = state.editing.as_ref().filter(|(n, p, _)| n == id && p == name);
                let mut text = editing.map(|(_, _, t)| t.clone()).unwrap_or_else(|| stored.clone());
                let r = ui
                    .add_sized([state.text_width, ui.spacing().interact_size.y], egui::TextEdit::singleline(&mut text))
                    .labelled_by(name_label.id)
                    .on_hover_text(spec.doc);
                if r.changed() || r.has_focus() {
                    state.editing = Some((id.to_string(), name.to_string(), text.clone()));
                }
                if r.lost_focus() {
                    state.editing = None;
                    if text != stored {
                        edits.push(PanelEdit { command: set_cmd(ParamValue::Text(text)), coalesce: false });
                    }
                }
                let folder = matches!(spec.kind, ParamKind::InputFolder { .. });
                if matches!(spec.kind, ParamKind::InputPath { .. } | ParamKind::InputFolder { .. })
                    && ui
                        .small_button("…")
                        .on_hover_text(if folder { "pick a folder" } else { "pick a file" })
                        .clicked()
                {
                    state.browse = Some((ParamPath::new(id, name), folder));
                }
            });
        }
    }
    if is_set {
        if ui.small_button("reset").on_hover_text("reset to the default").clicked() {
            edits.push(PanelEdit {
                command: EditorCommand::ResetParam { param: ParamPath::new(id, name) },
                coalesce: false,
            });
        }
    } else {
        ui.label("");
    }
}
