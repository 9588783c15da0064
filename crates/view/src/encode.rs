//! Compact binary blocks for the page: quantised positions, deltas, zlib, base64.
//!
//! A 10-minute 120 Hz take of 41 markers has 8.9 million coordinates: 35 MB as float32 and 47
//! MB once base64 encoded, too much for a page that must open in seconds. So:
//!
//! 1. **Quantise** each axis to `i16` over the range the data covers ([`Quantiser`]): a 10 m
//!    capture volume gives 0.15 mm steps, far below marker noise (about 1 mm).
//! 2. **Track-major second differences**: each track (one axis of one marker or joint) is
//!    stored frame after frame, differenced twice ([`DELTA_ORDER`]; wrapping `i16`
//!    arithmetic, so the browser undoes it with two prefix sums in an `Int16Array`). Smooth
//!    motion turns into small numbers that compress well, better than after one difference
//!    (measured on real and synthetic takes: `docs/benchmarks.md`). A missing sample repeats
//!    the last known position (the first known one before it), so gaps cost nothing and the
//!    page can draw a "ghost" where a missing marker was last seen.
//! 3. **zlib** ([`flate2`], level 3) and **base64**: the browser inflates with its native
//!    `DecompressionStream("deflate")`, no JavaScript inflater needed. Level 3 because the
//!    differences are nearly noise to deflate: higher levels took several times as long and
//!    made no smaller pages (measured in `docs/benchmarks.md`).
//!
//! All numbers are little-endian (the byte order of every browser platform). The decoders in
//! this module mirror the page's JavaScript and exist for the round-trip tests.

use crate::ViewError;
use base64::Engine;
use locap_core::Vec3;
use std::io::Write;

/// Maps millimetre coordinates to `i16` steps: `value_mm = offset_mm + (q + 32767) * step_mm`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Quantiser {
    /// Smallest coordinate per axis, mm (maps to `q = -32767`).
    pub offset_mm: [f64; 3],
    /// Size of one step per axis, mm.
    pub step_mm: [f64; 3],
}

/// Smallest step: below this, quantisation is finer than any capture system.
const MIN_STEP_MM: f64 = 0.001;

