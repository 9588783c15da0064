//! Long takes and long LOCAP range lists, written by locap and read back by locap and by the
//! reference reader ezc3d (`ezc3d_read_back.py`, PyPI ezc3d 1.7.2 from `.ci/pydeps`).
//!
//! - A 41-marker x 500,000-frame take (69 minutes at 120 Hz, 328 MB of float data: ten times
//!   the ~33.5 MB at which writing used to fail) is written from a `Take` (what `convert`
//!   does for TRC/CSV input), converted C3D to C3D (`read_path` -> `write_path`, what
//!   `convert a.c3d b.c3d` does) and read back equal.
//! - 20,000 filled ranges in `LOCAP:FILLED` (compact form, `locap_core::range_list`) fit the
//!   255-block parameter section every reader reads, and decode from what ezc3d read to the
//!   lines locap stored.
//! - A parameter section past 255 blocks (the one-byte block count) is written, and locap and
//!   ezc3d read all of it.
//!
//! Without ezc3d the ezc3d halves are skipped with a message, but fail under CI.

mod common;

use locap_core::range_list;
use locap_core::{MarkerName, Take, Vec3};
use locap_io::c3d::{self, C3dFile};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// What ezc3d reads from `path` (see `ezc3d_read_back.py`).
fn ezc3d_read(path: &Path, frame_step: usize, parameters: &[&str]) -> Value {
    let output = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ezc3d_read_back.py"))
        .arg(path)
        .arg(frame_step.to_string())
        .args(parameters)
        .env("PYTHONPATH", common::pydeps())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "ezc3d could not read {} ({}):\n{}",
        path.display(),
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    serde_json::from_slice(&output.stdout).unwrap()
}

fn names(n: usize) -> Vec<MarkerName> {
    (0..n).map(|m| MarkerName::parse(&format!("Sub:M{m:02}"))).collect()
}

/// Marker `m` at frame `f`: coordinates are multiples of 1/4 below 2^14, exact in f32 and
/// summed exactly in f64 in any order; about one sample in 97 is missing.
fn sample(f: usize, m: usize) -> Option<Vec3> {
    if (f * 41 + m).is_multiple_of(97) {
        return None;
    }
    let (f, m) = (f as f64, m as f64);
    Some(Vec3::new(m * 100.0 + (f % 1000.0) * 0.25, m * 50.0 - (f % 777.0) * 0.5, 1000.0 + f % 333.0))
}

const MARKERS: usize = 41;
const LONG: usize = 500_000;

fn long_take() -> Take {
    let mut take = Take::empty(names(MARKERS), LONG, 120.0).unwrap();
    for f in 0..LONG {
        for m in 0..MARKERS {
            take.set_position_mm(f, m, sample(f, m)).unwrap();
        }
    }
    // Frame numbers past 65535 from the start: the header's 16-bit words cannot hold them.
    take.first_frame = 101;
    take
}

/// Checks what ezc3d read against [`sample`]: shape, missing count, exact sum, sampled frames.
fn check_ezc3d_points(read: &Value, frames: usize, step: usize) {
    let shape: Vec<u64> = read["shape"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap()).collect();
    assert_eq!(shape, [4, MARKERS as u64, frames as u64], "ezc3d's point array");
    let (mut missing, mut sum) = (0u64, 0f64);
    for f in 0..frames {
        for m in 0..MARKERS {
            match sample(f, m) {
                Some(p) => sum += p.x + p.y + p.z,
                None => missing += 1,
            }
        }
    }
    assert_eq!(read["missing"].as_u64(), Some(missing));
    assert_eq!(read["sum"].as_f64(), Some(sum));
    let picked: Vec<usize> = (0..frames).step_by(step).chain([frames - 1]).collect();
    for f in picked {
        let got = &read["frames"][f.to_string()];
        for m in 0..MARKERS {
            let want = sample(f, m).map(|p| vec![p.x, p.y, p.z]);
            let have: Option<Vec<f64>> =
                got[m].as_array().unwrap().iter().map(|v| v.as_f64()).collect::<Option<Vec<f64>>>();
            assert_eq!(have, want, "ezc3d frame {f} marker {m}");
        }
    }
    let labels: Vec<&str> = read["labels"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert_eq!(labels, names(MARKERS).iter().map(|n| n.full()).collect::<Vec<_>>());
}

#[test]
fn a_500000_frame_take_converts_and_reads_back_equal_in_locap_and_ezc3d() {
    let dir = tempfile::tempdir().unwrap();
    let (first, second) = (dir.path().join("long.c3d"), dir.path().join("converted.c3d"));
    {
        let take = long_take();
        c3d::write_path(&C3dFile::from_take(&take).unwrap(), &first).unwrap();
        // `locap convert long.c3d converted.c3d`.
        let file = c3d::read_path(&first).unwrap();
        assert_eq!(file.frames, LONG);
        c3d::write_path(&file, &second).unwrap();
        let back = c3d::read_path(&second).unwrap();
        assert_eq!((back.frames, back.first_frame()), (LONG, 101));
        let read = back.to_take().unwrap();
        assert_eq!(read.markers(), take.markers());
        assert_eq!(read.validity(), take.validity());
        for f in (0..LONG).step_by(4999).chain([LONG - 1]) {
            for m in 0..MARKERS {
                assert_eq!(read.position_mm(f, m), take.position_mm(f, m), "frame {f} marker {m}");
            }
        }
        // The bookkeeping readers of long takes look for.
        let p = &back.parameters;
        assert_eq!(p.get("TRIAL", "ACTUAL_START_FIELD").unwrap().floats(), [101.0, 0.0]);
        let end = 101 + LONG as u32 - 1;
        // Two 16-bit words, low first, stored as int16.
        let words = [(end & 0xffff) as u16 as i16 as f64, (end >> 16) as f64];
        assert_eq!(p.get("TRIAL", "ACTUAL_END_FIELD").unwrap().floats(), words);
        assert_eq!(p.get("POINT", "LONG_FRAMES").unwrap().floats(), [LONG as f64]);
        assert_eq!(p.get("POINT", "FRAMES").unwrap().floats(), [-1.0], "65535 as int16, as ezc3d writes it");
        assert_eq!((back.header.first_frame, back.header.last_frame), (1, 65535));
    }
    if !common::python_has("ezc3d, numpy") {
        return;
    }
    let read = ezc3d_read(&second, 4999, &[]);
    check_ezc3d_points(&read, LONG, 4999);
    // ezc3d read the 65535 header frames as "to the end of the file" and counted them.
    assert_eq!(read["point_frames"][0].as_u64(), Some(LONG as u64));
}

/// `n` filled ranges over `markers` markers, as `locap clean` lists them: per marker, runs of
/// 1 to 30 frames with gaps of 10 to 1,000 frames between them.
fn filled_lines(n: usize, markers: usize) -> Vec<String> {
    let per_marker = n.div_ceil(markers);
    let mut lines = Vec::with_capacity(n);
    'markers: for m in 0..markers {
        let mut frame = 1 + (m * 37) % 400;
        for k in 0..per_marker {
            if lines.len() == n {
                break 'markers;
            }
            let len = 1 + (k * 7 + m) % 30;
            lines.push(format!("Sub:M{m:02} {frame}-{}", frame + len - 1));
            frame += len + 10 + (k * 131 + m * 17) % 991;
        }
    }
    lines
}

