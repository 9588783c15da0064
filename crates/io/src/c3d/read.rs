//! The C3D reader: header, parameter section, data section.
//!
//! Counts from the header and parameters are checked against the file's size and against
//! [`Limits`] before anything is allocated (see [`crate::limits`]). Frames of zero bytes (a
//! file with no points and no analog channels) are bounded by the bytes after the data
//! start, one frame per byte: `TRIAL:ACTUAL_END_FIELD` can claim 4 billion of them in a 1 KB
//! file, and nothing in the file backs them.

use super::params::{Group, ParamData, Parameter, Parameters, Record};
use super::{AnalogSamples, C3dFile, ExtraSection, Header, HeaderEvent, Processor, Storage, trial_field};
use crate::limits::{self, Limits};
use crate::{Error, Result};
use locap_core::LengthUnit;
use std::path::Path;

const BLOCK: usize = 512;

/// How forgiving the reader is, and how much it may allocate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Fail on a truncated data section instead of reading the complete frames it holds
    /// (with a warning in [`C3dFile::warnings`]). Off by default: a capture cut short by a
    /// crash still holds good frames, and the reference reader ezc3d reads them too.
    pub strict: bool,
    /// Ceilings on file size, frames and samples (see [`Limits`]).
    pub limits: Limits,
}

/// Reads a C3D file from disk with default options. Errors name the file.
pub fn read_path(path: &Path) -> Result<C3dFile> {
    read_path_with(path, ReadOptions::default())
}

/// Reads a C3D file from disk. Errors name the file; a path that is not a regular file (a
/// named pipe, a device, a directory) is refused before it is opened.
pub fn read_path_with(path: &Path, options: ReadOptions) -> Result<C3dFile> {
    let bytes = limits::read_file(path, &options.limits)?;
    read_with(&bytes, options).map_err(|e| e.in_file(path))
}

/// Reads a C3D file held in memory with default options.
pub fn read(bytes: &[u8]) -> Result<C3dFile> {
    read_with(bytes, ReadOptions::default())
}

