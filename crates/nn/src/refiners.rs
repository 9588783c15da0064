//! Learned refiners as fillers of the clean stage (LocalMoCap section 3.1: the network corrects
//! the initial fill of the occluded samples), so `locap_clean::clean_with` runs them exactly as
//! it runs a classical fill.
//!
//! A body model and hand models cover different markers of one take; [`Refiners`] runs them
//! together ([`crate::refine_all`]), each correcting the samples of its own markers.

use crate::NnError;
use crate::refiner::Refiner;
use locap_clean::{FillConfig, FillError, FillMethod, Filled, Filler};
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

/// Where the learned refiners of a fill come from: what `locap clean --method`, `locap solve
/// --fill / --refiner` and the Python calls choose between.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub enum RefinerSource {
    /// None: the classical fill alone.
    #[default]
    None,
    /// The refiners shipped with locap that fit the take; a take none fits is refused
    /// rather than filled some other way than asked.
    Shipped,
    /// Model files (their bytes), each with a name for the record, run together.
    Given(Vec<(String, Vec<u8>)>),
}

/// The filler of one take: `fill` alone, or the refiners of `source` (each starting from the
/// fill it was trained on, so `fill` is not used then).
///
/// Refiners are loaded per call: a burn module is not shared between threads, so a caller
/// filling takes in parallel calls this once per take.
///
/// # Errors
/// A given model does not load; [`NnError::NoShippedRefiner`] where `source` is
/// [`RefinerSource::Shipped`] and no shipped refiner carries the take's markers.
pub fn filler_for(take: &Take, fill: FillConfig, source: &RefinerSource) -> Result<Box<dyn Filler>, NnError> {
    let device = Default::default();
    match source {
        RefinerSource::None => Ok(Box::new(fill)),
        RefinerSource::Given(models) => {
            let mut named = Vec::with_capacity(models.len());
            for (name, bytes) in models {
                named.push((name.clone(), Refiner::from_bytes(bytes, &device)?));
            }
            Ok(Box::new(Refiners::new(named)))
        }
        RefinerSource::Shipped => {
            let fitting = crate::shipped::refiners_for(take, &device)?;
            if fitting.is_empty() {
                let shipped: Vec<&str> = crate::shipped::REFINERS.iter().map(|s| s.name).collect();
                return Err(NnError::NoShippedRefiner { shipped: shipped.join(", ") });
            }
            Ok(Box::new(fitting))
        }
    }
}

/// Of a set of refiners, those that carry a take's markers, run together: one filler that
/// scores "the shipped refiners" on takes of different marker sets (`locap bench fill`'s
/// `neural`).
#[derive(Debug, Clone, Copy)]
pub struct FittingRefiners<'a>(pub &'a [Refiner]);

impl Filler for FittingRefiners<'_> {
    fn describe(&self) -> String {
        "shipped refiners".into()
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        let fitting: Vec<&Refiner> = self.0.iter().filter(|r| r.fits(take)).collect();
        if fitting.is_empty() {
            return Err(FillError::new(self, "no shipped refiner was trained on this marker set"));
        }
        crate::refine_all_of(take, &fitting).map_err(|e| FillError::new(self, e))
    }
}
