//! The model file layout both model kinds share (the refiner of LocalMoCap section 3.1, the
//! solver of section 3.2): one header writer and one reader, so the two kinds cannot drift.
//!
//! # Model file (version 1, one file, little-endian)
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic: `LOCAPNN\0` (refiner) or `LOCAPSV\0` (solver) |
//! | 4 | `u32` format version (1) |
//! | 4 | `u32` length `H` of the metadata |
//! | `H` | UTF-8 JSON metadata ([`crate::refiner::ModelMeta`], [`crate::solver::SolverMeta`]) |
//! | rest | the weights as a burn record (burnpack bytes, `ModuleRecord::into_bytes`) |
//!
//! One file keeps the weights and what is needed to use them together: a model is never run
//! with another model's statistics or graph. The magic differs per kind, so a solver file
//! given as a refiner (or the other way round) is refused by name.

use crate::NnError;
use burn::module::Module;
use burn::store::ModuleRecord;
use burn::tensor::Bytes;
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Which model a file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The gap-fill refiner (`LOCAPNN\0`).
    Refiner,
    /// The motion solver (`LOCAPSV\0`).
    Solver,
}

impl Kind {
    /// The magic bytes at the start of the file.
    pub fn magic(self) -> &'static [u8; 8] {
        match self {
            Kind::Refiner => b"LOCAPNN\0",
            Kind::Solver => b"LOCAPSV\0",
        }
    }

    /// The kind's name in messages.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Refiner => "refiner",
            Kind::Solver => "solver",
        }
    }
}

/// Format version written.
pub const VERSION: u32 = 1;
/// Largest metadata accepted: the length is read from the file, so it is bounded before use.
const MAX_META_BYTES: u32 = 64 << 20;

/// The file bytes of `meta` and `net`'s weights.
///
/// # Errors
/// The metadata or the weights cannot be serialised.
pub fn write<M: Module>(kind: Kind, meta: &impl Serialize, net: M) -> Result<Vec<u8>, NnError> {
    let json = serde_json::to_vec(meta).map_err(|e| NnError::BadModel(e.to_string()))?;
    let weights = net.into_record().into_bytes().map_err(|e| NnError::BadModel(format!("weights: {e:?}")))?;
    let mut out = Vec::with_capacity(16 + json.len() + weights.len());
    out.extend_from_slice(kind.magic());
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&weights);
    Ok(out)
}

/// The metadata of a file of `kind`, and a function that loads its weights into a network
/// built from that metadata (the network's shape comes from the metadata, so it is checked
/// between the two steps).
///
/// # Errors
/// Not a file of `kind`, another version, a metadata length past the end, damaged metadata.
pub fn read<T: DeserializeOwned>(kind: Kind, bytes: &[u8]) -> Result<(T, Weights<'_>), NnError> {
    let name = kind.name();
    let bad = |what: String| NnError::BadModel(what);
    if bytes.len() < 16 || &bytes[..8] != kind.magic() {
        let magic = String::from_utf8_lossy(&kind.magic()[..7]).into_owned();
        return Err(bad(format!("the file does not start with {magic} (not a locap {name} model)")));
    }
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    let version = word(8);
    if version != VERSION {
        return Err(bad(format!("{name} model format version {version}; this locap reads version {VERSION}")));
    }
    let len = word(12);
    if len > MAX_META_BYTES || 16 + len as usize > bytes.len() {
        return Err(bad("the metadata length runs past the end of the file".into()));
    }
    let meta = serde_json::from_slice(&bytes[16..16 + len as usize]).map_err(|e| bad(format!("metadata: {e}")))?;
    Ok((meta, Weights(&bytes[16 + len as usize..])))
}

/// The weight bytes of a model file ([`read`]).
#[derive(Debug, Clone, Copy)]
pub struct Weights<'a>(&'a [u8]);

impl Weights<'_> {
    /// `net` with these weights.
    ///
    /// # Errors
    /// The weights are damaged or do not fit `net`.
    pub fn load<M: Module>(self, net: M) -> Result<M, NnError> {
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(self.0.to_vec()))
            .map_err(|e| NnError::BadModel(format!("weights: {e:?}")))?;
        net.try_load_record(record).map_err(|e| NnError::BadModel(format!("weights: {e:?}")))
    }
}
