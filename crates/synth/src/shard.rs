//! Training shards: one synthesized take as a compact binary file that training reads in
//! chunks of frames, without parsing C3D or BVH and without holding the whole take.
//!
//! # Format (version 1, all numbers little-endian)
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `LOCAPSHD` |
//! | 4 | `u32` format version (1) |
//! | 4 | `u32` header length `H` in bytes |
//! | `H` | UTF-8 JSON [`ShardHeader`]: frame count, frame rate, marker and joint names, record layout, skeleton |
//! | 0-3 | zero padding so the frame records start at a multiple of 4 bytes |
//! | `T x R x 4` | `T` frame records of `R = 7M + 7J` `f32` each |
//!
//! One frame record holds, in this order (`M` markers, `J` joints):
//! 1. `clean_mm[M][3]`: ground-truth marker positions, lab frame, mm;
//! 2. `observed_mm[M][3]`: the corrupted markers (occluded samples are 0, shifted ones moved);
//! 3. `visible[M]`: 1.0 where the observed sample exists, 0.0 where it is occluded;
//! 4. `joint_positions_mm[J][3]`: global joint positions from forward kinematics, in the same
//!    lab frame as the markers;
//! 5. `joint_rotations[J][4]`: *local* joint rotations as unit quaternions `(x, y, z, w)`
//!    (the root's relative to the motion's world frame, Y-up for CMU).
//!
//! The header's optional `skeleton` (joint names, parents, subject-scaled rest offsets in mm,
//! in the motion's frame) lets a solver run forward kinematics on the rotations; shards written
//! before it existed read with `skeleton: None`.
//!
//! Fixed-size records make the file seekable (`offset = data_start + frame * R * 4`) and
//! memory-mappable; [`ShardReader`] streams it in chunks from any `Read`, and [`Record`] is
//! the one decoder of the record layout (consumers never index records by hand). Consumers
//! that want the whole take (training reads every shard once) call
//! [`ShardReader::read_clean`] or [`ShardReader::read_all`], the one place where records
//! become [`Take`]s and joint arrays.
//!
//! # Reading untrusted shards
//! A shard is input like any other: the reader checks every count in the header against
//! documented ceilings ([`MAX_HEADER_BYTES`], [`MAX_MARKERS`], [`MAX_JOINTS`]) and, given the
//! file's length ([`ShardReader::with_len`]), the frame count against the bytes that are
//! there, before anything is allocated from them. A shard with trailing bytes after its last
//! record is refused too: the writer never makes one, so it means a header that undercounts.

use crate::synthesize::LabFrame;
use locap_core::{MarkerName, Motion, Quat, Skeleton, Take, TakeError, Vec3};
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};

/// The magic bytes at the start of a shard.
pub const MAGIC: &[u8; 8] = b"LOCAPSHD";
/// The format version written.
pub const VERSION: u32 = 1;
/// Largest header read, bytes (16 MiB: a 4,096-marker, 1,024-joint header is under 0.5 MiB).
pub const MAX_HEADER_BYTES: u32 = 16 << 20;
/// Most markers a shard may declare (body, hands and face sets have a few hundred at most).
pub const MAX_MARKERS: usize = 4096;
/// Most joints a shard may declare (CMU skeletons have 31, detailed hands add about 40).
pub const MAX_JOINTS: usize = 1024;
/// Largest chunk [`ShardReader::next_chunk`] reads at once, bytes (64 MiB); one record of the
/// largest shard is under 0.2 MiB, so every chunk holds at least one frame.
pub const MAX_CHUNK_BYTES: usize = 64 << 20;

/// Errors reading or writing shards.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// Reading or writing failed.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// Not a shard.
    #[error("not a locap training shard (magic {0:?}, expected \"LOCAPSHD\")")]
    BadMagic([u8; 8]),
    /// A version this reader does not know.
    #[error("shard format version {0} is not supported (this reader knows version 1)")]
    Version(u32),
    /// A header that is too long, not JSON, or inconsistent.
    #[error("bad shard header: {0}")]
    Header(String),
    /// The file ends early (in the header, or in the frame named).
    #[error("the shard is cut short: it ends inside {0}")]
    Truncated(String),
    /// The file's length is not what its header promises.
    #[error("the shard's size does not match its header: {0}")]
    Size(String),
    /// The takes and motion given to the writer do not line up.
    #[error("cannot write shard: {0}")]
    Shape(String),
    /// Memory cannot hold the samples the (length-checked) header announces.
    #[error("cannot hold the shard's {samples} samples")]
    Memory {
        /// Samples (marker or joint values per frame, times frames) announced.
        samples: usize,
        /// What the allocator said.
        #[source]
        source: std::collections::TryReserveError,
    },
    /// The records do not make a take (a frame rate or sample the take refuses).
    #[error("the shard's markers do not make a take")]
    Take(#[source] TakeError),
}

