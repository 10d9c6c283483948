//! `ik.solve`: chains named by their first and end joints solved toward goals by the
//! weighted IK of [`crate::kernels::ik::solve`].

use std::sync::Arc;

use glam::DVec3;
use serde_json::json;

use crate::kernels::ik::{IkRig, IkSolver, RigError, SolveParams, SolveReport};
use crate::model::{Clip, ClipError, Curves, Skeleton};
use crate::node::into_report;
use crate::node::{FloatParam, Input, IntParam, Node, NodeContext, NodeError, NodeSchema, Output, Report, TextParam};
/// One chain of an `ik.solve` node: its joints turn, its end joint is an effector.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainSpec {
    /// First joint that turns.
    pub root: String,
    /// End effector joint.
    pub end: String,
}

/// Parses `"LeftUpLeg>LeftToeBase, RightUpLeg>RightToeBase"`.
fn parse_chains(text: &str) -> Result<Vec<ChainSpec>, String> {
    text.split(',')
        .map(str::trim)
        .filter(|c| !c.is_empty())
        .map(|c| {
            let (root, end) = c.split_once('>').ok_or_else(|| format!("`{c}` is not ROOT>END"))?;
            Ok(ChainSpec { root: root.trim().to_owned(), end: end.trim().to_owned() })
        })
        .collect()
}

