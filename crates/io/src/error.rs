//! Errors of every reader and writer, with the evidence a user needs to find the problem:
//! the file, and the byte offset and section (binary formats) or line and column (text).

use std::path::{Path, PathBuf};

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// An error reading or writing a capture file.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system failed to read or write.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// A binary file is malformed at a known byte offset.
    #[error("{format} {section} malformed at byte {offset}: {message}")]
    Binary {
        /// Format name (`C3D`).
        format: &'static str,
        /// Section of the file (`header`, `parameter section`, `POINT data`, ...).
        section: String,
        /// Byte offset from the start of the file.
        offset: u64,
        /// What was seen versus what was expected.
        message: String,
    },
    /// A text file is malformed at a known line (1-based).
    #[error("{format} line {line}{}: {message}", column.map(|c| format!(", column {c}")).unwrap_or_default())]
    Text {
        /// Format name (`BVH`, `TRC`, `ASF`, `AMC`).
        format: &'static str,
        /// Line number, 1-based.
        line: usize,
        /// Column number, 1-based, if known.
        column: Option<usize>,
        /// What was wrong.
        message: String,
    },
    /// The file is valid but uses something locap does not support.
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// The data cannot be represented in the target format.
    #[error("cannot write: {0}")]
    Unwritable(String),
    /// The file's size or counts exceed a safety limit (see [`crate::Limits`]).
    #[error("limit exceeded: {0}")]
    Limit(String),
    /// The path is not a regular file (a named pipe, device, socket or directory), refused
    /// before opening it because opening a named pipe blocks.
    #[error("not a regular file: this is {0}")]
    NotAFile(&'static str),
    /// The data read does not form a valid take.
    #[error(transparent)]
    Take(#[from] locap_core::TakeError),
    /// The data read does not form a valid skeleton or motion.
    #[error(transparent)]
    Skeleton(#[from] locap_core::SkeletonError),
    /// A `LOCAP` record that cannot be stored (a list past the compact form's ceiling).
    #[error(transparent)]
    Provenance(#[from] locap_core::provenance::ProvenanceError),
    /// An error in a named file.
    #[error("{}: {error}", path.display())]
    InFile {
        /// The file.
        path: PathBuf,
        /// What went wrong in it.
        error: Box<Error>,
    },
}

impl Error {
    /// Wraps this error with the file it happened in (once: a wrapped error is not re-wrapped).
    pub fn in_file(self, path: &Path) -> Error {
        match self {
            e @ Error::InFile { .. } => e,
            e => Error::InFile { path: path.to_path_buf(), error: Box::new(e) },
        }
    }

    /// A text-format error at `line` (1-based).
    pub fn text(format: &'static str, line: usize, message: impl Into<String>) -> Error {
        Error::Text { format, line, column: None, message: message.into() }
    }
}
