//! Fuzz target `bvh_reader`: arbitrary bytes into the BVH reader.
//!
//! The reader must never panic, and whenever it accepts a file the clip it returns must
//! hold these invariants (each failure aborts with a message naming the invariant):
//! 1. `frames × joints` equals the number of rotations and of translations;
//! 2. the frame rate, the recorded frame time and the import scale are positive and finite;
//! 3. every joint's parent comes before it (the skeleton's parents-first order);
//! 4. every local rotation and translation is finite, and rotations are unit length;
//! 5. forward kinematics gives finite world rotations and positions for every joint at
//!    every frame.

#![no_main]

use std::path::Path;

use kinegraph_nodes::formats::bvh::{BvhReadOptions, read_bvh};
use kinegraph_nodes::model::forward_kinematics;
use libfuzzer_sys::fuzz_target;

/// How far from 1 a stored rotation's length may be (the clip renormalises on build).
const UNIT_TOL: f32 = 1e-3;

fuzz_target!(|data: &[u8]| {
    let Ok(loaded) = read_bvh(data, Path::new("fuzz.bvh"), BvhReadOptions::default()) else {
        return;
    };
    let (clip, stats) = &loaded.value;
    let joints = clip.joint_count();
    let frames = clip.frame_count();

    // 1. Buffer sizes.
    assert_eq!(joints, clip.skeleton().len(), "joint_count disagrees with the skeleton");
    assert_eq!(frames * joints, clip.rotations().len(), "frames × joints != rotations.len()");
    assert_eq!(frames * joints, clip.translations().len(), "frames × joints != translations.len()");

    // 2. Rates and scale.
    assert!(clip.fps().is_finite() && clip.fps() > 0.0, "fps {} is not positive and finite", clip.fps());
    assert!(
        stats.frame_time_secs.is_finite() && stats.frame_time_secs > 0.0,
        "frame time {} is not positive and finite",
        stats.frame_time_secs
    );
    let scale = clip.import_scale.metres_per_unit;
    assert!(scale.is_finite() && scale > 0.0, "metres_per_unit {scale} is not positive and finite");

    // 3. Skeleton order and rest data.
    for (index, joint) in clip.skeleton().joints().iter().enumerate() {
        if let Some(parent) = joint.parent {
            assert!(parent < index, "joint {index} '{}' has parent {parent} after it", joint.name);
        }
        assert!(joint.rest_offset.is_finite(), "joint {index} '{}' has a non-finite rest offset", joint.name);
    }

    // 4. Local transforms.
    for (i, q) in clip.rotations().iter().enumerate() {
        assert!(q.is_finite(), "rotation {i} (frame {}, joint {}) is not finite: {q:?}", i / joints, i % joints);
        assert!(
            (q.length() - 1.0).abs() <= UNIT_TOL,
            "rotation {i} (frame {}, joint {}) is not unit length: {q:?}",
            i / joints,
            i % joints
        );
    }
    for (i, t) in clip.translations().iter().enumerate() {
        assert!(t.is_finite(), "translation {i} (frame {}, joint {}) is not finite: {t:?}", i / joints, i % joints);
    }

    // 5. Forward kinematics.
    let poses = forward_kinematics(clip);
    assert_eq!(poses.frame_count(), frames, "FK frame count differs from the clip's");
    for frame in 0..frames {
        for (joint, world) in poses.frame(frame).iter().enumerate() {
            assert!(
                world.rotation.is_finite() && world.translation.is_finite(),
                "FK gives a non-finite world transform at frame {frame}, joint {joint} ('{}'): {world:?}",
                clip.skeleton().joints()[joint].name
            );
        }
    }
});
