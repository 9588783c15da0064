//! Issue 14, "Never lose a take": readers that never hang, abort or over-allocate.
//!
//! Each case of the issue has a regression test here: the 1 KB C3D claiming 4.29 billion
//! frames with no data, a BVH nested 100,000 deep (and the writer's output on deep trees),
//! a named pipe given as input, NaN / zero / negative frame rates, an empty `POINT:UNITS`,
//! and limits a library user sets. Inputs are built in the test from bytes; the real-data
//! tests at the end check that the default limits and the new warnings fit the shared
//! captures.

mod common;

use locap_core::{LengthUnit, MarkerName, Take, Vec3};
use locap_io::c3d::{self, C3dFile, ParamData, ReadOptions};
use locap_io::{Error, Limits, asf_amc, bvh, csv, trc};
use proptest::prelude::*;
use std::path::Path;

// ---------------------------------------------------------------------------------------
// C3D files built byte by byte (C3D User Guide: header block, parameter section, data).

/// A parameter record: name length, id (negative for a group), name, offset to the next
/// record, payload.
fn record(out: &mut Vec<u8>, name: &str, id: i8, payload: &[u8]) {
    out.push(name.len() as u8);
    out.push(id as u8);
    out.extend_from_slice(name.as_bytes());
    out.extend_from_slice(&(2 + payload.len() as i16).to_le_bytes());
    out.extend_from_slice(payload);
}

/// An `i16` array parameter payload.
fn int_payload(values: &[i16]) -> Vec<u8> {
    let mut p = vec![2, 1, values.len() as u8];
    for v in values {
        p.extend_from_slice(&v.to_le_bytes());
    }
    p.push(0); // no description
    p
}

/// A 1 KB Intel C3D file with no points and no analog channels: a header saying
/// `header_frames` frames (first frame 1), a parameter block with `TRIAL:ACTUAL_*_FIELD`
/// (frames 1 to `trial_end`, when given), the data section starting at byte 1024, followed by
/// `data_bytes` zero bytes.
fn empty_frames_c3d(header_frames: u16, trial_end: Option<u32>, data_bytes: usize) -> Vec<u8> {
    let mut b = vec![0u8; 1024];
    b[0] = 2;
    b[1] = 0x50;
    let mut word = |n: usize, v: u16| b[2 * (n - 1)..2 * n].copy_from_slice(&v.to_le_bytes());
    word(4, 1);
    word(5, header_frames);
    word(9, 3);
    b[12..16].copy_from_slice(&(-1.0f32).to_le_bytes());
    b[20..24].copy_from_slice(&100.0f32.to_le_bytes());
    b[512..516].copy_from_slice(&[1, 0x50, 1, 84]);
    let mut params = Vec::new();
    record(&mut params, "TRIAL", -1, &[0]);
    if let Some(end) = trial_end {
        record(&mut params, "ACTUAL_START_FIELD", 1, &int_payload(&[1, 0]));
        record(&mut params, "ACTUAL_END_FIELD", 1, &int_payload(&[end as u16 as i16, (end >> 16) as u16 as i16]));
    }
    b[516..516 + params.len()].copy_from_slice(&params);
    b.resize(1024 + data_bytes, 0);
    b
}

#[test]
fn c3d_claiming_4e9_frames_with_no_data_reads_as_no_frames() {
    // TRIAL:ACTUAL_END_FIELD says frame 4,294,967,295; the header says none.
    let bytes = empty_frames_c3d(0, Some(u32::MAX), 0);
    assert_eq!(bytes.len(), 1024);
    let file = c3d::read(&bytes).unwrap();
    assert_eq!((file.point_count, file.frames), (0, 0));
    let take = file.to_take().unwrap();
    assert_eq!(take.frame_count(), 0);
    // What `convert` writes stays small (it wrote gigabytes of empty frames).
    let mut out = Vec::new();
    c3d::write(&file, &mut out).unwrap();
    assert!(out.len() <= 4096, "{} bytes written", out.len());
    let mut text = Vec::new();
    trc::write_trc(&take, LengthUnit::Millimetre, &mut text).unwrap();
    assert!(text.len() < 1024, "{} bytes of TRC", text.len());
}

