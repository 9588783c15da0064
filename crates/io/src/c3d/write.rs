//! The C3D writer: always Intel, parameters in their original order, point bookkeeping
//! updated, everything else as read.

use super::params::{ParamData, Parameter, Parameters, Record};
use super::{AnalogSamples, C3dFile, Storage, set_trial_field};
use crate::{Error, Result};
use std::io::Write;
use std::path::Path;

const BLOCK: usize = 512;

/// Writes `file` to `path` atomically (temporary file + rename).
pub fn write_path(file: &C3dFile, path: &Path) -> Result<()> {
    let bytes = to_bytes(file)?;
    crate::atomic::write_atomically(path, |w| Ok(w.write_all(&bytes)?))
}

/// Writes `file` as Intel C3D.
pub fn write(file: &C3dFile, w: &mut dyn Write) -> Result<()> {
    w.write_all(&to_bytes(file)?)?;
    Ok(())
}

/// Encodes `file` as Intel C3D bytes.
pub fn to_bytes(file: &C3dFile) -> Result<Vec<u8>> {
    if file.points.len() != file.frames * file.point_count {
        return Err(Error::Unwritable(format!(
            "{} point samples for {} frames x {} points",
            file.points.len(),
            file.frames,
            file.point_count
        )));
    }
    if file.point_count > u16::MAX as usize {
        return Err(Error::Unwritable(format!("{} points; C3D holds at most 65535", file.point_count)));
    }
    let analog_per_frame = file.header.analog_per_frame as usize;
    if file.analog.len() != file.frames * analog_per_frame {
        return Err(Error::Unwritable(format!(
            "{} analog samples for {} frames x {analog_per_frame} samples",
            file.analog.len(),
            file.frames
        )));
    }
    // Integer files stay integer when every coordinate fits the 16-bit range at the file's
    // scale, so unchanged samples keep their exact stored values; otherwise the whole file
    // becomes float (analog integers convert to floats exactly).
    let scale = file.point_scale();
    let storage = match file.storage {
        Storage::Int if fits_int(file, scale) => Storage::Int,
        _ => Storage::Float,
    };
    let mut params = file.parameters.clone();
    let signed_scale = match storage {
        Storage::Int => scale,
        Storage::Float => -scale,
    };
    // Without points, POINT:SCALE describes nothing (the header's scale says how analog
    // samples are stored): it is carried through as read (Kistler, BTK's EMG files keep
    // POINT:SCALE -1 with integer analog data).
    let header_scale = if file.point_count == 0
        && file.header.scale != 0.0
        && (file.header.scale < 0.0) == (storage == Storage::Float)
    {
        file.header.scale
    } else {
        update_number(&mut params, "POINT", "SCALE", signed_scale as f64, true);
        signed_scale
    };
    update_number(&mut params, "POINT", "USED", file.point_count as f64, false);
    let first = super::trial_field(&params, "ACTUAL_START_FIELD").unwrap_or(file.header.first_frame as u32);
    let frames = frame_numbers(&mut params, first, file.frames);
    // POINT:DATA_START depends on the parameter section's size, which does not depend on its
    // value (it is one int16), so size first, then fill in.
    update_number(&mut params, "POINT", "DATA_START", 0.0, false);
    add_missing_analog_parameters(&mut params);
    if !file.extra_sections.is_empty() && file.processor != super::Processor::Intel {
        return Err(Error::Unwritable(format!(
            "the {} file has data sections locap cannot convert to Intel ({})",
            file.processor.name(),
            file.extra_sections.iter().map(|e| e.group.as_str()).collect::<Vec<_>>().join(", ")
        )));
    }
    for extra in &file.extra_sections {
        update_number(&mut params, &extra.group, "DATA_START", 0.0, false);
    }
    let param_blocks = encode_parameters(&params, 0)?.len() / BLOCK;
    let data_block = 2 + param_blocks;
    // The one true limit: header word 9 and POINT:DATA_START are 16-bit block numbers. The
    // data section itself may run past block 65535 (long takes); nothing addresses its end.
    if data_block > u16::MAX as usize {
        return Err(Error::Unwritable(format!(
            "the parameter section takes {param_blocks} blocks; the data section must start by block 65535"
        )));
    }
    let word = match storage {
        Storage::Int => 2,
        Storage::Float => 4,
    };
    let frame_bytes = (file.point_count * 4 + analog_per_frame) * word;
    let data_bytes = file.frames * frame_bytes;
    let mut next_block = data_block + data_bytes.div_ceil(BLOCK);
    for extra in &file.extra_sections {
        // Other groups' data sections are located by their own 16-bit DATA_START.
        if next_block > u16::MAX as usize {
            return Err(Error::Unwritable(format!(
                "the {} data section would start at block {next_block}, past the 16-bit {}:DATA_START",
                extra.group, extra.group
            )));
        }
        update_number(&mut params, &extra.group, "DATA_START", next_block as f64, false);
        next_block += extra.bytes.len().div_ceil(BLOCK);
    }
    update_number(&mut params, "POINT", "DATA_START", data_block as f64, false);
    let param_bytes = encode_parameters(&params, param_blocks)?;

    let mut out = Vec::with_capacity(BLOCK + param_bytes.len() + file.points.len() * 16);
    out.extend(encode_header(file, header_scale, data_block, frames));
    out.extend(param_bytes);
    encode_data(file, storage, scale, &mut out)?;
    // ezc3d reads a header range of 65535 frames as "to the end of the file" and would take
    // zero padding of a frame's size or more for extra frames: such a data section ends
    // unpadded (readers do not need the last block to be whole; ezc3d and py-c3d do not).
    let to_the_end = frames.header_last - frames.header_first == u16::MAX - 1;
    if !(to_the_end && file.extra_sections.is_empty() && frame_bytes > 0) {
        pad_block(&mut out);
    }
    for extra in &file.extra_sections {
        out.extend(&extra.bytes);
        pad_block(&mut out);
    }
    Ok(out)
}