/// The JSON header of a shard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardHeader {
    /// Number of frame records.
    pub frames: usize,
    /// Frame rate, Hz.
    pub frame_rate_hz: f64,
    /// Marker labels, record order.
    pub markers: Vec<String>,
    /// Joint names, record order (empty without motion).
    pub joints: Vec<String>,
    /// Names of the record fields in order (documentation for readers in other languages).
    pub record: Vec<String>,
    /// Lab frame of marker and joint positions.
    pub lab: LabFrame,
    /// The (subject-scaled) skeleton of the joints, in [`ShardHeader::joints`] order; `None`
    /// without motion and in shards written before this field existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skeleton: Option<Skeleton>,
}

impl ShardHeader {
    /// Number of `f32` in one frame record.
    pub fn record_len(&self) -> usize {
        7 * self.markers.len() + 7 * self.joints.len()
    }

    /// Bytes of all frame records, `None` if that overflows a `u64`.
    pub fn data_len(&self) -> Option<u64> {
        (self.frames as u64).checked_mul(4 * self.record_len() as u64)
    }
}

/// Writes one shard: `clean` (ground truth) and `observed` (corrupted) takes of the same
/// markers and frames, and optionally the `motion` they come from (same frame count).
pub fn write_shard(
    w: &mut dyn Write,
    clean: &Take,
    observed: &Take,
    motion: Option<&Motion>,
    lab: LabFrame,
) -> Result<(), ShardError> {
    let (t, m) = (clean.frame_count(), clean.marker_count());
    if observed.frame_count() != t || observed.marker_count() != m {
        return Err(ShardError::Shape(format!(
            "clean take is {t} x {m}, observed take is {} x {}",
            observed.frame_count(),
            observed.marker_count()
        )));
    }
    if let Some(mo) = motion
        && mo.frame_count() != t
    {
        return Err(ShardError::Shape(format!("take has {t} frames, motion has {}", mo.frame_count())));
    }
    // Never write what the reader refuses.
    let j = motion.map_or(0, |mo| mo.skeleton.len());
    if m == 0 || m > MAX_MARKERS || j > MAX_JOINTS {
        return Err(ShardError::Shape(format!(
            "{m} markers and {j} joints (1 to {MAX_MARKERS} markers, at most {MAX_JOINTS} joints)"
        )));
    }
    let header = ShardHeader {
        frames: t,
        frame_rate_hz: clean.frame_rate_hz(),
        markers: clean.markers().iter().map(|n| n.label.clone()).collect(),
        joints: motion.map(|mo| mo.skeleton.joints().iter().map(|j| j.name.clone()).collect()).unwrap_or_default(),
        record: [
            "clean_mm[M][3]",
            "observed_mm[M][3]",
            "visible[M]",
            "joint_positions_mm[J][3]",
            "joint_rotations_xyzw[J][4]",
        ]
        .map(String::from)
        .to_vec(),
        lab,
        skeleton: motion.map(|mo| mo.skeleton.clone()),
    };
    let json = serde_json::to_vec(&header).map_err(|e| ShardError::Header(e.to_string()))?;
    w.write_all(MAGIC)?;
    w.write_all(&VERSION.to_le_bytes())?;
    w.write_all(&(json.len() as u32).to_le_bytes())?;
    w.write_all(&json)?;
    w.write_all(&[0u8; 3][..(4 - json.len() % 4) % 4])?;
    let mut record: Vec<u8> = Vec::with_capacity(header.record_len() * 4);
    let push = |record: &mut Vec<u8>, v: f64| record.extend_from_slice(&(v as f32).to_le_bytes());
    for f in 0..t {
        record.clear();
        for k in 0..m {
            let p = clean.position_mm(f, k).unwrap_or_default();
            (0..3).for_each(|i| push(&mut record, p[i]));
        }
        for k in 0..m {
            let p = observed.position_mm(f, k).unwrap_or_default();
            (0..3).for_each(|i| push(&mut record, p[i]));
        }
        for k in 0..m {
            push(&mut record, if observed.is_valid(f, k) { 1.0 } else { 0.0 });
        }
        if let Some(mo) = motion {
            let pose = mo.forward_kinematics(f);
            for p in &pose.positions_mm {
                let p = lab.to_lab(*p);
                (0..3).for_each(|i| push(&mut record, p[i]));
            }
            for q in mo.local_rotations(f) {
                let c = q.coords;
                (0..4).for_each(|i| push(&mut record, c[i]));
            }
        }
        w.write_all(&record)?;
    }
    Ok(())
}

