//! The momentum pre-fit (momentum-based editing, step 2) on the real jumps of the corpus:
//! C1 at the stage borders checked numerically on the fitted curves, the residual to the
//! measured momentum reported. Needs `../shared/data` (skips without it outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinegraph_nodes::builtin::momentum::splines::border_jumps;
use kinegraph_nodes::corpus::{JUMP_CLIPS, shared_data};
use kinegraph_nodes::kernels::body::{MassTable, body_model};
use kinegraph_nodes::kernels::load::{ClipLoadOptions, load_clip};
use kinegraph_nodes::kernels::momentum_splines::{CHANNELS, fit_momentum};
use kinegraph_nodes::kernels::stages::stage_clip;
use kinegraph_nodes::model::StageKind;

#[test]
fn fitted_momentum_is_c1_at_the_borders_except_vertical_at_landings() {
    let Some(data) = shared_data() else { return };
    for name in JUMP_CLIPS {
        let clip = load_clip(&data.join(name), ClipLoadOptions::default()).unwrap().value;
        let model = body_model(clip.skeleton(), 70.0, MassTable::DeLevaMale, None).unwrap();
        let staged = stage_clip(&clip, &model, None, None).unwrap();
        let linear: Vec<glam::DVec3> = staged.track.com_velocity_mps.iter().map(|v| *v * 70.0).collect();
        let fit = fit_momentum(&staged.stages, &linear, &staged.track.momentum, 70.0, 0.1).unwrap();
        let h = 1e-6;
        let jumps = border_jumps(&fit, h);
        let stages = &staged.stages.stages;
        let mut worst = (0.0f64, 0.0f64);
        for (b, per_channel) in jumps.iter().enumerate() {
            // Border b lies between stage b and stage b + 1.
            let landing = stages[b].kind == StageKind::Flight;
            for (c, &(dv, ds)) in per_channel.iter().enumerate() {
                let scale = fit.measured[c].iter().map(|v| v.abs()).fold(1.0, f64::max);
                if landing && CHANNELS[c] == "p.y" {
                    continue;
                }
                // Values agree to round-off; slopes to the round-off of a difference h wide.
                assert!(dv < 1e-9 * scale, "{name} border {b} {}: value jump {dv}", CHANNELS[c]);
                assert!(ds < 1e-7 * scale / h, "{name} border {b} {}: slope jump {ds}", CHANNELS[c]);
                worst = (worst.0.max(dv / scale), worst.1.max(ds * h / scale));
            }
        }
        // The landing is free: the fitted p.y jumps there on real data.
        let landing_jump = jumps
            .iter()
            .enumerate()
            .filter(|(b, _)| stages[*b].kind == StageKind::Flight)
            .map(|(_, j)| j[1].0)
            .fold(0.0, f64::max);
        let rms: Vec<String> = fit.channels.iter().map(|c| format!("{} {:.2}", c.name, c.rms_residual)).collect();
        eprintln!(
            "{name}: {} borders, worst relative jumps value {:.1e} slope·h {:.1e}; p.y landing jump {landing_jump:.1} kg·m/s; rms {}",
            fit.borders_secs.len(),
            worst.0,
            worst.1,
            rms.join(", ")
        );
        for ch in &fit.fitted {
            assert!(ch.iter().all(|v| v.is_finite()), "{name}");
        }
        // The fit follows the measured momentum: residual well under the curves' spread.
        for (c, ch) in fit.channels.iter().enumerate() {
            let m = &fit.measured[c];
            let mean = m.iter().sum::<f64>() / m.len() as f64;
            let sd = (m.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / m.len() as f64).sqrt();
            assert!(ch.rms_residual < sd.max(1e-9), "{name} {}: rms {} vs spread {sd}", ch.name, ch.rms_residual);
        }
    }
}
