//! Momentum-based editing, the part that exists so far (issue 15, step 3, partial): the
//! user's edits of ground stages, the paper's initial guess (the *naive kinematic edit*),
//! and the measures an edit is judged by. The spacetime optimisation that starts from this
//! guess is [`momentum_solve`](super::momentum_solve).
//!
//! An edit moves ground stage i rigidly: X_i(p) = R_y(θ_i)(p − c_i) + c_i + Δ_i, with c_i the
//! stage's centre of mass at its middle frame on the floor plane, Δ_i a horizontal offset
//! (metres) and θ_i a turn about the vertical (radians). Flight frames between ground
//! stages i and j take the transform with θ, Δ and c interpolated linearly in time; frames
//! before the first or after the last ground stage take its transform.

use glam::{DQuat, DVec3, Quat};

use super::angular::momentum_of_poses;
use super::body::{BodyModel, limb_tip};
use crate::model::{Clip, ClipError, ClipPoses, FrameRange, StageKind, Stages, forward_kinematics};

/// The user's edit of one ground stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GroundEdit {
    /// Horizontal translation, metres (the Y component is ignored).
    pub offset_m: DVec3,
    /// Turn about the vertical through the stage's centre of mass, radians.
    pub turn_rad: f64,
}

/// A rigid horizontal transform: turn about `pivot`, then shift.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Placement {
    pivot: DVec3,
    offset: DVec3,
    turn_rad: f64,
}

impl Placement {
    fn apply(&self, p: DVec3) -> DVec3 {
        DQuat::from_rotation_y(self.turn_rad) * (p - self.pivot) + self.pivot + self.offset
    }
    fn lerp(&self, other: &Placement, w: f64) -> Placement {
        Placement {
            pivot: self.pivot.lerp(other.pivot, w),
            offset: self.offset.lerp(other.offset, w),
            turn_rad: self.turn_rad + (other.turn_rad - self.turn_rad) * w,
        }
    }
}

/// Why an edit could not be applied.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EditError {
    /// One edit per ground stage is needed.
    #[error("{got} ground-stage edits given, the clip has {want} ground stages")]
    EditCount {
        /// Edits given.
        got: usize,
        /// Ground stages.
        want: usize,
    },
    /// The stages describe another clip.
    #[error("the stages describe {stages} frames, the clip has {clip}")]
    Frames {
        /// Frames of the stages.
        stages: usize,
        /// Frames of the clip.
        clip: usize,
    },
    /// The edited clip is unusable.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// Each ground stage's frames and pivot: its centre of mass at its middle frame, dropped
/// onto the floor plane (Y = 0), metres. An edit turns the stage about this point.
pub fn ground_pivots(stages: &Stages, com_m: &[DVec3]) -> Vec<(FrameRange, DVec3)> {
    stages
        .stages
        .iter()
        .filter(|s| s.kind == StageKind::Ground)
        .map(|s| {
            let mid = com_m.get(s.frames.start + s.frames.len() / 2).copied().unwrap_or(DVec3::ZERO);
            (s.frames, DVec3::new(mid.x, 0.0, mid.z))
        })
        .collect()
}

/// The placement of every frame for `edits` (one per ground stage, in time order).
fn placements(stages: &Stages, com_m: &[DVec3], edits: &[GroundEdit]) -> Result<Vec<Placement>, EditError> {
    let grounds = ground_pivots(stages, com_m);
    if grounds.len() != edits.len() {
        return Err(EditError::EditCount { got: edits.len(), want: grounds.len() });
    }
    let anchors: Vec<(FrameRange, Placement)> = grounds
        .iter()
        .zip(edits)
        .map(|((r, pivot), e)| {
            let placement =
                Placement { pivot: *pivot, offset: DVec3::new(e.offset_m.x, 0.0, e.offset_m.z), turn_rad: e.turn_rad };
            (*r, placement)
        })
        .collect();
    let identity = Placement { pivot: DVec3::ZERO, offset: DVec3::ZERO, turn_rad: 0.0 };
    Ok((0..stages.frame_count)
        .map(|f| {
            if let Some((_, p)) = anchors.iter().find(|(r, _)| r.contains(f)) {
                return *p;
            }
            let before = anchors.iter().rev().find(|(r, _)| r.end <= f);
            let after = anchors.iter().find(|(r, _)| r.start > f);
            match (before, after) {
                (Some((a, pa)), Some((b, pb))) => {
                    // Between the last ground frame before and the first one after.
                    let (t0, t1) = ((a.end - 1) as f64, b.start as f64);
                    pa.lerp(pb, (f as f64 - t0) / (t1 - t0))
                }
                (Some((_, p)), None) | (None, Some((_, p))) => *p,
                (None, None) => identity,
            }
        })
        .collect())
}

