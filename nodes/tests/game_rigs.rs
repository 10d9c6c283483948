//! Issue 18: characters as users bring them. Test rigs built from the corpus's Mixamo Xbot
//! (renamed to the Unreal, Unity, Rigify, 3ds Max Biped and `UpperLegL` game-rig naming
//! families; feet re-parented under a new ground-level root as IK-style game rigs do; extra
//! twist bones) receive a CMU walk through `skeleton.map`'s automatic bone map and must move
//! exactly like the original Xbot does: the same pairs, the same leg-length scale and the same
//! world joint positions in every frame. Needs `../shared/data` (skips without it outside CI).

#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use glam::{Quat, Vec3};
use kinegraph_nodes::builtin::ik::map::{Bodies, MapError, TransferOptions, Transferred, map_by_roles, transfer};
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::formats::gltf::{GltfReadOptions, read_gltf_file};
use kinegraph_nodes::model::bone_map::BoneMap;
use kinegraph_nodes::model::fk::rest_world;
use kinegraph_nodes::model::{Clip, Joint, Skeleton, forward_kinematics};

/// The Mixamo body joints and their names in each family (left side; the right side swaps
/// the side word). `None`: the joint keeps its Mixamo name without the namespace.
const FAMILIES: &[(&str, &[(&str, &str)])] = &[
    (
        "unreal",
        &[
            ("Hips", "pelvis"),
            ("Spine", "spine_01"),
            ("Spine1", "spine_02"),
            ("Spine2", "spine_03"),
            ("Neck", "neck_01"),
            ("Head", "head"),
            ("LeftShoulder", "clavicle_l"),
            ("LeftArm", "upperarm_l"),
            ("LeftForeArm", "lowerarm_l"),
            ("LeftHand", "hand_l"),
            ("LeftUpLeg", "thigh_l"),
            ("LeftLeg", "calf_l"),
            ("LeftFoot", "foot_l"),
            ("LeftToeBase", "ball_l"),
        ],
    ),
    (
        "unity",
        &[
            ("Spine1", "Chest"),
            ("Spine2", "UpperChest"),
            ("LeftArm", "LeftUpperArm"),
            ("LeftForeArm", "LeftLowerArm"),
            ("LeftUpLeg", "LeftUpperLeg"),
            ("LeftLeg", "LeftLowerLeg"),
            ("LeftToeBase", "LeftToes"),
        ],
    ),
    (
        "rigify",
        &[
            ("Hips", "DEF-spine"),
            ("Spine", "DEF-spine.001"),
            ("Spine1", "DEF-spine.002"),
            ("Spine2", "DEF-spine.003"),
            ("Neck", "DEF-neck"),
            ("Head", "DEF-head"),
            ("LeftShoulder", "DEF-shoulder.L"),
            ("LeftArm", "DEF-upper_arm.L"),
            ("LeftForeArm", "DEF-forearm.L"),
            ("LeftHand", "DEF-hand.L"),
            ("LeftUpLeg", "DEF-thigh.L"),
            ("LeftLeg", "DEF-shin.L"),
            ("LeftFoot", "DEF-foot.L"),
            ("LeftToeBase", "DEF-toe.L"),
        ],
    ),
    (
        "biped",
        &[
            ("Hips", "Bip01 Pelvis"),
            ("Spine", "Bip01 Spine"),
            ("Neck", "Bip01 Neck"),
            ("Head", "Bip01 Head"),
            ("LeftShoulder", "Bip01 L Clavicle"),
            ("LeftArm", "Bip01 L UpperArm"),
            ("LeftForeArm", "Bip01 L Forearm"),
            ("LeftHand", "Bip01 L Hand"),
            ("LeftUpLeg", "Bip01 L Thigh"),
            ("LeftLeg", "Bip01 L Calf"),
            ("LeftFoot", "Bip01 L Foot"),
            ("LeftToeBase", "Bip01 L Toe0"),
        ],
    ),
    (
        "game",
        &[
            ("Hips", "Pelvis"),
            ("LeftShoulder", "ShoulderL"),
            ("LeftArm", "UpperArmL"),
            ("LeftForeArm", "LowerArmL"),
            ("LeftHand", "HandL"),
            ("LeftUpLeg", "UpperLegL"),
            ("LeftLeg", "LowerLegL"),
            ("LeftFoot", "FootL"),
            ("LeftToeBase", "ToeL"),
        ],
    ),
];

