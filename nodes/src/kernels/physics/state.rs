//! What the controllers sense: the figure's centre of mass and its velocity, the base of
//! support of the feet on the ground and the polygon where they press, the capture point of
//! the linear inverted pendulum, the trunk's tilt and the head's height. The supervisor
//! computes it once per step for every controller (the paper's "common sensor values").
//!
//! All positions are world metres, Y up, ground at `y = 0`; horizontal quantities are
//! `Vec2(x, z)`.

use glam::{Quat, Vec2, Vec3};

use super::figure::{BodyRole, BodyShape, Figure, Spawned};
use super::{World, from_rapier};

/// A sole corner closer to the ground than this touches it, metres.
pub const CONTACT_HEIGHT_M: f32 = 0.02;
/// Once a foot touches the ground, its corners up to this height count in the support
/// polygon, metres. A foot rocking back on its heel (or up on its toes) lifts the far corners
/// past [`CONTACT_HEIGHT_M`] for a moment and then comes back down flat; counting only the
/// touching corners shrank the polygon to the heel edge, and balance gave up on the Xbot's
/// 15 N·s backward push with the capture point still 3 cm in front of the heels (and the
/// protective step's landing, judged on the new foot's heel alone, failed as often as not).
pub const SUPPORT_HEIGHT_M: f32 = 0.04;
/// The head is on the ground below this clearance, metres.
pub const HEAD_CONTACT_M: f32 = 0.01;

/// The figure's state as the controllers see it.
#[derive(Clone, Debug, PartialEq)]
pub struct FigureState {
    /// Simulated time, seconds.
    pub time_secs: f32,
    /// Body rotations relative to the rest pose (world), by figure body.
    pub body_rot: Vec<Quat>,
    /// Body origins (their driving joints), world metres.
    pub body_pos: Vec<Vec3>,
    /// Whole-body centre of mass, metres.
    pub com: Vec3,
    /// Its velocity, m/s.
    pub com_vel: Vec3,
    /// Whether each foot (0 left, 1 right) has a sole corner on the ground.
    pub foot_down: [bool; 2],
    /// Each foot's sole centre, metres.
    pub sole_centre: [Vec3; 2],
    /// The base of support: convex hull (x, z), counter-clockwise seen from above, of the
    /// corners of the feet that touch the ground, those up to [`SUPPORT_HEIGHT_M`] high;
    /// empty when no foot does. What balance, the step and the fall judge the capture point
    /// against.
    pub support: Vec<Vec2>,
    /// Convex hull (x, z) of the sole corners touching the ground (below
    /// [`CONTACT_HEIGHT_M`]): where the feet press now. Seated, the feet rest tipped onto
    /// their heels and press only there; sit and rise plan against this polygon.
    pub contact: Vec<Vec2>,
    /// Capture point of the linear inverted pendulum at the COM's height (x, z), metres.
    pub capture_point: Vec2,
    /// Signed distance of the COM's ground projection to the support polygon, metres
    /// (negative inside; `+∞` without support).
    pub com_support_distance_m: f32,
    /// Signed distance of the capture point to the support polygon, metres.
    pub capture_distance_m: f32,
    /// Lowest point of the head body above the ground, metres.
    pub head_clearance_m: f32,
    /// Downward speed of the head (its centre of mass), m/s; 0 while it rises. With
    /// [`head_clearance_m`](Self::head_clearance_m) it tells a head laid on the ground from
    /// one that hits it.
    pub head_down_speed_m_s: f32,
    /// Cosine of the chest's tilt from vertical (1 upright, 0 lying).
    pub trunk_upright: f32,
    /// Kinetic energy of the figure, joules.
    pub kinetic_energy_j: f32,
    /// Current joint coordinates per body, in the motors' units (see
    /// [`Targets`](super::controller::Targets)); zeros for the root.
    pub joint_coords: Vec<[f32; 3]>,
}

