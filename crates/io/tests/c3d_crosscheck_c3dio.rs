//! Cross-check against a second, independent Rust reader: every C3D file under
//! `../shared/data` that c3dio (crates.io) reads without error must give the same point
//! count, frame count, frame rate, labels and point coordinates in locap, except for the
//! documented disagreements in [`KNOWN`], each checked by hand (see there for who is right).
//!
//! Missing samples: c3dio has no notion of them; it returns the stored coordinates and the
//! residual byte. In float files it reads the residual as the *low byte* of the residual word
//! taken as a signed byte (so a valid sample whose residual byte is 128 or more reads as
//! negative; about 288 000 samples of the shared files), in integer files it does so only when
//! the word is negative; the C3D standard (and locap) calls a sample missing when the whole
//! 16-bit word is negative, and locap also treats all-zero or
//! non-finite coordinates as missing. So coordinates are compared where locap finds a sample
//! and c3dio's residual is non-negative, and every sample where the two disagree about a
//! negative residual must be explained by c3dio's low-byte rule applied to the raw word.

mod common;

use locap_io::c3d::{self, C3dFile, Storage};

/// Files where c3dio and locap disagree, checked by hand, with the (points, frames) locap must
/// read. All three lack a `POINT:FRAMES` parameter, and c3dio 0.8 then reads 0 frames
/// (`Points::calc_num_frames` replaces the header's frame range by `POINT:FRAMES` whenever the
/// two differ, and takes an absent parameter as 0); the header's frame range and the size of
/// the data section both give locap's count exactly, so **locap is right**:
/// - `phasespace_sample.c3d`: no parameter records at all; header: 40 float points, frames
///   1-701, data from block 3: 449664 bytes = 2 * 512 + 701 * 40 * 16. c3dio also loses the
///   40 points (its point grid has no columns when it has no rows).
/// - `1123x01EMG.c3d`: EMG only (no points, 8 float analog samples per frame), header frames
///   1-4564, data from block 9: (150144 - 8 * 512) / (8 * 4) = 4564 frames.
/// - `Kistler.c3d`: no `POINT` group, 160 integer analog samples per frame, header frames
///   1-3969, data from block 4: (1271616 - 3 * 512) / (160 * 2) = 3969 frames.
const KNOWN: &[(&str, usize, usize)] =
    &[("phasespace_sample.c3d", 40, 701), ("1123x01EMG.c3d", 0, 4564), ("Kistler.c3d", 0, 3969)];

/// Samples compared, and samples locap finds that c3dio calls missing (negative residual).
#[derive(Default)]
struct Counts {
    compared: usize,
    valid_but_negative_residual: usize,
}

