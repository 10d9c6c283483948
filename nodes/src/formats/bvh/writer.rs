//! BVH writer.
//!
//! Writes by default in the unit the clip was read in (so a round trip leaves a DCC's scene
//! scale alone), or in centimetres or metres on request, and with each joint's original
//! channel layout; joints that never had one (from glTF or generated) get the usual
//! `Zrotation Yrotation Xrotation`, plus positions on the root and on any joint whose
//! translation is animated.
//!
//! The root's OFFSET is written as zero on every axis that has a position channel, with
//! the root's full position in those channels. Readers disagree on whether the root's
//! position channels add to its OFFSET (most) or replace it (ours, MotionBuilder's
//! convention): with a zero offset both put the hips at the same place.
//!
//! End sites (joints read from an `End Site` block, or leaf joints named `…_EndSite`, the
//! name our reader gives them, which survives formats without the flag) are written as
//! `End Site` blocks.

use std::fmt::Write as _;
use std::path::Path;

use glam::Quat;

use crate::formats::atomic::write_atomic_with;
use crate::formats::error::{FormatError, Loaded};
use crate::math::euler::{Axis, decompose1, decompose3};
use crate::model::{Channel, Clip};

/// Length unit of a written BVH file.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum BvhUnit {
    /// The unit the clip was read in (its import scale); metres for glTF or generated clips.
    #[default]
    AsRead,
    /// Centimetres.
    Centimetre,
    /// Metres.
    Metre,
}

impl BvhUnit {
    /// Metres per file unit when writing `clip`.
    pub fn metres_per_unit(self, clip: &Clip) -> f64 {
        match self {
            BvhUnit::AsRead => clip.import_scale.metres_per_unit,
            BvhUnit::Centimetre => 0.01,
            BvhUnit::Metre => 1.0,
        }
    }
}

/// Options for writing BVH.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhWriteOptions {
    /// Length unit of the file.
    pub unit: BvhUnit,
}

/// Whether joint `j` is written as an `End Site` block: a leaf flagged as an end site or
/// named like the reader names them (`Parent_EndSite`, possibly with a number).
pub fn is_end_site(clip: &Clip, j: usize) -> bool {
    let skeleton = clip.skeleton();
    let joint = &skeleton.joints()[j];
    let is_leaf = !skeleton.joints().iter().any(|c| c.parent == Some(j));
    let named = joint.name.trim_end_matches(|c: char| c.is_ascii_digit()).ends_with("_EndSite");
    joint.parent.is_some() && is_leaf && (joint.end_site || named)
}

/// Serialises `clip` as BVH text in the unit it was read in, with warnings for anything
/// the layout cannot carry.
pub fn write_bvh(clip: &Clip) -> Loaded<String> {
    write_bvh_with(clip, BvhWriteOptions::default())
}

/// Serialises `clip` as BVH text with `options`, with warnings for anything the layout
/// cannot carry.
pub fn write_bvh_with(clip: &Clip, options: BvhWriteOptions) -> Loaded<String> {
    let mut bytes = Vec::with_capacity(64 * clip.joint_count() + clip.frame_count() * clip.joint_count() * 30);
    // Writing into memory cannot fail; were it to, the failure is a warning, not a panic.
    let warnings =
        write_bvh_to(clip, options, &mut bytes).unwrap_or_else(|e| vec![format!("BVH text incomplete: {e}")]);
    let value = String::from_utf8(bytes).unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned());
    Loaded { value, warnings }
}

