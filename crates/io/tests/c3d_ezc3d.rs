//! Round trip through the reference reader: every C3D file with frames under `../shared/data`
//! is read by locap and written back; ezc3d (PyPI) must then read the same labels, rate,
//! point values (within the integer scale), analog values and rotation data from locap's file as from the
//! original. `.ci/run` installs ezc3d into `.ci/pydeps`; elsewhere the test is skipped with a
//! message (but fails under CI, so a broken install cannot pass silently).

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Runs `tests/SCRIPT` with the cases as JSON on its standard input; whether it succeeded, and
/// its report (also printed).
fn run_script(script: &str, cases: &[serde_json::Value]) -> (bool, String) {
    let mut child = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join(script))
        .env("PYTHONPATH", common::pydeps())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(serde_json::to_string(cases).unwrap().as_bytes()).unwrap();
    let output = child.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&output.stdout).into_owned();
    eprintln!("{report}{}", String::from_utf8_lossy(&output.stderr));
    (output.status.success(), format!("{report}({})", output.status))
}

/// The Intel file ezc3d should read instead of a MIPS file it cannot read (same take).
fn reference_for(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_str()?;
    let intel = match name {
        "sgi_int.c3d" => "pc_int.c3d",
        "sgi_real.c3d" => "pc_real.c3d",
        "Eb015si.c3d" => "Eb015pi.c3d",
        "Eb015sr.c3d" => "Eb015pr.c3d",
        _ => return None,
    };
    Some(path.with_file_name(intel))
}

/// Files ezc3d 1.7.2 cannot read, or reads wrongly, each checked by hand: for these the test
/// requires that ezc3d reads locap's *output* with the points and frames locap found.
/// - MIPS: `MACsample.c3d` ("MIPS processor type not supported").
/// - "OFFSET parameter is not an INT": `Dance1.c3d`, `golfswing1.c3d` (for `Dance.c3d` and
///   `golfswing.c3d` see [`rejected_as_read`]).
/// - "format is not standard": `bad_parameter_section.c3d` (c3d.org's deliberately corrupt
///   file), `Facial-Sing.c3d`.
/// - `kyowadengyo.c3d`: header 11 points, `POINT:USED` 12. ezc3d trusts `USED` and gets
///   mean frame-to-frame jumps of 3.7 m and analog values outside the 12-bit range; read with
///   the header's 11 points, the mean jump is 0.24 m and analog stays within 0..3018
///   (offset 2047). The header is right.
/// - `phasespace_sample.c3d`: no parameter records at all; ezc3d reads 0 points, locap (like
///   py-c3d) reads the header's 40 points x 701 frames.
fn beyond_reference(path: &Path) -> bool {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    [
        "MACsample.c3d",
        "Dance1.c3d",
        "golfswing1.c3d",
        "bad_parameter_section.c3d",
        "Facial-Sing.c3d",
        "kyowadengyo.c3d",
        "phasespace_sample.c3d",
    ]
    .contains(&name)
}

/// Files whose `ANALOG:OFFSET` is stored as floats, which ezc3d 1.7.2 rejects ("OFFSET
/// parameter is not an INT") and py-c3d cannot reshape: locap carries the parameter as read
/// (a round trip changes nothing beyond the data start), so ezc3d must reject the output for
/// the same reason and nothing else.
fn rejected_as_read(path: &Path) -> bool {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    ["Dance.c3d", "golfswing.c3d"].contains(&name)
}

#[test]
fn ezc3d_reads_what_locap_writes() {
    let Some(data) = common::shared_data() else { return };
    if !common::python_has("ezc3d, numpy") {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let mut cases = Vec::new();
    for (i, path) in common::files_with_extension(&data, "c3d").iter().enumerate() {
        let Ok(file) = locap_io::c3d::read_path(path) else { continue };
        if file.frames == 0 {
            continue;
        }
        // Also exercise the take conversion: to a Take and back, as every locap command does.
        let mut file = file;
        let take = file.to_take().unwrap();
        file.set_take(&take).unwrap();
        let written = out.path().join(format!("{i}.c3d"));
        locap_io::c3d::write_path(&file, &written).unwrap();
        let mut case = serde_json::json!({
            "verbose": std::env::var_os("LOCAP_VERBOSE").is_some(),
            "original": path,
            "written": written,
            "points": file.point_count,
            "frames": file.frames,
        });
        if let Some(reference) = reference_for(path) {
            case["reference"] = serde_json::json!(reference);
        }
        if beyond_reference(path) {
            case["beyond_reference"] = serde_json::json!(true);
        }
        if rejected_as_read(path) {
            case["rejected_as_read"] = serde_json::json!(true);
        }
        // ezc3d rejects this BKIN file as read and as written ("format is not standard"; with
        // ignore_bad_formatting it finds no analog data although the 20 channels fill the data
        // section exactly); py-c3d reads both, and must read the same numbers.
        if path.ends_with("BKINtechnologies.c3d") {
            case["pyc3d_only"] = serde_json::json!(true);
        }
        cases.push(case);
    }
    assert!(cases.len() > 100, "expected the shared C3D files, found {}", cases.len());
    let (ok, report) = run_script("ezc3d_compare.py", &cases);
    assert!(ok, "ezc3d disagrees with locap's output:\n{report}");
}

/// `locap convert a.c3d b.c3d` as ezc3d sees it: every parameter and the header events read
/// the same from the output as from the original (`ezc3d_parameters.py`), except the data
/// start blocks. Files ezc3d cannot read as they are, or reads wrongly, are left to the test
/// above ([`beyond_reference`], [`rejected_as_read`]).
#[test]
fn ezc3d_reads_the_same_parameters_after_convert() {
    let Some(data) = common::shared_data() else { return };
    if !common::python_has("ezc3d, numpy") {
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let mut cases = Vec::new();
    for (i, path) in common::files_with_extension(&data, "c3d").iter().enumerate() {
        let Ok(file) = locap_io::c3d::read_path(path) else { continue };
        // BKINtechnologies.c3d: ezc3d rejects it as read (see above).
        let unreadable = path.ends_with("BKINtechnologies.c3d") || rejected_as_read(path);
        if unreadable || beyond_reference(path) || reference_for(path).is_some() {
            continue;
        }
        let written = out.path().join(format!("{i}.c3d"));
        locap_io::c3d::write_path(&file, &written).unwrap();
        cases.push(serde_json::json!({"original": path, "written": written}));
    }
    assert!(cases.len() > 100, "expected the shared C3D files, found {}", cases.len());
    let (ok, report) = run_script("ezc3d_parameters.py", &cases);
    assert!(ok, "ezc3d reads other parameters after convert:\n{report}");
}
