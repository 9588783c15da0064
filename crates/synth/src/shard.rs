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
//! memory-mappable; [`ShardReader`] streams it in chunks from any `Read`.

use crate::synthesize::LabFrame;
use locap_core::{Motion, Skeleton, Take};
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};

/// The magic bytes at the start of a shard.
pub const MAGIC: &[u8; 8] = b"LOCAPSHD";
/// The format version written.
pub const VERSION: u32 = 1;
/// Largest header accepted when reading (guards the allocation against corrupt files).
const MAX_HEADER_BYTES: u32 = 16 << 20;

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
    /// The takes and motion given to the writer do not line up.
    #[error("cannot write shard: {0}")]
    Shape(String),
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
}

/// Streams a shard in chunks of frames.
pub struct ShardReader<R: Read> {
    reader: R,
    header: ShardHeader,
    next_frame: usize,
}

impl<R: Read> ShardReader<R> {
    /// Reads and checks the header.
    pub fn new(mut reader: R) -> Result<ShardReader<R>, ShardError> {
        let mut magic = [0u8; 8];
        reader.read_exact(&mut magic)?;
        if &magic != MAGIC {
            return Err(ShardError::BadMagic(magic));
        }
        let mut word = [0u8; 4];
        reader.read_exact(&mut word)?;
        let version = u32::from_le_bytes(word);
        if version != VERSION {
            return Err(ShardError::Version(version));
        }
        reader.read_exact(&mut word)?;
        let len = u32::from_le_bytes(word);
        if len > MAX_HEADER_BYTES {
            return Err(ShardError::Header(format!("header of {len} bytes is longer than {MAX_HEADER_BYTES}")));
        }
        let mut json = vec![0u8; len as usize];
        reader.read_exact(&mut json)?;
        let header: ShardHeader = serde_json::from_slice(&json).map_err(|e| ShardError::Header(e.to_string()))?;
        if let Some(sk) = &header.skeleton {
            // Deserialising bypasses the skeleton's checks: run them, and match the joints.
            Skeleton::new(sk.joints().to_vec()).map_err(|e| ShardError::Header(format!("skeleton: {e}")))?;
            if sk.joints().iter().map(|j| &j.name).ne(header.joints.iter()) {
                return Err(ShardError::Header("the skeleton's joints are not the header's joints".into()));
            }
        }
        let mut pad = [0u8; 3];
        reader.read_exact(&mut pad[..(4 - len as usize % 4) % 4])?;
        Ok(ShardReader { reader, header, next_frame: 0 })
    }

    /// The header.
    pub fn header(&self) -> &ShardHeader {
        &self.header
    }

    /// The next at most `max_frames` frames; `None` at the end. A file cut short is an error.
    pub fn next_chunk(&mut self, max_frames: usize) -> Result<Option<Chunk>, ShardError> {
        let frames = max_frames.max(1).min(self.header.frames - self.next_frame);
        if frames == 0 {
            return Ok(None);
        }
        let n = frames * self.header.record_len();
        let mut bytes = vec![0u8; n * 4];
        self.reader.read_exact(&mut bytes)?;
        let data = bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let chunk = Chunk { first_frame: self.next_frame, frames, data };
        self.next_frame += frames;
        Ok(Some(chunk))
    }
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
        assert!(matches!(reader.next_chunk(10), Err(ShardError::Io(_))));
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
}
