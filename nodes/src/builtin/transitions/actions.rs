//! Action labels: names for the actions of a clip set, each a whole clip or the stretch of
//! one between two times — so a sequence can ask for "walk, punch, kick" and pick single
//! actions out of long takes that hold several.
//!
//! A label file is RON:
//!
//! ```ron
//! (actions: {
//!     "walk": (clip: "02_01"),
//!     "punch": (clip: "02_05", start_secs: 1.2, end_secs: 3.4),
//! })
//! ```
//!
//! `start_secs` defaults to the clip's start and `end_secs` to its end; both are seconds
//! from the clip's first frame and round to the nearest frame, both ends included.

use std::collections::BTreeMap;
use std::sync::Arc;

use serde::Deserialize;

use crate::model::{Clip, ClipSet, FrameRange};
use crate::node::did_you_mean;

/// What one label names.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActionSpan {
    /// Name of a clip of the set.
    pub clip: String,
    /// Where the action starts, seconds from the clip's first frame (default 0).
    #[serde(default)]
    pub start_secs: f64,
    /// Where it ends, seconds from the clip's first frame (default: the clip's end).
    #[serde(default = "to_the_end")]
    pub end_secs: f64,
}

fn to_the_end() -> f64 {
    f64::INFINITY
}

/// A label file: action name → span.
#[derive(Clone, Debug, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActionLabels {
    /// The labelled actions, by name.
    pub actions: BTreeMap<String, ActionSpan>,
}

/// An action ready to play.
#[derive(Clone, Debug, PartialEq)]
pub struct Action {
    /// The name it was asked for by.
    pub name: String,
    /// The clip of the set it comes from.
    pub clip_name: String,
    /// Its frames in that clip.
    pub frames: FrameRange,
    /// Those frames.
    pub clip: Arc<Clip>,
}

impl ActionLabels {
    /// Reads a label file's text; errors carry the line and column.
    pub fn parse(text: &str) -> Result<ActionLabels, String> {
        ron::from_str(text).map_err(|e| e.to_string())
    }

    /// Every label checked against `set` (its clip exists, the times lie inside it and
    /// span at least two frames) and turned into frames; an error names the label.
    pub fn resolve(&self, set: &ClipSet) -> Result<BTreeMap<String, Action>, String> {
        let mut out = BTreeMap::new();
        for (name, span) in &self.actions {
            let named = set.get(&span.clip).ok_or_else(|| {
                let hint = did_you_mean(&span.clip, set.clips().iter().map(|c| c.name.as_str()));
                format!("action '{name}': no clip called '{}' in the set{hint}", span.clip)
            })?;
            let clip = &named.clip;
            let (fps, duration) = (clip.fps(), clip.duration_secs());
            let (start, end) = (span.start_secs, span.end_secs.min(duration));
            if !(start.is_finite() && start >= 0.0) || span.end_secs.is_nan() {
                return Err(format!("action '{name}': start_secs must be a number ≥ 0 and end_secs a number"));
            }
            if span.end_secs.is_finite() && span.end_secs > duration + 0.5 / fps {
                return Err(format!(
                    "action '{name}': end_secs {} is after the end of '{}' ({duration:.3} s)",
                    span.end_secs, span.clip
                ));
            }
            let (first, last) = ((start * fps).round() as usize, (end * fps).round() as usize);
            if last <= first {
                return Err(format!(
                    "action '{name}': {start} s to {end} s of '{}' holds fewer than two frames",
                    span.clip
                ));
            }
            let frames = FrameRange::new(first, last + 1);
            let action = Action {
                name: name.clone(),
                clip_name: span.clip.clone(),
                frames,
                clip: Arc::new(clip.slice(frames.start, frames.end)),
            };
            out.insert(name.clone(), action);
        }
        Ok(out)
    }
}