#[test]
fn c3d_empty_frames_are_bounded_by_the_bytes_after_the_data_start() {
    // The header's 65535 frames, with nothing after the data start: none are read, with a
    // warning; strict reading refuses the file.
    let bytes = empty_frames_c3d(u16::MAX, None, 0);
    let file = c3d::read(&bytes).unwrap();
    assert_eq!(file.frames, 0);
    assert!(file.warnings.iter().any(|w| w.contains("nothing in the file backs them")), "{:?}", file.warnings);
    let strict = ReadOptions { strict: true, ..ReadOptions::default() };
    assert!(matches!(c3d::read_with(&bytes, strict), Err(Error::Limit(_))));
    // With 512 bytes after the data start (and TRIAL claiming 4.29e9): at most 512 frames.
    let file = c3d::read(&empty_frames_c3d(u16::MAX, Some(u32::MAX), 512)).unwrap();
    assert_eq!(file.frames, 512);
    assert_eq!(file.to_take().unwrap().frame_count(), 512);
}

// ---------------------------------------------------------------------------------------
// C3D files from a take, then edited.

fn small_take(frames: usize, markers: usize) -> Take {
    let names = (0..markers).map(|m| MarkerName::parse(&format!("M{m}"))).collect();
    let samples: Vec<Option<Vec3>> =
        (0..frames * markers).map(|i| Some(Vec3::new(i as f64, 1.0, 2.0 + i as f64 * 0.5))).collect();
    match markers {
        0 => Take::empty(names, frames, 100.0).unwrap(),
        _ => Take::from_samples(names, &samples, 100.0).unwrap(),
    }
}

fn c3d_bytes(file: &C3dFile) -> Vec<u8> {
    let mut out = Vec::new();
    c3d::write(file, &mut out).unwrap();
    out
}

/// A file whose `POINT:RATE` is `point_rate` and whose header rate is `header_rate`.
fn with_rates(point_rate: f32, header_rate: f32) -> C3dFile {
    let mut file = C3dFile::from_take(&small_take(3, 2)).unwrap();
    file.parameters.set("POINT", "RATE", vec![], ParamData::Float(vec![point_rate]));
    file.header.frame_rate_hz = header_rate;
    c3d::read(&c3d_bytes(&file)).unwrap()
}

#[test]
fn c3d_without_a_valid_rate_reads_but_gives_no_take() {
    for (point, header) in [(f32::NAN, 0.0), (0.0, 0.0), (-120.0, -1.0), (f32::INFINITY, f32::NAN)] {
        let file = with_rates(point, header);
        assert!(file.warnings.iter().any(|w| w.contains("no frame rate")), "{point}/{header}: {:?}", file.warnings);
        let err = file.to_take().unwrap_err().to_string();
        assert!(err.contains("no frame rate"), "{point}/{header}: {err}");
    }
    // A bad POINT:RATE with a good header rate: the header's rate, and a warning.
    let file = with_rates(-5.0, 240.0);
    assert!(file.warnings.iter().any(|w| w.contains("POINT:RATE is -5")), "{:?}", file.warnings);
    assert_eq!(file.to_take().unwrap().frame_rate_hz(), 240.0);
    let file = with_rates(120.0, 0.0);
    assert!(!file.warnings.iter().any(|w| w.contains("RATE") || w.contains("rate")), "{:?}", file.warnings);
    assert_eq!(file.to_take().unwrap().frame_rate_hz(), 120.0);
}

#[test]
fn text_formats_refuse_nan_zero_and_negative_rates() {
    let trc = |rate: &str| {
        format!(
            "PathFileType\t4\nDataRate\tUnits\n{rate}\tmm\nFrame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n\n1\t0\t1\t2\t3\n2\t0.01\t1\t2\t3\n"
        )
    };
    assert!(trc::read_trc(&trc("100")).is_ok());
    for bad in ["NaN", "0", "-100", "inf"] {
        match trc::read_trc(&trc(bad)) {
            Err(Error::Text { line: 3, message, .. }) => assert!(message.contains("DataRate"), "{message}"),
            other => panic!("DataRate {bad}: {other:?}"),
        }
    }
    let bvh = |time: &str| {
        format!(
            "HIERARCHY\nROOT A\n{{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n}}\nMOTION\nFrames: 1\nFrame Time: {time}\n1 2 3\n"
        )
    };
    assert!(bvh::read_bvh(&bvh("0.01"), LengthUnit::Millimetre).is_ok());
    for bad in ["NaN", "0", "-0.01", "inf"] {
        match bvh::read_bvh(&bvh(bad), LengthUnit::Millimetre) {
            Err(Error::Text { line: 9, .. }) => {}
            other => panic!("Frame Time {bad}: {other:?}"),
        }
    }
    let asf = asf_amc::read_asf(&chain_asf(1)).unwrap();
    let amc = "1\nroot 0 0 0 0 0 0\nb0 10\n";
    assert!(asf_amc::read_amc(amc, &asf, 120.0).is_ok());
    for bad in [f64::NAN, 0.0, -120.0, f64::INFINITY] {
        let err = asf_amc::read_amc(amc, &asf, bad).unwrap_err();
        assert!(matches!(err, Error::Skeleton(_)), "rate {bad}: {err:?}");
    }
}

