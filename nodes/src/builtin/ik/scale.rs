//! Non-uniform skeleton scaling: shorter legs, a longer spine, to make test characters
//! (Choi & Ko's target is about 60 % of the source, non-uniformly).
//!
//! A rule `NAME=FACTOR` scales the bones that start at every joint whose name ends with
//! `NAME` (case-insensitive; the longest matching rule wins), i.e. the rest offsets of that
//! joint's children. Bones no rule matches take the uniform factor.

use std::sync::Arc;

use glam::Vec3;

use crate::model::{Clip, ClipError, Skeleton, SkeletonError};
use crate::node::{FloatParam, Input, Node, NodeContext, NodeError, NodeSchema, Output, TextParam};

/// Why a scale rule list is rejected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ScaleError {
    /// A rule that is not `NAME=FACTOR` with a positive finite factor.
    #[error("scale rule `{0}` is not NAME=FACTOR with a factor above 0")]
    BadRule(String),
    /// The scaled skeleton is invalid.
    #[error(transparent)]
    Skeleton(#[from] SkeletonError),
    /// The scaled clip is invalid.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// Parses `"UpLeg=0.55, Leg=0.6"` into (suffix, factor) rules.
pub fn parse_rules(text: &str) -> Result<Vec<(String, f32)>, ScaleError> {
    text.split([',', ';'])
        .map(str::trim)
        .filter(|r| !r.is_empty())
        .map(|rule| {
            let bad = || ScaleError::BadRule(rule.to_owned());
            let (name, factor) = rule.split_once('=').ok_or_else(bad)?;
            let factor: f32 = factor.trim().parse().map_err(|_| bad())?;
            if !(factor.is_finite() && factor > 0.0) || name.trim().is_empty() {
                return Err(bad());
            }
            Ok((name.trim().to_ascii_lowercase(), factor))
        })
        .collect()
}

/// Scale factor of the bone from each joint's parent to the joint.
pub fn bone_factors(skeleton: &Skeleton, uniform: f32, rules: &[(String, f32)]) -> Vec<f32> {
    let factor_of = |name: &str| {
        let lower = name.to_ascii_lowercase();
        rules
            .iter()
            .filter(|(suffix, _)| lower.ends_with(suffix.as_str()))
            .max_by_key(|(suffix, _)| suffix.len())
            .map_or(uniform, |(_, f)| *f)
    };
    skeleton.joints().iter().map(|j| j.parent.map_or(uniform, |p| factor_of(&skeleton.joints()[p].name))).collect()
}

/// The skeleton with every bone scaled by its factor (see [`bone_factors`]).
pub fn scale_skeleton(skeleton: &Skeleton, factors: &[f32]) -> Result<Skeleton, SkeletonError> {
    let joints = skeleton
        .joints()
        .iter()
        .zip(factors)
        .map(|(j, f)| crate::model::Joint { rest_offset: j.rest_offset * *f, ..j.clone() })
        .collect();
    Skeleton::new(joints)
}

/// The clip on the scaled skeleton: the same joint rotations (a plain angle copy), other
/// joints' translations scaled with their bones, the root's path scaled by the ratio of
/// root heights so the feet stay near the ground.
pub fn scale_clip(clip: &Clip, uniform: f32, rules: &[(String, f32)]) -> Result<Clip, ScaleError> {
    let source = clip.skeleton();
    let factors = bone_factors(source, uniform, rules);
    let skeleton = Arc::new(scale_skeleton(source, &factors)?);
    let root_ratio = source.root_height_ratio(&skeleton).unwrap_or(uniform);
    let joints = source.len();
    let translations: Vec<Vec3> = clip
        .translations()
        .iter()
        .enumerate()
        .map(|(i, t)| if i % joints == 0 { *t * root_ratio } else { *t * factors[i % joints] })
        .collect();
    Ok(Clip::new(skeleton, clip.fps(), clip.rotations().to_vec(), translations, clip.import_scale)?)
}

const CLIP: Input<Arc<Clip>> = Input::required("clip", "The clip whose skeleton to resize.");
const SCALED: Output<Arc<Clip>> = Output::new(
    "clip",
    "The same motion on the resized skeleton: joint angles copied, the root path scaled by the change in hip height.",
);
const UNIFORM: FloatParam =
    FloatParam::new("scale", "Factor for every bone no rule names (0.6 = 60 %).", 1.0, 0.01, 100.0, "");
const RULES: TextParam = TextParam::new(
    "bones",
    "Per-bone factors, `NAME=FACTOR` separated by commas: a rule scales the bones that start at every joint whose name ends with NAME (longest match wins), e.g. `UpLeg=0.62, Leg=0.52`.",
    "",
);

/// `skeleton.scale`.
pub struct ScaleSkeleton;

static SCALE_SKELETON: NodeSchema = NodeSchema {
    kind: "skeleton.scale",
    category: "skeleton",
    doc: "Resizes a character bone by bone (non-uniformly), keeping its joint angles: makes test characters of other proportions.",
    inputs: &[CLIP.spec()],
    outputs: &[SCALED.spec()],
    params: &[UNIFORM.0, RULES.0],
    writes_files: false,
    version: 1,
};

impl Node for ScaleSkeleton {
    fn schema(&self) -> &'static NodeSchema {
        &SCALE_SKELETON
    }
    fn eval(&self, ctx: &mut NodeContext<'_>) -> Result<(), NodeError> {
        let clip = ctx.input(&CLIP)?;
        let rules = parse_rules(ctx.text_param(&RULES)?).map_err(|e| NodeError::param("bones", e.to_string()))?;
        let uniform = ctx.float(&UNIFORM)? as f32;
        let unused: Vec<String> = rules
            .iter()
            .filter(|(suffix, _)| {
                !clip.skeleton().joints().iter().any(|j| j.name.to_ascii_lowercase().ends_with(suffix.as_str()))
            })
            .map(|(suffix, _)| format!("bone rule `{suffix}` matches no joint"))
            .collect();
        ctx.warn_all(unused);
        let scaled = scale_clip(&clip, uniform, &rules).map_err(|e| NodeError::param("bones", e.to_string()))?;
        ctx.set_output(&SCALED, Arc::new(scaled));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Joint;

    #[test]
    fn longest_suffix_wins_and_bones_scale_from_their_start_joint() {
        let skeleton = Skeleton::new(vec![
            Joint::new("Hips", None, Vec3::ZERO),
            Joint::new("LeftUpLeg", Some(0), Vec3::new(0.1, 0.0, 0.0)),
            Joint::new("LeftLeg", Some(1), Vec3::new(0.0, -0.4, 0.0)),
            Joint::new("LeftFoot", Some(2), Vec3::new(0.0, -0.4, 0.0)),
        ])
        .unwrap();
        let rules = parse_rules("Leg=0.5, UpLeg=0.7").unwrap();
        let f = bone_factors(&skeleton, 0.6, &rules);
        assert_eq!(f, vec![0.6, 0.6, 0.7, 0.5]);
        let scaled = scale_skeleton(&skeleton, &f).unwrap();
        assert!((scaled.joints()[3].rest_offset.y + 0.2).abs() < 1e-6);
        // Root height: 0.8 m → 0.28 + 0.2 = 0.48 m.
        assert!((scaled.root_height() - 0.48).abs() < 1e-6);
        assert!(parse_rules("Leg=0").is_err() && parse_rules("Leg").is_err() && parse_rules("=2").is_err());
    }
}