impl FigureState {
    /// Reads the state of a spawned figure.
    pub fn read(figure: &Figure, world: &World, spawned: &Spawned, gravity_m_s2: f32, time_secs: f32) -> FigureState {
        let (body_rot, body_pos) = figure.read_poses(world, spawned);
        let (mut m, mut com, mut mom, mut ke) = (0.0f32, Vec3::ZERO, Vec3::ZERO, 0.0f32);
        for &h in &spawned.handles {
            let rb = &world.inner.bodies[h];
            let mass = rb.mass();
            m += mass;
            com += from_rapier(rb.center_of_mass()) * mass;
            mom += from_rapier(rb.linvel()) * mass;
            ke += rb.kinetic_energy();
        }
        let com = com / m.max(1e-6);
        let com_vel = mom / m.max(1e-6);
        let mut corners: Vec<Vec2> = Vec::new();
        let mut touching: Vec<Vec2> = Vec::new();
        let mut foot_down = [false; 2];
        let mut sole_centre = [Vec3::ZERO; 2];
        let mut head_clearance_m = f32::INFINITY;
        let mut head_down_speed_m_s = 0.0f32;
        let mut trunk_upright = 1.0;
        for (i, body) in figure.bodies.iter().enumerate() {
            let (q, p) = (body_rot[i], body_pos[i]);
            match (body.role, body.shape) {
                (BodyRole::Foot, BodyShape::Box { centre, half_extents, rotation }) => {
                    let side = body.side.unwrap_or(0).min(1);
                    let sole = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)].map(|(sx, sz)| {
                        p + q
                            * (centre + rotation * Vec3::new(sx * half_extents.x, -half_extents.y, sz * half_extents.z))
                    });
                    let xz = |w: &Vec3| Vec2::new(w.x, w.z);
                    if sole.iter().any(|w| w.y < CONTACT_HEIGHT_M) {
                        foot_down[side] = true;
                        corners.extend(sole.iter().filter(|w| w.y < SUPPORT_HEIGHT_M).map(xz));
                        touching.extend(sole.iter().filter(|w| w.y < CONTACT_HEIGHT_M).map(xz));
                    }
                    sole_centre[side] = sole.iter().sum::<Vec3>() * 0.25;
                }
                (BodyRole::Head, BodyShape::Capsule { a, b, radius_m }) => {
                    head_clearance_m = (p + q * a).y.min((p + q * b).y) - radius_m;
                    head_down_speed_m_s = (-world.inner.bodies[spawned.handles[i]].linvel().y).max(0.0);
                }
                (BodyRole::Chest, _) => trunk_upright = (q * Vec3::Y).y,
                _ => {}
            }
        }
        let joint_coords = spawned
            .joints
            .iter()
            .map(|j| {
                let Some((mb, link)) = j.and_then(|h| world.inner.multibody_joints.get(h)) else { return [0.0; 3] };
                let Some(link) = mb.link(link) else { return [0.0; 3] };
                let c = link.joint().coords();
                // Linear coordinates first, then the angular ones about X, Y, Z.
                [c[3], c[4], c[5]]
            })
            .collect();
        let support = convex_hull(&corners);
        let contact = convex_hull(&touching);
        let com_xz = Vec2::new(com.x, com.z);
        let capture_point = capture_point(com_xz, Vec2::new(com_vel.x, com_vel.z), com.y, gravity_m_s2);
        FigureState {
            time_secs,
            body_rot,
            body_pos,
            com,
            com_vel,
            foot_down,
            sole_centre,
            com_support_distance_m: signed_distance(&support, com_xz),
            capture_distance_m: signed_distance(&support, capture_point),
            support,
            contact,
            capture_point,
            head_clearance_m,
            head_down_speed_m_s,
            trunk_upright,
            kinetic_energy_j: ke,
            joint_coords,
        }
    }

    /// The head's downward speed while it touches the ground (clearance below
    /// [`HEAD_CONTACT_M`]), m/s; `None` while it is clear of the ground.
    pub fn head_contact_speed(&self) -> Option<f32> {
        (self.head_clearance_m < HEAD_CONTACT_M).then_some(self.head_down_speed_m_s)
    }

    /// The COM's ground projection (x, z).
    pub fn com_xz(&self) -> Vec2 {
        Vec2::new(self.com.x, self.com.z)
    }

    /// Foot `side`'s sole centre projected on the ground (x, z).
    pub fn sole_xz(&self, side: usize) -> Vec2 {
        Vec2::new(self.sole_centre[side].x, self.sole_centre[side].z)
    }

    /// Area centroid of the support polygon (the mean of its vertices for a point or a
    /// segment), or the soles' midpoint without support. The area centroid, unlike the
    /// vertex mean, does not jump when a collinear corner joins or leaves the hull.
    pub fn support_centre(&self) -> Vec2 {
        self.centre_of(&self.support)
    }

    /// Area centroid of the contact polygon, as [`support_centre`](Self::support_centre).
    pub fn contact_centre(&self) -> Vec2 {
        self.centre_of(&self.contact)
    }

    fn centre_of(&self, polygon: &[Vec2]) -> Vec2 {
        if polygon.is_empty() {
            let c = (self.sole_centre[0] + self.sole_centre[1]) * 0.5;
            return Vec2::new(c.x, c.z);
        }
        polygon_centroid(polygon).unwrap_or_else(|| polygon.iter().copied().sum::<Vec2>() / polygon.len() as f32)
    }
}

