//! Cross-check with files another implementation *wrote*: `pyc3d_write.py` uses py-c3d's
//! `c3d.Writer` (PyPI `c3d` 0.6.0) to write an integer file (`POINT:SCALE` 0.1) and a float
//! file (scale -1) with known markers, missing samples (residual -1), residuals, camera masks
//! and two analog channels at 4 samples per frame; locap must read exactly that. The other
//! way round, a file locap writes from a `Take` must read back in py-c3d with the same labels,
//! rate and points. `.ci/run` installs py-c3d into `.ci/pydeps`; elsewhere the test is skipped
//! with a message (but fails under CI, so a broken install cannot pass silently).

mod common;

use locap_core::take::SampleQuality;
use locap_core::{MarkerName, Take, Vec3};
use locap_io::c3d::{self, AnalogSamples, C3dFile, Storage};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Runs `pyc3d_write.py` with `args`, returning its standard output.
fn script(args: &[&Path]) -> String {
    let output = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/pyc3d_write.py"))
        .args(args)
        .env("PYTHONPATH", common::pydeps())
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "pyc3d_write.py {args:?} failed ({}):\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).unwrap()
}

fn vec3(v: &Value) -> Vec3 {
    let c: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    Vec3::new(c[0], c[1], c[2])
}

fn strings(v: &Value) -> Vec<String> {
    v.as_array().unwrap().iter().map(|s| s.as_str().unwrap().to_string()).collect()
}

#[test]
fn locap_reads_what_pyc3d_writes() {
    if !common::python_has("c3d, numpy") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    script(&[Path::new("write"), dir.path()]);
    let expected: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("expected.json")).unwrap()).unwrap();
    let markers = strings(&expected["markers"]);
    let channels = strings(&expected["channels"]);
    let frames = expected["frames"].as_u64().unwrap() as usize;
    let rate = expected["rate"].as_f64().unwrap();
    let analog_per_frame = expected["analog_per_frame"].as_u64().unwrap() as usize;
    for (name, case) in expected["files"].as_object().unwrap() {
        let file = c3d::read_path(Path::new(case["path"].as_str().unwrap())).unwrap();
        assert!(file.warnings.is_empty(), "{name}: {:?}", file.warnings);
        let scale = case["scale"].as_f64().unwrap();
        assert_eq!(file.storage, if scale > 0.0 { Storage::Int } else { Storage::Float }, "{name}");
        assert_eq!(file.point_scale(), scale.abs() as f32, "{name}");
        assert_eq!(file.point_labels(), markers, "{name}");
        assert_eq!((file.point_count, file.frames), (markers.len(), frames), "{name}");
        assert_eq!(file.frame_rate_hz(), rate, "{name}");
        assert_eq!(file.first_frame(), 1, "{name}");

        // Points: py-c3d truncates integer coordinates toward zero, so within one scale unit.
        let take = file.to_take().unwrap();
        assert_eq!(take.markers()[2], MarkerName::parse("Subj:LANK"), "{name}");
        let tolerance = if scale > 0.0 { scale * 1.0001 } else { 1e-3 };
        let (mut present, mut absent) = (0, 0);
        for f in 0..frames {
            for m in 0..markers.len() {
                let want = &case["points"][f][m];
                match take.position_mm(f, m) {
                    Some(p) if !want.is_null() => {
                        let d = (p - vec3(want)).amax();
                        assert!(d <= tolerance, "{name} frame {f} marker {m}: {p:?} vs {want}");
                        let q = take.quality(f, m);
                        let residual = case["residuals"][f][m].as_f64().unwrap();
                        assert!((q.residual_mm as f64 - residual).abs() < 1e-4, "{name} {f} {m}: {q:?} vs {residual}");
                        assert_eq!(q.cameras as u64, case["cameras"][f][m].as_u64().unwrap(), "{name} {f} {m}");
                        present += 1;
                    }
                    None if want.is_null() => absent += 1,
                    got => panic!("{name} frame {f} marker {m}: locap {got:?}, py-c3d wrote {want}"),
                }
            }
        }
        // py-c3d leaves stale coordinates on missing samples: locap must go by the residual.
        let stale =
            (0..frames * markers.len()).filter(|i| file.points[*i][3] < 0.0 && file.points[*i][0] != 0.0).count();
        assert!(stale > 0, "{name}: expected py-c3d's stale coordinates on missing samples");
        assert_eq!(absent, 7, "{name}");
        assert_eq!(present, frames * markers.len() - 7, "{name}");

        // Analog: count, layout (sub-sample major, channel minor) and raw values.
        let info = file.analog_info();
        assert_eq!(info.labels, channels, "{name}");
        assert_eq!(info.samples_per_frame, analog_per_frame, "{name}");
        assert_eq!(info.rate_hz, rate * analog_per_frame as f64, "{name}");
        let want: Vec<f64> = case["analog"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert_eq!(want.len(), frames * analog_per_frame * channels.len());
        // Compared as f32: the values are f32 (float file) or integers, and JSON's decimal
        // text round-trips them exactly at that precision.
        let got: Vec<f32> = match &file.analog {
            AnalogSamples::Int(v) => v.iter().map(|x| *x as f32).collect(),
            AnalogSamples::Float(v) => v.clone(),
        };
        assert_eq!(matches!(file.analog, AnalogSamples::Int(_)), scale > 0.0, "{name}");
        assert_eq!(got.len(), want.len(), "{name}: analog sample count");
        if let Some(i) = (0..got.len()).find(|i| got[*i] != want[*i] as f32) {
            panic!("{name}: raw analog sample {i}: locap {}, py-c3d wrote {}", got[i], want[i]);
        }
        eprintln!("{name}: {present} points, {absent} missing, {} analog samples as py-c3d wrote them", got.len());
    }
}