/// A chunk of consecutive frame records.
#[derive(Debug, Clone, PartialEq)]
pub struct Chunk {
    /// Index of the first frame of the chunk.
    pub first_frame: usize,
    /// Number of frames.
    pub frames: usize,
    /// `frames x record_len` values, record after record.
    pub data: Vec<f32>,
    markers: usize,
    joints: usize,
}

impl Chunk {
    /// The chunk's frame records, typed: the one place that knows the record layout.
    pub fn records(&self) -> impl ExactSizeIterator<Item = Record<'_>> {
        let len = 7 * (self.markers + self.joints);
        // `ShardReader` refuses shards without markers, so `len` is never 0.
        self.data.chunks_exact(len).map(|values| Record { values, markers: self.markers, joints: self.joints })
    }
}

/// One frame record (see the module docs for the layout).
#[derive(Debug, Clone, Copy)]
pub struct Record<'a> {
    values: &'a [f32],
    markers: usize,
    joints: usize,
}

impl<'a> Record<'a> {
    fn triples(values: &'a [f32]) -> impl ExactSizeIterator<Item = [f32; 3]> + 'a {
        values.as_chunks::<3>().0.iter().copied()
    }

    /// Ground-truth marker positions, mm, header marker order.
    pub fn clean_mm(&self) -> impl ExactSizeIterator<Item = [f32; 3]> + 'a {
        Record::triples(&self.values[..3 * self.markers])
    }

    /// Corrupted marker positions, mm (occluded samples are zeros: see [`Record::observed_mm`]).
    pub fn observed_raw_mm(&self) -> impl ExactSizeIterator<Item = [f32; 3]> + 'a {
        Record::triples(&self.values[3 * self.markers..6 * self.markers])
    }

    /// Whether each observed sample exists (the stored flag is 1.0 or 0.0; above 0.5 counts).
    pub fn visible(&self) -> impl ExactSizeIterator<Item = bool> + 'a {
        self.values[6 * self.markers..7 * self.markers].iter().map(|v| *v > 0.5)
    }

    /// Corrupted marker positions, mm, `None` where occluded.
    pub fn observed_mm(&self) -> impl ExactSizeIterator<Item = Option<[f32; 3]>> + 'a {
        self.observed_raw_mm().zip(self.visible()).map(|(p, v)| v.then_some(p))
    }

    /// Global joint positions, lab frame, mm, header joint order.
    pub fn joint_positions_mm(&self) -> impl ExactSizeIterator<Item = [f32; 3]> + 'a {
        let m = 7 * self.markers;
        Record::triples(&self.values[m..m + 3 * self.joints])
    }

    /// Local joint rotations as quaternions `(x, y, z, w)`, header joint order.
    pub fn joint_rotations_xyzw(&self) -> impl ExactSizeIterator<Item = [f32; 4]> + 'a {
        let m = 7 * self.markers + 3 * self.joints;
        self.values[m..].as_chunks::<4>().0.iter().copied()
    }
}

/// Streams a shard in chunks of frames.
///
/// # Bounds
/// Nothing a file says is allocated before it is checked. The header's length is capped
/// ([`MAX_HEADER_BYTES`]) and its marker and joint counts too ([`MAX_MARKERS`],
/// [`MAX_JOINTS`]). Given the file's length ([`ShardReader::with_len`]), the frame count must
/// account for the file's bytes exactly, so a caller may reserve `frames x record` up front.
/// Over a stream of unknown length ([`ShardReader::new`]) the frame count is only a promise:
/// a chunk is at most [`MAX_CHUNK_BYTES`] and its buffer grows with the bytes that actually
/// arrive, so a lying header ends in [`ShardError::Truncated`], never in a huge allocation.
pub struct ShardReader<R: Read> {
    reader: R,
    header: ShardHeader,
    next_frame: usize,
    /// The frame count was checked against the file's length ([`ShardReader::with_len`]), so
    /// buffers may be sized from it.
    length_checked: bool,
}

/// Everything a shard holds, decoded ([`ShardReader::read_all`]).
#[derive(Debug, Clone)]
pub struct ShardContents {
    /// The header.
    pub header: ShardHeader,
    /// Ground-truth markers, lab frame.
    pub clean: Take,
    /// Corrupted markers (occluded samples missing), lab frame.
    pub observed: Take,
    /// Global joint positions, lab frame, `[frame * J + joint]`, mm (empty without motion).
    pub joint_positions_mm: Vec<Vec3>,
    /// Local joint rotations (the root's in the motion frame), `[frame * J + joint]`.
    pub joint_rotations: Vec<Quat>,
}

