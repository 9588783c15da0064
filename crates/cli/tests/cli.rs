//! The `locap` binary as a user runs it.

mod common;

use common::{locap, repo, shared_data};
use std::process::Command;

/// The README's run command, on the take shipped in the repository.
#[test]
fn info_on_the_shipped_example() {
    let out = locap().args(["info", "examples/cmu_01_01_last10s.c3d"]).current_dir(repo()).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("42 markers x 1200 frames at 120 Hz"), "{text}");
    assert!(text.contains("RBAC "), "{text}");

    let out = locap().args(["info", "--json", "examples/cmu_01_01_last10s.c3d"]).current_dir(repo()).output().unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["frames"], 1200);
    assert_eq!(json["first_frame"], 1591);
    let rbac = json["gaps"]["markers"].as_array().unwrap().iter().find(|m| m["name"] == "RBAC").unwrap();
    assert_eq!(rbac["missing_frames"], 30);
    assert_eq!(rbac["gap_length_histogram"][30], 1);
}

/// `info` over the whole shared data folder: every file but the empty one is described, the
/// empty one is reported with its path and the batch goes on, exit status 1.
#[test]
fn info_on_every_shared_file() {
    let Some(data) = shared_data() else { return };
    let out = locap().args(["info", "--json"]).arg(&data).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let failures: Vec<&str> = stderr.lines().filter(|l| l.starts_with("locap: ")).collect();
    assert_eq!(failures.len(), 3, "{stderr}");
    assert!(failures.iter().any(|l| l.contains("Empty.c3d") && l.contains("byte 0")), "{stderr}");
    assert!(failures.iter().any(|l| l.contains("Empty.trc") && l.contains("line")), "{stderr}");
    assert!(failures.iter().any(|l| l.contains("Truncated.trc") && l.contains("line")), "{stderr}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let takes = json.as_array().unwrap();
    assert!(takes.len() >= 155, "{}", takes.len());
    let sgi = takes.iter().find(|t| t["path"].as_str().unwrap().ends_with("sgi_real.c3d")).unwrap();
    assert_eq!(sgi["processor"], "MIPS/SGI");
    assert_eq!(sgi["markers"], 36);
}

/// C3D -> TRC -> C3D keeps every sample; C3D -> C3D with --frames keeps the analog data.
#[test]
fn convert_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let example = repo().join("examples/cmu_01_01_last10s.c3d");
    let trc = dir.path().join("take.trc");
    let back = dir.path().join("back.c3d");
    assert!(locap().arg("convert").arg(&example).arg(&trc).status().unwrap().success());
    assert!(locap().arg("convert").arg(&trc).arg(&back).status().unwrap().success());
    let a = locap_io::c3d::read_path(&example).unwrap().to_take().unwrap();
    let b = locap_io::c3d::read_path(&back).unwrap().to_take().unwrap();
    assert_eq!(a.markers(), b.markers());
    assert_eq!(a.validity(), b.validity());
    assert_eq!(a.first_frame, b.first_frame);
    for f in 0..a.frame_count() {
        for m in 0..a.marker_count() {
            if let (Some(p), Some(q)) = (a.position_mm(f, m), b.position_mm(f, m)) {
                assert!((p - q).amax() < 1e-3);
            }
        }
    }

    let Some(data) = shared_data() else { return };
    let with_analog = data.join("c3d-vendors/Vicon.c3d");
    let cut = dir.path().join("cut.c3d");
    let status = locap().arg("convert").arg(&with_analog).arg(&cut).args(["--frames", "10..60"]).status().unwrap();
    assert!(status.success());
    let original = locap_io::c3d::read_path(&with_analog).unwrap();
    let cut = locap_io::c3d::read_path(&cut).unwrap();
    assert_eq!(cut.frames, 50);
    let per_frame = original.header.analog_per_frame as usize;
    assert!(per_frame > 0);
    match (&original.analog, &cut.analog) {
        (locap_io::c3d::AnalogSamples::Float(a), locap_io::c3d::AnalogSamples::Float(b)) => {
            assert_eq!(&a[10 * per_frame..60 * per_frame], &b[..])
        }
        (locap_io::c3d::AnalogSamples::Int(a), locap_io::c3d::AnalogSamples::Int(b)) => {
            assert_eq!(&a[10 * per_frame..60 * per_frame], &b[..])
        }
        _ => panic!("storage changed"),
    }
}

/// Bad input: clear message, no panic, input untouched.
#[test]
fn bad_input_is_reported_not_panicked() {
    let dir = tempfile::tempdir().unwrap();
    let junk = dir.path().join("junk.c3d");
    std::fs::write(&junk, vec![7u8; 3000]).unwrap();
    let out = locap().arg("info").arg(&junk).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("junk.c3d") && stderr.contains("byte 1"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");

    // A missing file is a failed take (1), not a usage error (2).
    let out = locap().args(["info", "does-not-exist.c3d"]).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("does-not-exist.c3d"));

    let example = repo().join("examples/cmu_01_01_last10s.c3d");
    let out = locap().arg("convert").arg(&example).arg(&example).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("never overwrites its input"));
}

