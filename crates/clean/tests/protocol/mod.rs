//! The fixed-length gap protocol of issue 15, shared by `tests/auto_real.rs` and
//! `examples/auto_fill.rs`: on a gap-free take, hide seeded gaps of 0.1 / 0.5 / 1 / 2 s
//! (`per_length` of each, where the marker is captured around them, never at the take's
//! edges), and score a filler by the RMSE over exactly the hidden samples.
//! - "single": one gap per input;
//! - "multi": all gaps at once, plus three neighbouring markers of one arm hidden together for
//!   1 s (scored as the bucket `limb`).
//!
//! A hidden sample a filler leaves missing counts with the error of the linear fill there, so
//! every filler is scored on the same samples; the count is reported.

#![allow(dead_code)]

use locap_clean::{Filled, baseline};
use locap_core::Take;
use std::ops::Range;

/// Gap lengths in seconds.
pub const LENGTHS_S: [f64; 4] = [0.1, 0.5, 1.0, 2.0];

/// The arm markers hidden together in "multi" (CMU / HDM05 names), for 1 s.
pub const LIMB: [&str; 3] = ["LFRM", "LWRA", "LWRB"];

/// One hidden gap.
#[derive(Debug, Clone)]
pub struct Hidden {
    pub marker: usize,
    pub frames: Range<usize>,
    /// Bucket name: `0.1s`, ..., `limb`.
    pub bucket: String,
}

/// Squared-error sums per bucket.
#[derive(Debug, Clone, Default)]
pub struct Score {
    /// (bucket, sum of squared errors, samples, samples left missing)
    pub buckets: Vec<(String, f64, usize, usize)>,
}

impl Score {
    pub fn add(&mut self, bucket: &str, sq: f64, missing: bool) {
        let entry = match self.buckets.iter().position(|b| b.0 == bucket) {
            Some(k) => &mut self.buckets[k],
            None => {
                self.buckets.push((bucket.to_string(), 0.0, 0, 0));
                self.buckets.last_mut().unwrap()
            }
        };
        entry.1 += sq;
        entry.2 += 1;
        entry.3 += missing as usize;
    }

    pub fn merge(&mut self, other: &Score) {
        for (b, sq, n, miss) in &other.buckets {
            let entry = match self.buckets.iter().position(|x| x.0 == *b) {
                Some(k) => &mut self.buckets[k],
                None => {
                    self.buckets.push((b.clone(), 0.0, 0, 0));
                    self.buckets.last_mut().unwrap()
                }
            };
            entry.1 += sq;
            entry.2 += n;
            entry.3 += miss;
        }
    }

    pub fn rmse(&self, bucket: &str) -> Option<f64> {
        self.buckets.iter().find(|b| b.0 == bucket).map(|b| (b.1 / b.2.max(1) as f64).sqrt())
    }

    pub fn overall(&self) -> f64 {
        let (sq, n) = self.buckets.iter().fold((0.0, 0), |(s, n), b| (s + b.1, n + b.2));
        (sq / n.max(1) as f64).sqrt()
    }

    pub fn missing(&self) -> usize {
        self.buckets.iter().map(|b| b.3).sum()
    }
}

/// SplitMix64 step.
pub fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Reads a shared take and drops its unlabeled points (the protocol scores labeled markers).
pub fn read_take(relative: &str) -> Option<Take> {
    let path = locap_testkit::shared_file(relative)?;
    let take = locap_io::c3d::read_path(&path).expect("shared take reads").to_take().expect("shared take converts");
    let keep: Vec<usize> = (0..take.marker_count()).filter(|i| !take.markers()[*i].is_unlabeled()).collect();
    let names = keep.iter().map(|i| take.markers()[*i].clone()).collect();
    let samples: Vec<_> = (0..take.frame_count())
        .flat_map(|f| keep.iter().map(move |i| (f, *i)))
        .map(|(f, i)| take.position_mm(f, i))
        .collect();
    Some(Take::from_samples(names, &samples, take.frame_rate_hz()).expect("labeled subset"))
}