impl<R: Read> ShardReader<R> {
    /// Reads and checks the header of a shard of unknown length.
    ///
    /// # Errors
    /// Not a shard, an unknown version, a header that is cut short, not JSON, or out of
    /// bounds (see the type's docs).
    pub fn new(reader: R) -> Result<ShardReader<R>, ShardError> {
        ShardReader::open(reader, None)
    }

    /// Reads and checks the header of a shard of `len` bytes (a file's length), and that the
    /// frame records fill the rest of it exactly: a file cut short, or a header claiming more
    /// (or fewer) frames than the file holds, is [`ShardError::Size`].
    ///
    /// # Errors
    /// As [`ShardReader::new`], and the size check.
    pub fn with_len(reader: R, len: u64) -> Result<ShardReader<R>, ShardError> {
        ShardReader::open(reader, Some(len))
    }

    fn open(mut reader: R, file_len: Option<u64>) -> Result<ShardReader<R>, ShardError> {
        let cut = |e: std::io::Error| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => ShardError::Truncated("the header".into()),
            _ => ShardError::Io(e),
        };
        let mut magic = [0u8; 8];
        reader.read_exact(&mut magic).map_err(cut)?;
        if &magic != MAGIC {
            return Err(ShardError::BadMagic(magic));
        }
        let mut word = [0u8; 4];
        reader.read_exact(&mut word).map_err(cut)?;
        let version = u32::from_le_bytes(word);
        if version != VERSION {
            return Err(ShardError::Version(version));
        }
        reader.read_exact(&mut word).map_err(cut)?;
        let len = u32::from_le_bytes(word);
        if len > MAX_HEADER_BYTES {
            return Err(ShardError::Header(format!("header of {len} bytes is longer than {MAX_HEADER_BYTES}")));
        }
        let data_start = 16 + u64::from(len).next_multiple_of(4);
        if let Some(file_len) = file_len
            && file_len < data_start
        {
            return Err(ShardError::Size(format!("{file_len} bytes cannot hold the {len}-byte header it announces")));
        }
        // `read_to_end` grows the buffer with the bytes that arrive, not with what `len` says.
        let mut json = Vec::new();
        (&mut reader).take(u64::from(len)).read_to_end(&mut json)?;
        if json.len() != len as usize {
            return Err(ShardError::Truncated("the header".into()));
        }
        let header: ShardHeader = serde_json::from_slice(&json).map_err(|e| ShardError::Header(e.to_string()))?;
        check_header(&header)?;
        let data_len = header.data_len().ok_or_else(|| {
            ShardError::Header(format!(
                "{} frames of {} values overflow a file length",
                header.frames,
                header.record_len()
            ))
        })?;
        if let Some(file_len) = file_len
            && file_len - data_start != data_len
        {
            return Err(ShardError::Size(format!(
                "the header promises {} frames of {} bytes ({} bytes after the header), the file has {}",
                header.frames,
                4 * header.record_len(),
                data_len,
                file_len - data_start
            )));
        }
        let mut pad = [0u8; 3];
        reader.read_exact(&mut pad[..(4 - len as usize % 4) % 4]).map_err(cut)?;
        Ok(ShardReader { reader, header, next_frame: 0, length_checked: file_len.is_some() })
    }

    /// The header.
    pub fn header(&self) -> &ShardHeader {
        &self.header
    }

    /// The next at most `max_frames` frames (fewer when a chunk would pass
    /// [`MAX_CHUNK_BYTES`]); `None` at the end.
    ///
    /// # Errors
    /// The data ends before the header's frame count ([`ShardError::Truncated`]), or reading
    /// fails.
    pub fn next_chunk(&mut self, max_frames: usize) -> Result<Option<Chunk>, ShardError> {
        let record_bytes = 4 * self.header.record_len();
        let frames = max_frames.max(1).min(self.header.frames - self.next_frame).min(MAX_CHUNK_BYTES / record_bytes);
        if frames == 0 {
            return Ok(None);
        }
        let n = frames * record_bytes;
        let mut bytes = Vec::new();
        (&mut self.reader).take(n as u64).read_to_end(&mut bytes)?;
        if bytes.len() != n {
            let frame = self.next_frame + bytes.len() / record_bytes;
            return Err(ShardError::Truncated(format!("frame {frame} of {}", self.header.frames)));
        }
        let data = bytes.as_chunks::<4>().0.iter().map(|b| f32::from_le_bytes(*b)).collect();
        let (markers, joints) = (self.header.markers.len(), self.header.joints.len());
        let chunk = Chunk { first_frame: self.next_frame, frames, data, markers, joints };
        self.next_frame += frames;
        Ok(Some(chunk))
    }
}