/// Reads a C3D file held in memory.
pub fn read_with(bytes: &[u8], options: ReadOptions) -> Result<C3dFile> {
    if bytes.len() as u64 > options.limits.max_file_bytes {
        return Err(Error::Limit(format!(
            "C3D file of {} bytes exceeds the limit of {} bytes",
            bytes.len(),
            options.limits.max_file_bytes
        )));
    }
    if bytes.len() < BLOCK {
        return Err(binary("header", 0, format!("file is {} bytes, a C3D header alone is 512", bytes.len())));
    }
    if bytes[1] != 0x50 {
        return Err(binary("header", 1, format!("second byte is 0x{:02x}, a C3D file has 0x50", bytes[1])));
    }
    let param_block = bytes[0] as usize;
    if param_block == 0 {
        return Err(binary("header", 0, "parameter section block number is 0".to_string()));
    }
    let param_offset = (param_block - 1) * BLOCK;
    if param_offset + 4 > bytes.len() {
        return Err(binary(
            "header",
            0,
            format!(
                "parameter section at block {param_block} (byte {param_offset}) lies past the end of the {}-byte file",
                bytes.len()
            ),
        ));
    }
    let processor = Processor::from_byte(bytes[param_offset + 3]).ok_or_else(|| {
        binary(
            "parameter section",
            (param_offset + 3) as u64,
            format!("processor type {} is not 84 (Intel), 85 (DEC) or 86 (MIPS)", bytes[param_offset + 3]),
        )
    })?;
    let header = read_header(bytes, processor);
    let mut warnings = Vec::new();
    // The parameter section ends where the data section starts (when that lies after it):
    // its declared block count is wrong in several vendors' files.
    // Records beyond both the declared blocks and the data start are still read if the chain
    // of offsets leads there (c3d.org sample 18 overlaps its data block); the bound only keeps
    // reads inside the file.
    let data_hint = read_u16_word(bytes, processor, 9) as usize;
    let declared_end = param_offset + (bytes[param_offset + 2] as usize).max(1) * BLOCK;
    let param_end = match data_hint.saturating_sub(1) * BLOCK {
        d if d > param_offset => d.max(declared_end).min(bytes.len()),
        _ => bytes.len(),
    };
    let parameters = read_parameters(bytes, param_offset, param_end, processor, &mut warnings)?;
    rate_warnings(&header, &parameters, &mut warnings);

    let storage = if header.scale < 0.0 { Storage::Float } else { Storage::Int };
    let word = match storage {
        Storage::Int => 2,
        Storage::Float => 4,
    };
    let point_count = header.point_count as usize;
    if let Some(used) = parameters.get("POINT", "USED").and_then(|p| p.as_i64())
        && used as u16 as usize != point_count
    {
        warnings.push(format!(
            "header says {point_count} points, POINT:USED says {used}; the header defines the data layout"
        ));
    }
    let data_block = match header.data_block {
        0 => parameters.get("POINT", "DATA_START").and_then(|p| p.as_i64()).unwrap_or(0) as u16 as usize,
        b => b as usize,
    };
    let data_offset = data_block.saturating_sub(1) * BLOCK;
    let mut header = header;
    let data_len = bytes.len().saturating_sub(data_offset);
    let analog_per_frame = analog_samples_per_frame(&header, &parameters, point_count, word, data_len, &mut warnings);
    if analog_per_frame != header.analog_per_frame as usize {
        header.analog_per_frame = analog_per_frame as u16;
        let channels = parameters.get("ANALOG", "USED").and_then(|p| p.as_i64()).unwrap_or(0).max(1) as usize;
        header.analog_per_channel = (analog_per_frame / channels) as u16;
    }
    if point_count > 0
        && let Some(w) = units_warning(&parameters)
    {
        warnings.push(w);
    }
    let frame_bytes = (point_count * 4 + analog_per_frame) * word;
    let backing = if data_offset > bytes.len() || data_block == 0 { 0 } else { bytes.len() - data_offset };
    // Empty frames: at most one per byte after the data start (see the module doc).
    let available = backing.checked_div(frame_bytes).unwrap_or(backing);
    let frames = frame_count(&header, &parameters, available, &mut warnings);
    if frame_bytes == 0 && frames > available {
        let message = format!(
            "{frames} frames declared, but with no point or analog data per frame nothing in the file backs them: \
             the {backing} bytes after the data start allow at most {available}"
        );
        if options.strict {
            return Err(Error::Limit(message));
        }
        warnings.push(format!("{message}; read {available}"));
    }
    if frame_bytes > 0 && frames > 0 {
        if data_block == 0 {
            return Err(binary("header", 16, "data section block number is 0".to_string()));
        }
        if frames > available {
            let message = format!(
                "truncated: {frames} frames of {frame_bytes} bytes declared from byte {data_offset}, \
                 but the {}-byte file holds only {available} complete frames",
                bytes.len()
            );
            if options.strict || available == 0 {
                return Err(binary("data section", (data_offset + available * frame_bytes) as u64, message));
            }
            warnings.push(format!("{message}; read those {available}"));
        }
    }
    let frames = frames.min(available);
    options.limits.check_samples("C3D", frames, point_count + analog_per_frame, "point and analog values")?;

    let scale = super::C3dFile::point_scale_of(&parameters, header.scale);
    let mut points = Vec::with_capacity(frames * point_count);
    let mut analog_int = Vec::new();
    let mut analog_float = Vec::new();
    match storage {
        Storage::Int => analog_int.reserve(frames * analog_per_frame),
        Storage::Float => analog_float.reserve(frames * analog_per_frame),
    }
    // With no points and no analog samples there is nothing to read, and the frame count is
    // not bounded by the file's size (TRIAL:ACTUAL_END_FIELD can say 4 billion): looping
    // over empty frames hung the fuzzer.
    let data_frames = if frame_bytes == 0 { 0 } else { frames };
    for f in 0..data_frames {
        let mut at = data_offset + f * frame_bytes;
        for _ in 0..point_count {
            points.push(match storage {
                Storage::Int => {
                    let v: [i16; 4] =
                        std::array::from_fn(|k| processor.i16([bytes[at + 2 * k], bytes[at + 2 * k + 1]]));
                    [v[0] as f32 * scale, v[1] as f32 * scale, v[2] as f32 * scale, v[3] as f32]
                }
                Storage::Float => std::array::from_fn(|k| {
                    let b = at + 4 * k;
                    processor.f32([bytes[b], bytes[b + 1], bytes[b + 2], bytes[b + 3]])
                }),
            });
            at += 4 * word;
        }
        for _ in 0..analog_per_frame {
            match storage {
                Storage::Int => analog_int.push(processor.i16([bytes[at], bytes[at + 1]])),
                Storage::Float => {
                    analog_float.push(processor.f32([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]))
                }
            }
            at += word;
        }
    }
    let analog = match storage {
        Storage::Int => AnalogSamples::Int(analog_int),
        Storage::Float => AnalogSamples::Float(analog_float),
    };
    let data_end = data_offset + frames * frame_bytes;
    let extra_sections = extra_sections(bytes, &parameters, data_end, &mut warnings);
    Ok(C3dFile {
        processor,
        header,
        parameters,
        storage,
        frames,
        point_count,
        points,
        analog,
        extra_sections,
        warnings,
    })
}

