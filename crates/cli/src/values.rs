//! Checked option values: a number that cannot make sense is a usage error (exit status 2)
//! with a message naming the option, never a silent fallback, a hang or an allocation abort.
//!
//! The ceilings are the libraries' own (`locap_nn::limits`, `locap_synth`, `locap_eval`), which
//! check them again for library users: generous bounds a real job stays far below, so that a
//! typo (`--rate 1e9`, `--hidden 100000`) is refused at once instead of allocating terabytes.

use clap::builder::{RangedU64ValueParser, TypedValueParser};

/// Fastest frame rate accepted, Hz (the resampler's ceiling).
pub const MAX_RATE_HZ: f64 = locap_synth::synthesize::MAX_RATE_HZ;

/// Largest length, mm (a capture volume is tens of metres).
pub const MAX_LENGTH_MM: f64 = 1e6;

/// A bound for [`count`] from a library's `usize` ceiling.
pub const fn max(ceiling: usize) -> u64 {
    ceiling as u64
}

fn number(text: &str) -> Result<f64, String> {
    let value: f64 = text.trim().parse().map_err(|_| format!("{text:?} is not a number"))?;
    if !value.is_finite() {
        return Err(format!("{text:?} is not a finite number"));
    }
    Ok(value)
}

/// A finite number > 0.
pub fn positive(text: &str) -> Result<f64, String> {
    let value = number(text)?;
    if !(value > 0.0) {
        return Err(format!("{value} must be greater than 0"));
    }
    Ok(value)
}

/// A finite number >= 0.
pub fn non_negative(text: &str) -> Result<f64, String> {
    let value = number(text)?;
    if !(value >= 0.0) {
        return Err(format!("{value} must not be negative"));
    }
    Ok(value)
}

/// A probability or fraction in [0, 1].
pub fn fraction(text: &str) -> Result<f64, String> {
    let value = number(text)?;
    if !(0.0..=1.0).contains(&value) {
        return Err(format!("{value} must be between 0 and 1"));
    }
    Ok(value)
}

/// A frame rate in Hz: > 0 and at most [`MAX_RATE_HZ`].
pub fn rate_hz(text: &str) -> Result<f64, String> {
    let value = positive(text)?;
    if value > MAX_RATE_HZ {
        return Err(format!("{value} Hz is faster than any capture system (at most {MAX_RATE_HZ} Hz)"));
    }
    Ok(value)
}

/// A length in mm: >= 0 and at most [`MAX_LENGTH_MM`].
pub fn length_mm(text: &str) -> Result<f64, String> {
    let value = non_negative(text)?;
    if value > MAX_LENGTH_MM {
        return Err(format!("{value} mm is larger than any capture volume (at most {MAX_LENGTH_MM} mm)"));
    }
    Ok(value)
}

/// A positive length in mm, at most [`MAX_LENGTH_MM`].
pub fn positive_length_mm(text: &str) -> Result<f64, String> {
    let value = length_mm(text)?;
    if !(value > 0.0) {
        return Err(format!("{value} must be greater than 0"));
    }
    Ok(value)
}

/// A count in `min..=max`, as `usize`.
pub fn count(min: u64, max: u64) -> impl TypedValueParser<Value = usize> {
    RangedU64ValueParser::<usize>::new().range(min..=max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_that_cannot_make_sense_are_refused() {
        for bad in ["nan", "NaN", "inf", "-inf", "0", "-1", "x", ""] {
            assert!(positive(bad).is_err(), "{bad}");
        }
        assert_eq!(positive("1e-3"), Ok(1e-3));
        assert!(rate_hz("1e9").is_err());
        assert_eq!(rate_hz("240"), Ok(240.0));
        assert!(fraction("1.5").is_err());
        assert!(non_negative("-0.1").is_err());
        assert!(length_mm("1e308").is_err());
    }
}
