//! C3D: the binary format of optical motion capture, read and written losslessly.
//!
//! Implements the C3D file format as documented in the C3D User Guide (c3d.org, "The C3D File
//! Format"): a 512-byte header block, a parameter section of 512-byte blocks ([`params`]),
//! and a data section holding, per frame, every 3D point (x, y, z, residual word) followed by
//! the analog samples of that frame. Integer files store coordinates as `i16 * POINT:SCALE`;
//! a negative `POINT:SCALE` means IEEE (or VAX, or big-endian) floats instead.
//!
//! # What locap keeps
//! [`C3dFile`] holds the header, every parameter record in file order, the raw point words
//! and the raw analog samples. [`C3dFile::to_take`] derives a [`Take`] (millimetres, explicit
//! missing samples); [`C3dFile::set_take`] puts edited points back. [`write`] changes only
//! what locap changed: point data, point labels if relabeled, and the bookkeeping parameters
//! that describe them (`POINT:USED`, `POINT:FRAMES`, `POINT:DATA_START`, `POINT:SCALE` when
//! there are points, `POINT:LONG_FRAMES` and `TRIAL:ACTUAL_*_FIELD`, see below). Every other
//! parameter (parameters of groups the file never declares included, written without a
//! group as they were read), the header events of all 18 slots, residual words as stored
//! (BTK's -32768 as well as -1) and the analog data are carried through; `convert a.c3d b.c3d`
//! on the 139 shared real files changes nothing else (`tests/c3d_round_trip.rs`). Deliberate
//! changes: the output is always Intel (processor type 84), which every reader supports; the
//! optional "3D label and range" section of old files (header words 148-149) is dropped
//! because nothing references it; reserved header words of non-Intel files are blanked (their
//! number format is unknown); and `ANALOG:GEN_SCALE`, `SCALE`, `OFFSET` are added when a file
//! with analog channels lacks them (ezc3d crashes without them). A float `ANALOG:OFFSET`
//! (c3d.org sample 13) is kept as float although ezc3d rejects it: the output is then exactly
//! as readable as the input.
//!
//! # Long takes
//! Only the data section's start must fit 16 bits (header word 9 and `POINT:DATA_START`); the
//! data section may run to any length. Frame numbers past 65535 are written the way the
//! readers that handle long takes expect (ezc3d 1.7.2 source, `Header.cpp`/`Data.cpp`; BTK;
//! the C3D.org user guide on `POINT:LONG_FRAMES`): header frames 1..=65535, which ezc3d reads
//! as "to the end of the file" (so that data section is not padded to a whole block),
//! `POINT:FRAMES` = 65535 as int16 (ezc3d refuses a float one), `POINT:LONG_FRAMES` (float,
//! C-Motion) and `TRIAL:ACTUAL_START_FIELD`/`ACTUAL_END_FIELD` (two 16-bit words each, Vicon)
//! with the true numbers. The reader takes the frame count from the TRIAL fields, then
//! `LONG_FRAMES`, then `POINT:FRAMES`, when they are consistent with the file's size.
//!
//! # Long parameter sections
//! The section's block count is one byte. ezc3d and locap follow the records' offsets and
//! ignore it; py-c3d reads only the blocks it counts. locap writes sections of any size up to
//! the 16-bit data start (65,533 blocks, ~33.5 MB) and saturates the count at 255, so py-c3d
//! still reads the first 255 blocks: the standard groups, written first; locap's own groups
//! come last. `locap clean`'s range lists are compact (`locap_core::range_list`) so that
//! tens of thousands of ranges stay within 255 blocks. One record holds at most 32 KiB (its
//! offset to the next is an int16): [`Parameters::set_continued_strings`] splits long string
//! lists into `NAME`, `NAME2`, ... accordingly.

//! # Missing samples
//! A sample is missing if its residual word is negative (the standard) **or** all three
//! coordinates are exactly zero (CMU and several exporters write zeros) or a coordinate is
//! not finite. locap writes missing samples as zeros with residual -1, which every reader
//! understands.
//!
//! # Robustness
//! Counts read from the file are checked against the file's size and against
//! [`crate::Limits`] (in [`ReadOptions`]) before anything is allocated, and every malformed
//! structure gives [`Error::Binary`] with the byte offset and section; no input makes the
//! reader panic (a fuzz target checks this). What the reader resolved by a choice (header
//! and parameters disagreeing, a truncated data section, an empty or unknown `POINT:UNITS`
//! read as millimetres, an invalid `POINT:RATE`) is reported in [`C3dFile::warnings`] for the
//! caller to show; a file with no valid frame rate at all reads (its parameters and analog
//! data are not lost) but [`C3dFile::to_take`] refuses it rather than invent one.

