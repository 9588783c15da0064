//! The motion writers on a real BVH take, checked by the readers users have: the Khronos glTF
//! validator (npm `gltf-validator`) for glTF and GLB, Blender (`bpy`) for glTF and FBX, OpenSim
//! for `.mot`. Each tool is installed by `.ci/run`; without it the check is skipped, under CI
//! it fails (see `locap_testkit::tool`).

mod common;

use locap_core::LengthUnit;
use locap_io::export::{MotionOutput, write_motion_path};
use locap_testkit::{Tool, run_json, tool};
use serde_json::Value;
use std::path::Path;

fn script(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests").join(name)
}

/// CMU 131_01 (read as centimetres) written as each of `names` in a new folder.
fn written(names: &[&str]) -> Option<(locap_core::Motion, tempfile::TempDir, Vec<std::path::PathBuf>)> {
    let path = locap_testkit::shared_file("cmu-bvh/131_01.bvh")?;
    let motion = locap_io::bvh::read_bvh_path(&path, LengthUnit::Centimetre).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let outs: Vec<_> = names.iter().map(|n| dir.path().join(n)).collect();
    for out in &outs {
        write_motion_path(&motion, &MotionOutput::default(), out).unwrap();
    }
    Some((motion, dir, outs))
}

/// CMU 131_01 (31 joints, 994 frames at 120 Hz) as glTF and GLB: no validator error,
/// warning, info or hint, and the animation is there.
#[test]
fn gltf_of_a_real_take_passes_the_khronos_validator() {
    let Some((_, _dir, outs)) = written(&["131_01.gltf", "131_01.glb"]) else { return };
    for out in &outs {
        let name = out.display();
        let Some(mut node) = tool(Tool::GltfValidator) else { return };
        node.arg(script("gltf_validate.js")).arg(out);
        let report: Value = serde_json::from_str(&run_json(node)).unwrap();
        eprintln!("{name}: {report}");
        assert_eq!(report["errors"], 0, "{report}");
        assert_eq!(report["warnings"], 0, "{report}");
        assert_eq!(report["infos"], 0, "{report}");
        assert_eq!(report["hints"], 0, "{report}");
        assert_eq!(report["animations"], 1, "{report}");
    }
}

/// The same take through Blender's glTF and FBX importers: 31 bones, all 994 frames, and the
/// root where the BVH puts it (metres, glTF and FBX both Y-up, so Blender turns both alike).
#[test]
fn gltf_and_fbx_of_a_real_take_import_in_blender() {
    let Some((motion, _dir, outs)) = written(&["131_01.glb", "131_01.fbx"]) else { return };
    for out in &outs {
        let name = out.display();
        let Some(mut blender) = tool(Tool::Blender) else { return };
        blender.arg(script("blender_import.py")).arg(out).arg("100");
        let report: Value = serde_json::from_str(&run_json(blender)).unwrap();
        assert_eq!(report["bones"], 31, "{name}: {report}");
        assert_eq!(report["end"].as_i64().unwrap() - report["start"].as_i64().unwrap() + 1, 994, "{name}: {report}");
        assert!((report["fps"].as_f64().unwrap() - 120.0).abs() < 1e-3, "{name}: {report}");
        for f in report["frames"].as_array().unwrap() {
            let frame = f["frame"].as_u64().unwrap() as usize;
            // Blender is Z-up: a Y-up (x, y, z) lands at (x, -z, y).
            let p = motion.root_position_mm(frame) / 1000.0;
            let root: Vec<f64> = f["root"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            let d = ((root[0] - p.x).powi(2) + (root[1] + p.z).powi(2) + (root[2] - p.y).powi(2)).sqrt();
            assert!(d < 0.01, "{name} frame {frame}: root {root:?}, BVH {p:?} (Y-up)");
        }
    }
}

/// `.mot` of the take read by OpenSim's Storage and TimeSeriesTable.
#[test]
fn mot_of_a_real_take_reads_in_opensim() {
    let Some((motion, dir, outs)) = written(&["131_01.mot"]) else { return };
    let mot = &outs[0];
    let Some(mut opensim) = tool(Tool::OpenSim) else { return };
    // OpenSim writes opensim.log into its working folder.
    opensim
        .current_dir(dir.path())
        .arg("-c")
        .arg(
            "import sys, json, opensim; s = opensim.Storage(sys.argv[1]); t = opensim.TimeSeriesTable(sys.argv[1]); \
             print(json.dumps({'rows': t.getNumRows(), 'columns': t.getNumColumns(), 'storage': s.getSize(), \
             'degrees': s.isInDegrees(), 'first': list(t.getColumnLabels())[0], 'ty': t.getDependentColumn('Hips_ty')[0]}))",
        )
        .arg(mot);
    let report: Value = serde_json::from_str(&run_json(opensim)).unwrap();
    assert_eq!(report["rows"], 994, "{report}");
    assert_eq!(report["storage"], 994, "{report}");
    assert_eq!(report["degrees"], true, "{report}");
    // Root translation (3) and three angles for each of the 31 joints.
    assert_eq!(report["columns"], 3 + 3 * 31, "{report}");
    assert_eq!(report["first"], "Hips_tx", "{report}");
    assert!((report["ty"].as_f64().unwrap() - motion.root_position_mm(0).y / 1000.0).abs() < 1e-9, "{report}");
}
