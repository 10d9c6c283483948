//! BVH reader.
//!
//! Steps: 1. skip a BOM and anything before `HIERARCHY` (with a warning); 2. parse the
//! joint tree line by line into joints with channel layouts; 3. read the `Frames:` and
//! `Frame Time:` header; 4. stream the frame rows, one per line, converting each straight
//! to local rotations and translations; 5. detect (or take) the length unit and scale to
//! metres. Memory grows with the data actually present, never with the header's claim.

use std::path::Path;
use std::sync::Arc;

use glam::{Quat, Vec3};

use super::frames::FrameLayout;
use super::numbers::parse_row;
use crate::formats::error::{FormatError, FormatErrorKind as Kind, Loaded, Location};
use crate::math::euler::Axis;
use crate::model::units::{ImportScale, detect_unit};
use crate::model::{Channel, Clip, Joint, Skeleton};

/// Options for reading BVH.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhReadOptions {
    /// Metres per file unit; `None` detects the unit from the skeleton's size.
    pub metres_per_unit: Option<f64>,
}

/// Facts about a parsed file that the clip itself does not carry.
#[derive(Clone, Debug, PartialEq)]
pub struct BvhStats {
    /// Frame time exactly as written (seconds).
    pub frame_time_secs: f64,
    /// Largest rest-pose extent in file units (what unit detection used).
    pub rest_extent_file_units: f64,
}

/// Reads a BVH file from disk.
pub fn read_bvh_file(path: &Path, options: BvhReadOptions) -> Result<Loaded<(Clip, BvhStats)>, FormatError> {
    let bytes = std::fs::read(path).map_err(|e| FormatError::io(path, &e))?;
    read_bvh(&bytes, path, options)
}

/// Parses BVH `bytes`; `path` only names the file in errors.
pub fn read_bvh(bytes: &[u8], path: &Path, options: BvhReadOptions) -> Result<Loaded<(Clip, BvhStats)>, FormatError> {
    Parser { path, warnings: Vec::new() }.parse(bytes, options)
}

struct Parser<'p> {
    path: &'p Path,
    warnings: Vec<String>,
}

/// A joint while parsing, in file units.
struct RawJoint {
    name: String,
    parent: Option<usize>,
    offset: Vec3,
    channels: Vec<Channel>,
    end_site: bool,
    line: usize,
}

/// Lines of the file with their 1-based numbers (line endings stripped). Bytes, not text:
/// frame rows are parsed as bytes, so only the hierarchy pays for UTF-8 checks.
struct Lines<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Lines<'a> {
    fn next_line(&mut self) -> Option<(usize, &'a [u8])> {
        let rest = self.bytes.get(self.pos..).filter(|r| !r.is_empty())?;
        let end = memchr::memchr(b'\n', rest).unwrap_or(rest.len());
        self.pos += (end + 1).min(rest.len());
        self.line += 1;
        let line = &rest[..end];
        Some((self.line, line.strip_suffix(b"\r").unwrap_or(line)))
    }
}

/// Whitespace tokens of the hierarchy section, each with its line.
struct Tokens<'a> {
    lines: Lines<'a>,
    current: std::iter::Peekable<std::str::SplitWhitespace<'a>>,
    line: usize,
    /// The first line that was not UTF-8; tokens stop there.
    not_utf8: Option<usize>,
}

impl<'a> Tokens<'a> {
    fn next_token(&mut self) -> Option<(usize, &'a str)> {
        loop {
            if let Some(t) = self.current.next() {
                return Some((self.line, t));
            }
            let (n, l) = self.lines.next_line()?;
            self.line = n;
            let Ok(text) = std::str::from_utf8(l) else {
                self.not_utf8 = Some(n);
                return None;
            };
            self.current = text.split_whitespace().peekable();
        }
    }

    /// The rest of the current line, joined by single spaces.
    fn rest_of_line(&mut self) -> Vec<&'a str> {
        self.current.by_ref().collect()
    }
}

