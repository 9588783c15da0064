//! The trained models shipped inside locap, produced by `locap train fill` and `locap train
//! solve` (the commands, data and training times are recorded in `models/README.md` beside the
//! files).
//!
//! They are used when a command needs a model and none is given: each take is refined by the
//! refiners whose markers it carries ([`refiners_for`]: the body model on the CMU/HDM05
//! 41-marker set, the hand models on the paper's 14 markers per hand, `LIWR` ... `LPNK6` and
//! `RIWR` ... `RPNK6`), and solved by [`solver`] (the CMU 41-marker set on the CMU ASF
//! skeleton).

use crate::NnError;
use crate::refiner::Refiner;
use crate::refiners::Refiners;
use crate::solver::Solver;
use burn::prelude::Device;
use locap_core::Take;

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

/// The shipped solver: the third body model (`models/README.md`, "solver-cmu41-v3"), with the
/// first and second answering beside it as an ensemble ([`Solver::with_members`]: the three
/// answers averaged per frame and joint). Refined by the kinematic solver, the ensemble's answer
/// is closer to the held-out subject's motion on the joints the markers constrain than the third
/// model's alone (docs/benchmarks.md, "The three networks as one").
pub const SOLVER: Shipped =
    Shipped { name: "solver-cmu41-v3.locapsv", bytes: include_bytes!("../../../models/solver-cmu41-v3.locapsv") };

/// The models that answer beside [`SOLVER`] in the shipped ensemble.
pub const SOLVER_MEMBERS: &[Shipped] = &[
    Shipped { name: "solver-cmu41-v2.locapsv", bytes: include_bytes!("../../../models/solver-cmu41-v2.locapsv") },
    Shipped { name: "solver-cmu41.locapsv", bytes: include_bytes!("../../../models/solver-cmu41.locapsv") },
];

/// The shipped solver, loaded on `device`: [`SOLVER`] with [`SOLVER_MEMBERS`] beside it.
///
/// # Errors
/// A shipped file does not load (a build from a damaged checkout).
pub fn solver(device: &Device) -> Result<Solver, NnError> {
    let load = |s: &Shipped| {
        Solver::from_bytes(s.bytes, device).map_err(|e| NnError::BadModel(format!("shipped {}: {e}", s.name)))
    };
    let members = SOLVER_MEMBERS.iter().map(load).collect::<Result<Vec<_>, _>>()?;
    load(&SOLVER)?.with_members(members)
}

/// The shipped refiners whose markers `take` carries, loaded on `device`, named `shipped
/// <local frame>` for the record; empty when none fits (the caller falls back to EDM, or
/// refuses).
///
/// # Errors
/// A shipped file does not load (a build from a damaged checkout).
pub fn refiners_for(take: &Take, device: &Device) -> Result<Refiners, NnError> {
    let fitting = refiners(device)?.into_iter().filter(|r| r.fits(take));
    Ok(Refiners::new(fitting.map(|r| (format!("shipped {}", r.meta.frame.name), r)).collect()))
}

/// Every shipped refiner, loaded on `device`.
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
