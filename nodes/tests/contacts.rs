//! Foot contacts on bodies of other sizes: CMU 02_01 carried onto the same skeleton at half
//! size (every bone and the root's path halved, the timing kept, as a retarget does) must
//! plant its feet in the frames the adult did. Needs `../shared/data` (skips without it
//! outside CI). The figures are printed (`--nocapture`) for the closing note.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinegraph_nodes::builtin::clip_edit::trim;
use kinegraph_nodes::builtin::ik::scale::scale_clip;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::contacts::{ContactThresholds, contacts_of};
use kinegraph_nodes::model::{Clip, Contacts, forward_kinematics};

/// Frames each foot is planted, as one flag per frame and foot.
fn planted(contacts: &Contacts) -> Vec<[bool; 2]> {
    (0..contacts.frame_count)
        .map(|f| [0, 1].map(|k| contacts.feet[k].intervals.iter().any(|r| r.contains(f))))
        .collect()
}

/// Frames (over both feet) on which two contact sets disagree.
fn disagreements(a: &Contacts, b: &Contacts) -> usize {
    planted(a).iter().zip(planted(b)).map(|(x, y)| (x[0] != y[0]) as usize + (x[1] != y[1]) as usize).sum()
}

fn detect(clip: &Clip, thresholds: &ContactThresholds) -> Contacts {
    contacts_of(clip, &forward_kinematics(clip), thresholds).unwrap().0
}

