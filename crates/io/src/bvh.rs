//! Biovision hierarchy (BVH): skeleton motion in and out.
//!
//! A BVH file is a `HIERARCHY` section (nested `ROOT`/`JOINT`/`End Site` blocks with an
//! `OFFSET` and a `CHANNELS` list each) followed by a `MOTION` section (`Frames:`,
//! `Frame Time:` and one line of channel values per frame, in hierarchy order).
//!
//! # Format choices
//! - **Units.** BVH does not say what unit its offsets and positions are in (CMU files use
//!   scaled inches, others centimetres or metres), so the caller names it: every length is
//!   multiplied by [`LengthUnit::mm_per_unit`] on read and divided by it on write.
//! - **Rotation orders.** Each joint may list its rotation channels in any order; the order is
//!   kept in [`locap_core::Joint::rotation_order`] and written back unchanged. With the core
//!   convention (`R = R_a1 * R_a2 * R_a3` in listed order) a BVH channel list *is* an
//!   [`EulerOrder`]. A joint listing fewer than three rotation axes gets the missing axes
//!   appended (X, Y, Z order) with angle 0, which is the same rotation; a joint with no
//!   channels is read with an identity rotation.
//! - **Root position.** The root's position channels are its absolute position, so they go to
//!   `root_position_mm` and the root's `OFFSET` is kept in the skeleton but not added (see
//!   [`locap_core::skeleton`]). A root without position channels stands at its `OFFSET`.
//! - **End sites.** An `End Site` becomes a leaf joint with `is_end_site: true`, named
//!   `<parent>_End` (with a number appended if that name is taken), and an identity rotation
//!   in every frame.
//! - **Not supported:** position channels on a joint other than the root (an
//!   [`Error::Unsupported`]), and several `ROOT`s in one file.
//! - **Strictness.** The `Frames:` count must equal the number of motion lines (blank lines
//!   are skipped, so trailing blank lines are fine), every line must have exactly one value
//!   per channel, and every number must be finite. Every error names the 1-based line (and,
//!   for a bad value, the column) where the file goes wrong.
//! - **Writing** uses six channels for the root and three for every other joint, numbers in
//!   Rust's shortest round-trip notation (so reading a written file gives back the same
//!   `f64`s), and the frame time likewise, so the frame rate survives to ~1e-15 relative.
//!   Indentation (one tab per level) stops growing at [`MAX_INDENT`] levels, so the output
//!   stays linear in the joint count however deep the tree (readers ignore whitespace; a
//!   100,000-deep chain once wrote 7.6 GB).
//!
//! # Limits
//! [`read_bvh_with`] checks the hierarchy's depth and joint count against [`Limits`] while it
//! parses, and frames × joints (including end sites and joints without channels, which no
//! motion value backs) against [`Limits::max_samples`] and the text's size before reserving
//! the motion (see [`crate::limits`]).

use crate::atomic::write_atomically;
use crate::limits::{self, Limits};
use crate::{Error, Result};
use locap_core::{EulerOrder, Joint, LengthUnit, Motion, Quat, Skeleton, Vec3};
use std::collections::HashSet;
use std::io::Write;
use std::path::Path;

const FORMAT: &str = "BVH";

/// Deepest indentation the writer uses, in tabs.
pub const MAX_INDENT: usize = 32;

/// One whitespace-separated word of the hierarchy with where it was found.
#[derive(Debug, Clone, Copy)]
struct Token<'a> {
    text: &'a str,
    line: usize,
    column: usize,
}

/// Splits a line into tokens with 1-based columns (counted in characters).
fn tokens_of(line_text: &str, line: usize) -> impl Iterator<Item = Token<'_>> {
    let mut column = 0usize;
    let mut start: Option<(usize, usize)> = None; // (byte index, column)
    let mut out = Vec::new();
    for (byte, ch) in line_text.char_indices() {
        column += 1;
        if ch.is_whitespace() {
            if let Some((b, c)) = start.take() {
                out.push(Token { text: &line_text[b..byte], line, column: c });
            }
        } else if start.is_none() {
            start = Some((byte, column));
        }
    }
    if let Some((b, c)) = start {
        out.push(Token { text: &line_text[b..], line, column: c });
    }
    out.into_iter()
}

