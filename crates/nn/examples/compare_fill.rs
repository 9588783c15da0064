//! EDM alone against EDM + refiner on real takes with hidden gaps drawn from real occlusion
//! statistics (the gaps `locap bench fill` draws for the same seed), until the bench itself
//! gains the neural method.
//!
//!     cargo run --release -p locap-nn --example compare_fill -- MODEL TAKE.c3d... [--seed N]

use locap_clean::fill_gaps;
use locap_eval::fill_bench::hide_gaps;
use locap_nn::Refiner;
use locap_nn::features::edm_config;
use locap_synth::gap_model::GapModel;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let seed = match args.iter().position(|a| a == "--seed") {
        Some(i) => {
            let s = args.get(i + 1).ok_or("--seed needs a number")?.parse()?;
            args.drain(i..i + 2);
            s
        }
        None => 1u64,
    };
    let (model, takes) = args.split_first().ok_or("usage: compare_fill MODEL TAKE.c3d... [--seed N]")?;
    let refiner = Refiner::from_bytes(&std::fs::read(model)?, &Default::default())?;
    let gap_model = GapModel::builtin();
    let (mut edm_err, mut nn_err) = (Vec::new(), Vec::new());
    let (mut edm_s, mut nn_s, mut frames) = (0.0, 0.0, 0usize);
    for (index, path) in takes.iter().enumerate() {
        let truth = locap_io::c3d::read_path(std::path::Path::new(path))?.to_take()?;
        let (holed, hidden, _) = hide_gaps(&truth, &gap_model, seed, index);
        let t = Instant::now();
        let edm = fill_gaps(&holed, &edm_config(refiner.meta.edm_neighbours));
        edm_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let refined = refiner.refine(&holed)?;
        nn_s += t.elapsed().as_secs_f64();
        frames += truth.frame_count();
        let err = |take: &locap_core::Take, out: &mut Vec<f64>| {
            let before = out.len();
            for &(f, m, _) in &hidden {
                if let (Some(a), Some(b)) = (take.position_mm(f, m), truth.position_mm(f, m)) {
                    out.push((a - b).norm());
                }
            }
            let n = out.len() - before;
            out[before..].iter().sum::<f64>() / n.max(1) as f64
        };
        let (e, r) = (err(&edm.take, &mut edm_err), err(&refined.take, &mut nn_err));
        println!("{path}: {} hidden samples; EDM {e:.2} mm, EDM + refiner {r:.2} mm", hidden.len());
    }
    let summary = |name: &str, e: &mut Vec<f64>, s: f64| {
        e.sort_by(f64::total_cmp);
        let mean = e.iter().sum::<f64>() / e.len().max(1) as f64;
        let p95 = e.get(((e.len().max(1) - 1) as f64 * 0.95).round() as usize).copied().unwrap_or(f64::NAN);
        println!("{name:<16} OMPE mean {mean:7.2} mm  p95 {p95:7.2} mm  {:9.0} frames/s", frames as f64 / s);
    };
    summary("EDM", &mut edm_err, edm_s);
    summary("EDM + refiner", &mut nn_err, nn_s);
    Ok(())
}
