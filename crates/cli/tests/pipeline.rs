//! `examples/pipeline.rs`, the library stages without the CLI, runs on the shipped example take
//! and writes a cleaned C3D with its `LOCAP` record and a BVH of the take's frames.

mod common;

use common::repo;
use std::process::Command;

#[test]
fn the_pipeline_example_labels_cleans_solves_and_writes() {
    // `cargo test` builds the package's examples next to the test binaries' folder.
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().and_then(|deps| deps.parent()).unwrap().join("examples").join("pipeline");
    assert!(
        example.exists(),
        "{} not built (`cargo test` builds it; or `cargo build --release --examples`)",
        example.display()
    );
    let dir = tempfile::tempdir().unwrap();
    let out =
        Command::new(&example).arg(repo().join("examples/cmu_01_01_last10s.c3d")).arg(dir.path()).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("1200 frames solved"), "{text}");
    let file = locap_io::c3d::read_path(&dir.path().join("cleaned.c3d")).unwrap();
    let take = file.to_take().unwrap();
    assert_eq!(take.frame_count(), 1200);
    let record = file.provenance(&take).unwrap();
    assert_eq!(record.method.as_deref(), Some("Auto trials=3 blend=3"));
    assert!(!record.filled.is_empty());
    let motion =
        locap_io::bvh::read_bvh_path(&dir.path().join("motion.bvh"), locap_core::LengthUnit::Centimetre).unwrap();
    assert_eq!(motion.frame_count(), 1200);
}
