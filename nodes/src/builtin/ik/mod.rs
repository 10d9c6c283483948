//! The IK nodes (the solver, rig and foot lock are in [`crate::kernels::ik`]): `ik.solve`,
//! the foot lock, the procedural walk (Meredith & Maddock), online retargeting (Choi & Ko 2000) and skeleton
//! edits to make test characters.

pub mod foot_lock;
pub mod gait;
pub mod map;
pub mod retarget;
pub mod scale;
pub mod solve;

use std::sync::Arc;

use crate::kernels::ik::Weighting;
use crate::model::Curves;
use crate::model::choice::choices;
use crate::node::{ChoiceParam, NodeError, Output, Registry};

choices!(Weighting { InsideInverse = "inside", Paper = "paper" });

/// Where the joint weights enter the IK steps, shared by the nodes that solve IK.
const WEIGHTING: ChoiceParam<Weighting> = ChoiceParam::new(
    "weighting",
    "How the joint weights shape each step: inside the pseudo-inverse (every step reaches its linear goal; stiff joints take less of it), or the paper's eq. 1.6 (the plain step with each joint's share scaled by its weight; more iterations).",
    "inside",
);

/// The per-frame curves output of the IK nodes, for the editor's plots.
const RESIDUAL_CURVES: Output<Arc<Curves>> = Output::new(
    "residuals",
    "Per frame, to plot: how far the ends stayed from their goals (m), and the dexterity when retargeting.",
);

/// Per-frame IK figures (`(channel, unit, values)`) at `fps` as curves.
fn residual_curves(fps: f64, channels: Vec<(&str, &str, Vec<f64>)>) -> Result<Arc<Curves>, NodeError> {
    let frames = channels.first().map_or(0, |c| c.2.len());
    let mut curves = Curves::new(fps, frames);
    for (name, unit, values) in channels {
        curves.push(name, unit, values).map_err(NodeError::kernel)?;
    }
    Ok(Arc::new(curves))
}

/// Registers the IK family's nodes.
pub fn register(registry: &mut Registry) {
    registry.add(Box::new(solve::IkSolve));
    registry.add(Box::new(scale::ScaleSkeleton));
    registry.add(Box::new(retarget::RetargetOnline));
    registry.add(Box::new(foot_lock::FootLock));
    registry.add(Box::new(map::MapSkeleton));
    registry.add(Box::new(map::ExportBoneMap));
    registry.add(Box::new(gait::ProceduralGait));
}
