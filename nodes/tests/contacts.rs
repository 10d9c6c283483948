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
