//! `locap clean`: fill occlusion gaps and remove outliers (LocalMoCap section 3.1), one take
//! per job.
//!
//! Order of work for a take: swapped labels are detected and exchanged back, outliers are
//! detected and removed, every gap
//! (occlusions and removed outliers alike) is filled with the chosen method, then the
//! outlier windows are refilled with a cubic spline through the now-complete trajectory, as
//! the paper does. Filled samples get residual 0 (the C3D convention for "not measured") and
//! are listed, frame ranges per marker, in the C3D parameters `LOCAP:FILLED`,
//! `LOCAP:OUTLIERS` and `LOCAP:SWAPS` (compact text, `locap_core::range_list`), so locap's
//! viewer shows what locap changed.

use crate::inputs;
use anyhow::{Context, Result, bail};
use clap::{Parser, ValueEnum};
use locap_clean::outliers::{self, OutlierConfig};
use locap_clean::swaps::{self, SwapConfig};
use locap_clean::{FillConfig, FillMethod, neighbours::Selection};
use locap_core::Take;
use locap_io::c3d;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap clean`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Examples:\n  locap clean take.c3d -o take_clean.c3d\n  locap clean takes/ -o cleaned/ --method edm"
)]
pub struct Args {
    /// C3D takes, or folders searched recursively.
    #[arg(required = true, value_name = "FILE")]
    inputs: Vec<PathBuf>,
    /// Output C3D file (one input) or folder (several inputs or a folder).
    #[arg(short, long, value_name = "PATH", help_heading = "Output")]
    output: PathBuf,
    /// Gap-filling method.
    #[arg(long, value_enum, default_value_t = Method::Edm, help_heading = "Filling")]
    method: Method,
    /// Refiner models for `--method neural` (from `locap train fill`; a body model and hand
    /// models may be given together). Default: the refiners shipped with locap that fit the
    /// take (CMU/HDM05 41-marker body set; see `models/README.md`).
    #[arg(long, value_name = "MODEL", num_args = 1.., help_heading = "Filling")]
    model: Vec<PathBuf>,
    /// Neighbours used by EDM (the paper's K).
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_NEIGHBOURS)), long, default_value_t = 6, value_name = "K", help_heading = "Filling")]
    neighbours: usize,
    /// How neighbours are ranked.
    #[arg(long, value_enum, default_value_t = Ranking::Variance, help_heading = "Filling")]
    ranking: Ranking,
    /// Detect and repair outliers: swapped labels, acceleration spikes, stuck markers.
    #[arg(long, value_enum, default_value_t = Switch::On, help_heading = "Outliers")]
    outliers: Switch,
    /// Acceleration prominence that makes a body marker sample an outlier, m/s^2 at 120 Hz
    /// (scaled by (rate/120)^2 above, and at least 8 times the marker's noise).
    #[arg(value_parser = crate::values::positive, long, default_value_t = OutlierConfig::default().body_threshold_m_s2, value_name = "M_S2", help_heading = "Outliers")]
    body_threshold: f64,
    /// Acceleration prominence that makes a hand marker sample an outlier, m/s^2 at 120 Hz
    /// (scaled like the body threshold).
    #[arg(value_parser = crate::values::positive, long, default_value_t = OutlierConfig::default().hand_threshold_m_s2, value_name = "M_S2", help_heading = "Outliers")]
    hand_threshold: f64,
}

/// Gap-filling methods on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Method {
    /// Locality EDM fill (the paper's).
    Edm,
    /// Linear interpolation.
    Linear,
    /// Cubic spline.
    Spline,
    /// PCA over all markers (Gløersen & Federolf 2016).
    Pca,
    /// Rigid-body fill from 3 neighbours.
    Rigid,
    /// EDM refined by a learned network, shipped or `--model` (LocalMoCap section 3.1).
    Neural,
}

impl From<Method> for FillMethod {
    fn from(m: Method) -> FillMethod {
        match m {
            // The refiner starts from EDM's fill.
            Method::Neural => FillMethod::Edm,
            Method::Edm => FillMethod::Edm,
            Method::Linear => FillMethod::Linear,
            Method::Spline => FillMethod::Spline,
            Method::Pca => FillMethod::Pca,
            Method::Rigid => FillMethod::Rigid,
        }
    }
}

/// Neighbour ranking on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Ranking {
    /// Lowest variance of the distance (the paper's).
    Variance,
    /// Nearest on average.
    Nearest,
}

/// On or off.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Switch {
    /// Enabled.
    On,
    /// Disabled.
    Off,
}

/// What cleaning did to one take.
#[derive(Debug, Default)]
struct Summary {
    gaps: usize,
    filled_samples: usize,
    still_missing: usize,
    outliers: usize,
    outlier_samples: usize,
    swaps: usize,
    /// Per marker: (label, gaps, filled samples, still missing, outlier ranges).
    markers: Vec<(String, usize, usize, usize, usize)>,
}

/// Runs `locap clean`.
pub fn run(args: Args) -> Result<ExitCode> {
    let models = match args.method {
        Method::Neural if args.model.is_empty() => Models::Shipped,
        Method::Neural => {
            let mut given = Vec::new();
            for path in &args.model {
                inputs::protect(&[path])?;
                let bytes = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
                // Checked once here, so a bad model is a usage error, not a failure of every take.
                locap_nn::Refiner::from_bytes(&bytes, &Default::default())
                    .with_context(|| format!("{}", path.display()))?;
                given.push(bytes);
            }
            Models::Given(given)
        }
        _ if !args.model.is_empty() => return Err(inputs::usage("--model is only used with --method neural")),
        _ => Models::None,
    };
    let files = inputs::expand(&args.inputs, &["c3d"])?;
    let targets = inputs::targets(&args.inputs, &files, &args.output)?;
    let (done, failed) = crate::run_takes(&files, "cleaning", |i, input| {
        inputs::create_parent(&targets[i])?;
        clean_one(input, &targets[i], &args, &models)
    });
    let text: String = done.iter().map(|(path, summary)| format_summary(path, summary)).collect();
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// The refiners of `--method neural`.
enum Models {
    /// Not refining.
    None,
    /// The shipped ones that fit each take.
    Shipped,
    /// Model files given with `--model` (all must fit).
    Given(Vec<Vec<u8>>),
}

impl Models {
    /// The refiners for `take` (loaded per job: a burn module is not shared between threads).
    fn for_take(&self, take: &locap_core::Take) -> Result<Vec<locap_nn::Refiner>> {
        let device = Default::default();
        match self {
            Models::None => Ok(Vec::new()),
            Models::Given(files) => {
                files.iter().map(|b| locap_nn::Refiner::from_bytes(b, &device).map_err(Into::into)).collect()
            }
            Models::Shipped => {
                let fitting: Vec<locap_nn::Refiner> = locap_nn::shipped::refiners(&device)?
                    .into_iter()
                    .filter(|r| locap_nn::features::marker_order(take, &r.meta.markers).is_ok())
                    .collect();
                if fitting.is_empty() {
                    let names: Vec<&str> = locap_nn::shipped::REFINERS.iter().map(|s| s.name).collect();
                    bail!(
                        "no shipped refiner fits this take's markers (shipped: {}); train one with `locap train fill` \
                         and give it with --model, or use --method edm",
                        names.join(", ")
                    );
                }
                Ok(fitting)
            }
        }
    }
}

fn clean_one(input: &Path, output: &Path, args: &Args, models: &Models) -> Result<Summary> {
    let mut file = inputs::read_c3d(input)?;
    let mut raw = file.to_take().map_err(|e| e.in_file(input))?;
    let swapped = if args.outliers == Switch::On { swaps::detect(&raw, &SwapConfig::default()) } else { Vec::new() };
    swaps::unswap(&mut raw, &swapped);
    let config = OutlierConfig {
        body_threshold_m_s2: args.body_threshold,
        hand_threshold_m_s2: args.hand_threshold,
        ..OutlierConfig::default()
    };
    let found = if args.outliers == Switch::On { outliers::detect(&raw, &config) } else { Vec::new() };
    let mut holed = raw.clone();
    let removed = outliers::remove(&mut holed, &found);
    let fill = FillConfig {
        method: args.method.into(),
        neighbours: args.neighbours,
        selection: match args.ranking {
            Ranking::Variance => Selection::Variance,
            Ranking::Nearest => Selection::MeanDistance,
        },
    };
    let refiners = models.for_take(&holed)?;
    let mut filled = if refiners.is_empty() {
        locap_clean::fill_gaps(&holed, &fill)
    } else {
        locap_nn::refine_all(&holed, &refiners)?
    };
    locap_clean::refill_outliers(&mut filled, &found);
    let mut summary = summarize(&raw, &filled.take, &filled.filled, &removed, &found);
    summary.swaps = swapped.len();
    let labels: Vec<String> = raw.markers().iter().map(|m| m.full()).collect();
    file.set_take(&filled.take).map_err(|e| e.in_file(input))?;
    let filled_ranges = ranges(&filled.take, &filled.filled, &labels);
    let outlier_ranges: Vec<String> = found
        .iter()
        .map(|o| {
            format!(
                "{} {}-{} {:?}",
                labels[o.marker],
                raw.first_frame as usize + o.frames.start,
                raw.first_frame as usize + o.frames.end - 1,
                o.kind
            )
        })
        .collect();
    set_ranges(&mut file, "FILLED", &filled_ranges)?;
    set_ranges(&mut file, "OUTLIERS", &outlier_ranges)?;
    let swap_ranges: Vec<String> = swapped
        .iter()
        .map(|s| {
            let first = raw.first_frame as usize + s.frames.start;
            format!("{} {} {}-{}", labels[s.a], labels[s.b], first, raw.first_frame as usize + s.frames.end - 1)
        })
        .collect();
    set_ranges(&mut file, "SWAPS", &swap_ranges)?;
    let method = if refiners.is_empty() {
        format!("{:?} K={}", fill.method, fill.neighbours)
    } else {
        let names: Vec<String> = match models {
            Models::Given(_) => {
                args.model.iter().map(|p| p.file_name().unwrap_or_default().to_string_lossy().into_owned()).collect()
            }
            _ => refiners.iter().map(|r| format!("shipped {}", r.meta.frame.name)).collect(),
        };
        format!("Neural {} (EDM start)", names.join(" + "))
    };
    file.parameters.set_strings("LOCAP", "METHOD", &[method]);
    c3d::write_path(&file, output)?;
    Ok(summary)
}

/// Stores a range list as `LOCAP:<name>` in the compact form of `locap_core::range_list`:
/// about three characters a range, so tens of thousands of ranges fit the parameter section
/// (one string per line did not past ~6,000).
pub(crate) fn set_ranges(file: &mut c3d::C3dFile, name: &str, lines: &[String]) -> Result<()> {
    let strings = locap_core::range_list::encode(lines).with_context(|| format!("LOCAP:{name}"))?;
    file.parameters.set_continued_strings("LOCAP", name, &strings);
    Ok(())
}

/// `LABEL first-last` (C3D frame numbers) for every run of filled samples.
pub(crate) fn ranges(take: &Take, filled: &[bool], labels: &[String]) -> Vec<String> {
    let m = take.marker_count();
    let mut out = Vec::new();
    for (marker, label) in labels.iter().enumerate() {
        let mask = (0..take.frame_count()).map(|f| filled[f * m + marker]);
        for gap in locap_core::gaps::gaps_of(mask.map(|x| !x)) {
            let first = take.first_frame as usize + gap.start;
            out.push(format!("{label} {first}-{}", first + gap.len - 1));
        }
    }
    out
}

fn summarize(raw: &Take, result: &Take, filled: &[bool], removed: &[bool], found: &[outliers::Outlier]) -> Summary {
    let m = raw.marker_count();
    let mut s = Summary::default();
    let stats = locap_core::GapStatistics::of_take(raw);
    for (marker, name) in raw.markers().iter().enumerate() {
        let filled_here = (0..raw.frame_count()).filter(|f| filled[f * m + marker] && !removed[f * m + marker]).count();
        let missing = (0..raw.frame_count()).filter(|f| !result.is_valid(*f, marker)).count();
        let outs = found.iter().filter(|o| o.marker == marker).count();
        let gaps = stats.markers[marker].gap_count;
        s.gaps += gaps;
        s.filled_samples += filled_here;
        s.still_missing += missing;
        s.outliers += outs;
        s.markers.push((name.full(), gaps, filled_here, missing, outs));
    }
    s.outlier_samples = removed.iter().filter(|r| **r).count();
    s
}

fn format_summary(path: &Path, s: &Summary) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{}: {} gaps, {} samples filled, {} still missing; {} outliers ({} samples) removed and refilled; {} label swaps undone",
        path.display(),
        s.gaps,
        s.filled_samples,
        s.still_missing,
        s.outliers,
        s.outlier_samples,
        s.swaps
    );
    for (name, gaps, filled, missing, outs) in &s.markers {
        if *gaps > 0 || *outs > 0 || *missing > 0 {
            let _ = writeln!(
                t,
                "  {name:<24} gaps {gaps:>4}  filled {filled:>6}  missing {missing:>6}  outliers {outs:>3}"
            );
        }
    }
    t
}
