//! `locap bench`: accuracy and speed measured on real takes, against baselines run in the
//! same process on the same data.

use crate::inputs::{self, read_take};
use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use locap_core::Take;
use locap_eval::fill_bench::{self, Candidate};
use locap_eval::fill_candidates::{self, FillCandidates, GapSource};
use locap_eval::fill_lengths;
use locap_eval::gap_model::GapModel;
use locap_eval::label_bench::{self, GhostCount, LabelBenchConfig};
use locap_eval::unlabel::GhostMode;
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
    /// Labeling accuracy (identification rate of trajectories) and speed of soft graph
    /// matching, unary graph matching and closest point, at several frame rates, with and
    /// without ghosts.
    Label(LabelArgs),
}

/// Arguments of `locap bench label`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Example:\n  locap bench label ../shared/data/cmu-c3d/*.c3d ../shared/data/hdm05-c3d/*.c3d --json label.json"
)]
pub struct LabelArgs {
    /// Labeled takes (the truth); they are unlabeled, given ghosts and occlusions, and
    /// labeled again by every method.
    #[arg(required = true, value_name = "TAKE")]
    takes: Vec<PathBuf>,
    /// Frame rates to test (Hz), comma-separated.
    #[arg(value_parser = crate::values::rate_hz, long, value_delimiter = ',', default_value = "120,60,30", value_name = "HZ")]
    fps: Vec<f64>,
    /// Ghost points per frame to test, comma-separated; `M` means as many as markers.
    #[arg(long, value_delimiter = ',', default_value = "0,M", value_name = "N", value_parser = parse_ghosts)]
    ghosts: Vec<GhostCount>,
    /// Where ghosts appear: near the body, riding on markers, or anywhere in the volume.
    #[arg(long, value_enum, default_value_t = GhostModeArg::Near)]
    ghost_mode: GhostModeArg,
    /// Extra occlusions: with real statistics (built-in, a real Qualisys capture), or none.
    #[arg(long, value_enum, default_value_t = Drop::Real)]
    drop: Drop,
    /// Occlusion statistics for `--drop real`: a gap statistics JSON (locap's or the LocalMoCap
    /// paper's) or a C3D/TRC take with real gaps. Default: the built-in statistics of a real
    /// Qualisys capture (numediart 03_rolling: 23% missing, long gaps).
    #[arg(long, value_name = "FILE")]
    gap_source: Option<PathBuf>,
    /// Segment length (s): each segment is labeled on its own from its first frame.
    #[arg(value_parser = crate::values::positive, long, default_value_t = 10.0, value_name = "SECONDS")]
    segment: f64,
    /// Seed (same seed, same points).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A marker layout with its skeleton (`locap layout --from-opensim`): takes with at least
    /// half of its markers are also labeled from it alone, as `locap label --layout` does
    /// (rows `layout`; slow: the fit and calibration rounds run on every segment).
    #[arg(long, value_name = "FILE")]
    layout: Option<PathBuf>,
    /// Also write the report as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

/// Ghost placement (see `locap_eval::unlabel`).
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum GhostModeArg {
    /// Standing still N(0, 20 mm) from where a marker was.
    Near,
    /// Moving with a marker, N(0, 20 mm) off (the hardest case).
    Riding,
    /// Standing anywhere in the capture volume.
    Random,
}

impl From<GhostModeArg> for GhostMode {
    fn from(mode: GhostModeArg) -> GhostMode {
        match mode {
            GhostModeArg::Near => GhostMode::Near,
            GhostModeArg::Riding => GhostMode::Riding,
            GhostModeArg::Random => GhostMode::Random,
        }
    }
}

/// Extra occlusions.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Drop {
    /// Real occlusion statistics.
    Real,
    /// Only the take's own gaps.
    None,
}

/// Parses a ghost count: a number up to [`locap_eval::unlabel::MAX_GHOSTS_PER_FRAME`], or `M` for as many as
/// markers.
pub fn parse_ghosts(text: &str) -> Result<GhostCount, String> {
    match text.trim() {
        "M" | "m" | "markers" => Ok(GhostCount::PerMarker),
        n => {
            let count: usize = n.parse().map_err(|_| format!("ghost count {n:?} is not a number or M"))?;
            if count > locap_eval::unlabel::MAX_GHOSTS_PER_FRAME {
                return Err(format!("{count} ghosts per frame: at most {}", locap_eval::unlabel::MAX_GHOSTS_PER_FRAME));
            }
            Ok(GhostCount::Fixed(count))
        }
    }
}