/// Finds the data sections of groups other than POINT (`GROUP:DATA_START`) that lie after the
/// point and analog data; each runs to the next such section or the end of the file.
fn extra_sections(bytes: &[u8], params: &Parameters, data_end: usize, warnings: &mut Vec<String>) -> Vec<ExtraSection> {
    let mut starts: Vec<(usize, String)> = params
        .groups()
        .filter(|g| !g.name.eq_ignore_ascii_case("POINT"))
        .filter_map(|g| {
            let block = params.get(&g.name, "DATA_START")?.as_i64()?;
            let offset = (block as u16 as usize).checked_sub(1)? * BLOCK;
            Some((offset, g.name.clone()))
        })
        .collect();
    starts.sort();
    let mut out = Vec::new();
    for (i, (offset, group)) in starts.iter().enumerate() {
        if *offset < data_end || *offset >= bytes.len() {
            warnings.push(format!(
                "{group}:DATA_START points at byte {offset}, outside the free part of the file; its data is not carried"
            ));
            continue;
        }
        let end = starts.get(i + 1).map(|(o, _)| (*o).min(bytes.len())).unwrap_or(bytes.len());
        out.push(ExtraSection { group: group.clone(), bytes: bytes[*offset..end.max(*offset)].to_vec() });
    }
    out
}

/// Decides how many analog samples each 3D frame holds. Header word 3 should be the total
/// over all channels, but some writers (The MotionMonitor) put the channel count there; the
/// candidates are checked against the data section's size and the one that fills it (to
/// within the last block's padding) wins.
fn analog_samples_per_frame(
    header: &Header,
    params: &Parameters,
    point_count: usize,
    word: usize,
    data_len: usize,
    warnings: &mut Vec<String>,
) -> usize {
    let stated = header.analog_per_frame as usize;
    let channels = params.get("ANALOG", "USED").and_then(|p| p.as_i64()).filter(|c| *c > 0).map(|c| c as usize);
    let Some(channels) = channels else { return stated };
    let frames = frame_count(header, params, usize::MAX, &mut Vec::new());
    let point_rate = params.get("POINT", "RATE").and_then(|p| p.as_f64()).unwrap_or(header.frame_rate_hz as f64);
    let analog_rate = params.get("ANALOG", "RATE").and_then(|p| p.as_f64()).unwrap_or(0.0);
    let ratio = if point_rate > 0.0 && analog_rate > 0.0 { (analog_rate / point_rate).round() as usize } else { 0 };
    let slack = |samples: usize| {
        let need = frames.checked_mul((point_count * 4 + samples) * word)?;
        data_len.checked_sub(need)
    };
    if frames == 0 || slack(stated).is_some_and(|r| r < BLOCK) {
        return stated;
    }
    // Saturating: a float ANALOG:USED can be ~1e18 and overflow the product; such a count is
    // then filtered out as more than 65535 samples.
    let better =
        [channels.saturating_mul(header.analog_per_channel as usize), channels.saturating_mul(ratio.min(1 << 16))]
            .into_iter()
            .filter(|c| *c != stated && *c > 0 && *c <= u16::MAX as usize)
            .filter_map(|c| slack(c).filter(|r| *r < BLOCK).map(|r| (r, c)))
            .min();
    match better {
        Some((_, c)) => {
            warnings.push(format!(
                "header word 3 says {stated} analog samples per frame; the data section holds {c} ({channels} channels)"
            ));
            c
        }
        None => stated,
    }
}