fn pad_block(out: &mut Vec<u8>) {
    let pad = (BLOCK - out.len() % BLOCK) % BLOCK;
    out.resize(out.len() + pad, 0);
}

/// The frame numbers as the header states them.
#[derive(Clone, Copy)]
struct FrameNumbers {
    header_first: u16,
    header_last: u16,
}

/// Writes the frame count and range into the parameters, and returns the header words.
///
/// The header's 16-bit first/last frame words cannot number a long take, so when the last
/// frame number passes 65535 locap writes what the readers that handle long takes look for:
/// - `TRIAL:ACTUAL_START_FIELD` / `ACTUAL_END_FIELD`, two 16-bit words each forming a 32-bit
///   frame number (Vicon; BTK and locap read them first);
/// - `POINT:LONG_FRAMES`, the frame count as a float (C-Motion; C3D.org user guide), exact up
///   to 2^24 frames;
/// - `POINT:FRAMES` as the integer 65535 (-1 as int16), as ezc3d writes it: ezc3d rejects a
///   float `POINT:FRAMES` ("FRAMES parameter is not an INT");
/// - header frames 1..=65535 (or 1..=frames when fewer), which ezc3d reads as "every frame to
///   the end of the file"; the true first frame is in `TRIAL:ACTUAL_START_FIELD`.
///
/// Existing parameters keep their stored type.
fn frame_numbers(params: &mut Parameters, first: u32, frames: usize) -> FrameNumbers {
    let last = first as u64 + (frames as u64).saturating_sub(1);
    let long = last > u16::MAX as u64;
    let frames_value = match params.get("POINT", "FRAMES").map(|p| &p.data) {
        Some(ParamData::Float(_)) => frames as f64,
        _ => frames.min(u16::MAX as usize) as f64,
    };
    update_number(params, "POINT", "FRAMES", frames_value, false);
    if frames > u16::MAX as usize || params.get("POINT", "LONG_FRAMES").is_some() {
        update_number(params, "POINT", "LONG_FRAMES", frames as f64, true);
    }
    let last32 = last.min(u32::MAX as u64) as u32;
    for (name, value) in [("ACTUAL_START_FIELD", first), ("ACTUAL_END_FIELD", last32)] {
        match params.get_mut("TRIAL", name) {
            Some(p) => set_trial_field(p, value),
            None if long => {
                let words = vec![(value & 0xffff) as u16 as i16, (value >> 16) as u16 as i16];
                params.set("TRIAL", name, vec![2], ParamData::Int(words));
            }
            None => {}
        }
    }
    if long {
        FrameNumbers { header_first: 1, header_last: frames.clamp(1, u16::MAX as usize) as u16 }
    } else {
        FrameNumbers { header_first: first as u16, header_last: last as u16 }
    }
}