/// Lines of `text` without their `\r\n` / `\n` ending, numbered from 1.
fn numbered_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.split('\n').enumerate().map(|(i, l)| (i + 1, l.strip_suffix('\r').unwrap_or(l)))
}

fn err_at(tok: &Token<'_>, message: impl Into<String>) -> Error {
    Error::Text { format: FORMAT, line: tok.line, column: Some(tok.column), message: message.into() }
}

/// Parses a finite number; NaN and infinities are refused because no capture value is one.
fn number(tok: &Token<'_>, what: &str) -> Result<f64> {
    match tok.text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(err_at(tok, format!("expected a number for {what}, found {:?}", tok.text))),
    }
}

/// What one channel of the motion data drives.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Channel {
    Position(usize),
    Rotation(usize),
}

fn parse_channel(tok: &Token<'_>) -> Result<Channel> {
    let lower = tok.text.to_ascii_lowercase();
    // Split after the first *character*: a byte split panicked inside a multi-byte first
    // character (fuzzer-found, `㑑zrotation`).
    let mut chars = lower.chars();
    let axis = match chars.next() {
        Some('x') => 0,
        Some('y') => 1,
        Some('z') => 2,
        _ => return Err(err_at(tok, format!("unknown channel {:?}", tok.text))),
    };
    match chars.as_str() {
        "position" => Ok(Channel::Position(axis)),
        "rotation" => Ok(Channel::Rotation(axis)),
        _ => Err(err_at(tok, format!("unknown channel {:?}", tok.text))),
    }
}

/// A joint as the hierarchy declares it, before the skeleton is built.
struct Declared {
    name: Option<String>,
    parent: Option<usize>,
    offset: Option<Vec3>,
    channels: Vec<Channel>,
    is_end_site: bool,
    line: usize,
}

/// How to decode one joint's slice of a motion line.
struct Decoder {
    /// Position channel slots (axis, index into the line).
    positions: Vec<(usize, usize)>,
    /// The rotation order and, per angle of that order, the slot holding it (if any).
    order: EulerOrder,
    angle_slots: [Option<usize>; 3],
}

/// Reads a cursor of hierarchy tokens.
struct Cursor<'a> {
    tokens: Vec<Token<'a>>,
    at: usize,
    /// Line to blame when the tokens run out.
    end_line: usize,
}

impl<'a> Cursor<'a> {
    fn next(&mut self, expected: &str) -> Result<Token<'a>> {
        match self.tokens.get(self.at) {
            Some(t) => {
                self.at += 1;
                Ok(*t)
            }
            None => Err(Error::text(FORMAT, self.end_line, format!("file ends where {expected} was expected"))),
        }
    }

    fn expect(&mut self, word: &str) -> Result<Token<'a>> {
        let tok = self.next(&format!("{word:?}"))?;
        if tok.text.eq_ignore_ascii_case(word) {
            Ok(tok)
        } else {
            Err(err_at(&tok, format!("expected {word:?}, found {:?}", tok.text)))
        }
    }
}

