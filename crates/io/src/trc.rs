//! TRC: the marker text format of Motion Analysis (Cortex / EVaRT) that OpenSim adopted.
//!
//! # Layout
//! ```text
//! PathFileType  4  (X/Y/Z)  walk.trc
//! DataRate  CameraRate  NumFrames  NumMarkers  Units  OrigDataRate  OrigDataStartFrame  OrigNumFrames
//! 100       100         238        41          mm     100           1                   238
//! Frame#  Time  R.ASIS        L.ASIS        ...
//!               X1  Y1  Z1    X2  Y2  Z2    ...
//! (blank)
//! 1       0.00  12.3 4.5 6.7  ...
//! ```
//! Fields are tab-separated; a missing sample is three empty fields, and rows may simply stop
//! early when the last markers are missing.
//!
//! # Choices made when reading (all seen in real exporters' files)
//! - **Header by name, not position.** The key line and the values line are split on any
//!   whitespace and paired in order, because some writers put doubled tabs or padding spaces
//!   between values. Only `DataRate` and `Units` are required; `Units` may be mm, cm, m (or
//!   inches) and every coordinate is converted to millimetres.
//! - **Markers come from the columns, not from `NumMarkers`.** Cortex appends unlabeled
//!   markers as extra column triples after the named ones without naming them, and its
//!   `NumMarkers` then matches neither the names nor the columns (`Gait.trc` declares 66,
//!   names 33 and has data in 105 triples). Dropping those columns would silently lose data,
//!   so every named triple becomes a marker (even if it never has data), and every unnamed
//!   triple that holds data anywhere becomes an unlabeled marker `*N`, `N` being the triple's
//!   1-based number as in the `XN YN ZN` line (the vendors' convention for unlabeled points).
//!   Unnamed triples that are empty in every row (trailing tabs) are not markers. A mismatch
//!   with `NumMarkers` is reported in [`TrcFile::notes`].
//! - **Missing samples** are empty fields, absent fields (short rows), or `NaN`. A sample
//!   with one or two of its three coordinates missing is an error rather than a guess: it
//!   cannot be represented without inventing or dropping a coordinate.
//! - **Frames.** The first `Frame#` becomes [`Take::first_frame`] (`OrigDataStartFrame` if
//!   there are no rows); frame numbers must then
//!   increase by one per row (a jump means rows were lost or edited, which locap will not
//!   paper over). `Time` is checked to be a number but not used: the frame rate is `DataRate`.
//! - **`NumFrames` versus rows.** Fewer rows than declared is an error at the end of the file
//!   (the file was almost certainly cut short, and reading it quietly would lose the end of
//!   the take). More rows than declared are all read, since no data is lost that way, and the
//!   discrepancy is reported in [`TrcFile::notes`].
//! - Blank lines are skipped; CRLF and LF both work; a UTF-8 byte order mark is ignored. Files
//!   read from disk that are not UTF-8 are decoded as Latin-1 (older Windows exporters), which
//!   cannot fail and keeps accented marker names.
//!
//! # Writing
//! All columns of every row are written (empty fields for missing samples, or `NaN` with
//! [`Missing::NaN`], which OpenSim needs) so the file lines up in a spreadsheet. Coordinates get enough decimals for a resolution of 10⁻⁵ mm in any
//! unit (5 in mm, 8 in m): far below any capture system's noise, so a round trip loses
//! nothing measurable. `Time` is `(Frame# - 1) / DataRate`, the Cortex / OpenSim convention.

use crate::atomic::write_atomically;
use crate::limits::{self, Limits};
use crate::{Error, Result};
use locap_core::{LengthUnit, MarkerName, Take, Vec3};
use std::io::Write;
use std::path::Path;

const FORMAT: &str = "TRC";

/// A TRC file as read: the take plus what the header said, for writing it back the same way.
#[derive(Debug, Clone, PartialEq)]
pub struct TrcFile {
    /// The marker data, in millimetres.
    pub take: Take,
    /// The unit the file used (`Units`).
    pub unit: LengthUnit,
    /// `NumFrames` of the header, if present.
    pub declared_frames: Option<usize>,
    /// `NumMarkers` of the header, if present.
    pub declared_markers: Option<usize>,
    /// Discrepancies that were resolved without losing data (see the module documentation),
    /// each naming the line it concerns; worth showing to the user.
    pub notes: Vec<String>,
}