impl Parser<'_> {
    fn err(&self, line: usize, kind: Kind, message: impl Into<String>) -> FormatError {
        FormatError::new(self.path, Location::Line { line, column: None }, kind, message)
    }

    fn parse(mut self, bytes: &[u8], options: BvhReadOptions) -> Result<Loaded<(Clip, BvhStats)>, FormatError> {
        let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
        let start = memchr::memmem::find(bytes, b"HIERARCHY")
            .ok_or_else(|| FormatError::file(self.path, Kind::Syntax, "no HIERARCHY keyword: not a BVH file"))?;
        let skipped_lines = bytes[..start].iter().filter(|&&b| b == b'\n').count();
        if bytes[..start].iter().any(|b| !b.is_ascii_whitespace()) {
            self.warnings.push(format!("skipped {} bytes before HIERARCHY", start));
        }
        let mut tokens = Tokens {
            lines: Lines { bytes: &bytes[start..], pos: 0, line: skipped_lines },
            current: "".split_whitespace().peekable(),
            line: skipped_lines,
            not_utf8: None,
        };
        let header = self.parse_hierarchy(&mut tokens).and_then(|joints| {
            let motion = self.parse_motion_header(&mut tokens)?;
            Ok((joints, motion))
        });
        // A line that is not text ends the token stream; say that rather than what the
        // parser made of the early end.
        if let Some(line) = tokens.not_utf8 {
            return Err(self.err(line, Kind::Syntax, "bytes that are not UTF-8 text"));
        }
        let (joints, (claimed_frames, frame_time, frames_line)) = header?;
        let mut lines = tokens.lines;
        let file_skeleton = self.build_skeleton(&joints)?;
        let rest_extent = f64::from(file_skeleton.rest_extent().max_element());
        let (unit, metres_per_unit, detected) = match options.metres_per_unit {
            Some(m) if m.is_finite() && m > 0.0 => (None, m, false),
            Some(m) => {
                return Err(FormatError::file(
                    self.path,
                    Kind::Value,
                    format!("scale override {m} is not a positive number"),
                ));
            }
            None => {
                let unit = detect_unit(rest_extent);
                (Some(unit), unit.metres(), true)
            }
        };
        let skeleton = file_skeleton
            .scaled(metres_per_unit as f32)
            .map_err(|e| self.err(joints[0].line, Kind::Value, format!("{e} after scaling to metres")))?;
        let (rotations, translations) =
            self.parse_frames(&mut lines, &joints, &skeleton, claimed_frames, frames_line, metres_per_unit as f32)?;
        let scale = ImportScale { unit, metres_per_unit, detected };
        let clip = Clip::new(Arc::new(skeleton), 1.0 / frame_time, rotations, translations, scale)
            .map_err(|e| FormatError::file(self.path, Kind::Value, e.to_string()))?;
        let stats = BvhStats { frame_time_secs: frame_time, rest_extent_file_units: rest_extent };
        Ok(Loaded { value: (clip, stats), warnings: self.warnings })
    }

    fn parse_hierarchy(&mut self, tokens: &mut Tokens<'_>) -> Result<Vec<RawJoint>, FormatError> {
        let (line, first) =
            tokens.next_token().ok_or_else(|| FormatError::file(self.path, Kind::Truncated, "empty file"))?;
        if first != "HIERARCHY" {
            return Err(self.err(line, Kind::Syntax, format!("expected HIERARCHY, found '{first}'")));
        }
        let mut joints: Vec<RawJoint> = Vec::new();
        // Stack of open blocks: index into `joints`.
        let mut stack: Vec<usize> = Vec::new();
        loop {
            let Some((line, token)) = tokens.next_token() else {
                return Err(self.err(
                    tokens.line,
                    Kind::Truncated,
                    "file ends inside the HIERARCHY section (no MOTION)",
                ));
            };
            match token {
                "ROOT" | "JOINT" => {
                    if token == "ROOT" && !stack.is_empty() {
                        return Err(self.err(line, Kind::Syntax, "ROOT inside another joint's block"));
                    }
                    if token == "JOINT" && stack.is_empty() {
                        return Err(self.err(line, Kind::Syntax, "JOINT outside any ROOT block"));
                    }
                    let mut words = tokens.rest_of_line();
                    let opens_inline = words.last() == Some(&"{");
                    if opens_inline {
                        words.pop();
                    }
                    if words.is_empty() {
                        return Err(self.err(line, Kind::Syntax, format!("{token} without a name")));
                    }
                    let name = words.join(" ");
                    joints.push(RawJoint {
                        name,
                        parent: stack.last().copied(),
                        offset: Vec3::ZERO,
                        channels: Vec::new(),
                        end_site: false,
                        line,
                    });
                    if !opens_inline {
                        self.expect(tokens, "{")?;
                    }
                    stack.push(joints.len() - 1);
                }
                "End" => {
                    let Some(&parent) = stack.last() else {
                        return Err(self.err(line, Kind::Syntax, "End Site outside any joint"));
                    };
                    let words = tokens.rest_of_line();
                    let opens_inline = words.last() == Some(&"{");
                    if words.first() != Some(&"Site") {
                        return Err(self.err(line, Kind::Syntax, "expected 'End Site'"));
                    }
                    joints.push(RawJoint {
                        name: format!("{}_EndSite", joints[parent].name),
                        parent: Some(parent),
                        offset: Vec3::ZERO,
                        channels: Vec::new(),
                        end_site: true,
                        line,
                    });
                    if !opens_inline {
                        self.expect(tokens, "{")?;
                    }
                    stack.push(joints.len() - 1);
                }
                "OFFSET" => {
                    let Some(&current) = stack.last() else {
                        return Err(self.err(line, Kind::Syntax, "OFFSET outside any joint"));
                    };
                    let mut v = [0.0f32; 3];
                    for c in &mut v {
                        *c = self.number(tokens, "OFFSET")?;
                    }
                    joints[current].offset = Vec3::from(v);
                }
                "CHANNELS" => {
                    let Some(&current) = stack.last() else {
                        return Err(self.err(line, Kind::Syntax, "CHANNELS outside any joint"));
                    };
                    if joints[current].end_site {
                        return Err(self.err(line, Kind::Syntax, "an End Site cannot have CHANNELS"));
                    }
                    let count = self.number(tokens, "CHANNELS")?;
                    if !(0.0..=64.0).contains(&count) || count.fract() != 0.0 {
                        return Err(self.err(
                            line,
                            Kind::Value,
                            format!("channel count {count} is not a whole number from 0 to 64"),
                        ));
                    }
                    let mut channels = Vec::with_capacity(count as usize);
                    for _ in 0..count as usize {
                        let (l, name) = tokens
                            .next_token()
                            .ok_or_else(|| self.err(line, Kind::Truncated, "file ends in a CHANNELS list"))?;
                        channels.push(parse_channel(name).ok_or_else(|| {
                            self.err(l, Kind::Syntax, format!("'{name}' is not a channel name (expected e.g. Xposition, Zrotation); the CHANNELS count may be wrong"))
                        })?);
                    }
                    joints[current].channels = channels;
                }
                "}" => {
                    if stack.pop().is_none() {
                        return Err(self.err(line, Kind::Syntax, "unmatched '}'"));
                    }
                }
                "MOTION" => {
                    if !stack.is_empty() {
                        return Err(self.err(line, Kind::Syntax, "MOTION before every joint block is closed"));
                    }
                    break;
                }
                other => {
                    return Err(self.err(line, Kind::Syntax, format!("unexpected '{other}' in HIERARCHY")));
                }
            }
        }
        if joints.iter().all(|j| j.end_site) {
            return Err(self.err(tokens.line, Kind::Structure, "the hierarchy has no joints"));
        }
        Ok(joints)
    }

    fn expect(&self, tokens: &mut Tokens<'_>, want: &str) -> Result<(), FormatError> {
        match tokens.next_token() {
            Some((_, t)) if t == want => Ok(()),
            Some((l, t)) => Err(self.err(l, Kind::Syntax, format!("expected '{want}', found '{t}'"))),
            None => Err(self.err(tokens.line, Kind::Truncated, format!("file ends where '{want}' was expected"))),
        }
    }

    fn number(&self, tokens: &mut Tokens<'_>, what: &str) -> Result<f32, FormatError> {
        let (l, t) = tokens
            .next_token()
            .ok_or_else(|| self.err(tokens.line, Kind::Truncated, format!("file ends inside {what}")))?;
        match t.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.err(l, Kind::Value, format!("'{t}' in {what} is not a finite number"))),
        }
    }

    fn parse_motion_header(&self, tokens: &mut Tokens<'_>) -> Result<(usize, f64, usize), FormatError> {
        let mut frames = None;
        let mut frame_time = None;
        while frames.is_none() || frame_time.is_none() {
            let Some((line, t)) = tokens.next_token() else {
                return Err(self.err(tokens.line, Kind::Truncated, "file ends inside the MOTION header"));
            };
            let value = |tokens: &mut Tokens<'_>| -> Result<f64, FormatError> {
                let (l, v) = tokens
                    .next_token()
                    .ok_or_else(|| self.err(line, Kind::Truncated, "file ends inside the MOTION header"))?;
                v.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| self.err(l, Kind::Value, format!("'{v}' is not a number")))
            };
            match t {
                "Frames:" => {
                    let n = value(tokens)?;
                    if n < 0.0 || n.fract() != 0.0 {
                        return Err(self.err(
                            line,
                            Kind::Value,
                            format!("frame count {n} is not a whole non-negative number"),
                        ));
                    }
                    frames = Some((n as usize, line));
                }
                "Frame" => {
                    self.expect(tokens, "Time:")?;
                    let dt = value(tokens)?;
                    if dt <= 0.0 {
                        return Err(self.err(line, Kind::Value, format!("frame time {dt} s must be positive")));
                    }
                    frame_time = Some(dt);
                }
                other => {
                    return Err(self.err(
                        line,
                        Kind::Syntax,
                        format!("expected 'Frames:' or 'Frame Time:', found '{other}'"),
                    ));
                }
            }
        }
        if tokens.current.peek().is_some() {
            return Err(self.err(tokens.line, Kind::Syntax, "unexpected text after the frame time"));
        }
        let (frames, frames_line) = frames.unwrap_or((0, tokens.line));
        Ok((frames, frame_time.unwrap_or(1.0), frames_line))
    }

    /// The skeleton in file units.
    fn build_skeleton(&self, joints: &[RawJoint]) -> Result<Skeleton, FormatError> {
        let mut out: Vec<Joint> = joints
            .iter()
            .map(|r| Joint {
                name: r.name.clone(),
                parent: r.parent,
                rest_offset: r.offset,
                rest_rotation: Quat::IDENTITY,
                limits: None,
                channels: r.channels.clone(),
                end_site: r.end_site,
            })
            .collect();
        // An end-site name may collide with a real joint: make it unique, keep real names.
        let mut taken: std::collections::BTreeSet<String> =
            out.iter().filter(|j| !j.end_site).map(|j| j.name.clone()).collect();
        for j in out.iter_mut().filter(|j| j.end_site) {
            let mut name = j.name.clone();
            let mut n = 1;
            while taken.contains(&name) {
                n += 1;
                name = format!("{}{n}", j.name);
            }
            taken.insert(name.clone());
            j.name = name;
        }
        Skeleton::new(out).map_err(|e| {
            let line = match &e {
                crate::model::SkeletonError::DuplicateName { second, .. } => joints[*second].line,
                _ => joints[0].line,
            };
            self.err(line, Kind::Structure, e.to_string())
        })
    }

    fn parse_frames(
        &mut self,
        lines: &mut Lines<'_>,
        joints: &[RawJoint],
        skeleton: &Skeleton,
        claimed: usize,
        frames_line: usize,
        scale: f32,
    ) -> Result<(Vec<Quat>, Vec<Vec3>), FormatError> {
        let mut layout = FrameLayout::new(joints.iter().map(|j| j.channels.as_slice()));
        let joint_count = joints.len();
        // Reserve from the data present, not from the claim: a row takes at least two
        // bytes per channel.
        let remaining = lines.bytes.len().saturating_sub(lines.pos);
        let plausible = remaining / (2 * layout.channel_count().max(1)) + 1;
        let reserve = claimed.min(plausible) * joint_count;
        let mut rotations = Vec::with_capacity(reserve);
        let mut translations = Vec::with_capacity(reserve);
        let mut values = vec![0.0f32; layout.channel_count()];
        let mut frames = 0usize;
        let mut extra_lines = 0usize;
        while let Some((line, text)) = lines.next_line() {
            let count = match parse_row(text, &mut values) {
                Ok(count) => count,
                Err(token) => {
                    return Err(self.err(line, Kind::Value, format!("'{token}' is not a finite number")));
                }
            };
            if count == 0 {
                continue;
            }
            if frames == claimed {
                extra_lines += 1;
                continue;
            }
            if count != layout.channel_count() {
                return Err(self.err(
                    line,
                    Kind::Structure,
                    format!(
                        "frame {} has {count} values, the hierarchy declares {} channels",
                        frames,
                        layout.channel_count()
                    ),
                ));
            }
            layout.push_frame(skeleton.joints(), &values, scale, &mut rotations, &mut translations);
            frames += 1;
        }
        if frames < claimed {
            return Err(self.err(
                frames_line,
                Kind::Truncated,
                format!("Frames: claims {claimed} frames but the file holds {frames}"),
            ));
        }
        if extra_lines > 0 {
            self.warnings.push(format!("ignored {extra_lines} rows after the {claimed} frames the header declares"));
        }
        Ok((rotations, translations))
    }
}

fn parse_channel(name: &str) -> Option<Channel> {
    let lower = name.to_ascii_lowercase();
    let (axis, kind) = lower.split_at_checked(1)?;
    let axis = match axis {
        "x" => Axis::X,
        "y" => Axis::Y,
        "z" => Axis::Z,
        _ => return None,
    };
    match kind {
        "position" => Some(Channel::Position(axis)),
        "rotation" => Some(Channel::Rotation(axis)),
        _ => None,
    }
}
