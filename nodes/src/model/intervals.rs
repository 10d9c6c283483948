//! Frame intervals of a clip: motion phases and foot contacts.

use serde::{Deserialize, Serialize};

/// Frames `start..end` (half-open) of a clip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct FrameRange {
    /// First frame inside.
    pub start: usize,
    /// First frame after.
    pub end: usize,
}

impl FrameRange {
    /// `start..end`; an inverted range becomes empty at `start`.
    pub fn new(start: usize, end: usize) -> Self {
        FrameRange { start, end: end.max(start) }
    }

    /// Number of frames inside.
    pub fn len(&self) -> usize {
        self.end - self.start
    }

    /// True when no frame is inside.
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }

    /// Whether `frame` is inside.
    pub fn contains(&self, frame: usize) -> bool {
        (self.start..self.end).contains(&frame)
    }

    /// The frames inside both, if any.
    pub fn intersect(&self, other: &FrameRange) -> Option<FrameRange> {
        let r = FrameRange::new(self.start.max(other.start), self.end.min(other.end));
        (!r.is_empty()).then_some(r)
    }

    /// The first half (the middle frame goes to the second half).
    pub fn first_half(&self) -> FrameRange {
        FrameRange::new(self.start, self.start + self.len() / 2)
    }

    /// The second half.
    pub fn second_half(&self) -> FrameRange {
        FrameRange::new(self.start + self.len() / 2, self.end)
    }
}

/// The phases of a dynamic full-body motion (Shum et al. 2009): the main phase carries the
/// peak angular momentum; the preparatory and posterior phases, when present, turn the
/// other way.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Phases {
    /// Frame rate of the clip the frames refer to.
    pub fps: f64,
    /// Frames in that clip.
    pub frame_count: usize,
    /// The frame inside the main phase the segmentation started from.
    pub main_frame: usize,
    /// Wind-up before the main phase, if any.
    pub preparatory: Option<FrameRange>,
    /// The main phase.
    pub main: FrameRange,
    /// Recovery after the main phase, if any.
    pub posterior: Option<FrameRange>,
}

/// When one foot touches the ground.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FootContacts {
    /// Which foot, by its joint name.
    pub foot: String,
    /// Frames in contact, sorted and disjoint.
    pub intervals: Vec<FrameRange>,
}

/// Foot contacts of a clip.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contacts {
    /// Frame rate of the clip the frames refer to.
    pub fps: f64,
    /// Frames in that clip.
    pub frame_count: usize,
    /// Contacts per foot (left first).
    pub feet: Vec<FootContacts>,
    /// Frames where both feet are in contact, sorted and disjoint.
    pub double_support: Vec<FrameRange>,
    /// Contacts per hand (left first) when the hands are watched (cartwheels, crawls):
    /// they support the body like the feet (stages, foot locking) but are not feet (gait
    /// measures, soles).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hands: Vec<FootContacts>,
}

impl Contacts {
    /// Every limb's contacts: the feet's, then the hands'.
    pub fn limbs(&self) -> impl Iterator<Item = &FootContacts> {
        self.feet.iter().chain(&self.hands)
    }
}

/// The frames inside both sorted, disjoint interval lists.
pub fn intersect_all(a: &[FrameRange], b: &[FrameRange]) -> Vec<FrameRange> {
    let (mut i, mut j, mut out) = (0, 0, Vec::new());
    while i < a.len() && j < b.len() {
        if let Some(r) = a[i].intersect(&b[j]) {
            out.push(r);
        }
        if a[i].end < b[j].end { i += 1 } else { j += 1 }
    }
    out
}

/// The frames inside either sorted, disjoint interval list, as one sorted, disjoint list
/// (touching intervals merged).
pub fn union_all(a: &[FrameRange], b: &[FrameRange]) -> Vec<FrameRange> {
    let mut all: Vec<FrameRange> = a.iter().chain(b).copied().filter(|r| !r.is_empty()).collect();
    all.sort();
    let mut out: Vec<FrameRange> = Vec::with_capacity(all.len());
    for r in all {
        match out.last_mut() {
            Some(last) if r.start <= last.end => last.end = last.end.max(r.end),
            _ => out.push(r),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interval_lists_intersect_like_sets_of_frames() {
        let a = [FrameRange::new(0, 10), FrameRange::new(20, 30)];
        let b = [FrameRange::new(5, 25), FrameRange::new(28, 40)];
        let got = intersect_all(&a, &b);
        let frames = |v: &[FrameRange]| v.iter().flat_map(|r| r.start..r.end).collect::<Vec<_>>();
        let want: Vec<usize> = frames(&a).into_iter().filter(|f| frames(&b).contains(f)).collect();
        assert_eq!(frames(&got), want);
        assert_eq!(got.len(), 3);
    }

    #[test]
    fn union_merges_overlapping_and_touching_intervals() {
        let a = [FrameRange::new(0, 5), FrameRange::new(10, 12)];
        let b = [FrameRange::new(4, 8), FrameRange::new(12, 14), FrameRange::new(20, 21), FrameRange::new(30, 30)];
        assert_eq!(union_all(&a, &b), vec![FrameRange::new(0, 8), FrameRange::new(10, 14), FrameRange::new(20, 21)]);
    }

    #[test]
    fn halves_cover_the_range() {
        let r = FrameRange::new(4, 11);
        assert_eq!((r.first_half(), r.second_half()), (FrameRange::new(4, 7), FrameRange::new(7, 11)));
        assert!(FrameRange::new(5, 2).is_empty());
    }
}
