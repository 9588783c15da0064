//! `locap train fill` and `locap clean --method neural` as a user runs them.

mod common;

use common::{locap, repo, shared_data};

#[test]
fn neural_clean_needs_a_usable_model() {
    let dir = tempfile::tempdir().unwrap();
    let take = repo().join("examples/cmu_01_01_last10s.c3d");
    let out = locap()
        .arg("clean")
        .arg(&take)
        .args(["--method", "neural", "-o"])
        .arg(dir.path().join("o.c3d"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("needs --model"));
    let bad = dir.path().join("bad.locapnn");
    std::fs::write(&bad, b"LOCAPNN\0garbage").unwrap();
    let out = locap()
        .arg("clean")
        .arg(&take)
        .args(["--method", "neural", "--model"])
        .arg(&bad)
        .arg("-o")
        .arg(dir.path().join("o.c3d"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a usable locap refiner model"));
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
    let out = locap()
        .args(["train", "fill", "--data"])
        .arg(&shards)
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
