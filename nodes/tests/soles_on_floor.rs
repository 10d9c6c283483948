//! Issue 18: skinned soles on the floor. A CMU walk carried onto Xbot (both meshes, by
//! `character.load`) and onto CesiumMan, locked with `motion.foot_lock`'s ground mode
//! `soles` as `graphs/walk_on_xbot.ron` and `graphs/walk_on_cesium_man.ron` do, exported to
//! GLB. The file is then read back by the `gltf` crate alone and skinned here, frame by
//! frame, from its own nodes, animation samplers, joints, weights and inverse bind matrices
//! (none of our skinning or FK code). In every contact the planted foot's sole must reach
//! the floor (its lowest vertex within 0.5 cm of it at the plant's lowest) and never go more
//! than 0.5 cm under it: no floating, no sinking. (Frame by frame the sole rises above the
//! floor where the detected contacts run on into heel-off and toe-off; that roll is the
//! clip's own and is kept.) Needs `../shared/data` (skips without it outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod gltf_validator;

use std::path::Path;
use std::sync::Arc;

use glam::{Mat4, Quat, Vec3, Vec4};
use kinegraph_nodes::builtin::ik::map::{Bodies, TransferOptions, map_by_roles, transfer};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::formats::gltf::write_glb_file;
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::kernels::ik::foot_lock::{FootLockParams, Ground, foot_lock};
use kinegraph_nodes::kernels::load::load_character;
use kinegraph_nodes::model::{Clip, Contacts, Mesh, forward_kinematics};

/// Most a planted sole may sit above or below the floor (metres): the 0.5 cm.
const SOLE_TOLERANCE_M: f32 = 0.005;

/// The CMU walk (first frame dropped as the graphs' `clip.trim` does) carried onto
/// `character`'s skeleton by body roles, as `skeleton.map` does.
fn mapped_walk(character: &Clip, data: &Path) -> Clip {
    let walk = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value.0;
    let walk = walk.slice(1, walk.frame_count());
    let bodies = Bodies::of(character, &walk).unwrap();
    let map = map_by_roles(character.skeleton(), &bodies.target, walk.skeleton(), &bodies.source);
    transfer(&walk, character, &map, &TransferOptions { bodies: Some(&bodies), ..Default::default() }).unwrap().clip
}

/// [`mapped_walk`] foot-locked with `params`, and its contacts.
fn locked_walk(character: &Clip, data: &Path, params: FootLockParams) -> (Clip, Contacts) {
    let mapped = mapped_walk(character, data);
    let (contacts, _) = contacts_of(&mapped, &forward_kinematics(&mapped), &ContactThresholds::default()).unwrap();
    (foot_lock(&mapped, &contacts, &params).unwrap().clip, contacts)
}

/// [`locked_walk`] on `ground` with the other defaults.
fn walk_on(character: &Clip, data: &Path, ground: Ground) -> (Clip, Contacts) {
    locked_walk(character, data, FootLockParams { ground, ..FootLockParams::default() })
}

/// Per frame, per node: the world matrix of every node of the file's first scene, from the
/// node's own transform with its animated channels (one key per frame) in place.
fn node_worlds(doc: &gltf::Document, buffers: &[gltf::buffer::Data], frames: usize) -> Vec<Vec<Mat4>> {
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let mut t: Vec<Vec<Vec3>> = Vec::new();
    let mut r: Vec<Vec<Quat>> = Vec::new();
    let mut s: Vec<Vec<Vec3>> = Vec::new();
    for n in &nodes {
        let (tt, rr, ss) = n.transform().decomposed();
        t.push(vec![Vec3::from(tt); frames]);
        r.push(vec![Quat::from_array(rr); frames]);
        s.push(vec![Vec3::from(ss); frames]);
    }
    let animation = doc.animations().next().expect("the file has an animation");
    for channel in animation.channels() {
        let node = channel.target().node().index();
        let reader = channel.reader(|b| Some(&buffers[b.index()]));
        let keys = reader.read_inputs().unwrap().count();
        assert_eq!(keys, frames, "one key per frame");
        match reader.read_outputs().unwrap() {
            gltf::animation::util::ReadOutputs::Translations(v) => t[node] = v.map(Vec3::from).collect(),
            gltf::animation::util::ReadOutputs::Rotations(v) => r[node] = v.into_f32().map(Quat::from_array).collect(),
            gltf::animation::util::ReadOutputs::Scales(v) => s[node] = v.map(Vec3::from).collect(),
            gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => {}
        }
    }
    let mut parent = vec![None; nodes.len()];
    for n in &nodes {
        for c in n.children() {
            parent[c.index()] = Some(n.index());
        }
    }
    (0..frames)
        .map(|f| {
            let mut world: Vec<Option<Mat4>> = vec![None; nodes.len()];
            fn resolve(
                i: usize,
                f: usize,
                p: &[Option<usize>],
                l: &dyn Fn(usize, usize) -> Mat4,
                w: &mut [Option<Mat4>],
            ) -> Mat4 {
                if let Some(m) = w[i] {
                    return m;
                }
                let m = match p[i] {
                    Some(q) => resolve(q, f, p, l, w) * l(i, f),
                    None => l(i, f),
                };
                w[i] = Some(m);
                m
            }
            let local = |i: usize, f: usize| Mat4::from_scale_rotation_translation(s[i][f], r[i][f], t[i][f]);
            (0..nodes.len()).map(|i| resolve(i, f, &parent, &local, &mut world)).collect()
        })
        .collect()
}

