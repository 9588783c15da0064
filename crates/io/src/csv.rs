//! CSV: a plain marker table for spreadsheets and scripts, and back.
//!
//! # Layout
//! ```text
//! frame,time_s,Male:LFWT_x_mm,Male:LFWT_y_mm,Male:LFWT_z_mm,RBAC_x_mm,...
//! 1,0,12.3456,-7.8900,1001.0000,,,
//! ```
//! One row per frame; three columns per marker named after its full name (subject prefix
//! included) with the axis and unit in the column name, so a spreadsheet user never has to
//! guess the unit. A missing sample is three empty fields, never 0 or NaN.
//!
//! # Choices
//! - Fields are quoted as RFC 4180 says (only names containing a comma, quote or line break
//!   need it). Lines end in LF rather than RFC 4180's CRLF: every spreadsheet reads LF and line
//!   tools prefer it; the reader accepts both.
//! - Coordinates are written with 4 decimals in mm (0.1 µm), two orders of magnitude finer
//!   than optical capture noise, so nothing measurable is lost while files stay readable.
//! - `time_s` is `(frame - 1) / rate` (as in TRC) printed in the shortest form that parses
//!   back to the same `f64`, because the reader recovers the frame rate from it: a rate with
//!   at most six decimals comes back exactly, any other within rounding (parts in 10¹²).
//! - The reader accepts exactly this layout. Every row must have all the header's fields
//!   (a short row in a file without a frame count is the only sign of a cut-off file), frame
//!   numbers must be consecutive and times must follow one constant rate, so rows deleted in a
//!   spreadsheet are reported instead of silently shifting the rest of the take in time. At
//!   least two rows are needed, since one frame does not determine a frame rate.

use crate::atomic::write_atomically;
use crate::limits::{self, Limits};
use crate::trc::{combine_xyz, frame_time_s, parse_coordinate, snippet};
use crate::{Error, Result};
use locap_core::{MarkerName, Take, Vec3};
use std::io::Write;
use std::path::Path;

const FORMAT: &str = "CSV";
const AXES: [&str; 3] = ["x", "y", "z"];

/// Writes `take` as a CSV table (layout in the module documentation).
pub fn write_csv(take: &Take, w: &mut dyn Write) -> Result<()> {
    let mut line = String::from("frame,time_s");
    for marker in take.markers() {
        let name = marker.full();
        for axis in AXES {
            line.push(',');
            line.push_str(&quote(&format!("{name}_{axis}_mm")));
        }
    }
    line.push('\n');
    w.write_all(line.as_bytes())?;
    let rate = take.frame_rate_hz();
    for f in 0..take.frame_count() {
        line.clear();
        let frame_number = u64::from(take.first_frame) + f as u64;
        line.push_str(&format!("{frame_number},{}", frame_time_s(take.first_frame, f, rate)));
        for m in 0..take.marker_count() {
            match take.position_mm(f, m) {
                Some(p) => line.push_str(&format!(",{:.4},{:.4},{:.4}", p.x, p.y, p.z)),
                None => line.push_str(",,,"),
            }
        }
        line.push('\n');
        w.write_all(line.as_bytes())?;
    }
    Ok(())
}

/// Writes `take` as a CSV file at `path`, atomically (see [`crate::atomic`]).
pub fn write_csv_path(take: &Take, path: &Path) -> Result<()> {
    write_atomically(path, |w| write_csv(take, w))
}

/// Reads a table written by [`write_csv`] (or laid out the same way) into a [`Take`].
///
/// The frame rate is recovered from the `time_s` column and the first frame number from the
/// `frame` column. Errors carry the line and column.
pub fn read_csv(text: &str) -> Result<Take> {
    read_csv_with(text, &Limits::default())
}

