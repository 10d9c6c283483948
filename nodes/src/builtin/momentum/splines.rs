//! `motion.momentum_splines`: the node over the momentum pre-fit
//! ([`crate::kernels::momentum_splines`]).

use std::sync::Arc;

use serde_json::json;

use super::{MASS_OVERRIDE, MASS_TABLE, TOTAL_MASS, check_stages_fit, mass_model_of};
use crate::kernels::angular::momentum_of_poses;
use crate::kernels::momentum_splines::{CHANNELS, MomentumFit, SplineError, UNITS, fit_momentum};
use crate::model::{Clip, Curves, CurvesError, Stages, forward_kinematics};
use crate::node::{FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, Registry, Report, report_of};

/// Registers the momentum pre-fit node.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(MomentumSplines));
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The jump, hop or flip whose momentum to fit.");
const STAGES: Input<Arc<Stages>> =
    Input::required("stages", "Its ground and flight stages and fitted gravity (from motion.stages).");
const CURVES: Output<Arc<Curves>> = Output::new(
    "curves",
    "Measured and fitted whole-body momentum, one sample per frame: linear p.x/y/z (kg·m/s) and angular L.x/y/z \
     about the centre of mass (kg·m²/s), each next to its 'fitted' twin.",
);
const REPORT: Output<Arc<Report>> = Output::new(
    "report",
    "Per channel the RMS residual of the fit; per stage border the jump in value and slope of the fitted curves \
     (zero where the fit is C1); the knots used.",
);
const KNOT_SPACING: FloatParam = FloatParam::new(
    "knot_spacing_secs",
    "Spacing of the spline knots in ground stages: smaller follows the measured momentum more closely.",
    0.1,
    0.01,
    2.0,
    "s",
);

/// `motion.momentum_splines`.
pub struct MomentumSplines;

static MOMENTUM_SPLINES: NodeSchema = NodeSchema {
    kind: "motion.momentum_splines",
    category: "motion",
    doc: "Fits the whole-body linear and angular momentum of a dynamic motion: straight lines under gravity in \
          flight, smooth cubic B-splines on the ground that join the flights without a kink (except the vertical \
          momentum at a landing, which is an impact). The momentum patterns momentum-based editing preserves.",
    inputs: &[CLIP.spec(), STAGES.spec()],
    outputs: &[CURVES.spec(), REPORT.spec()],
    params: &[TOTAL_MASS.0, MASS_TABLE.0, MASS_OVERRIDE.0, KNOT_SPACING.0],
    writes_files: false,
    version: 1,
};

/// Value and slope jumps of every channel at every border, measured on the fitted curves
/// by one-sided differences `step_secs` wide.
pub fn border_jumps(fit: &MomentumFit, step_secs: f64) -> Vec<Vec<(f64, f64)>> {
    let h = step_secs;
    fit.borders_secs
        .iter()
        .map(|&t| {
            fit.channels
                .iter()
                .map(|ch| {
                    let (l1, l2, r1, r2) =
                        (ch.value(t - 2.0 * h), ch.value(t - h), ch.value(t + h), ch.value(t + 2.0 * h));
                    // Extrapolate each side to the border, then compare slopes.
                    let (left, right) = (2.0 * l2 - l1, 2.0 * r1 - r2);
                    ((right - left).abs(), ((r2 - r1) / h - (l2 - l1) / h).abs())
                })
                .collect()
        })
        .collect()
}

fn curves_of(fit: &MomentumFit, fps: f64, frames: usize) -> Result<Curves, CurvesError> {
    let mut c = Curves::new(fps, frames);
    for (i, name) in CHANNELS.iter().enumerate() {
        c.push(name, UNITS[i], fit.measured[i].clone())?;
        c.push(&format!("{name} fitted"), UNITS[i], fit.fitted[i].clone())?;
    }
    Ok(c)
}

impl Node for MomentumSplines {
    fn schema(&self) -> &'static NodeSchema {
        &MOMENTUM_SPLINES
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let stages = ctx.input(&STAGES)?;
        check_stages_fit(&clip, &stages)?;
        let spacing = ctx.float(&KNOT_SPACING)?;
        let model = mass_model_of(ctx, &clip)?;
        let track = momentum_of_poses(&forward_kinematics(&clip), clip.fps(), &model);
        let linear: Vec<glam::DVec3> = track.com_velocity_mps.iter().map(|v| *v * model.total_mass_kg).collect();
        let fit =
            fit_momentum(&stages, &linear, &track.momentum, model.total_mass_kg, spacing).map_err(|e| match e {
                SplineError::KnotSpacing(_) => NodeError::param("knot_spacing_secs", e.to_string()),
                _ => NodeError::input("stages", e.to_string()),
            })?;
        let jumps = border_jumps(&fit, 1e-4 / clip.fps());
        let borders: Vec<serde_json::Value> = fit
            .borders_secs
            .iter()
            .zip(&jumps)
            .map(|(t, j)| {
                let per: serde_json::Map<String, serde_json::Value> = CHANNELS
                    .iter()
                    .zip(j)
                    .map(|(n, (dv, ds))| (n.to_string(), json!({ "value_jump": dv, "slope_jump": ds })))
                    .collect();
                json!({ "secs": t, "channels": per })
            })
            .collect();
        let residuals: serde_json::Map<String, serde_json::Value> =
            fit.channels.iter().map(|c| (c.name.to_string(), json!(c.rms_residual))).collect();
        let curves = curves_of(&fit, clip.fps(), clip.frame_count()).map_err(NodeError::kernel)?;
        ctx.set_output(&CURVES, Arc::new(curves));
        ctx.set_output(
            &REPORT,
            report_of(json!({
                "gravity_mps2": stages.gravity_mps2,
                "total_mass_kg": model.total_mass_kg,
                "rms_residual": residuals,
                "borders": borders,
                "knot_spacing_secs": spacing,
            })),
        );
        Ok(())
    }
}