impl<R: Read> ShardReader<R> {
    /// The clean (ground-truth) markers of the whole shard, as a take: what a gap-fill
    /// refiner trains on.
    ///
    /// # Errors
    /// As [`ShardReader::read_all`].
    pub fn read_clean(self) -> Result<Take, ShardError> {
        Ok(self.decode(false)?.clean)
    }

    /// Every frame record of the shard, decoded: clean and corrupted takes, joint positions
    /// and rotations. A reader made with [`ShardReader::with_len`] sizes its buffers from the
    /// (checked) frame count; one over a stream of unknown length grows them with the records
    /// that arrive, so a lying header cannot make it allocate.
    ///
    /// # Errors
    /// The data ends early ([`ShardError::Truncated`]), reading fails, memory cannot hold the
    /// announced samples ([`ShardError::Memory`]), or a sample is not finite
    /// ([`ShardError::Take`]).
    pub fn read_all(self) -> Result<ShardContents, ShardError> {
        self.decode(true)
    }

    /// [`ShardReader::read_all`]; without `all`, the observed take and joints stay empty.
    fn decode(mut self, all: bool) -> Result<ShardContents, ShardError> {
        let header = self.header.clone();
        let (m, j, t) = (header.markers.len(), if all { header.joints.len() } else { 0 }, header.frames);
        // Only a length-checked frame count may size a buffer (see the type's docs).
        let cap = |per_frame: usize| if self.length_checked { t.saturating_mul(per_frame) } else { 0 };
        let mut clean = reserved(cap(m))?;
        let mut observed = reserved(cap(if all { m } else { 0 }))?;
        let mut joint_positions_mm = reserved(cap(j))?;
        let mut joint_rotations = reserved(cap(j))?;
        let v3 = |p: [f32; 3]| Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        while let Some(chunk) = self.next_chunk(1024)? {
            for record in chunk.records() {
                clean.extend(record.clean_mm().map(|p| Some(v3(p))));
                if all {
                    observed.extend(record.observed_mm().map(|p| p.map(v3)));
                    joint_positions_mm.extend(record.joint_positions_mm().map(v3));
                    joint_rotations.extend(record.joint_rotations_xyzw().map(|[x, y, z, w]| {
                        Quat::from_quaternion(nalgebra::Quaternion::new(w as f64, x as f64, y as f64, z as f64))
                    }));
                }
            }
        }
        let names: Vec<MarkerName> = header.markers.iter().map(|l| MarkerName::parse(l)).collect();
        let take = |samples: &[Option<Vec3>]| {
            Take::from_samples(names.clone(), samples, header.frame_rate_hz).map_err(ShardError::Take)
        };
        let clean = take(&clean)?;
        let observed = if all { take(&observed)? } else { take(&[])? };
        Ok(ShardContents { header, clean, observed, joint_positions_mm, joint_rotations })
    }
}

/// An empty vector with room for `n` items, or [`ShardError::Memory`]: the counts are checked
/// against the file's size, but a real file can still be larger than memory.
fn reserved<T>(n: usize) -> Result<Vec<T>, ShardError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|source| ShardError::Memory { samples: n, source })?;
    Ok(v)
}

