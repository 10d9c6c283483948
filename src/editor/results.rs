//! What the selected node produced besides clips, at the bottom of the panel: its report
//! as a readable tree, its curves as a plot with its phases or ground and flight stages
//! shaded behind, its phases, stages and foot contacts as time ranges.

use std::collections::{BTreeMap, BTreeSet};

use egui::{CollapsingHeader, Color32, RichText, Ui};
use egui_plot::{Line, Plot, Span};
use kinegraph_nodes::model::{Contacts, Curves, FrameRange, Phases, StageKind, Stages};
use kinegraph_nodes::node::{PortSpec, Value};
use serde_json::Value as Json;

/// Which curve channels the user turned on, per node and port.
#[derive(Default)]
pub(crate) struct ResultsState {
    /// `node.port.channel` of every channel switched on.
    shown: BTreeSet<String>,
    /// `node.port` whose default channels were already switched on once.
    initialised: BTreeSet<String>,
    /// The bands shaded behind each curve plot (`node.port`) when it was last drawn.
    bands: BTreeMap<String, Vec<Band>>,
}

impl ResultsState {
    /// The bands shaded behind the curve plot of `node`'s output `port` when it was last
    /// drawn.
    pub(crate) fn bands(&self, node: &str, port: &str) -> Option<&[Band]> {
        self.bands.get(&format!("{node}.{port}")).map(Vec::as_slice)
    }
}

/// A time range shaded behind a curve plot: a phase or a stage.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    /// `preparatory`, `main`, `posterior`, `ground` or `flight`.
    pub name: &'static str,
    /// Start, seconds.
    pub start_secs: f64,
    /// End, seconds.
    pub end_secs: f64,
}

/// Draws the results of node `id`: one section per non-clip output. `inputs` are the values
/// it took: stages it was given (as momentum splines are) shade its curves too.
pub(crate) fn show(
    ui: &mut Ui,
    state: &mut ResultsState,
    id: &str,
    ports: &[PortSpec],
    outputs: &[Option<Value>],
    inputs: &[Value],
) {
    // Phases or stages the node gives (else the stages it takes) are shaded on its curve plots.
    let phases = outputs.iter().flatten().find_map(|v| match v {
        Value::Phases(p) => Some(phase_bands(p)),
        _ => None,
    });
    let stages = outputs.iter().flatten().chain(inputs).find_map(|v| match v {
        Value::Stages(s) => Some(stage_bands(s)),
        _ => None,
    });
    let bands = phases.or(stages).unwrap_or_default();
    for (port, value) in ports.iter().zip(outputs) {
        let key = format!("{id}.{}", port.name);
        match value {
            Some(Value::Report(report)) => {
                CollapsingHeader::new(format!("Report ({})", port.name)).id_salt(&key).default_open(true).show(
                    ui,
                    |ui| {
                        for (name, v) in report.iter() {
                            json_row(ui, &format!("{key}.{name}"), name, v);
                        }
                    },
                );
            }
            Some(Value::Curves(curves)) => {
                CollapsingHeader::new(format!("Curves ({})", port.name))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| curves_plot(ui, state, &key, curves, &bands));
            }
            Some(Value::Phases(phases)) => {
                CollapsingHeader::new(format!("Phases ({})", port.name))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| phases_text(ui, phases));
            }
            Some(Value::Stages(stages)) => {
                CollapsingHeader::new(format!("Stages ({})", port.name))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| stages_text(ui, stages));
            }
            Some(Value::Contacts(contacts)) => {
                CollapsingHeader::new(format!("Contacts ({})", port.name))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| contacts_text(ui, contacts));
            }
            _ => {}
        }
    }
}

/// One key of a report: scalars on one line, objects and arrays of objects nested.
fn json_row(ui: &mut Ui, salt: &str, name: &str, value: &Json) {
    match value {
        Json::Object(map) => {
            CollapsingHeader::new(name).id_salt(salt).show(ui, |ui| {
                for (k, v) in map {
                    json_row(ui, &format!("{salt}.{k}"), k, v);
                }
            });
        }
        Json::Array(items) if items.iter().any(|i| i.is_object() || i.is_array()) => {
            CollapsingHeader::new(format!("{name} ({})", items.len())).id_salt(salt).show(ui, |ui| {
                for (i, v) in items.iter().enumerate() {
                    json_row(ui, &format!("{salt}[{i}]"), &i.to_string(), v);
                }
            });
        }
        other => {
            ui.horizontal_wrapped(|ui| {
                ui.label(RichText::new(name).weak());
                ui.label(scalar_text(other));
            });
        }
    }
}