/// The names of family `name`.
fn family(name: &str) -> &'static [(&'static str, &'static str)] {
    FAMILIES.iter().find(|(f, _)| *f == name).unwrap().1
}

/// The name of Mixamo joint `mixamo` (namespace included) in `family`.
fn renamed(family: &[(&str, &str)], mixamo: &str) -> String {
    let bare = mixamo.rsplit(':').next().unwrap();
    let left = bare.replace("Right", "Left");
    let is_right = left != bare;
    match family.iter().find(|(m, _)| *m == left) {
        Some((_, name)) if is_right => {
            let swapped = name.replace("_l", "_r").replace(".L", ".R").replace(" L ", " R ").replace("Left", "Right");
            // `UpperLegL` → `UpperLegR`.
            match swapped.strip_suffix('L') {
                Some(stem) if swapped == *name => format!("{stem}R"),
                _ => swapped,
            }
        }
        Some((_, name)) => name.to_string(),
        None => bare.to_string(),
    }
}

/// A copy of `skeleton` with every joint renamed by `name`.
fn rename(skeleton: &Skeleton, name: impl Fn(&str) -> String) -> Skeleton {
    let joints = skeleton.joints().iter().map(|j| Joint { name: name(&j.name), ..j.clone() }).collect();
    Skeleton::new(joints).unwrap()
}

/// An IK-style game rig from `skeleton`: a new `Root` joint on the ground under the pelvis
/// becomes the parent of the old root and of both feet (`feet`, by name), each keeping its
/// world rest transform; and one twist bone half way down each thigh and upper arm
/// (`twists`, by name). Joint order stays parent-before-child.
fn game_rig(skeleton: &Skeleton, feet: [&str; 2], twists: &[&str]) -> Skeleton {
    let world = rest_world(skeleton);
    let old = skeleton.joints();
    let mut joints = vec![Joint::new("Root", None, Vec3::ZERO)];
    for j in old {
        let mut j = j.clone();
        j.parent = Some(j.parent.map_or(0, |p| p + 1));
        joints.push(j);
    }
    for foot in feet {
        let k = skeleton.index_of(foot).unwrap();
        let j = &mut joints[k + 1];
        j.parent = Some(0);
        j.rest_offset = world[k].translation;
        j.rest_rotation = world[k].rotation;
    }
    for twist in twists {
        let k = skeleton.index_of(twist).unwrap();
        let child = skeleton.children(k).next().unwrap();
        let mut t = Joint::new(format!("{twist}Twist"), Some(k + 1), 0.5 * old[child].rest_offset);
        t.rest_rotation = Quat::IDENTITY;
        joints.push(t);
    }
    Skeleton::new(joints).unwrap()
}

struct Setup {
    walk: Clip,
    xbot: Arc<Skeleton>,
}

fn setup() -> Option<Setup> {
    let data = shared_data()?;
    let walk = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value.0;
    let walk = walk.slice(1, walk.frame_count());
    let asset = read_gltf_file(&data.join("gltf/Xbot.glb"), &GltfReadOptions::default()).unwrap().value;
    let xbot = asset.clips[0].clip.skeleton().clone();
    Some(Setup { walk, xbot })
}

