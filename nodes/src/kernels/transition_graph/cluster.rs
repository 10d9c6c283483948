//! Frame-based two-pass clustering (Peng et al. 2007, "Frame-Based Two-Pass Clustering").
//!
//! 1. The first frame is the centre of cluster 0.
//! 2. First pass, frames in corpus order: with d the distance to the nearest centre,
//!    d < r joins that cluster, d > 2r starts a new cluster centred on the frame, anything
//!    between is left undefined.
//! 3. Second pass: every undefined frame joins its nearest centre (no new clusters).

use std::sync::Arc;

use rayon::prelude::*;

use super::distance::{DistanceParams, PoseFeatures};
use crate::cancel::{Cancel, Cancelled};
use crate::model::ClipSet;

/// Every frame of a clip set labelled with a cluster, and the cluster centres.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Clusters {
    /// The corpus.
    pub clip_set: Arc<ClipSet>,
    /// The distance the clusters were made with.
    pub params: DistanceParams,
    /// Radius r (in units of the distance, rad²).
    pub radius: f32,
    /// Features of every frame, clips one after another.
    pub features: PoseFeatures,
    /// Index of each clip's first frame in `features` (one more entry: the total).
    pub clip_starts: Vec<usize>,
    /// Cluster of every frame.
    pub labels: Vec<u32>,
    /// Centre frame of every cluster (index into `features`).
    pub centres: Vec<usize>,
    /// Frames left undefined by the first pass.
    pub undefined_after_first_pass: usize,
}

/// Result of the two passes over a feature table.
#[derive(Clone, Debug, PartialEq)]
pub struct TwoPass {
    /// Cluster of every frame.
    pub labels: Vec<u32>,
    /// Centre frame of every cluster.
    pub centres: Vec<usize>,
    /// Frames left undefined by the first pass.
    pub undefined: usize,
}

/// The nearest centre to frame `i` of `query` and its distance.
pub fn nearest_centre(features: &PoseFeatures, centres: &[usize], query: &PoseFeatures, i: usize) -> (u32, f32) {
    let mut best = (0, f32::INFINITY);
    for (c, &f) in centres.iter().enumerate() {
        let d = query.distance_below(i, features, f, best.1);
        if d < best.1 {
            best = (c as u32, d);
        }
    }
    best
}

/// The two-pass clustering of every frame of `features` with radius `radius`. The work per
/// frame is one distance per centre, so `cancel` is polled once per frame.
pub fn two_pass(features: &PoseFeatures, radius: f32, cancel: Cancel) -> Result<TwoPass, Cancelled> {
    const UNDEFINED: u32 = u32::MAX;
    let mut labels = vec![UNDEFINED; features.len()];
    let mut centres: Vec<usize> = Vec::new();
    for (i, label) in labels.iter_mut().enumerate() {
        cancel.check()?;
        let (c, d) = nearest_centre(features, &centres, features, i);
        if centres.is_empty() || d > 2.0 * radius {
            *label = centres.len() as u32;
            centres.push(i);
        } else if d < radius {
            *label = c;
        }
    }
    let undefined = labels.iter().filter(|&&l| l == UNDEFINED).count();
    labels.par_iter_mut().enumerate().filter(|(_, l)| **l == UNDEFINED).try_for_each(|(i, l)| {
        cancel.check()?;
        *l = nearest_centre(features, &centres, features, i).0;
        Ok(())
    })?;
    Ok(TwoPass { labels, centres, undefined })
}

/// Features of every frame of `clip_set` (velocities never straddle two clips) and the
/// index of each clip's first frame.
pub fn corpus_features(clip_set: &ClipSet, params: &DistanceParams) -> (PoseFeatures, Vec<usize>) {
    let mut features = PoseFeatures::empty(params);
    let mut starts = vec![0];
    for c in clip_set.clips() {
        let clip = &c.clip;
        features.push_frames(
            clip.rotations(),
            clip.translations(),
            clip.joint_count(),
            clip.fps(),
            0..clip.frame_count(),
        );
        starts.push(features.len());
    }
    (features, starts)
}

