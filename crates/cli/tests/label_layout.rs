//! `locap label --layout` as a user runs it with no labeled take (issue 16, item 1b): the
//! OpenSim-built layout of the shared 62-marker set labels the shared take, and the flag
//! combinations that mean nothing are refused as usage errors.

mod common;

use common::{locap, shared_data};

#[test]
fn label_from_the_opensim_layout_alone() {
    let Some(data) = shared_data() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (labeling, layout) = (data.join("labeling"), dir.path().join("r62.toml"));
    let out = locap()
        .args(["layout", "--from-opensim"])
        .arg(labeling.join("Rajagopal2015_mod.osim"))
        .arg(labeling.join("MarkerSet.xml"))
        .arg("-o")
        .arg(&layout)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (take, labeled) = (labeling.join("KneeltoProne01.c3d"), dir.path().join("out.c3d"));
    let out = locap().arg("label").arg(&take).arg("--layout").arg(&layout).arg("-o").arg(&labeled).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let summary = String::from_utf8_lossy(&out.stdout);
    // The take's 62 markers, labeled (measured 99.85% of the samples labeled, 100% of the
    // shuffled take's points right in `crates/eval/tests/label_layout.rs`).
    let file = locap_io::c3d::read_path(&labeled).unwrap();
    let result = file.to_take().unwrap();
    assert_eq!(result.marker_count(), 62, "{summary}");
    let valid = (0..result.frame_count()).map(|f| (0..62).filter(|&m| result.is_valid(f, m)).count()).sum::<usize>();
    assert!(valid as f64 >= 0.99 * (62 * result.frame_count()) as f64, "{summary}");
    let recorded = file.parameters.continued_strings("LOCAP", "LABELED").join(" ");
    assert!(recorded.contains("layout") && recorded.contains("r62.toml"), "{recorded}");

    // A layout with a template but no skeleton, and a rigid fit with no template: usage errors.
    for args in [vec!["--template", take.to_str().unwrap()], vec!["--fit", "rigid"]] {
        let out = locap()
            .arg("label")
            .arg(&take)
            .arg("--layout")
            .arg(&layout)
            .args(&args)
            .arg("-o")
            .arg(dir.path().join("x.c3d"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
    }
    // Neither a template nor a layout: clap refuses.
    let out = locap().arg("label").arg(&take).arg("-o").arg(dir.path().join("x.c3d")).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}
