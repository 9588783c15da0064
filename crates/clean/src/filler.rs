//! The [`Filler`] trait: anything that fills a take's gaps, so the clean stage, the solver's
//! cleaning and the fill benchmark take one type whether the fill is a classical method of
//! this crate ([`FillConfig`]) or a learned refiner from the `nn` crate (LocalMoCap section
//! 3.1: EDM first, then the biLSTM's correction).

use crate::{FillConfig, FillMethod, Filled, auto};
use locap_core::Take;
use locap_core::provenance::{FillRecord, MarkerFrames};

/// A gap filler.
///
/// Implementations fill every gap they can of every labeled marker and report which samples
/// they computed ([`Filled::filled`]); samples they cannot reach stay missing. A filler never
/// changes a captured sample.
pub trait Filler {
    /// What filled, as recorded in `LOCAP:METHOD` and benchmark tables (e.g. `Edm K=6`).
    fn describe(&self) -> String;

    /// Fills `take`.
    ///
    /// # Errors
    /// The filler cannot run on this take (e.g. a learned model trained on other markers).
    fn fill(&self, take: &Take) -> Result<Filled, FillError>;

    /// Fills `take` and says, per gap, what filled it, for a filler that chooses per gap
    /// (`auto`); one that fills every gap one way returns no records (its
    /// [`Filler::describe`] says it all).
    ///
    /// # Errors
    /// As [`Filler::fill`].
    fn fill_recorded(&self, take: &Take) -> Result<(Filled, Vec<FillRecord>), FillError> {
        Ok((self.fill(take)?, Vec::new()))
    }
}

/// Why a [`Filler`] could not fill a take.
#[derive(Debug, thiserror::Error)]
#[error("{filler}: {source}")]
pub struct FillError {
    /// The filler's [`Filler::describe`].
    pub filler: String,
    /// What went wrong.
    #[source]
    pub source: Box<dyn std::error::Error + Send + Sync>,
}

impl FillError {
    /// Wraps `source` as a failure of `filler`.
    pub fn new(filler: &dyn Filler, source: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> FillError {
        FillError { filler: filler.describe(), source: source.into() }
    }
}

impl Filler for FillConfig {
    fn describe(&self) -> String {
        match self.method {
            crate::FillMethod::Edm => format!("Edm K={}", self.neighbours),
            crate::FillMethod::Auto => auto::AutoConfig::from_fill(self).describe(),
            method => format!("{method:?}"),
        }
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        Ok(crate::fill_gaps(take, self))
    }

    fn fill_recorded(&self, take: &Take) -> Result<(Filled, Vec<FillRecord>), FillError> {
        match self.method {
            FillMethod::Auto => auto::AutoConfig::from_fill(self).fill_recorded(take),
            _ => Ok((crate::fill_gaps(take, self), Vec::new())),
        }
    }
}

impl Filler for auto::AutoConfig {
    fn describe(&self) -> String {
        format!("Auto trials={} blend={}", self.trials, self.blend)
    }

    fn fill(&self, take: &Take) -> Result<Filled, FillError> {
        Ok(auto::fill(take, self).filled)
    }

    fn fill_recorded(&self, take: &Take) -> Result<(Filled, Vec<FillRecord>), FillError> {
        let auto = auto::fill(take, self);
        let records = auto
            .choices
            .iter()
            .filter(|c| c.filled > 0)
            .map(|c| FillRecord { at: MarkerFrames { marker: c.marker, frames: c.frames.clone() }, method: c.method() })
            .collect();
        Ok((auto.filled, records))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FillMethod;
    use locap_core::{MarkerName, Vec3};

    #[test]
    fn a_fill_config_fills_like_fill_gaps_and_names_itself() {
        let names = vec![MarkerName::parse("A"), MarkerName::parse("B")];
        let samples: Vec<Option<Vec3>> = (0..10)
            .flat_map(|f| {
                let a = (f != 4).then(|| Vec3::new(f as f64, 0.0, 0.0));
                [a, Some(Vec3::new(f as f64, 100.0, 0.0))]
            })
            .collect();
        let take = Take::from_samples(names, &samples, 100.0).unwrap();
        let config = FillConfig { method: FillMethod::Linear, ..FillConfig::default() };
        let filled = Filler::fill(&config, &take).unwrap();
        assert_eq!(filled, crate::fill_gaps(&take, &config));
        assert_eq!(filled.filled_count(), 1);
        assert_eq!(config.describe(), "Linear");
        assert_eq!(FillConfig::default().describe(), "Edm K=6");
        let boxed: Box<dyn Filler> = Box::new(config);
        assert_eq!(boxed.describe(), "Linear");
    }
}
