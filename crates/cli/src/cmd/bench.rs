//! `locap bench`: accuracy and speed measured on real takes, against baselines run in the
//! same process on the same data.

use crate::inputs::{self, read_take};
use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use locap_eval::fill_bench::{self, Variant};
use locap_eval::gap_model::GapModel;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `locap bench`.
#[derive(Parser, Debug)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand, Debug)]
enum What {
    /// Gap-fill accuracy (OMPE) and speed of every fill method on real takes with realistic
    /// hidden gaps.
    Fill(FillArgs),
}

/// Arguments of `locap bench fill`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Example:\n  locap bench fill ../shared/data/cmu-c3d/*.c3d ../shared/data/hdm05-c3d/*.c3d \\\n    \
                        --gap-source ../shared/data/numediart-c3d/03_rolling.c3d --json fill.json"
)]
pub struct FillArgs {
    /// Takes with ground truth (gap-free, or nearly: only captured samples are hidden).
    #[arg(required = true, value_name = "TAKE")]
    takes: Vec<PathBuf>,
    /// How gaps are drawn: from real occlusion statistics, or uniform lengths.
    #[arg(long, value_enum, default_value_t = Gaps::Real)]
    gaps: Gaps,
    /// Real occlusion statistics: C3D/TRC takes with real gaps (measured), or gap statistics
    /// JSON (locap's or the LocalMoCap paper's). Default: the real gaps of the takes under test,
    /// or, when they have few, the built-in statistics of a real Qualisys capture.
    #[arg(long, value_name = "FILE")]
    gap_source: Vec<PathBuf>,
    /// Longest gap hidden, frames.
    #[arg(long, default_value_t = 600, value_name = "FRAMES")]
    max_gap: usize,
    /// Missing fraction per marker with `--gaps uniform`.
    #[arg(long, default_value_t = 0.1)]
    uniform_fraction: f64,
    /// Seed of the gap sampler (same seed, same gaps).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Neighbours used by EDM.
    #[arg(long, default_value_t = 6)]
    neighbours: usize,
    /// Also write the report as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

/// Fewer real gaps than this in the takes under test say too little about occlusion.
const MIN_OWN_GAPS: usize = 50;

/// Gap sources.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Gaps {
    /// Real occlusion statistics.
    Real,
    /// Uniform lengths up to --max-gap.
    Uniform,
}

/// Runs `locap bench`.
pub fn run(args: Args) -> Result<ExitCode> {
    match args.what {
        What::Fill(a) => fill(a),
    }
}

fn fill(args: FillArgs) -> Result<ExitCode> {
    let files = inputs::expand(&args.takes, &["c3d", "trc"])?;
    let takes: Vec<(String, locap_core::Take)> =
        files.iter().map(|p| Ok((p.display().to_string(), read_take(p)?))).collect::<Result<_>>()?;
    let mut model = match args.gaps {
        Gaps::Uniform => GapModel::uniform(args.uniform_fraction, args.max_gap),
        Gaps::Real => {
            let mut stats = Vec::new();
            let mut models = Vec::new();
            if args.gap_source.is_empty() {
                let own: Vec<_> = takes.iter().map(|(_, t)| locap_core::GapStatistics::of_take(t)).collect();
                if own.iter().map(|s| s.gap_count()).sum::<usize>() >= MIN_OWN_GAPS {
                    stats.extend(own);
                } else {
                    eprintln!(
                        "the takes have few real gaps: hiding gaps drawn from the built-in real statistics (numediart 03_rolling)"
                    );
                    models.push(GapModel::builtin());
                }
            }
            for source in &args.gap_source {
                if inputs::has_extension(source, &["json"]) {
                    let text = std::fs::read_to_string(source).with_context(|| format!("{}", source.display()))?;
                    models.push(GapModel::from_json(&text).with_context(|| format!("{}", source.display()))?);
                } else {
                    stats.push(locap_core::GapStatistics::of_take(&read_take(source)?));
                }
            }
            let mut model = if stats.is_empty() {
                models.pop().context("no gap statistics")?
            } else {
                GapModel::from_statistics(&stats).context(
                    "the takes have no real gaps to learn from: give --gap-source (e.g. a take with real occlusions)",
                )?
            };
            for m in &models {
                model.merge(m);
            }
            model
        }
    };
    model.max_gap_frames = args.max_gap.min(model.length_histogram.len().saturating_sub(1)).max(1);
    if takes.is_empty() {
        bail!("no takes");
    }
    eprintln!("filling hidden gaps in {} takes with {} methods...", takes.len(), Variant::all().len());
    let report = fill_bench::run(&takes, &model, &Variant::all(), args.neighbours, args.seed);
    crate::emit(&report.table())?;
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report)?;
        locap_io::atomic::write_atomically(path, |w| Ok(w.write_all(text.as_bytes())?))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}
