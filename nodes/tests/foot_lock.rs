//! Foot locking on a real CMU walk: the planted toes stop sliding, the legs change only a
//! little and nothing else moves. Needs `../shared/data` (skips without it outside CI).
//! The figures are printed (`--nocapture`) for the closing note.

#![allow(clippy::unwrap_used, clippy::expect_used)]

use kinegraph_nodes::builtin::clip_edit::trim;
use kinegraph_nodes::corpus::shared_data;
use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh_file};
use kinegraph_nodes::kernels::body::{find_landmarks, limb_tip};
use kinegraph_nodes::kernels::contacts::{ContactThresholds, detect_contacts, ground_height};
use kinegraph_nodes::kernels::ik::foot_lock::{FootLockParams, foot_lock};
use kinegraph_nodes::model::forward_kinematics;

#[test]
fn a_cmu_walk_keeps_its_planted_toes_still() {
    let Some(data) = shared_data() else { return };
    let (clip, _) = read_bvh_file(&data.join("bvh/cmu/02_01.bvh"), BvhReadOptions::default()).unwrap().value;
    // Without the cgspeed T-pose frame 0 (data README).
    let clip = trim(&clip, 0.01, None).unwrap();
    let poses = forward_kinematics(&clip);
    let landmarks = find_landmarks(clip.skeleton()).unwrap();
    let contacts = detect_contacts(&clip, &poses, &landmarks, &ContactThresholds::default());
    let params = FootLockParams::default();
    let locked = foot_lock(&clip, &contacts, &params).unwrap();
    assert!(locked.clip.rotations().iter().all(|q| q.is_finite()));
    let after = forward_kinematics(&locked.clip);
    let blend = (params.blend_secs * clip.fps()).round() as usize;

    // Independently of the kernel's own figures: for each contact, how far the toe tip
    // strays horizontally from where it is at the contact's lowest frame, over the frames
    // a blend away from both edges, before and after.
    let mut worst = [0.0f32; 2];
    let mut plants = 0;
    for (k, &ankle) in landmarks.feet().iter().enumerate() {
        let tip = limb_tip(clip.skeleton(), ankle);
        for r in &contacts.feet[k].intervals {
            if r.len() <= 2 * blend {
                continue;
            }
            plants += 1;
            let lowest =
                (r.start..r.end).min_by(|&a, &b| poses.position(a, tip).y.total_cmp(&poses.position(b, tip).y));
            let place = poses.position(lowest.unwrap(), tip);
            for f in r.start + blend..r.end - blend {
                let stray = |p: &kinegraph_nodes::model::ClipPoses| (p.position(f, tip) - place).with_y(0.0).length();
                worst[0] = worst[0].max(stray(&poses));
                worst[1] = worst[1].max(stray(&after));
            }
        }
    }
    println!(
        "{plants} plants: toe strays up to {:.2} cm from its plant before, {:.3} cm after",
        worst[0] * 100.0,
        worst[1] * 100.0
    );
    for foot in &locked.feet {
        println!(
            "{}: {} plants, planted toe travel {:.2} cm → {:.3} cm",
            foot.foot,
            foot.plants,
            foot.skate_before_m * 100.0,
            foot.skate_after_m * 100.0
        );
    }
    assert!(plants >= 4, "a 2.9 s walk has at least four plants");
    assert!(worst[0] > 0.01, "the captured toes slide more than a centimetre");
    assert!(worst[1] < 0.002, "locked toes stay within 2 mm of their plants: {} m", worst[1]);

    // The toe heights are the clip's (the lock is horizontal) and its ground stays.
    for (k, &ankle) in landmarks.feet().iter().enumerate() {
        let tip = limb_tip(clip.skeleton(), ankle);
        let track = |p: &kinegraph_nodes::model::ClipPoses| {
            (0..clip.frame_count()).map(|f| p.position(f, tip).as_dvec3()).collect::<Vec<_>>()
        };
        let (h0, h1) = (ground_height(&track(&poses)), ground_height(&track(&after)));
        assert!((h0 - h1).abs() < 0.002, "foot {k}: ground {h0} → {h1}");
    }

    // Only the legs turned, and not by much; the root path is the clip's.
    let sk = clip.skeleton();
    let legs: Vec<usize> = landmarks.feet().iter().flat_map(|&a| [a, sk.joints()[a].parent.unwrap()]).collect();
    let hips: Vec<usize> = legs.iter().map(|&k| sk.joints()[k].parent.unwrap()).collect();
    let mut largest = 0.0f32;
    for f in 0..clip.frame_count() {
        assert_eq!(locked.clip.frame_translations(f), clip.frame_translations(f));
        for j in 0..sk.len() {
            let (a, b) = (clip.frame_rotations(f)[j], locked.clip.frame_rotations(f)[j]);
            if legs.contains(&j) || hips.contains(&j) {
                largest = largest.max(a.angle_between(b));
            } else {
                assert_eq!(a, b, "joint {} changed at frame {f}", sk.joints()[j].name);
            }
        }
    }
    println!("largest leg joint change: {:.1}°", largest.to_degrees());
    assert!(largest < 0.5, "the lock corrects centimetres; no joint turns by half a radian");
}
