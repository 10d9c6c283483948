//! `motion.stages`: the node over the stage kernel ([`crate::kernels::stages`]) — ground and
//! flight stages of a dynamic motion and the gravity that makes its flights ballistic.

use std::sync::Arc;

use serde_json::json;

use super::{MASS_OVERRIDE, MASS_TABLE, TOTAL_MASS, mass_model_of};
use crate::kernels::stages::{DEFAULT_MIN_FLIGHT_SECS, StagedClip, StagesError, stage_clip_with, stage_thresholds};
use crate::model::{Clip, Contacts, Curves, StageKind, Stages};
use crate::node::{
    FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Registry, Report, TextParam, report_of,
};

/// Registers the stage node.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(FindStages));
}

/// Standard gravity, m/s²: the reference for the frame time that would make the flights
/// ballistic on Earth.
pub const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The jump, hop or flip to cut into stages.");
const CONTACTS: Input<Arc<Contacts>> = Input::optional(
    "contacts",
    "Foot contacts of the clip (e.g. from motion.contacts with tuned thresholds). Not wired: a foot touches \
     while its ankle or toe is within 5 cm of its rest height, however fast it moves.",
);
const STAGES: Output<Arc<Stages>> = Output::new(
    "stages",
    "Alternating ground stages (a foot touches the ground) and flight stages (none does), with the gravity \
     fitted to the flights.",
);
const CURVES: Output<Arc<Curves>> = Output::new(
    "curves",
    "Centre of mass (com.x/y/z, m), its fitted flight parabola (com.y ballistic, m), angular momentum about it \
     (L.x/y/z, kg·m²/s) and a flight flag (1 in flight, 0 on the ground), one sample per frame.",
);
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Fitted gravity (m/s²), the parabola's RMS residual (cm), per flight stage its rise, residual and how much \
     its angular momentum varies (%), and the stage ranges.",
);
const BORDERS: TextParam = TextParam::new(
    "borders_secs",
    "Stage borders set by hand, in seconds, comma separated (e.g. \"0.52, 1.10\"): each starts a new stage, \
     kinds alternating from the first frame's. Empty: borders from the foot contacts.",
    "",
);

const MIN_FLIGHT: FloatParam = FloatParam::new(
    "min_flight_secs",
    "Shorter gaps between foot contacts stay ground (capture noise, not a flight).",
    DEFAULT_MIN_FLIGHT_SECS,
    0.0,
    5.0,
    "s",
);

/// `motion.stages`.
pub struct FindStages;

static FIND_STAGES: NodeSchema = NodeSchema {
    kind: "motion.stages",
    category: "motion",
    doc: "Cuts a dynamic motion into ground and flight stages and fits the gravity that makes each flight \
          ballistic (centre of mass on a parabola, angular momentum constant): the first step of \
          momentum-based editing.",
    inputs: &[CLIP.spec(), CONTACTS.spec()],
    outputs: &[STAGES.spec(), CURVES.spec(), REPORT.spec()],
    params: &[TOTAL_MASS.0, MASS_TABLE.0, MASS_OVERRIDE.0, BORDERS.0, MIN_FLIGHT.0],
    writes_files: false,
    version: 1,
};

/// Parses the borders param: `None` when empty.
fn parse_borders(text: &str) -> Result<Option<Vec<f64>>, NodeError> {
    if text.trim().is_empty() {
        return Ok(None);
    }
    text.split(',')
        .map(|part| {
            part.trim()
                .parse::<f64>()
                .map_err(|_| NodeError::param("borders_secs", format!("'{}' is not a number of seconds", part.trim())))
        })
        .collect::<Result<Vec<f64>, NodeError>>()
        .map(Some)
}

/// The stage kernel's error, located on the node's port or param.
fn located(e: StagesError) -> NodeError {
    match e {
        StagesError::BorderOutside { .. } | StagesError::BordersNotIncreasing(_) => {
            NodeError::param("borders_secs", e.to_string())
        }
        StagesError::ContactsMismatch { .. } => NodeError::input("contacts", e.to_string()),
        StagesError::TooShort(_) | StagesError::NoFlight | StagesError::Feet(_) => {
            NodeError::input("clip", e.to_string())
        }
    }
}

