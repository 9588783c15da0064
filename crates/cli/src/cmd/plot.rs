//! `locap plot`: PNG or SVG charts of gaps and of fill accuracy (drawn by
//! `locap_view::plot` with plotters).
//!
//! `gaps` pools the takes given (each read as one parallel job) into a gap-length histogram
//! and per-marker occlusion rates: the two statistics the LocalMoCap occlusion augmentation is
//! built from (section 3.3, Eq. 6). `fill` draws the error by gap length of each method from
//! the JSON report of `locap bench fill --json`.

use crate::inputs;
use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use locap_eval::fill_bench::FillBenchReport;
use locap_view::plot::{Chart, Format};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap plot`.
#[derive(Parser, Debug)]
pub struct Args {
    #[command(subcommand)]
    chart: Which,
}

#[derive(Subcommand, Debug)]
enum Which {
    /// Gap-length histogram and per-marker occlusion rates of takes (pooled).
    #[command(after_help = "Example:\n  locap plot gaps ../shared/data/numediart-c3d -o charts/ --format svg")]
    Gaps(GapsArgs),
    /// Mean fill error by gap length per method, from `locap bench fill --json FILE`.
    #[command(
        after_help = "Example:\n  locap bench fill takes/ --json fill.json && locap plot fill fill.json -o fill.png"
    )]
    Fill(FillArgs),
}

/// Arguments of `locap plot gaps`.
#[derive(Parser, Debug)]
struct GapsArgs {
    /// Takes (C3D, TRC or CSV), or folders searched recursively.
    #[arg(required = true, value_name = "FILE")]
    inputs: Vec<PathBuf>,
    /// Output folder: gap-lengths.EXT and occlusion-rates.EXT are written into it.
    #[arg(short, long, value_name = "DIR", help_heading = "Output")]
    output: PathBuf,
    /// Image format.
    #[arg(long, value_enum, default_value_t = ImageFormat::Png, help_heading = "Output")]
    format: ImageFormat,
}

/// Arguments of `locap plot fill`.
#[derive(Parser, Debug)]
struct FillArgs {
    /// JSON report written by `locap bench fill --json`.
    #[arg(value_name = "REPORT")]
    report: PathBuf,
    /// Output image; the format comes from the extension (.png or .svg).
    #[arg(short, long, value_name = "FILE", help_heading = "Output")]
    output: PathBuf,
}

/// Image formats on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum ImageFormat {
    /// PNG image.
    Png,
    /// SVG drawing.
    Svg,
}

/// Runs `locap plot`.
pub fn run(args: Args) -> Result<ExitCode> {
    match args.chart {
        Which::Gaps(args) => gaps(args),
        Which::Fill(args) => fill(args),
    }
}

fn gaps(args: GapsArgs) -> Result<ExitCode> {
    let files = inputs::expand(&args.inputs, &["c3d", "trc", "csv"])?;
    let ext = match args.format {
        ImageFormat::Png => "png",
        ImageFormat::Svg => "svg",
    };
    let names = ["gap-lengths", "occlusion-rates"];
    inputs::check_outputs(&names.map(|name| args.output.join(format!("{name}.{ext}"))))?;
    let (done, failed) = crate::run_takes(&files, "reading takes", |_, input| {
        let (take, _) = crate::cmd::view::read_take(input)?;
        Ok(locap_core::GapStatistics::of_take(&take))
    });
    if done.is_empty() {
        bail!("no take could be read");
    }
    let stats: Vec<_> = done.into_iter().map(|(_, s)| s).collect();
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create output folder", args.output.display()))?;
    let (format, ext) = match args.format {
        ImageFormat::Png => (Format::Png, "png"),
        ImageFormat::Svg => (Format::Svg, "svg"),
    };
    let what = if stats.len() == 1 { "1 take".to_string() } else { format!("{} takes", stats.len()) };
    let charts = [
        (
            "gap-lengths",
            Chart::gap_lengths(
                &stats,
                &format!("Gap lengths ({what}, {} gaps)", stats.iter().map(|s| s.gap_count()).sum::<usize>()),
            ),
        ),
        ("occlusion-rates", Chart::occlusion_rates(&stats, &format!("Frames missing per marker ({what})"))),
    ];
    let mut text = String::new();
    for (name, chart) in charts {
        let target = args.output.join(format!("{name}.{ext}"));
        match chart {
            Ok(chart) => {
                write_chart(&chart, format, &target)?;
                text.push_str(&format!("{}\n", target.display()));
            }
            Err(err) => text.push_str(&format!("{name}: {err}\n")),
        }
    }
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn fill(args: FillArgs) -> Result<ExitCode> {
    let ext = args.output.extension().and_then(|e| e.to_str()).unwrap_or_default();
    let format = Format::from_extension(ext)
        .ok_or_else(|| inputs::usage(format!("{}: the output must end in .png or .svg", args.output.display())))?;
    inputs::protect(&[&args.report])?;
    inputs::check_outputs(std::slice::from_ref(&args.output))?;
    let text =
        std::fs::read_to_string(&args.report).with_context(|| format!("{}: cannot read", args.report.display()))?;
    let report: FillBenchReport = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a report of `locap bench fill --json`", args.report.display()))?;
    let title = format!("Fill error by gap length ({} hidden gaps, seed {})", report.hidden_gaps, report.seed);
    let chart = Chart::fill_error(&report.error_by_gap_length(), &title)
        .with_context(|| format!("{}", args.report.display()))?;
    inputs::create_parent(&args.output)?;
    write_chart(&chart, format, &args.output)?;
    crate::emit(&format!("{}\n", args.output.display()))?;
    Ok(ExitCode::SUCCESS)
}

fn write_chart(chart: &Chart, format: Format, target: &Path) -> Result<()> {
    let bytes = chart.render(format, chart.default_size()).with_context(|| format!("{}", target.display()))?;
    locap_io::atomic::write_atomically(target, |w| Ok(w.write_all(&bytes)?))?;
    Ok(())
}