/// The paper's initial guess and the naive kinematic edit: every frame's root moved by its
/// placement (ground stages rigidly, flights interpolated).
pub fn naive_edit(clip: &Clip, stages: &Stages, model: &BodyModel, edits: &[GroundEdit]) -> Result<Clip, EditError> {
    let n = clip.frame_count();
    if stages.frame_count != n {
        return Err(EditError::Frames { stages: stages.frame_count, clip: n });
    }
    let track = momentum_of_poses(&forward_kinematics(clip), clip.fps(), model);
    let place = placements(stages, &track.com_m, edits)?;
    let joints = clip.joint_count();
    let roots: Vec<usize> = (0..joints).filter(|&j| clip.skeleton().joints()[j].parent.is_none()).collect();
    let mut rotations = clip.rotations().to_vec();
    let mut translations = clip.translations().to_vec();
    for (f, p) in place.iter().enumerate() {
        let yaw = Quat::from_rotation_y(p.turn_rad as f32);
        for &j in &roots {
            let i = f * joints + j;
            rotations[i] = yaw * rotations[i];
            translations[i] = p.apply(translations[i].as_dvec3()).as_vec3();
        }
    }
    Ok(Clip::new(clip.skeleton().clone(), clip.fps(), rotations, translations, clip.import_scale)?)
}

/// How an edited clip measures up (the acceptance measures).
#[derive(Clone, Debug, PartialEq)]
pub struct EditMeasures {
    /// Per ground stage, the largest distance of a foot where it comes to rest from where
    /// the edit asked it to be (the original foot moved by the stage's edit, raised onto
    /// the floor where the capture has it below), metres: the ankle and the toe tip at the
    /// frame of each contact starting in the stage where the original's toe tip is lowest
    /// (a landing foot still slides and turns onto its heel for some frames after its toe
    /// touches), contacts held from a landing as the edit holds them
    /// ([`held_from_landings`]: a capture's toe that slides on at floor height after the
    /// landing is held at its lowest point); a stage where no contact starts, the ankles at
    /// its first frame.
    pub placement_error_m: Vec<f64>,
    /// Largest horizontal drift of a planted foot's toe tip during any of its contact
    /// intervals, metres (from its place at the interval's first frame): the point a
    /// planted foot rolls about, which stays put while the heel rises at a take-off.
    pub planted_drift_m: f64,
    /// Deepest a foot goes below the original floor, metres (0 when never below): its
    /// ankle and its toe tip, each against the height it rests at in the original.
    pub below_floor_m: f64,
    /// Per flight stage, RMS distance of the centre of mass from the best parabola under
    /// `gravity_mps2`, metres.
    pub parabola_rms_m: Vec<f64>,
    /// Per border (stage i to i + 1), the extra change of linear momentum across it that
    /// the edit asks for compared with the original, kg·m/s: the impulse nobody supplies.
    pub border_momentum_jump: Vec<f64>,
}