/// The walk carried onto a rest-pose clip of `skeleton` by the automatic map.
fn carry(walk: &Clip, skeleton: Skeleton) -> (Clip, BoneMap, Transferred) {
    let target = Clip::rest_pose(Arc::new(skeleton), 30.0, 1).unwrap();
    let bodies = Bodies::of(&target, walk).unwrap();
    let map = map_by_roles(target.skeleton(), &bodies.target, walk.skeleton(), &bodies.source);
    let out = transfer(walk, &target, &map, &TransferOptions { bodies: Some(&bodies), ..Default::default() }).unwrap();
    (target, map, out)
}

/// Largest distance between each original joint and its renamed copy over every frame.
fn worst_joint_distance(original: &Clip, copy: &Clip, name: impl Fn(&str) -> String) -> (f32, String) {
    let (a, b) = (forward_kinematics(original), forward_kinematics(copy));
    let mut worst = (0.0f32, String::new());
    for (j, joint) in original.skeleton().joints().iter().enumerate() {
        let k = copy.skeleton().index_of(&name(&joint.name)).unwrap();
        for f in 0..original.frame_count() {
            let d = a.position(f, j).distance(b.position(f, k));
            if d > worst.0 {
                worst = (d, format!("{} frame {f}", joint.name));
            }
        }
    }
    worst
}

#[test]
fn every_naming_family_maps_like_the_mixamo_original() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (original, original_map, original_out) = carry(&walk, (*xbot).clone());
    println!("Xbot: {} pairs, root scale {:.4}", original_map.joints.len(), original_out.root_scale);
    for (family, names) in FAMILIES {
        let name = |n: &str| renamed(names, n);
        let (_, map, out) = carry(&walk, rename(&xbot, name));
        // The same pairs, renamed.
        let want: Vec<(String, String)> = original_map.joints.iter().map(|(t, s)| (name(t), s.clone())).collect();
        let got: Vec<(String, String)> = map.joints.clone().into_iter().collect();
        let mut want_sorted = want.clone();
        want_sorted.sort();
        assert_eq!(got, want_sorted, "{family}");
        assert!((out.root_scale - original_out.root_scale).abs() < 1e-6, "{family}: {}", out.root_scale);
        let (worst, at) = worst_joint_distance(&original_out.clip, &out.clip, name);
        println!(
            "{family}: {} pairs, root scale {:.4}, worst joint distance {worst:.2e} m ({at})",
            map.joints.len(),
            out.root_scale
        );
        assert!(worst < 1e-5, "{family}: {worst} m at {at}");
        let _ = &original;
    }
}

#[test]
fn a_game_rig_with_feet_under_the_root_and_twist_bones_walks_like_the_original() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original_out) = carry(&walk, (*xbot).clone());
    let game = family("game");
    let name = |n: &str| renamed(game, n);
    let renamed_xbot = rename(&xbot, name);
    let rig = game_rig(&renamed_xbot, ["FootL", "FootR"], &["UpperLegL", "UpperLegR", "UpperArmL", "UpperArmR"]);
    // The feet really hang off the root.
    let foot = rig.index_of("FootL").unwrap();
    assert_eq!(rig.joints()[foot].parent, Some(0));
    let (_, map, out) = carry(&walk, rig);
    assert_eq!(map.joints.get("FootL").map(String::as_str), Some("LeftFoot"), "{map:?}");
    assert_eq!(map.joints.get("LowerLegR").map(String::as_str), Some("RightLeg"), "{map:?}");
    assert!((out.root_scale - original_out.root_scale).abs() < 1e-6, "{}", out.root_scale);
    let (worst, at) = worst_joint_distance(&original_out.clip, &out.clip, name);
    // The feet apart, as on the original (issue 18: they were glued together under the root).
    let poses = forward_kinematics(&out.clip);
    let (l, r) = (out.clip.skeleton().index_of("FootL").unwrap(), out.clip.skeleton().index_of("FootR").unwrap());
    let min_gap = (0..out.clip.frame_count())
        .map(|f| poses.position(f, l).distance(poses.position(f, r)))
        .fold(f32::INFINITY, f32::min);
    println!("game rig: worst joint distance to the original {worst:.2e} m ({at}); feet at least {min_gap:.3} m apart");
    assert!(worst < 1e-4, "{worst} m at {at}");
    assert!(min_gap > 0.05);
}

