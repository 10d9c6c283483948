//! Loading a folder of clips as one clip set: one skeleton family, one frame rate,
//! cgspeed T-pose first frames dropped. A kernel: the `transitions.load` node, the
//! candidate-path tests and the transitions benchmarks load their corpus with it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::load::{ClipLoadOptions, LeadingTPose, load_clip};
use super::resample::resample;
use crate::formats::FormatError;
use crate::model::clip::{sampled_bytes, sampling_refusal};
use crate::model::{Clip, ClipError, ClipSet, ClipSetError, NamedClip, Skeleton};

/// Case-insensitive wildcard match (`*` any run, `?` one character).
fn wildcard(pattern: &[u8], name: &[u8]) -> bool {
    match (pattern.first(), name.first()) {
        (None, None) => true,
        (Some(b'*'), _) => wildcard(&pattern[1..], name) || (!name.is_empty() && wildcard(pattern, &name[1..])),
        (Some(p), Some(n)) if *p == b'?' || p.eq_ignore_ascii_case(n) => wildcard(&pattern[1..], &name[1..]),
        _ => false,
    }
}

/// `clip` on `skeleton` (same names and hierarchy): each joint keeps its own animated
/// translation relative to its rest offset, on the reference skeleton's rest offsets; the
/// root's path (height included) is scaled by the ratio of the two skeletons' root heights,
/// so a clip captured on shorter legs does not sink into the floor on longer ones (and a
/// longer-legged actor's clip does not float), and its strides keep their length relative to
/// the legs.
fn onto_skeleton(clip: &Clip, skeleton: &Arc<Skeleton>) -> Result<Clip, ConformError> {
    if Arc::ptr_eq(clip.skeleton(), skeleton) {
        return Ok(clip.clone());
    }
    let (own, reference) = (clip.skeleton().joints(), skeleton.joints());
    if own.len() != reference.len() || own.iter().zip(reference).any(|(a, b)| a.name != b.name || a.parent != b.parent)
    {
        return Err(ConformError::OtherSkeleton);
    }
    let n = own.len();
    let root_ratio = clip.skeleton().root_height_ratio(skeleton).unwrap_or(1.0);
    let translations = clip
        .translations()
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let j = i % n;
            if j == 0 { *t * root_ratio } else { reference[j].rest_offset + (*t - own[j].rest_offset) }
        })
        .collect();
    Ok(Clip::new(skeleton.clone(), clip.fps(), clip.rotations().to_vec(), translations, clip.import_scale)?)
}

/// `clip` at `fps` on `skeleton`.
pub fn conform(clip: &Clip, skeleton: &Arc<Skeleton>, fps: f64) -> Result<Clip, ConformError> {
    let at_rate = if (clip.fps() - fps).abs() > 1e-6 * fps { resample(clip, fps)? } else { clip.clone() };
    onto_skeleton(&at_rate, skeleton)
}

/// Why a clip could not be put on a set's skeleton and rate ([`conform`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ConformError {
    /// The clip's joints (names or hierarchy) differ from the set's.
    #[error("is on a skeleton with other joints than the graph's")]
    OtherSkeleton,
    /// Resampling or rebuilding the clip failed.
    #[error(transparent)]
    Clip(#[from] ClipError),
}