/// Reads a TRC file's text into a [`Take`] in millimetres. See [`read_trc_file`] for the
/// header's unit and the notes on discrepancies.
pub fn read_trc(text: &str) -> Result<Take> {
    read_trc_file(text).map(|file| file.take)
}

/// Reads a TRC file from disk into a [`Take`]; errors name the file.
pub fn read_trc_path(path: &Path) -> Result<Take> {
    read_trc_file_path(path).map(|file| file.take)
}

/// Reads a TRC file from disk, keeping its unit and notes; errors name the file.
pub fn read_trc_file_path(path: &Path) -> Result<TrcFile> {
    read_trc_file_path_with(path, &Limits::default())
}

/// [`read_trc_file_path`] with explicit [`Limits`]. A path that is not a regular file (a
/// named pipe, a device, a directory) is refused before it is opened.
pub fn read_trc_file_path_with(path: &Path, limits: &Limits) -> Result<TrcFile> {
    let bytes = limits::read_file(path, limits)?;
    read_trc_file_with(&decode_text(bytes), limits).map_err(|e| e.in_file(path))
}

/// Decodes a text file: UTF-8 if it is, Latin-1 otherwise (every byte is a Latin-1 character,
/// so this cannot fail, and old Windows exporters wrote accented names that way).
pub(crate) fn decode_text(bytes: Vec<u8>) -> String {
    match String::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => e.into_bytes().iter().map(|&b| char::from(b)).collect(),
    }
}

/// Reads a TRC file's text, keeping the header's unit and declared counts.
pub fn read_trc_file(text: &str) -> Result<TrcFile> {
    read_trc_file_with(text, &Limits::default())
}

