//! `locap stats`: real occlusion statistics of takes, pooled into one JSON file that
//! `locap synth --augment` draws gaps from (LocalMoCap section 3.3, Fig. 4: per-marker
//! occlusion probabilities and the gap-length distribution).

use crate::inputs::{self, read_take};
use anyhow::{Context, Result};
use clap::Parser;
use locap_core::GapStatistics;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `locap stats`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap stats ../shared/data/numediart-c3d ../shared/data/cmu-c3d -o stats.json")]
pub struct Args {
    /// Takes (C3D or TRC) or folders of them.
    #[arg(required = true, value_name = "TAKE", help_heading = "Input")]
    takes: Vec<PathBuf>,
    /// Where to write the pooled statistics (JSON; markers pooled by label).
    #[arg(short, long, value_name = "FILE", help_heading = "Output")]
    output: PathBuf,
}

/// Gap-length bins for printed histograms: `[lo, hi]` frames.
pub const BINS: [(usize, usize); 10] =
    [(1, 1), (2, 2), (3, 4), (5, 8), (9, 16), (17, 32), (33, 64), (65, 128), (129, 256), (257, usize::MAX)];

/// Share of gaps of histogram `h` in each of [`BINS`].
pub fn binned(h: &[usize]) -> Vec<f64> {
    let total = h.iter().skip(1).sum::<usize>().max(1) as f64;
    BINS.iter()
        .map(|(lo, hi)| {
            h.iter().enumerate().filter(|(l, _)| l >= lo && l <= hi).map(|(_, c)| *c).sum::<usize>() as f64 / total
        })
        .collect()
}

/// Label of bin `b`.
pub fn bin_label(b: usize) -> String {
    match BINS[b] {
        (lo, hi) if lo == hi => format!("{lo}"),
        (lo, usize::MAX) => format!("{lo}+"),
        (lo, hi) => format!("{lo}-{hi}"),
    }
}

/// Runs `locap stats`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.takes, &["c3d", "trc"])?;
    inputs::check_outputs(std::slice::from_ref(&args.output))?;
    let (done, failed) =
        crate::run_takes(&files, "measuring gaps", |_, path| Ok(GapStatistics::of_take(&read_take(path)?)));
    let stats: Vec<&GapStatistics> = done.iter().map(|(_, s)| s).collect();
    let pooled = GapStatistics::pool(stats.iter().copied()).context("no take could be read")?;
    let rates: Vec<f64> = stats.iter().map(|s| s.frame_rate_hz).collect();
    if rates.iter().any(|r| (r - rates[0]).abs() > 1e-6) {
        eprintln!(
            "locap: warning: the takes have different frame rates ({rates:?} Hz); gap lengths are pooled in frames"
        );
    }
    inputs::write_json(&args.output, &pooled)?;
    let mut out = format!(
        "{} takes, {} markers (by label), {} frames at {} Hz: {:.2}% of samples missing in {} gaps\n",
        done.len(),
        pooled.markers.len(),
        pooled.total_frames,
        pooled.frame_rate_hz,
        100.0 * pooled.missing_fraction(),
        pooled.gap_count()
    );
    out.push_str("gap length (frames)  share of gaps\n");
    for (b, share) in binned(&pooled.gap_length_histogram).iter().enumerate() {
        let _ = writeln!(out, "  {:>8}           {:>6.1}%", bin_label(b), 100.0 * share);
    }
    let _ = writeln!(out, "wrote {}", args.output.display());
    crate::emit(&out)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}