/// Per foot named in `feet` (joint names), per frame, the lowest height of the skinned
/// vertices whose heaviest weight is on that foot's node or a node below it, over every
/// skinned primitive of the GLB at `path`, skinned here by linear blend skinning.
fn sole_heights_in_file(path: &Path, feet: &[&str], frames: usize) -> Vec<Vec<f32>> {
    let (doc, buffers, _) = gltf::import(path).unwrap();
    let worlds = node_worlds(&doc, &buffers, frames);
    let below = |root: usize| {
        let mut out = vec![root];
        let mut i = 0;
        while i < out.len() {
            out.extend(doc.nodes().nth(out[i]).unwrap().children().map(|c| c.index()));
            i += 1;
        }
        out
    };
    let foot_nodes: Vec<Vec<usize>> = feet
        .iter()
        .map(|name| below(doc.nodes().find(|n| n.name() == Some(name)).expect("foot node").index()))
        .collect();
    let mut lowest = vec![vec![f32::INFINITY; frames]; feet.len()];
    for node in doc.nodes() {
        let (Some(mesh), Some(skin)) = (node.mesh(), node.skin()) else { continue };
        let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        let ibms = gltf_validator::inverse_bind_matrices(&skin, &buffers);
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let positions: Vec<Vec3> = reader.read_positions().unwrap().map(Vec3::from).collect();
            let influences: Vec<[u16; 4]> = reader.read_joints(0).unwrap().into_u16().collect();
            let weights: Vec<[f32; 4]> = reader.read_weights(0).unwrap().into_f32().collect();
            for (foot, nodes) in foot_nodes.iter().enumerate() {
                let sole: Vec<usize> = (0..positions.len())
                    .filter(|&v| {
                        let k = (0..4).max_by(|&a, &b| weights[v][a].total_cmp(&weights[v][b])).unwrap();
                        nodes.contains(&joints[usize::from(influences[v][k])])
                    })
                    .collect();
                for (f, world) in worlds.iter().enumerate() {
                    for &v in &sole {
                        let mut p = Vec4::ZERO;
                        for k in 0..4 {
                            let j = usize::from(influences[v][k]);
                            p += weights[v][k] * (world[joints[j]] * ibms[j] * positions[v].extend(1.0));
                        }
                        lowest[foot][f] = lowest[foot][f].min(p.y);
                    }
                }
            }
        }
    }
    lowest
}

/// Exports `clip` with `mesh` and reads the soles back: over the contacts, the largest
/// distance of a plant's lowest sole height from the floor (floating or sunk), the deepest
/// a planted sole goes under the floor, and the deepest any sole goes under it, in metres.
fn soles_in_contact(name: &str, clip: &Clip, mesh: &Mesh, contacts: &Contacts) -> (f32, f32, f32) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{name}.glb"));
    write_glb_file(&path, clip, Some(mesh)).unwrap();
    let feet: Vec<&str> = contacts.feet.iter().map(|c| c.foot.as_str()).collect();
    let soles = sole_heights_in_file(&path, &feet, clip.frame_count());
    let (mut off, mut sunk, mut deepest) = (0.0f32, 0.0f32, 0.0f32);
    for (foot, c) in contacts.feet.iter().enumerate() {
        assert!(soles[foot].iter().all(|h| h.is_finite()), "{name}: no sole vertex for {}", c.foot);
        deepest = deepest.max(soles[foot].iter().map(|h| -h).fold(0.0, f32::max));
        for r in c.intervals.iter().filter(|r| r.end > r.start) {
            let lowest = soles[foot][r.start..r.end].iter().copied().fold(f32::INFINITY, f32::min);
            off = off.max(lowest.abs());
            sunk = sunk.max(-lowest);
        }
    }
    (off, sunk, deepest)
}