mod params;
mod processor;
mod read;
mod write;

pub use params::{Group, ParamData, Parameter, Parameters, Record};
pub use processor::Processor;
pub use read::{ReadOptions, read, read_path, read_path_with, read_with};
pub use write::{write, write_path};

use crate::{Error, Result};
use locap_core::provenance::{self, Provenance, ProvenanceError};
use locap_core::take::SampleQuality;
use locap_core::{LengthUnit, MarkerName, Take, UpAxis, Vec3};

/// How numbers of the data section are stored (the sign of `POINT:SCALE`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    /// 16-bit integers, coordinates multiplied by `|POINT:SCALE|`.
    Int,
    /// 32-bit floats.
    Float,
}

/// One event stored in the header (C3D header words 150-234).
#[derive(Debug, Clone, PartialEq)]
pub struct HeaderEvent {
    /// Event time in seconds.
    pub time_s: f32,
    /// Display flag (0 = off).
    pub display: u8,
    /// Four-character label.
    pub label: [u8; 4],
}

/// The fields of the 512-byte header that locap interprets; the rest is carried through.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// First byte of the file: the 1-based block of the parameter section.
    pub parameter_block: u8,
    /// Number of 3D points (word 2).
    pub point_count: u16,
    /// Analog samples per 3D frame, all channels together (word 3).
    pub analog_per_frame: u16,
    /// First frame number (word 4).
    pub first_frame: u16,
    /// Last frame number (word 5; overflows on long takes, see [`C3dFile::frames`]).
    pub last_frame: u16,
    /// Maximum interpolation gap (word 6).
    pub max_gap: u16,
    /// Point scale factor (words 7-8), negative for float storage.
    pub scale: f32,
    /// 1-based block of the data section (word 9).
    pub data_block: u16,
    /// Analog samples per channel per 3D frame (word 10).
    pub analog_per_channel: u16,
    /// 3D frame rate in Hz (words 11-12).
    pub frame_rate_hz: f32,
    /// Whether 4-character event labels are used (word 150 = 12345).
    pub events_key: bool,
    /// Events (at most 18).
    pub events: Vec<HeaderEvent>,
    /// The 512 bytes as read, for the bytes locap does not interpret.
    pub raw: Vec<u8>,
}

/// The raw analog samples: per 3D frame, `analog_per_frame` values (sub-sample major,
/// channel minor), exactly as stored.
#[derive(Debug, Clone, PartialEq)]
pub enum AnalogSamples {
    /// Integer storage (interpreted as unsigned when `ANALOG:FORMAT` is `UNSIGNED`).
    Int(Vec<i16>),
    /// Float storage.
    Float(Vec<f32>),
}

impl AnalogSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        match self {
            AnalogSamples::Int(v) => v.len(),
            AnalogSamples::Float(v) => v.len(),
        }
    }

    /// True if there are no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A whole C3D file.
#[derive(Debug, Clone, PartialEq)]
pub struct C3dFile {
    /// Processor type of the file as read (written files are always Intel).
    pub processor: Processor,
    /// Header fields.
    pub header: Header,
    /// Parameter section.
    pub parameters: Parameters,
    /// Storage of the data section.
    pub storage: Storage,
    /// Number of 3D frames.
    pub frames: usize,
    /// Number of 3D points per frame.
    pub point_count: usize,
    /// Point words, frame-major: `[x, y, z, residual word]` in the file's point unit (integer
    /// coordinates already multiplied by the scale; the residual word as stored).
    pub points: Vec<[f32; 4]>,
    /// Analog samples.
    pub analog: AnalogSamples,
    /// Data sections of other groups (for example Theia's `ROTATION` matrices), located by
    /// their own `GROUP:DATA_START` parameter, carried through byte for byte.
    pub extra_sections: Vec<ExtraSection>,
    /// Things that were odd but readable (header and parameters disagreeing, ...).
    pub warnings: Vec<String>,
}