/// Why a clip set could not be loaded ([`load_clip_set`]).
#[derive(Debug, thiserror::Error)]
pub enum LoadSetError {
    /// The folder could not be listed.
    #[error("{0}")]
    Folder(String),
    /// No file matches the patterns.
    #[error("no file in {} matches '{}'", .folder.display(), .patterns.join(", "))]
    NoMatch {
        /// The folder searched.
        folder: PathBuf,
        /// The wildcard patterns.
        patterns: Vec<String>,
    },
    /// A file could not be read.
    #[error(transparent)]
    Load(#[from] FormatError),
    /// The clips read so far fill the run's memory limit.
    #[error("{clip}: the clip set's memory limit is reached: {reason}")]
    MemoryLimit {
        /// The clip refused, by its path under the folder.
        clip: String,
        /// How much it needs against what is left.
        reason: String,
    },
    /// The clip naming the skeleton family is not in the folder.
    #[error("no clip called '{0}' to pick the skeleton family from")]
    NoSuchClip(String),
    /// A clip could not be put on the set's skeleton and rate.
    #[error("{clip} {source}")]
    Conform {
        /// The clip, by its path under the folder.
        clip: String,
        /// Why.
        source: ConformError,
    },
    /// The clips do not make a set.
    #[error(transparent)]
    Set(#[from] ClipSetError),
}

/// Identity of a skeleton family: joint names and parents.
fn family_key(skeleton: &Skeleton) -> Vec<(String, Option<usize>)> {
    skeleton.joints().iter().map(|j| (j.name.clone(), j.parent)).collect()
}

/// A loaded clip set and what was left out or changed.
#[derive(Debug)]
pub struct LoadedClipSet {
    /// The set.
    pub set: ClipSet,
    /// Clips of other skeleton families, by path.
    pub left_out: Vec<String>,
    /// Oddities met (units detected, T-poses dropped).
    pub warnings: Vec<String>,
}

/// What the clips of a set may still allocate under the run's memory limit.
struct MemoryBudget {
    limit: Option<u64>,
    used: f64,
}

impl MemoryBudget {
    /// Bytes left for the next clip, `None` when there is no limit.
    fn left(&self) -> Option<u64> {
        self.limit.map(|limit| (limit as f64 - self.used).max(0.0) as u64)
    }

    /// Counts a clip of `frames` frames of `joints` joints, or refuses it, naming `clip`.
    fn take(&mut self, frames: f64, joints: usize, clip: &str) -> Result<(), LoadSetError> {
        if self.limit.is_some()
            && let Some(reason) = sampling_refusal(frames, joints, self.left(), "fps")
        {
            return Err(LoadSetError::MemoryLimit { clip: clip.to_owned(), reason });
        }
        self.used += sampled_bytes(frames, joints);
        Ok(())
    }
}

/// How many files and folders a clip-set folder may hold: a library of actions, not a disk.
pub const MAX_FOLDER_ENTRIES: usize = 200_000;

/// Loads every file under `folder` (recursively) whose name matches one of `patterns`
/// (comma-separated wildcards), groups them by skeleton family, keeps the family of the
/// clip named `family` (else the largest family, ties to the first file), drops cgspeed
/// T-pose first frames, resamples to `fps` and puts every clip on the first clip's skeleton.
/// Actions are named by file stem, or by their path under `folder` when two stems clash.
/// The clips read and the resampled set together stay within `max_bytes` (the run's memory
/// limit; `None` for the readers' default per clip), checked before each allocation.
pub fn load_clip_set(
    folder: &Path,
    patterns: &str,
    fps: f64,
    family: Option<&str>,
    max_bytes: Option<u64>,
) -> Result<LoadedClipSet, LoadSetError> {
    let patterns: Vec<&str> = patterns.split(',').map(str::trim).filter(|p| !p.is_empty()).collect();
    let mut files: Vec<_> = crate::corpus::files_under(folder, &["bvh", "glb", "gltf", "fbx"], MAX_FOLDER_ENTRIES)
        .map_err(LoadSetError::Folder)?
        .into_iter()
        .filter(|p| {
            let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            patterns.iter().any(|pat| wildcard(pat.as_bytes(), name.as_bytes()))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(LoadSetError::NoMatch {
            folder: folder.to_path_buf(),
            patterns: patterns.iter().map(|p| p.to_string()).collect(),
        });
    }
    let mut warnings = Vec::new();
    let mut clips = Vec::new();
    let mut budget = MemoryBudget { limit: max_bytes, used: 0.0 };
    for path in &files {
        let options =
            ClipLoadOptions { max_clip_bytes: budget.left(), t_pose: LeadingTPose::Drop, ..Default::default() };
        let loaded = load_clip(path, options)?;
        warnings.extend(loaded.warnings);
        let relative = path.strip_prefix(folder).unwrap_or(path).with_extension("");
        // BVH clips are bounded by their file, not by the option: count them all here.
        budget.take(loaded.value.frame_count() as f64, loaded.value.joint_count(), &relative.to_string_lossy())?;
        clips.push((relative.to_string_lossy().replace('\\', "/"), loaded.value));
    }
    let mut families: BTreeMap<Vec<(String, Option<usize>)>, Vec<usize>> = BTreeMap::new();
    for (i, (_, clip)) in clips.iter().enumerate() {
        families.entry(family_key(clip.skeleton())).or_default().push(i);
    }
    let stem = |relative: &str| relative.rsplit('/').next().unwrap_or(relative).to_string();
    let chosen: Vec<usize> = match family {
        Some(name) => {
            let index = clips
                .iter()
                .position(|(r, _)| r == name || stem(r) == name)
                .ok_or_else(|| LoadSetError::NoSuchClip(name.to_owned()))?;
            families.values().find(|f| f.contains(&index)).cloned().unwrap_or_default()
        }
        None => families.values().max_by_key(|f| (f.len(), std::cmp::Reverse(f[0]))).cloned().unwrap_or_default(),
    };
    let left_out: Vec<String> = (0..clips.len()).filter(|i| !chosen.contains(i)).map(|i| clips[i].0.clone()).collect();
    let skeleton = clips[chosen[0]].1.skeleton().clone();
    let mut stems: BTreeMap<String, usize> = BTreeMap::new();
    for &i in &chosen {
        *stems.entry(stem(&clips[i].0)).or_default() += 1;
    }
    let mut named = Vec::new();
    for &i in &chosen {
        let (relative, clip) = &clips[i];
        budget.take((clip.duration_secs() * fps).ceil() + 1.0, skeleton.len(), relative)?;
        let clip =
            conform(clip, &skeleton, fps).map_err(|source| LoadSetError::Conform { clip: relative.clone(), source })?;
        if clip.frame_count() < 2 {
            warnings.push(format!("{relative}: left out, fewer than 2 frames"));
            continue;
        }
        let name = if stems[&stem(relative)] > 1 { relative.clone() } else { stem(relative) };
        named.push(NamedClip { name, clip: Arc::new(clip) });
    }
    let set = ClipSet::new(named)?;
    Ok(LoadedClipSet { set, left_out, warnings })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A standing clip captured on 0.8 m legs, put on a set whose skeleton has 1.0 m legs:
    /// its feet stay on the floor (found by forward kinematics on the set's skeleton, not
    /// from the scaling) and its root path grows with the legs.
    #[test]
    fn a_clip_on_shorter_legs_stands_on_the_floor_of_a_longer_legged_set() {
        use crate::model::{ImportScale, Joint, forward_kinematics};
        use glam::{Quat, Vec3};
        let legs = |length: f32| {
            Arc::new(
                Skeleton::new(vec![
                    Joint::new("Hips", None, Vec3::new(0.0, length, 0.0)),
                    Joint::new("LeftFoot", Some(0), Vec3::new(0.1, -length, 0.0)),
                    Joint::new("RightFoot", Some(0), Vec3::new(-0.1, -length, 0.0)),
                ])
                .unwrap(),
            )
        };
        let (short, long) = (legs(0.8), legs(1.0));
        // Two frames walking 0.3 m forward on the short legs, feet on the floor.
        let translations: Vec<Vec3> = [0.0f32, 0.3]
            .iter()
            .flat_map(|z| [Vec3::new(0.0, 0.8, *z), Vec3::new(0.1, -0.8, 0.0), Vec3::new(-0.1, -0.8, 0.0)])
            .collect();
        let clip = Clip::new(short, 30.0, vec![Quat::IDENTITY; 6], translations, ImportScale::METRES).unwrap();
        let on_long = onto_skeleton(&clip, &long).unwrap();
        let poses = forward_kinematics(&on_long);
        for f in 0..2 {
            for foot in [1, 2] {
                assert!(poses.position(f, foot).y.abs() < 1e-6, "frame {f}: foot at {}", poses.position(f, foot).y);
            }
        }
        // The stride grows with the legs: 0.3 m × 1.0 / 0.8.
        let stride = poses.position(1, 0).z - poses.position(0, 0).z;
        assert!((stride - 0.375).abs() < 1e-6, "{stride}");
    }

    #[test]
    fn wildcards_match_file_names() {
        assert!(wildcard(b"*.bvh", b"02_01.BVH"));
        assert!(wildcard(b"02_0?.bvh", b"02_05.bvh"));
        assert!(!wildcard(b"02_*.bvh", b"144_05.bvh"));
        assert!(wildcard(b"*", b""));
    }
}
