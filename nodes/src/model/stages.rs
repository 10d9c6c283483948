//! Ground and flight stages of a dynamic motion (momentum-based editing): alternating frame
//! ranges where the body touches the ground or flies ballistically.

use serde::{Deserialize, Serialize};

use super::intervals::FrameRange;

/// Whether the body is supported or airborne during a stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StageKind {
    /// At least one foot is in contact with the ground.
    Ground,
    /// No contact: only gravity acts, linear momentum falls at m·g and angular momentum is constant.
    Flight,
}

/// One stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Stage {
    /// Ground or flight.
    pub kind: StageKind,
    /// Its frames (half-open).
    pub frames: FrameRange,
}

/// The stages of one clip: they tile its frames and alternate in kind.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stages {
    /// Frame rate of the clip the frames refer to.
    pub fps: f64,
    /// Frames in that clip.
    pub frame_count: usize,
    /// The stages in time order.
    pub stages: Vec<Stage>,
    /// Gravity that makes the flight stages ballistic (fitted to the centre-of-mass
    /// parabola), m/s², pointing down (−Y).
    pub gravity_mps2: f64,
}

impl Stages {
    /// The flight stages, in time order.
    pub fn flights(&self) -> impl Iterator<Item = &Stage> {
        self.stages.iter().filter(|s| s.kind == StageKind::Flight)
    }

    /// The frames of each ground stage, in time order (the stages an edit moves).
    pub fn ground_frames(&self) -> Vec<FrameRange> {
        self.stages.iter().filter(|s| s.kind == StageKind::Ground).map(|s| s.frames).collect()
    }

    /// The index of the stage holding `frame`.
    pub fn stage_of(&self, frame: usize) -> Option<usize> {
        self.stages.iter().position(|s| s.frames.contains(frame))
    }
}

/// Alternating stages from a per-frame "in contact" flag: consecutive frames of equal flag
/// form one stage.
pub fn stages_from_flags(grounded: &[bool]) -> Vec<Stage> {
    let mut out: Vec<Stage> = Vec::new();
    for (f, &g) in grounded.iter().enumerate() {
        let kind = if g { StageKind::Ground } else { StageKind::Flight };
        match out.last_mut() {
            Some(last) if last.kind == kind => last.frames.end = f + 1,
            _ => out.push(Stage { kind, frames: FrameRange::new(f, f + 1) }),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_become_alternating_stages_that_tile_the_frames() {
        let flags = [true, true, false, false, false, true, false];
        let s = stages_from_flags(&flags);
        let kinds: Vec<StageKind> = s.iter().map(|s| s.kind).collect();
        use StageKind::*;
        assert_eq!(kinds, vec![Ground, Flight, Ground, Flight]);
        let ranges: Vec<(usize, usize)> = s.iter().map(|s| (s.frames.start, s.frames.end)).collect();
        assert_eq!(ranges, vec![(0, 2), (2, 5), (5, 6), (6, 7)]);
        assert!(stages_from_flags(&[]).is_empty());
    }
}