/// [`read_trc_file`] with explicit [`Limits`]: frames × markers are checked before the take is
/// allocated, and since rows may stop after their last visible marker, the take may hold at
/// most one sample per byte of text (see [`crate::limits`]).
pub fn read_trc_file_with(text: &str, limits: &Limits) -> Result<TrcFile> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // Lines keep their 1-based number for error messages; `split('\n')` plus stripping `\r`
    // handles LF and CRLF files alike.
    let lines: Vec<(usize, &str)> =
        text.split('\n').map(|l| l.strip_suffix('\r').unwrap_or(l)).enumerate().map(|(i, l)| (i + 1, l)).collect();
    let line_at = |n: usize| lines.get(n - 1).map(|&(_, l)| l);

    // Line 1: PathFileType.
    let first = line_at(1).unwrap_or("");
    if first.trim().is_empty() {
        return Err(Error::text(FORMAT, 1, "the file is empty (a TRC file starts with a `PathFileType` line)"));
    }
    if !first.trim_start().to_ascii_lowercase().starts_with("pathfiletype") {
        return Err(Error::text(
            FORMAT,
            1,
            format!("not a TRC file: expected `PathFileType`, found `{}`", snippet(first)),
        ));
    }

    // Lines 2 and 3: keys and values.
    let keys = match line_at(2) {
        Some(l) if !l.trim().is_empty() => tokens(l),
        _ => {
            return Err(truncated_header(2, "the key line (`DataRate CameraRate NumFrames ...`)"));
        }
    };
    let values_line = match line_at(3) {
        Some(l) if !l.trim().is_empty() => l,
        _ => return Err(truncated_header(3, "the header values line")),
    };
    let values = tokens(values_line);
    let header = Header { keys: &keys, values: &values, line: values_line };

    let rate_text = header.required("DataRate")?;
    let frame_rate_hz = match rate_text.1.parse::<f64>() {
        Ok(r) if r.is_finite() && r > 0.0 => r,
        _ => {
            return Err(at(
                3,
                rate_text.0,
                values_line,
                format!("DataRate `{}` is not a positive number", rate_text.1),
            ));
        }
    };
    let unit_text = header.required("Units")?;
    let unit = LengthUnit::parse(unit_text.1).ok_or_else(|| {
        at(3, unit_text.0, values_line, format!("unknown Units `{}` (expected mm, cm or m)", unit_text.1))
    })?;
    let declared_frames = header.count("NumFrames")?;
    let declared_markers = header.count("NumMarkers")?;

    // Line 4: `Frame# Time name...`.
    let names_line = match line_at(4) {
        Some(l) if !l.trim().is_empty() => l,
        _ => return Err(truncated_header(4, "the `Frame# Time <marker names>` line")),
    };
    let name_fields = fields(names_line);
    match name_fields.first() {
        Some((_, f)) if f.eq_ignore_ascii_case("Frame#") => {}
        _ => {
            return Err(at(
                4,
                0,
                names_line,
                format!("expected the `Frame# Time <marker names>` line, found `{}`", snippet(names_line)),
            ));
        }
    }
    let slots = name_slots(&name_fields);

    // Line 5 is `X1 Y1 Z1 ...`, unless a writer left it out and data starts right away.
    let mut data_start = 5;
    if let Some(l) = line_at(5)
        && !starts_with_frame_number(l)
    {
        data_start = 6;
    }

    // Data rows.
    let mut rows: Vec<Vec<Option<Vec3>>> = Vec::new();
    let mut first_frame: Option<u64> = None;
    let mut previous: Option<(u64, usize)> = None;
    let mut last_line = 4;
    let scale = unit.mm_per_unit();
    for &(n, line) in lines.iter().skip(data_start - 1) {
        last_line = n;
        if line.trim().is_empty() {
            continue;
        }
        let row = fields(line);
        let frame = parse_frame_number(row.first().copied(), n, line)?;
        if let Some((prev, prev_line)) = previous {
            if Some(frame) != prev.checked_add(1) {
                return Err(at(
                    n,
                    0,
                    line,
                    format!(
                        "Frame# {frame} follows Frame# {prev} (line {prev_line}); frames must be \
                         consecutive, rows may have been lost or reordered"
                    ),
                ));
            }
        } else {
            first_frame = Some(frame);
        }
        previous = Some((frame, n));
        if let Some(&(offset, time)) = row.get(1)
            && !time.is_empty()
            && time.parse::<f64>().is_err()
        {
            return Err(at(n, offset, line, format!("Time `{}` is not a number", snippet(time))));
        }
        rows.push(parse_samples(row.get(2..).unwrap_or(&[]), scale, n, line)?);
    }
    let frames = rows.len();

    if let Some(declared) = declared_frames
        && frames < declared
    {
        return Err(Error::text(
            FORMAT,
            last_line,
            format!(
                "the file ends after {frames} data rows but the header (line 3) declares \
                 NumFrames {declared}: it was probably cut short"
            ),
        ));
    }

    // Markers: named triples, then unnamed triples that hold data.
    let triples = rows.iter().map(Vec::len).max().unwrap_or(0).max(slots.len());
    let mut has_data = vec![false; triples];
    for row in &rows {
        for (t, sample) in row.iter().enumerate() {
            if sample.is_some()
                && let Some(flag) = has_data.get_mut(t)
            {
                *flag = true;
            }
        }
    }
    let mut markers = Vec::new();
    // `column_of[marker]` is the triple the marker is read from.
    let mut column_of = Vec::new();
    for (t, data) in has_data.iter().enumerate() {
        match slots.get(t).and_then(Option::as_ref) {
            Some(name) => markers.push(MarkerName::parse(name)),
            None if *data => markers.push(MarkerName::parse(&format!("*{}", t + 1))),
            None => continue,
        }
        column_of.push(t);
    }
    let named = slots.iter().filter(|s| s.is_some()).count();

    limits.check_text_samples(FORMAT, frames, markers.len(), "markers", text.len())?;
    let mut take = Take::empty(markers, frames, frame_rate_hz)?;
    for (f, row) in rows.iter().enumerate() {
        for (m, &t) in column_of.iter().enumerate() {
            if let Some(Some(p)) = row.get(t) {
                take.set_position_mm(f, m, Some(*p))?;
            }
        }
    }
    match first_frame {
        Some(first) => {
            take.first_frame = u32::try_from(first)
                .map_err(|_| Error::text(FORMAT, data_start, format!("first Frame# {first} is too large")))?;
        }
        // Without rows, the header's start frame is the only record of the numbering (and
        // what `write_trc` puts there), so an empty take keeps it through a round trip.
        None => {
            if let Some(Ok(start)) = header.get("OrigDataStartFrame").map(|(_, v)| v.parse::<u32>()) {
                take.first_frame = start;
            }
        }
    }

    let mut notes = Vec::new();
    if let Some(declared) = declared_frames
        && frames > declared
    {
        notes.push(format!(
            "header (line 3) declares NumFrames {declared} but the file has {frames} data rows; \
             all rows were read"
        ));
    }
    let read_markers = take.marker_count();
    if let Some(declared) = declared_markers
        && declared != read_markers
    {
        notes.push(format!(
            "header (line 3) declares NumMarkers {declared}; line 4 names {named} markers and \
             {read_markers} were read ({} unlabeled, from unnamed columns holding data)",
            read_markers.saturating_sub(named.min(read_markers))
        ));
    }
    Ok(TrcFile { take, unit, declared_frames, declared_markers, notes })
}

