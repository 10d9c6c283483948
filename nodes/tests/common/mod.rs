//! Set-up shared by the momentum-editing tests (`momentum_edit`, `momentum_family`): a
//! jump of the corpus (mostly CMU 16_01, a standing jump) with what an edit of it needs.
//! Needs `../shared/data` (None without it outside CI).

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use glam::DVec3;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::kernels::body::{BodyModel, MassTable, body_model};
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::kernels::load::{ClipLoadOptions, LeadingTPose, load_clip};
use kinegraph_nodes::kernels::stages::{StagedClip, stage_clip};
use kinegraph_nodes::model::{Clip, FrameRange, forward_kinematics};

/// A jump and what an edit of it needs.
pub struct Jump {
    /// The clip (16_01: 323 frames at 120 fps).
    pub clip: Clip,
    /// De Leva's male table, 70 kg.
    pub model: BodyModel,
    /// Its stages (16_01: ground, flight, ground) and momentum track.
    pub staged: StagedClip,
    /// The jump's direction: the horizontal travel of the centre of mass over the flight.
    pub forward: DVec3,
    /// The ankle joints the contacts were read from.
    pub ankles: [usize; 2],
    /// The original's contacts: (ankle joint, frames).
    pub planted: Vec<(usize, FrameRange)>,
}

/// CMU 16_01, or None without the shared corpus.
pub fn jump_16_01() -> Option<Jump> {
    jump("bvh/cmu/16_01.bvh")
}

/// A jump of the corpus (`path` under the shared data), or None without it.
pub fn jump(path: &str) -> Option<Jump> {
    let data = shared_data()?;
    // As clip.load gives it: without cgspeed's T-pose before the motion.
    let options = ClipLoadOptions { t_pose: LeadingTPose::Drop, ..Default::default() };
    let clip = load_clip(&data.join(path), options).unwrap().value;
    let model = body_model(clip.skeleton(), 70.0, MassTable::DeLevaMale, None).unwrap();
    let staged = stage_clip(&clip, &model, None, None).unwrap();
    let flight = staged.stages.stages[1].frames;
    let travel = staged.track.com_m[flight.end - 1] - staged.track.com_m[flight.start];
    let forward = DVec3::new(travel.x, 0.0, travel.z).normalize_or_zero();
    eprintln!("{path} jump direction (COM travel in the first flight): {forward}");
    let (contacts, ankles) = contacts_of(&clip, &forward_kinematics(&clip), &ContactThresholds::default()).unwrap();
    let planted =
        contacts.feet.iter().zip(ankles).flat_map(|(c, j)| c.intervals.iter().map(move |r| (j, *r))).collect();
    Some(Jump { clip, model, staged, forward, ankles, planted })
}
