//! The whole pipeline with the library stages, no CLI: read a raw take, label it against a
//! template, clean it, solve it into skeleton motion, write the cleaned markers (C3D, with the
//! `LOCAP` record of what was changed) and the motion (BVH).
//!
//!     cargo run --release -p locap --example pipeline -- [LABELED.c3d] [OUT_DIR]
//!
//! A raw capture is unlabeled points; this example has only the shipped labeled take, so it
//! makes the raw take from it (labels removed, columns reversed) and labels it back with a
//! template built from the labeled take. With a real raw capture, read it instead.

use anyhow::Result;
use locap_core::{LengthUnit, MarkerName, Take};
use std::path::Path;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let input = args.get(1).map_or("examples/cmu_01_01_last10s.c3d", String::as_str);
    let out = Path::new(args.get(2).map_or("pipeline-out", String::as_str));
    std::fs::create_dir_all(out)?;

    let labeled = locap_io::c3d::read_path(Path::new(input))?.to_take()?;
    let raw = without_labels(&labeled)?;
    // The pipeline: label, clean, solve, write.
    let template = locap_label::Template::from_take(&labeled, None)?;
    let relabeled = locap_label::label_take(&raw, &template, &locap_label::LabelConfig::default())?;
    let cleaned = locap_clean::clean(&relabeled.take, &locap_clean::CleanConfig::default());
    let solver = locap_nn::shipped::solver(&Default::default())?;
    let motion = solver.solve_cleaned(&cleaned, cleaned.take().frame_rate_hz())?;
    let mut file = locap_io::c3d::C3dFile::from_take(cleaned.take())?;
    file.set_provenance(cleaned.take(), &cleaned.provenance())?;
    locap_io::c3d::write_path(&file, &out.join("cleaned.c3d"))?;
    locap_io::bvh::write_bvh_path(&motion, LengthUnit::Centimetre, &out.join("motion.bvh"))?;

    println!(
        "{input}: {} of {} points labeled; {} samples filled, {} outliers replaced; {} frames solved -> {}",
        relabeled.labeled_samples(),
        relabeled.frames.point_count(),
        cleaned.filled_samples(),
        cleaned.outliers.len(),
        motion.frame_count(),
        out.display()
    );
    Ok(())
}

/// `take`'s points with their labels removed (`*0`, `*1`, ...) and the columns reversed: what
/// a capture system hands over before labeling.
fn without_labels(take: &Take) -> Result<Take> {
    let m = take.marker_count();
    let names: Vec<MarkerName> = (0..m).map(|i| MarkerName::parse(&format!("*{i}"))).collect();
    let samples: Vec<_> =
        (0..take.frame_count()).flat_map(|f| (0..m).rev().map(move |k| take.position_mm(f, k))).collect();
    let mut raw = Take::from_samples(names, &samples, take.frame_rate_hz())?;
    raw.first_frame = take.first_frame;
    raw.up_axis = take.up_axis;
    Ok(raw)
}
