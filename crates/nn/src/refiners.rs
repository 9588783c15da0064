//! Learned refiners as fillers of the clean stage (LocalMoCap section 3.1: the network corrects
//! the initial fill of the occluded samples), so `locap_clean::clean_with` runs them exactly as
//! it runs a classical fill.
//!
//! A body model and hand models cover different markers of one take; [`Refiners`] runs them
//! together ([`crate::refine_all`]), each correcting the samples of its own markers.

use crate::refiner::Refiner;
use locap_clean::{FillError, FillMethod, Filled, Filler};
use locap_core::Take;

/// The start of a refiner's fill, as `LOCAP:METHOD` names it.
fn start(refiner: &Refiner) -> &'static str {
    match refiner.meta.init {
        FillMethod::Edm => "EDM",
        other => other.name(),
    }
}

impl Refiner {
    /// Whether `take` carries every marker this refiner was trained on (the one test of "the
    /// refiners that fit this take").
    pub fn fits(&self, take: &Take) -> bool {
        crate::features::marker_order(take, &self.meta.markers).is_ok()
    }
}

impl Filler for Refiner {
    fn describe(&self) -> String {
        format!("Neural {} ({} start)", self.meta.frame.name, start(self))
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        self.refine(take).map_err(|e| FillError::new(self, e))
    }
}

/// Refiners run together on one take, each with a name for the record (a file name, or
/// `shipped waist`).
#[derive(Debug, Default)]
pub struct Refiners {
    named: Vec<(String, Refiner)>,
}

impl Refiners {
    /// The refiners `named`, in the order they run.
    pub fn new(named: Vec<(String, Refiner)>) -> Refiners {
        Refiners { named }
    }

    /// No refiner: a caller falls back to a classical fill.
    pub fn is_empty(&self) -> bool {
        self.named.is_empty()
    }

    /// How many.
    pub fn len(&self) -> usize {
        self.named.len()
    }

    /// The refiners.
    pub fn iter(&self) -> impl Iterator<Item = &Refiner> {
        self.named.iter().map(|(_, r)| r)
    }

    /// Their names.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.named.iter().map(|(n, _)| n.as_str())
    }
}

impl Filler for Refiners {
    fn describe(&self) -> String {
        let names: Vec<&str> = self.names().collect();
        let start = self.named.first().map_or("EDM", |(_, r)| start(r));
        format!("Neural {} ({start} start)", names.join(" + "))
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        crate::refine_all_of(take, &self.iter().collect::<Vec<_>>()).map_err(|e| FillError::new(self, e))
    }
}