/// Adds `ANALOG:SCALE`, `OFFSET` and `GEN_SCALE` with the C3D defaults (1, 0, 1) when a file
/// with analog channels lacks them (MACsample.c3d spells it `OFFSETS`). The values read do not
/// change, and readers that require them (ezc3d crashes without `OFFSET`) can open the file.
/// An `OFFSET` stored as floats (c3d.org sample 13), which the C3D manual defines as integers
/// and ezc3d rejects, is carried as read: the output is exactly as readable as the input.
fn add_missing_analog_parameters(params: &mut Parameters) {
    let channels = params.get("ANALOG", "USED").and_then(|p| p.as_i64()).unwrap_or(0);
    if !(1..=255).contains(&channels) {
        return;
    }
    let n = channels as usize;
    if params.get("ANALOG", "GEN_SCALE").is_none() {
        params.set("ANALOG", "GEN_SCALE", vec![], ParamData::Float(vec![1.0]));
    }
    if params.get("ANALOG", "SCALE").is_none() {
        params.set("ANALOG", "SCALE", vec![n as u8], ParamData::Float(vec![1.0; n]));
    }
    if params.get("ANALOG", "OFFSET").is_none() {
        params.set("ANALOG", "OFFSET", vec![n as u8], ParamData::Int(vec![0; n]));
    }
}

fn fits_int(file: &C3dFile, scale: f32) -> bool {
    file.points.iter().all(|w| {
        w[..3].iter().all(|v| {
            let q = (v / scale).round();
            q.is_finite() && q >= i16::MIN as f32 && q <= i16::MAX as f32
        }) && (w[3] < 0.0 || w[3] <= i16::MAX as f32)
    })
}

/// Sets a numeric parameter, keeping its stored type where it exists (`float` forces float
/// for a new one).
fn update_number(params: &mut Parameters, group: &str, name: &str, value: f64, float: bool) {
    match params.get_mut(group, name) {
        Some(p) => match &mut p.data {
            ParamData::Int(v) if !v.is_empty() => v[0] = value as i64 as u16 as i16,
            ParamData::Float(v) if !v.is_empty() => v[0] = value as f32,
            ParamData::Byte(v) if !v.is_empty() && value <= 255.0 => v[0] = value as u8,
            _ => {
                p.dims = vec![];
                p.data = if float {
                    ParamData::Float(vec![value as f32])
                } else {
                    ParamData::Int(vec![value as i64 as u16 as i16])
                };
            }
        },
        None => {
            let data = if float {
                ParamData::Float(vec![value as f32])
            } else {
                ParamData::Int(vec![value as i64 as u16 as i16])
            };
            params.set(group, name, vec![], data);
        }
    }
}