/// The actions called `names`: a label of `labelled` first, else a whole clip of `set`.
/// An unknown name is an error suggesting the nearest label or clip name.
pub fn find_actions(set: &ClipSet, labelled: &BTreeMap<String, Action>, names: &[&str]) -> Result<Vec<Action>, String> {
    names
        .iter()
        .map(|&name| {
            if let Some(a) = labelled.get(name) {
                return Ok(a.clone());
            }
            if let Some(c) = set.get(name) {
                let frames = FrameRange::new(0, c.clip.frame_count());
                return Ok(Action { name: name.into(), clip_name: name.into(), frames, clip: c.clip.clone() });
            }
            let known = labelled.keys().map(String::as_str).chain(set.clips().iter().map(|c| c.name.as_str()));
            let hint = did_you_mean(name, known);
            Err(format!("no action or clip called '{name}'{hint}"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ImportScale, Joint, NamedClip, Skeleton};
    use glam::{Quat, Vec3};

    /// Two clips at 10 fps: "long" 31 frames (3 s) whose root height is the frame index
    /// in metres, so a frame can be identified from its pose; "short" 5 frames.
    fn set() -> ClipSet {
        let s = Arc::new(Skeleton::new(vec![Joint::new("Hips", None, Vec3::Y)]).unwrap());
        let clip = |frames: usize| {
            let translations = (0..frames).map(|f| Vec3::new(0.0, f as f32, 0.0)).collect();
            Arc::new(
                Clip::new(s.clone(), 10.0, vec![Quat::IDENTITY; frames], translations, ImportScale::METRES).unwrap(),
            )
        };
        ClipSet::new(vec![
            NamedClip { name: "long".into(), clip: clip(31) },
            NamedClip { name: "short".into(), clip: clip(5) },
        ])
        .unwrap()
    }

    #[test]
    fn labels_pick_whole_clips_and_time_ranges() {
        let labels = ActionLabels::parse(
            r#"(actions: {
                "punch": (clip: "long", start_secs: 1.2, end_secs: 2.04),
                "rest": (clip: "short"),
                "tail": (clip: "long", start_secs: 2.5),
            })"#,
        )
        .unwrap();
        let set = set();
        let labelled = labels.resolve(&set).unwrap();
        let got = find_actions(&set, &labelled, &["punch", "rest", "tail", "long"]).unwrap();
        // 1.2 s → frame 12, 2.04 s → frame 20.4 → 20, both included: 9 frames, heights 12..=20.
        assert_eq!((got[0].clip_name.as_str(), got[0].frames), ("long", FrameRange::new(12, 21)));
        let heights: Vec<f32> = got[0].clip.root_translations().map(|t| t.y).collect();
        assert_eq!(heights, (12..=20).map(|f| f as f32).collect::<Vec<_>>());
        assert_eq!(got[1].frames, FrameRange::new(0, 5));
        assert_eq!(got[2].frames, FrameRange::new(25, 31));
        // A clip name still works without a label.
        assert_eq!((got[3].name.as_str(), got[3].frames), ("long", FrameRange::new(0, 31)));
    }

    #[test]
    fn unknown_names_and_bad_spans_are_explained() {
        let set = set();
        let labelled = ActionLabels::parse(r#"(actions: {"punch": (clip: "long")})"#).unwrap().resolve(&set).unwrap();
        let e = find_actions(&set, &labelled, &["pnuch"]).unwrap_err();
        assert!(e.contains("'pnuch'") && e.contains("did you mean 'punch'"), "{e}");
        let e = find_actions(&set, &labelled, &["shrot"]).unwrap_err();
        assert!(e.contains("did you mean 'short'"), "{e}");
        let bad = |text: &str| ActionLabels::parse(text).unwrap().resolve(&set).unwrap_err();
        let e = bad(r#"(actions: {"kick": (clip: "lnog")})"#);
        assert!(e.contains("action 'kick'") && e.contains("did you mean 'long'"), "{e}");
        assert!(bad(r#"(actions: {"kick": (clip: "long", end_secs: 3.5)})"#).contains("after the end"));
        assert!(
            bad(r#"(actions: {"kick": (clip: "long", start_secs: 2.0, end_secs: 2.0)})"#).contains("fewer than two")
        );
        assert!(bad(r#"(actions: {"kick": (clip: "long", start_secs: -1.0)})"#).contains("≥ 0"));
        // A misspelt field is refused with its position.
        let e = ActionLabels::parse(r#"(actions: {"kick": (clip: "long", start: 1.0)})"#).unwrap_err();
        assert!(e.contains("start") && e.contains("1:"), "{e}");
    }
}
