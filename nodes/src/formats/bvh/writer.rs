//! BVH writer.
//!
//! Writes in the unit the clip was read in (so a round trip leaves a DCC's scene scale
//! alone) and with each joint's original channel layout; joints that never had one (from
//! glTF or generated) get the usual `Zrotation Yrotation Xrotation`, plus positions on the
//! root and on any joint whose translation is animated.

use std::fmt::Write as _;
use std::path::Path;

use glam::Quat;

use crate::formats::atomic::write_atomic;
use crate::formats::error::{FormatError, Loaded};
use crate::math::euler::{Axis, decompose1, decompose3};
use crate::model::{Channel, Clip};

/// Serialises `clip` as BVH text, with warnings for anything the layout cannot carry.
pub fn write_bvh(clip: &Clip) -> Loaded<String> {
    let skeleton = clip.skeleton();
    let unit = clip.import_scale.metres_per_unit as f32;
    let to_file = 1.0 / unit;
    let animated: Vec<bool> = (0..skeleton.len()).map(|j| clip.translation_is_animated(j)).collect();
    let layouts: Vec<Vec<Channel>> = (0..skeleton.len()).map(|j| channel_layout(clip, j, animated[j])).collect();
    // Parents come first, so one pass gives every joint's nesting depth.
    let mut depths: Vec<usize> = Vec::with_capacity(skeleton.len());
    for joint in skeleton.joints() {
        let depth = joint.parent.map_or(0, |p| depths[p] + 1);
        depths.push(depth);
    }
    let mut warnings = Vec::new();
    for (j, joint) in skeleton.joints().iter().enumerate() {
        if joint.rest_rotation != Quat::IDENTITY && !joint.end_site {
            warnings.push(format!(
                "joint '{}' has a rest rotation; BVH has none, so it is baked into the channels",
                joint.name
            ));
        }
        let has_position = layouts[j].iter().any(|c| matches!(c, Channel::Position(_)));
        if !has_position && animated[j] {
            warnings.push(format!(
                "joint '{}' has animated translation but no position channels: it is dropped",
                joint.name
            ));
        }
    }

    let mut out = String::with_capacity(64 * skeleton.len() + clip.frame_count() * skeleton.len() * 30);
    out.push_str("HIERARCHY\n");
    for (j, joint) in skeleton.joints().iter().enumerate() {
        let depth = depths[j];
        let pad = "\t".repeat(depth);
        let o = joint.rest_offset * to_file;
        if joint.end_site {
            let _ = writeln!(out, "{pad}End Site\n{pad}{{\n{pad}\tOFFSET {:.6} {:.6} {:.6}", o.x, o.y, o.z);
        } else {
            let keyword = if joint.parent.is_none() { "ROOT" } else { "JOINT" };
            let _ =
                writeln!(out, "{pad}{keyword} {}\n{pad}{{\n{pad}\tOFFSET {:.6} {:.6} {:.6}", joint.name, o.x, o.y, o.z);
            let _ = write!(out, "{pad}\tCHANNELS {}", layouts[j].len());
            for c in &layouts[j] {
                out.push(' ');
                out.push_str(channel_name(*c));
            }
            out.push('\n');
        }
        // Close this block and every ancestor block that ends here.
        let next_depth = depths.get(j + 1).copied().unwrap_or(0);
        for d in (next_depth..=depth).rev() {
            let _ = writeln!(out, "{}}}", "\t".repeat(d));
        }
    }
    let _ = writeln!(out, "MOTION\nFrames: {}\nFrame Time: {}", clip.frame_count(), 1.0 / clip.fps());

    for frame in 0..clip.frame_count() {
        let rotations = clip.frame_rotations(frame);
        let translations = clip.frame_translations(frame);
        let mut first = true;
        for (j, layout) in layouts.iter().enumerate() {
            if layout.is_empty() {
                continue;
            }
            let position = translations[j] * to_file;
            let angles = euler_degrees(rotations[j], layout);
            let mut rotation_index = 0;
            for c in layout {
                let v = match c {
                    Channel::Position(axis) => position[axis.index()],
                    Channel::Rotation(_) => {
                        rotation_index += 1;
                        angles[rotation_index - 1]
                    }
                };
                if !first {
                    out.push(' ');
                }
                first = false;
                let _ = write!(out, "{v:.6}");
            }
        }
        out.push('\n');
    }
    Loaded { value: out, warnings }
}

/// Writes `clip` to `path` atomically.
pub fn write_bvh_file(clip: &Clip, path: &Path) -> Result<Vec<String>, FormatError> {
    let Loaded { value, warnings } = write_bvh(clip);
    write_atomic(path, value.as_bytes())?;
    Ok(warnings)
}

fn channel_layout(clip: &Clip, j: usize, animated: bool) -> Vec<Channel> {
    let joint = &clip.skeleton().joints()[j];
    if !joint.channels.is_empty() || joint.end_site {
        return joint.channels.clone();
    }
    let rotation = [Axis::Z, Axis::Y, Axis::X].map(Channel::Rotation);
    if joint.parent.is_none() || animated {
        let mut layout = [Axis::X, Axis::Y, Axis::Z].map(Channel::Position).to_vec();
        layout.extend(rotation);
        layout
    } else {
        rotation.to_vec()
    }
}

/// Angles (degrees) for the rotation channels of `layout`, in their written order.
fn euler_degrees(q: Quat, layout: &[Channel]) -> Vec<f32> {
    let axes: Vec<Axis> = layout
        .iter()
        .filter_map(|c| match c {
            Channel::Rotation(a) => Some(*a),
            Channel::Position(_) => None,
        })
        .collect();
    let radians: Vec<f32> = match axes.as_slice() {
        [] => Vec::new(),
        [a] => vec![decompose1(q, *a)],
        [a, b] => {
            // Complete to three distinct axes; the dropped third angle is zero for any
            // rotation the two channels can express.
            let c = [Axis::X, Axis::Y, Axis::Z].into_iter().find(|x| x != a && x != b).unwrap_or(Axis::X);
            decompose3(q, [*a, *b, c]).map(|r| vec![r[0], r[1]]).unwrap_or_else(|| vec![0.0; 2])
        }
        [a, b, c] => decompose3(q, [*a, *b, *c]).map(|r| r.to_vec()).unwrap_or_else(|| vec![0.0; 3]),
        more => {
            // Unusual repeated-axis layouts: put the rotation in the first three distinct
            // axes' decomposition when possible, zero the rest.
            let mut v = vec![0.0; more.len()];
            if let Some(r) = decompose3(q, [more[0], more[1], more[2]]) {
                v[..3].copy_from_slice(&r);
            }
            v
        }
    };
    radians.into_iter().map(f32::to_degrees).collect()
}

fn channel_name(c: Channel) -> &'static str {
    match c {
        Channel::Position(Axis::X) => "Xposition",
        Channel::Position(Axis::Y) => "Yposition",
        Channel::Position(Axis::Z) => "Zposition",
        Channel::Rotation(Axis::X) => "Xrotation",
        Channel::Rotation(Axis::Y) => "Yrotation",
        Channel::Rotation(Axis::Z) => "Zrotation",
    }
}