fn encode_header(file: &C3dFile, scale: f32, data_block: usize, frames: FrameNumbers) -> Vec<u8> {
    let mut h = file.header.raw.clone();
    h.resize(BLOCK, 0);
    let p = file.processor;
    if p != super::Processor::Intel {
        // The uninterpreted words of a non-Intel header may hold non-Intel numbers: blank the
        // reserved ones rather than carry numbers readers would misread, and convert the event
        // times of all 18 slots. Event display flags and labels are bytes and stay as read.
        let time = |i: usize| {
            let at = 2 * (153 + 2 * i - 1);
            p.f32([h[at], h[at + 1], h[at + 2], h[at + 3]])
        };
        let times: Vec<f32> = (0..18).map(time).collect();
        let key = p.u16([h[298], h[299]]);
        for range in [24..376, 394..396, 468..BLOCK] {
            h[range].fill(0);
        }
        h[298..300].copy_from_slice(&key.to_le_bytes());
        for (i, t) in times.iter().enumerate() {
            let at = 2 * (153 + 2 * i - 1);
            h[at..at + 4].copy_from_slice(&t.to_le_bytes());
        }
    }
    let mut word = |n: usize, v: u16| h[2 * (n - 1)..2 * n].copy_from_slice(&v.to_le_bytes());
    word(2, file.point_count as u16);
    word(3, file.header.analog_per_frame);
    word(4, frames.header_first);
    word(5, frames.header_last);
    word(6, file.header.max_gap);
    word(9, data_block as u16);
    word(10, file.header.analog_per_channel);
    word(148, 0);
    word(149, 0);
    // Word 150 is 12345 when 4-character event labels are used; any other value is carried.
    if file.header.events_key {
        word(150, 12345);
    }
    word(151, file.header.events.len() as u16);
    h[0] = 2;
    h[1] = 0x50;
    h[12..16].copy_from_slice(&scale.to_le_bytes());
    h[20..24].copy_from_slice(&file.header.frame_rate_hz.to_le_bytes());
    for (i, e) in file.header.events.iter().take(18).enumerate() {
        let at = 2 * (153 + 2 * i - 1);
        h[at..at + 4].copy_from_slice(&e.time_s.to_le_bytes());
        h[376 + i] = e.display;
        h[396 + 4 * i..400 + 4 * i].copy_from_slice(&e.label);
    }
    h
}

fn encode_parameters(params: &Parameters, blocks_hint: usize) -> Result<Vec<u8>> {
    let mut records: Vec<Vec<u8>> = Vec::new();
    for r in &params.records {
        let mut rec = Vec::new();
        match r {
            Record::Group(g) => {
                let name = checked_name(&g.name)?;
                rec.push(signed_len(name.len(), g.locked));
                rec.push((-(g.id as i16)) as i8 as u8);
                rec.extend(name);
                rec.extend([0, 0]);
                push_description(&mut rec, &g.description);
            }
            Record::Parameter(p) => {
                let name = checked_name(&p.name)?;
                rec.push(signed_len(name.len(), p.locked));
                rec.push(p.group_id);
                rec.extend(name);
                rec.extend([0, 0]);
                encode_parameter_payload(p, &mut rec)?;
            }
        }
        records.push(rec);
    }
    let mut out = vec![0u8; 4];
    let n = records.len();
    for (i, mut rec) in records.into_iter().enumerate() {
        let name_len = (rec[0] as i8).unsigned_abs() as usize;
        let offset_at = 2 + name_len;
        let next = if i + 1 == n { 0 } else { rec.len() - offset_at };
        if next > i16::MAX as usize {
            return Err(Error::Unwritable("a parameter record is larger than 32 KiB".into()));
        }
        rec[offset_at..offset_at + 2].copy_from_slice(&(next as i16).to_le_bytes());
        out.extend(rec);
    }
    // A zero byte after the last record terminates the section for readers that do not stop
    // at offset 0.
    out.push(0);
    let blocks = out.len().div_ceil(BLOCK).max(blocks_hint).max(1);
    out.resize(blocks * BLOCK, 0);
    out[0] = 1;
    out[1] = 0x50;
    // The block count is one byte. ezc3d and locap follow the records' offsets to the end of
    // the section and do not need it; py-c3d reads the blocks it counts, so a longer section
    // says 255 and py-c3d reads the records in its first 255 blocks (locap appends its own
    // parameters, the long range lists, last). See the module doc.
    out[2] = blocks.min(255) as u8;
    out[3] = super::Processor::Intel.to_byte();
    Ok(out)
}