#[test]
fn empty_or_absent_point_units_is_a_warning() {
    let units_warning = |file: &C3dFile| file.warnings.iter().find(|w| w.contains("POINT:UNITS")).cloned();
    let mut file = C3dFile::from_take(&small_take(2, 1)).unwrap();
    assert_eq!(units_warning(&c3d::read(&c3d_bytes(&file)).unwrap()), None, "mm is a unit");
    file.parameters.set_strings("POINT", "UNITS", &[String::new()]);
    let read = c3d::read(&c3d_bytes(&file)).unwrap();
    let warning = units_warning(&read).expect("a warning for an empty POINT:UNITS");
    assert!(warning.contains("empty") && warning.contains("millimetres"), "{warning}");
    assert_eq!(read.to_take().unwrap().position_mm(1, 0), Some(Vec3::new(1.0, 1.0, 2.5)), "still read as mm");
    file.parameters.set_strings("POINT", "UNITS", &["furlong".to_string()]);
    assert!(units_warning(&c3d::read(&c3d_bytes(&file)).unwrap()).unwrap().contains("\"furlong\""));
    file.parameters.remove("POINT", "UNITS");
    assert!(units_warning(&c3d::read(&c3d_bytes(&file)).unwrap()).unwrap().contains("absent"));
}

// ---------------------------------------------------------------------------------------
// Deep hierarchies.

/// A BVH chain of `joints` joints, each nested in the previous one, with one frame.
fn chain_bvh(joints: usize) -> String {
    let mut s = String::from(
        "HIERARCHY\nROOT J0\n{\nOFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n",
    );
    for i in 1..joints {
        s.push_str(&format!("JOINT J{i}\n{{\nOFFSET 0 1 0\nCHANNELS 3 Zrotation Xrotation Yrotation\n"));
    }
    s.push_str("End Site\n{\nOFFSET 0 1 0\n}\n");
    s.push_str(&"}\n".repeat(joints));
    s.push_str("MOTION\nFrames: 1\nFrame Time: 0.01\n");
    s.push_str(&vec!["0"; 6 + 3 * (joints - 1)].join(" "));
    s.push('\n');
    s
}

#[test]
fn bvh_nested_100000_deep_is_a_clear_error() {
    let text = chain_bvh(100_000);
    let err = bvh::read_bvh(&text, LengthUnit::Centimetre).unwrap_err();
    assert!(matches!(err, Error::Limit(_)), "{err:?}");
    let message = err.to_string();
    // J257 is the first joint deeper than 256, declared on line 6 + 4 * 256.
    assert!(message.contains("deeper than 256 levels") && message.contains("line 1030"), "{message}");
}

#[test]
fn bvh_writer_output_is_linear_in_depth() {
    let written = |joints: usize| {
        let limits = Limits { max_depth: joints, max_joints: joints + 1, ..Limits::default() };
        let motion = bvh::read_bvh_with(&chain_bvh(joints), LengthUnit::Centimetre, &limits).unwrap();
        let mut out = Vec::new();
        bvh::write_bvh(&motion, LengthUnit::Centimetre, &mut out).unwrap();
        let back = bvh::read_bvh_with(std::str::from_utf8(&out).unwrap(), LengthUnit::Centimetre, &limits).unwrap();
        assert_eq!(back.skeleton.len(), motion.skeleton.len());
        out.len()
    };
    // Indented per depth, 10,000 joints took ~250 MB (quadratic); with the indentation
    // bounded, twice the joints take twice the bytes (plus the fixed header).
    let (small, large) = (written(5_000), written(10_000));
    assert!(large < 300 * 10_000, "{large} bytes for 10,000 joints");
    assert!((large as f64) < 2.05 * small as f64, "{small} bytes for 5,000 joints, {large} for 10,000");
}