/// Writes `take` as TRC text with coordinates in `unit`.
pub fn write_trc(take: &Take, unit: LengthUnit, w: &mut dyn Write) -> Result<()> {
    write_trc_named(take, unit, Missing::Empty, "locap.trc", w)
}

/// Writes `take` as a TRC file at `path`, atomically (see [`crate::atomic`]).
pub fn write_trc_path(take: &Take, unit: LengthUnit, path: &Path) -> Result<()> {
    write_trc_path_with(take, unit, Missing::Empty, path)
}

/// How a missing sample is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Missing {
    /// Three empty fields, the Motion Analysis convention (and what this reader reads best).
    #[default]
    Empty,
    /// `NaN` three times: OpenSim 4.6's TRC reader refuses a row that ends in empty fields
    /// (it counts one column too few), so files for OpenSim need this when the last markers
    /// can be missing.
    NaN,
}

/// [`write_trc_path`] with missing samples written as `missing`.
pub fn write_trc_path_with(take: &Take, unit: LengthUnit, missing: Missing, path: &Path) -> Result<()> {
    // The PathFileType line conventionally carries the file's own name.
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    write_atomically(path, |w| write_trc_named(take, unit, missing, &name, w))
}

fn write_trc_named(take: &Take, unit: LengthUnit, missing: Missing, file_name: &str, w: &mut dyn Write) -> Result<()> {
    let names: Vec<String> = take.markers().iter().map(MarkerName::full).collect();
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            return Err(Error::Unwritable(format!("TRC: marker {i} has an empty name")));
        }
        if name.contains(['\t', '\n', '\r']) {
            return Err(Error::Unwritable(format!(
                "TRC: marker name {name:?} contains a tab or line break, which TRC cannot hold"
            )));
        }
    }
    // A tab or line break in the file name would break the first line; it is informational.
    let file_name: String = file_name.chars().map(|c| if c.is_control() { '_' } else { c }).collect();
    let rate = take.frame_rate_hz();
    let frames = take.frame_count();
    let markers = take.marker_count();
    let symbol = unit.symbol();
    let first = take.first_frame;
    writeln!(w, "PathFileType\t4\t(X/Y/Z)\t{file_name}")?;
    writeln!(w, "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames")?;
    // `{}` prints the shortest text that parses back to the same f64, so the rate is exact.
    writeln!(w, "{rate}\t{rate}\t{frames}\t{markers}\t{symbol}\t{rate}\t{first}\t{frames}")?;
    let mut line = String::from("Frame#\tTime");
    for name in &names {
        line.push('\t');
        line.push_str(name);
        line.push_str("\t\t");
    }
    writeln!(w, "{line}")?;
    line.clear();
    line.push('\t');
    for m in 1..=markers {
        line.push_str(&format!("\tX{m}\tY{m}\tZ{m}"));
    }
    writeln!(w, "{line}")?;
    writeln!(w)?;
    let decimals = decimals_for(unit);
    let scale = 1.0 / unit.mm_per_unit();
    for f in 0..frames {
        line.clear();
        let frame_number = u64::from(first) + f as u64;
        line.push_str(&format!("{frame_number}\t{:.6}", frame_time_s(first, f, rate)));
        for m in 0..markers {
            match take.position_mm(f, m) {
                Some(p) => {
                    let p = p * scale;
                    line.push_str(&format!("\t{:.d$}\t{:.d$}\t{:.d$}", p.x, p.y, p.z, d = decimals));
                }
                None => line.push_str(match missing {
                    Missing::Empty => "\t\t\t",
                    Missing::NaN => "\tNaN\tNaN\tNaN",
                }),
            }
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

/// Time of the `index`-th frame of a take starting at frame `first_frame`: `(Frame# - 1) /
/// rate`, the Cortex / OpenSim convention (frame 1 at 0 s); takes counting from frame 0 also
/// start at 0 s rather than at a negative time.
pub(crate) fn frame_time_s(first_frame: u32, index: usize, rate_hz: f64) -> f64 {
    (f64::from(first_frame.saturating_sub(1)) + index as f64) / rate_hz
}

/// Decimals that give a resolution of at most 10⁻⁵ mm in `unit`.
fn decimals_for(unit: LengthUnit) -> usize {
    match unit {
        LengthUnit::Millimetre => 5,
        LengthUnit::Centimetre => 6,
        LengthUnit::Inch => 7,
        LengthUnit::Metre => 8,
    }
}

/// Parses one coordinate text: `Ok(None)` for a missing one (empty or any spelling of NaN),
/// an error message for text that is not a finite number.
pub(crate) fn parse_coordinate(text: &str) -> std::result::Result<Option<f64>, String> {
    let text = text.trim();
    if text.is_empty() || text.trim_start_matches(['+', '-']).eq_ignore_ascii_case("nan") {
        return Ok(None);
    }
    match text.parse::<f64>() {
        Ok(v) if v.is_nan() => Ok(None),
        Ok(v) if v.is_finite() => Ok(Some(v)),
        Ok(_) => Err(format!("coordinate `{}` is not finite", snippet(text))),
        Err(_) => Err(format!("coordinate `{}` is not a number", snippet(text))),
    }
}

/// Combines three parsed coordinates into a sample: all missing is a missing sample; some but
/// not all missing is an error naming the first missing axis (index into the triple).
pub(crate) fn combine_xyz(xyz: [Option<f64>; 3]) -> std::result::Result<Option<Vec3>, usize> {
    match xyz {
        [Some(x), Some(y), Some(z)] => Ok(Some(Vec3::new(x, y, z))),
        [None, None, None] => Ok(None),
        _ => Err(xyz.iter().position(Option::is_none).unwrap_or(0)),
    }
}

/// Parses the coordinate fields of one row (after Frame# and Time), scaled to millimetres.
/// Trailing missing samples are dropped, since absent and missing mean the same.
fn parse_samples(cells: &[(usize, &str)], scale: f64, n: usize, line: &str) -> Result<Vec<Option<Vec3>>> {
    let mut samples = Vec::with_capacity(cells.len().div_ceil(3));
    for (t, triple) in cells.chunks(3).enumerate() {
        let mut xyz = [None; 3];
        for (axis, &(offset, text)) in triple.iter().enumerate() {
            let value = parse_coordinate(text)
                .map_err(|msg| at(n, offset, line, format!("{} of marker column {}: {msg}", AXES[axis % 3], t + 1)))?;
            if let (Some(v), Some(slot)) = (value, xyz.get_mut(axis)) {
                let mm = v * scale;
                if !mm.is_finite() {
                    return Err(at(n, offset, line, format!("coordinate `{}` is too large", snippet(text))));
                }
                *slot = Some(mm);
            }
        }
        let sample = combine_xyz(xyz).map_err(|axis| {
            let offset = triple.first().map_or(0, |c| c.0);
            at(
                n,
                offset,
                line,
                format!(
                    "marker column {} has some coordinates but not {}: a sample must be complete \
                     or entirely missing",
                    t + 1,
                    AXES[axis % 3]
                ),
            )
        })?;
        samples.push(sample);
    }
    while samples.last().is_some_and(Option::is_none) {
        samples.pop();
    }
    Ok(samples)
}

const AXES: [&str; 3] = ["X", "Y", "Z"];

/// Which name each column triple has: `slots[t]` is the name of triple `t` (0-based), if any.
///
/// Standard files put each name above its X column, followed by two empty columns; a few
/// writers put the names one per column. Names all at multiples of three are read by
/// position (so an unnamed triple between named ones stays unnamed); otherwise in order.
fn name_slots(fields: &[(usize, &str)]) -> Vec<Option<String>> {
    let names: Vec<(usize, &str)> =
        fields.iter().skip(2).enumerate().filter(|(_, (_, f))| !f.is_empty()).map(|(i, (_, f))| (i, *f)).collect();
    let aligned = names.iter().all(|(i, _)| i % 3 == 0);
    let mut slots: Vec<Option<String>> = Vec::new();
    for (order, (i, name)) in names.iter().enumerate() {
        let slot = if aligned { i / 3 } else { order };
        if slots.len() <= slot {
            slots.resize(slot + 1, None);
        }
        if let Some(s) = slots.get_mut(slot) {
            *s = Some((*name).to_string());
        }
    }
    slots
}

/// Header values looked up by key.
struct Header<'a> {
    keys: &'a [(usize, &'a str)],
    values: &'a [(usize, &'a str)],
    line: &'a str,
}

