//! The physics set-up (kernels::physics) against closed forms: free fall, a pendulum's
//! period (exact elliptic-integral formula), conservation of angular momentum of a free
//! articulated body, and bit-for-bit determinism.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinegraph_nodes::kernels::physics::{World, WorldParams};
use rapier3d::prelude::*;

fn world(dt: f32, gravity: f32) -> World {
    World::new(WorldParams { dt_secs: dt, gravity_m_s2: gravity, ..WorldParams::default() }).unwrap()
}

/// A capsule dropped from rest falls y(t) = y0 − g t²/2 (no air, no ground).
#[test]
fn free_capsule_falls_with_g() {
    let g = 9.80665f32;
    let mut w = world(WorldParams::default().dt_secs, g);
    let body = w.inner.bodies.insert(RigidBodyBuilder::dynamic().translation(Vector::new(0.0, 100.0, 0.0)));
    w.inner.colliders.insert_with_parent(
        ColliderBuilder::capsule_y(0.3, 0.1).density(1000.0),
        body,
        &mut w.inner.bodies,
    );
    let steps = (1.0 / w.dt_secs()).round() as usize;
    for _ in 0..steps {
        w.step();
    }
    let t = f64::from(w.dt_secs()) * steps as f64;
    let fallen = 100.0 - f64::from(w.inner.bodies[body].translation().y);
    let expected = 0.5 * f64::from(g) * t * t;
    let rel = (fallen - expected).abs() / expected;
    println!("free fall over {t} s: {fallen:.5} m, closed form {expected:.5} m, error {:.4} %", rel * 100.0);
    assert!(rel < 1e-3, "fell {fallen} m, closed form {expected} m ({:.3} %)", rel * 100.0);
    let v = -f64::from(w.inner.bodies[body].linvel().y);
    assert!((v - f64::from(g) * t).abs() / (f64::from(g) * t) < 1e-3, "speed {v} m/s after {t} s");
}

/// Complete elliptic integral of the first kind K(k) by the arithmetic–geometric mean.
fn elliptic_k(k: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..30 {
        let (an, bn) = ((a + b) / 2.0, (a * b).sqrt());
        a = an;
        b = bn;
    }
    std::f64::consts::PI / (2.0 * a)
}

/// Swing period of a physical pendulum (a ball on a massless rod, revolute multibody joint)
/// released from `amplitude_rad`, measured from successive zero crossings.
fn pendulum_period(amplitude_rad: f32) -> (f64, f64) {
    let (g, length, mass, radius) = (9.80665f32, 1.0f32, 2.0f32, 0.05f32);
    let mut w = world(1.0 / 1000.0, g);
    let base = w.inner.bodies.insert(RigidBodyBuilder::fixed());
    // The bob hangs at −length along the rotated Y; its inertia is a solid ball's.
    let i_ball = 0.4 * mass * radius * radius;
    let bob =
        w.inner.bodies.insert(RigidBodyBuilder::dynamic().can_sleep(false).additional_mass_properties(
            MassProperties::new(Vector::new(0.0, -length, 0.0), mass, Vector::splat(i_ball)),
        ));
    let joint = RevoluteJointBuilder::new(Vector::Z).local_anchor1(Vector::ZERO).local_anchor2(Vector::ZERO);
    let handle = w.inner.multibody_joints.insert(base, bob, joint, true).unwrap();
    // One step with gravity off lets rapier collapse the fixed base's free root to no degrees
    // of freedom; then release from the amplitude.
    let gravity = w.inner.gravity;
    w.inner.gravity = Vector::ZERO;
    w.step();
    w.inner.gravity = gravity;
    set_revolute_angle(&mut w, handle, amplitude_rad);
    let angle = |w: &World| {
        let r = w.inner.bodies[bob].rotation();
        2.0 * f64::from(r.z).atan2(f64::from(r.w))
    };
    let dt = f64::from(w.dt_secs());
    let mut crossings = Vec::new();
    let mut prev = angle(&w);
    let mut t = 0.0;
    while crossings.len() < 7 && t < 30.0 {
        w.step();
        t += dt;
        let now = angle(&w);
        if prev.signum() != now.signum() && prev != 0.0 {
            crossings.push(t - dt + dt * prev / (prev - now));
        }
        prev = now;
    }
    assert!(crossings.len() == 7, "pendulum did not swing: {crossings:?}");
    // Three full periods between the first and the seventh zero crossing.
    let measured = (crossings[6] - crossings[0]) / 3.0;
    let i_pivot = f64::from(i_ball + mass * length * length);
    let omega0 = (f64::from(mass * g * length) / i_pivot).sqrt();
    let k = (f64::from(amplitude_rad) / 2.0).sin();
    let exact = 4.0 / omega0 * elliptic_k(k);
    (measured, exact)
}