/// The seeded gaps: `per_length` of each length, distinct markers per length where possible,
/// each where its marker is captured from one frame before to one frame after, and (for the
/// multi input) not overlapping another gap of the same marker.
pub fn gaps(take: &Take, per_length: usize, seed: u64) -> Vec<Hidden> {
    let frames = take.frame_count();
    let markers = take.marker_count();
    let mut state = seed;
    let mut out: Vec<Hidden> = Vec::new();
    for len_s in LENGTHS_S {
        let len = (len_s * take.frame_rate_hz()).round() as usize;
        let mut placed = 0;
        let mut tries = 0;
        while placed < per_length && tries < 10_000 {
            tries += 1;
            let marker = (splitmix(&mut state) % markers as u64) as usize;
            if frames < len + 4 {
                break;
            }
            let start = 1 + (splitmix(&mut state) % (frames - len - 2) as u64) as usize;
            let frames_r = start..start + len;
            let captured = (start - 1..start + len + 1).all(|f| take.is_valid(f, marker));
            let clash =
                out.iter().any(|h| h.marker == marker && h.frames.start < start + len + 2 && start < h.frames.end + 2);
            if captured && !clash {
                out.push(Hidden { marker, frames: frames_r, bucket: format!("{len_s}s") });
                placed += 1;
            }
        }
    }
    out
}

/// The limb gap of the multi input: [`LIMB`] for 1 s at a seeded start, where they are
/// captured and no other hidden gap of theirs is.
pub fn limb(take: &Take, others: &[Hidden], seed: u64) -> Vec<Hidden> {
    let ids: Option<Vec<usize>> = LIMB.iter().map(|n| take.marker_index(n)).collect();
    let Some(ids) = ids else { return Vec::new() };
    let len = take.frame_rate_hz().round() as usize;
    let frames = take.frame_count();
    let mut state = seed ^ 0x11AB;
    for _ in 0..10_000 {
        if frames < len + 4 {
            break;
        }
        let start = 1 + (splitmix(&mut state) % (frames - len - 2) as u64) as usize;
        let ok = ids.iter().all(|m| {
            (start - 1..start + len + 1).all(|f| take.is_valid(f, *m))
                && !others
                    .iter()
                    .any(|h| h.marker == *m && h.frames.start < start + len + 2 && start < h.frames.end + 2)
        });
        if ok {
            return ids
                .iter()
                .map(|m| Hidden { marker: *m, frames: start..start + len, bucket: "limb".into() })
                .collect();
        }
    }
    Vec::new()
}

/// `take` with `gaps` removed.
pub fn holed(take: &Take, gaps: &[Hidden]) -> Take {
    let mut out = take.clone();
    for h in gaps {
        for f in h.frames.clone() {
            out.set_position_mm(f, h.marker, None).expect("removing a sample");
        }
    }
    out
}

/// Scores `filled` on `gaps` against `truth`; `linear` is the linear fill of the same input,
/// whose error stands in for samples `filled` left missing.
pub fn score(truth: &Take, filled: &Filled, linear: &Filled, gaps: &[Hidden], into: &mut Score) {
    for h in gaps {
        for f in h.frames.clone() {
            let t = truth.position_mm(f, h.marker).expect("hidden samples were captured");
            match filled.take.position_mm(f, h.marker) {
                Some(p) => into.add(&h.bucket, (p - t).norm_squared(), false),
                None => {
                    let p = linear.take.position_mm(f, h.marker).expect("interior gaps fill linearly");
                    into.add(&h.bucket, (p - t).norm_squared(), true);
                }
            }
        }
    }
}

/// The linear fill, the stand-in for missing samples.
pub fn linear(take: &Take) -> Filled {
    baseline::linear::fill(take)
}
