//! What the selected node produced besides clips, at the bottom of the panel: its report
//! as a readable tree, its curves as a plot with its phases, ground and flight stages or
//! controller activations shaded behind, its phases, stages, controller timeline and foot
//! contacts as time ranges.

use std::collections::{BTreeMap, BTreeSet};

use egui::{CollapsingHeader, Color32, RichText, Ui};
use egui_plot::{Line, Plot, Span, VLine};
use kinegraph_nodes::model::{Contacts, Curves, FrameRange, Phases, StageKind, Stages};
use kinegraph_nodes::node::{Report, Value};
use serde_json::Value as Json;

/// Which curve channels the user turned on, per node and port, and the viewport's time the
/// plots mark.
#[derive(Default)]
pub(crate) struct ResultsState {
    /// The viewport's time (seconds), drawn as a line on every curve plot.
    pub(crate) playhead: f64,
    /// A time picked by a click on a curve plot, for the viewport to jump to.
    pub(crate) seek: Option<f64>,
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

/// A time range shaded behind a curve plot: a phase, a stage or a controller's activation.
#[derive(Clone, Debug, PartialEq)]
pub struct Band {
    /// `preparatory`, `main`, `posterior`, `ground`, `flight` or the controller's name.
    pub name: String,
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
    outputs: &[(String, Option<Value>)],
    inputs: &[Value],
) {
    let given: Vec<&Value> = outputs.iter().filter_map(|(_, v)| v.as_ref()).collect();
    let bands = time_bands(&given, &inputs.iter().collect::<Vec<_>>());
    for (port, value) in outputs {
        let key = format!("{id}.{port}");
        match value {
            Some(Value::Report(report)) => {
                CollapsingHeader::new(format!("Report ({port})")).id_salt(&key).default_open(true).show(ui, |ui| {
                    for (name, v) in report.iter() {
                        json_row(ui, &format!("{key}.{name}"), name, v);
                    }
                });
                let timeline = timeline_of(report);
                if !timeline.is_empty() {
                    CollapsingHeader::new("Controller timeline")
                        .id_salt(format!("{key}.timeline"))
                        .default_open(true)
                        .show(ui, |ui| timeline_strip(ui, &timeline));
                }
            }
            Some(Value::Curves(curves)) => {
                CollapsingHeader::new(format!("Curves ({port})"))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| curves_plot(ui, state, &key, curves, &bands));
            }
            Some(Value::Phases(phases)) => {
                CollapsingHeader::new(format!("Phases ({port})"))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| phases_text(ui, phases));
            }
            Some(Value::Stages(stages)) => {
                CollapsingHeader::new(format!("Stages ({port})"))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| stages_text(ui, stages));
            }
            Some(Value::Contacts(contacts)) => {
                CollapsingHeader::new(format!("Contacts ({port})"))
                    .id_salt(&key)
                    .default_open(true)
                    .show(ui, |ui| contacts_text(ui, contacts));
            }
            _ => {}
        }
    }
}

/// One key of a report: scalars on one line, objects and arrays of objects nested.
/// The time ranges a node's results mark, shaded on its curve plots and under the viewport's
/// timeline: the phases it gives, else the stages it gives or takes, else its controller
/// activations; with the transitions and the blend window its report names.
pub(crate) fn time_bands(outputs: &[&Value], inputs: &[&Value]) -> Vec<Band> {
    let phases = outputs.iter().find_map(|v| match v {
        Value::Phases(p) => Some(phase_bands(p)),
        _ => None,
    });
    let stages = outputs.iter().chain(inputs).find_map(|v| match v {
        Value::Stages(s) => Some(stage_bands(s)),
        _ => None,
    });
    let reports: Vec<&Report> = outputs
        .iter()
        .filter_map(|v| match v {
            Value::Report(r) => Some(r.as_ref()),
            _ => None,
        })
        .collect();
    let controllers =
        reports.iter().map(|r| timeline_of(r)).find(|t| !t.is_empty()).map(|t| t.into_iter().map(|a| a.band).collect());
    let mut bands: Vec<Band> = phases.or(stages).or(controllers).unwrap_or_default();
    let fps = outputs.iter().find_map(|v| match v {
        Value::Clip(c) => Some(c.fps()),
        _ => None,
    });
    bands.extend(reports.iter().flat_map(|r| joins_of(r, fps)));
    bands
}

/// The transitions (`motion.sequence`: output frames per transition, of a clip at `fps`) and
/// the blend window (`motion.concat`: `window_secs`) a report names, as bands.
fn joins_of(report: &Report, fps: Option<f64>) -> Vec<Band> {
    let mut bands = Vec::new();
    if let Some([a, b]) = report.get("window_secs").and_then(Json::as_array).map(Vec::as_slice)
        && let (Some(start_secs), Some(end_secs)) = (a.as_f64(), b.as_f64())
    {
        bands.push(Band { name: "blend window".into(), start_secs, end_secs });
    }
    let Some(fps) = fps.filter(|f| *f > 0.0) else { return bands };
    for t in report.get("transitions").and_then(Json::as_array).into_iter().flatten() {
        let frames = t.get("frames");
        let at = |k: &str| frames.and_then(|f| f.get(k)).and_then(Json::as_f64);
        if let (Some(start), Some(end)) = (at("start"), at("end")) {
            bands.push(Band { name: "transition".into(), start_secs: start / fps, end_secs: end / fps });
        }
    }
    bands
}

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