/// Streams `clip` as BVH text with `options` into `sink`, a frame line at a time (an
/// export never holds the whole text); gives the warnings for anything the layout cannot
/// carry.
pub fn write_bvh_to(
    clip: &Clip,
    options: BvhWriteOptions,
    sink: &mut dyn std::io::Write,
) -> std::io::Result<Vec<String>> {
    let skeleton = clip.skeleton();
    let unit = options.unit.metres_per_unit(clip) as f32;
    let to_file = 1.0 / unit;
    let animated: Vec<bool> = (0..skeleton.len()).map(|j| clip.translation_is_animated(j)).collect();
    let end_sites: Vec<bool> = (0..skeleton.len()).map(|j| is_end_site(clip, j)).collect();
    let layouts: Vec<Vec<Channel>> =
        (0..skeleton.len()).map(|j| channel_layout(clip, j, animated[j], end_sites[j])).collect();
    // Parents come first, so one pass gives every joint's nesting depth.
    let mut depths: Vec<usize> = Vec::with_capacity(skeleton.len());
    for joint in skeleton.joints() {
        let depth = joint.parent.map_or(0, |p| depths[p] + 1);
        depths.push(depth);
    }
    let mut warnings = Vec::new();
    let rest_rotated: Vec<&str> = skeleton
        .joints()
        .iter()
        .enumerate()
        .filter(|(j, joint)| joint.rest_rotation != Quat::IDENTITY && !end_sites[*j])
        .map(|(_, joint)| joint.name.as_str())
        .collect();
    if let Some(first) = rest_rotated.first() {
        let more = rest_rotated.len() - 1;
        let others = if more == 0 { String::new() } else { format!(" and {more} more") };
        warnings.push(format!(
            "{} joint(s) ('{first}'{others}) have a rest rotation; BVH has none, so the written rest pose has no rotations and the channels carry the full rotations (the motion is unchanged)",
            rest_rotated.len()
        ));
    }
    for (j, joint) in skeleton.joints().iter().enumerate() {
        let has_position = layouts[j].iter().any(|c| matches!(c, Channel::Position(_)));
        if !has_position && animated[j] {
            warnings.push(format!(
                "joint '{}' has animated translation but no position channels: it is dropped",
                joint.name
            ));
        }
    }

    let mut out = String::with_capacity(64 * skeleton.len());
    out.push_str("HIERARCHY\n");
    for (j, joint) in skeleton.joints().iter().enumerate() {
        let depth = depths[j];
        let pad = "\t".repeat(depth);
        let mut o = joint.rest_offset * to_file;
        if joint.parent.is_none() {
            // The root's position channels carry its whole position (see the module doc).
            for c in &layouts[j] {
                if let Channel::Position(axis) = c {
                    o[axis.index()] = 0.0;
                }
            }
        }
        if end_sites[j] {
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
    sink.write_all(out.as_bytes())?;

    for frame in 0..clip.frame_count() {
        out.clear();
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
        sink.write_all(out.as_bytes())?;
    }
    Ok(warnings)
}

/// Writes `clip` to `path` atomically, in the unit it was read in.
pub fn write_bvh_file(clip: &Clip, path: &Path) -> Result<Vec<String>, FormatError> {
    let mut warnings = Vec::new();
    write_atomic_with(path, |out| {
        warnings = write_bvh_to(clip, BvhWriteOptions::default(), out)?;
        Ok(())
    })?;
    Ok(warnings)
}

fn channel_layout(clip: &Clip, j: usize, animated: bool, end_site: bool) -> Vec<Channel> {
    let joint = &clip.skeleton().joints()[j];
    if end_site {
        return Vec::new();
    }
    if !joint.channels.is_empty() {
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

#[cfg(test)]
mod tests {
    use std::path::Path;
    use std::sync::Arc;

    use glam::Vec3;

    use super::*;
    use crate::formats::bvh::{BvhReadOptions, read_bvh};
    use crate::model::{ImportScale, Joint, Skeleton, forward_kinematics};

    /// A chain whose three joints carry rest rotations (as from glTF) plus an end site.
    fn rest_rotated_chain() -> Clip {
        let mut joints = vec![Joint::new("root", None, Vec3::new(0.0, 1.0, 0.0))];
        for (i, name) in ["a", "b", "c"].into_iter().enumerate() {
            let mut j = Joint::new(name, Some(i), Vec3::new(0.0, 0.3, 0.0));
            j.rest_rotation = Quat::from_rotation_z(0.5);
            joints.push(j);
        }
        let mut tip = Joint::new("c_EndSite", Some(3), Vec3::new(0.0, 0.2, 0.0));
        tip.end_site = true;
        tip.rest_rotation = Quat::from_rotation_x(0.3);
        joints.push(tip);
        let skeleton = Arc::new(Skeleton::new(joints).unwrap());
        let mut rotations = Vec::new();
        let mut translations = Vec::new();
        for f in 0..3 {
            for j in skeleton.joints() {
                rotations.push(j.rest_rotation * Quat::from_rotation_x(0.2 * f as f32));
                translations.push(j.rest_offset + Vec3::X * (f as f32 * 0.1) * f32::from(u8::from(j.parent.is_none())));
            }
        }
        Clip::new(skeleton, 30.0, rotations, translations, ImportScale::METRES).unwrap()
    }

    #[test]
    fn rest_rotations_give_one_warning_for_the_clip_and_the_motion_survives() {
        let clip = rest_rotated_chain();
        let written = write_bvh(&clip);
        assert_eq!(written.warnings.len(), 1, "{:?}", written.warnings);
        assert!(written.warnings[0].starts_with("3 joint(s) ('a' and 2 more)"), "{}", written.warnings[0]);
        let back =
            read_bvh(written.value.as_bytes(), Path::new("t.bvh"), BvhReadOptions { metres_per_unit: Some(1.0) })
                .unwrap()
                .value
                .0;
        let (pa, pb) = (forward_kinematics(&clip), forward_kinematics(&back));
        for f in 0..3 {
            for j in 0..clip.joint_count() {
                assert!((pa.position(f, j) - pb.position(f, j)).length() < 1e-5, "frame {f} joint {j}");
            }
        }
    }
}