/// Parses the hierarchy tokens into declared joints (parents first, in channel order).
fn parse_hierarchy(cursor: &mut Cursor<'_>, limits: &Limits) -> Result<Vec<Declared>> {
    cursor.expect("HIERARCHY")?;
    let root_tok = cursor.expect("ROOT")?;
    let name = cursor.next("the root's name")?;
    cursor.expect("{")?;
    let mut joints = vec![Declared {
        name: Some(name.text.to_string()),
        parent: None,
        offset: None,
        channels: Vec::new(),
        is_end_site: false,
        line: root_tok.line,
    }];
    // An explicit stack instead of recursion: a deeply nested (or hostile) file cannot
    // overflow the call stack.
    let mut open = vec![0usize];
    while let Some(&current) = open.last() {
        let tok = cursor.next("\"}\"")?;
        let word = tok.text.to_ascii_uppercase();
        match word.as_str() {
            "OFFSET" => {
                let mut v = [0.0; 3];
                for x in &mut v {
                    *x = number(&cursor.next("an OFFSET value")?, "OFFSET")?;
                }
                let joint = joints.get_mut(current).ok_or_else(|| err_at(&tok, "internal: no joint"))?;
                if joint.offset.is_some() {
                    return Err(err_at(&tok, "second OFFSET in one joint"));
                }
                joint.offset = Some(Vec3::from(v));
            }
            "CHANNELS" => {
                let count_tok = cursor.next("a channel count")?;
                let count: usize = count_tok
                    .text
                    .parse()
                    .map_err(|_| err_at(&count_tok, format!("expected a channel count, found {:?}", count_tok.text)))?;
                if count > 6 {
                    return Err(err_at(&count_tok, format!("{count} channels; at most 6 are possible")));
                }
                let mut channels = Vec::with_capacity(count);
                for _ in 0..count {
                    let ch_tok = cursor.next("a channel name")?;
                    let ch = parse_channel(&ch_tok)?;
                    if channels.contains(&ch) {
                        return Err(err_at(&ch_tok, format!("channel {:?} listed twice", ch_tok.text)));
                    }
                    if matches!(ch, Channel::Position(_)) && current != 0 {
                        return Err(Error::Unsupported(format!(
                            "BVH line {}: position channels on joint {:?}, which is not the root",
                            ch_tok.line,
                            joints.get(current).and_then(|j| j.name.clone()).unwrap_or_default()
                        )));
                    }
                    channels.push(ch);
                }
                let joint = joints.get_mut(current).ok_or_else(|| err_at(&tok, "internal: no joint"))?;
                if joint.is_end_site {
                    return Err(err_at(&tok, "an End Site has no channels"));
                }
                if !joint.channels.is_empty() {
                    return Err(err_at(&tok, "second CHANNELS in one joint"));
                }
                joint.channels = channels;
            }
            "JOINT" | "END" => {
                let is_end_site = word == "END";
                if joints.get(current).is_some_and(|j| j.is_end_site) {
                    return Err(err_at(&tok, "an End Site cannot have children"));
                }
                let name = if is_end_site {
                    cursor.expect("Site")?;
                    None
                } else {
                    Some(cursor.next("a joint name")?.text.to_string())
                };
                cursor.expect("{")?;
                // Depth of the new joint is the number of blocks open around it.
                limits.check_hierarchy(FORMAT, tok.line, open.len(), joints.len() + 1)?;
                joints.push(Declared {
                    name,
                    parent: Some(current),
                    offset: None,
                    channels: Vec::new(),
                    is_end_site,
                    line: tok.line,
                });
                open.push(joints.len() - 1);
            }
            "}" => {
                if joints.get(current).is_some_and(|j| j.offset.is_none()) {
                    return Err(err_at(&tok, "block closed without an OFFSET"));
                }
                open.pop();
            }
            "ROOT" => {
                return Err(err_at(&tok, "ROOT inside a joint (or a second ROOT): not supported"));
            }
            _ => {
                return Err(err_at(
                    &tok,
                    format!("expected OFFSET, CHANNELS, JOINT, End Site or \"}}\", found {:?}", tok.text),
                ));
            }
        }
    }
    if let Some(extra) = cursor.tokens.get(cursor.at) {
        return Err(err_at(extra, format!("expected MOTION after the root block, found {:?}", extra.text)));
    }
    Ok(joints)
}

