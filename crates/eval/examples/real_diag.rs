//! Per hidden gap of `locap bench fill`'s real-statistics run (the same gaps: same takes in the
//! same order, same seed) whose length is within `MIN..=MAX` frames: auto's choice and its
//! candidates' trial scores beside each candidate's real mean error on that gap, so a bucket
//! `bench fill` loses can be traced to the gaps and choices that lose it.
//!
//! ```text
//! cargo run -p locap-eval --release --example real_diag -- SEED MIN MAX TAKE.c3d...
//! ```
//!
//! Columns: take, marker, frames, choice (trial count), auto's mean error, then each of
//! [`auto::CANDIDATES`] filling the whole take alone, then their trial scores (mm).
use locap_clean::auto::{self, AutoConfig};
use locap_clean::{FillConfig, fill_gaps};
use locap_eval::{fill_bench, fill_candidates};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 4 {
        anyhow::bail!("usage: real_diag SEED MIN MAX TAKE.c3d...");
    }
    let seed: u64 = args[0].parse()?;
    let lo: usize = args[1].parse()?;
    let hi: usize = args[2].parse()?;
    let mut takes = Vec::new();
    for p in &args[3..] {
        let t = locap_io::c3d::read_path(std::path::Path::new(p))?.to_take()?;
        takes.push((p.clone(), t));
    }
    let (model, _) = fill_candidates::real_gap_model(&takes, Vec::new(), 600)?;
    let methods = auto::CANDIDATES;
    for (index, (name, truth)) in takes.iter().enumerate() {
        let (holed, hidden, _) = fill_bench::hide_gaps(truth, &model, seed, index);
        let out = auto::fill(&holed, &AutoConfig::default());
        let each: Vec<_> = methods
            .iter()
            .map(|m| fill_gaps(&holed, &FillConfig { method: *m, ..FillConfig::default() }).take)
            .collect();
        let mut seen = std::collections::BTreeSet::new();
        for &(f, m, len) in &hidden {
            if len < lo || len > hi {
                continue;
            }
            let Some(c) = out.choices.iter().find(|c| c.marker == m && c.frames.contains(&f)) else { continue };
            if !seen.insert((m, c.frames.start)) {
                continue;
            }
            let mean_error = |take: &locap_core::Take| -> f64 {
                let v: Vec<f64> = hidden
                    .iter()
                    .filter(|(g, k, _)| *k == m && c.frames.contains(g))
                    .filter_map(|(g, _, _)| Some((take.position_mm(*g, m)? - truth.position_mm(*g, m)?).norm()))
                    .collect();
                v.iter().sum::<f64>() / v.len().max(1) as f64
            };
            let real: Vec<String> = each.iter().map(|t| format!("{:.1}", mean_error(t))).collect();
            let trials: Vec<String> = methods
                .iter()
                .map(|x| c.trial_rmse_mm.iter().find(|(t, _)| t == x).map_or("-".into(), |(_, e)| format!("{e:.1}")))
                .collect();
            println!(
                "| {} | {} | {:?} | {} ({}) | {:.1} | {} | {} |",
                name.rsplit('/').next().unwrap_or(name),
                truth.markers()[m],
                c.frames,
                c.method(),
                c.trials,
                mean_error(&out.filled.take),
                real.join(" | "),
                trials.join(" | ")
            );
        }
    }
    Ok(())
}
