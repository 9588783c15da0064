//! `locap solve` on the shipped example into every motion format, read by the programs users
//! open them with: Blender (`bpy`) for BVH, glTF and FBX, OpenSim for `.mot` and a `--up y`
//! TRC. Each tool is installed by `.ci/run`; without it the check is skipped, under CI it
//! fails (`locap_testkit::tool`).

mod common;

use common::{locap, repo};
use locap_core::Vec3;
use locap_testkit::{Tool, run_json, tool};
use serde_json::Value;
use std::path::Path;

fn script(name: &str) -> std::path::PathBuf {
    repo().join("crates/io/tests").join(name)
}

fn solve(take: &Path, out: &Path, extra: &[&str]) {
    let result = locap().arg("solve").arg(take).arg("-o").arg(out).args(extra).output().unwrap();
    assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
}

fn vec3(v: &Value) -> Vec3 {
    let a: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    Vec3::new(a[0], a[1], a[2])
}

fn blender(file: &Path, render: Option<&Path>) -> Option<Value> {
    let mut command = tool(Tool::Blender)?;
    command.arg(script("blender_import.py")).arg(file).arg("100");
    if let Some(png) = render {
        command.arg(png);
    }
    Some(serde_json::from_str(&run_json(command)).unwrap())
}

/// Horizontal direction (Blender's Z-up lab) the character faces: the left hip minus the
/// right hip is its left, and forward is left x up.
fn facing(frame: &Value) -> Vec3 {
    let left = vec3(&frame["lfemur"]) - vec3(&frame["rfemur"]);
    let f = left.cross(&Vec3::z());
    Vec3::new(f.x, f.y, 0.0).normalize()
}

/// The BVH of `locap solve` in Blender: 31 bones, 1200 frames at 120 Hz, upright (the head
/// a metre and more above the feet) and facing where the front-of-pelvis markers face; the
/// glTF and FBX of the same take: the same bones, frames and rate, the root within 1 cm of the
/// BVH's at every 100th frame.
#[test]
fn solved_motion_stands_up_and_faces_forward_in_blender() {
    let dir = tempfile::tempdir().unwrap();
    let take = repo().join("examples/cmu_01_01_last10s.c3d");
    let (bvh, glb, fbx, clean) =
        (dir.path().join("x.bvh"), dir.path().join("x.glb"), dir.path().join("x.fbx"), dir.path().join("clean.c3d"));
    solve(&take, &bvh, &["--markers-out", clean.to_str().unwrap()]);
    solve(&take, &glb, &["--with-markers"]);
    solve(&take, &fbx, &[]);
    let markers = locap_io::c3d::read_path(&clean).unwrap().to_take().unwrap();
    let marker = |frame: usize, label: &str| markers.position_mm(frame, markers.marker_index(label).unwrap()).unwrap();

    // LOCAP_KEEP_RENDER=docs/guide/blender-solved.png keeps a render of the BVH in Blender
    // (the guide's picture).
    let render = std::env::var_os("LOCAP_KEEP_RENDER").map(|p| repo().join(p));
    let Some(reference) = blender(&bvh, render.as_deref()) else { return };
    if let Some(png) = &render {
        assert!(std::fs::metadata(png).is_ok_and(|m| m.len() > 10_000), "{} not rendered", png.display());
    }
    let check_counts = |report: &Value, name: &str| {
        assert_eq!(report["bones"], 31, "{name}: {report}");
        assert_eq!(report["end"].as_i64().unwrap() - report["start"].as_i64().unwrap() + 1, 1200, "{name}: {report}");
        assert!((report["fps"].as_f64().unwrap() - 120.0).abs() < 1e-3, "{name}: {report}");
    };
    check_counts(&reference, "BVH");
    let frames = reference["frames"].as_array().unwrap();
    let mut worst_deg: f64 = 0.0;
    for f in frames {
        let frame = f["frame"].as_u64().unwrap() as usize;
        let (head, feet) = (vec3(&f["head"]), (vec3(&f["lfoot"]) + vec3(&f["rfoot"])) / 2.0);
        assert!(head.z - feet.z > 1.0, "BVH frame {frame}: head {head:?}, feet {feet:?} (Blender Z-up, m)");
        let front = (marker(frame, "LFWT") + marker(frame, "RFWT")) / 2.0;
        let back = (marker(frame, "LBWT") + marker(frame, "RBWT")) / 2.0;
        let forward = Vec3::new(front.x - back.x, front.y - back.y, 0.0).normalize();
        let angle = facing(f).dot(&forward).clamp(-1.0, 1.0).acos().to_degrees();
        worst_deg = worst_deg.max(angle);
        assert!(angle < 30.0, "BVH frame {frame}: faces {:?}, the pelvis markers {forward:?}", facing(f));
        // The character stands where its markers are: the root within 15 cm of the pelvis.
        let pelvis = (front + back) / 2000.0;
        assert!(
            (vec3(&f["root"]) - pelvis).norm() < 0.15,
            "BVH frame {frame}: root {} vs pelvis {pelvis:?}",
            f["root"]
        );
    }
    eprintln!("BVH in Blender: facing within {worst_deg:.1} degrees of the pelvis markers' direction");

    for (path, name) in [(&glb, "glTF"), (&fbx, "FBX")] {
        let Some(report) = blender(path, None) else { return };
        check_counts(&report, name);
        let mut worst_m: f64 = 0.0;
        for (f, r) in report["frames"].as_array().unwrap().iter().zip(frames) {
            assert_eq!(f["frame"], r["frame"]);
            let d = (vec3(&f["root"]) - vec3(&r["root"])).norm();
            worst_m = worst_m.max(d);
            assert!(d < 0.01, "{name} frame {}: root {} vs the BVH's {}", f["frame"], f["root"], r["root"]);
            assert!(vec3(&f["head"]).z - vec3(&f["lfoot"]).z > 1.0, "{name} frame {}: not upright", f["frame"]);
        }
        eprintln!("{name} in Blender: root within {:.2} mm of the BVH's", worst_m * 1000.0);
    }
}

