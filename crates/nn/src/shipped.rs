//! The trained refiners shipped inside locap, produced by `locap train fill` (the commands, data
//! and training times are recorded in `models/README.md` beside the files).
//!
//! They are used when a command needs a refiner and none is given: each take is refined by
//! those whose markers it carries (the body model on the CMU/HDM05 41-marker set, the hand
//! models on the paper's 14 markers per hand, `LIWR` ... `LPNK6` and `RIWR` ... `RPNK6`).

use crate::NnError;
use crate::refiner::Refiner;
use burn::prelude::Device;

/// A shipped model: its file name under `models/` and its bytes.
#[derive(Debug, Clone, Copy)]
pub struct Shipped {
    /// File name under `models/`.
    pub name: &'static str,
    /// The model file.
    pub bytes: &'static [u8],
}

/// Every shipped refiner.
pub const REFINERS: &[Shipped] = &[
    Shipped { name: "refiner-cmu41.locapnn", bytes: include_bytes!("../../../models/refiner-cmu41.locapnn") },
    Shipped { name: "refiner-hand-left.locapnn", bytes: include_bytes!("../../../models/refiner-hand-left.locapnn") },
    Shipped { name: "refiner-hand-right.locapnn", bytes: include_bytes!("../../../models/refiner-hand-right.locapnn") },
];

/// The shipped refiners, loaded on `device`.
///
/// # Errors
/// A shipped file does not load (a build from a damaged checkout).
pub fn refiners(device: &Device) -> Result<Vec<Refiner>, NnError> {
    REFINERS
        .iter()
        .map(|s| {
            Refiner::from_bytes(s.bytes, device).map_err(|e| NnError::BadModel(format!("shipped {}: {e}", s.name)))
        })
        .collect()
}