/// Names end sites `<parent>_End`, numbered if that is taken, and checks names are unique.
fn build_skeleton(declared: &[Declared], mm: f64) -> Result<(Skeleton, Vec<Decoder>)> {
    let mut names: HashSet<String> = HashSet::new();
    for d in declared {
        if let Some(name) = &d.name
            && !names.insert(name.clone())
        {
            return Err(Error::text(FORMAT, d.line, format!("joint name {name:?} is used twice")));
        }
    }
    let mut joints: Vec<Joint> = Vec::with_capacity(declared.len());
    let mut decoders = Vec::with_capacity(declared.len());
    let mut slot = 0usize;
    for d in declared {
        let name = match &d.name {
            Some(n) => n.clone(),
            None => {
                let parent_name = d.parent.and_then(|p| joints.get(p)).map(|j| j.name.as_str()).unwrap_or("Root");
                let base = format!("{parent_name}_End");
                let mut name = base.clone();
                let mut k = 2usize;
                while names.contains(&name) {
                    name = format!("{base}{k}");
                    k += 1;
                }
                names.insert(name.clone());
                name
            }
        };
        // Rotation axes as listed; missing axes are appended (angle 0) to make an order.
        let mut axes: Vec<usize> = Vec::with_capacity(3);
        let mut positions = Vec::new();
        let mut rotation_slots: Vec<(usize, usize)> = Vec::new();
        for ch in &d.channels {
            match *ch {
                Channel::Position(axis) => positions.push((axis, slot)),
                Channel::Rotation(axis) => {
                    axes.push(axis);
                    rotation_slots.push((axis, slot));
                }
            }
            slot += 1;
        }
        let order = if axes.is_empty() {
            EulerOrder::ZXY
        } else {
            for axis in 0..3 {
                if !axes.contains(&axis) {
                    axes.push(axis);
                }
            }
            let arr: [usize; 3] = [axes[0], axes[1], axes[2]];
            EulerOrder::from_axes(arr).ok_or_else(|| Error::text(FORMAT, d.line, "rotation axis listed twice"))?
        };
        let mut angle_slots = [None; 3];
        for (pos, axis) in order.axes().iter().enumerate() {
            angle_slots[pos] = rotation_slots.iter().find(|(a, _)| a == axis).map(|&(_, s)| s);
        }
        decoders.push(Decoder { positions, order, angle_slots });
        joints.push(Joint {
            name,
            parent: d.parent,
            offset_mm: d.offset.unwrap_or_else(Vec3::zeros) * mm,
            rotation_order: order,
            is_end_site: d.is_end_site,
        });
    }
    Ok((Skeleton::new(joints)?, decoders))
}

/// Exporters print the frame time with few digits (CMU: `.008333`, i.e. 120.0048 Hz). When the
/// frame time is printed with at most 7 significant digits (so it is evidently rounded), a
/// rate within 0.005 % of a whole number of hertz is that whole number: capture systems run at
/// whole rates, and a take's length in seconds should not drift by 4e-5 per frame. locap
/// writes the frame time exactly, so its own files are never snapped.
fn significant_digits(number: &str) -> usize {
    let mantissa = number.split(['e', 'E']).next().unwrap_or("");
    mantissa.chars().filter(|c| c.is_ascii_digit()).skip_while(|c| *c == '0').count()
}

fn snap_rate(hz: f64) -> f64 {
    let whole = hz.round();
    if whole > 0.0 && ((hz - whole) / whole).abs() < 5e-5 { whole } else { hz }
}

/// Parses `key: value` header lines of the MOTION section (`Frames:`, `Frame Time:`).
fn header_value<'a>(line_text: &'a str, line: usize, key: &str) -> Result<&'a str> {
    let (k, v) = line_text
        .split_once(':')
        .ok_or_else(|| Error::text(FORMAT, line, format!("expected \"{key}:\", found {:?}", line_text.trim())))?;
    let normalized: Vec<&str> = k.split_whitespace().collect();
    let wanted: Vec<&str> = key.split_whitespace().collect();
    let same =
        normalized.len() == wanted.len() && normalized.iter().zip(&wanted).all(|(a, b)| a.eq_ignore_ascii_case(b));
    if !same {
        return Err(Error::text(FORMAT, line, format!("expected \"{key}:\", found {:?}", line_text.trim())));
    }
    Ok(v.trim())
}

/// Reads a BVH file's text. Offsets and positions are in `unit` (BVH does not say).
pub fn read_bvh(text: &str, unit: LengthUnit) -> Result<Motion> {
    read_bvh_with(text, unit, &Limits::default())
}

