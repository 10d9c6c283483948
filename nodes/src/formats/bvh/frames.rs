//! Frame rows to local transforms.
//!
//! The channel layout is resolved once per file; each row then takes two tight passes: the
//! half-angle sine and cosine of every rotation channel, then one product of axis
//! rotations per joint. The arithmetic is exactly that of `Axis::rotation` composed in
//! written order, so results are bit for bit those of the straightforward loop.

use glam::{Quat, Vec3};

use crate::math::euler::Axis;
use crate::model::{Channel, Joint};

/// Where each joint's channels sit in a frame row.
pub(super) struct FrameLayout {
    joints: Vec<JointLayout>,
    /// Row index of every rotation channel, joints in order.
    rotation_values: Vec<usize>,
    /// Half-angle (sine, cosine) of every rotation channel of the current row.
    half_angles: Vec<(f32, f32)>,
    channel_count: usize,
}

struct JointLayout {
    /// (row index, axis index) of each position channel.
    positions: Vec<(usize, usize)>,
    /// Axes of the rotation channels, as written; their half angles start at `first_rotation`.
    rotation_axes: Vec<Axis>,
    first_rotation: usize,
}

impl FrameLayout {
    pub(super) fn new<'c>(channels: impl IntoIterator<Item = &'c [Channel]>) -> Self {
        let mut rotation_values = Vec::new();
        let mut start = 0;
        let joints = channels
            .into_iter()
            .map(|channels| {
                let first_rotation = rotation_values.len();
                let (mut positions, mut rotation_axes) = (Vec::new(), Vec::new());
                for (index, channel) in (start..).zip(channels) {
                    match *channel {
                        Channel::Position(axis) => positions.push((index, axis.index())),
                        Channel::Rotation(axis) => {
                            rotation_values.push(index);
                            rotation_axes.push(axis);
                        }
                    }
                }
                start += channels.len();
                JointLayout { positions, rotation_axes, first_rotation }
            })
            .collect();
        let half_angles = vec![(0.0, 1.0); rotation_values.len()];
        FrameLayout { joints, rotation_values, half_angles, channel_count: start }
    }

    /// Values per row.
    pub(super) fn channel_count(&self) -> usize {
        self.channel_count
    }

    /// Converts one row (file units, degrees) into local transforms (metres, radians).
    #[inline]
    pub(super) fn push_frame(
        &mut self,
        skeleton_joints: &[Joint],
        values: &[f32],
        scale: f32,
        rotations: &mut Vec<Quat>,
        translations: &mut Vec<Vec3>,
    ) {
        for (half, &index) in self.half_angles.iter_mut().zip(&self.rotation_values) {
            *half = half_angle_sin_cos(values[index]);
        }
        for (layout, joint) in self.joints.iter().zip(skeleton_joints) {
            let mut translation = joint.rest_offset;
            for &(index, axis) in &layout.positions {
                translation[axis] = values[index] * scale;
            }
            let halves = &self.half_angles[layout.first_rotation..];
            let mut rotation = Quat::IDENTITY;
            for (&(s, c), axis) in halves.iter().zip(&layout.rotation_axes) {
                // `Axis::rotation` from its half-angle sine and cosine, as glam builds it.
                rotation *= match axis {
                    Axis::X => Quat::from_xyzw(s, 0.0, 0.0, c),
                    Axis::Y => Quat::from_xyzw(0.0, s, 0.0, c),
                    Axis::Z => Quat::from_xyzw(0.0, 0.0, s, c),
                };
            }
            rotations.push(rotation);
            translations.push(translation);
        }
    }
}

/// Sine and cosine of half of `degrees` in radians, computed as `Axis::rotation` does. A
/// zero angle (about a fifth of CMU's values) skips the library call: sin(±0) = ±0 and
/// cos(±0) = 1 exactly (IEEE 754, C Annex F), so the result is the same bit for bit.
#[inline]
fn half_angle_sin_cos(degrees: f32) -> (f32, f32) {
    let half = degrees.to_radians() * 0.5;
    if half == 0.0 { (half, 1.0) } else { half.sin_cos() }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every layout (positions and rotations interleaved, any axis order, repeated axes,
    /// zero and signed-zero angles) gives exactly `Axis::rotation` composed in order.
    #[test]
    fn rows_match_axis_rotations_composed_in_order() {
        use Axis::*;
        let layouts: Vec<Vec<Channel>> = vec![
            vec![Channel::Position(X), Channel::Position(Y), Channel::Position(Z)]
                .into_iter()
                .chain([Channel::Rotation(Z), Channel::Rotation(X), Channel::Rotation(Y)])
                .collect(),
            vec![Channel::Rotation(Y), Channel::Position(Z), Channel::Rotation(X), Channel::Rotation(Y)],
            vec![],
            vec![Channel::Rotation(X); 5],
        ];
        let joints: Vec<Joint> = layouts
            .iter()
            .map(|channels| Joint {
                name: String::new(),
                parent: None,
                rest_offset: Vec3::new(1.0, -2.0, 3.0),
                rest_rotation: Quat::IDENTITY,
                limits: None,
                channels: channels.clone(),
                end_site: false,
            })
            .collect();
        let mut layout = FrameLayout::new(layouts.iter().map(Vec::as_slice));
        let count = layout.channel_count();
        assert_eq!(count, 6 + 4 + 5);
        let rows = [vec![0.0f32; count], vec![-0.0; count], (0..count).map(|i| i as f32 * 37.3 - 170.0).collect()];
        for row in rows {
            let (mut rotations, mut translations) = (Vec::new(), Vec::new());
            layout.push_frame(&joints, &row, 0.01, &mut rotations, &mut translations);
            let mut values = row.iter();
            for ((joint, q), t) in joints.iter().zip(&rotations).zip(&translations) {
                let (mut expected_q, mut expected_t) = (Quat::IDENTITY, joint.rest_offset);
                for (channel, &v) in joint.channels.iter().zip(values.by_ref()) {
                    match channel {
                        Channel::Position(axis) => expected_t[axis.index()] = v * 0.01,
                        Channel::Rotation(axis) => expected_q *= axis.rotation(v.to_radians()),
                    }
                }
                assert_eq!(q.to_array().map(f32::to_bits), expected_q.to_array().map(f32::to_bits), "{row:?}");
                assert_eq!(t.to_array().map(f32::to_bits), expected_t.to_array().map(f32::to_bits), "{row:?}");
            }
        }
    }
}