#[test]
fn a_hand_written_map_alone_scales_by_leg_length() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, original_map, original_out) = carry(&walk, (*xbot).clone());
    // Names no reader knows: the map file is all there is (auto = none, no root_scale).
    let anonymous = rename(&xbot, |n| format!("b{:03}", xbot.index_of(n).unwrap()));
    let target = Clip::rest_pose(Arc::new(anonymous), 30.0, 1).unwrap();
    let map = BoneMap {
        joints: original_map
            .joints
            .iter()
            .map(|(t, s)| (format!("b{:03}", xbot.index_of(t).unwrap()), s.clone()))
            .collect(),
    };
    let out = transfer(&walk, &target, &map, &TransferOptions::default()).unwrap();
    println!("map only: root scale {:.4} (by body roles {:.4})", out.root_scale, original_out.root_scale);
    assert!((out.root_scale - original_out.root_scale).abs() < 1e-5);
    // Without the legs in the map, the refusal names the unmapped source joints and what to set.
    let mut no_legs = map.clone();
    no_legs.joints.retain(|_, s| !s.contains("Leg") && !s.contains("Foot"));
    let e = transfer(&walk, &target, &no_legs, &TransferOptions::default()).unwrap_err();
    assert!(matches!(e, MapError::NoRootScale(_)));
    let msg = e.to_string();
    assert!(msg.contains("LeftUpLeg") && msg.contains("root_scale") && msg.contains("map_file"), "{msg}");
}

#[test]
fn a_one_legged_rig_is_refused_naming_what_was_found_and_what_to_set() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let cut = xbot.index_of("mixamorig:RightUpLeg").unwrap();
    let keep: Vec<usize> = (0..xbot.len()).filter(|&j| j != cut && !xbot.is_ancestor(cut, j)).collect();
    let joints = keep
        .iter()
        .map(|&j| {
            let mut joint = xbot.joints()[j].clone();
            joint.parent = joint.parent.map(|p| keep.iter().position(|&k| k == p).unwrap());
            joint
        })
        .collect();
    let target = Clip::rest_pose(Arc::new(Skeleton::new(joints).unwrap()), 30.0, 1).unwrap();
    let e = Bodies::of(&target, &walk).unwrap_err().to_string();
    println!("{e}");
    for part in ["target", "left thigh = mixamorig:LeftUpLeg", "right thigh", "map_file"] {
        assert!(e.contains(part), "'{part}' missing from: {e}");
    }
}

/// `clip` with its joints renamed `b000`, `b001`… (no reader knows them).
fn anonymous(clip: &Clip) -> Clip {
    let sk = clip.skeleton();
    let renamed = rename(sk, |n| format!("b{:03}", sk.index_of(n).unwrap()));
    Clip::new(Arc::new(renamed), clip.fps(), clip.rotations().to_vec(), clip.translations().to_vec(), clip.import_scale)
        .unwrap()
}