/// [`read_bvh`] with explicit [`Limits`] on depth, joints, frames and samples.
pub fn read_bvh_with(text: &str, unit: LengthUnit, limits: &Limits) -> Result<Motion> {
    let mm = unit.mm_per_unit();
    let mut lines = numbered_lines(text);
    let mut hierarchy_tokens = Vec::new();
    let mut motion_line = None;
    let mut last_line = 1;
    for (number, line_text) in lines.by_ref() {
        last_line = number;
        let mut toks = tokens_of(line_text, number).peekable();
        if toks.peek().is_some_and(|t| t.text.eq_ignore_ascii_case("MOTION")) {
            if let Some(extra) = toks.nth(1) {
                return Err(err_at(&extra, format!("unexpected {:?} after MOTION", extra.text)));
            }
            motion_line = Some(number);
            break;
        }
        hierarchy_tokens.extend(toks);
    }
    let mut cursor = Cursor { tokens: hierarchy_tokens, at: 0, end_line: last_line };
    let declared = parse_hierarchy(&mut cursor, limits)?;
    let motion_line =
        motion_line.ok_or_else(|| Error::text(FORMAT, last_line, "file ends before the MOTION section"))?;
    let (skeleton, decoders) = build_skeleton(&declared, mm)?;
    let channel_count: usize = declared.iter().map(|d| d.channels.len()).sum();

    // Header lines, skipping blank ones.
    let mut next_nonblank = |what: &str| -> Result<(usize, &str)> {
        let mut end = motion_line;
        for (number, line_text) in lines.by_ref() {
            end = number;
            if !line_text.trim().is_empty() {
                return Ok((number, line_text));
            }
        }
        Err(Error::text(FORMAT, end, format!("file ends where {what} was expected")))
    };
    let (frames_line, frames_text) = next_nonblank("\"Frames:\"")?;
    let frames_value = header_value(frames_text, frames_line, "Frames")?;
    let frames: usize = frames_value
        .parse()
        .map_err(|_| Error::text(FORMAT, frames_line, format!("expected a frame count, found {frames_value:?}")))?;
    let (time_line, time_text) = next_nonblank("\"Frame Time:\"")?;
    let time_value = header_value(time_text, time_line, "Frame Time")?;
    let frame_time: f64 = match time_value.parse::<f64>() {
        Ok(t) if t.is_finite() && t > 0.0 => t,
        _ => {
            return Err(Error::text(
                FORMAT,
                time_line,
                format!("expected a positive frame time in seconds, found {time_value:?}"),
            ));
        }
    };
    let frame_rate_hz =
        if significant_digits(time_value) <= 7 { snap_rate(1.0 / frame_time) } else { 1.0 / frame_time };
    if !frame_rate_hz.is_finite() {
        return Err(Error::text(FORMAT, time_line, format!("frame time {frame_time} is too small")));
    }

    let joints = skeleton.len();
    limits.check_samples(FORMAT, frames, joints, "joints")?;
    // The declared count only guides the allocation up to what the text could back: a
    // corrupt header must not make us reserve gigabytes before the lines are seen.
    let mut rotations: Vec<Quat> = Vec::with_capacity((frames * joints).min(text.len()));
    let mut root_positions: Vec<Vec3> = Vec::with_capacity(frames.min(text.len() / 2));
    let root_offset = skeleton.joints().first().map(|j| j.offset_mm).unwrap_or_else(Vec3::zeros);
    let mut values = Vec::with_capacity(channel_count);
    let mut end_line = time_line;
    for (number, line_text) in lines {
        end_line = number;
        if line_text.trim().is_empty() {
            continue;
        }
        if root_positions.len() == frames {
            return Err(Error::text(
                FORMAT,
                number,
                format!("more motion lines than the {frames} frames that \"Frames:\" declares"),
            ));
        }
        // Joints without channels (end sites) take no bytes of a motion line, so the motion
        // is bounded by the text as it grows (see the module doc).
        limits.check_text_samples(FORMAT, root_positions.len() + 1, joints, "joints", text.len())?;
        values.clear();
        let mut count = 0usize;
        for tok in tokens_of(line_text, number) {
            count += 1;
            if count > channel_count {
                return Err(err_at(
                    &tok,
                    format!("more than the {channel_count} values the hierarchy's channels need"),
                ));
            }
            values.push(number_value(&tok)?);
        }
        if count < channel_count {
            return Err(Error::text(
                FORMAT,
                number,
                format!("{count} values, but the hierarchy's channels need {channel_count}"),
            ));
        }
        for (index, dec) in decoders.iter().enumerate() {
            let mut angles = [0.0; 3];
            for (angle, slot) in angles.iter_mut().zip(dec.angle_slots) {
                if let Some(s) = slot {
                    *angle = values.get(s).copied().unwrap_or(0.0);
                }
            }
            rotations.push(dec.order.to_quat_deg(angles));
            if index == 0 {
                let mut p = if dec.positions.is_empty() { root_offset } else { Vec3::zeros() };
                for &(axis, s) in &dec.positions {
                    p[axis] = values.get(s).copied().unwrap_or(0.0) * mm;
                }
                root_positions.push(p);
            }
        }
    }
    if root_positions.len() != frames {
        return Err(Error::text(
            FORMAT,
            end_line,
            format!("file ends after {} motion lines, but \"Frames:\" declares {frames}", root_positions.len()),
        ));
    }
    Ok(Motion::new(skeleton, rotations, root_positions, frame_rate_hz)?)
}