impl Header<'_> {
    /// The value (byte offset, text) under `key`, if the key and its value are present.
    fn get(&self, key: &str) -> Option<(usize, &str)> {
        let i = self.keys.iter().position(|(_, k)| k.eq_ignore_ascii_case(key))?;
        self.values.get(i).copied()
    }

    fn required(&self, key: &str) -> Result<(usize, &str)> {
        self.get(key).ok_or_else(|| {
            let line = if self.keys.iter().any(|(_, k)| k.eq_ignore_ascii_case(key)) { 3 } else { 2 };
            Error::text(FORMAT, line, format!("the header has no {key} value"))
        })
    }

    /// An optional count such as `NumFrames`; present but not a count is an error.
    fn count(&self, key: &str) -> Result<Option<usize>> {
        match self.get(key) {
            None => Ok(None),
            Some((offset, text)) => text
                .parse::<usize>()
                .map(Some)
                .map_err(|_| at(3, offset, self.line, format!("{key} `{}` is not a count", snippet(text)))),
        }
    }
}

/// Whitespace-separated tokens with their byte offsets.
fn tokens(line: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, c) in line.char_indices() {
        match (c.is_whitespace(), start) {
            (true, Some(s)) => {
                out.push((s, line.get(s..i).unwrap_or("")));
                start = None;
            }
            (false, None) => start = Some(i),
            _ => {}
        }
    }
    if let Some(s) = start {
        out.push((s, line.get(s..).unwrap_or("")));
    }
    out
}