/// How c3dio's reading of a file differs from locap's (empty if they agree).
fn compare(ours: &C3dFile, theirs: &c3dio::C3d, counts: &mut Counts) -> Vec<String> {
    let mut diffs = Vec::new();
    let (mut frames, points) = (theirs.points.rows(), theirs.points.cols());
    // c3dio keeps points in a `grid::Grid`, which has no rows when it has no columns: for a
    // file without points, its frame count is in the analog grid (one row per analog sample).
    let per_frame = theirs.analog.samples_per_channel_per_frame as usize;
    if points == 0 && per_frame > 0 {
        frames = theirs.analog.rows() / per_frame;
    }
    // Without points or analog channels (C3DRotationExample.c3d: rotations only), c3dio has
    // no frame count to compare.
    let frames_comparable = points > 0 || theirs.analog.samples_per_frame > 0;
    if points != ours.point_count {
        diffs.push(format!("point count: locap {}, c3dio {points}", ours.point_count));
    }
    if frames_comparable && frames != ours.frames {
        diffs.push(format!("frame count: locap {}, c3dio {frames}", ours.frames));
    }
    let rate = theirs.points.frame_rate as f64;
    if (rate - ours.frame_rate_hz()).abs() > 1e-3 * rate.abs().max(1.0) {
        diffs.push(format!("frame rate: locap {}, c3dio {rate}", ours.frame_rate_hz()));
    }
    let labels = ours.point_labels();
    // c3dio reads POINT:LABELS only (not LABELS2, ...), trimmed, possibly more or fewer than
    // there are points; locap completes missing labels with `*N`.
    for (i, (a, b)) in labels.iter().zip(&theirs.points.labels).enumerate() {
        if a.trim() != b.trim() && !(b.trim().is_empty() && *a == format!("*{i}")) {
            diffs.push(format!("label {i}: locap {a:?}, c3dio {b:?}"));
            break;
        }
    }
    if !diffs.is_empty() {
        return diffs;
    }
    let tolerance = match ours.storage {
        Storage::Int => ours.point_scale() * 1.0001,
        Storage::Float => 1e-3,
    };
    let take = ours.to_take().unwrap();
    let (mut worst, mut validity_unexplained) = (0f32, 0usize);
    let mut first_bad = None;
    for f in 0..frames {
        for m in 0..points {
            let w = ours.points[f * points + m];
            let p = theirs.points[f][m];
            let theirs_negative = p.residual < 0.0;
            // c3dio's rule on the raw residual word: the low byte as a signed byte.
            let word = match ours.storage {
                Storage::Int => w[3] as i32 as i16,
                Storage::Float => w[3] as i16,
            };
            let low_byte_negative = ((word & 0xff) as u8 as i8) < 0;
            let predicted = match ours.storage {
                // Integer files: c3dio keeps the unsigned low byte when the word is non-negative.
                Storage::Int => word < 0 && low_byte_negative,
                Storage::Float => low_byte_negative,
            };
            if theirs_negative != predicted {
                validity_unexplained += 1;
            }
            if take.is_valid(f, m) && !theirs_negative {
                let d = (0..3).map(|k| (w[k] - p.point[k]).abs()).fold(0f32, f32::max);
                if d.is_nan() || d > tolerance {
                    first_bad.get_or_insert((f, m, w, p.point));
                }
                if d.is_finite() {
                    worst = worst.max(d);
                }
                counts.compared += 1;
            } else if take.is_valid(f, m) {
                counts.valid_but_negative_residual += 1;
            }
        }
    }
    if let Some((f, m, w, p)) = first_bad {
        diffs.push(format!(
            "positions: frame {f} point {m}: locap {:?}, c3dio {p:?} (worst {worst}, tolerance {tolerance})",
            &w[..3]
        ));
    }
    if validity_unexplained > 0 {
        diffs.push(format!("{validity_unexplained} residuals not explained by c3dio's low-byte rule"));
    }
    diffs
}

#[test]
fn c3dio_reads_what_locap_reads() {
    let Some(data) = common::shared_data() else { return };
    let (mut read_by_both, mut counts) = (0, Counts::default());
    let (mut report, mut known_seen) = (Vec::new(), 0);
    for path in common::files_with_extension(&data, "c3d") {
        let name = path.strip_prefix(&data).unwrap().display().to_string();
        let theirs = std::panic::catch_unwind(|| c3dio::C3d::load_path(path.clone()).map_err(|e| format!("{e:?}")));
        let theirs = match theirs {
            Ok(Ok(c)) => c,
            Ok(Err(e)) => {
                eprintln!("{name}: c3dio error {e}");
                continue;
            }
            Err(_) => {
                eprintln!("{name}: c3dio panicked");
                continue;
            }
        };
        let ours = match c3d::read_path(&path) {
            Ok(f) => f,
            Err(e) => {
                report.push(format!("{name}: locap fails ({e}) but c3dio reads it"));
                continue;
            }
        };
        read_by_both += 1;
        let diffs = compare(&ours, &theirs, &mut counts);
        let file_name = path.file_name().unwrap().to_str().unwrap();
        match KNOWN.iter().find(|(k, _, _)| *k == file_name) {
            Some((_, points, frames)) => {
                eprintln!("{name}: known disagreement: {}", diffs.join("; "));
                assert!(!diffs.is_empty(), "{name}: c3dio now agrees; remove it from KNOWN");
                assert_eq!((ours.point_count, ours.frames), (*points, *frames), "{name}");
                known_seen += 1;
            }
            None if !diffs.is_empty() => report.push(format!("{name}: {}", diffs.join("; "))),
            None => {}
        }
    }
    eprintln!(
        "{read_by_both} files read by both, {} samples compared; {} samples locap finds are missing \
         for c3dio (residual word with its low byte >= 128)",
        counts.compared, counts.valid_but_negative_residual
    );
    assert!(read_by_both > 100, "expected the shared C3D files, c3dio and locap read only {read_by_both}");
    assert_eq!(known_seen, KNOWN.len(), "a file of KNOWN was not read by both readers");
    assert!(report.is_empty(), "c3dio and locap disagree:\n{}", report.join("\n"));
}