#[test]
fn bvh_joint_and_sample_limits() {
    let text = chain_bvh(5);
    let tight = Limits { max_joints: 4, ..Limits::default() };
    assert!(matches!(bvh::read_bvh_with(&text, LengthUnit::Millimetre, &tight), Err(Error::Limit(_))));
    let tight = Limits { max_samples: 5, ..Limits::default() };
    let err = bvh::read_bvh_with(&text, LengthUnit::Millimetre, &tight).unwrap_err().to_string();
    assert!(err.contains("1 frames x 6 joints"), "{err}");
    assert!(bvh::read_bvh_with(&text, LengthUnit::Millimetre, &Limits { max_samples: 6, ..tight }).is_ok());
    // 2,000 joints without channels and 2,000 one-value motion lines: 4 million rotations
    // from 60 KB, which no byte of the file backs.
    let mut s = String::from("HIERARCHY\nROOT R\n{\nOFFSET 0 0 0\nCHANNELS 1 Xposition\n");
    for i in 0..2000 {
        s.push_str(&format!("JOINT J{i}\n{{\nOFFSET 0 0 0\n}}\n"));
    }
    s.push_str("}\nMOTION\nFrames: 2000\nFrame Time: 0.01\n");
    s.push_str(&"1\n".repeat(2000));
    let err = bvh::read_bvh(&s, LengthUnit::Millimetre).unwrap_err().to_string();
    assert!(err.contains("at least one byte per sample"), "{err}");
}

/// An ASF chain `root -> b0 -> b1 -> ...` of `bones` bones with one rotational dof each.
fn chain_asf(bones: usize) -> String {
    let mut s =
        String::from(":units\n  length 1\n  angle deg\n:root\n  order TX TY TZ RX RY RZ\n  axis XYZ\n:bonedata\n");
    for i in 0..bones {
        s.push_str(&format!("begin\nname b{i}\ndirection 0 1 0\nlength 1\naxis 0 0 0 XYZ\ndof rx\nend\n"));
    }
    s.push_str(":hierarchy\nbegin\nroot b0\n");
    for i in 1..bones {
        s.push_str(&format!("b{} b{i}\n", i - 1));
    }
    s.push_str("end\n");
    s
}

#[test]
fn asf_depth_and_bone_limits() {
    let text = chain_asf(1000);
    let err = asf_amc::read_asf(&text).unwrap_err();
    assert!(matches!(err, Error::Limit(_)), "{err:?}");
    assert!(err.to_string().contains("deeper than 256 levels"), "{err}");
    let deep = Limits { max_depth: 1000, ..Limits::default() };
    assert_eq!(asf_amc::read_asf_with(&text, &deep).unwrap().bones.len(), 1000);
    let few = Limits { max_joints: 100, ..Limits::default() };
    let err = asf_amc::read_asf_with(&chain_asf(101), &few).unwrap_err().to_string();
    assert!(err.contains("more than 100 joints"), "{err}");
    assert!(asf_amc::read_asf_with(&chain_asf(100), &few).is_ok());
}

#[test]
fn amc_frames_are_limited_and_backed() {
    let asf = asf_amc::read_asf(&chain_asf(3)).unwrap();
    let amc: String = (1..=10).map(|f| format!("{f}\nroot 0 0 0 0 0 0\nb0 1\nb1 2\nb2 3\n")).collect();
    assert_eq!(asf_amc::read_amc(&amc, &asf, 120.0).unwrap().frame_count(), 10);
    let tight = Limits { max_frames: 9, ..Limits::default() };
    let err = asf_amc::read_amc_scaled_with(&amc, &asf, 120.0, 1.0, &tight).unwrap_err().to_string();
    assert!(err.contains("10 frames exceed the limit of 9"), "{err}");
    // Frames that leave every bone out are read at rest: samples no byte backs.
    let asf = asf_amc::read_asf(&chain_asf(200)).unwrap();
    let bare: String = (1..=1000).map(|f| format!("{f}\n")).collect();
    let err = asf_amc::read_amc(&bare, &asf, 120.0).unwrap_err().to_string();
    assert!(err.contains("at least one byte per sample"), "{err}");
}

// ---------------------------------------------------------------------------------------
// Text tables.

#[test]
fn trc_short_rows_cannot_imply_a_huge_take() {
    let mut text = String::from("PathFileType\t4\nDataRate\tUnits\n100\tmm\nFrame#\tTime\tA\t\t\n\t\tX1\tY1\tZ1\n\n");
    text.push_str("1\t0");
    text.push_str(&"\t1\t2\t3".repeat(500));
    text.push('\n');
    for f in 2..=20_000 {
        text.push_str(&format!("{f}\t0\n"));
    }
    let err = trc::read_trc(&text).unwrap_err().to_string();
    assert!(err.contains("20000 frames x 500 markers") && err.contains("at least one byte per sample"), "{err}");
}

