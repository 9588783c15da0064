//! Resource limits of the readers, checked before anything is allocated, and the one way a
//! reader opens a file on disk.
//!
//! Modelled on image-png's `Limits` (`png::Limits { bytes }`, "default is 64 MiB"), which the
//! decoder checks before sizing a buffer from an untrusted header. A capture file's header
//! says how many frames, markers, channels and joints follow; a corrupt or hostile file can
//! say 4 billion frames in 1 KB. Every reader of this crate checks such counts against
//! [`Limits`] (and, where the file must hold bytes for them, against the file's size) before
//! it reserves memory or loops over them, and fails with [`Error::Limit`] otherwise.
//!
//! # Defaults
//! Generous enough for real studio data, small enough that a count no file backs cannot
//! exhaust a workstation:
//! - [`Limits::max_file_bytes`] 16 GiB: the whole file is read into memory.
//! - [`Limits::max_frames`] 2²⁷ = 134,217,728: 37 hours at 1000 Hz (a 24 h capture at
//!   1000 Hz is real; the 4.29 billion frames of a corrupt C3D header are not).
//! - [`Limits::max_samples`] 2²⁸ = 268,435,456 values of one kind per frame and channel
//!   (a marker position, an analog value, a joint rotation): 2 h of 150 markers at 240 Hz,
//!   or 24 h of 3 markers at 1000 Hz. A [`locap_core::Take`] costs 33 bytes per sample, so
//!   the ceiling is about 9 GB of take.
//! - [`Limits::max_depth`] 256 levels of a BVH or ASF hierarchy (real skeletons are 10-20
//!   deep, finger chains included).
//! - [`Limits::max_joints`] 10,000 joints or bones (real skeletons have 20-200).
//!
//! # Samples a file does not spell out
//! Some formats let a file imply samples it holds no bytes for: TRC rows may stop after the
//! last visible marker, an AMC frame may leave bones out (they are read at rest), a BVH joint
//! may have no channels, and a C3D file with no points and no analog channels has frames of
//! zero bytes. Such samples are bounded by the file's size as well: a take read from text
//! may hold at most one sample per byte of that text (a real file writes at least the
//! separators of a missing sample, or a line per bone), and a C3D file at most one empty
//! frame per byte after its data start. Without this rule, a 10 KB text file could ask for
//! `max_samples` samples.
//!
//! # Files on disk
//! [`read_file`] refuses anything that is not a regular file (a named pipe would block the
//! reader forever, a device would never end, a directory cannot be read) *before* opening it,
//! and refuses files larger than [`Limits::max_file_bytes`] before reading them.

use crate::{Error, Result};
use std::io::Read;
use std::path::Path;

/// Ceilings on what a reader may allocate or loop over; see the module documentation for the
/// defaults and why they are what they are.
///
/// ```
/// let tight = locap_io::Limits { max_frames: 10_000, ..locap_io::Limits::default() };
/// assert!(tight.max_samples > 0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest file a path reader reads into memory, in bytes.
    pub max_file_bytes: u64,
    /// Most frames a take or motion may have.
    pub max_frames: usize,
    /// Most samples (frames × markers, frames × analog values, frames × joints) a reader may
    /// allocate.
    pub max_samples: usize,
    /// Deepest nesting of a BVH or ASF hierarchy (the root is depth 0).
    pub max_depth: usize,
    /// Most joints of a BVH hierarchy or bones of an ASF skeleton.
    pub max_joints: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_file_bytes: 16 << 30,
            max_frames: 1 << 27,
            max_samples: 1 << 28,
            max_depth: 256,
            max_joints: 10_000,
        }
    }
}

impl Limits {
    /// No limits at all (still never more samples than `usize` counts): for trusted input.
    pub fn none() -> Limits {
        Limits {
            max_file_bytes: u64::MAX,
            max_frames: usize::MAX,
            max_samples: usize::MAX,
            max_depth: usize::MAX,
            max_joints: usize::MAX,
        }
    }

    /// Checks `frames` frames of `channels` samples each (`what` names them in the error).
    pub(crate) fn check_samples(&self, format: &str, frames: usize, channels: usize, what: &str) -> Result<()> {
        if frames > self.max_frames {
            return Err(Error::Limit(format!("{format}: {frames} frames exceed the limit of {}", self.max_frames)));
        }
        match frames.checked_mul(channels) {
            Some(n) if n <= self.max_samples => Ok(()),
            n => Err(Error::Limit(format!(
                "{format}: {frames} frames x {channels} {what} = {} samples exceed the limit of {}",
                n.map_or_else(|| "more than 2^64".to_string(), |n| n.to_string()),
                self.max_samples
            ))),
        }
    }