/// `locap clean` on a take with real gaps: every gap between captured samples is filled (a gap
/// at the take's start or end only as far as the neighbours support it), the captured samples and every parameter but the point bookkeeping are unchanged, and the filled
/// ranges are listed in `LOCAP:FILLED`.
#[test]
fn clean_fills_real_gaps_and_changes_nothing_else() {
    let Some(data) = shared_data() else { return };
    let input = data.join("numediart-c3d/03_rolling.c3d");
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("clean.c3d");
    let before = std::fs::read(&input).unwrap();
    let out = locap().arg("clean").arg(&input).arg("-o").arg(&output).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(std::fs::read(&input).unwrap(), before, "input must not change");
    let stdout = String::from_utf8_lossy(&out.stdout);

    let original = locap_io::c3d::read_path(&input).unwrap();
    let cleaned = locap_io::c3d::read_path(&output).unwrap();
    let (a, b) = (original.to_take().unwrap(), cleaned.to_take().unwrap());
    assert!(stdout.contains(&format!("{} still missing", b.missing_count())), "{stdout}");
    // What is left missing lies only before a marker's first or after its last filled sample.
    for m in 0..b.marker_count() {
        let valid: Vec<usize> = (0..b.frame_count()).filter(|&f| b.is_valid(f, m)).collect();
        if let (Some(first), Some(last)) = (valid.first(), valid.last()) {
            assert_eq!(valid.len(), last - first + 1, "{}: an interior gap is left", b.markers()[m].full());
        }
    }
    // Edge gaps the neighbours cannot carry stay missing (and are reported); most are filled.
    assert!(b.missing_count() * 2 < a.missing_count(), "{} of {} left", b.missing_count(), a.missing_count());
    // Stored compactly (locap_core::range_list); decoded to `LABEL first-last Kind` lines.
    let outliers = locap_core::range_list::decode(&cleaned.parameters.continued_strings("LOCAP", "OUTLIERS")).unwrap();
    let mut unchanged = 0;
    for f in 0..a.frame_count() {
        for m in 0..a.marker_count() {
            if let Some(p) = a.position_mm(f, m) {
                let label = &a.markers()[m].full();
                let frame = a.first_frame as usize + f;
                let in_outlier = outliers.iter().any(|o| {
                    let mut parts = o.split_whitespace();
                    let (Some(l), Some(r)) = (parts.next(), parts.next()) else { return false };
                    let (s, e) = r.split_once('-').unwrap();
                    l == label && (s.parse::<usize>().unwrap()..=e.parse::<usize>().unwrap()).contains(&frame)
                });
                if !in_outlier {
                    assert!((b.position_mm(f, m).unwrap() - p).amax() < 1e-3, "captured sample changed");
                    unchanged += 1;
                }
            }
        }
    }
    assert!(unchanged > 100_000);
    // Every parameter group of the input is carried through.
    for g in original.parameters.groups() {
        for p in original.parameters.parameters_of(g.id) {
            if g.name == "POINT" && p.name == "DATA_START" {
                continue;
            }
            let q = cleaned.parameters.get(&g.name, &p.name).unwrap_or_else(|| panic!("{}:{} lost", g.name, p.name));
            assert_eq!(q.data, p.data, "{}:{} changed", g.name, p.name);
        }
    }
    assert!(!cleaned.parameters.continued_strings("LOCAP", "FILLED").is_empty());
    assert_eq!(cleaned.analog, original.analog);

    // The reference reader opens the cleaned take, missing exactly what we left missing.
    let pydeps = repo().join(".ci/pydeps");
    let script = "import ezc3d, sys, numpy as np; c = ezc3d.c3d(sys.argv[1]); p = c['data']['points']; \
                  assert p.shape == (4, 68, 2305), p.shape; n = int(np.isnan(p[0]).sum()); \
                  assert n == int(sys.argv[2]), (n, sys.argv[2]); print('ezc3d ok')";
    let left = b.missing_count().to_string();
    match Command::new("python3").arg("-c").arg(script).arg(&output).arg(&left).env("PYTHONPATH", &pydeps).output() {
        Ok(out) if out.status.success() => {}
        Ok(out) if String::from_utf8_lossy(&out.stderr).contains("No module named") => {
            assert!(std::env::var_os("CI").is_none(), "CI must install ezc3d into .ci/pydeps");
            eprintln!("skipping the ezc3d check: ezc3d not importable from {}", pydeps.display());
        }
        Ok(out) => panic!("ezc3d rejects the cleaned take: {}", String::from_utf8_lossy(&out.stderr)),
        Err(e) => eprintln!("skipping the ezc3d check: no python3 ({e})"),
    }
}