/// A row's fields, trimmed, with the byte offset where each starts. Tab-separated as the
/// format says; a line without any tab is split on whitespace, as a few writers use spaces.
fn fields(line: &str) -> Vec<(usize, &str)> {
    if !line.contains('\t') {
        return tokens(line);
    }
    let mut out = Vec::new();
    let mut offset = 0;
    for field in line.split('\t') {
        let trimmed = field.trim_start();
        out.push((offset + field.len() - trimmed.len(), trimmed.trim_end()));
        offset += field.len() + 1;
    }
    out
}

fn starts_with_frame_number(line: &str) -> bool {
    line.trim_start().starts_with(|c: char| c.is_ascii_digit())
}

fn parse_frame_number(field: Option<(usize, &str)>, n: usize, line: &str) -> Result<u64> {
    let (offset, text) = field.unwrap_or((0, ""));
    if let Ok(v) = text.parse::<u64>() {
        return Ok(v);
    }
    // Some writers print frame numbers as floats (`12.0`).
    match text.parse::<f64>() {
        Ok(v) if v.fract() == 0.0 && (0.0..=u32::MAX as f64).contains(&v) => Ok(v as u64),
        _ => Err(at(n, offset, line, format!("Frame# `{}` is not a frame number", snippet(text)))),
    }
}