/// A data section that locap does not interpret, found through `GROUP:DATA_START`.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraSection {
    /// The group whose `DATA_START` points at it.
    pub group: String,
    /// Its bytes, from its first block to the next section or the end of the file.
    pub bytes: Vec<u8>,
}

/// Summary of the analog channels of a file.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalogInfo {
    /// Channel labels.
    pub labels: Vec<String>,
    /// Channel units.
    pub units: Vec<String>,
    /// Analog sample rate in Hz.
    pub rate_hz: f64,
    /// Samples per channel per 3D frame.
    pub samples_per_frame: usize,
}

impl C3dFile {
    /// Point labels: `POINT:LABELS`, `LABELS2`, ..., completed with `*N` for unnamed points.
    pub fn point_labels(&self) -> Vec<String> {
        let mut labels = self.parameters.continued_strings("POINT", "LABELS");
        labels.truncate(self.point_count);
        while labels.len() < self.point_count {
            labels.push(format!("*{}", labels.len()));
        }
        for (i, l) in labels.iter_mut().enumerate() {
            if l.is_empty() {
                *l = format!("*{i}");
            }
        }
        labels
    }

    /// Unit of point coordinates (`POINT:UNITS`; millimetres if absent or unknown).
    pub fn point_unit(&self) -> LengthUnit {
        self.parameters
            .get("POINT", "UNITS")
            .and_then(|p| p.strings().first().and_then(|s| LengthUnit::parse(s)))
            .unwrap_or(LengthUnit::Millimetre)
    }

    /// Magnitude of the point scale factor (`POINT:SCALE`, else the header's).
    pub fn point_scale(&self) -> f32 {
        Self::point_scale_of(&self.parameters, self.header.scale)
    }

    pub(crate) fn point_scale_of(parameters: &Parameters, header_scale: f32) -> f32 {
        let s = parameters
            .get("POINT", "SCALE")
            .and_then(|p| p.as_f64())
            .map(|s| s as f32)
            .filter(|s| s.is_finite() && *s != 0.0)
            .unwrap_or(header_scale);
        if s.is_finite() && s != 0.0 { s.abs() } else { 1.0 }
    }

    /// 3D frame rate in Hz (`POINT:RATE`, else the header's).
    pub fn frame_rate_hz(&self) -> f64 {
        self.parameters
            .get("POINT", "RATE")
            .and_then(|p| p.as_f64())
            .filter(|r| r.is_finite() && *r > 0.0)
            .unwrap_or(self.header.frame_rate_hz as f64)
    }

    /// First frame number (`TRIAL:ACTUAL_START_FIELD` if present, else the header's).
    pub fn first_frame(&self) -> u32 {
        trial_field(&self.parameters, "ACTUAL_START_FIELD").unwrap_or(self.header.first_frame as u32)
    }

    /// Which axis is up, from `POINT:Y_SCREEN` (`+Y` means Y-up); Z-up by default.
    pub fn up_axis(&self) -> UpAxis {
        match self.parameters.get("POINT", "Y_SCREEN").and_then(|p| p.strings().into_iter().next()) {
            Some(s) if s.trim().ends_with('Y') => UpAxis::Y,
            _ => UpAxis::Z,
        }
    }

    /// Analog channel summary.
    pub fn analog_info(&self) -> AnalogInfo {
        let channels = self
            .parameters
            .get("ANALOG", "USED")
            .and_then(|p| p.as_i64())
            .filter(|c| *c > 0)
            // A float ANALOG:USED can say 1e9 channels (fuzzer-found: the label vectors below
            // took gigabytes); a frame holds at most 65535 samples (header word 3).
            .map(|c| c.min(u16::MAX as i64) as usize)
            .unwrap_or(0);
        let samples_per_frame = match (channels, self.header.analog_per_frame as usize) {
            (0, _) => 0,
            (c, n) => n / c,
        };
        let rate_hz = self
            .parameters
            .get("ANALOG", "RATE")
            .and_then(|p| p.as_f64())
            .filter(|r| r.is_finite() && *r > 0.0)
            .unwrap_or(self.frame_rate_hz() * samples_per_frame as f64);
        let mut labels = self.parameters.continued_strings("ANALOG", "LABELS");
        labels.resize(channels, String::new());
        let mut units = self.parameters.continued_strings("ANALOG", "UNITS");
        units.resize(channels, String::new());
        AnalogInfo { labels, units, rate_hz, samples_per_frame }
    }

