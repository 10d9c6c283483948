//! How smooth a transition is: peak joint angular acceleration inside it relative to the
//! peak inside the clips it joins (a ratio near or below 1 means the transition is no
//! jerkier than the captured motion), measured on the joints the pose distance weighs.

use crate::kernels::transition_graph::distance::{PoseFeatures, rotation_vector};
use crate::model::{Clip, FrameRange};

/// Largest angular acceleration (rad/s²) of any weighted joint of `layout` over the frames
/// `range` of `clip`: ω from consecutive frames, α from consecutive ω.
pub fn peak_angular_acceleration(clip: &Clip, layout: &PoseFeatures, range: FrameRange) -> f64 {
    let fps = clip.fps() as f32;
    let omega = |f: usize, j: usize| rotation_vector(clip.frame_rotations(f)[j], clip.frame_rotations(f + 1)[j]) * fps;
    let end = range.end.min(clip.frame_count().saturating_sub(2));
    let mut peak = 0.0f32;
    for f in range.start..end {
        for (j, _) in layout.weighted_joints() {
            peak = peak.max((omega(f + 1, j) - omega(f, j)).length() * fps);
        }
    }
    f64::from(peak)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use glam::{Quat, Vec3};

    use super::*;
    use crate::kernels::transition_graph::distance::DistanceParams;
    use crate::model::{ImportScale, Joint, Skeleton};

    #[test]
    fn a_constant_angular_acceleration_is_measured_exactly() {
        // θ(t) = ½ a t² about X: ω from forward differences grows by a/fps per frame, so
        // every second difference is a.
        let (fps, a) = (50.0f32, 8.0f32);
        let s = Arc::new(Skeleton::new(vec![Joint::new("Hips", None, Vec3::Y)]).unwrap());
        let frames = 20;
        let rotations = (0..frames).map(|f| Quat::from_rotation_x(0.5 * a * (f as f32 / fps).powi(2))).collect();
        let clip = Clip::new(s.clone(), f64::from(fps), rotations, vec![Vec3::Y; frames], ImportScale::METRES).unwrap();
        let layout = PoseFeatures::empty(&DistanceParams { weights: vec![1.0], velocity_weight: 0.0 });
        let peak = peak_angular_acceleration(&clip, &layout, FrameRange::new(0, frames));
        assert!((peak - f64::from(a)).abs() < 0.05, "{peak}");
    }
}