fn set_revolute_angle(w: &mut World, handle: MultibodyJointHandle, angle: f32) {
    let inner = &mut w.inner;
    let (mb, link_id) = inner.multibody_joints.get_mut(handle).unwrap();
    let ndofs = mb.ndofs();
    let mut disp = vec![0.0; ndofs];
    let assembly = mb.link(link_id).unwrap().assembly_id();
    disp[assembly] = angle;
    mb.apply_displacements(&disp);
    mb.forward_kinematics(&inner.bodies, false);
    mb.update_rigid_bodies(&mut inner.bodies, false);
}

#[test]
fn pendulum_swings_at_its_analytic_period() {
    for amplitude in [0.05f32, 0.8] {
        let (measured, exact) = pendulum_period(amplitude);
        let rel = (measured - exact).abs() / exact;
        println!(
            "pendulum amplitude {amplitude} rad: period {measured:.5} s, exact {exact:.5} s, error {:.4} %",
            rel * 100.0
        );
        assert!(rel < 0.01, "amplitude {amplitude}: period {measured} s, exact {exact} s");
    }
}

/// One body's state for the momentum check: mass, principal inertia and its frame (body
/// local), world centre of mass and world rotation.
#[derive(Clone, Copy)]
struct BodyState {
    mass: f64,
    inertia: [f64; 3],
    inertia_frame: glam::DQuat,
    com: glam::DVec3,
    rotation: glam::DQuat,
}

fn body_states(w: &World, handles: &[RigidBodyHandle]) -> Vec<BodyState> {
    let dq = |q: Rotation| glam::DQuat::from_xyzw(f64::from(q.x), f64::from(q.y), f64::from(q.z), f64::from(q.w));
    let dv = |v: Vector| glam::DVec3::new(f64::from(v.x), f64::from(v.y), f64::from(v.z));
    handles
        .iter()
        .map(|&h| {
            let b = &w.inner.bodies[h];
            let mp = b.mass_properties().local_mprops;
            let i = mp.principal_inertia();
            BodyState {
                mass: f64::from(b.mass()),
                inertia: [f64::from(i.x), f64::from(i.y), f64::from(i.z)],
                inertia_frame: dq(mp.principal_inertia_local_frame),
                com: dv(b.center_of_mass()),
                rotation: dq(*b.rotation()),
            }
        })
        .collect()
}

/// Angular momentum about the common centre of mass at the middle of three successive
/// states, with velocities by central differences of the poses (not rapier's own velocity
/// fields): an independent measure of the motion rapier integrated.
fn angular_momentum(before: &[BodyState], now: &[BodyState], after: &[BodyState], dt: f64) -> glam::DVec3 {
    let m: f64 = now.iter().map(|b| b.mass).sum();
    let c: glam::DVec3 = now.iter().map(|b| b.com * b.mass).sum::<glam::DVec3>() / m;
    let vc: glam::DVec3 =
        before.iter().zip(after).map(|(a, b)| (b.com - a.com) * a.mass).sum::<glam::DVec3>() / (m * 2.0 * dt);
    let mut l = glam::DVec3::ZERO;
    for ((a, b), n) in before.iter().zip(after).zip(now) {
        let v = (b.com - a.com) / (2.0 * dt) - vc;
        let omega = (b.rotation * a.rotation.inverse()).to_scaled_axis() / (2.0 * dt);
        let frame = n.rotation * n.inertia_frame;
        let w_local = frame.inverse() * omega;
        let spin =
            frame * glam::DVec3::new(n.inertia[0] * w_local.x, n.inertia[1] * w_local.y, n.inertia[2] * w_local.z);
        l += spin + (n.com - c).cross(v * n.mass);
    }
    l
}

