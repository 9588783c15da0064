//! Ceilings on network, batch and window sizes, checked before anything is allocated.
//!
//! A size comes from a command line, a config file or a model file; none of them may make
//! training or inference allocate without bound or run for ever (issue 14: `train fill
//! --hidden 100000` aborted on an allocation failure, `--batch 100000` never finished a step).
//! Each ceiling is far above what the paper uses (its defaults are in brackets), so a
//! researcher scaling up meets them only where the machine would fail first:
//!
//! | setting | default | ceiling |
//! |---|---|---|
//! | refiner LSTM hidden size per direction | 128 | [`MAX_HIDDEN`] 2,048 |
//! | features per marker or joint node (refiner and solver `channels`) | 16, 32 | [`MAX_CHANNELS`] 512 |
//! | solver global node (the MLP: 4 x global) | 128 | [`MAX_GLOBAL`] 4,096 |
//! | refiner window, and each margin | 64, 32 | [`MAX_WINDOW`] 4,096 frames |
//! | refiner batch (windows per step) | 16 | [`MAX_BATCH_WINDOWS`] 1,024 |
//! | solver batch (frames per step) | 256 | [`MAX_BATCH_FRAMES`] 65,536 |
//! | validation examples (refiner windows, solver frames) | 64, 2,048 | [`MAX_VALIDATION_WINDOWS`] 4,096, [`MAX_VALIDATION_FRAMES`] 1,048,576 |
//! | graph neighbours per marker | 6, 3 | [`MAX_NEIGHBOURS`] 64 |
//! | weights of one network | about 0.9 M (refiner, 41 markers) | [`MAX_WEIGHTS`] 100 M |
//!
//! Sizes multiply (the refiner's LSTM reads `markers x channels` features), so the weight
//! count is checked too, once the markers and joints are known ([`check_weights`]): 100 M
//! weights are 400 MB of `f32`, about 1.6 GB with Adam's two moments and the gradients.

use crate::NnError;

/// Largest LSTM hidden size per direction.
pub const MAX_HIDDEN: usize = 2048;
/// Most features per marker or joint node.
pub const MAX_CHANNELS: usize = 512;
/// Widest solver global node (the MLP's width is 4 times it).
pub const MAX_GLOBAL: usize = 4096;
/// Longest refiner window or margin, frames.
pub const MAX_WINDOW: usize = 4096;
/// Most refiner windows per step.
pub const MAX_BATCH_WINDOWS: usize = 1024;
/// Most solver frames per step.
pub const MAX_BATCH_FRAMES: usize = 65_536;
/// Most refiner validation windows.
pub const MAX_VALIDATION_WINDOWS: usize = 4096;
/// Most solver validation frames.
pub const MAX_VALIDATION_FRAMES: usize = 1 << 20;
/// Most graph neighbours per marker.
pub const MAX_NEIGHBOURS: usize = 64;
/// Most weights of one network.
pub const MAX_WEIGHTS: u64 = 100_000_000;

/// `value` of the setting `what` against `max`.
///
/// # Errors
/// [`NnError::Limit`] above the ceiling.
pub fn check(what: &'static str, value: usize, max: usize) -> Result<(), NnError> {
    if value > max { Err(NnError::Limit { what, value: value as u64, max: max as u64 }) } else { Ok(()) }
}

/// Each of `settings` (name, value) against the floor `min`.
///
/// # Errors
/// [`NnError::Setting`] for the first below it.
pub fn at_least(min: usize, settings: &[(&'static str, usize)]) -> Result<(), NnError> {
    match settings.iter().find(|(_, value)| *value < min) {
        Some((what, value)) => Err(NnError::Setting {
            what,
            value: value.to_string(),
            expected: if min == 1 { "1 or more" } else { "2 or more" },
        }),
        None => Ok(()),
    }
}

/// The fraction of every take held out for validation: in `0..0.9`.
///
/// # Errors
/// [`NnError::Setting`] outside it.
pub fn validation_fraction(value: f64) -> Result<(), NnError> {
    if (0.0..0.9).contains(&value) {
        return Ok(());
    }
    Err(NnError::Setting { what: "validation fraction", value: value.to_string(), expected: "in 0..0.9" })
}

/// A network's weight count (as `f64`: sizes from a file may overflow integer products)
/// against [`MAX_WEIGHTS`].
///
/// # Errors
/// [`NnError::Limit`] above the ceiling.
pub fn check_weights(weights: f64) -> Result<(), NnError> {
    if weights > MAX_WEIGHTS as f64 {
        return Err(NnError::Limit {
            what: "network weights",
            value: weights.min(u64::MAX as f64) as u64,
            max: MAX_WEIGHTS,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ceilings_are_inclusive_and_named() {
        assert!(check("hidden", MAX_HIDDEN, MAX_HIDDEN).is_ok());
        let e = check("hidden", 100_000, MAX_HIDDEN).unwrap_err().to_string();
        assert_eq!(e, "hidden 100000 is above its ceiling 2048");
        assert!(check_weights(MAX_WEIGHTS as f64).is_ok());
        assert!(check_weights(1e30).unwrap_err().to_string().starts_with("network weights 18446744073709551615"));
    }
}