fn encode_parameter_payload(p: &Parameter, rec: &mut Vec<u8>) -> Result<()> {
    // Checked: 255 dimensions of 255 overflow usize (the reader rejects such records too).
    let count = p.dims.iter().try_fold(1usize, |n, d| n.checked_mul(*d as usize));
    let values = match &p.data {
        ParamData::Char(v) | ParamData::Byte(v) => v.len(),
        ParamData::Int(v) => v.len(),
        ParamData::Float(v) => v.len(),
    };
    if count != Some(values) || p.dims.len() > 255 {
        return Err(Error::Unwritable(format!(
            "parameter {}: dimensions {:?} do not match {values} values",
            p.name, p.dims
        )));
    }
    rec.push(p.data.type_code() as u8);
    rec.push(p.dims.len() as u8);
    rec.extend(&p.dims);
    match &p.data {
        ParamData::Char(v) | ParamData::Byte(v) => rec.extend(v),
        ParamData::Int(v) => v.iter().for_each(|x| rec.extend(x.to_le_bytes())),
        ParamData::Float(v) => v.iter().for_each(|x| rec.extend(x.to_le_bytes())),
    }
    push_description(rec, &p.description);
    Ok(())
}

fn push_description(rec: &mut Vec<u8>, desc: &[u8]) {
    let d = &desc[..desc.len().min(255)];
    rec.push(d.len() as u8);
    rec.extend(d);
}

fn checked_name(name: &str) -> Result<&[u8]> {
    let b = name.as_bytes();
    if b.is_empty() || b.len() > 127 {
        return Err(Error::Unwritable(format!("parameter or group name {name:?} must be 1-127 bytes")));
    }
    Ok(b)
}

fn signed_len(len: usize, locked: bool) -> u8 {
    let l = len as i8;
    (if locked { -l } else { l }) as u8
}

fn encode_data(file: &C3dFile, storage: Storage, scale: f32, out: &mut Vec<u8>) -> Result<()> {
    let m = file.point_count;
    let a = file.header.analog_per_frame as usize;
    if m == 0 && a == 0 {
        // Empty frames: nothing to write, and `frames` may be in the billions (see the reader).
        return Ok(());
    }
    for f in 0..file.frames {
        for w in &file.points[f * m..(f + 1) * m] {
            match storage {
                Storage::Int => {
                    for v in &w[..3] {
                        out.extend(((v / scale).round() as i16).to_le_bytes());
                    }
                    // The residual word as read: negative words other than -1 (BTK writes -32768)
                    // are carried too.
                    let r = if w[3] < 0.0 {
                        if w[3].fract() == 0.0 && w[3] >= i16::MIN as f32 { w[3] as i16 } else { -1 }
                    } else {
                        w[3] as i32 as u16 as i16
                    };
                    out.extend(r.to_le_bytes());
                }
                Storage::Float => w.iter().for_each(|v| out.extend(v.to_le_bytes())),
            }
        }
        match (&file.analog, storage) {
            (AnalogSamples::Int(v), Storage::Int) => {
                v[f * a..(f + 1) * a].iter().for_each(|x| out.extend(x.to_le_bytes()))
            }
            (AnalogSamples::Int(v), Storage::Float) => {
                let unsigned = analog_unsigned(&file.parameters);
                v[f * a..(f + 1) * a].iter().for_each(|x| {
                    let value = if unsigned { *x as u16 as f32 } else { *x as f32 };
                    out.extend(value.to_le_bytes())
                })
            }
            (AnalogSamples::Float(v), Storage::Float) => {
                v[f * a..(f + 1) * a].iter().for_each(|x| out.extend(x.to_le_bytes()))
            }
            (AnalogSamples::Float(v), Storage::Int) => {
                for x in &v[f * a..(f + 1) * a] {
                    if x.fract() != 0.0 || *x < i16::MIN as f32 || *x > i16::MAX as f32 {
                        return Err(Error::Unwritable("float analog samples cannot be stored as integers".into()));
                    }
                    out.extend((*x as i16).to_le_bytes());
                }
            }
        }
    }
    Ok(())
}

fn analog_unsigned(params: &Parameters) -> bool {
    params
        .get("ANALOG", "FORMAT")
        .and_then(|p| p.strings().into_iter().next())
        .is_some_and(|s| s.eq_ignore_ascii_case("UNSIGNED"))
}
