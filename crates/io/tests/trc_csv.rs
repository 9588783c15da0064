//! TRC and CSV against real files from several exporters, round trips, and hostile input.

mod common;

use locap_core::{LengthUnit, MarkerName, Take, Vec3};
use locap_io::Error;
use locap_io::csv::{read_csv, write_csv, write_csv_path};
use locap_io::trc::{read_trc, read_trc_file, read_trc_file_path, read_trc_path, write_trc, write_trc_path};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

fn data_dir() -> Option<PathBuf> {
    common::shared_data().map(|d| d.join("trc"))
}

/// Every `.trc` below `dir`, sorted, as (path relative to `dir`, full path).
fn trc_files(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("trc")) {
                let rel = path.strip_prefix(dir).unwrap().to_string_lossy().replace('\\', "/");
                out.push((rel, path));
            }
        }
    }
    out.sort();
    out
}

/// What each real file must give: (markers, frames, first frame, rate) or the error line.
enum Expect {
    Take { markers: usize, frames: usize, first_frame: u32, rate: f64 },
    ErrorAtLine(usize),
}

fn expected(name: &str) -> Option<Expect> {
    use Expect::*;
    let take = |markers, frames, first_frame, rate| Take { markers, frames, first_frame, rate };
    Some(match name {
        // NumMarkers 0 and no names at all: every data column is an unlabeled marker.
        "10002-20130626160334-Unnamed.trc" => take(10, 882, 1, 400.0),
        "10002-20130731010438-Unnamed.trc" => take(37, 1313, 1, 400.0),
        "Anto.trc" => take(34, 128, 1, 100.0),
        "Empty.trc" => ErrorAtLine(1),
        // NumMarkers 66, 33 names, and 59 unnamed column triples holding data (unlabeled).
        "Gait.trc" => take(92, 487, 1, 100.0),
        // 71 names, the last ones never seen: kept as all-missing markers.
        "Knee.trc" => take(71, 200, 1, 200.0),
        "MOTEK/T.trc" => take(41, 89, 1, 30.0),
        "MOTEK/ballet_reduced.trc" => take(41, 100, 1, 30.0),
        "Pipelines_Gait2392_Simbody_subject01_static.trc" => take(49, 300, 1, 60.0),
        "Pipelines_Gait2392_Simbody_subject01_walk1.trc" => take(41, 151, 1, 60.0),
        "Pipelines_Hamner_subject02_running.trc" => take(41, 600, 1, 60.0),
        "Pipelines_Hamner_subject02_static.trc" => take(49, 300, 1, 60.0),
        "Pipelines_Leg39_leg39_swing.trc" => take(41, 28, 1, 60.0),
        // Frame numbers start at 23 (OrigDataStartFrame 23).
        "Pipelines_Rajagopal_ExpData_motion_capture_run.trc" => take(42, 510, 23, 100.0),
        // Doubled tabs and padding in the header values line.
        "Pipelines_Rajagopal_ExpData_motion_capture_walk.trc" => take(41, 238, 1, 100.0),
        "Pipelines_Rajagopal_ExpData_static_walk_1.trc" => take(64, 287, 1, 100.0),
        "Res16bits.trc" => take(44, 100, 1, 100.0),
        // 65 names plus 5 unnamed columns with data.
        "SprintCalib.trc" => take(70, 337, 1, 250.0),
        "SprintMotion.trc" => take(59, 788, 1, 250.0),
        // Two header lines only.
        "Truncated.trc" => ErrorAtLine(3),
        "Tutorials_Computed_Muscle_Control_InverseKinematics_arm26_elbow_flex.trc" => take(3, 121, 1, 120.0),
        // 34 names plus 2 unnamed columns with data.
        "UpperLimbStatic.trc" => take(36, 146, 1, 100.0),
        _ => return None,
    })
}