/// [`read_csv`] with explicit [`Limits`] on frames and samples, checked row by row before the
/// row's samples are stored.
pub fn read_csv_with(text: &str, limits: &Limits) -> Result<Take> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut records = parse_records(text)?.into_iter().filter(|r| !r.is_blank());
    let header = records
        .next()
        .ok_or_else(|| Error::text(FORMAT, 1, "the file is empty (expected a `frame,time_s,...` header)"))?;
    let markers = parse_header(&header)?;
    let width = 2 + 3 * markers.len();

    let mut samples: Vec<Option<Vec3>> = Vec::new();
    // (frame number, time, line) of each row.
    let mut rows: Vec<(u64, f64, usize)> = Vec::new();
    for record in records {
        if record.fields.len() != width {
            return Err(Error::text(
                FORMAT,
                record.line,
                format!("row has {} fields but the header has {width}", record.fields.len()),
            ));
        }
        let frame_field = record.field(0)?;
        let frame =
            frame_field.text.trim().parse::<u64>().map_err(|_| {
                frame_field.error(format!("frame `{}` is not a frame number", snippet(&frame_field.text)))
            })?;
        if let Some(&(prev, _, prev_line)) = rows.last()
            && Some(frame) != prev.checked_add(1)
        {
            return Err(frame_field
                .error(format!("frame {frame} follows frame {prev} (line {prev_line}); frames must be consecutive")));
        }
        let time_field = record.field(1)?;
        let time = match time_field.text.trim().parse::<f64>() {
            Ok(t) if t.is_finite() => t,
            _ => {
                return Err(time_field.error(format!("time_s `{}` is not a number", snippet(&time_field.text))));
            }
        };
        rows.push((frame, time, record.line));
        limits.check_samples(FORMAT, rows.len(), markers.len(), "markers")?;
        for m in 0..markers.len() {
            let mut xyz = [None; 3];
            for (axis, slot) in xyz.iter_mut().enumerate() {
                let field = record.field(2 + 3 * m + axis)?;
                *slot = parse_coordinate(&field.text).map_err(|msg| field.error(msg))?;
            }
            let sample = combine_xyz(xyz).map_err(|axis| {
                let column = record.field(2 + 3 * m + axis).map_or(1, |f| f.column);
                Error::Text {
                    format: FORMAT,
                    line: record.line,
                    column: Some(column),
                    message: format!(
                        "marker {} has some coordinates but not {}: a sample must be complete or \
                     entirely missing",
                        markers.get(m).map(MarkerName::full).unwrap_or_default(),
                        AXES[axis % 3]
                    ),
                }
            })?;
            samples.push(sample);
        }
    }

    let rate = frame_rate(&rows, header.line)?;
    let first_frame = match rows.first() {
        Some(&(first, _, line)) => {
            u32::try_from(first).map_err(|_| Error::text(FORMAT, line, format!("first frame {first} is too large")))?
        }
        None => 1,
    };
    let mut take = Take::from_samples(markers, &samples, rate)?;
    take.first_frame = first_frame;
    Ok(take)
}

/// Reads a CSV file from disk; errors name the file.
pub fn read_csv_path(path: &Path) -> Result<Take> {
    read_csv_path_with(path, &Limits::default())
}

/// [`read_csv_path`] with explicit [`Limits`]. A path that is not a regular file (a named
/// pipe, a device, a directory) is refused before it is opened.
pub fn read_csv_path_with(path: &Path, limits: &Limits) -> Result<Take> {
    let bytes = limits::read_file(path, limits)?;
    read_csv_with(&crate::trc::decode_text(bytes), limits).map_err(|e| e.in_file(path))
}

/// The frame rate implied by the rows' times.
///
/// Each step between rows must be within half of the typical (median) step, so an edited time
/// is reported on its own line; the rate itself comes from the whole span, the most precise
/// estimate when times were printed with few decimals.
fn frame_rate(rows: &[(u64, f64, usize)], header_line: usize) -> Result<f64> {
    let (Some(&(_, t0, line0)), Some(&(_, t_last, line_last))) = (rows.first(), rows.last()) else {
        return Err(Error::text(FORMAT, header_line, "no data rows, so no frame rate"));
    };
    if rows.len() < 2 {
        return Err(Error::text(FORMAT, line0, "a single row does not determine the frame rate"));
    }
    let steps = || {
        rows.windows(2).filter_map(|w| match w {
            [(_, a, _), (_, b, line)] => Some((b - a, *line)),
            _ => None,
        })
    };
    let mut sorted: Vec<f64> = steps().map(|(d, _)| d).collect();
    sorted.sort_by(f64::total_cmp);
    let typical = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    for (step, line) in steps() {
        if !(typical > 0.0 && (step - typical).abs() <= 0.5 * typical) {
            return Err(Error::text(
                FORMAT,
                line,
                format!(
                    "time_s steps by {step} s here but typically by {typical} s: times must \
                     follow one constant frame rate"
                ),
            ));
        }
    }
    let mut rate = (rows.len() - 1) as f64 / (t_last - t0);
    // The times are exact to the last bit, so the estimate is off by rounding only. Rates are
    // normally round numbers (120, 59.94): snapping to the micro-hertz when that is within
    // rounding gives them back exactly rather than as 120.00000000000001.
    let snapped = (rate * 1e6).round() / 1e6;
    if (snapped - rate).abs() <= 1e-12 * rate {
        rate = snapped;
    }
    if !(rate.is_finite() && rate > 0.0) {
        return Err(Error::text(
            FORMAT,
            line_last,
            format!("time_s goes from {t0} to {t_last}: no positive frame rate"),
        ));
    }
    Ok(rate)
}