/// A report scalar (or flat array) for reading: reals to four significant digits.
fn scalar_text(value: &Json) -> String {
    match value {
        Json::Number(n) if n.is_f64() => n.as_f64().map(|x| format!("{x:.4}")).unwrap_or_default(),
        Json::Array(items) => format!("[{}]", items.iter().map(scalar_text).collect::<Vec<_>>().join(", ")),
        Json::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// The phases as bands.
fn phase_bands(p: &Phases) -> Vec<Band> {
    [("preparatory", p.preparatory), ("main", Some(p.main)), ("posterior", p.posterior)]
        .into_iter()
        .filter_map(|(name, range)| range.map(|r| band(name, r, p.fps)))
        .collect()
}

/// The ground and flight stages as bands.
fn stage_bands(s: &Stages) -> Vec<Band> {
    s.stages.iter().map(|stage| band(stage_name(stage.kind), stage.frames, s.fps)).collect()
}

fn band(name: &'static str, range: FrameRange, fps: f64) -> Band {
    Band { name, start_secs: range.start as f64 / fps, end_secs: range.end as f64 / fps }
}

fn stage_name(kind: StageKind) -> &'static str {
    match kind {
        StageKind::Ground => "ground",
        StageKind::Flight => "flight",
    }
}

/// The fill of a band: phases blue, red, green; ground stages brown, flights sky blue.
fn band_colour(name: &str) -> Color32 {
    match name {
        "preparatory" => Color32::from_rgba_unmultiplied(90, 140, 255, 40),
        "main" => Color32::from_rgba_unmultiplied(255, 110, 90, 40),
        "posterior" => Color32::from_rgba_unmultiplied(110, 220, 130, 40),
        "ground" => Color32::from_rgba_unmultiplied(170, 120, 70, 45),
        _ => Color32::from_rgba_unmultiplied(120, 200, 255, 45),
    }
}

/// Checkboxes per channel and one plot against time (seconds), `bands` shaded behind. The
/// first channel's unit is shown by default, so the first view has one scale.
fn curves_plot(ui: &mut Ui, state: &mut ResultsState, key: &str, curves: &Curves, bands: &[Band]) {
    let channels = curves.channels();
    if state.initialised.insert(key.to_string()) {
        let unit = channels.first().map(|c| c.unit.clone()).unwrap_or_default();
        for c in channels.iter().filter(|c| c.unit == unit) {
            state.shown.insert(format!("{key}.{}", c.name));
        }
    }
    // The channel toggles are the legend, in the lines' colours, above the plot rather than
    // over its curves.
    ui.horizontal_wrapped(|ui| {
        for (i, c) in channels.iter().enumerate() {
            let id = format!("{key}.{}", c.name);
            let mut on = state.shown.contains(&id);
            let label = RichText::new(format!("{} ({})", c.name, c.unit)).color(channel_colour(i));
            if ui.checkbox(&mut on, label).changed() {
                if on {
                    state.shown.insert(id);
                } else {
                    state.shown.remove(&id);
                }
            }
        }
    });
    let fps = curves.fps();
    let unit = channels.iter().find(|c| state.shown.contains(&format!("{key}.{}", c.name))).map(|c| c.unit.clone());
    // A y axis wide enough for its tick labels (a narrow one showed only "0").
    let plot = Plot::new(format!("{key}.plot")).height(180.0).x_axis_label("s").y_axis_min_width(52.0);
    plot.y_axis_label(unit.unwrap_or_default()).show(ui, |plot| {
        for b in bands {
            plot.span(Span::new(b.name, b.start_secs..=b.end_secs).fill(band_colour(b.name)));
        }
        for (i, c) in channels.iter().enumerate().filter(|(_, c)| state.shown.contains(&format!("{key}.{}", c.name))) {
            let points: Vec<[f64; 2]> = c.values.iter().enumerate().map(|(i, v)| [i as f64 / fps, *v]).collect();
            plot.line(Line::new(c.name.clone(), points).color(channel_colour(i)));
        }
    });
    state.bands.insert(key.to_string(), bands.to_vec());
}

/// The colour of channel `i` of a curve set: the toggles and the lines share it.
fn channel_colour(i: usize) -> Color32 {
    const PALETTE: [Color32; 8] = [
        Color32::from_rgb(90, 160, 255),
        Color32::from_rgb(255, 140, 70),
        Color32::from_rgb(110, 210, 120),
        Color32::from_rgb(230, 90, 200),
        Color32::from_rgb(240, 220, 80),
        Color32::from_rgb(80, 220, 220),
        Color32::from_rgb(200, 200, 200),
        Color32::from_rgb(170, 120, 255),
    ];
    PALETTE[i % PALETTE.len()]
}

fn seconds(range: FrameRange, fps: f64) -> String {
    format!("{:.3} – {:.3} s", range.start as f64 / fps, range.end as f64 / fps)
}

fn phases_text(ui: &mut Ui, phases: &Phases) {
    let fps = phases.fps;
    ui.label(format!("main-phase peak at {:.3} s", phases.main_frame as f64 / fps));
    for (name, range) in
        [("preparatory", phases.preparatory), ("main", Some(phases.main)), ("posterior", phases.posterior)]
    {
        ui.label(match range {
            Some(r) => format!("{name}: {}", seconds(r, fps)),
            None => format!("{name}: none"),
        });
    }
}

fn contacts_text(ui: &mut Ui, contacts: &Contacts) {
    let fps = contacts.fps;
    let total = |rs: &[FrameRange]| rs.iter().map(|r| r.len()).sum::<usize>() as f64 / fps;
    for foot in &contacts.feet {
        ui.label(format!("{}: {} contacts, {:.2} s planted", foot.foot, foot.intervals.len(), total(&foot.intervals)));
    }
    ui.label(format!(
        "double support: {} spans, {:.2} s",
        contacts.double_support.len(),
        total(&contacts.double_support)
    ));
}

fn stages_text(ui: &mut Ui, stages: &Stages) {
    ui.label(format!("gravity fitted to the flights: {:.3} m/s²", stages.gravity_mps2));
    for (i, stage) in stages.stages.iter().enumerate() {
        ui.label(format!("{i}: {}, {}", stage_name(stage.kind), seconds(stage.frames, stages.fps)));
    }
}