/// Issue 18, `motion.contacts` with named feet: on an anonymous IK-style rig (feet under a
/// ground-level root, names no reader knows) the feet cannot be found, and named ankles and
/// toes give exactly the contacts found automatically on the original Xbot walking the same
/// walk, with the same thresholds (the rig's legs cannot be read, so they are not scaled to
/// them: the test sets them as metres for both).
#[test]
fn named_feet_find_the_contacts_detection_cannot() {
    use kinegraph_nodes::kernels::contacts::{ContactThresholds, NamedFeet, contacts_of, contacts_with, joint_pair};
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original) = carry(&walk, (*xbot).clone());
    let game = family("game");
    let rig = game_rig(&rename(&xbot, |n| renamed(game, n)), ["FootL", "FootR"], &["UpperLegL", "UpperLegR"]);
    let (_, _, on_rig) = carry(&walk, rig);
    let lost = anonymous(&on_rig.clip);
    let t = ContactThresholds { leg_m: None, ..ContactThresholds::default() };
    let poses = forward_kinematics(&lost);
    let e = contacts_of(&lost, &poses, &t).unwrap_err();
    println!("anonymous IK rig: {e}");
    let name = |n: &str| format!("b{:03}", on_rig.clip.skeleton().index_of(n).unwrap());
    let sk = lost.skeleton();
    let named = NamedFeet {
        ankles: joint_pair(sk, &format!("{}, {}", name("FootL"), name("FootR"))).unwrap(),
        toes: joint_pair(sk, &format!("{} ,{}", name("LeftToe_End"), name("RightToe_End"))).unwrap(),
        hands: None,
    };
    let found = contacts_with(&lost, &poses, &ContactThresholds::default(), &named).unwrap();
    assert_eq!(found.scaled_to_leg_m, None, "no legs to scale to");
    let got = found.contacts;
    let (want, _) = contacts_of(&original.clip, &forward_kinematics(&original.clip), &t).unwrap();
    assert_eq!(got.double_support, want.double_support);
    for (g, w) in got.feet.iter().zip(&want.feet) {
        assert_eq!(g.intervals, w.intervals);
    }
    println!("named feet: {} and {} plants", got.feet[0].intervals.len(), got.feet[1].intervals.len());
    assert!(got.feet.iter().all(|f| f.intervals.len() >= 3));
    // A wrong name is refused with the nearest one.
    let e = joint_pair(sk, "b06x, b064").unwrap_err();
    assert!(e.contains("did you mean"), "{e}");
}

/// Issue 18, `motion.foot_lock` with named toes: locking the walk on the anonymous Xbot with
/// named feet and toes moves every joint exactly as locking it on the original Xbot does.
#[test]
fn named_toes_lock_like_the_original() {
    use kinegraph_nodes::kernels::contacts::{ContactThresholds, NamedFeet, contacts_of, contacts_with};
    use kinegraph_nodes::kernels::ik::foot_lock::{FootLockParams, foot_lock};
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original) = carry(&walk, (*xbot).clone());
    let clip = original.clip.slice(0, 120);
    let t = ContactThresholds::default();
    let (contacts, feet) = contacts_of(&clip, &forward_kinematics(&clip), &t).unwrap();
    let want = foot_lock(&clip, &contacts, &FootLockParams::default()).unwrap();
    let lost = anonymous(&clip);
    let sk = clip.skeleton();
    let toes = ["mixamorig:LeftToe_End", "mixamorig:RightToe_End"].map(|n| sk.index_of(n).unwrap());
    let named = NamedFeet { ankles: Some(feet), toes: Some(toes), hands: None };
    let lost_contacts = contacts_with(&lost, &forward_kinematics(&lost), &t, &named).unwrap().contacts;
    let params = FootLockParams { toes: Some(toes.map(|j| format!("b{j:03}"))), ..FootLockParams::default() };
    let got = foot_lock(&lost, &lost_contacts, &params).unwrap();
    let (a, b) = (forward_kinematics(&want.clip), forward_kinematics(&got.clip));
    let mut worst = 0.0f32;
    for f in 0..clip.frame_count() {
        for j in 0..clip.joint_count() {
            worst = worst.max(a.position(f, j).distance(b.position(f, j)));
        }
    }
    println!(
        "foot lock with named toes vs the original: worst joint distance {worst:.2e} m; skate after {:.4} m",
        got.feet.iter().map(|f| f.skate_after_m).sum::<f64>()
    );
    assert!(worst < 1e-6);
    assert!(got.feet.iter().zip(&want.feet).all(|(g, w)| (g.skate_after_m - w.skate_after_m).abs() < 1e-9));
    let bad = FootLockParams { toes: Some(["b999".into(), "b064".into()]), ..FootLockParams::default() };
    assert!(foot_lock(&lost, &lost_contacts, &bad).unwrap_err().to_string().contains("b999"));
}