    /// Vendor / manufacturer, from `MANUFACTURER:COMPANY` and `SOFTWARE`, if recorded.
    pub fn manufacturer(&self) -> Option<String> {
        let company = self.parameters.get("MANUFACTURER", "COMPANY").and_then(|p| p.strings().into_iter().next());
        let software = self.parameters.get("MANUFACTURER", "SOFTWARE").and_then(|p| p.strings().into_iter().next());
        match (company, software) {
            (Some(c), Some(s)) if !s.is_empty() => Some(format!("{c} ({s})")),
            (Some(c), _) if !c.is_empty() => Some(c),
            (_, Some(s)) if !s.is_empty() => Some(s),
            _ => None,
        }
    }

    /// The marker take: positions in millimetres, missing samples explicit (see the module
    /// doc for the rules), residuals and camera masks kept as [`SampleQuality`]. Fails if the
    /// file has no valid frame rate (NaN, zero or negative in both `POINT:RATE` and header).
    pub fn to_take(&self) -> Result<Take> {
        let names: Vec<MarkerName> = self.point_labels().iter().map(|l| MarkerName::parse(l)).collect();
        let mm = self.point_unit().mm_per_unit();
        let scale = self.point_scale();
        let rate = self.frame_rate_hz();
        // A take needs a time base; inventing one (this used to become 1 Hz) would make every
        // velocity and gap length downstream wrong without a word. No shared vendor file
        // lacks a valid rate.
        if !(rate.is_finite() && rate > 0.0) {
            return Err(Error::Binary {
                format: "C3D",
                section: "header".to_string(),
                offset: 20,
                message: format!(
                    "no frame rate: POINT:RATE is absent or not positive and the header (words 11-12) says {} Hz",
                    self.header.frame_rate_hz
                ),
            });
        }
        let mut take = Take::empty(names, self.frames, rate)?;
        take.first_frame = self.first_frame();
        take.up_axis = self.up_axis();
        let m = self.point_count;
        for (i, w) in self.points.iter().enumerate() {
            if let Some(p) = decode_position(w) {
                let (frame, marker) = (i / m, i % m);
                take.set_position_mm(frame, marker, Some(p * mm))?;
                let word = w[3] as i32;
                take.set_quality(
                    frame,
                    marker,
                    SampleQuality {
                        residual_mm: (word & 0xff) as f32 * scale * mm as f32,
                        cameras: ((word >> 8) & 0xff) as u8,
                    },
                );
            }
        }
        Ok(take)
    }

    /// What locap recorded in this file's `LOCAP` group about `take` (the file's own take,
    /// or one of the same markers and frames); empty for a file locap did not change.
    ///
    /// # Errors
    /// A `LOCAP` list that is corrupt or does not fit `take` (see
    /// [`Provenance::from_parameters`]).
    pub fn provenance(&self, take: &Take) -> std::result::Result<Provenance, ProvenanceError> {
        Provenance::from_parameters(take, |name| self.parameters.continued_strings(provenance::GROUP, name))
    }

    /// Stores `record` (about `take`, the take this file holds) in the `LOCAP` group,
    /// replacing the lists an earlier run left.
    ///
    /// # Errors
    /// A list past the compact form's ceiling.
    pub fn set_provenance(&mut self, take: &Take, record: &Provenance) -> std::result::Result<(), ProvenanceError> {
        for (name, strings) in record.to_parameters(take)? {
            if name == "METHOD" {
                self.parameters.set_strings(provenance::GROUP, name, &strings);
            } else {
                self.parameters.set_continued_strings(provenance::GROUP, name, &strings);
            }
        }
        Ok(())
    }