/// `unlabel` then `label` on the shipped example: shuffled points with as many ghosts as
/// markers, labeled back from the original as template and scored against the truth file.
#[test]
fn unlabel_then_label_the_shipped_example() {
    let dir = tempfile::tempdir().unwrap();
    let example = repo().join("examples/cmu_01_01_last10s.c3d");
    let before = std::fs::read(&example).unwrap();
    let raw = dir.path().join("raw.c3d");
    let out = locap()
        .args(["unlabel", example.to_str().unwrap(), "-o", raw.to_str().unwrap(), "--ghosts", "M", "--seed", "3"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let truth = dir.path().join("raw.truth.json");
    assert!(truth.is_file());
    let info = locap().args(["info", "--json", raw.to_str().unwrap()]).output().unwrap();
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json["frames"], 1200);
    let markers = json["gaps"]["markers"].as_array().unwrap();
    assert!(markers.iter().all(|m| m["name"].as_str().unwrap().starts_with('*')));

    let labeled = dir.path().join("labeled.c3d");
    // Percent of samples correct with `method`.
    let score = |method: &str| -> f64 {
        let out = locap()
            .args(["label", raw.to_str().unwrap(), "--template", example.to_str().unwrap(), "-o"])
            .arg(&labeled)
            .arg("--truth")
            .arg(&truth)
            .args(["--method", method])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        text.split("against")
            .nth(1)
            .and_then(|s| s.split(": ").nth(1))
            .and_then(|s| s.split('%').next())
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or_else(|| panic!("no score in {text}"))
    };
    // Ghosts standing near the body, as many as markers: soft graph matching beats unary
    // matching (measured: 92.5% against 87.8%, closest point 41.4%).
    let (ugm, ours) = (score("ugm"), score("ours"));
    assert!(ours > 90.0 && ours > ugm + 3.0, "ours {ours}%, ugm {ugm}%");
    let info = locap().args(["info", "--json", labeled.to_str().unwrap()]).output().unwrap();
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    let names: Vec<&str> =
        json["gaps"]["markers"].as_array().unwrap().iter().map(|m| m["name"].as_str().unwrap()).collect();
    assert!(names.contains(&"RBAC") && names.contains(&"LFHD"), "{names:?}");
    assert_eq!(std::fs::read(&example).unwrap(), before, "the input is never modified");

    // A template that is not one: a clear error, not a panic.
    let empty = dir.path().join("empty.c3d");
    std::fs::write(&empty, b"").unwrap();
    let out = locap()
        .args(["label", raw.to_str().unwrap(), "--template", empty.to_str().unwrap(), "-o", "x.c3d"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "a bad file is not a usage error");
    assert!(String::from_utf8_lossy(&out.stderr).contains("empty.c3d"));
}

/// `bench label` on the shipped example: a table with every method and a JSON report.
#[test]
fn bench_label_on_the_shipped_example() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("label.json");
    let out = locap()
        .args([
            "bench",
            "label",
            "examples/cmu_01_01_last10s.c3d",
            "--fps",
            "120,30",
            "--ghosts",
            "0,M",
            "--drop",
            "none",
        ])
        .arg("--json")
        .arg(&json)
        .current_dir(repo())
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    for method in ["ours", "ugm", "cp"] {
        assert!(table.contains(method), "{table}");
    }
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let all = report["rows"].as_array().unwrap();
    // Every method from each segment's own first frame, then ours in the cross-trial case.
    let rows: Vec<serde_json::Value> = all.iter().filter(|r| r["template"] == "own first frame").cloned().collect();
    assert_eq!(rows.len(), 2 * 2 * 3);
    let cross: Vec<&serde_json::Value> = all.iter().filter(|r| r["template"] == "other half").collect();
    assert_eq!(cross.len(), 2 * 2);
    assert!(cross.iter().all(|r| r["method"] == "ours" && r["score"]["fits"].as_u64() > Some(0)), "{table}");
    // 1200 frames in 10 s segments: one segment of 42 trajectories per row.
    assert!(rows.iter().all(|r| r["score"]["trajectories"] == 42));
    let ours_120 = &rows[0];
    assert_eq!((ours_120["method"].as_str(), ours_120["frame_rate_hz"].as_f64()), (Some("ours"), Some(120.0)));
    assert!(ours_120["accuracy"].as_f64().unwrap() > 95.0, "{table}");
    // Ours labels at least as many samples as UGM and CP in every setting (rows come as
    // ours, ugm, cp per rate and ghost count).
    for group in rows.chunks(3) {
        let accuracy = |r: &serde_json::Value| r["accuracy"].as_f64().unwrap();
        assert!(accuracy(&group[0]) >= accuracy(&group[1]) && accuracy(&group[0]) >= accuracy(&group[2]), "{table}");
    }

    let out = locap()
        .args(["bench", "label", "examples/cmu_01_01_last10s.c3d", "--ghosts", "lots"])
        .current_dir(repo())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("lots"));
}