fn parse_header(header: &Record) -> Result<Vec<MarkerName>> {
    for (i, expected) in ["frame", "time_s"].into_iter().enumerate() {
        let field = header.field(i)?;
        if field.text.trim() != expected {
            return Err(field.error(format!(
                "expected `{expected}` (header `frame,time_s,<marker>_x_mm,...`), found `{}`",
                snippet(&field.text)
            )));
        }
    }
    let columns = header.fields.len().saturating_sub(2);
    if !columns.is_multiple_of(3) {
        return Err(Error::text(
            FORMAT,
            header.line,
            format!("{columns} marker columns is not a multiple of three (x, y, z per marker)"),
        ));
    }
    let mut markers = Vec::with_capacity(columns / 3);
    for m in 0..columns / 3 {
        let mut name: Option<String> = None;
        for (axis, label) in AXES.iter().enumerate() {
            let field = header.field(2 + 3 * m + axis)?;
            let suffix = format!("_{label}_mm");
            let this = field
                .text
                .strip_suffix(suffix.as_str())
                .ok_or_else(|| field.error(format!("column `{}` should end in `{suffix}`", snippet(&field.text))))?;
            match name {
                Some(n) if n != this => {
                    return Err(
                        field.error(format!("column `{}` does not continue marker `{n}`", snippet(&field.text)))
                    );
                }
                Some(_) => {}
                None => name = Some(this.to_string()),
            }
        }
        markers.push(MarkerName::parse(name.as_deref().unwrap_or("")));
    }
    Ok(markers)
}

/// Quotes a field if RFC 4180 requires it.
fn quote(field: &str) -> String {
    if field.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", field.replace('"', "\"\""))
    } else {
        field.to_string()
    }
}

/// One CSV record and where it starts.
struct Record {
    line: usize,
    fields: Vec<Field>,
}

/// One field, unquoted, with its 1-based line and column.
struct Field {
    text: String,
    line: usize,
    column: usize,
}

impl Field {
    fn error(&self, message: String) -> Error {
        Error::Text { format: FORMAT, line: self.line, column: Some(self.column), message }
    }
}

impl Record {
    fn is_blank(&self) -> bool {
        matches!(self.fields.as_slice(), [f] if f.text.trim().is_empty())
    }

    /// Field `i`, or an error on this record's line if the record is shorter.
    fn field(&self, i: usize) -> Result<&Field> {
        self.fields.get(i).ok_or_else(|| Error::text(FORMAT, self.line, format!("the row ends before field {}", i + 1)))
    }
}