fn band(name: &str, range: FrameRange, fps: f64) -> Band {
    Band { name: name.to_string(), start_secs: range.start as f64 / fps, end_secs: range.end as f64 / fps }
}

/// One controller activation of a report's `timeline` (physics.simulate): its band and how
/// it ended.
struct Activation {
    band: Band,
    outcome: String,
}

/// The activations listed under a report's `timeline` key (objects with `controller`,
/// `start_secs`, `end_secs` and `outcome`); none when the report has no such list.
fn timeline_of(report: &Report) -> Vec<Activation> {
    let Some(Json::Array(items)) = report.get("timeline") else { return Vec::new() };
    items
        .iter()
        .filter_map(|a| {
            let band = Band {
                name: a.get("controller")?.as_str()?.to_string(),
                start_secs: a.get("start_secs")?.as_f64()?,
                end_secs: a.get("end_secs")?.as_f64()?,
            };
            let outcome = match a.get("outcome")? {
                Json::Object(map) => {
                    map.iter().map(|(k, v)| format!("{k}: {}", scalar_text(v))).collect::<Vec<_>>().join(", ")
                }
                other => scalar_text(other),
            };
            Some(Activation { band, outcome })
        })
        .collect()
}

/// The activations as labelled boxes along the run's time, then one line each.
fn timeline_strip(ui: &mut Ui, timeline: &[Activation]) {
    let end = timeline.iter().map(|a| a.band.end_secs).fold(0.0, f64::max).max(1e-6);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width(), 18.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_gray(40));
    for a in timeline {
        let x = |secs: f64| rect.left() + rect.width() * (secs / end) as f32;
        let cell = egui::Rect::from_x_y_ranges(x(a.band.start_secs)..=x(a.band.end_secs), rect.y_range());
        painter.rect_filled(cell.shrink2(egui::vec2(0.5, 0.0)), 2.0, band_colour(&a.band.name, 160));
        painter.with_clip_rect(cell).text(
            cell.left_center() + egui::vec2(3.0, 0.0),
            egui::Align2::LEFT_CENTER,
            &a.band.name,
            egui::FontId::proportional(11.0),
            Color32::WHITE,
        );
    }
    for a in timeline {
        ui.label(format!("{}: {:.3} – {:.3} s, {}", a.band.name, a.band.start_secs, a.band.end_secs, a.outcome));
    }
}

fn stage_name(kind: StageKind) -> &'static str {
    match kind {
        StageKind::Ground => "ground",
        StageKind::Flight => "flight",
    }
}

/// The fill of a band at opacity `alpha`: phases blue, red, green; ground stages brown,
/// flights sky blue; a controller a palette colour picked by its name (so it keeps it
/// across runs).
pub(crate) fn band_colour(name: &str, alpha: u8) -> Color32 {
    let [r, g, b] = match name {
        "transition" => [255, 200, 60],
        "blend window" => [230, 120, 255],
        "preparatory" => [90, 140, 255],
        "main" => [255, 110, 90],
        "posterior" => [110, 220, 130],
        "ground" => [170, 120, 70],
        "flight" => [120, 200, 255],
        controller => {
            let c = channel_colour(controller.bytes().map(usize::from).sum());
            [c.r(), c.g(), c.b()]
        }
    };
    Color32::from_rgba_unmultiplied(r, g, b, alpha)
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
    let response = plot.y_axis_label(unit.unwrap_or_default()).show(ui, |plot| {
        for b in bands {
            plot.span(Span::new(b.name.as_str(), b.start_secs..=b.end_secs).fill(band_colour(&b.name, 40)));
        }
        for (i, c) in channels.iter().enumerate().filter(|(_, c)| state.shown.contains(&format!("{key}.{}", c.name))) {
            let points: Vec<[f64; 2]> = c.values.iter().enumerate().map(|(i, v)| [i as f64 / fps, *v]).collect();
            plot.line(Line::new(c.name.clone(), points).color(channel_colour(i)));
        }
        plot.vline(VLine::new("time", state.playhead).color(PLAYHEAD).width(1.5));
        // A click on the plot moves the viewport there (drags still pan and zoom the plot).
        plot.response().clicked().then(|| plot.pointer_coordinate()).flatten().map(|p| p.x)
    });
    if let Some(secs) = response.inner {
        state.seek = Some(secs.max(0.0));
    }
    state.bands.insert(key.to_string(), bands.to_vec());
}

/// The colour of the viewport's time on the plots.
const PLAYHEAD: Color32 = Color32::from_rgb(255, 80, 80);

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