#[test]
fn csv_and_trc_obey_user_limits() {
    let take = small_take(30, 3);
    let mut out = Vec::new();
    csv::write_csv(&take, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(csv::read_csv_with(&text, &Limits { max_frames: 30, ..Limits::default() }).is_ok());
    let err = csv::read_csv_with(&text, &Limits { max_frames: 29, ..Limits::default() }).unwrap_err().to_string();
    assert!(err.contains("30 frames exceed the limit of 29"), "{err}");
    let err = csv::read_csv_with(&text, &Limits { max_samples: 89, ..Limits::default() }).unwrap_err().to_string();
    assert!(err.contains("exceed the limit of 89"), "{err}");
    let mut out = Vec::new();
    trc::write_trc(&take, LengthUnit::Millimetre, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(trc::read_trc_file_with(&text, &Limits { max_samples: 90, ..Limits::default() }).is_ok());
    assert!(matches!(
        trc::read_trc_file_with(&text, &Limits { max_samples: 89, ..Limits::default() }),
        Err(Error::Limit(_))
    ));
}

#[test]
fn path_readers_check_the_file_size_and_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("take.c3d");
    std::fs::write(&path, c3d_bytes(&C3dFile::from_take(&small_take(10, 2)).unwrap())).unwrap();
    let size = std::fs::metadata(&path).unwrap().len();
    let small = ReadOptions { limits: Limits { max_file_bytes: size - 1, ..Limits::default() }, strict: false };
    let err = c3d::read_path_with(&path, small).unwrap_err().to_string();
    assert!(err.contains("take.c3d") && err.contains("exceeds the limit"), "{err}");
    let few_frames = ReadOptions { limits: Limits { max_frames: 9, ..Limits::default() }, strict: false };
    let err = c3d::read_path_with(&path, few_frames).unwrap_err().to_string();
    assert!(err.contains("take.c3d") && err.contains("10 frames exceed the limit of 9"), "{err}");
    assert_eq!(c3d::read_path(&path).unwrap().frames, 10);
}

// ---------------------------------------------------------------------------------------
// Things that are not files.

/// Every path reader on `path`, with the error each gives.
fn every_path_reader(path: &Path) -> Vec<(&'static str, Error)> {
    let asf = asf_amc::read_asf(&chain_asf(1)).unwrap();
    let limits = Limits::default();
    vec![
        ("c3d::read_path", c3d::read_path(path).err()),
        ("trc::read_trc_path", trc::read_trc_path(path).err()),
        ("trc::read_trc_file_path_with", trc::read_trc_file_path_with(path, &limits).err()),
        ("csv::read_csv_path", csv::read_csv_path(path).err()),
        ("bvh::read_bvh_path", bvh::read_bvh_path(path, LengthUnit::Centimetre).err()),
        ("asf_amc::read_asf_path", asf_amc::read_asf_path(path).err()),
        ("asf_amc::read_amc_path", asf_amc::read_amc_path(path, &asf, 120.0).err()),
        ("limits::read_file", locap_io::limits::read_file(path, &limits).err()),
    ]
    .into_iter()
    .map(|(name, e)| (name, e.unwrap_or_else(|| panic!("{name} read {}", path.display()))))
    .collect()
}

fn assert_refused(path: &Path, kind: &str) {
    for (reader, err) in every_path_reader(path) {
        let text = err.to_string();
        assert!(text.contains(&path.display().to_string()), "{reader}: error must name the file: {text}");
        match err {
            Error::InFile { error, .. } => match *error {
                Error::NotAFile(k) => assert!(k.contains(kind), "{reader}: {k}"),
                other => panic!("{reader}: {other:?}"),
            },
            other => panic!("{reader}: {other:?}"),
        }
    }
}

/// Opening a named pipe blocks until a writer comes; every reader must refuse it first. (A
/// regression would hang this test rather than fail it.)
#[cfg(unix)]
#[test]
fn named_pipes_are_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.c3d");
    let status = std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo (coreutils) must run");
    assert!(status.success(), "mkfifo failed");
    assert_refused(&fifo, "named pipe");
    // Through a symbolic link too.
    let link = dir.path().join("link.trc");
    std::os::unix::fs::symlink(&fifo, &link).unwrap();
    assert_refused(&link, "named pipe");
}