/// Arguments of `locap bench fill`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Example:\n  locap bench fill ../shared/data/cmu-c3d/*.c3d ../shared/data/hdm05-c3d/*.c3d \\\n    \
                        --gap-source ../shared/data/numediart-c3d/03_rolling.c3d --json fill.json\n  \
                        locap bench fill ../shared/data/cmu-c3d/85_12.c3d --lengths 0.1,0.5,1,2 --per-length 5"
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
    #[arg(value_parser = crate::values::count(1, 1 << 24), long, default_value_t = 600, value_name = "FRAMES")]
    max_gap: usize,
    /// Missing fraction per marker with `--gaps uniform`.
    #[arg(value_parser = crate::values::fraction, long, default_value_t = 0.1)]
    uniform_fraction: f64,
    /// Seed of the gap sampler (same seed, same gaps). Default: 1 for real-statistics and
    /// uniform gaps, 0 for `--lengths`.
    #[arg(long)]
    seed: Option<u64>,
    /// The fixed-length protocol instead of gaps from occlusion statistics: gaps of these
    /// lengths (seconds, comma-separated, e.g. `0.1,0.5,1,2`), `--per-length` of each, filled
    /// one per input ("single") and all at once with three neighbouring markers of one limb
    /// hidden together for 1 s ("multi"); RMSE mm over the hidden samples per length.
    #[arg(long, value_delimiter = ',', value_name = "SECONDS", value_parser = crate::values::positive)]
    lengths: Vec<f64>,
    /// Gaps of each length with `--lengths`.
    #[arg(value_parser = crate::values::count(1, 10_000), long, default_value_t = 5, value_name = "N", requires = "lengths")]
    per_length: usize,
    /// Neighbours used by EDM.
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_NEIGHBOURS)), long, default_value_t = 6)]
    neighbours: usize,
    /// Learned refiners (`locap train fill`) to score on the same gaps: a model trained on EDM's
    /// fill is reported as `neural`, one trained on the linear fill as `neural-no-edm` (the
    /// paper's "w/o EDM initial value" ablation). The refiners shipped with locap are scored
    /// too, as `neural`, on the takes they fit.
    #[arg(long, value_name = "MODEL", num_args = 1..)]
    model: Vec<PathBuf>,
    /// Leave the shipped refiners out.
    #[arg(long)]
    no_neural: bool,
    /// Also write the report as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
}

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
        What::Label(a) => label(a),
    }
}

fn read_takes(paths: &[PathBuf], json: Option<&std::path::Path>) -> Result<Vec<(String, locap_core::Take)>> {
    let files = inputs::expand(paths, &["c3d", "trc"])?;
    inputs::check_outputs(json.map(std::path::Path::to_path_buf).as_slice())?;
    files.iter().map(|p| Ok((p.display().to_string(), read_take(p)?))).collect()
}

/// Occlusion statistics from a JSON file or a take with real gaps.
pub fn gap_model_from(source: &std::path::Path) -> Result<GapModel> {
    inputs::protect(&[source])?;
    if inputs::has_extension(source, &["json"]) {
        let text = std::fs::read_to_string(source).with_context(|| format!("{}", source.display()))?;
        Ok(GapModel::from_json(&text).with_context(|| format!("{}", source.display()))?)
    } else {
        let stats = locap_core::GapStatistics::of_take(&read_take(source)?);
        GapModel::from_statistics([&stats]).with_context(|| format!("{}: no real gaps to learn from", source.display()))
    }
}

fn label(args: LabelArgs) -> Result<ExitCode> {
    let takes = read_takes(&args.takes, args.json.as_deref())?;
    if takes.is_empty() {
        bail!("no takes");
    }
    let config = LabelBenchConfig {
        frame_rates_hz: args.fps.clone(),
        ghosts: args.ghosts.clone(),
        ghost_mode: args.ghost_mode.into(),
        drop: match (args.drop, &args.gap_source) {
            (Drop::None, _) => None,
            (Drop::Real, None) => Some(GapModel::builtin()),
            (Drop::Real, Some(source)) => Some(gap_model_from(source)?),
        },
        segment_s: args.segment,
        seed: args.seed,
        layout: match &args.layout {
            Some(path) => Some(
                locap_eval::label_layout::template_from_layout(&crate::cmd::layout::read_layout(path)?)
                    .with_context(|| format!("{}", path.display()))?,
            ),
            None => None,
        },
        ..LabelBenchConfig::default()
    };
    eprintln!(
        "labeling {} takes at {} frame rates x {} ghost settings with {} methods...",
        takes.len(),
        config.frame_rates_hz.len(),
        config.ghosts.len(),
        config.methods.len()
    );
    let report = label_bench::run(&takes, &config)?;
    publish(&report.table(), &report, args.json.as_deref())
}