#[test]
fn pyc3d_reads_what_locap_writes() {
    if !common::python_has("c3d, numpy") {
        return;
    }
    let markers: Vec<MarkerName> = ["RASI", "Bob:LASI", "STRN"].iter().map(|n| MarkerName::parse(n)).collect();
    let (frames, rate) = (40, 150.0);
    let mut samples = Vec::new();
    for f in 0..frames {
        for m in 0..markers.len() {
            let t = f as f64 / rate;
            let missing = (m == 0 && (5..9).contains(&f)) || (m == 2 && f == frames - 1);
            samples.push((!missing).then(|| {
                Vec3::new(-812.25 + 300.0 * m as f64 + 40.0 * t.sin(), 1234.5 * t.cos(), 1000.0 + 7.125 * f as f64)
            }));
        }
    }
    let mut take = Take::from_samples(markers.clone(), &samples, rate).unwrap();
    take.set_quality(3, 1, SampleQuality { residual_mm: 1.5, cameras: 0b101 });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("locap.c3d");
    c3d::write_path(&C3dFile::from_take(&take).unwrap(), &path).unwrap();

    let read: Value = serde_json::from_str(&script(&[Path::new("read"), &path])).unwrap();
    let labels: Vec<String> = markers.iter().map(|m| m.full()).collect();
    assert_eq!(strings(&read["labels"]), labels);
    assert_eq!(read["rate"].as_f64().unwrap(), rate);
    let got = read["frames"].as_array().unwrap();
    assert_eq!(got.len(), frames);
    for (f, row) in got.iter().enumerate() {
        for (m, p) in row.as_array().unwrap().iter().enumerate() {
            match (&samples[f * markers.len() + m], p.is_null()) {
                (Some(want), false) => {
                    assert!((vec3(p) - want).amax() < 1e-3, "frame {f} marker {m}: py-c3d {p}, locap wrote {want:?}")
                }
                (None, true) => {}
                (want, _) => panic!("frame {f} marker {m}: py-c3d {p}, locap wrote {want:?}"),
            }
        }
    }
    // Residual 1.5 mm at locap's scale of 0.1 mm: byte 15, which py-c3d reads as 1.5.
    assert!((got[3][1][3].as_f64().unwrap() - 1.5).abs() < 1e-6, "{}", got[3][1]);
}