#[test]
fn planted_soles_of_xbot_and_cesium_man_stand_on_the_floor_in_the_exported_file() {
    let Some(data) = shared_data() else { return };
    let xbot = load_character(&data.join("gltf/Xbot.glb"), 0).unwrap().value;
    let cesium = load_character(&data.join("gltf/CesiumMan.glb"), 0).unwrap().value;
    for (name, character) in [("xbot", xbot), ("cesium_man", cesium)] {
        let mesh = Arc::new(character.mesh);
        let (before, contacts) = walk_on(&character.clip, &data, Ground::Clip);
        let soles = Ground::Soles { mesh: mesh.clone(), floor_height_m: 0.0 };
        let (after, _) = walk_on(&character.clip, &data, soles);
        let (off_before, sunk_before, deepest_before) = soles_in_contact(name, &before, &mesh, &contacts);
        let (off, sunk, deepest) = soles_in_contact(name, &after, &mesh, &contacts);
        println!(
            "{name}: plants' lowest soles off the floor by up to {:.2} → {:.2} cm, planted soles under it by \
             {:.2} → {:.2} cm, any sole under it by {:.2} → {:.2} cm (clip's heights → on the soles)",
            off_before * 100.0,
            off * 100.0,
            sunk_before * 100.0,
            sunk * 100.0,
            deepest_before * 100.0,
            deepest * 100.0
        );
        // The check can fail: at the clip's heights the plants are centimetres off the floor.
        assert!(off_before > 2.0 * SOLE_TOLERANCE_M, "{name}: {off_before}");
        assert!(off <= SOLE_TOLERANCE_M, "{name}: a plant's sole is {off} m off the floor");
        assert!(sunk <= SOLE_TOLERANCE_M, "{name}: a planted sole is {sunk} m under the floor");
    }
}

/// Per joint named in `joints`, the peak acceleration (m/s², second differences of its
/// world position) of the node of that name in the GLB `clip` is exported to, read back by
/// the `gltf` crate alone.
fn peak_accelerations_in_file(name: &str, clip: &Clip, joints: &[&str]) -> Vec<f32> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("{name}.glb"));
    write_glb_file(&path, clip, None).unwrap();
    let (doc, buffers, _) = gltf::import(&path).unwrap();
    let worlds = node_worlds(&doc, &buffers, clip.frame_count());
    let fps = clip.fps() as f32;
    joints
        .iter()
        .map(|joint| {
            let node = doc.nodes().find(|n| n.name() == Some(joint)).expect("joint node").index();
            let track: Vec<Vec3> = worlds.iter().map(|w| w[node].w_axis.truncate()).collect();
            track.windows(3).map(|p| (p[0] - 2.0 * p[1] + p[2]).length() * fps * fps).fold(0.0, f32::max)
        })
        .collect()
}

/// Issue 19: a plant that asks a leg for more than its length (a heel strike the lock
/// stretches) straightened Xbot's knee, and the knee snapped 4.6 cm in one frame at 120 fps
/// when the goal came back into reach (618 m/s², 3.3× the mapped walk's peak). Eased over
/// the last 2 % of the leg (soft reach, the default), each knee's peak in the exported file
/// stays within 1.5× the mapped walk's own.
#[test]
fn xbot_knees_do_not_snap_where_a_plant_stretches_the_leg() {
    let Some(data) = shared_data() else { return };
    let xbot = load_character(&data.join("gltf/Xbot.glb"), 0).unwrap().value;
    let mesh = Arc::new(xbot.mesh);
    let knees = ["mixamorig:LeftLeg", "mixamorig:RightLeg"];
    let source = peak_accelerations_in_file("mapped", &mapped_walk(&xbot.clip, &data), &knees);
    let lock = |soft_reach: f64| {
        let ground = Ground::Soles { mesh: mesh.clone(), floor_height_m: 0.0 };
        locked_walk(&xbot.clip, &data, FootLockParams { ground, soft_reach, ..FootLockParams::default() }).0
    };
    let hard = peak_accelerations_in_file("hard", &lock(0.0), &knees);
    let soft = peak_accelerations_in_file("soft", &lock(FootLockParams::default().soft_reach), &knees);
    println!("knee peaks (m/s², left, right): mapped walk {source:.0?}, hard reach {hard:.0?}, soft reach {soft:.0?}");
    // The check can fail: with a hard reach a knee snaps.
    assert!(hard.iter().zip(&source).any(|(h, s)| *h > 2.0 * s), "{hard:?} vs {source:?}");
    for ((knee, s), name) in soft.iter().zip(&source).zip(knees) {
        assert!(*knee <= 1.5 * s, "{name}: peak {knee} m/s², the mapped walk's {s}");
    }
}