fn parameter_blocks(path: &Path) -> u8 {
    let bytes = std::fs::read(path).unwrap();
    bytes[(bytes[0] as usize - 1) * 512 + 2]
}

#[test]
fn twenty_thousand_filled_ranges_fit_and_read_back_in_locap_and_ezc3d() {
    let lines = filled_lines(20_000, MARKERS);
    let frames = 260_000;
    assert!(lines.iter().all(|l| l.rsplit('-').next().unwrap().parse::<usize>().unwrap() <= frames));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cleaned.c3d");
    let mut take = Take::empty(names(MARKERS), frames, 120.0).unwrap();
    for f in 0..frames {
        for m in 0..MARKERS {
            take.set_position_mm(f, m, sample(f, m)).unwrap();
        }
    }
    let mut file = C3dFile::from_take(&take).unwrap();
    // What `locap clean` stores (crates/cli/src/cmd/clean.rs, `set_ranges`).
    let stored = range_list::encode(&lines).unwrap();
    file.parameters.set_continued_strings("LOCAP", "FILLED", &stored);
    c3d::write_path(&file, &path).unwrap();
    // Every reader reads the whole section: its block count fits the one byte.
    let blocks = parameter_blocks(&path);
    assert!(blocks < 255, "{blocks} parameter blocks for 20,000 ranges");
    let back = c3d::read_path(&path).unwrap();
    assert_eq!(back.frames, frames);
    let strings = back.parameters.continued_strings("LOCAP", "FILLED");
    assert_eq!(range_list::decode(&strings).unwrap(), lines);
    if !common::python_has("ezc3d, numpy") {
        return;
    }
    let read = ezc3d_read(&path, 9973, &["LOCAP:FILLED"]);
    check_ezc3d_points(&read, frames, 9973);
    let from_ezc3d: Vec<String> =
        read["strings"]["LOCAP:FILLED"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    assert_eq!(range_list::decode(&from_ezc3d).unwrap(), lines, "the lines, decoded from what ezc3d read");
}

#[test]
fn a_parameter_section_past_255_blocks_is_written_and_read_whole() {
    // 60,000 ranges in the plain form, one string each (~1 MB of parameters, ~2,000 blocks):
    // what older locap versions stored, and what a list too long even for the compact form
    // looks like.
    let lines = filled_lines(60_000, MARKERS);
    let frames = 1000;
    let take = Take::from_samples(
        names(MARKERS),
        &(0..frames * MARKERS).map(|i| sample(i / MARKERS, i % MARKERS)).collect::<Vec<_>>(),
        120.0,
    )
    .unwrap();
    let mut file = C3dFile::from_take(&take).unwrap();
    file.parameters.set_continued_strings("LOCAP", "FILLED", &lines);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.c3d");
    c3d::write_path(&file, &path).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let data_start = u16::from_le_bytes([bytes[16], bytes[17]]) as usize;
    assert!(data_start > 2 + 255, "data starts at block {data_start}");
    assert_eq!(parameter_blocks(&path), 255, "the one-byte count saturates");
    let back = c3d::read_path(&path).unwrap();
    assert_eq!(back.parameters.continued_strings("LOCAP", "FILLED"), lines);
    assert_eq!(back.to_take().unwrap().validity(), take.validity());
    if !common::python_has("ezc3d, numpy") {
        return;
    }
    let read = ezc3d_read(&path, 97, &["LOCAP:FILLED"]);
    check_ezc3d_points(&read, frames, 97);
    let from_ezc3d: Vec<&str> =
        read["strings"]["LOCAP:FILLED"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    assert_eq!(from_ezc3d, lines);
}