fn truncated_header(line: usize, what: &str) -> Error {
    Error::text(FORMAT, line, format!("the header is incomplete: expected {what} here"))
}

/// A text error at byte `offset` of `line_text`, with its 1-based character column.
fn at(line: usize, offset: usize, line_text: &str, message: String) -> Error {
    let column = line_text.get(..offset).map_or(1, |s| s.chars().count() + 1);
    Error::Text { format: FORMAT, line, column: Some(column), message }
}

/// At most 40 characters of `text`, for messages.
pub(crate) fn snippet(text: &str) -> String {
    let mut s: String = text.chars().take(40).collect();
    if s.len() < text.len() {
        s.push('…');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "PathFileType\t4\t(X/Y/Z)\tsmall.trc\n\
        DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n\
        100\t100\t3\t2\tm\t100\t10\t3\n\
        Frame#\tTime\tS:A\t\t\tB\t\t\n\
        \t\tX1\tY1\tZ1\tX2\tY2\tZ2\n\
        \n\
        10\t0.09\t0.001\t0.002\t0.003\t1\t2\t3\n\
        11\t0.10\t\t\t\t4\t5\t6\n\
        12\t0.11\t0.004\t0.005\t0.006\n";

    fn line_of(err: Error) -> (usize, Option<usize>) {
        match err {
            Error::Text { line, column, .. } => (line, column),
            other => panic!("expected a text error, got {other}"),
        }
    }

    #[test]
    fn reads_units_missing_samples_and_frame_numbers() {
        let file = read_trc_file(SMALL).unwrap();
        let take = &file.take;
        assert_eq!(file.unit, LengthUnit::Metre);
        assert_eq!((take.frame_count(), take.marker_count()), (3, 2));
        assert_eq!(take.first_frame, 10);
        assert_eq!(take.markers()[0].subject.as_deref(), Some("S"));
        assert_eq!(take.frame_rate_hz(), 100.0);
        let p = take.position_mm(0, 0).unwrap();
        assert!((p - Vec3::new(1.0, 2.0, 3.0)).norm() < 1e-9);
        assert_eq!(take.position_mm(1, 0), None);
        assert!(file.notes.is_empty());
        assert_eq!(take.position_mm(2, 1), None, "short row: trailing markers missing");
    }

    #[test]
    fn partial_sample_is_an_error_with_position() {
        let err = read_trc(SMALL.replace("4\t5\t6", "4\t\t6").as_str()).unwrap_err();
        assert_eq!(line_of(err).0, 8);
    }

    #[test]
    fn nan_triples_are_missing() {
        let text = SMALL.replace("\t\t\t\t4", "\tnan\tNaN\t-nan\t4");
        let take = read_trc(&text).unwrap();
        assert_eq!(take.position_mm(1, 0), None);
        assert!(take.position_mm(1, 1).is_some());
    }

    #[test]
    fn truncated_and_bad_headers_name_their_line() {
        assert_eq!(line_of(read_trc("").unwrap_err()).0, 1);
        assert_eq!(line_of(read_trc("hello\n").unwrap_err()).0, 1);
        assert_eq!(line_of(read_trc("PathFileType\t4\n").unwrap_err()).0, 2);
        let two = "PathFileType\t4\nDataRate\tUnits\n";
        assert_eq!(line_of(read_trc(two).unwrap_err()).0, 3);
        let bad_unit = "PathFileType\t4\nDataRate\tUnits\n100\tfurlong\n";
        assert_eq!(line_of(read_trc(bad_unit).unwrap_err()), (3, Some(5)));
        let bad_rate = "PathFileType\t4\nDataRate\tUnits\n-1\tmm\nFrame#\tTime\n";
        assert_eq!(line_of(read_trc(bad_rate).unwrap_err()).0, 3);
    }

    #[test]
    fn fewer_rows_than_declared_is_an_error_more_is_a_note() {
        let cut = SMALL.rsplit_once("12\t").unwrap().0;
        assert_eq!(line_of(read_trc(cut).unwrap_err()).0, 9);
        let more = format!("{SMALL}13\t0.12\n");
        let file = read_trc_file(&more).unwrap();
        assert_eq!(file.take.frame_count(), 4);
        assert_eq!(file.notes.len(), 1);
    }

    #[test]
    fn frame_jumps_are_errors() {
        let text = SMALL.replace("12\t0.11", "14\t0.13");
        assert_eq!(line_of(read_trc(&text).unwrap_err()).0, 9);
    }

    #[test]
    fn unnamed_columns_with_data_become_unlabeled_markers() {
        let text = SMALL.replace("12\t0.11\t0.004\t0.005\t0.006", "12\t0.11\t\t\t\t\t\t\t\t\t\t7\t8\t9\t\t");
        let file = read_trc_file(&text).unwrap();
        let names: Vec<String> = file.take.markers().iter().map(MarkerName::full).collect();
        assert_eq!(names, ["S:A", "B", "*4"]);
        assert!(file.take.markers()[2].is_unlabeled());
        assert_eq!(file.take.position_mm(2, 2), Some(Vec3::new(7000.0, 8000.0, 9000.0)));
        assert_eq!(file.notes.len(), 1, "NumMarkers 2 but 3 read");
    }

    #[test]
    fn padded_header_values_pair_by_order() {
        // As in OpenSim's Rajagopal walk file: doubled tabs and padding in the values line.
        let text =
            SMALL.replace("100\t100\t3\t2\tm\t100\t10\t3", "  100.0\t\t  100.0\t\t    3\t\t     2\t\t m\t 1\t 1\t 3");
        assert_eq!(read_trc(&text).unwrap().frame_rate_hz(), 100.0);
    }

    #[test]
    fn writes_and_reads_back() {
        let take = read_trc(SMALL).unwrap();
        for unit in [LengthUnit::Millimetre, LengthUnit::Metre, LengthUnit::Centimetre, LengthUnit::Inch] {
            let mut out = Vec::new();
            write_trc(&take, unit, &mut out).unwrap();
            let back = read_trc_file(std::str::from_utf8(&out).unwrap()).unwrap();
            assert_eq!(back.unit, unit);
            assert!(back.notes.is_empty(), "{:?}", back.notes);
            assert_eq!(back.take.markers(), take.markers());
            assert_eq!(back.take.first_frame, 10);
            assert_eq!(back.take.validity(), take.validity());
            for f in 0..take.frame_count() {
                for m in 0..take.marker_count() {
                    if let (Some(a), Some(b)) = (take.position_mm(f, m), back.take.position_mm(f, m)) {
                        assert!((a - b).norm() < 1e-4);
                    }
                }
            }
        }
    }

    #[test]
    fn missing_samples_as_nan_read_back_missing() {
        let take = read_trc(SMALL).unwrap();
        assert!(take.missing_count() > 0);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("nan.trc");
        write_trc_path_with(&take, LengthUnit::Metre, Missing::NaN, &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("\tNaN\tNaN\tNaN") && !text.lines().skip(6).any(|l| l.ends_with('\t')), "{text}");
        assert_eq!(read_trc(&text).unwrap().validity(), take.validity());
    }

    #[test]
    fn unwritable_names_are_refused() {
        let take = Take::empty(vec![MarkerName::parse("a\tb")], 1, 60.0).unwrap();
        assert!(matches!(write_trc(&take, LengthUnit::Millimetre, &mut Vec::new()), Err(Error::Unwritable(_))));
        let take = Take::empty(vec![MarkerName::parse("")], 1, 60.0).unwrap();
        assert!(matches!(write_trc(&take, LengthUnit::Millimetre, &mut Vec::new()), Err(Error::Unwritable(_))));
    }

    #[test]
    fn latin1_is_decoded() {
        assert_eq!(decode_text(b"Poign\xe9e".to_vec()), "Poignée");
        assert_eq!(decode_text("Poignée".as_bytes().to_vec()), "Poignée");
    }
}