/// Measures `edited` against `original` and the `edits` asked, with `feet` the ankle joints
/// and `planted` the (ankle joint, frames) contacts of the original.
#[allow(clippy::too_many_arguments)]
pub fn measure_edit(
    original: &Clip,
    edited: &Clip,
    stages: &Stages,
    model: &BodyModel,
    edits: &[GroundEdit],
    feet: &[usize],
    planted: &[(usize, FrameRange)],
    gravity_mps2: f64,
) -> Result<EditMeasures, EditError> {
    let (po, pe): (ClipPoses, ClipPoses) = (forward_kinematics(original), forward_kinematics(edited));
    let to = momentum_of_poses(&po, original.fps(), model);
    let te = momentum_of_poses(&pe, edited.fps(), model);
    let place = placements(stages, &to.com_m, edits)?;
    let foot = |poses: &ClipPoses, f: usize, j: usize| poses.position(f, j).as_dvec3();
    let floor = floor_height(&po, feet);
    let grounds = stages.ground_frames();
    let skeleton = edited.skeleton();
    let toes: Vec<usize> = feet.iter().map(|&j| limb_tip(skeleton, j)).collect();
    let toe_floor = floor_height(&po, &toes);
    // The distance of joint `j` at frame `f` from where the edit asked it, raised onto `rest`.
    let missed = |f: usize, j: usize, rest: f64| {
        let mut asked = place[f].apply(foot(&po, f, j));
        asked.y = asked.y.max(rest);
        (foot(&pe, f, j) - asked).length()
    };
    let held = held_from_landings(planted, &grounds, original.fps());
    let placement_error_m = grounds
        .iter()
        .map(|g| {
            // (ankle, toe tip, the contact's frame where the original's toe tip is lowest)
            let resting: Vec<(usize, usize, usize)> = held
                .iter()
                .filter(|(_, r)| g.contains(r.start) && r.end <= po.frame_count())
                .filter_map(|&(j, r)| {
                    let toe = limb_tip(skeleton, j);
                    let lowest =
                        (r.start..r.end).min_by(|a, b| foot(&po, *a, toe).y.total_cmp(&foot(&po, *b, toe).y))?;
                    Some((j, toe, lowest))
                })
                .collect();
            if resting.is_empty() {
                return feet.iter().map(|&j| missed(g.start, j, floor)).fold(0.0, f64::max);
            }
            resting
                .iter()
                .map(|&(j, toe, f)| missed(f, j, floor).max(missed(f, toe, floor_height(&po, &[toe]))))
                .fold(0.0, f64::max)
        })
        .collect();
    let mut planted_drift_m = 0.0f64;
    for &(j, r) in planted {
        let toe = limb_tip(skeleton, j);
        for f in r.start..r.end.min(pe.frame_count()) {
            let drift = (foot(&pe, f, toe) - foot(&pe, r.start, toe)).with_y(0.0).length();
            planted_drift_m = planted_drift_m.max(drift);
        }
    }
    // Ankles and toe tips each against the height they rest at in the original.
    let points: Vec<(usize, f64)> =
        feet.iter().map(|&j| (j, floor)).chain(toes.iter().map(|&t| (t, toe_floor))).collect();
    let below_floor_m = (0..pe.frame_count())
        .flat_map(|f| points.iter().map(move |&(j, rest)| (f, j, rest)))
        .map(|(f, j, rest)| rest - foot(&pe, f, j).y)
        .fold(0.0, f64::max);
    let fps = edited.fps();
    let parabola_rms_m = stages
        .flights()
        .map(|s| {
            let com = &te.com_m[s.frames.start..s.frames.end];
            // Remove the known gravity term, then the best line per component.
            let lifted: Vec<DVec3> = com
                .iter()
                .enumerate()
                .map(|(i, c)| {
                    let t = i as f64 / fps;
                    *c + DVec3::new(0.0, 0.5 * gravity_mps2 * t * t, 0.0)
                })
                .collect();
            line_rms(&lifted, fps)
        })
        .collect();
    let n = te.com_m.len();
    // Velocity over the interval (b−2, b−1) before border b and over (b, b+1) after it.
    let change = |com: &[DVec3], b: usize| (com[b + 1] - com[b] - (com[b - 1] - com[b - 2])) * fps;
    let border_momentum_jump = stages
        .stages
        .windows(2)
        .map(|w| {
            let b = w[1].frames.start;
            if b < 2 || b + 1 >= n {
                return 0.0;
            }
            ((change(&te.com_m, b) - change(&to.com_m, b)) * model.total_mass_kg).length()
        })
        .collect();
    Ok(EditMeasures { placement_error_m, planted_drift_m, below_floor_m, parabola_rms_m, border_momentum_jump })
}