fn number_value(tok: &Token<'_>) -> Result<f64> {
    number(tok, "a channel value")
}

/// Reads a BVH file (see [`read_bvh`]); errors name the file.
pub fn read_bvh_path(path: &Path, unit: LengthUnit) -> Result<Motion> {
    read_bvh_path_with(path, unit, &Limits::default())
}

/// [`read_bvh_path`] with explicit [`Limits`]. A path that is not a regular file (a named
/// pipe, a device, a directory) is refused before it is opened.
pub fn read_bvh_path_with(path: &Path, unit: LengthUnit, limits: &Limits) -> Result<Motion> {
    let text = limits::read_utf8(path, limits)?;
    read_bvh_with(&text, unit, limits).map_err(|e| e.in_file(path))
}

/// Checks a value can be written and read back.
fn finite(v: f64, what: &str) -> Result<f64> {
    if v.is_finite() { Ok(v) } else { Err(Error::Unwritable(format!("{what} is {v}"))) }
}

/// Writes a motion as BVH with lengths in `unit`. Every joint keeps its own rotation order;
/// end sites become `End Site` blocks (their names are not stored by BVH).
pub fn write_bvh(motion: &Motion, unit: LengthUnit, w: &mut dyn Write) -> Result<()> {
    let skeleton = &motion.skeleton;
    let joints = skeleton.joints();
    let mm = unit.mm_per_unit();
    // Children lists once, so writing stays linear in the joint count.
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); joints.len()];
    for (i, j) in joints.iter().enumerate() {
        if let Some(p) = j.parent
            && let Some(list) = children.get_mut(p)
        {
            list.push(i);
        }
    }
    for (i, j) in joints.iter().enumerate() {
        if j.name.is_empty() || j.name.chars().any(char::is_whitespace) {
            return Err(Error::Unwritable(format!("joint name {:?} is empty or has blanks", j.name)));
        }
        if j.is_end_site && children.get(i).is_some_and(|c| !c.is_empty()) {
            return Err(Error::Unwritable(format!("end site {:?} has children", j.name)));
        }
        if i == 0 && j.is_end_site {
            return Err(Error::Unwritable("the root is an end site".into()));
        }
    }

    // The channel data is written in the order joints appear in the hierarchy text, which is
    // a depth-first walk; keep that order to lay out the motion lines.
    let mut text_order = Vec::with_capacity(joints.len());
    writeln!(w, "HIERARCHY")?;
    // (joint, depth, children written so far); an explicit stack for arbitrarily deep trees.
    let mut stack: Vec<(usize, usize, usize)> = vec![(0, 0, 0)];
    let mut opened = vec![false; joints.len()];
    while let Some(top) = stack.last_mut() {
        let (joint, depth, next_child) = *top;
        let Some(j) = joints.get(joint) else { break };
        let indent = "\t".repeat(depth.min(MAX_INDENT));
        if !opened.get(joint).copied().unwrap_or(true) {
            if let Some(o) = opened.get_mut(joint) {
                *o = true;
            }
            if j.is_end_site {
                writeln!(w, "{indent}End Site")?;
            } else {
                writeln!(w, "{indent}{} {}", if j.parent.is_none() { "ROOT" } else { "JOINT" }, j.name)?;
                text_order.push(joint);
            }
            writeln!(w, "{indent}{{")?;
            let o = j.offset_mm / mm;
            writeln!(
                w,
                "{indent}\tOFFSET {} {} {}",
                finite(o.x, "an offset")?,
                finite(o.y, "an offset")?,
                finite(o.z, "an offset")?
            )?;
            if !j.is_end_site {
                let axes = j.rotation_order.name().chars();
                let rot: Vec<String> = axes.map(|c| format!("{c}rotation")).collect();
                if j.parent.is_none() {
                    writeln!(w, "{indent}\tCHANNELS 6 Xposition Yposition Zposition {}", rot.join(" "))?;
                } else {
                    writeln!(w, "{indent}\tCHANNELS 3 {}", rot.join(" "))?;
                }
            }
        }
        match children.get(joint).and_then(|c| c.get(next_child)) {
            Some(&child) => {
                top.2 += 1;
                stack.push((child, depth + 1, 0));
            }
            None => {
                writeln!(w, "{indent}}}")?;
                stack.pop();
            }
        }
    }

    writeln!(w, "MOTION")?;
    writeln!(w, "Frames: {}", motion.frame_count())?;
    writeln!(w, "Frame Time: {}", 1.0 / motion.frame_rate_hz())?;
    let mut line = String::new();
    for frame in 0..motion.frame_count() {
        line.clear();
        let local = motion.local_rotations(frame);
        let p = motion.root_position_mm(frame) / mm;
        for v in [p.x, p.y, p.z] {
            push_value(&mut line, finite(v, "a root position")?);
        }
        for &joint in &text_order {
            let (Some(j), Some(q)) = (joints.get(joint), local.get(joint)) else {
                continue;
            };
            for a in j.rotation_order.from_quat_deg(q) {
                push_value(&mut line, finite(a, "a rotation")?);
            }
        }
        writeln!(w, "{line}")?;
    }
    Ok(())
}