/// The curves of a staged clip.
pub fn stage_curves(staged: &StagedClip) -> Result<Curves, crate::model::CurvesError> {
    let s = &staged.stages;
    let mut c = Curves::new(s.fps, s.frame_count);
    let com = &staged.track.com_m;
    c.push("com.x", "m", com.iter().map(|p| p.x).collect())?;
    c.push("com.y", "m", com.iter().map(|p| p.y).collect())?;
    c.push("com.z", "m", com.iter().map(|p| p.z).collect())?;
    c.push("com.y ballistic", "m", staged.fit.com_fitted_m.iter().map(|p| p.y).collect())?;
    let l = &staged.track.momentum;
    c.push("L.x", "kg·m²/s", l.iter().map(|v| v.x).collect())?;
    c.push("L.y", "kg·m²/s", l.iter().map(|v| v.y).collect())?;
    c.push("L.z", "kg·m²/s", l.iter().map(|v| v.z).collect())?;
    let mut flag = vec![0.0; s.frame_count];
    for st in s.flights() {
        for v in flag.iter_mut().take(st.frames.end).skip(st.frames.start) {
            *v = 1.0;
        }
    }
    c.push("flight", "", flag)?;
    Ok(c)
}

impl Node for FindStages {
    fn schema(&self) -> &'static NodeSchema {
        &FIND_STAGES
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let contacts = ctx.optional_input(&CONTACTS)?;
        let borders = parse_borders(ctx.text_param(&BORDERS)?)?;
        let model = mass_model_of(ctx, &clip)?;
        let min_flight_secs = ctx.float(&MIN_FLIGHT)?;
        let staged = stage_clip_with(
            &clip,
            &model,
            contacts.as_deref(),
            borders.as_deref(),
            &stage_thresholds(),
            min_flight_secs,
        )
        .map_err(located)?;
        let g = staged.fit.gravity_mps2;
        if g.is_nan() || g <= 0.0 {
            return Err(NodeError::input(
                "clip",
                format!("the flights do not fall (fitted gravity {g:.3} m/s²): check the stage borders"),
            ));
        }
        let fps = clip.fps();
        let stage_rows: Vec<serde_json::Value> = staged
            .stages
            .stages
            .iter()
            .map(|s| {
                json!({
                    "kind": match s.kind { StageKind::Ground => "ground", StageKind::Flight => "flight" },
                    "start_frame": s.frames.start,
                    "end_frame": s.frames.end,
                    "start_secs": s.frames.start as f64 / fps,
                    "end_secs": s.frames.end as f64 / fps,
                })
            })
            .collect();
        let flights: Vec<serde_json::Value> = staged
            .fit
            .flights
            .iter()
            .map(|f| {
                json!({
                    "start_frame": f.frames.start,
                    "end_frame": f.frames.end,
                    "fitted": f.fitted,
                    "rms_residual_cm": 100.0 * f.rms_residual_m,
                    "rise_m": f.rise_m,
                    "mean_angular_momentum": [f.mean_momentum.x, f.mean_momentum.y, f.mean_momentum.z],
                    "angular_momentum_variation_pct": f.momentum_variation_pct,
                })
            })
            .collect();
        let curves = stage_curves(&staged).map_err(NodeError::kernel)?;
        ctx.set_output(&CURVES, Arc::new(curves));
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "gravity_mps2": g,
                "frame_time_for_standard_gravity_secs": (g / STANDARD_GRAVITY_MPS2).sqrt() / fps,
                "parabola_rms_residual_cm": 100.0 * staged.fit.rms_residual_m,
                "max_angular_momentum_variation_pct": staged.fit.max_momentum_variation_pct(),
                "stages": stage_rows,
                "flights": flights,
                "borders": if borders.is_some() { "manual" } else { "contacts" },
            })),
        );
        ctx.set_output(&STAGES, Arc::new(staged.stages));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn borders_parse_or_name_the_param() {
        assert_eq!(parse_borders("  ").unwrap(), None);
        assert_eq!(parse_borders("0.5, 1.25").unwrap(), Some(vec![0.5, 1.25]));
        let err = parse_borders("0.5, x").unwrap_err();
        assert!(err.to_string().contains("borders_secs") && err.to_string().contains("'x'"), "{err}");
    }
}