/// Decides the number of 3D frames. The header's 16-bit first/last frame words overflow past
/// 65535 frames, so `TRIAL:ACTUAL_*_FIELD` (32-bit) and `POINT:FRAMES` (read as unsigned) are
/// preferred when they are consistent with the file's size.
fn frame_count(header: &Header, params: &Parameters, available: usize, warnings: &mut Vec<String>) -> usize {
    let from_header = if header.last_frame >= header.first_frame && header.last_frame > 0 {
        (header.last_frame - header.first_frame) as usize + 1
    } else {
        0
    };
    let from_trial = match (trial_field(params, "ACTUAL_START_FIELD"), trial_field(params, "ACTUAL_END_FIELD")) {
        (Some(s), Some(e)) if e >= s => Some((e - s) as usize + 1),
        _ => None,
    };
    let from_point = params.get("POINT", "FRAMES").and_then(|p| match &p.data {
        ParamData::Int(v) => v.first().map(|x| *x as u16 as usize),
        ParamData::Float(v) => v.first().filter(|x| x.is_finite() && **x >= 0.0).map(|x| *x as usize),
        _ => None,
    });
    // C-Motion's POINT:LONG_FRAMES: the frame count as a float, for takes past 65535 frames.
    let from_long = params
        .get("POINT", "LONG_FRAMES")
        .and_then(|p| p.as_f64())
        .filter(|x| x.is_finite() && *x >= 1.0)
        .map(|x| x.min(u32::MAX as f64) as usize);
    for candidate in [from_trial, from_long, from_point].into_iter().flatten() {
        // Longer than the header says: the 16-bit header words overflowed. Shorter, when the
        // header's count does not fit in the file: the header is wrong (Optotrak writes a
        // bogus last frame) and the parameters agree with the data actually present.
        let longer = candidate > from_header && candidate <= available;
        let header_impossible = from_header > available && candidate <= available && candidate > 0;
        if longer || header_impossible {
            warnings
                .push(format!("header frame range gives {from_header} frames; using {candidate} from the parameters"));
            return candidate;
        }
    }
    from_header
}

/// Warns when `POINT:UNITS` does not name a length unit: coordinates are then read as
/// millimetres, which is a guess the user should hear about (the labeling set's Vicon files
/// leave it empty; several c3d.org samples have none).
fn units_warning(params: &Parameters) -> Option<String> {
    let assumed = "coordinates are read as millimetres";
    let Some(p) = params.get("POINT", "UNITS") else {
        return Some(format!("POINT:UNITS is absent; {assumed}"));
    };
    match p.strings().into_iter().next() {
        Some(s) if LengthUnit::parse(&s).is_some() => None,
        Some(s) if !s.trim().is_empty() => Some(format!("POINT:UNITS is {s:?}, not a known length unit; {assumed}")),
        _ => Some(format!("POINT:UNITS is empty; {assumed}")),
    }
}