/// A free chain of four capsules on ball joints, tumbling without gravity, set spinning by
/// generalised velocities (root rotation and joint rates); returns the angular momentum
/// about its centre of mass at each step, and the top link's pose per step.
fn tumbling_chain(seconds: f32) -> (Vec<glam::DVec3>, Vec<[f32; 7]>) {
    let mut w = world(WorldParams::default().dt_secs, 0.0);
    let mut handles = Vec::new();
    for i in 0..4 {
        let body = w.inner.bodies.insert(RigidBodyBuilder::dynamic().can_sleep(false).translation(Vector::new(
            0.0,
            0.5 * i as f32,
            0.0,
        )));
        // Short enough that neighbours never touch (a capsule reaches 0.235 m from its centre).
        let shape = ColliderBuilder::capsule_y(0.15, 0.04 + 0.015 * i as f32).density(1000.0);
        w.inner.colliders.insert_with_parent(shape, body, &mut w.inner.bodies);
        handles.push(body);
    }
    let mut last = None;
    for i in 1..4 {
        let joint = SphericalJointBuilder::new()
            .local_anchor1(Vector::new(0.0, 0.25, 0.0))
            .local_anchor2(Vector::new(0.0, -0.25, 0.0));
        last = w.inner.multibody_joints.insert(handles[i - 1], handles[i], joint, true);
    }
    w.clear_articulation_damping(handles[0]);
    {
        let (mb, _) = w.inner.multibody_joints.get_mut(last.unwrap()).unwrap();
        let mut v = mb.generalized_velocity_mut();
        let rates = [0.0f32, 0.0, 0.0, 1.0, -0.5, 0.7, 0.4, -0.6, 0.2, -0.3, 0.5, 0.1, 0.4, 0.3, -0.5];
        for (k, r) in rates.iter().enumerate().take(v.len()) {
            v[k] = *r;
        }
    }
    let dt = f64::from(w.dt_secs());
    let steps = (seconds / w.dt_secs()).round() as usize;
    let mut history = vec![body_states(&w, &handles)];
    let mut poses = Vec::new();
    for _ in 0..steps {
        w.step();
        history.push(body_states(&w, &handles));
        let top = &w.inner.bodies[handles[3]];
        let (p, q) = (top.translation(), top.rotation());
        poses.push([p.x, p.y, p.z, q.x, q.y, q.z, q.w]);
    }
    let momenta = history.windows(3).map(|s| angular_momentum(&s[0], &s[1], &s[2], dt)).collect();
    (momenta, poses)
}

#[test]
fn free_tumbling_chain_conserves_angular_momentum() {
    let (momenta, _) = tumbling_chain(2.0);
    let l0 = momenta[0];
    assert!(l0.length() > 0.1, "the chain does not spin: L = {l0:?}");
    let worst = momenta.iter().map(|l| (*l - l0).length() / l0.length()).fold(0.0f64, f64::max);
    println!("tumbling chain: |L0| = {:.5} kg·m²/s, largest drift over 2 s {:.4} %", l0.length(), worst * 100.0);
    assert!(worst < 0.01, "angular momentum drifted by {:.3} %", worst * 100.0);
}

#[test]
fn same_input_same_bits() {
    let (_, a) = tumbling_chain(1.0);
    let (_, b) = tumbling_chain(1.0);
    let bits = |s: &Vec<[f32; 7]>| s.iter().flat_map(|x| x.map(f32::to_bits)).collect::<Vec<u32>>();
    assert_eq!(bits(&a), bits(&b));
}