/// Prints a report's table and, when asked, writes the report as JSON.
fn publish(table: &str, report: &impl serde::Serialize, json: Option<&std::path::Path>) -> Result<ExitCode> {
    crate::emit(table)?;
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(report)?;
        locap_io::atomic::write_atomically(path, |w| Ok(w.write_all(text.as_bytes())?))?;
        eprintln!("wrote {}", path.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn fill(args: FillArgs) -> Result<ExitCode> {
    let takes = read_takes(&args.takes, args.json.as_deref())?;
    if takes.is_empty() {
        bail!("no takes");
    }
    if !args.lengths.is_empty() {
        return fill_lengths(&args, &takes);
    }
    let model = match args.gaps {
        Gaps::Uniform => {
            let mut model = GapModel::uniform(args.uniform_fraction, args.max_gap);
            model.max_gap_frames = args.max_gap.min(model.length_histogram.len().saturating_sub(1)).max(1);
            model
        }
        Gaps::Real => {
            let mut sources = Vec::new();
            for source in &args.gap_source {
                sources.push(if inputs::has_extension(source, &["json"]) {
                    GapSource::Model(gap_model_from(source)?)
                } else {
                    GapSource::Statistics(locap_core::GapStatistics::of_take(&read_take(source)?))
                });
            }
            let (model, builtin) = fill_candidates::real_gap_model(&takes, sources, args.max_gap).context(
                "the takes have no real gaps to learn from: give --gap-source (e.g. a take with real occlusions)",
            )?;
            if builtin {
                eprintln!(
                    "the takes have few real gaps: hiding gaps drawn from the built-in real statistics (numediart 03_rolling)"
                );
            }
            model
        }
    };
    with_candidates(&args, &takes, |methods| {
        eprintln!("filling hidden gaps in {} takes with {} methods...", takes.len(), methods.len());
        let report = fill_bench::run_candidates(&takes, &model, methods, args.seed.unwrap_or(1));
        publish(&report.table(), &report, args.json.as_deref())
    })
}

/// `bench fill --lengths`: the fixed-length protocol ([`locap_eval::fill_lengths`]).
fn fill_lengths(args: &FillArgs, takes: &[(String, Take)]) -> Result<ExitCode> {
    let config = fill_lengths::LengthsConfig {
        lengths_s: args.lengths.clone(),
        per_length: args.per_length,
        seed: args.seed.unwrap_or(0),
        limb: true,
    };
    with_candidates(args, takes, |methods| {
        eprintln!(
            "filling {} gaps of each of {} lengths in {} takes, one at a time and all at once, with {} methods...",
            config.per_length,
            config.lengths_s.len(),
            takes.len(),
            methods.len()
        );
        let report = fill_lengths::run_lengths(takes, methods, &config);
        publish(&report.table(), &report, args.json.as_deref())
    })
}

/// Calls `run` with every fill method under test: locap's methods, the refiners of `--model`
/// and the shipped refiners (unless `--no-neural`) where some take carries their markers.
fn with_candidates(
    args: &FillArgs,
    takes: &[(String, Take)],
    run: impl FnOnce(&[Candidate]) -> Result<ExitCode>,
) -> Result<ExitCode> {
    let mut given = Vec::new();
    for path in &args.model {
        inputs::protect(&[path])?;
        let bytes = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
        let refiner = locap_nn::Refiner::from_bytes(&bytes, &Default::default())
            .with_context(|| format!("{}", path.display()))?;
        given.push((path.file_stem().unwrap_or_default().to_string_lossy().into_owned(), refiner));
    }
    let shipped = if !args.no_neural { locap_nn::shipped::refiners(&Default::default())? } else { Vec::new() };
    let candidates = FillCandidates::new(args.neighbours, given, shipped);
    let fitting = candidates.fitting();
    let methods = candidates.for_takes(takes, &fitting);
    run(&methods)
}