#[test]
fn a_half_size_body_plants_its_feet_where_the_adult_did() {
    let Some(data) = shared_data() else { return };
    let (clip, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    // Without the cgspeed T-pose frame 0 (data README).
    let adult = trim(&clip, 0.01, None).unwrap();
    let child = scale_clip(&adult, 0.5, &[]).unwrap();
    let scaled = ContactThresholds::default();
    let absolute = ContactThresholds { leg_m: None, ..scaled };
    let reference = detect(&adult, &absolute);
    let frames = 2 * adult.frame_count();
    let (with_legs, as_metres) = (disagreements(&reference, &detect(&child, &scaled)), {
        disagreements(&reference, &detect(&child, &absolute))
    });
    println!(
        "half-size 02_01: contacts differ from the adult's on {with_legs} of {frames} foot-frames with thresholds \
         scaled to the legs, on {as_metres} with the adult's metres"
    );
    // The adult's own legs are the reference's: scaling changes nothing there.
    assert_eq!(disagreements(&reference, &detect(&adult, &scaled)), 0);
    // Scaled with the body, the thresholds see the same motion: the same plants.
    assert_eq!(with_legs, 0, "scaled thresholds: {with_legs} of {frames} foot-frames differ");
    assert!(as_metres > 20, "the adult's metres on a child: only {as_metres} of {frames} differ");
}

/// Issue 18, hands by name: on the CMU cartwheel (90_02, 120 fps) the named hands are found
/// on the floor where the body needs them. Independently of the detection (which watches
/// the palms' heights), every frame the body is upside down (the head below the hips) with
/// no foot down has a hand down, no hand is down while the head is over 1 m up (the actor
/// upright), the feet's contacts are those found without the hands, and with the hands
/// watched the cartwheel has no flight stage where the feet alone leave one longer than
/// 0.35 s (the hands' support). `motion.foot_lock` then holds the hands as it holds feet: each
/// slides less than half as far through its plant.
#[test]
fn named_hands_are_found_on_the_floor_through_a_cartwheel() {
    use kinegraph_nodes::kernels::contacts::{NamedFeet, contacts_with, joint_pair};
    use kinegraph_nodes::kernels::stages::stages_from_contacts;
    use kinegraph_nodes::model::StageKind;
    let Some(data) = shared_data() else { return };
    let clip = read_bvh_file(&data.join("bvh/cmu/90_02.bvh"), BvhReadOptions::default()).unwrap().value.0;
    let poses = forward_kinematics(&clip);
    let sk = clip.skeleton();
    let t = ContactThresholds::default();
    let feet_only = contacts_with(&clip, &poses, &t, &NamedFeet::default()).unwrap().contacts;
    let hands = joint_pair(sk, "LeftHand, RightHand").unwrap();
    let with_hands = contacts_with(&clip, &poses, &t, &NamedFeet { hands, ..NamedFeet::default() }).unwrap().contacts;
    assert_eq!((with_hands.feet.len(), with_hands.hands.len()), (2, 2));
    assert_eq!(with_hands.feet, feet_only.feet, "the feet's contacts are unchanged");
    assert_eq!(with_hands.double_support, feet_only.double_support);
    let on = |c: &Contacts, k: usize, f: usize| {
        c.limbs().nth(k).is_some_and(|l| l.intervals.iter().any(|r| r.start <= f && f < r.end))
    };
    let (head, hips) = (sk.index_of("Head").unwrap(), sk.index_of("Hips").unwrap());
    let inverted: Vec<usize> =
        (0..clip.frame_count()).filter(|&f| poses.position(f, head).y < poses.position(f, hips).y).collect();
    let hand_frames: Vec<usize> =
        (0..clip.frame_count()).filter(|&f| on(&with_hands, 2, f) || on(&with_hands, 3, f)).collect();
    println!(
        "90_02: {} frames, upside down {}..={} ({} frames), hands down on {} frames: left {:?}, right {:?}",
        clip.frame_count(),
        inverted.first().unwrap(),
        inverted.last().unwrap(),
        inverted.len(),
        hand_frames.len(),
        with_hands.hands[0].intervals,
        with_hands.hands[1].intervals
    );
    let foot_down = |f: usize| on(&with_hands, 0, f) || on(&with_hands, 1, f);
    let unsupported: Vec<usize> =
        inverted.iter().copied().filter(|&f| !foot_down(f) && !hand_frames.contains(&f)).collect();
    assert!(unsupported.is_empty(), "upside down with no foot and no hand down: {unsupported:?}");
    let upright: Vec<usize> = hand_frames.iter().copied().filter(|&f| poses.position(f, head).y > 1.0).collect();
    assert!(upright.is_empty(), "a hand down while the head is over 1 m up: {upright:?}");
    let stages = |c: &Contacts| stages_from_contacts(c, (0.1 * clip.fps()) as usize);
    let longest_flight = |c: &Contacts| {
        stages(c).iter().filter(|s| s.kind == StageKind::Flight).map(|s| s.frames.len()).max().unwrap_or(0)
    };
    println!(
        "longest flight: feet only {} frames, with hands {}",
        longest_flight(&feet_only),
        longest_flight(&with_hands)
    );
    assert!(longest_flight(&feet_only) as f64 / clip.fps() > 0.35);
    assert_eq!(longest_flight(&with_hands), 0);
    // motion.foot_lock holds the hands like the feet (elbow and shoulder turning).
    let locked = kinegraph_nodes::kernels::ik::foot_lock::foot_lock(&clip, &with_hands, &Default::default()).unwrap();
    for limb in &locked.feet {
        println!(
            "{}: {} plants, planted travel {:.1} cm -> {:.2} cm, {} frames short",
            limb.foot,
            limb.plants,
            100.0 * limb.skate_before_m,
            100.0 * limb.skate_after_m,
            limb.short_frames
        );
    }
    for hand in &locked.feet[2..] {
        assert!(hand.skate_after_m < 0.5 * hand.skate_before_m, "{hand:?}");
    }
}

/// Hands that never reach the floor are never down: named on the CMU walk (02_01), whose
/// arms swing slowly at the turn of each swing well above the floor, they get no contact.
#[test]
fn hands_swinging_above_the_floor_are_never_down() {
    use kinegraph_nodes::kernels::contacts::{NamedFeet, contacts_with, joint_pair};
    let Some(data) = shared_data() else { return };
    let clip = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value.0;
    let hands = joint_pair(clip.skeleton(), "LeftHand, RightHand").unwrap();
    let named = NamedFeet { hands, ..NamedFeet::default() };
    let found = contacts_with(&clip, &forward_kinematics(&clip), &ContactThresholds::default(), &named).unwrap();
    let (feet, hands) = (&found.contacts.feet, &found.contacts.hands);
    assert_eq!((feet.len(), hands.len()), (2, 2));
    assert!(feet.iter().all(|f| !f.intervals.is_empty()));
    assert!(hands.iter().all(|h| h.intervals.is_empty()), "{hands:?}");
}