/// The checks serde cannot make: counts within bounds, a usable frame rate, a skeleton that
/// is one and matches the joints.
fn check_header(header: &ShardHeader) -> Result<(), ShardError> {
    let (m, j) = (header.markers.len(), header.joints.len());
    if m == 0 || m > MAX_MARKERS {
        return Err(ShardError::Header(format!("{m} markers (1 to {MAX_MARKERS} are read)")));
    }
    if j > MAX_JOINTS {
        return Err(ShardError::Header(format!("{j} joints (at most {MAX_JOINTS} are read)")));
    }
    if !(header.frame_rate_hz.is_finite() && header.frame_rate_hz > 0.0) {
        return Err(ShardError::Header(format!("frame rate {} Hz is not positive", header.frame_rate_hz)));
    }
    if let Some(sk) = &header.skeleton {
        // Deserialising bypasses the skeleton's checks: run them, and match the joints.
        Skeleton::new(sk.joints().to_vec()).map_err(|e| ShardError::Header(format!("skeleton: {e}")))?;
        if sk.joints().iter().map(|j| &j.name).ne(header.joints.iter()) {
            return Err(ShardError::Header("the skeleton's joints are not the header's joints".into()));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{MarkerName, Vec3};

    fn takes() -> (Take, Take) {
        let samples: Vec<Option<Vec3>> = (0..10).map(|i| Some(Vec3::new(i as f64, 2.0 * i as f64, -1.5))).collect();
        let names = vec![MarkerName::parse("S:A"), MarkerName::parse("B")];
        let clean = Take::from_samples(names.clone(), &samples, 100.0).unwrap();
        let mut observed = clean.clone();
        observed.set_position_mm(2, 1, None).unwrap();
        (clean, observed)
    }

    #[test]
    fn round_trips_in_chunks() {
        let (clean, observed) = takes();
        let mut bytes = Vec::new();
        write_shard(&mut bytes, &clean, &observed, None, LabFrame::Motion).unwrap();
        let mut reader = ShardReader::new(bytes.as_slice()).unwrap();
        assert_eq!(reader.header().markers, vec!["A", "B"]);
        assert_eq!(reader.header().record_len(), 14);
        let mut frames = Vec::new();
        while let Some(chunk) = reader.next_chunk(2).unwrap() {
            assert!(chunk.frames <= 2);
            frames.extend(chunk.data.chunks(14).map(<[f32]>::to_vec));
        }
        assert_eq!(frames.len(), 5);
        // Frame 2: clean B = (5, 10, -1.5); observed B hidden (zeros, visible 0).
        assert_eq!(&frames[2][3..6], &[5.0, 10.0, -1.5]);
        assert_eq!(&frames[2][9..12], &[0.0, 0.0, 0.0]);
        assert_eq!(&frames[2][12..14], &[1.0, 0.0]);
        // Data start is 4-byte aligned.
        let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!((bytes.len() - 16 - header_len.next_multiple_of(4)) % 4, 0);
    }

    #[test]
    fn whole_shards_decode_to_takes_and_joints() {
        use crate::test_util::joint;
        let (clean, observed) = takes();
        let sk =
            Skeleton::new(vec![joint("root", None, [0.0; 3]), joint("knee", Some(0), [0.0, -400.0, 0.0])]).unwrap();
        let turn = locap_core::Quat::from_axis_angle(&Vec3::y_axis(), 0.5);
        let rot = (0..10).map(|i| if i % 2 == 1 { turn } else { locap_core::Quat::identity() }).collect();
        let motion = Motion::new(sk, rot, vec![Vec3::new(1.0, 2.0, 3.0); 5], 100.0).unwrap();
        let mut bytes = Vec::new();
        write_shard(&mut bytes, &clean, &observed, Some(&motion), LabFrame::Motion).unwrap();
        let all = ShardReader::with_len(bytes.as_slice(), bytes.len() as u64).unwrap().read_all().unwrap();
        assert_eq!(all.clean.markers().iter().map(|n| n.label.as_str()).collect::<Vec<_>>(), ["A", "B"]);
        assert_eq!((all.clean.frame_count(), all.clean.frame_rate_hz()), (5, 100.0));
        assert_eq!(all.clean.position_mm(2, 1), clean.position_mm(2, 1));
        assert_eq!(all.observed.position_mm(2, 1), None);
        assert_eq!(all.observed.position_mm(3, 1), clean.position_mm(3, 1));
        assert_eq!((all.joint_positions_mm.len(), all.joint_rotations.len()), (10, 10));
        assert!((all.joint_rotations[1].angle() - 0.5).abs() < 1e-6);
        assert!((all.joint_positions_mm[1] - Vec3::new(1.0, -398.0, 3.0)).norm() < 1e-3);
        // The refiner's half: the same clean take, from a stream of unknown length too.
        assert_eq!(ShardReader::new(bytes.as_slice()).unwrap().read_clean().unwrap(), all.clean);
        // A stream whose header lies about its frames ends in an error, not an allocation.
        let liar = handmade(&header_json(1_000_000_000_000, 2), &[0u8; 14 * 4 * 3]);
        let e = ShardReader::new(liar.as_slice()).unwrap().read_clean().unwrap_err();
        assert!(matches!(&e, ShardError::Truncated(at) if at == "frame 3 of 1000000000000"), "{e}");
    }

    #[test]
    fn bad_input_is_an_error() {
        let (clean, observed) = takes();
        let mut bytes = Vec::new();
        write_shard(&mut bytes, &clean, &observed, None, LabFrame::Motion).unwrap();
        assert!(matches!(ShardReader::new(&b"NOTASHARD......."[..]), Err(ShardError::BadMagic(_))));
        let mut v2 = bytes.clone();
        v2[8] = 2;
        assert!(matches!(ShardReader::new(v2.as_slice()), Err(ShardError::Version(2))));
        let truncated = &bytes[..bytes.len() - 3];
        let mut reader = ShardReader::new(truncated).unwrap();
        assert!(matches!(reader.next_chunk(10), Err(ShardError::Truncated(_))));
        assert!(matches!(ShardReader::with_len(truncated, truncated.len() as u64), Err(ShardError::Size(_))));
        let short = clean.slice_frames(0..3);
        assert!(matches!(
            write_shard(&mut Vec::new(), &short, &observed, None, LabFrame::Motion),
            Err(ShardError::Shape(_))
        ));
    }

    /// The skeleton travels in the header (checked on reading); a header without it (an older
    /// shard) still reads.
    #[test]
    fn skeleton_in_the_header() {
        use crate::test_util::joint;
        let (clean, observed) = takes();
        let sk =
            Skeleton::new(vec![joint("root", None, [0.0; 3]), joint("knee", Some(0), [0.0, -400.0, 0.0])]).unwrap();
        let rot = vec![locap_core::Quat::identity(); 2 * 5];
        let motion = Motion::new(sk.clone(), rot, vec![Vec3::new(1.0, 2.0, 3.0); 5], 100.0).unwrap();
        let mut bytes = Vec::new();
        write_shard(&mut bytes, &clean, &observed, Some(&motion), LabFrame::ZUpFromYUp).unwrap();
        let reader = ShardReader::new(bytes.as_slice()).unwrap();
        assert_eq!(reader.header().skeleton.as_ref(), Some(&sk));
        assert_eq!(reader.header().record_len(), 14 + 14);
        // An old header (no skeleton field) reads with None.
        let header_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        let mut json: serde_json::Value = serde_json::from_slice(&bytes[16..16 + header_len]).unwrap();
        json.as_object_mut().unwrap().remove("skeleton");
        let old: ShardHeader = serde_json::from_value(json.clone()).unwrap();
        assert_eq!(old.skeleton, None);
        // A skeleton whose parents are out of order is refused.
        json["skeleton"] = serde_json::json!({"joints": [
            {"name": "root", "parent": 1, "offset_mm": [0.0, 0.0, 0.0], "rotation_order": "ZXY", "is_end_site": false},
            {"name": "knee", "parent": null, "offset_mm": [0.0, 0.0, 0.0], "rotation_order": "ZXY", "is_end_site": false}]});
        let text = serde_json::to_vec(&json).unwrap();
        let mut bad = Vec::new();
        bad.extend_from_slice(MAGIC);
        bad.extend_from_slice(&VERSION.to_le_bytes());
        bad.extend_from_slice(&(text.len() as u32).to_le_bytes());
        bad.extend_from_slice(&text);
        bad.extend_from_slice(&[0u8; 3][..(4 - text.len() % 4) % 4]);
        assert!(matches!(ShardReader::new(bad.as_slice()), Err(ShardError::Header(_))));
    }

    /// A shard built by hand from a JSON header and `data` bytes after it.
    fn handmade(header: &serde_json::Value, data: &[u8]) -> Vec<u8> {
        let text = serde_json::to_vec(header).unwrap();
        let mut bytes = Vec::new();
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&VERSION.to_le_bytes());
        bytes.extend_from_slice(&(text.len() as u32).to_le_bytes());
        bytes.extend_from_slice(&text);
        bytes.extend_from_slice(&[0u8; 3][..(4 - text.len() % 4) % 4]);
        bytes.extend_from_slice(data);
        bytes
    }

    fn header_json(frames: u64, markers: usize) -> serde_json::Value {
        let names: Vec<String> = (0..markers).map(|k| format!("M{k}")).collect();
        serde_json::json!({"frames": frames, "frame_rate_hz": 120.0, "markers": names, "joints": [],
            "record": [], "lab": "motion"})
    }

    /// Records decode through `Record`: clean, observed with visibility, joints.
    #[test]
    fn records_are_typed() {
        use crate::test_util::joint;
        let (clean, observed) = takes();
        let sk = Skeleton::new(vec![joint("root", None, [0.0; 3])]).unwrap();
        let rot = vec![locap_core::Quat::identity(); 5];
        let motion = Motion::new(sk, rot, vec![Vec3::new(1.0, 2.0, 3.0); 5], 100.0).unwrap();
        let mut bytes = Vec::new();
        write_shard(&mut bytes, &clean, &observed, Some(&motion), LabFrame::Motion).unwrap();
        let mut reader = ShardReader::with_len(bytes.as_slice(), bytes.len() as u64).unwrap();
        let chunk = reader.next_chunk(100).unwrap().unwrap();
        assert_eq!(chunk.records().len(), 5);
        let r = chunk.records().nth(2).unwrap();
        assert_eq!(r.clean_mm().collect::<Vec<_>>(), vec![[4.0, 8.0, -1.5], [5.0, 10.0, -1.5]]);
        assert_eq!(r.observed_mm().collect::<Vec<_>>(), vec![Some([4.0, 8.0, -1.5]), None]);
        assert_eq!(r.visible().collect::<Vec<_>>(), vec![true, false]);
        assert_eq!(r.joint_positions_mm().collect::<Vec<_>>(), vec![[1.0, 2.0, 3.0]]);
        assert_eq!(r.joint_rotations_xyzw().collect::<Vec<_>>(), vec![[0.0, 0.0, 0.0, 1.0]]);
        assert!(reader.next_chunk(100).unwrap().is_none());
    }

    /// A 100-byte file, a header that claims 10^12 frames, or one that undercounts: typed
    /// errors, and no allocation from the claim (a stream reads what is there, then stops).
    #[test]
    fn lying_sizes_are_errors() {
        let (clean, observed) = takes();
        let mut good = Vec::new();
        write_shard(&mut good, &clean, &observed, None, LabFrame::Motion).unwrap();
        let hundred = &good[..100];
        assert!(matches!(ShardReader::with_len(hundred, 100), Err(ShardError::Size(_))));
        assert!(matches!(ShardReader::new(hundred), Err(ShardError::Truncated(_))));

        let liar = handmade(&header_json(1_000_000_000_000, 2), &[0u8; 14 * 4 * 3]);
        let e = ShardReader::with_len(liar.as_slice(), liar.len() as u64).err().unwrap();
        assert!(e.to_string().contains("1000000000000 frames"), "{e}");
        let mut stream = ShardReader::new(liar.as_slice()).unwrap();
        let e = stream.next_chunk(usize::MAX).unwrap_err();
        assert!(matches!(&e, ShardError::Truncated(at) if at == "frame 3 of 1000000000000"), "{e}");

        let mut trailing = good.clone();
        trailing.extend_from_slice(&[0u8; 56]);
        assert!(matches!(ShardReader::with_len(trailing.as_slice(), trailing.len() as u64), Err(ShardError::Size(_))));
        // A frame count whose byte size overflows a u64.
        let huge = handmade(&header_json(u64::MAX / 8, 2), &[]);
        assert!(matches!(ShardReader::with_len(huge.as_slice(), huge.len() as u64), Err(ShardError::Header(_))));
        // A header longer than the file, before reading it.
        let mut long = good[..16].to_vec();
        long[12..16].copy_from_slice(&(1u32 << 20).to_le_bytes());
        assert!(matches!(ShardReader::with_len(long.as_slice(), 16), Err(ShardError::Size(_))));
        assert!(matches!(ShardReader::new(long.as_slice()), Err(ShardError::Truncated(_))));
    }

    /// Marker and joint counts beyond the ceilings, no markers, a bad frame rate: refused on
    /// reading, and never written.
    #[test]
    fn header_counts_are_bounded() {
        for json in [header_json(0, 0), header_json(0, MAX_MARKERS + 1)] {
            let bytes = handmade(&json, &[]);
            assert!(matches!(ShardReader::new(bytes.as_slice()), Err(ShardError::Header(_))));
        }
        let mut joints = header_json(0, 1);
        joints["joints"] = serde_json::json!(vec!["j"; MAX_JOINTS + 1]);
        assert!(matches!(ShardReader::new(handmade(&joints, &[]).as_slice()), Err(ShardError::Header(_))));
        let mut rate = header_json(0, 1);
        rate["frame_rate_hz"] = serde_json::json!(0.0);
        assert!(matches!(ShardReader::new(handmade(&rate, &[]).as_slice()), Err(ShardError::Header(_))));
        let empty = Take::from_samples(vec![], &[], 100.0).unwrap();
        assert!(matches!(
            write_shard(&mut Vec::new(), &empty, &empty, None, LabFrame::Motion),
            Err(ShardError::Shape(_))
        ));
    }

    /// Chunks stay under `MAX_CHUNK_BYTES` whatever `max_frames` asks.
    #[test]
    fn chunks_are_bounded() {
        let markers = 600; // 16,800 bytes a record: 3,994 records fit in 64 MiB
        let per_chunk = MAX_CHUNK_BYTES / (7 * markers * 4);
        let frames = per_chunk + 5;
        let data = vec![0u8; frames * 7 * markers * 4];
        let bytes = handmade(&header_json(frames as u64, markers), &data);
        let mut reader = ShardReader::with_len(bytes.as_slice(), bytes.len() as u64).unwrap();
        assert_eq!(reader.next_chunk(usize::MAX).unwrap().unwrap().frames, per_chunk);
        assert_eq!(reader.next_chunk(usize::MAX).unwrap().unwrap().frames, 5);
        assert!(reader.next_chunk(usize::MAX).unwrap().is_none());
    }
}