    /// Puts `take`, this file's own take changed (cleaned, relabeled), back into the file with
    /// `record` of what changed in the `LOCAP` group, and writes the file atomically to
    /// `output`; every other parameter and the analog data stay as read. `locap clean` and the
    /// Python bindings write a changed take through this one call, so both give the same bytes.
    ///
    /// # Errors
    /// The take does not fit the file ([`C3dFile::set_take`]; named after `input`, the file
    /// this one was read from), a `LOCAP` list past its ceiling or a failed write (named after
    /// `output`).
    pub fn write_changed(
        &mut self,
        take: &Take,
        record: Option<&Provenance>,
        input: &std::path::Path,
        output: &std::path::Path,
    ) -> Result<()> {
        self.set_take(take).map_err(|e| e.in_file(input))?;
        if let Some(record) = record {
            self.set_provenance(take, record).map_err(|e| Error::from(e).in_file(output))?;
        }
        write_path(self, output)
    }

    /// Replaces the point data with `take` (positions converted back to the file's unit).
    /// Marker count and names may change (relabeling); the frame count may change only if
    /// the file has no analog data, since analog samples are tied to 3D frames.
    pub fn set_take(&mut self, take: &Take) -> Result<()> {
        let frames = take.frame_count();
        if frames != self.frames && !self.analog.is_empty() {
            return Err(Error::Unwritable(format!(
                "the take has {frames} frames but the file's analog data covers {}; \
                 cutting analog data is not supported",
                self.frames
            )));
        }
        let mm = self.point_unit().mm_per_unit();
        let scale = self.point_scale();
        let m = take.marker_count();
        let mut points = Vec::with_capacity(frames * m);
        for f in 0..frames {
            for k in 0..m {
                points.push(match take.position_mm(f, k) {
                    Some(p) => {
                        let q = take.quality(f, k);
                        let residual = (q.residual_mm as f64 / mm / scale as f64).round().clamp(0.0, 255.0) as i32;
                        let word = ((q.cameras as i32) << 8) | residual;
                        let p = p / mm;
                        [p.x as f32, p.y as f32, p.z as f32, word as f32]
                    }
                    None => [0.0, 0.0, 0.0, -1.0],
                });
            }
        }
        let labels: Vec<String> = take.markers().iter().map(|n| n.full()).collect();
        if labels != self.point_labels() {
            self.parameters.set_continued_strings("POINT", "LABELS", &labels);
        }
        if let Some(desc) = self.parameters.get("POINT", "DESCRIPTIONS") {
            let mut d = desc.strings();
            if d.len() != m {
                d.resize(m, String::new());
                self.parameters.set_continued_strings("POINT", "DESCRIPTIONS", &d);
            }
        }
        self.points = points;
        self.point_count = m;
        self.frames = frames;
        self.set_first_frame(take.first_frame);
        Ok(())
    }

    /// Keeps only frames `range` (0-based indices into the file's frames): points, analog
    /// samples and the first-frame bookkeeping. Fails for files with extra data sections,
    /// whose per-frame layout locap does not know.
    pub fn cut_frames(&mut self, range: std::ops::Range<usize>) -> Result<()> {
        if range.start >= range.end || range.end > self.frames {
            return Err(Error::Unwritable(format!(
                "frame range {}..{} is empty or outside the take's {} frames",
                range.start, range.end, self.frames
            )));
        }
        if !self.extra_sections.is_empty() {
            return Err(Error::Unsupported("cutting a file with extra data sections (e.g. ROTATION)".into()));
        }
        let m = self.point_count;
        self.points = self.points[range.start * m..range.end * m].to_vec();
        let a = self.header.analog_per_frame as usize;
        self.analog = match &self.analog {
            AnalogSamples::Int(v) => AnalogSamples::Int(v[range.start * a..range.end * a].to_vec()),
            AnalogSamples::Float(v) => AnalogSamples::Float(v[range.start * a..range.end * a].to_vec()),
        };
        let first = self.first_frame().saturating_add(range.start as u32);
        self.frames = range.end - range.start;
        self.set_first_frame(first);
        Ok(())
    }

    /// Sets the first frame number: the header word, and `TRIAL:ACTUAL_START_FIELD` if the
    /// file has it or the number needs its 32 bits.
    fn set_first_frame(&mut self, first: u32) {
        self.header.first_frame = first.min(u16::MAX as u32) as u16;
        match self.parameters.get_mut("TRIAL", "ACTUAL_START_FIELD") {
            Some(p) => set_trial_field(p, first),
            None if first > u16::MAX as u32 => {
                let words = vec![(first & 0xffff) as u16 as i16, (first >> 16) as u16 as i16];
                self.parameters.set("TRIAL", "ACTUAL_START_FIELD", vec![2], ParamData::Int(words));
            }
            None => {}
        }
    }