#[test]
fn every_real_trc_reads_or_fails_with_a_line() {
    let Some(dir) = data_dir() else { return };
    let files = trc_files(&dir);
    assert!(files.len() >= 20, "expected the shared TRC set, found {}", files.len());
    for (name, path) in &files {
        let result = read_trc_file_path(path);
        match &result {
            Ok(file) => println!(
                "{name}: {} markers x {} frames, {} Hz, {}, first frame {}, {} missing; notes: {:?}",
                file.take.marker_count(),
                file.take.frame_count(),
                file.take.frame_rate_hz(),
                file.unit,
                file.take.first_frame,
                file.take.missing_count(),
                file.notes
            ),
            Err(e) => println!("{name}: error {e}"),
        }
        match (expected(name), result) {
            (None, Ok(_)) => println!("  (no expectation recorded for {name})"),
            (None, Err(e)) => panic!("{name}: unexpected error {e}"),
            (Some(Expect::Take { markers, frames, first_frame, rate }), Ok(file)) => {
                let take = &file.take;
                assert_eq!(take.marker_count(), markers, "{name} markers");
                assert_eq!(take.frame_count(), frames, "{name} frames");
                assert_eq!(take.first_frame, first_frame, "{name} first frame");
                assert_eq!(take.frame_rate_hz(), rate, "{name} rate");
                assert_eq!(file.unit, LengthUnit::Millimetre, "{name} unit");
                // Counts agree with the header wherever the header is consistent.
                assert_eq!(file.declared_frames, Some(frames), "{name} NumFrames");
                if file.declared_markers == Some(markers) {
                    assert!(file.notes.is_empty(), "{name}: {:?}", file.notes);
                } else {
                    assert_eq!(file.notes.len(), 1, "{name}: the NumMarkers mismatch is reported");
                }
                assert!(take.missing_count() < take.validity().len() || frames == 0, "{name} has data");
            }
            (Some(Expect::ErrorAtLine(line)), Err(e)) => {
                // Path-level errors name the file, and inside it the line.
                let Error::InFile { path: p, error: source } = e else { panic!("{name}: error without file") };
                assert_eq!(&p, path);
                match *source {
                    Error::Text { format: "TRC", line: l, .. } => assert_eq!(l, line, "{name} error line"),
                    other => panic!("{name}: expected a TRC line error, got {other}"),
                }
            }
            (Some(Expect::ErrorAtLine(_)), Ok(_)) => panic!("{name} should not read"),
            (Some(Expect::Take { .. }), Err(e)) => panic!("{name}: {e}"),
        }
    }
}

/// Asserts that `b` holds the same samples as `a` to within `tolerance_mm`, and the same
/// missing samples exactly.
fn assert_same_samples(a: &Take, b: &Take, tolerance_mm: f64, what: &str) {
    assert_eq!(a.markers(), b.markers(), "{what}: names");
    assert_eq!(a.frame_count(), b.frame_count(), "{what}: frames");
    assert_eq!(a.first_frame, b.first_frame, "{what}: first frame");
    assert_eq!(a.validity(), b.validity(), "{what}: missing samples");
    for f in 0..a.frame_count() {
        for m in 0..a.marker_count() {
            if let (Some(p), Some(q)) = (a.position_mm(f, m), b.position_mm(f, m)) {
                assert!((p - q).amax() <= tolerance_mm, "{what}: frame {f} marker {m}: {p:?} vs {q:?}");
            }
        }
    }
}

#[test]
fn real_files_round_trip_through_trc_and_csv() {
    let Some(dir) = data_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    for (name, path) in trc_files(&dir) {
        let Ok(original) = read_trc_path(&path) else {
            continue;
        };
        // TRC in mm and in m, through files (atomic writers) and through memory.
        let trc = tmp.path().join("out.trc");
        write_trc_path(&original, LengthUnit::Millimetre, &trc).unwrap();
        let back = read_trc_file_path(&trc).unwrap();
        assert!(back.notes.is_empty(), "{name}: {:?}", back.notes);
        assert_eq!(back.take.frame_rate_hz(), original.frame_rate_hz());
        assert_same_samples(&original, &back.take, 1e-5, &name);
        let mut metres = Vec::new();
        write_trc(&original, LengthUnit::Metre, &mut metres).unwrap();
        let back = read_trc(std::str::from_utf8(&metres).unwrap()).unwrap();
        assert_same_samples(&original, &back, 1e-5, &name);
        // CSV.
        let csv = tmp.path().join("out.csv");
        write_csv_path(&original, &csv).unwrap();
        let back = locap_io::csv::read_csv_path(&csv).unwrap();
        assert_eq!(back.frame_rate_hz(), original.frame_rate_hz(), "{name}: rate from time_s");
        assert_same_samples(&original, &back, 1e-4, &name);
    }
    // Only the two outputs remain: no temporary files left behind.
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 2);
}