/// Warns about frame rates that are not positive numbers. `POINT:RATE` wins over the header
/// when valid (see [`C3dFile::frame_rate_hz`]); with neither valid the file still reads, so
/// its parameters and analog data are not lost, but [`C3dFile::to_take`] refuses it.
fn rate_warnings(header: &Header, params: &Parameters, warnings: &mut Vec<String>) {
    let valid = |r: f64| r.is_finite() && r > 0.0;
    let header_rate = header.frame_rate_hz as f64;
    match params.get("POINT", "RATE").and_then(|p| p.as_f64()) {
        Some(r) if valid(r) => {}
        Some(r) if valid(header_rate) => {
            warnings.push(format!("POINT:RATE is {r}, not a positive number; using the header's {header_rate} Hz"))
        }
        Some(r) => warnings.push(format!("no frame rate: POINT:RATE is {r} and the header says {header_rate} Hz")),
        None if !valid(header_rate) => {
            warnings.push(format!("no frame rate: no POINT:RATE and the header says {header_rate} Hz"))
        }
        None => {}
    }
}

fn read_u16_word(b: &[u8], p: Processor, n: usize) -> u16 {
    p.u16([b[2 * (n - 1)], b[2 * (n - 1) + 1]])
}

fn read_header(b: &[u8], p: Processor) -> Header {
    let word = |n: usize| p.u16([b[2 * (n - 1)], b[2 * (n - 1) + 1]]);
    let float = |n: usize| {
        let i = 2 * (n - 1);
        p.f32([b[i], b[i + 1], b[i + 2], b[i + 3]])
    };
    let events_key = word(150) == 12345;
    let event_count = (word(151) as usize).min(18);
    let events = (0..event_count)
        .map(|i| HeaderEvent {
            time_s: float(153 + 2 * i),
            display: b[376 + i],
            label: [b[396 + 4 * i], b[397 + 4 * i], b[398 + 4 * i], b[399 + 4 * i]],
        })
        .collect();
    Header {
        parameter_block: b[0],
        point_count: word(2),
        analog_per_frame: word(3),
        first_frame: word(4),
        last_frame: word(5),
        max_gap: word(6),
        scale: float(7),
        data_block: word(9),
        analog_per_channel: word(10),
        frame_rate_hz: float(11),
        events_key,
        events,
        raw: b[..BLOCK].to_vec(),
    }
}

/// Reads parameter records until a zero name length, a zero offset, or the end of the
/// declared parameter blocks.
fn read_parameters(
    bytes: &[u8],
    start: usize,
    end: usize,
    p: Processor,
    warnings: &mut Vec<String>,
) -> Result<Parameters> {
    let mut records = Vec::new();
    let mut at = start + 4;
    let section = "parameter section";
    loop {
        if at + 2 > end {
            break;
        }
        let name_len_raw = bytes[at] as i8;
        if name_len_raw == 0 {
            break;
        }
        let locked = name_len_raw < 0;
        let name_len = name_len_raw.unsigned_abs() as usize;
        let id = bytes[at + 1] as i8;
        let name_at = at + 2;
        let offset_at = name_at + name_len;
        if offset_at + 2 > end {
            return Err(binary(
                section,
                at as u64,
                format!("record name of {name_len} bytes runs past the parameter section end (byte {end})"),
            ));
        }
        let name = String::from_utf8_lossy(&bytes[name_at..offset_at]).trim_end_matches([' ', '\0']).to_string();
        let next = p.i16([bytes[offset_at], bytes[offset_at + 1]]);
        let payload = offset_at + 2;
        // The last record may point nowhere (offset 0); its payload then ends at the section end.
        let record_end = if next > 0 { (offset_at + next as usize).min(end) } else { end };
        if name.is_empty() || name.len() > 127 {
            // Blank names (and lossy UTF-8 growing past 127 bytes) cannot be written back and
            // cannot be looked up (fuzzer-found: the round trip failed to write). A skipped
            // group's parameters stay without a group, as in the file.
            warnings.push(format!("record at byte {at} has name {name:?}, not 1-127 bytes; skipped"));
        } else if id == 0 {
            warnings.push(format!("record {name:?} at byte {at} has group id 0; skipped"));
        } else if id < 0 {
            let desc = description(bytes, payload, record_end);
            records.push(Record::Group(Group { id: id.unsigned_abs(), name: name.clone(), locked, description: desc }));
        } else {
            match read_parameter(bytes, payload, record_end, p, id as u8, name.clone(), locked) {
                Ok(param) => records.push(Record::Parameter(param)),
                Err(e) if next <= 0 => {
                    // A broken *last* record (e.g. c3d.org sample 18's empty group with offset
                    // -1) does not make the rest of the file unreadable.
                    warnings.push(format!("last parameter record {name:?} is malformed and was skipped: {e}"));
                    break;
                }
                Err(e) => return Err(e),
            }
        }
        if next <= 0 {
            if next < 0 {
                warnings.push(format!(
                    "record {name:?} at byte {at} has negative offset {next}; parameter section ends there"
                ));
            }
            break;
        }
        at = offset_at + next as usize;
    }
    // Parameters whose group is never declared are kept as they are (and written back so):
    // a file this broken is worth a warning.
    let groups: Vec<u8> =
        records.iter().filter_map(|r| if let Record::Group(g) = r { Some(g.id) } else { None }).collect();
    let mut orphans: Vec<u8> = records
        .iter()
        .filter_map(|r| if let Record::Parameter(q) = r { Some(q.group_id) } else { None })
        .filter(|id| !groups.contains(id))
        .collect();
    orphans.dedup();
    for id in orphans {
        warnings.push(format!("parameters refer to group {id}, which is never declared"));
    }
    Ok(Parameters { records })
}

