//! Regression inputs found by the fuzz targets (`fuzz/`): each file under
//! `tests/data/bugfixes/` once made the C3D reader or writer panic. Reading must now give a
//! file or an error, and a file that reads must go through `to_take`, `set_take`, `write` and
//! a re-read.

use locap_io::c3d;
use std::path::Path;

fn check(bytes: &[u8]) {
    let Ok(file) = c3d::read(bytes) else { return };
    let _ = file.analog_info();
    let Ok(take) = file.to_take() else { return };
    if file.point_count == 0 || file.frames == 0 {
        return;
    }
    let mut edited = file.clone();
    edited.set_take(&take).expect("set_take");
    let mut out = Vec::new();
    c3d::write(&edited, &mut out).expect("write");
    let again = c3d::read(&out).expect("re-read");
    assert_eq!(again.to_take().expect("to_take").validity(), take.validity());
}

#[test]
fn fuzzer_found_c3d_inputs_do_not_panic() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bugfixes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "c3d") {
            check(&std::fs::read(&path).unwrap());
            n += 1;
        }
    }
    assert!(n > 0, "no regression inputs in {}", dir.display());
}

/// A parameter of 10 dimensions of 255: their product overflowed `usize` (the fuzzer's
/// minimised input, `c3d_param_dims_overflow.c3d`, also has a bad data type, which is now
/// checked first, so the overflow is rebuilt here by hand).
#[test]
fn param_dims_overflow_is_an_error() {
    let mut bytes = vec![0u8; 1024];
    bytes[..2].copy_from_slice(&[2, 0x50]);
    let mut params = vec![1, 0x50, 1, 84];
    // Group POINT (id -1), offset 3 to the next record, empty description.
    params.extend([5, 0xff]);
    params.extend(b"POINT");
    params.extend([3, 0, 0]);
    // Parameter POINT:USED, not the last record (offset 16), bytes, dimensions 255^10.
    params.extend([4, 1]);
    params.extend(b"USED");
    params.extend([16, 0, 1, 10]);
    params.extend([255; 10]);
    bytes[512..512 + params.len()].copy_from_slice(&params);
    let err = c3d::read(&bytes).unwrap_err().to_string();
    assert!(err.contains("too many values"), "{err}");
}

/// No points, no analog samples, and `TRIAL:ACTUAL_END_FIELD` saying billions of frames: the
/// reader looped over every empty frame (a fuzzer timeout), and then reported them all, so
/// every stage after it did. Empty frames are now bounded by the bytes after the data start
/// (see `locap_io::limits`), which is what this checks instead of the time taken.
#[test]
fn empty_frames_do_not_hang() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bugfixes/c3d_empty_frames_hang.c3d");
    let bytes = std::fs::read(path).unwrap();
    if let Ok(file) = &c3d::read(&bytes) {
        assert!(file.points.is_empty() && file.analog.is_empty());
        assert!(file.frames <= bytes.len(), "{} empty frames from {} bytes", file.frames, bytes.len());
        let mut out = Vec::new();
        c3d::write(file, &mut out).unwrap();
    }
}

/// `ANALOG:USED` stored as a float of 6.6e8: `analog_info` sized its label vectors from it
/// (a fuzzer out-of-memory). The channel count is now capped at 65535.
#[test]
fn huge_analog_used_does_not_allocate_gigabytes() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bugfixes/c3d_huge_analog_used.c3d");
    let file = c3d::read(&std::fs::read(path).unwrap()).unwrap();
    let info = file.analog_info();
    assert!(info.labels.len() <= 65535 && info.units.len() <= 65535);
}

/// A parameter whose name is all blanks read as `""`, which the writer rejects: the round
/// trip failed. Such records are now skipped with a warning.
#[test]
fn blank_parameter_names_are_skipped() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bugfixes/c3d_empty_param_name.c3d");
    let file = c3d::read(&std::fs::read(path).unwrap()).unwrap();
    assert!(file.warnings.iter().any(|w| w.contains("not 1-127 bytes")), "{:?}", file.warnings);
    c3d::write(&file, &mut Vec::new()).unwrap();
}