    /// A new file holding just `take` (float storage, millimetres, no analog data), for
    /// converting other formats to C3D.
    pub fn from_take(take: &Take) -> Result<C3dFile> {
        let mut parameters = Parameters::default();
        let rate = take.frame_rate_hz() as f32;
        parameters.set("POINT", "USED", vec![], ParamData::Int(vec![0]));
        parameters.set("POINT", "SCALE", vec![], ParamData::Float(vec![-0.1]));
        parameters.set("POINT", "RATE", vec![], ParamData::Float(vec![rate]));
        parameters.set("POINT", "DATA_START", vec![], ParamData::Int(vec![0]));
        parameters.set("POINT", "FRAMES", vec![], ParamData::Int(vec![0]));
        parameters.set_strings("POINT", "UNITS", &["mm".to_string()]);
        parameters.set_continued_strings("POINT", "LABELS", &[]);
        parameters.set_strings("POINT", "X_SCREEN", &["+X".to_string()]);
        let up = match take.up_axis {
            UpAxis::Y => "+Y",
            UpAxis::Z => "+Z",
        };
        parameters.set_strings("POINT", "Y_SCREEN", &[up.to_string()]);
        parameters.set("ANALOG", "USED", vec![], ParamData::Int(vec![0]));
        parameters.set("ANALOG", "RATE", vec![], ParamData::Float(vec![rate]));
        parameters.set_strings("MANUFACTURER", "SOFTWARE", &[format!("locap {}", env!("CARGO_PKG_VERSION"))]);
        let mut file = C3dFile {
            processor: Processor::Intel,
            header: Header {
                parameter_block: 2,
                point_count: 0,
                analog_per_frame: 0,
                first_frame: 1,
                last_frame: 0,
                max_gap: 0,
                scale: -0.1,
                data_block: 0,
                // One analog sample per channel per frame, matching ANALOG:RATE = POINT:RATE
                // above (with no channels, no analog data either way); a 0 here contradicts
                // that rate, and py-c3d refuses such files ("inconsistent analog rate").
                analog_per_channel: 1,
                frame_rate_hz: rate,
                events_key: true,
                events: Vec::new(),
                raw: vec![0; 512],
            },
            parameters,
            storage: Storage::Float,
            frames: 0,
            point_count: 0,
            points: Vec::new(),
            analog: AnalogSamples::Float(Vec::new()),
            extra_sections: Vec::new(),
            warnings: Vec::new(),
        };
        file.set_take(take)?;
        Ok(file)
    }
}

/// Position of a point word in the file's unit, or `None` if the sample is missing.
fn decode_position(w: &[f32; 4]) -> Option<Vec3> {
    let finite = w[0].is_finite() && w[1].is_finite() && w[2].is_finite();
    let all_zero = w[0] == 0.0 && w[1] == 0.0 && w[2] == 0.0;
    // A NaN residual counts as missing too.
    let residual_ok = w[3] >= 0.0;
    if !finite || all_zero || !residual_ok {
        return None;
    }
    Some(Vec3::new(w[0] as f64, w[1] as f64, w[2] as f64))
}

/// Reads a `TRIAL:ACTUAL_*_FIELD` parameter: two 16-bit words forming an unsigned 32-bit
/// frame number (low word first), the C3D way of numbering frames past 65535.
fn trial_field(params: &Parameters, name: &str) -> Option<u32> {
    let p = params.get("TRIAL", name)?;
    match &p.data {
        ParamData::Int(v) if v.len() >= 2 => Some(v[0] as u16 as u32 | ((v[1] as u16 as u32) << 16)),
        ParamData::Int(v) if v.len() == 1 => Some(v[0] as u16 as u32),
        ParamData::Float(v) => v.first().filter(|x| x.is_finite() && **x >= 0.0).map(|x| *x as u32),
        _ => None,
    }
    .filter(|f| *f > 0)
}