/// `skeleton` with an Unreal-style IK bone set under its first joint: `ik_foot_root` with
/// `ik_foot_l` / `ik_foot_r` standing on the feet (`feet`, by name), and `ik_hand_root` with
/// `ik_hand_gun`, `ik_hand_l` / `ik_hand_r` on the hands (`hands`, by name). Game engines
/// drive these for their own IK; no animation moves them.
fn with_ik_bones(skeleton: &Skeleton, feet: [&str; 2], hands: [&str; 2]) -> Skeleton {
    let world = rest_world(skeleton);
    let mut joints = skeleton.joints().to_vec();
    let at = |name: &str| world[skeleton.index_of(name).unwrap()].translation;
    let root_at = world[0].translation;
    for (group, ends, names) in
        [("ik_foot_root", feet, ["ik_foot_l", "ik_foot_r"]), ("ik_hand_root", hands, ["ik_hand_l", "ik_hand_r"])]
    {
        let group_index = joints.len();
        joints.push(Joint::new(group, Some(0), Vec3::ZERO));
        if group == "ik_hand_root" {
            joints.push(Joint::new("ik_hand_gun", Some(group_index), at(ends[1]) - root_at));
        }
        for (end, name) in ends.iter().zip(names) {
            // In the first joint's frame (its rest rotation undone).
            let offset = world[0].rotation.inverse() * (at(end) - root_at);
            joints.push(Joint::new(name, Some(group_index), offset));
        }
    }
    Skeleton::new(joints).unwrap()
}

/// Issue 18: a game rig with Unreal's IK bones beside its feet and hands (leaves standing
/// exactly where the feet and hands are, named like them) is read and walks like the
/// original Xbot: the IK bones are paired with nothing and stay where the rig put them.
#[test]
fn a_game_rig_with_ik_bones_walks_like_the_original() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original_out) = carry(&walk, (*xbot).clone());
    let game = family("game");
    let name = |n: &str| renamed(game, n);
    let rig = game_rig(&rename(&xbot, name), ["FootL", "FootR"], &["UpperLegL", "UpperLegR"]);
    let rig = with_ik_bones(&rig, ["FootL", "FootR"], ["HandL", "HandR"]);
    let (_, map, out) = carry(&walk, rig);
    let ik: Vec<&String> = map.joints.keys().filter(|t| t.starts_with("ik_")).collect();
    assert!(ik.is_empty(), "IK bones paired: {ik:?}");
    assert_eq!(map.joints.get("FootL").map(String::as_str), Some("LeftFoot"), "{map:?}");
    assert!((out.root_scale - original_out.root_scale).abs() < 1e-6, "{}", out.root_scale);
    let (worst, at) = worst_joint_distance(&original_out.clip, &out.clip, name);
    println!(
        "game rig with IK bones: {} pairs, worst joint distance to the original {worst:.2e} m ({at})",
        map.joints.len()
    );
    assert!(worst < 1e-4, "{worst} m at {at}");
}

/// The first 120 frames of `clip` with their feet locked (contacts detected, default
/// thresholds and lock).
fn lock(clip: &Clip) -> kinegraph_nodes::kernels::ik::foot_lock::FootLocked {
    use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
    use kinegraph_nodes::kernels::ik::foot_lock::{FootLockParams, foot_lock};
    let clip = clip.slice(0, 120);
    let (contacts, _) = contacts_of(&clip, &forward_kinematics(&clip), &ContactThresholds::default()).unwrap();
    foot_lock(&clip, &contacts, &FootLockParams::default()).unwrap()
}