impl Quantiser {
    /// A quantiser covering every point of `points` (a unit box at the origin if there are
    /// none). Non-finite points are ignored.
    pub fn covering(points: impl IntoIterator<Item = Vec3>) -> Quantiser {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points.into_iter().filter(|p| p.iter().all(|c| c.is_finite())) {
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let mut q = Quantiser { offset_mm: [0.0; 3], step_mm: [MIN_STEP_MM; 3] };
        for a in 0..3 {
            if lo[a].is_finite() {
                q.offset_mm[a] = lo[a];
                q.step_mm[a] = ((hi[a] - lo[a]) / 65534.0).max(MIN_STEP_MM);
            }
        }
        q
    }

    /// The steps of `p` (clamped to the covered range).
    pub fn quantise(&self, p: Vec3) -> [i16; 3] {
        std::array::from_fn(|a| {
            let steps = ((p[a] - self.offset_mm[a]) / self.step_mm[a]).round();
            (steps.clamp(0.0, 65534.0) - 32767.0) as i16
        })
    }

    /// The position of steps `q`, mm.
    pub fn dequantise(&self, q: [i16; 3]) -> Vec3 {
        Vec3::from_fn(|a, _| self.offset_mm[a] + (f64::from(q[a]) + 32767.0) * self.step_mm[a])
    }

    /// Largest error [`Quantiser::quantise`] makes inside the covered range, mm.
    pub fn max_error_mm(&self) -> f64 {
        self.step_mm.iter().fold(0.0, |m, s| m.max(s / 2.0))
    }
}

/// How many times each track is differenced (the page's JSON header carries it as
/// `delta_order`).
pub const DELTA_ORDER: usize = 2;

/// Encodes `tracks` (one per marker or joint, each with one optional position per frame, all
/// of the same length) as track-major, axis-minor steps differenced [`DELTA_ORDER`] times:
/// element `(track * 3 + axis) * frames + frame`. Missing samples repeat the last known
/// position (the first known one for a leading gap; the quantiser's origin if the track is
/// never seen).
pub fn encode_tracks(tracks: &[Vec<Option<Vec3>>], q: &Quantiser) -> Vec<i16> {
    let frames = tracks.first().map_or(0, Vec::len);
    let mut out = Vec::with_capacity(tracks.len() * 3 * frames);
    for track in tracks {
        debug_assert_eq!(track.len(), frames);
        let first = track.iter().flatten().next().map_or([-32767; 3], |p| q.quantise(*p));
        let mut held = first;
        let steps: Vec<[i16; 3]> = track
            .iter()
            .map(|p| {
                if let Some(p) = p {
                    held = q.quantise(*p);
                }
                held
            })
            .collect();
        for a in 0..3 {
            let mut channel: Vec<i16> = steps.iter().map(|s| s[a]).collect();
            for _ in 0..DELTA_ORDER {
                let mut previous = 0i16;
                for v in &mut channel {
                    (*v, previous) = (v.wrapping_sub(previous), *v);
                }
            }
            out.extend(channel);
        }
    }
    out
}

/// Undoes [`encode_tracks`]: `tracks` tracks of `frames` positions (held ones included), mm.
pub fn decode_tracks(deltas: &[i16], tracks: usize, frames: usize, q: &Quantiser) -> Vec<Vec<Vec3>> {
    (0..tracks)
        .map(|t| {
            let axes: [Vec<i16>; 3] = std::array::from_fn(|a| {
                let mut channel = deltas[(t * 3 + a) * frames..(t * 3 + a + 1) * frames].to_vec();
                for _ in 0..DELTA_ORDER {
                    let mut value = 0i16;
                    for v in &mut channel {
                        value = value.wrapping_add(*v);
                        *v = value;
                    }
                }
                channel
            });
            (0..frames).map(|f| q.dequantise([axes[0][f], axes[1][f], axes[2][f]])).collect()
        })
        .collect()
}

/// Little-endian bytes of `values`.
pub fn i16_bytes(values: &[i16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// Little-endian bytes of `values`.
pub fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// zlib-compresses `bytes` and base64-encodes the result (standard alphabet, padded): the
/// text of one block in the page.
pub fn pack(bytes: &[u8]) -> String {
    let mut z = flate2::write::ZlibEncoder::new(Vec::with_capacity(bytes.len() / 3), flate2::Compression::new(3));
    // Writing into a Vec cannot fail.
    let _ = z.write_all(bytes);
    let compressed = z.finish().unwrap_or_default();
    base64::engine::general_purpose::STANDARD.encode(compressed)
}

/// Undoes [`pack`].
///
/// # Errors
/// Text that is not base64 or bytes that are not zlib data.
pub fn unpack(text: &str) -> Result<Vec<u8>, ViewError> {
    let compressed = base64::engine::general_purpose::STANDARD
        .decode(text.trim())
        .map_err(|e| ViewError::BadBlock(format!("not base64: {e}")))?;
    let mut out = Vec::new();
    let mut z = flate2::write::ZlibDecoder::new(&mut out);
    z.write_all(&compressed)
        .and_then(|_| z.finish().map(|_| ()))
        .map_err(|e| ViewError::BadBlock(format!("not zlib: {e}")))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn held_samples_repeat_the_last_known_position() {
        let q = Quantiser::covering([Vec3::new(0.0, 0.0, 0.0), Vec3::new(1000.0, 2000.0, 3000.0)]);
        let a = Vec3::new(10.0, 20.0, 30.0);
        let b = Vec3::new(500.0, 1500.0, 2500.0);
        let tracks = vec![vec![None, Some(a), None, Some(b), None], vec![None; 5]];
        let back = decode_tracks(&encode_tracks(&tracks, &q), 2, 5, &q);
        let close = |p: Vec3, r: Vec3| (p - r).amax() <= q.max_error_mm() + 1e-9;
        assert!(close(back[0][0], a) && close(back[0][1], a) && close(back[0][2], a));
        assert!(close(back[0][3], b) && close(back[0][4], b));
        assert!(back[1].iter().all(|p| close(*p, Vec3::new(0.0, 0.0, 0.0))));
    }

    #[test]
    fn pack_round_trips_and_compresses_smooth_deltas() {
        let q = Quantiser::covering([Vec3::new(-3000.0, -3000.0, 0.0), Vec3::new(3000.0, 3000.0, 2000.0)]);
        let track: Vec<Option<Vec3>> = (0..12_000)
            .map(|f| {
                let t = f as f64 / 120.0;
                Some(Vec3::new(1000.0 * t.sin(), 800.0 * (0.7 * t).cos(), 1000.0 + 200.0 * (2.0 * t).sin()))
            })
            .collect();
        let deltas = encode_tracks(&[track], &q);
        let bytes = i16_bytes(&deltas);
        let text = pack(&bytes);
        assert_eq!(unpack(&text).unwrap(), bytes);
        // base64 adds 4/3; smooth motion still ends up well under the raw size.
        assert!(text.len() < bytes.len() / 2, "{} vs {}", text.len(), bytes.len());
        assert!(unpack("not base64!").unwrap_err().to_string().contains("base64"));
        assert!(unpack("aGVsbG8=").unwrap_err().to_string().contains("zlib"));
    }

    proptest! {
        #[test]
        fn tracks_round_trip_within_half_a_step(
            samples in proptest::collection::vec(
                proptest::option::of((-5000.0f64..5000.0, -5000.0f64..5000.0, 0.0f64..3000.0)), 1..60),
        ) {
            let track: Vec<Option<Vec3>> = samples.iter().map(|s| s.map(|(x, y, z)| Vec3::new(x, y, z))).collect();
            let q = Quantiser::covering(track.iter().flatten().copied());
            let back = decode_tracks(&encode_tracks(std::slice::from_ref(&track), &q), 1, track.len(), &q);
            for (p, r) in track.iter().zip(&back[0]) {
                if let Some(p) = p {
                    prop_assert!((p - r).amax() <= q.max_error_mm() + 1e-9);
                }
            }
            prop_assert!(q.max_error_mm() <= 10_000.0 / 65534.0 / 2.0 + 1e-9);
        }
    }
}