/// Parses `"x y z; x y z"` (metres) into one goal per chain.
fn parse_goals(text: &str) -> Result<Vec<DVec3>, String> {
    text.split(';')
        .map(str::trim)
        .filter(|g| !g.is_empty())
        .map(|g| {
            let v: Vec<f64> = g
                .split_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()
                .map_err(|_| format!("`{g}` is not three numbers"))?;
            match v.as_slice() {
                [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(DVec3::new(*x, *y, *z)),
                _ => Err(format!("`{g}` is not three finite numbers")),
            }
        })
        .collect()
}

/// Parses `"LeftLeg=0.1, LeftUpLeg=0.8"` into per-joint stiffness weights in [0, 1].
pub(crate) fn parse_weights(text: &str) -> Result<Vec<(String, f64)>, String> {
    text.split(',')
        .map(str::trim)
        .filter(|w| !w.is_empty())
        .map(|w| {
            let (name, value) = w.split_once('=').ok_or_else(|| format!("`{w}` is not JOINT=WEIGHT"))?;
            let value: f64 = value.trim().parse().map_err(|_| format!("`{w}` has no number"))?;
            if !(0.0..=1.0).contains(&value) {
                return Err(format!("`{w}`: weights lie in [0, 1]"));
            }
            Ok((name.trim().to_owned(), value))
        })
        .collect()
}

/// Builds the rig of an `ik.solve` node: each chain's joints turn about three axes with the
/// given weights (1 where none is given).
pub fn chains_rig(
    skeleton: &Arc<Skeleton>,
    chains: &[ChainSpec],
    weights: &[(String, f64)],
) -> Result<IkRig, RigError> {
    let mut rig = IkRig::new(skeleton.clone());
    for (name, _) in weights {
        rig.joint(name)?;
    }
    for c in chains {
        let path = rig.chain_joints(&c.root, &c.end)?;
        for &j in &path[..path.len() - 1] {
            let name = &skeleton.joints()[j].name;
            let w = weights.iter().find(|(n, _)| n == name).map_or(1.0, |(_, w)| *w);
            rig.add_joint(j, [true; 3], w);
        }
        rig.add_effector(*path.last().unwrap_or(&0));
    }
    rig.finish()
}

/// Solves every frame of `clip` toward `goals(frame)` (one per chain), starting each frame
/// from the clip's own pose; returns the new clip and each frame's report.
pub fn solve_clip(
    clip: &Clip,
    rig: IkRig,
    goals: impl Fn(usize, &mut [DVec3]),
    params: &SolveParams,
) -> Result<(Clip, Vec<SolveReport>), ClipError> {
    let mut solver = IkSolver::new(rig);
    let mut frame_goals = vec![DVec3::ZERO; solver.rig().effectors().len()];
    let mut rotations = clip.rotations().to_vec();
    let mut reports = Vec::with_capacity(clip.frame_count());
    let joints = clip.joint_count();
    let mut pose = solver.rig().pose_from(clip.frame_rotations(0), clip.frame_translations(0));
    for f in 0..clip.frame_count() {
        solver.rig().fill_pose(clip.frame_rotations(f), clip.frame_translations(f), &mut pose);
        goals(f, &mut frame_goals);
        reports.push(solver.solve(&mut pose, &frame_goals, params));
        solver.rig().rotations_of(&pose, &mut rotations[f * joints..(f + 1) * joints]);
    }
    let out =
        Clip::new(clip.skeleton().clone(), clip.fps(), rotations, clip.translations().to_vec(), clip.import_scale)?;
    Ok((out, reports))
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The motion to pose.");
const TARGET_CURVES: Input<Arc<Curves>> = Input::optional(
    "targets",
    "Goal paths per frame: channels `END.x`, `END.y`, `END.z` (metres) for a chain ending at END. Overrides `goals`.",
);
const SOLVED: Output<Arc<Clip>> = Output::new("clip", "The motion with each chain's end on its goal.");
const SOLVE_REPORT: Output<Arc<Report>> =
    Output::new("report", "Per-frame residual distance to the goals and how many frames did not converge.");
const CHAINS: TextParam = TextParam::new(
    "chains",
    "Chains as ROOT>END joint names, separated by commas; every joint from ROOT up to END's parent turns, END reaches its goal.",
    "",
);
const GOALS: TextParam =
    TextParam::new("goals", "Constant goal per chain, world metres: `x y z; x y z` in chain order.", "");
const WEIGHTS: TextParam = TextParam::new(
    "weights",
    "Stiffness per joint, `JOINT=W` with W in [0, 1] (1 free, 0.1 stiff, 0 locked); unnamed joints are free.",
    "",
);
const TOLERANCE: FloatParam =
    FloatParam::new("tolerance_m", "A frame is solved when every end is this close to its goal.", 1e-4, 1e-7, 1.0, "m");
const ITERATIONS: IntParam = IntParam::new("max_iterations", "Iterations allowed per frame.", 50, 1, 10_000);

/// `ik.solve`.
pub struct IkSolve;

static IK_SOLVE: NodeSchema = NodeSchema {
    kind: "ik.solve",
    category: "ik",
    doc: "Weighted Jacobian IK (Meredith & Maddock): moves chains so their ends reach goals; stiff joints (low weight) move less and the others take up the motion.",
    inputs: &[CLIP.spec(), TARGET_CURVES.spec()],
    outputs: &[SOLVED.spec(), SOLVE_REPORT.spec(), super::RESIDUAL_CURVES.spec()],
    params: &[CHAINS.0, GOALS.0, WEIGHTS.0, super::WEIGHTING.0, TOLERANCE.0, ITERATIONS.0],
    writes_files: false,
    version: 2,
};

impl Node for IkSolve {
    fn schema(&self) -> &'static NodeSchema {
        &IK_SOLVE
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let curves = ctx.optional_input(&TARGET_CURVES)?;
        let chains = parse_chains(ctx.text_param(&CHAINS)?).map_err(|e| NodeError::param("chains", e))?;
        if chains.is_empty() {
            return Err(NodeError::param("chains", "name at least one chain, e.g. `LeftUpLeg>LeftToeBase`"));
        }
        let weights = parse_weights(ctx.text_param(&WEIGHTS)?).map_err(|e| NodeError::param("weights", e))?;
        let rig =
            chains_rig(clip.skeleton(), &chains, &weights).map_err(|e| NodeError::param("chains", e.to_string()))?;
        let params = SolveParams {
            tolerance_m: ctx.float(&TOLERANCE)?,
            max_iterations: usize::try_from(ctx.int(&ITERATIONS)?).unwrap_or(1),
            weighting: ctx.choice(&super::WEIGHTING)?,
            ..SolveParams::default()
        };
        let result = match &curves {
            Some(c) => {
                if c.frame_count() != clip.frame_count() {
                    return Err(NodeError::input(
                        "targets",
                        "the goal curves and the clip have different frame counts",
                    ));
                }
                let mut paths = Vec::new();
                for chain in &chains {
                    let axis = |a: &str| {
                        c.channel(&format!("{}.{a}", chain.end)).map(|ch| ch.values.clone()).ok_or_else(|| {
                            NodeError::input(
                                "targets",
                                format!("no channel `{}.{a}` for chain end `{}`", chain.end, chain.end),
                            )
                        })
                    };
                    paths.push([axis("x")?, axis("y")?, axis("z")?]);
                }
                solve_clip(
                    &clip,
                    rig,
                    |f, out| {
                        for (o, p) in out.iter_mut().zip(&paths) {
                            *o = DVec3::new(p[0][f], p[1][f], p[2][f]);
                        }
                    },
                    &params,
                )
            }
            None => {
                let goals = parse_goals(ctx.text_param(&GOALS)?).map_err(|e| NodeError::param("goals", e))?;
                if goals.len() != chains.len() {
                    return Err(NodeError::param(
                        "goals",
                        format!("{} goals for {} chains", goals.len(), chains.len()),
                    ));
                }
                solve_clip(&clip, rig, |_, out| out.copy_from_slice(&goals), &params)
            }
        }
        .map_err(|e| NodeError::input("clip", e.to_string()))?;
        let (solved, reports) = result;
        let residuals: Vec<f64> = reports.iter().map(|r| r.residual_m).collect();
        let unconverged = reports.iter().filter(|r| !r.converged).count();
        if unconverged > 0 {
            ctx.warn(format!(
                "{unconverged} of {} frames did not reach their goals (out of reach or limited)",
                reports.len()
            ));
        }
        ctx.set_output(
            &super::RESIDUAL_CURVES,
            super::residual_curves(clip.fps(), vec![("residual", "m", residuals.clone())])?,
        );
        ctx.set_output(
            &SOLVE_REPORT,
            Arc::new(into_report(json!({
                "max_residual_m": residuals.iter().copied().fold(0.0, f64::max),
                "unconverged_frames": unconverged,
                "residual_m_per_frame": residuals,
            }))),
        );
        ctx.set_output(&SOLVED, Arc::new(solved));
        Ok(())
    }
}
