//! The C3D reader on every real file under `../shared/data`.
//!
//! Like png's `check_testimages`, the expected outcome of every file is listed: files that
//! must fail are named with the reason, every other file must read and convert to a take.

mod common;

use locap_io::c3d::{self, Processor, Storage};

/// Files that cannot be read, and why.
const EXPECTED_FAILURES: &[(&str, &str)] = &[("btk/Empty.c3d", "0 bytes: no header at all")];

#[test]
fn every_shared_c3d_file_reads_or_fails_as_expected() {
    let Some(data) = common::shared_data() else { return };
    let files = common::files_with_extension(&data, "c3d");
    assert!(files.len() >= 140, "expected the shared C3D files, found {}", files.len());
    for path in &files {
        let expected_failure = EXPECTED_FAILURES.iter().find(|(name, _)| path.ends_with(name));
        match (c3d::read_path(path), expected_failure) {
            (Ok(file), None) => {
                let take = file.to_take().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                assert_eq!(take.frame_count(), file.frames);
                assert_eq!(take.marker_count(), file.point_count);
                assert!(take.frame_rate_hz() > 0.0);
            }
            (Err(e), Some(_)) => {
                let text = e.to_string();
                assert!(text.contains(&path.display().to_string()), "error must name the file: {text}");
                assert!(text.contains("byte"), "error must give the offset: {text}");
            }
            (Ok(_), Some((_, why))) => panic!("{} should fail ({why})", path.display()),
            (Err(e), None) => panic!("{e}"),
        }
    }
}

/// c3d.org sample 01 and 02 store one take as Intel, DEC and MIPS files, each as integers and
/// floats: all six must give the same markers, frames and positions (within the integer
/// scale), which checks the VAX float and big-endian decoding against the Intel one.
#[test]
fn processor_variants_of_one_take_agree() {
    let Some(data) = common::shared_data() else { return };
    for (dir, names) in [
        ("c3d-conformance/sample_01", ["Eb015pi", "Eb015pr", "Eb015vi", "Eb015vr", "Eb015si", "Eb015sr"]),
        ("c3d-conformance/sample_02", ["pc_int", "pc_real", "dec_int", "dec_real", "sgi_int", "sgi_real"]),
    ] {
        let read = |name: &str| c3d::read_path(&data.join(dir).join(format!("{name}.c3d"))).unwrap();
        let reference = read(names[1]);
        assert_eq!((reference.processor, reference.storage), (Processor::Intel, Storage::Float));
        let expected = reference.to_take().unwrap();
        let mut processors = Vec::new();
        for name in names {
            let file = read(name);
            processors.push((file.processor, file.storage));
            let take = file.to_take().unwrap();
            assert_eq!(take.markers(), expected.markers(), "{name}");
            assert_eq!(take.frame_count(), expected.frame_count(), "{name}");
            assert_eq!(take.frame_rate_hz(), expected.frame_rate_hz(), "{name}");
            let tolerance = if file.storage == Storage::Int { file.point_scale() as f64 } else { 1e-3 };
            let mut compared = 0;
            for f in 0..take.frame_count() {
                for m in 0..take.marker_count() {
                    match (take.position_mm(f, m), expected.position_mm(f, m)) {
                        (Some(a), Some(b)) => {
                            assert!((a - b).amax() <= tolerance, "{name} frame {f} marker {m}: {a:?} vs {b:?}");
                            compared += 1;
                        }
                        (None, None) => {}
                        (a, b) => panic!("{name} frame {f} marker {m}: {a:?} vs {b:?}"),
                    }
                }
            }
            assert!(compared > 1000, "{name}: only {compared} samples compared");
        }
        for p in [Processor::Intel, Processor::Dec, Processor::Mips] {
            assert!(processors.iter().any(|(q, _)| *q == p), "{dir}: no {p:?} file");
        }
    }
}

/// CMU writes missing samples as all-zero coordinates with a non-negative residual; they must
/// be missing, not points at the origin. 01_01's RBAC marker is lost for its last 30 frames.
#[test]
fn zero_coordinates_are_missing() {
    let Some(data) = common::shared_data() else { return };
    let take = c3d::read_path(&data.join("cmu-c3d/01_01.c3d")).unwrap().to_take().unwrap();
    let rbac = take.marker_index("RBAC").unwrap();
    let last = take.frame_count() - 1;
    assert_eq!(take.position_mm(last, rbac), None);
    assert!(take.position_mm(0, rbac).is_some());
    let stats = locap_core::GapStatistics::of_take(&take);
    assert_eq!(stats.markers[rbac].missing_frames, 30);
    assert_eq!(stats.markers[rbac].longest_gap, 30);
    // Subject prefixes are split off but kept.
    let take = c3d::read_path(&data.join("cmu-c3d/02_01.c3d")).unwrap().to_take().unwrap();
    assert_eq!(take.markers()[0].subject.as_deref(), Some("TakeoMonday"));
    assert!(take.marker_index("LFWT").is_some());
}

/// More than 255 labels live in `POINT:LABELS2`; relabeling and writing keeps them apart.
#[test]
fn labels_beyond_255_round_trip() {
    let names: Vec<_> = (0..300).map(|i| locap_core::MarkerName::parse(&format!("Sub:M{i}"))).collect();
    let mut take = locap_core::Take::empty(names, 3, 100.0).unwrap();
    take.set_position_mm(1, 299, Some(locap_core::Vec3::new(1.0, 2.0, 3.0))).unwrap();
    let file = c3d::C3dFile::from_take(&take).unwrap();
    assert_eq!(file.parameters.get("POINT", "LABELS").unwrap().strings().len(), 255);
    assert_eq!(file.parameters.get("POINT", "LABELS2").unwrap().strings().len(), 45);
    let mut bytes = Vec::new();
    c3d::write(&file, &mut bytes).unwrap();
    let back = c3d::read(&bytes).unwrap().to_take().unwrap();
    assert_eq!(back.markers(), take.markers());
    assert_eq!(back.position_mm(1, 299), take.position_mm(1, 299));
    assert_eq!(back.missing_count(), take.missing_count());
}

/// Broken input gives an error with the section and byte offset, never a panic.
#[test]
fn broken_files_give_located_errors() {
    let Some(data) = common::shared_data() else { return };
    let bytes = std::fs::read(data.join("cmu-c3d/02_01.c3d")).unwrap();
    for cut in [0, 100, 511, 512, 600, 1024, 2000] {
        if let Err(e) = c3d::read(&bytes[..cut.min(bytes.len())]) {
            let text = e.to_string();
            assert!(text.contains("byte"), "{text}");
        }
    }
    let strict = c3d::ReadOptions { strict: true, ..Default::default() };
    let err = c3d::read_with(&bytes[..bytes.len() - 1000], strict).unwrap_err().to_string();
    assert!(err.contains("data section") && err.contains("truncated"), "{err}");
    // Lenient by default: the complete frames are read, with a warning.
    let file = c3d::read(&bytes[..bytes.len() - 1000]).unwrap();
    assert!(file.frames < 343 && file.frames > 300);
    assert!(file.warnings.iter().any(|w| w.contains("truncated")));
    let mut bad = bytes.clone();
    bad[1] = 0;
    assert!(c3d::read(&bad).unwrap_err().to_string().contains("0x50"));
}
