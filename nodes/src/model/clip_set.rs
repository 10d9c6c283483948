//! A set of named clips on one skeleton at one frame rate: the corpus a transition graph is
//! built from.

use std::sync::Arc;

use super::clip::Clip;
use super::skeleton::Skeleton;

/// One action of a [`ClipSet`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NamedClip {
    /// Action name (the file stem unless relabelled), unique in the set.
    pub name: String,
    /// The clip, on the set's skeleton and at the set's frame rate.
    pub clip: Arc<Clip>,
}

/// Clips sharing one skeleton (same joint names, hierarchy and rest offsets) and one frame
/// rate, sorted by name so every consumer sees them in the same order.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClipSet {
    skeleton: Arc<Skeleton>,
    fps: f64,
    clips: Vec<NamedClip>,
}

/// Why clips cannot form a set.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClipSetError {
    /// No clips.
    #[error("the clip set is empty")]
    Empty,
    /// A clip is on another skeleton or at another rate than the first.
    #[error("clip '{name}' {reason}")]
    Mismatch {
        /// The clip's name.
        name: String,
        /// What differs.
        reason: String,
    },
    /// Two clips share a name.
    #[error("two clips are called '{0}'")]
    DuplicateName(String),
}

impl ClipSet {
    /// Builds a set, sorting by name; every clip must share the first clip's skeleton
    /// (the same `Arc`) and frame rate.
    pub fn new(mut clips: Vec<NamedClip>) -> Result<ClipSet, ClipSetError> {
        clips.sort_by(|a, b| a.name.cmp(&b.name));
        let first = clips.first().ok_or(ClipSetError::Empty)?;
        let (skeleton, fps) = (first.clip.skeleton().clone(), first.clip.fps());
        for pair in clips.windows(2) {
            if pair[0].name == pair[1].name {
                return Err(ClipSetError::DuplicateName(pair[0].name.clone()));
            }
        }
        for c in &clips {
            if !Arc::ptr_eq(c.clip.skeleton(), &skeleton) {
                return Err(ClipSetError::Mismatch { name: c.name.clone(), reason: "is on another skeleton".into() });
            }
            if (c.clip.fps() - fps).abs() > 1e-9 * fps {
                return Err(ClipSetError::Mismatch {
                    name: c.name.clone(),
                    reason: format!("runs at {} fps, the set at {fps} fps", c.clip.fps()),
                });
            }
        }
        Ok(ClipSet { skeleton, fps, clips })
    }

    /// The shared skeleton.
    pub fn skeleton(&self) -> &Arc<Skeleton> {
        &self.skeleton
    }

    /// The shared frame rate, frames per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// The clips, sorted by name.
    pub fn clips(&self) -> &[NamedClip] {
        &self.clips
    }

    /// The clip called `name`.
    pub fn get(&self, name: &str) -> Option<&NamedClip> {
        self.clips.binary_search_by(|c| c.name.as_str().cmp(name)).ok().map(|i| &self.clips[i])
    }

    /// Total frames over all clips.
    pub fn frame_count(&self) -> usize {
        self.clips.iter().map(|c| c.clip.frame_count()).sum()
    }

    /// Names, frame counts and the rate, for reports and regression facts.
    pub fn summary(&self) -> serde_json::Value {
        let clips: serde_json::Map<String, serde_json::Value> =
            self.clips.iter().map(|c| (c.name.clone(), c.clip.frame_count().into())).collect();
        serde_json::json!({
            "fps": self.fps,
            "joints": self.skeleton.len(),
            "frames": self.frame_count(),
            "clips": clips,
        })
    }
}
