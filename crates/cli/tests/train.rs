//! `locap train fill` and `locap clean --method neural` as a user runs them.

mod common;

use common::{locap, repo, shared_data};

#[test]
fn neural_clean_uses_the_shipped_refiner_or_a_usable_model() {
    let dir = tempfile::tempdir().unwrap();
    let take = repo().join("examples/cmu_01_01_last10s.c3d");
    // Without --model, the shipped body refiner fits the CMU example take.
    let cleaned = dir.path().join("o.c3d");
    let out = locap().arg("clean").arg(&take).args(["--method", "neural", "-o"]).arg(&cleaned).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("2 gaps, 30 samples filled"), "{text}");
    let file = locap_io::c3d::read_path(&cleaned).unwrap();
    let method = file.parameters.get("LOCAP", "METHOD").map(|p| p.strings().join(" ")).unwrap_or_default();
    assert!(method.contains("shipped waist"), "{method}");

    let bad = dir.path().join("bad.locapnn");
    std::fs::write(&bad, b"LOCAPNN\0garbage").unwrap();
    let out = locap()
        .arg("clean")
        .arg(&take)
        .args(["--method", "neural", "--model"])
        .arg(&bad)
        .arg("-o")
        .arg(dir.path().join("o2.c3d"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "a bad model file is not a usage error");
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a usable locap model file"));
}

/// A tiny model trained for a few steps on shards of one CMU motion cleans the CMU example take
/// (every gap filled, as EDM fills it) and refuses the numediart take's marker set.
#[test]
fn train_fill_then_clean_neural() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let shards = dir.path().join("shards");
    let out = locap()
        .args(["synth", "--format", "shard", "--motion"])
        .arg(data.join("cmu-asfamc/01/01_01.amc"))
        .arg("-o")
        .arg(&shards)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let model = dir.path().join("tiny.locapnn");
    // Synthetic shards and a real labeled take train together.
    let out = locap()
        .args(["train", "fill", "--data"])
        .arg(&shards)
        .arg(data.join("cmu-c3d/02_01.c3d"))
        .args(["--steps", "4", "--batch", "4", "--window", "32", "--channels", "4", "--hidden", "16"])
        .args(["--validate-every", "2", "--out"])
        .arg(&model)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("4 steps") && text.contains("EDM alone"), "{text}");
    assert!(dir.path().join("tiny.locapnn.loss.svg").is_file());
    assert!(dir.path().join("tiny.locapnn.checkpoints/checkpoint.locapnn").is_file());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("training on 2 takes") && err.contains("waist frame"), "{err}");

    // The bench scores the model on the same hidden gaps as the other methods, and says which
    // takes it could not fill.
    let report = dir.path().join("bench.json");
    let out = locap()
        .args(["bench", "fill"])
        .arg(data.join("cmu-c3d/85_02.c3d"))
        .arg(data.join("numediart-c3d/03_rolling.c3d"))
        .arg("--model")
        .arg(&model)
        .arg("--json")
        .arg(&report)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let methods = json["methods"].as_array().unwrap();
    let row = |name: &str| methods.iter().find(|m| m["method"] == name).unwrap_or_else(|| panic!("{name}: {json}"));
    let (edm, neural) = (row("edm"), row("neural:tiny"));
    // The shipped refiner is scored beside it and refuses the numediart marker set too.
    assert!(row("neural")["scored_samples"].as_u64().unwrap() > 0);
    let hidden = json["hidden_samples"].as_u64().unwrap();
    assert_eq!(edm["scored_samples"].as_u64(), Some(hidden));
    let scored = neural["scored_samples"].as_u64().unwrap();
    assert!(scored > 0 && scored + neural["unfilled_samples"].as_u64().unwrap() == hidden, "{neural}");
    let failures = neural["failures"].as_array().unwrap();
    assert!(failures.len() == 1 && failures[0].as_str().unwrap().contains("another marker set"), "{neural}");

    let raw = repo().join("examples/cmu_01_01_last10s.c3d");
    let cleaned = dir.path().join("clean.c3d");
    let out = locap()
        .arg("clean")
        .arg(&raw)
        .args(["--method", "neural", "--model"])
        .arg(&model)
        .arg("-o")
        .arg(&cleaned)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // As EDM: both gaps filled; the 1200 missing samples are the unlabeled point `*42`, never filled.
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("2 gaps, 30 samples filled, 1200 still missing"), "{text}");
    let info = locap().arg("info").arg(&cleaned).output().unwrap();
    assert!(info.status.success());

    let rolling = data.join("numediart-c3d/03_rolling.c3d");
    let out = locap()
        .arg("clean")
        .arg(&rolling)
        .args(["--method", "neural", "--model"])
        .arg(&model)
        .arg("-o")
        .arg(dir.path().join("rolling.c3d"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("03_rolling") && err.contains("another marker set"), "{err}");
}

/// The shipped refiner must keep beating EDM alone, in mean and 95th percentile, on a real take
/// of a subject it never saw (the figures of the README's refiner table come from the same
/// command on three takes).
#[test]
fn shipped_refiner_beats_edm_on_a_held_out_real_take() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("bench.json");
    let out = locap()
        .args(["bench", "fill"])
        .arg(data.join("cmu-c3d/85_12.c3d"))
        .arg("--json")
        .arg(&report)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let row = |name: &str| json["methods"].as_array().unwrap().iter().find(|m| m["method"] == name).unwrap().clone();
    let (edm, neural) = (row("edm"), row("neural"));
    let f = |m: &serde_json::Value, k: &str| m[k].as_f64().unwrap();
    eprintln!(
        "85_12: EDM {:.2} / p95 {:.2} mm, refiner {:.2} / p95 {:.2} mm",
        f(&edm, "ompe_mean_mm"),
        f(&edm, "ompe_p95_mm"),
        f(&neural, "ompe_mean_mm"),
        f(&neural, "ompe_p95_mm")
    );
    assert_eq!(neural["unfilled_samples"].as_u64(), Some(0));
    assert!(f(&neural, "ompe_mean_mm") < f(&edm, "ompe_mean_mm"), "{neural}\n{edm}");
    assert!(f(&neural, "ompe_p95_mm") < f(&edm, "ompe_p95_mm"), "{neural}\n{edm}");
}

/// Issue 14: a 100-byte shard (a copy cut short) is an error naming the file, exit 1, for both
/// trainers: never an allocation abort from the frame count its header announces.
#[test]
fn a_shard_cut_short_is_an_error_naming_it() {
    use locap_core::{MarkerName, Take, Vec3};
    let dir = tempfile::tempdir().unwrap();
    let names: Vec<MarkerName> = ["A", "B", "C"].iter().map(|n| MarkerName::parse(n)).collect();
    let take = Take::from_samples(names, &vec![Some(Vec3::new(1.0, 2.0, 3.0)); 3 * 40], 120.0).unwrap();
    let mut bytes = Vec::new();
    locap_synth::shard::write_shard(&mut bytes, &take, &take, None, locap_synth::synthesize::LabFrame::ZUpFromYUp)
        .unwrap();
    let path = dir.path().join("short.shard");
    std::fs::write(&path, &bytes[..100]).unwrap();
    for (what, out) in [("fill", "m.locapnn"), ("solve", "m.locapsv")] {
        let out =
            locap().args(["train", what, "--data"]).arg(&path).arg("--out").arg(dir.path().join(out)).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "train {what}: {err}");
        assert!(
            err.contains(&format!("{}: ", path.display())) && err.contains("size does not match its header"),
            "{err}"
        );
    }
}