/// `skeleton` with each of `bones` split in two (Rigify's `DEF-shin.L` → `DEF-shin.L.001`
/// deform segments): a joint `NAME.001` half way to the bone's one child, which then hangs
/// from it; world rest transforms and joint order (parents first) kept.
fn split_bones(skeleton: &Skeleton, bones: &[&str]) -> Skeleton {
    let old = skeleton.joints();
    let splits: Vec<(usize, usize)> = bones
        .iter()
        .map(|b| {
            let k = skeleton.index_of(b).unwrap();
            (k, skeleton.children(k).next().unwrap())
        })
        .collect();
    // New joints in order: each split segment right before the child it now carries.
    let mut order: Vec<(usize, bool)> = Vec::new(); // (old joint, is the inserted segment before it)
    for j in 0..old.len() {
        if splits.iter().any(|&(_, c)| c == j) {
            order.push((j, true));
        }
        order.push((j, false));
    }
    let index_of = |j: usize, segment: bool| order.iter().position(|&o| o == (j, segment)).unwrap();
    let joints = order
        .iter()
        .map(|&(j, segment)| {
            let split = splits.iter().find(|&&(_, c)| c == j);
            match (segment, split) {
                (true, Some(&(bone, _))) => {
                    let mut s = Joint::new(
                        format!("{}.001", old[bone].name),
                        Some(index_of(bone, false)),
                        0.5 * old[j].rest_offset,
                    );
                    s.rest_rotation = Quat::IDENTITY;
                    s
                }
                (false, Some(_)) => {
                    Joint { parent: Some(index_of(j, true)), rest_offset: 0.5 * old[j].rest_offset, ..old[j].clone() }
                }
                _ => Joint { parent: old[j].parent.map(|p| index_of(p, false)), ..old[j].clone() },
            }
        })
        .collect();
    Skeleton::new(joints).unwrap()
}

/// Issue 18: a Rigify-style rig whose thighs and shins are split into two deform segments
/// (`DEF-thigh.L` → `DEF-thigh.L.001` → `DEF-shin.L` → `DEF-shin.L.001` → `DEF-foot.L`) maps
/// and locks like the original Xbot: the lock turns the thigh and the shin, not the two shin
/// segments above the foot.
#[test]
fn a_rig_with_split_leg_bones_maps_and_locks_like_the_original() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original) = carry(&walk, (*xbot).clone());
    let want = lock(&original.clip);
    let rigify = family("rigify");
    let name = |n: &str| renamed(rigify, n);
    let rig = split_bones(&rename(&xbot, name), &["DEF-thigh.L", "DEF-thigh.R", "DEF-shin.L", "DEF-shin.R"]);
    let (_, map, out) = carry(&walk, rig);
    assert_eq!(map.joints.get("DEF-shin.L").map(String::as_str), Some("LeftLeg"), "{map:?}");
    let (worst, at) = worst_joint_distance(&original.clip, &out.clip, name);
    println!("split legs: worst joint distance to the original {worst:.2e} m ({at})");
    assert!(worst < 1e-4, "{worst} m at {at}");
    let got = lock(&out.clip);
    let (worst, at) = worst_joint_distance(&want.clip, &got.clip, name);
    println!("split legs locked: worst joint distance to the locked original {worst:.2e} m ({at})");
    assert!(worst < 1e-4, "{worst} m at {at}");
}