#[test]
fn directories_and_devices_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    assert_refused(dir.path(), "directory");
    #[cfg(unix)]
    assert_refused(Path::new("/dev/null"), "device");
}

// ---------------------------------------------------------------------------------------
// Properties.

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// A C3D or TRC take reads exactly when it fits the limits, and fails with
    /// [`Error::Limit`] otherwise.
    #[test]
    fn reads_iff_within_limits(
        // From 1: the C3D writer declares one frame for a take of none (header last frame =
        // first frame), a writer bug reported to its owner, not a reading matter.
        frames in 1usize..30,
        markers in 1usize..5,
        max_frames in 0usize..35,
        max_samples in 0usize..120,
    ) {
        let take = small_take(frames, markers);
        let limits = Limits { max_frames, max_samples, ..Limits::default() };
        let fits = frames <= max_frames && frames * markers <= max_samples;
        let bytes = c3d_bytes(&C3dFile::from_take(&take).unwrap());
        let read = c3d::read_with(&bytes, ReadOptions { limits, strict: false });
        prop_assert_eq!(read.is_ok(), fits, "{:?}", read.as_ref().err());
        prop_assert!(read.is_ok() || matches!(read, Err(Error::Limit(_))));
        let mut text = Vec::new();
        trc::write_trc(&take, LengthUnit::Millimetre, &mut text).unwrap();
        let read = trc::read_trc_file_with(std::str::from_utf8(&text).unwrap(), &limits);
        prop_assert_eq!(read.is_ok(), fits, "{:?}", read.as_ref().err());
        prop_assert!(read.is_ok() || matches!(read, Err(Error::Limit(_))));
    }
}

// ---------------------------------------------------------------------------------------
// Real captures.

/// The default limits fit every shared capture: nothing is refused or cut, and the new
/// warnings appear exactly where the files deserve them.
#[test]
fn defaults_fit_the_shared_captures() {
    let Some(data) = common::shared_data() else { return };
    for path in common::files_with_extension(&data, "c3d") {
        let Ok(file) = c3d::read_path(&path) else { continue };
        for w in &file.warnings {
            assert!(!w.contains("backs them") && !w.contains("frame rate"), "{}: {w}", path.display());
        }
    }
    // The labeling set's Vicon files leave POINT:UNITS empty; Vicon.c3d says mm.
    let units = |rel: &str| {
        let file = c3d::read_path(&data.join(rel)).unwrap();
        file.warnings.iter().find(|w| w.contains("POINT:UNITS")).cloned()
    };
    assert!(units("labeling/KneeltoProne01.c3d").is_some_and(|w| w.contains("empty")));
    assert_eq!(units("c3d-vendors/Vicon.c3d"), None);
    for path in common::files_with_extension(&data, "trc") {
        if let Err(e) = trc::read_trc_path(&path) {
            assert!(!matches!(&e, Error::InFile { error, .. } if matches!(**error, Error::Limit(_))), "{e}");
        }
    }
    for path in common::files_with_extension(&data, "bvh") {
        bvh::read_bvh_path(&path, LengthUnit::Inch).unwrap_or_else(|e| panic!("{e}"));
    }
    for subject in ["01", "02", "03"] {
        let dir = data.join("cmu-asfamc").join(subject);
        let asf = asf_amc::read_asf_path(&dir.join(format!("{subject}.asf"))).unwrap();
        for amc in common::files_with_extension(&dir, "amc") {
            asf_amc::read_amc_path(&amc, &asf, 120.0).unwrap_or_else(|e| panic!("{e}"));
        }
    }
}

/// Fuzzer-found BVH inputs under `tests/data/bugfixes/` (`bvh_multibyte_channel.bvh`: a
/// channel name starting with a multi-byte character made the channel parser slice inside
/// it and panic): each must now be a located text error.
#[test]
fn fuzzer_found_bvh_inputs_are_errors() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/bugfixes");
    let files = common::files_with_extension(&dir, "bvh");
    assert!(!files.is_empty(), "no BVH regression inputs in {}", dir.display());
    for path in files {
        match bvh::read_bvh_path(&path, LengthUnit::Centimetre) {
            Err(Error::InFile { error, .. }) if matches!(*error, Error::Text { .. }) => {}
            other => panic!("{}: {other:?}", path.display()),
        }
    }
}