/// Splits RFC 4180 text into records, following line numbers through quoted line breaks.
fn parse_records(text: &str) -> Result<Vec<Record>> {
    let mut records = Vec::new();
    let mut chars = text.chars().peekable();
    let (mut line, mut column) = (1usize, 1usize);
    while chars.peek().is_some() {
        let mut record = Record { line, fields: Vec::new() };
        loop {
            let mut field = Field { text: String::new(), line, column };
            let mut end_of_record = true;
            if chars.peek() == Some(&'"') {
                chars.next();
                column += 1;
                loop {
                    match chars.next() {
                        None => return Err(field.error("quoted field is never closed".to_string())),
                        Some('"') if chars.peek() == Some(&'"') => {
                            chars.next();
                            column += 2;
                            field.text.push('"');
                        }
                        Some('"') => {
                            column += 1;
                            break;
                        }
                        Some('\n') => {
                            line += 1;
                            column = 1;
                            field.text.push('\n');
                        }
                        Some(c) => {
                            column += 1;
                            field.text.push(c);
                        }
                    }
                }
                if chars.peek() == Some(&'\r') {
                    chars.next();
                    column += 1;
                }
                match chars.next() {
                    None => {}
                    Some('\n') => {
                        line += 1;
                        column = 1;
                    }
                    Some(',') => {
                        column += 1;
                        end_of_record = false;
                    }
                    Some(c) => {
                        return Err(Error::Text {
                            format: FORMAT,
                            line,
                            column: Some(column),
                            message: format!("unexpected `{c}` after a closing quote"),
                        });
                    }
                }
            } else {
                loop {
                    match chars.next() {
                        None => break,
                        Some('\n') => {
                            line += 1;
                            column = 1;
                            break;
                        }
                        Some(',') => {
                            column += 1;
                            end_of_record = false;
                            break;
                        }
                        Some(c) => {
                            column += 1;
                            field.text.push(c);
                        }
                    }
                }
                if end_of_record && field.text.ends_with('\r') {
                    field.text.pop();
                }
            }
            record.fields.push(field);
            if end_of_record {
                break;
            }
        }
        records.push(record);
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn take() -> Take {
        let names = vec![MarkerName::parse("Male:LFWT"), MarkerName::parse("odd, \"name\"")];
        let samples = [Some(Vec3::new(1.0, -2.5, 3.25)), None, None, Some(Vec3::new(4.0, 5.0, 6.0)), None, None];
        let mut take = Take::from_samples(names, &samples, 120.0).unwrap();
        take.first_frame = 7;
        take
    }

    fn text_of(take: &Take) -> String {
        let mut out = Vec::new();
        write_csv(take, &mut out).unwrap();
        String::from_utf8(out).unwrap()
    }

    fn line_of(err: Error) -> usize {
        match err {
            Error::Text { line, .. } => line,
            other => panic!("expected a text error, got {other}"),
        }
    }

    #[test]
    fn writes_header_quoted_and_missing_empty() {
        let text = text_of(&take());
        let mut lines = text.lines();
        assert_eq!(
            lines.next().unwrap(),
            "frame,time_s,Male:LFWT_x_mm,Male:LFWT_y_mm,Male:LFWT_z_mm,\"odd, \"\"name\"\"_x_mm\",\
             \"odd, \"\"name\"\"_y_mm\",\"odd, \"\"name\"\"_z_mm\""
        );
        assert_eq!(lines.next().unwrap(), "7,0.05,1.0000,-2.5000,3.2500,,,");
        assert_eq!(lines.next().unwrap(), "8,0.058333333333333334,,,,4.0000,5.0000,6.0000");
    }

    #[test]
    fn round_trips() {
        let original = take();
        let back = read_csv(&text_of(&original)).unwrap();
        assert_eq!(back, original);
    }

    #[test]
    fn crlf_and_quoted_line_breaks_keep_line_numbers() {
        let text = "frame,time_s,\"a\nb_x_mm\",\"a\nb_y_mm\",\"a\nb_z_mm\"\r\n1,0,1,2,3\r\n2,0.5,1,x,3\r\n";
        assert_eq!(line_of(read_csv(text).unwrap_err()), 6);
        let ok = text.replace(",x,", ",2,");
        let take = read_csv(&ok).unwrap();
        assert_eq!(take.markers()[0].label, "a\nb");
        assert_eq!(take.frame_rate_hz(), 2.0);
    }

    #[test]
    fn bad_input_gives_line_numbers() {
        assert_eq!(line_of(read_csv("").unwrap_err()), 1);
        assert_eq!(line_of(read_csv("frame,t\n").unwrap_err()), 1);
        assert_eq!(line_of(read_csv("frame,time_s,a_x_mm,a_y_mm,b_z_mm\n").unwrap_err()), 1);
        let base = "frame,time_s,a_x_mm,a_y_mm,a_z_mm\n1,0,1,2,3\n2,0.1,1,2,3\n";
        assert!(read_csv(base).is_ok());
        assert_eq!(line_of(read_csv(&format!("{base}3,0.2,1,2\n")).unwrap_err()), 4);
        assert_eq!(line_of(read_csv(&format!("{base}5,0.4,1,2,3\n")).unwrap_err()), 4);
        let edited = format!("{base}3,0.2,1,2,3\n4,0.38,1,2,3\n5,0.4,1,2,3\n");
        assert_eq!(line_of(read_csv(&edited).unwrap_err()), 5);
        assert_eq!(line_of(read_csv(&format!("{base}3,0.2,1,,3\n")).unwrap_err()), 4);
        assert_eq!(line_of(read_csv("frame,time_s\n1,0\n").unwrap_err()), 2);
        assert_eq!(line_of(read_csv("frame,time_s,\"a_x_mm\n").unwrap_err()), 1);
    }
}