/// Issue 18, `motion.foot_lock` on an IK-style game rig: with the feet hanging off a root
/// on the ground (twist bones in the legs, Unreal's IK bones beside the feet), the lock turns the same hips and knees to
/// hold the same plants and puts each foot at the end of its shin, so every joint of the
/// rig moves as the original Xbot's does when the same walk is locked on it.
#[test]
fn a_game_rig_with_feet_under_the_root_locks_like_the_original() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original) = carry(&walk, (*xbot).clone());
    let want = lock(&original.clip);
    let game = family("game");
    let name = |n: &str| renamed(game, n);
    let rig = game_rig(&rename(&xbot, name), ["FootL", "FootR"], &["UpperLegL", "UpperLegR"]);
    let rig = with_ik_bones(&rig, ["FootL", "FootR"], ["HandL", "HandR"]);
    let (_, _, out) = carry(&walk, rig);
    let got = lock(&out.clip);
    let foot = got.clip.skeleton().index_of("FootL").unwrap();
    assert_eq!(got.clip.skeleton().joints()[foot].parent, Some(0), "the feet still hang off the root");
    let (worst, at) = worst_joint_distance(&want.clip, &got.clip, name);
    let skate = |l: &kinegraph_nodes::kernels::ik::foot_lock::FootLocked| {
        l.feet.iter().map(|f| (f.skate_before_m, f.skate_after_m)).collect::<Vec<_>>()
    };
    println!(
        "game rig locked: worst joint distance to the locked original {worst:.2e} m ({at}); skate (before, after) \
         {:?} vs the original's {:?}",
        skate(&got),
        skate(&want)
    );
    assert!(worst < 1e-4, "{worst} m at {at}");
    for ((gb, ga), (wb, wa)) in skate(&got).into_iter().zip(skate(&want)) {
        assert!((gb - wb).abs() < 1e-3 && (ga - wa).abs() < 1e-4 && ga < 0.1 * gb, "{ga} vs {wa}");
    }
}

/// Issue 18: an IK-style rig with names no reader knows (feet under a ground-level root,
/// twist bones) is read by its shape, and walks exactly like the original Xbot.
#[test]
fn an_anonymous_ik_rig_is_read_by_its_shape() {
    let Some(Setup { walk, xbot }) = setup() else { return };
    let (_, _, original_out) = carry(&walk, (*xbot).clone());
    let rig = game_rig(
        &xbot,
        ["mixamorig:LeftFoot", "mixamorig:RightFoot"],
        &["mixamorig:LeftUpLeg", "mixamorig:RightUpLeg", "mixamorig:LeftArm", "mixamorig:RightArm"],
    );
    let name_of = |n: &str| format!("b{:03}", rig.index_of(n).unwrap());
    let lost = rename(&rig, |n| format!("b{:03}", rig.index_of(n).unwrap()));
    let (target, map, out) = carry(&walk, lost);
    let bodies = Bodies::of(&target, &walk).unwrap();
    let names =
        |l: &kinegraph_nodes::kernels::roles::Limb| l.joints().map(|j| target.skeleton().joints()[j].name.clone());
    assert_eq!(
        names(&bodies.target.legs[0]),
        ["mixamorig:LeftUpLeg", "mixamorig:LeftLeg", "mixamorig:LeftFoot"].map(name_of)
    );
    assert_eq!(names(&bodies.target.arms[1])[2], name_of("mixamorig:RightHand"));
    assert!((out.root_scale - original_out.root_scale).abs() < 1e-6, "{}", out.root_scale);
    let (worst, at) = worst_joint_distance(&original_out.clip, &out.clip, name_of);
    println!(
        "anonymous IK rig by shape: {} pairs, worst joint distance to the original {worst:.2e} m ({at})",
        map.joints.len()
    );
    assert!(worst < 1e-4, "{worst} m at {at}");
}

/// Bad input: the quadruped Fox is not taken for a person; the refusal says what was and was
/// not found, and what to set.
#[test]
fn a_quadruped_is_refused_with_what_was_found() {
    let Some(Setup { walk, .. }) = setup() else { return };
    let data = shared_data().unwrap();
    let fox = read_gltf_file(&data.join("gltf/Fox.glb"), &GltfReadOptions::default()).unwrap().value;
    let target = Clip::rest_pose(fox.skeleton.clone().unwrap(), 30.0, 1).unwrap();
    let e = Bodies::of(&target, &walk).unwrap_err().to_string();
    println!("Fox: {e}");
    for part in ["target", "by joint name, found", "missing", "by shape", "map_file"] {
        assert!(e.contains(part), "'{part}' missing from: {e}");
    }
}