/// A random small take: names (optionally with a subject prefix), samples with random gaps.
fn arb_take(min_frames: usize, name_chars: &'static str) -> impl Strategy<Value = Take> {
    let name = (proptest::option::of("[A-Za-z][A-Za-z0-9]{0,4}"), name_chars).prop_map(|(subject, label)| {
        let full = match subject {
            Some(s) => format!("{s}:{label}"),
            None => label,
        };
        MarkerName::parse(&full)
    });
    let rate = prop_oneof![Just(120.0), Just(100.0), Just(59.94), Just(30000.0 / 1001.0), 0.5f64..2000.0];
    (1usize..5, min_frames..20usize, rate, 0u32..1000)
        .prop_flat_map(move |(markers, frames, rate, first)| {
            let sample = proptest::option::weighted(0.7, proptest::array::uniform3(-5e3f64..5e3));
            (
                proptest::collection::vec(name.clone(), markers),
                proptest::collection::vec(sample, markers * frames),
                Just(rate),
                Just(first),
            )
        })
        .prop_map(|(names, samples, rate, first)| {
            let samples: Vec<Option<Vec3>> = samples.into_iter().map(|s| s.map(Vec3::from)).collect();
            let mut take = Take::from_samples(names, &samples, rate).unwrap();
            take.first_frame = first;
            take
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn trc_round_trips(
        take in arb_take(0, "[A-Za-z*][A-Za-z0-9_. :,\"]{0,6}[A-Za-z0-9]"),
        unit in prop_oneof![
            Just(LengthUnit::Millimetre),
            Just(LengthUnit::Centimetre),
            Just(LengthUnit::Metre),
            Just(LengthUnit::Inch)
        ],
    ) {
        let mut out = Vec::new();
        write_trc(&take, unit, &mut out).unwrap();
        let back = read_trc_file(std::str::from_utf8(&out).unwrap()).unwrap();
        prop_assert_eq!(back.unit, unit);
        prop_assert!(back.notes.is_empty(), "{:?}", back.notes);
        prop_assert_eq!(back.take.frame_rate_hz(), take.frame_rate_hz());
        // 10^-5 mm print resolution, rounded to half of it, plus unit conversion.
        assert_same_samples(&take, &back.take, 1e-5, "TRC");
    }

    #[test]
    fn csv_round_trips(take in arb_take(2, "[A-Za-z*][A-Za-z0-9_. :,\"\n]{0,6}[A-Za-z0-9]")) {
        let mut out = Vec::new();
        write_csv(&take, &mut out).unwrap();
        let back = read_csv(std::str::from_utf8(&out).unwrap()).unwrap();
        let rate = take.frame_rate_hz();
        prop_assert!((back.frame_rate_hz() - rate).abs() <= 1e-9 * rate, "{} vs {}", back.frame_rate_hz(), rate);
        assert_same_samples(&take, &back, 1e-4, "CSV");
    }

    #[test]
    fn garbage_never_panics(text in "(?s).{0,300}") {
        let _ = read_trc(&text);
        let _ = read_csv(&text);
        // Garbage behind a valid header reaches the row parsers.
        let _ = read_trc(&format!("PathFileType\t4\nDataRate\tUnits\tNumFrames\n100\tmm\t2\nFrame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n{text}"));
        let _ = read_csv(&format!("frame,time_s,a_x_mm,a_y_mm,a_z_mm\n{text}"));
    }

    #[test]
    fn tab_soup_never_panics(text in "[0-9\t\n.eE+-naNm#]{0,400}") {
        let _ = read_trc(&format!("PathFileType\nDataRate Units\n{text}"));
        let _ = read_csv(&text.replace('\t', ","));
    }
}

/// The smallest real file, or a generated one when the shared data is absent.
fn sample_trc_text() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/data/trc/Tutorials_Computed_Muscle_Control_InverseKinematics_arm26_elbow_flex.trc");
    std::fs::read_to_string(path).unwrap_or_else(|_| {
        let names = vec![MarkerName::parse("A"), MarkerName::parse("B")];
        let samples: Vec<Option<Vec3>> = (0..40).map(|i| (i % 3 != 0).then(|| Vec3::new(i as f64, 1.0, 2.0))).collect();
        let take = Take::from_samples(names, &samples, 100.0).unwrap();
        let mut out = Vec::new();
        write_trc(&take, LengthUnit::Millimetre, &mut out).unwrap();
        String::from_utf8(out).unwrap()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// A file cut anywhere before its last row is an error, never a shorter take; cut inside
    /// the last row it may read (absent trailing fields mean missing), but never panics.
    #[test]
    fn truncated_real_file_is_an_error(cut in 0.0f64..1.0) {
        let text = sample_trc_text();
        let body = text.trim_end();
        let last_row = body.rfind('\n').unwrap();
        let at = (cut * body.len() as f64) as usize;
        let prefix = body.get(..at).unwrap();
        match read_trc(prefix) {
            Ok(_) => prop_assert!(at > last_row, "cut at {} of {} read without error", at, body.len()),
            Err(Error::Text { line, .. }) => prop_assert!(line >= 1 && line <= prefix.lines().count() + 1),
            Err(other) => prop_assert!(false, "unexpected error {}", other),
        }
    }

    /// Random byte edits of a real file never panic, and errors point inside the file.
    #[test]
    fn mutated_real_file_never_panics(edits in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 1..8)) {
        let mut bytes = sample_trc_text().into_bytes();
        for (pos, byte) in edits {
            let i = ((pos * bytes.len() as f64) as usize).min(bytes.len().saturating_sub(1));
            if let Some(b) = bytes.get_mut(i) {
                *b = byte;
            }
        }
        let text = String::from_utf8_lossy(&bytes);
        if let Err(Error::Text { line, .. }) = read_trc(&text) {
            prop_assert!(line <= text.split('\n').count());
        }
    }
}

#[test]
fn csv_cut_inside_a_row_is_an_error() {
    let take = read_trc(&sample_trc_text()).unwrap();
    let mut out = Vec::new();
    write_csv(&take, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let cut = text.get(..text.len() - 10).unwrap();
    match read_csv(cut) {
        Err(Error::Text { line, .. }) => assert_eq!(line, cut.lines().count()),
        other => panic!("expected a line error, got {other:?}"),
    }
}