/// Capture point of the linear inverted pendulum (Pratt et al. 2006): where the COM at
/// height `height_m` moving at `vel` must put its pivot to come to rest above it,
/// `x + ẋ·√(h/g)`.
pub fn capture_point(com: Vec2, vel: Vec2, height_m: f32, gravity_m_s2: f32) -> Vec2 {
    com + vel * (height_m.max(0.0) / gravity_m_s2.max(1e-3)).sqrt()
}

/// Area centroid of a simple polygon (shoelace formula), `None` when its area is (nearly)
/// zero.
pub fn polygon_centroid(poly: &[Vec2]) -> Option<Vec2> {
    let (mut area2, mut c) = (0.0f32, Vec2::ZERO);
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let cross = a.perp_dot(b);
        area2 += cross;
        c += (a + b) * cross;
    }
    (area2.abs() > 1e-8).then(|| c / (3.0 * area2))
}

/// Convex hull (Andrew's monotone chain), counter-clockwise in the (x, z) plane's own
/// orientation (positive `perp_dot` turns); collinear points dropped.
pub fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let mut p: Vec<Vec2> = points.iter().copied().filter(|v| v.is_finite()).collect();
    p.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut hull: Vec<Vec2> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &Vec2>> =
            if pass == 0 { Box::new(p.iter()) } else { Box::new(p.iter().rev()) };
        for &v in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], v) <= 0.0 {
                hull.pop();
            }
            hull.push(v);
        }
        hull.pop();
    }
    hull
}

/// Signed distance from `p` to the convex polygon `poly` (as [`convex_hull`] returns it):
/// negative inside (minus the distance to the nearest edge), positive outside, `+∞` for an
/// empty polygon. One or two vertices are a point or a segment.
pub fn signed_distance(poly: &[Vec2], p: Vec2) -> f32 {
    if poly.is_empty() {
        return f32::INFINITY;
    }
    let n = poly.len();
    let mut nearest = f32::INFINITY;
    let mut inside = n >= 3;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let ab = b - a;
        let t = if ab.length_squared() > 0.0 { ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0) } else { 0.0 };
        nearest = nearest.min(p.distance(a + ab * t));
        if ab.perp_dot(p - a) < 0.0 {
            inside = false;
        }
    }
    if inside { -nearest } else { nearest }
}