fn description(bytes: &[u8], at: usize, end: usize) -> Vec<u8> {
    if at >= end {
        return Vec::new();
    }
    let len = bytes[at] as usize;
    let from = at + 1;
    bytes[from.min(end)..(from + len).min(end)].to_vec()
}

fn read_parameter(
    bytes: &[u8],
    at: usize,
    end: usize,
    p: Processor,
    group_id: u8,
    name: String,
    locked: bool,
) -> Result<Parameter> {
    let section = "parameter section";
    let err = |offset: usize, message: String| binary(section, offset as u64, format!("parameter {name:?}: {message}"));
    if at + 2 > end {
        return Err(err(at, "record ends before its type and dimension count".into()));
    }
    let kind = bytes[at] as i8;
    let ndims = bytes[at + 1] as usize;
    let dims_at = at + 2;
    if dims_at + ndims > end {
        return Err(err(at + 1, format!("{ndims} dimensions run past the record end (byte {end})")));
    }
    let dims = bytes[dims_at..dims_at + ndims].to_vec();
    let size = match kind {
        -1 | 1 => 1,
        2 => 2,
        4 => 4,
        other => return Err(err(at, format!("data type {other} is not -1, 1, 2 or 4"))),
    };
    let data_at = dims_at + ndims;
    // Up to 255 dimensions of up to 255 each: the product overflows usize (fuzzer-found), so
    // it is computed checked; a size that overflows cannot fit in the record either.
    let count = dims.iter().try_fold(1usize, |n, d| n.checked_mul(*d as usize));
    let data_end = count.and_then(|c| c.checked_mul(size)).and_then(|n| n.checked_add(data_at));
    let data_end = match data_end {
        Some(e) if e <= end => e,
        _ => {
            let count = count.map_or_else(|| "too many".to_string(), |c| c.to_string());
            return Err(err(
                data_at,
                format!("{count} values of {size} bytes (dimensions {dims:?}) run past the record end (byte {end})"),
            ));
        }
    };
    let raw = &bytes[data_at..data_end];
    let data = match kind {
        -1 => ParamData::Char(raw.to_vec()),
        1 => ParamData::Byte(raw.to_vec()),
        2 => ParamData::Int(raw.chunks_exact(2).map(|c| p.i16([c[0], c[1]])).collect()),
        _ => ParamData::Float(raw.chunks_exact(4).map(|c| p.f32([c[0], c[1], c[2], c[3]])).collect()),
    };
    Ok(Parameter { group_id, name, locked, dims, data, description: description(bytes, data_end, end) })
}

fn binary(section: &str, offset: u64, message: String) -> Error {
    Error::Binary { format: "C3D", section: section.to_string(), offset, message }
}
