//! Euler angles in any of the six axis orders a BVH file may write.
//!
//! An order lists the axes as written in the file: `[Z, X, Y]` means `R = Rz · Rx · Ry`
//! (each factor a rotation about a fixed axis of the *parent* frame after the previous
//! ones, i.e. intrinsic, column vectors). Angles are radians here.

use glam::{EulerRot, Quat, Vec3};

/// A principal axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
pub enum Axis {
    /// The x axis.
    X,
    /// The y axis.
    Y,
    /// The z axis.
    Z,
}

impl Axis {
    /// Unit vector along this axis.
    pub fn unit(self) -> Vec3 {
        match self {
            Axis::X => Vec3::X,
            Axis::Y => Vec3::Y,
            Axis::Z => Vec3::Z,
        }
    }

    /// Index of this axis in a `Vec3` (x = 0).
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }

    /// Rotation by `angle` radians about this axis.
    pub fn rotation(self, angle: f32) -> Quat {
        match self {
            Axis::X => Quat::from_rotation_x(angle),
            Axis::Y => Quat::from_rotation_y(angle),
            Axis::Z => Quat::from_rotation_z(angle),
        }
    }
}

/// Composes rotations about `axes` in written order: `R = R(axes[0]) · R(axes[1]) · …`.
pub fn compose(axes: &[Axis], angles: &[f32]) -> Quat {
    axes.iter().zip(angles).fold(Quat::IDENTITY, |acc, (axis, &angle)| acc * axis.rotation(angle))
}

/// Decomposes `q` into angles about three distinct `axes` (written order), the inverse of
/// [`compose`]. Returns `None` when the axes are not three distinct ones.
pub fn decompose3(q: Quat, axes: [Axis; 3]) -> Option<[f32; 3]> {
    use Axis::*;
    let rot = match axes {
        [X, Y, Z] => EulerRot::XYZ,
        [X, Z, Y] => EulerRot::XZY,
        [Y, X, Z] => EulerRot::YXZ,
        [Y, Z, X] => EulerRot::YZX,
        [Z, X, Y] => EulerRot::ZXY,
        [Z, Y, X] => EulerRot::ZYX,
        _ => return None,
    };
    let (a, b, c) = q.to_euler(rot);
    Some([a, b, c])
}

/// Angle of `q` about a single `axis`, exact when `q` is a rotation about that axis only
/// (the twist component otherwise).
pub fn decompose1(q: Quat, axis: Axis) -> f32 {
    let v = Vec3::new(q.x, q.y, q.z);
    2.0 * v[axis.index()].atan2(q.w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::EXACT_TOL;

    const ORDERS: [[Axis; 3]; 6] = [
        [Axis::X, Axis::Y, Axis::Z],
        [Axis::X, Axis::Z, Axis::Y],
        [Axis::Y, Axis::X, Axis::Z],
        [Axis::Y, Axis::Z, Axis::X],
        [Axis::Z, Axis::X, Axis::Y],
        [Axis::Z, Axis::Y, Axis::X],
    ];

    /// Independent check of the composition convention: a rotation matrix built by hand
    /// from the textbook Rx, Ry, Rz matrices multiplied in written order.
    fn matrix(axis: Axis, a: f32) -> glam::Mat3 {
        let (s, c) = a.sin_cos();
        match axis {
            Axis::X => glam::Mat3::from_cols_array(&[1., 0., 0., 0., c, s, 0., -s, c]),
            Axis::Y => glam::Mat3::from_cols_array(&[c, 0., -s, 0., 1., 0., s, 0., c]),
            Axis::Z => glam::Mat3::from_cols_array(&[c, s, 0., -s, c, 0., 0., 0., 1.]),
        }
    }

    #[test]
    fn compose_matches_hand_built_matrices_in_every_order() {
        let angles = [0.3, -1.1, 2.0];
        for order in ORDERS {
            let q = compose(&order, &angles);
            let m = matrix(order[0], angles[0]) * matrix(order[1], angles[1]) * matrix(order[2], angles[2]);
            let v = glam::Vec3::new(0.2, -0.7, 1.3);
            assert!((q * v - m * v).length() < EXACT_TOL, "order {order:?}");
        }
    }

    #[test]
    fn decompose_inverts_compose_in_every_order() {
        let angles = [0.4, -0.9, 1.7];
        for order in ORDERS {
            let q = compose(&order, &angles);
            let back = decompose3(q, order).unwrap();
            let q2 = compose(&order, &back);
            assert!(q.angle_between(q2) < 1e-4, "order {order:?}");
            for (a, b) in angles.iter().zip(back) {
                assert!((a - b).abs() < 1e-4, "order {order:?}: {angles:?} vs {back:?}");
            }
        }
    }

    #[test]
    fn decompose_survives_gimbal_lock() {
        let q = compose(&[Axis::Z, Axis::X, Axis::Y], &[0.5, std::f32::consts::FRAC_PI_2, 0.2]);
        let back = decompose3(q, [Axis::Z, Axis::X, Axis::Y]).unwrap();
        assert!(back.iter().all(|a| a.is_finite()));
        let q2 = compose(&[Axis::Z, Axis::X, Axis::Y], &back);
        assert!(q.angle_between(q2) < 1e-3);
    }

    #[test]
    fn single_axis_round_trip() {
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let a = decompose1(axis.rotation(-2.5), axis);
            assert!((a + 2.5).abs() < EXACT_TOL);
        }
    }
}