fn set_trial_field(p: &mut Parameter, frame: u32) {
    match &mut p.data {
        ParamData::Int(v) if v.len() >= 2 => {
            v[0] = (frame & 0xffff) as u16 as i16;
            v[1] = (frame >> 16) as u16 as i16;
        }
        ParamData::Int(v) if v.len() == 1 => v[0] = frame.min(u16::MAX as u32) as u16 as i16,
        ParamData::Float(v) if !v.is_empty() => v[0] = frame as f32,
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn take() -> Take {
        let names = vec![MarkerName::parse("Sub:A"), MarkerName::parse("B")];
        let p = |x: f64| Some(Vec3::new(x, -2.5 * x, 1000.0 + x));
        Take::from_samples(names, &[p(1.0), None, p(2.0), p(3.0), None, p(4.5)], 240.0).unwrap()
    }

    fn reread(file: &C3dFile) -> C3dFile {
        let mut bytes = Vec::new();
        write(file, &mut bytes).unwrap();
        assert_eq!(bytes.len() % 512, 0);
        read(&bytes).unwrap()
    }

    #[test]
    fn float_round_trip_is_exact() {
        let t = take();
        let back = reread(&C3dFile::from_take(&t).unwrap());
        assert_eq!(back.to_take().unwrap().validity(), t.validity());
        assert_eq!(back.to_take().unwrap().markers(), t.markers());
        assert_eq!(back.frame_rate_hz(), 240.0);
        assert_eq!(back.to_take().unwrap().position_mm(2, 1), t.position_mm(2, 1));
    }

    #[test]
    fn metre_files_are_converted_both_ways() {
        let t = take();
        let mut file = C3dFile::from_take(&t).unwrap();
        file.parameters.set_strings("POINT", "UNITS", &["m".to_string()]);
        file.set_take(&t).unwrap();
        // Stored in metres...
        assert!((file.points[0][2] - 1.001).abs() < 1e-6);
        // ...read back in millimetres.
        let back = reread(&file).to_take().unwrap();
        let (a, b) = (back.position_mm(0, 0).unwrap(), t.position_mm(0, 0).unwrap());
        assert!((a - b).amax() < 1e-3, "{a:?} vs {b:?}");
    }

    #[test]
    fn integer_files_stay_integer_when_they_fit() {
        let t = take();
        let mut file = C3dFile::from_take(&t).unwrap();
        file.storage = Storage::Int;
        file.parameters.set("POINT", "SCALE", vec![], ParamData::Float(vec![0.1]));
        file.set_take(&t).unwrap();
        let back = reread(&file);
        assert_eq!(back.storage, Storage::Int);
        let (a, b) = (back.to_take().unwrap().position_mm(1, 1).unwrap(), t.position_mm(1, 1).unwrap());
        assert!((a - b).amax() <= 0.05 + 1e-6);
        // A coordinate beyond 32767 * 0.1 mm does not fit: the file becomes float, losslessly.
        let mut far = t.clone();
        far.set_position_mm(0, 0, Some(Vec3::new(5000.0, 0.0, 0.0))).unwrap();
        file.set_take(&far).unwrap();
        let back = reread(&file);
        assert_eq!(back.storage, Storage::Float);
        assert_eq!(back.to_take().unwrap().position_mm(0, 0), Some(Vec3::new(5000.0, 0.0, 0.0)));
    }

    #[test]
    fn relabeling_rewrites_labels_and_keeps_other_parameters() {
        let t = take();
        let mut file = C3dFile::from_take(&t).unwrap();
        file.parameters.set_strings("SUBJECTS", "NAMES", &["Sub".to_string()]);
        let mut relabeled = t.clone();
        relabeled.set_markers(vec![MarkerName::parse("Sub:LFWT"), MarkerName::parse("Sub:RFWT")]).unwrap();
        file.set_take(&relabeled).unwrap();
        let back = reread(&file);
        assert_eq!(back.point_labels(), vec!["Sub:LFWT", "Sub:RFWT"]);
        assert_eq!(back.parameters.get("SUBJECTS", "NAMES").unwrap().strings(), vec!["Sub"]);
    }

    fn long_take(frames: usize) -> C3dFile {
        let names = vec![MarkerName::parse("A")];
        let samples: Vec<Option<Vec3>> = (0..frames).map(|f| Some(Vec3::new(f as f64, 1.0, 2.0))).collect();
        C3dFile::from_take(&Take::from_samples(names, &samples, 120.0).unwrap()).unwrap()
    }

    #[test]
    fn long_takes_are_numbered_for_every_reader() {
        let frames = 70_000;
        let mut bytes = Vec::new();
        write(&long_take(frames), &mut bytes).unwrap();
        let back = read(&bytes).unwrap();
        assert_eq!((back.frames, back.first_frame()), (frames, 1));
        assert_eq!(back.points[frames - 1][0], (frames - 1) as f32);
        assert_eq!((back.header.first_frame, back.header.last_frame), (1, 65535));
        let p = &back.parameters;
        assert_eq!(p.get("POINT", "FRAMES").unwrap().data, ParamData::Int(vec![-1]));
        assert_eq!(p.get("POINT", "LONG_FRAMES").unwrap().data, ParamData::Float(vec![frames as f32]));
        assert_eq!(p.get("TRIAL", "ACTUAL_END_FIELD").unwrap().data, ParamData::Int(vec![4464, 1]));
        // "To the end of the file" for ezc3d: no zero padding it would read as frames.
        assert_eq!(bytes.len(), (back.header.data_block as usize - 1) * 512 + frames * 16);
    }

    #[test]
    fn long_frames_alone_gives_the_frame_count() {
        // A C-Motion style file: POINT:LONG_FRAMES but no TRIAL fields (renamed away here).
        let frames = 70_000;
        let mut bytes = Vec::new();
        write(&long_take(frames), &mut bytes).unwrap();
        let at = bytes.windows(5).position(|w| w == b"TRIAL").unwrap();
        bytes[at..at + 5].copy_from_slice(b"XRIAL");
        let back = read(&bytes).unwrap();
        assert_eq!(back.frames, frames);
    }

    #[test]
    fn short_takes_get_no_long_take_parameters() {
        let mut bytes = Vec::new();
        write(&long_take(100), &mut bytes).unwrap();
        let back = read(&bytes).unwrap();
        assert!(back.parameters.get("POINT", "LONG_FRAMES").is_none());
        assert!(back.parameters.group_id("TRIAL").is_none());
        assert_eq!((back.header.first_frame, back.header.last_frame), (1, 100));
        assert_eq!(bytes.len() % 512, 0);
    }

    #[test]
    fn frame_numbers_past_65535_use_the_trial_fields() {
        // 100 frames numbered 65500..65599: the header words cannot hold the last one.
        let mut file = long_take(100);
        file.header.first_frame = 65500;
        let mut bytes = Vec::new();
        write(&file, &mut bytes).unwrap();
        let back = read(&bytes).unwrap();
        assert_eq!((back.frames, back.first_frame()), (100, 65500));
        assert_eq!((back.header.first_frame, back.header.last_frame), (1, 100));
    }

    #[test]
    fn first_frames_past_65535_survive_set_take() {
        let mut take = long_take(10).to_take().unwrap();
        take.first_frame = 100_000;
        let file = C3dFile::from_take(&take).unwrap();
        let mut bytes = Vec::new();
        write(&file, &mut bytes).unwrap();
        let back = read(&bytes).unwrap();
        assert_eq!((back.frames, back.first_frame()), (10, 100_000));
    }

    #[test]
    fn parameter_sections_past_255_blocks_are_written() {
        let mut file = long_take(10);
        let lines: Vec<String> = (0..20_000).map(|i| format!("A {i}-{i}")).collect();
        file.parameters.set_continued_strings("LOCAP", "FILLED", &lines);
        let mut bytes = Vec::new();
        write(&file, &mut bytes).unwrap();
        assert_eq!(bytes[512 + 2], 255, "the one-byte block count saturates");
        let back = read(&bytes).unwrap();
        assert!(back.header.data_block > 257);
        assert_eq!(back.parameters.continued_strings("LOCAP", "FILLED"), lines);
        assert_eq!(back.frames, 10);
    }

    #[test]
    fn frame_count_change_with_analog_is_refused() {
        let t = take();
        let mut file = C3dFile::from_take(&t).unwrap();
        file.header.analog_per_frame = 2;
        file.analog = AnalogSamples::Float(vec![0.5; 2 * t.frame_count()]);
        let err = file.set_take(&t.slice_frames(0..2)).unwrap_err().to_string();
        assert!(err.contains("analog"), "{err}");
    }
}