/// `.mot` from `locap solve` read by OpenSim's Storage and TimeSeriesTable, and the cleaned
/// markers converted to a Y-up TRC in metres read by its TRC adapter: upright (head markers a
/// metre and more above the toes on Y) and at the lab positions turned by (x, z, -y).
#[test]
fn mot_and_y_up_trc_read_in_opensim() {
    let dir = tempfile::tempdir().unwrap();
    let take = repo().join("examples/cmu_01_01_last10s.c3d");
    let (mot, clean, trc) = (dir.path().join("x.mot"), dir.path().join("clean.c3d"), dir.path().join("clean.trc"));
    solve(&take, &mot, &["--markers-out", clean.to_str().unwrap()]);
    let out = locap()
        .arg("convert")
        .arg(&clean)
        .arg(&trc)
        .args(["--up", "y", "--trc-unit", "m", "--trc-missing", "nan"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let markers = locap_io::c3d::read_path(&clean).unwrap().to_take().unwrap();
    let Some(mut opensim) = tool(Tool::OpenSim) else { return };
    // OpenSim writes opensim.log into its working folder.
    opensim.current_dir(dir.path()).arg(script("opensim_read.py")).arg(&mot).arg(&trc);
    let report: Value = serde_json::from_str(&run_json(opensim)).unwrap();
    let m = &report["mot"];
    assert_eq!(m["rows"], 1200, "{m}");
    assert_eq!(m["storage_rows"], 1200, "{m}");
    assert_eq!(m["storage_in_degrees"], true, "{m}");
    assert_eq!(m["in_degrees"], "yes", "{m}");
    assert_eq!(m["labels"][0], "root_tx", "{m}");
    assert!((m["times"][1].as_f64().unwrap() - 1.0 / 120.0).abs() < 1e-9, "{m}");
    let t = &report["trc"];
    assert_eq!(t["rows"], 1200, "{t}");
    assert_eq!(t["markers"], markers.marker_count(), "{t}");
    assert_eq!(t["units"], "m", "{t}");
    assert_eq!(t["rate"], 120.0, "{t}");
    let read = |label: &str| {
        let name = markers.markers()[markers.marker_index(label).unwrap()].full();
        vec3(&t["first_frame"][name.as_str()])
    };
    for label in ["LFHD", "RTOE", "LFWT"] {
        let p = markers.position_mm(0, markers.marker_index(label).unwrap()).unwrap() / 1000.0;
        assert!((read(label) - Vec3::new(p.x, p.z, -p.y)).norm() < 1e-6, "{label}: {:?} vs lab {p:?}", read(label));
    }
    assert!(read("LFHD").y - read("RTOE").y > 1.0, "not Y-up: head {:?}, toe {:?}", read("LFHD"), read("RTOE"));
}