/// Clusters every frame of `clip_set`; stops early once `cancel` is raised.
pub fn cluster(
    clip_set: Arc<ClipSet>,
    params: DistanceParams,
    radius: f32,
    cancel: Cancel,
) -> Result<Clusters, Cancelled> {
    let (features, clip_starts) = corpus_features(&clip_set, &params);
    let TwoPass { labels, centres, undefined } = two_pass(&features, radius, cancel)?;
    Ok(Clusters {
        clip_set,
        params,
        radius,
        features,
        clip_starts,
        labels,
        centres,
        undefined_after_first_pass: undefined,
    })
}

impl Clusters {
    /// Cluster count.
    pub fn cluster_count(&self) -> usize {
        self.centres.len()
    }

    /// Which clip and frame a corpus frame index is.
    pub fn locate(&self, frame: usize) -> (usize, usize) {
        let clip = self.clip_starts.partition_point(|&s| s <= frame) - 1;
        (clip, frame - self.clip_starts[clip])
    }

    /// Counts for reports and regression facts.
    pub fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "frames": self.features.len(),
            "clusters": self.cluster_count(),
            "radius": self.radius,
            "undefined_after_first_pass": self.undefined_after_first_pass,
            "corpus_clips": self.clip_set.clips().len(),
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::model::{Clip, ImportScale, Joint, NamedClip, Skeleton};
    use glam::{Quat, Vec3};

    /// A one-joint clip whose root tilts by the given angles (radians about X), still.
    pub(crate) fn tilts(skeleton: &Arc<crate::model::Skeleton>, angles: &[f32]) -> Clip {
        let rotations = angles.iter().map(|a| Quat::from_rotation_x(*a)).collect();
        let translations = angles.iter().map(|_| Vec3::new(0.0, 1.0, 0.0)).collect();
        Clip::new(skeleton.clone(), 30.0, rotations, translations, ImportScale::METRES).unwrap()
    }

    fn features(angles: &[f32]) -> PoseFeatures {
        let s = Arc::new(Skeleton::new(vec![Joint::new("Hips", None, Vec3::Y)]).unwrap());
        let p = DistanceParams { weights: vec![1.0], velocity_weight: 0.0 };
        PoseFeatures::of_clip(&tilts(&s, angles), &p)
    }

    #[test]
    fn the_papers_figure_2_example() {
        // Distance = (half tilt)², so a tilt of a gives a²/4 from the upright centre.
        // r = 0.01 ⇔ tilt 0.2 rad; 2r ⇔ tilt ≈ 0.283 rad.
        // Frames 0-3 near 0 (cluster 0), 4-6 between r and 2r of cluster 0 (undefined), 7
        // far (new cluster 1), 8-9 near it, 10-11 undefined again.
        let angles = [0.0, 0.05, 0.1, 0.15, 0.22, 0.26, 0.27, 0.5, 0.48, 0.52, 0.29, 0.28];
        let got = two_pass(&features(&angles), 0.01, Cancel::NEVER).unwrap();
        assert_eq!(got.centres, vec![0, 7]);
        assert_eq!(got.undefined, 5);
        // Second pass: 0.22 is nearer 0 than 0.5; 0.26, 0.27, 0.29, 0.28 are nearer 0.5.
        assert_eq!(got.labels, vec![0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1]);
    }

    #[test]
    fn corpus_clusters_and_locates_frames_per_clip() {
        let s = Arc::new(Skeleton::new(vec![Joint::new("Hips", None, Vec3::Y)]).unwrap());
        let clip = |a: &[f32]| Arc::new(tilts(&s, a));
        let set = ClipSet::new(vec![
            NamedClip { name: "a".into(), clip: clip(&[0.0, 0.0, 1.0]) },
            NamedClip { name: "b".into(), clip: clip(&[1.0, 1.0]) },
        ])
        .unwrap();
        let c =
            cluster(Arc::new(set), DistanceParams { weights: vec![1.0], velocity_weight: 0.0 }, 0.01, Cancel::NEVER)
                .unwrap();
        assert_eq!(c.labels, vec![0, 0, 1, 1, 1]);
        assert_eq!(c.locate(3), (1, 0));
        assert_eq!(c.locate(2), (0, 2));
    }
}