/// A foot contact that starts no later than this after a landing is held from the landing,
/// seconds.
pub const LANDING_SECS: f64 = 0.1;

/// The contacts an edit holds: `planted` (foot joint, frames), each starting no later than
/// [`LANDING_SECS`] after a landing (the first frame of a ground stage but the clip's first)
/// moved to start there. The edit may bring a foot down faster than the capture did, and a
/// foot left free until its contact slid on after touching down (2 cm over CMU 16_01's
/// landing).
pub fn held_from_landings(
    planted: &[(usize, FrameRange)],
    grounds: &[FrameRange],
    fps: f64,
) -> Vec<(usize, FrameRange)> {
    let landing = (LANDING_SECS * fps).round() as usize;
    planted
        .iter()
        .map(|&(j, r)| {
            match grounds.iter().find(|g| g.start > 0 && r.start > g.start && r.start <= g.start + landing) {
                Some(g) => (j, FrameRange::new(g.start, r.end)),
                None => (j, r),
            }
        })
        .collect()
}

/// The floor under `feet` in `poses`: the lowest of their resting heights
/// ([`ground_height`](super::contacts::ground_height)), metres.
pub fn floor_height(poses: &ClipPoses, feet: &[usize]) -> f64 {
    feet.iter()
        .map(|&j| {
            let track: Vec<DVec3> = (0..poses.frame_count()).map(|f| poses.position(f, j).as_dvec3()).collect();
            super::contacts::ground_height(&track)
        })
        .fold(f64::INFINITY, f64::min)
}

/// RMS distance of `points` (one per frame) from their least-squares line in time.
fn line_rms(points: &[DVec3], fps: f64) -> f64 {
    let n = points.len() as f64;
    if points.len() < 2 {
        return 0.0;
    }
    let ts: Vec<f64> = (0..points.len()).map(|i| i as f64 / fps).collect();
    let mt = ts.iter().sum::<f64>() / n;
    let mp = points.iter().sum::<DVec3>() / n;
    let stt: f64 = ts.iter().map(|t| (t - mt).powi(2)).sum();
    let slope = ts.iter().zip(points).map(|(t, p)| (*p - mp) * (t - mt)).sum::<DVec3>() / stt.max(f64::MIN_POSITIVE);
    let sq: f64 = ts.iter().zip(points).map(|(t, p)| (mp + slope * (t - mt) - *p).length_squared()).sum();
    (sq / n).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Stage;

    #[test]
    fn placements_turn_about_the_pivot_and_interpolate_over_flights() {
        let stages = Stages {
            fps: 10.0,
            frame_count: 10,
            stages: vec![
                Stage { kind: StageKind::Ground, frames: FrameRange::new(0, 3) },
                Stage { kind: StageKind::Flight, frames: FrameRange::new(3, 7) },
                Stage { kind: StageKind::Ground, frames: FrameRange::new(7, 10) },
            ],
            gravity_mps2: 9.81,
        };
        let com = vec![DVec3::new(2.0, 1.0, 0.0); 10];
        let turn = std::f64::consts::FRAC_PI_2;
        let edits = [GroundEdit::default(), GroundEdit { offset_m: DVec3::new(0.0, 5.0, 1.0), turn_rad: turn }];
        let p = placements(&stages, &com, &edits).unwrap();
        // Ground stage 2: a point 1 m along +X from the pivot (2, 0, 0) turns a quarter about
        // +Y to −Z, then shifts 1 m along +Z (the vertical part of the offset is dropped).
        let moved = p[8].apply(DVec3::new(3.0, 0.0, 0.0));
        assert!((moved - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-12, "{moved}");
        // Frame 5 lies 3/5 of the way from the last ground frame (2) to the next (7).
        assert!((p[5].turn_rad - 0.6 * turn).abs() < 1e-12);
        assert!((p[5].offset - DVec3::new(0.0, 0.0, 0.6)).length() < 1e-12);
        assert_eq!(p[1], p[0]);
        assert_eq!(placements(&stages, &com, &edits[..1]), Err(EditError::EditCount { got: 1, want: 2 }));
    }
}