fn push_value(line: &mut String, v: f64) {
    use std::fmt::Write as _;
    if !line.is_empty() {
        line.push(' ');
    }
    // Writing to a String cannot fail.
    let _ = write!(line, "{v}");
}

/// Writes a motion as a BVH file, atomically (see [`write_bvh`]).
pub fn write_bvh_path(motion: &Motion, unit: LengthUnit, path: &Path) -> Result<()> {
    write_atomically(path, |w| write_bvh(motion, unit, w))
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "HIERARCHY\r\nROOT Hips\r\n{\r\n\tOFFSET 1 2 3\r\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\r\n\tJOINT Spine\r\n\t{\r\n\t\tOFFSET 0 10 0\r\n\t\tCHANNELS 3 Xrotation Yrotation Zrotation\r\n\t\tEnd Site\r\n\t\t{\r\n\t\t\tOFFSET 0 5 0\r\n\t\t}\r\n\t}\r\n\tJOINT Fixed\r\n\t{\r\n\t\tOFFSET 1 0 0\r\n\t\tCHANNELS 0\r\n\t}\r\n}\r\nMOTION\r\nFrames: 2\r\nFrame Time: 0.0083333333\r\n1 2 3 90 0 0 0 0 0\r\n4 5 6 0 0 0 0 90 0\r\n\r\n";

    #[test]
    fn reads_a_small_file() {
        let m = read_bvh(SMALL, LengthUnit::Centimetre).unwrap();
        let names: Vec<&str> = m.skeleton.joints().iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["Hips", "Spine", "Spine_End", "Fixed"]);
        assert_eq!(m.frame_count(), 2);
        assert!((m.frame_rate_hz() - 120.0).abs() < 1e-6);
        let j = m.skeleton.joints();
        assert_eq!(j[0].offset_mm, Vec3::new(10.0, 20.0, 30.0));
        assert_eq!(j[1].rotation_order, EulerOrder::XYZ);
        assert!(j[2].is_end_site);
        assert_eq!(m.root_position_mm(1), Vec3::new(40.0, 50.0, 60.0));
        // Frame 0: the root turns 90 degrees about Z, so the spine tip (0, 150, 0) goes to -X.
        let pose = m.forward_kinematics(0);
        assert!((pose.positions_mm[2] - Vec3::new(10.0 - 150.0, 20.0, 30.0)).norm() < 1e-9);
        // Frame 1: the spine turns about Y, which does not move its tip on the Y axis.
        let pose = m.forward_kinematics(1);
        assert!((pose.positions_mm[2] - Vec3::new(40.0, 200.0, 60.0)).norm() < 1e-9);
    }

    #[test]
    fn frame_count_must_match() {
        let more = SMALL.replace("Frames: 2", "Frames: 3");
        match read_bvh(&more, LengthUnit::Millimetre) {
            Err(Error::Text { line, .. }) => assert_eq!(line, 27),
            other => panic!("{other:?}"),
        }
        let fewer = SMALL.replace("Frames: 2", "Frames: 1");
        match read_bvh(&fewer, LengthUnit::Millimetre) {
            Err(Error::Text { line, .. }) => assert_eq!(line, 25),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn bad_values_name_line_and_column() {
        let bad = SMALL.replace("4 5 6 0", "4 5 x 0");
        match read_bvh(&bad, LengthUnit::Millimetre) {
            Err(Error::Text { line: 25, column: Some(5), .. }) => {}
            other => panic!("{other:?}"),
        }
        let short = SMALL.replace("4 5 6 0 0 0 0 90 0", "4 5 6 0 0 0 0 90");
        assert!(matches!(read_bvh(&short, LengthUnit::Millimetre), Err(Error::Text { line: 25, .. })));
        let nan = SMALL.replace("4 5 6 0", "4 5 NaN 0");
        assert!(matches!(read_bvh(&nan, LengthUnit::Millimetre), Err(Error::Text { line: 25, .. })));
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        let cut_at: Vec<usize> = SMALL.char_indices().map(|(i, _)| i).collect();
        for &i in &cut_at {
            let r = read_bvh(&SMALL[..i], LengthUnit::Millimetre);
            // A cut inside the last motion line can still be a valid file only if it ends on
            // a complete number sequence, which the frame count forbids for all but the end.
            if let Err(e) = r {
                assert!(matches!(e, Error::Text { .. }), "cut at {i}: {e:?}");
            }
        }
    }

    #[test]
    fn multibyte_channel_names_are_errors() {
        let bad = SMALL.replace("CHANNELS 3 Xrotation", "CHANNELS 3 \u{3451}zrotation");
        match read_bvh(&bad, LengthUnit::Millimetre) {
            Err(Error::Text { line: 9, message, .. }) => assert!(message.contains("unknown channel"), "{message}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn non_root_positions_are_unsupported() {
        let bad = SMALL.replace("CHANNELS 3 Xrotation", "CHANNELS 3 Xposition");
        assert!(matches!(read_bvh(&bad, LengthUnit::Millimetre), Err(Error::Unsupported(_))));
    }

    #[test]
    fn duplicate_names_are_text_errors() {
        let bad = SMALL.replace("JOINT Fixed", "JOINT Spine");
        assert!(matches!(read_bvh(&bad, LengthUnit::Millimetre), Err(Error::Text { line: 15, .. })));
    }

    #[test]
    fn write_then_read_is_identity() {
        let m = read_bvh(SMALL, LengthUnit::Centimetre).unwrap();
        let mut out = Vec::new();
        write_bvh(&m, LengthUnit::Centimetre, &mut out).unwrap();
        let back = read_bvh(std::str::from_utf8(&out).unwrap(), LengthUnit::Centimetre).unwrap();
        assert_eq!(back.skeleton.len(), m.skeleton.len());
        for (a, b) in back.skeleton.joints().iter().zip(m.skeleton.joints()) {
            assert_eq!(a.name, b.name);
            assert!((a.offset_mm - b.offset_mm).norm() < 1e-9);
        }
        assert!((back.frame_rate_hz() - m.frame_rate_hz()).abs() < 1e-9);
        for f in 0..m.frame_count() {
            for (a, b) in back.local_rotations(f).iter().zip(m.local_rotations(f)) {
                assert!(a.angle_to(b) < 1e-9);
            }
        }
    }
}
