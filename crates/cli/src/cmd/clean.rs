//! `locap clean`: fill occlusion gaps and remove outliers (LocalMoCap section 3.1), one take
//! per job.
//!
//! Order of work for a take: swapped labels are detected and exchanged back, outliers are
//! detected and removed, every gap
//! (occlusions and removed outliers alike) is filled with the chosen method, then the
//! outlier windows are refilled with a cubic spline through the now-complete trajectory, as
//! the paper does (the library stage `locap_clean::clean_with`; this command finds files, picks
//! the filler and writes). Filled samples get residual 0 (the C3D convention for "not
//! measured") and are listed, frame ranges per marker, in the C3D parameters `LOCAP:FILLED`,
//! `LOCAP:OUTLIERS` and `LOCAP:SWAPS` (`locap_core::provenance`), so locap's viewer shows what
//! locap changed.

use crate::inputs;
use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use locap_clean::outliers::OutlierConfig;
use locap_clean::swaps::SwapConfig;
use locap_clean::{CleanConfig, Cleaned, FillConfig, FillMethod, neighbours::Selection};
use locap_nn::RefinerSource;
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
    #[arg(long, value_enum, default_value_t = Method::Auto, help_heading = "Filling")]
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
    /// The same PCA in a frame that turns with the gap's neighbourhood (locap's).
    PcaAligned,
    /// Rigid-body fill from 3 neighbours.
    Rigid,
    /// The rigid-body fill with the marker's position relative to its neighbours splined
    /// across the gap (locap's, for short gaps).
    RigidSpline,
    /// Distance-constrained smoothing: the steady distances to the neighbours held across
    /// the gap, markers missing together solved together (locap's).
    Distance,
    /// Pose matching: each missing sample from the frames where the marker's neighbours stood
    /// in the same shape (locap's).
    PoseMatch,
    /// Per gap, the method (or blend) that filled trial gaps of the same length best in this
    /// take; recorded per gap in LOCAP:FILLS.
    Auto,
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
            Method::PcaAligned => FillMethod::PcaAligned,
            Method::Rigid => FillMethod::Rigid,
            Method::RigidSpline => FillMethod::RigidSpline,
            Method::Distance => FillMethod::Distance,
            Method::PoseMatch => FillMethod::PoseMatch,
            Method::Auto => FillMethod::Auto,
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

/// Runs `locap clean`.
pub fn run(args: Args) -> Result<ExitCode> {
    let models = match args.method {
        Method::Neural if args.model.is_empty() => RefinerSource::Shipped,
        Method::Neural => {
            let mut given = Vec::new();
            for path in &args.model {
                inputs::protect(&[path])?;
                let bytes = std::fs::read(path).with_context(|| format!("{}", path.display()))?;
                // Checked once here, so a bad model is a usage error, not a failure of every take.
                locap_nn::Refiner::from_bytes(&bytes, &Default::default())
                    .with_context(|| format!("{}", path.display()))?;
                let name = path.file_name().unwrap_or_default().to_string_lossy().into_owned();
                given.push((name, bytes));
            }
            RefinerSource::Given(given)
        }
        _ if !args.model.is_empty() => return Err(inputs::usage("--model is only used with --method neural")),
        _ => RefinerSource::None,
    };
    let files = inputs::expand(&args.inputs, &["c3d"])?;
    let targets = inputs::targets(&args.inputs, &files, &args.output)?;
    let (done, failed) = crate::run_takes(&files, "cleaning", |i, input| {
        inputs::create_parent(&targets[i])?;
        clean_one(input, &targets[i], &args, &models)
    });
    let text: String = done.iter().map(|(path, cleaned)| format_summary(path, cleaned)).collect();
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

impl Args {
    /// The stage's settings from the flags.
    fn config(&self) -> CleanConfig {
        let on = self.outliers == Switch::On;
        CleanConfig {
            swaps: on.then(SwapConfig::default),
            outliers: on.then(|| OutlierConfig {
                body_threshold_m_s2: self.body_threshold,
                hand_threshold_m_s2: self.hand_threshold,
                ..OutlierConfig::default()
            }),
            fill: FillConfig {
                method: self.method.into(),
                neighbours: self.neighbours,
                selection: match self.ranking {
                    Ranking::Variance => Selection::Variance,
                    Ranking::Nearest => Selection::MeanDistance,
                },
            },
        }
    }
}

fn clean_one(input: &Path, output: &Path, args: &Args, models: &RefinerSource) -> Result<Cleaned> {
    let mut file = inputs::read_c3d(input)?;
    let raw = file.to_take().map_err(|e| e.in_file(input))?;
    let config = args.config();
    let filler = locap_nn::filler_for(&raw, config.fill, models)?;
    let cleaned = locap_clean::clean_with(&raw, &config, filler.as_ref())?;
    file.write_changed(cleaned.take(), Some(&cleaned.provenance()), input, output)?;
    Ok(cleaned)
}

fn format_summary(path: &Path, s: &Cleaned) -> String {
    use std::fmt::Write;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{}: {} gaps, {} samples filled, {} still missing; {} outliers ({} samples) removed and refilled; {} label swaps undone",
        path.display(),
        s.gap_count(),
        s.filled_samples(),
        s.still_missing(),
        s.outliers.len(),
        s.outlier_samples,
        s.swaps.len()
    );
    let by_method = s.fills_by_method();
    if !by_method.is_empty() {
        let parts: Vec<String> =
            by_method.iter().map(|(name, gaps, samples)| format!("{name} {gaps} gaps ({samples} samples)")).collect();
        let _ = writeln!(t, "  filled by: {}", parts.join(", "));
    }
    for m in &s.markers {
        if m.gaps > 0 || m.outliers > 0 || m.still_missing > 0 {
            let _ = writeln!(
                t,
                "  {:<24} gaps {:>4}  filled {:>6}  missing {:>6}  outliers {:>3}",
                m.label, m.gaps, m.filled_samples, m.still_missing, m.outliers
            );
        }
    }
    t
}