    /// [`Limits::check_samples`], plus: a take read from `text_bytes` of text holds at most one
    /// sample per byte (see the module documentation).
    pub(crate) fn check_text_samples(
        &self,
        format: &str,
        frames: usize,
        channels: usize,
        what: &str,
        text_bytes: usize,
    ) -> Result<()> {
        self.check_samples(format, frames, channels, what)?;
        let n = frames.saturating_mul(channels);
        if n > text_bytes.max(1) {
            return Err(Error::Limit(format!(
                "{format}: {frames} frames x {channels} {what} = {n} samples from a file of {text_bytes} bytes; \
                 a file must hold at least one byte per sample"
            )));
        }
        Ok(())
    }

    /// Checks a hierarchy's nesting depth and joint count at (1-based) `line`.
    pub(crate) fn check_hierarchy(&self, format: &str, line: usize, depth: usize, joints: usize) -> Result<()> {
        if depth > self.max_depth {
            return Err(Error::Limit(format!(
                "{format} line {line}: hierarchy nested deeper than {} levels",
                self.max_depth
            )));
        }
        if joints > self.max_joints {
            return Err(Error::Limit(format!("{format} line {line}: more than {} joints", self.max_joints)));
        }
        Ok(())
    }
}

/// What a path that is not a regular file is, for the error message.
fn kind_of(file_type: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if file_type.is_fifo() {
            return "a named pipe (FIFO)";
        }
        if file_type.is_char_device() || file_type.is_block_device() {
            return "a device";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    if file_type.is_dir() { "a directory" } else { "an unknown kind of file" }
}

/// Reads a whole file into memory, refusing non-regular files before opening them and files
/// larger than `limits.max_file_bytes` before reading them. Errors name the file.
///
/// The type is checked on the path (following symbolic links) before `open`, because opening
/// a named pipe blocks until a writer appears; it is checked again on the open handle, and
/// the read stops one byte past the limit, so a file swapped or grown in between is refused
/// too rather than read without bound.
pub fn read_file(path: &Path, limits: &Limits) -> Result<Vec<u8>> {
    read_checked(path, limits).map_err(|e| e.in_file(path))
}

fn read_checked(path: &Path, limits: &Limits) -> Result<Vec<u8>> {
    check_regular(&std::fs::metadata(path)?, limits)?;
    let file = std::fs::File::open(path)?;
    let len = check_regular(&file.metadata()?, limits)?;
    let mut bytes = Vec::with_capacity(usize::try_from(len).unwrap_or(0));
    file.take(limits.max_file_bytes.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limits.max_file_bytes {
        return Err(too_large(bytes.len() as u64, limits));
    }
    Ok(bytes)
}

/// The file's length if it is a regular file within the size limit.
fn check_regular(meta: &std::fs::Metadata, limits: &Limits) -> Result<u64> {
    if !meta.is_file() {
        return Err(Error::NotAFile(kind_of(meta.file_type())));
    }
    if meta.len() > limits.max_file_bytes {
        return Err(too_large(meta.len(), limits));
    }
    Ok(meta.len())
}

fn too_large(len: u64, limits: &Limits) -> Error {
    Error::Limit(format!("file of {len} bytes exceeds the limit of {} bytes", limits.max_file_bytes))
}

/// [`read_file`] for text formats that must be UTF-8 (BVH, ASF, AMC).
pub(crate) fn read_utf8(path: &Path, limits: &Limits) -> Result<String> {
    let bytes = read_file(path, limits)?;
    String::from_utf8(bytes)
        .map_err(|e| Error::from(std::io::Error::new(std::io::ErrorKind::InvalidData, e)).in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_file(dir.path(), &Limits::default()).unwrap_err();
        assert!(matches!(&err, Error::InFile { error, .. } if matches!(**error, Error::NotAFile("a directory"))));
        assert!(err.to_string().contains(&dir.path().display().to_string()), "{err}");
    }

    #[test]
    fn size_limit_is_checked_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.txt");
        std::fs::write(&path, b"0123456789").unwrap();
        let limits = Limits { max_file_bytes: 9, ..Limits::default() };
        let err = read_file(&path, &limits).unwrap_err().to_string();
        assert!(err.contains("10 bytes exceeds the limit of 9"), "{err}");
        assert_eq!(read_file(&path, &Limits { max_file_bytes: 10, ..limits }).unwrap().len(), 10);
    }

    #[test]
    fn sample_checks_cover_overflow_frames_and_text_backing() {
        let l = Limits::default();
        assert!(l.check_samples("X", usize::MAX, 2, "markers").is_err());
        assert!(l.check_samples("X", l.max_frames + 1, 0, "markers").is_err());
        assert!(l.check_samples("X", l.max_frames, 2, "markers").is_ok());
        assert!(l.check_text_samples("X", 100, 10, "markers", 999).is_err());
        assert!(l.check_text_samples("X", 100, 10, "markers", 1000).is_ok());
        assert!(l.check_hierarchy("X", 1, 257, 1).is_err());
        assert!(l.check_hierarchy("X", 1, 256, 10_001).is_err());
        assert!(l.check_hierarchy("X", 1, 256, 10_000).is_ok());
    }
}
