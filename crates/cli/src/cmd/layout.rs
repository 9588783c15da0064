//! `locap layout`: calibrate and fit marker layouts (issue 5; LocalMoCap section 4 places
//! markers on a driven body, and locap needs those placements from real captures).

use crate::inputs::{self, MotionOptions, read_motion, read_take};
use anyhow::{Context, Result};
use clap::{Parser, Subcommand, ValueEnum};
use locap_synth::Layout;
use locap_synth::calibrate::{CalibrationOptions, calibrate};
use locap_synth::fit::{DistanceFitOptions, fit_to_distances};
use locap_synth::synthesize::LabFrame;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap layout`.
#[derive(Parser, Debug)]
#[command(
    args_conflicts_with_subcommands = true,
    after_help = "Example (the 62-marker set of ../shared/data/labeling):\n  locap layout --from-opensim \
                  ../shared/data/labeling/Rajagopal2015_mod.osim ../shared/data/labeling/MarkerSet.xml -o rajagopal62.toml"
)]
pub struct Args {
    #[command(subcommand)]
    what: Option<What>,
    /// Build a layout and its skeleton (joints, offsets, joint limits; Y up, mm) from an
    /// OpenSim 4 model and, optionally, a separate marker set file (else the model's own).
    #[arg(long, num_args = 1..=2, value_names = ["MODEL", "MARKERS"], help_heading = "OpenSim")]
    from_opensim: Vec<PathBuf>,
    /// Layout to write with --from-opensim (TOML; JSON if the name ends in .json).
    #[arg(short, long, value_name = "FILE", requires = "from_opensim", help_heading = "Output")]
    output: Option<PathBuf>,
}

#[derive(Subcommand, Debug)]
enum What {
    /// Fit a layout's marker offsets by least squares to real labeled takes and the skeleton
    /// motion solved from them (same frames), and report per-marker residuals.
    Calibrate(CalibrateArgs),
    /// Fit a layout's offsets to a real take's marker distances when no skeleton motion
    /// exists: markers on the same joint get the real take's distances (bring your own
    /// marker set), and report the residual.
    Fit(FitArgs),
}

/// Arguments of `locap layout fit`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Example:\n  locap layout fit --layout my-markers.toml --take my-capture.c3d -o my-markers.fitted.toml"
)]
pub struct FitArgs {
    /// Layout to fit (TOML or JSON): joints and initial offsets.
    #[arg(long, value_name = "LAYOUT", help_heading = "Input")]
    layout: PathBuf,
    /// A real labeled take of the marker set (C3D or TRC).
    #[arg(long, value_name = "TAKE", help_heading = "Input")]
    take: PathBuf,
    /// Pull towards the initial offsets (per mm^2 of offset change, against mm^2 of distance
    /// error): fixes where each joint's group of markers sits, which distances cannot.
    #[arg(value_parser = crate::values::non_negative, long, default_value_t = 0.01, value_name = "LAMBDA", help_heading = "Fit")]
    prior_weight: f64,
    /// Fitted layout to write (TOML; JSON if the name ends in .json).
    #[arg(short, long, value_name = "FILE", help_heading = "Output")]
    output: PathBuf,
    /// Also write the per-pair report as JSON.
    #[arg(long, value_name = "FILE", help_heading = "Output")]
    report: Option<PathBuf>,
}

/// Arguments of `locap layout calibrate`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Example (the shipped CMU layout):\n  locap layout calibrate --layout crates/synth/layouts/cmu41-template.toml \\\n    \
                        --take ../shared/data/cmu-c3d/01_01.c3d --motion ../shared/data/cmu-asfamc/01/01_01.amc \\\n    \
                        --take ../shared/data/cmu-c3d/02_01.c3d --motion ../shared/data/cmu-asfamc/02/02_01.amc \\\n    \
                        -o crates/synth/layouts/cmu41.toml"
)]
pub struct CalibrateArgs {
    /// Layout to calibrate (TOML or JSON): marker names, joints and blends; offsets are fitted.
    #[arg(long, value_name = "LAYOUT", help_heading = "Input")]
    layout: PathBuf,
    /// Real labeled takes (C3D or TRC), one per --motion, in the same order.
    #[arg(long = "take", required = true, value_name = "TAKE", help_heading = "Input")]
    takes: Vec<PathBuf>,
    /// Skeleton motion (AMC or BVH) solved from each take, frame for frame.
    #[arg(long = "motion", required = true, value_name = "MOTION", help_heading = "Input")]
    motions: Vec<PathBuf>,
    /// ASF skeleton for AMC files (default: the only .asf next to each AMC).
    #[arg(long, value_name = "ASF", help_heading = "Input")]
    asf: Option<PathBuf>,
    /// Millimetres per BVH unit (CMU BVH: 25.4 / 0.45).
    #[arg(value_parser = crate::values::positive, long, default_value_t = 25.4 / 0.45, value_name = "MM", help_heading = "Input")]
    bvh_mm_per_unit: f64,
    /// How the takes' lab frame relates to the motion frame.
    #[arg(long, value_enum, default_value_t = Lab::ZUpFromYUp, help_heading = "Input")]
    lab: Lab,
    /// Try every joint for markers without a blend and keep the best.
    #[arg(long, help_heading = "Fit")]
    search_joints: bool,
    /// Calibrated layout to write (TOML; JSON if the name ends in .json).
    #[arg(short, long, value_name = "FILE", help_heading = "Output")]
    output: PathBuf,
    /// Also write the residual report as JSON.
    #[arg(long, value_name = "FILE", help_heading = "Output")]
    report: Option<PathBuf>,
}

/// Lab frames on the command line.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Lab {
    /// Z-up lab, Y-up motion (CMU): lab (X, Y, Z) = motion (z, x, y).
    ZUpFromYUp,
    /// The takes are in the motion's own frame.
    Motion,
}

impl From<Lab> for LabFrame {
    fn from(lab: Lab) -> LabFrame {
        match lab {
            Lab::ZUpFromYUp => LabFrame::ZUpFromYUp,
            Lab::Motion => LabFrame::Motion,
        }
    }
}

/// Runs `locap layout`.
pub fn run(args: Args) -> Result<ExitCode> {
    match args.what {
        Some(What::Calibrate(a)) => run_calibrate(a),
        Some(What::Fit(a)) => run_fit(a),
        None if !args.from_opensim.is_empty() => {
            let Some(output) = &args.output else {
                return Err(inputs::usage("--from-opensim needs -o FILE, the layout to write"));
            };
            run_from_opensim(&args.from_opensim, output)
        }
        None => Err(inputs::usage("give a subcommand (calibrate, fit) or --from-opensim MODEL [MARKERS] -o FILE")),
    }
}

/// Reads an OpenSim model (and marker set) into a layout with its skeleton.
pub fn read_opensim(model: &Path, markers: Option<&Path>) -> Result<Layout> {
    let given: Vec<&Path> = std::iter::once(model).chain(markers).collect();
    inputs::protect(&given)?;
    let read = |p: &Path| std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()));
    let model_text = read(model)?;
    let marker_text = markers.map(read).transpose()?;
    let (model_name, marker_name) = (model.display().to_string(), markers.map(|p| p.display().to_string()));
    let layout = locap_synth::opensim::layout_from_opensim(
        locap_synth::opensim::XmlSource { name: &model_name, text: &model_text },
        match (&marker_name, &marker_text) {
            (Some(name), Some(text)) => Some(locap_synth::opensim::XmlSource { name, text }),
            _ => None,
        },
    )?;
    Ok(layout)
}

fn run_from_opensim(paths: &[PathBuf], output: &Path) -> Result<ExitCode> {
    inputs::check_outputs(&[output.to_path_buf()])?;
    let layout = read_opensim(&paths[0], paths.get(1).map(PathBuf::as_path))?;
    write_layout(&layout, output)?;
    let joints = layout.skeleton.as_ref().map_or(0, |s| s.joints.len());
    let dofs: usize = layout.skeleton.iter().flat_map(|s| &s.joints).map(|j| j.dofs.as_ref().map_or(3, Vec::len)).sum();
    crate::emit(&format!(
        "{}: {} markers on {joints} bodies ({dofs} rotational degrees of freedom with limits), Y up, mm\n",
        output.display(),
        layout.markers.len()
    ))?;
    eprintln!("wrote {}", output.display());
    Ok(ExitCode::SUCCESS)
}

/// Reads a layout file (TOML, or JSON by extension).
pub fn read_layout(path: &Path) -> Result<Layout> {
    inputs::protect(&[path])?;
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read layout", path.display()))?;
    let layout =
        if inputs::has_extension(path, &["json"]) { Layout::from_json(&text) } else { Layout::from_toml(&text) };
    layout.with_context(|| format!("{}", path.display()))
}

/// Writes a layout (TOML, or JSON by extension) atomically.
pub fn write_layout(layout: &Layout, path: &Path) -> Result<()> {
    let text =
        if inputs::has_extension(path, &["json"]) { serde_json::to_string_pretty(layout)? } else { layout.to_toml() };
    locap_io::atomic::write_atomically(path, |w| Ok(w.write_all(text.as_bytes())?))?;
    Ok(())
}

fn run_calibrate(args: CalibrateArgs) -> Result<ExitCode> {
    if args.takes.len() != args.motions.len() {
        return Err(inputs::usage(format!(
            "give one --motion per --take ({} takes, {} motions)",
            args.takes.len(),
            args.motions.len()
        )));
    }
    let given = [&args.layout].into_iter().chain(&args.takes).chain(&args.motions).chain(&args.asf);
    inputs::protect(&given.map(PathBuf::as_path).collect::<Vec<_>>())?;
    inputs::check_outputs(&[Some(args.output.clone()), args.report.clone()].into_iter().flatten().collect::<Vec<_>>())?;
    let layout = read_layout(&args.layout)?;
    let options = MotionOptions { asf: args.asf.clone(), bvh_mm_per_unit: args.bvh_mm_per_unit, amc_rate_hz: 120.0 };
    let lab: LabFrame = args.lab.into();
    let mut pairs = Vec::new();
    for (t, m) in args.takes.iter().zip(&args.motions) {
        let take = lab.take_to_motion(&read_take(t)?);
        let motion = read_motion(m, &options)?;
        pairs.push((take, motion));
    }
    let refs: Vec<_> = pairs.iter().map(|(t, m)| (t, m)).collect();
    let cal = CalibrationOptions { search_joints: args.search_joints, ..Default::default() };
    let (mut fitted, report) = calibrate(&layout, &refs, &cal)?;
    let names: Vec<String> = args
        .takes
        .iter()
        .map(|t| t.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default())
        .collect();
    fitted.description = format!(
        "{}; offsets calibrated by least squares on {} (locap layout calibrate), RMS residual {:.1} mm",
        layout.description.trim_end_matches('.'),
        names.join(" + "),
        report.rms_mm()
    );
    write_layout(&fitted, &args.output)?;
    let mut table = format!("{:<8} {:<24} {:>10}", "marker", "joint (blend)", "rms mm");
    for n in &names {
        let _ = write!(table, " {n:>10}");
    }
    table.push('\n');
    for m in &report.markers {
        let joint = match &m.blend {
            Some((b, w)) => format!("{} ({b} {w:.2})", m.joint),
            None => m.joint.clone(),
        };
        let _ = write!(table, "{:<8} {:<24} {:>10.1}", m.name, joint, m.rms_mm);
        for r in &m.rms_mm_per_take {
            match r {
                Some(r) => {
                    let _ = write!(table, " {r:>10.1}");
                }
                None => {
                    let _ = write!(table, " {:>10}", "-");
                }
            }
        }
        table.push('\n');
    }
    let _ = writeln!(table, "all markers: RMS residual {:.1} mm", report.rms_mm());
    crate::emit(&table)?;
    if let Some(path) = &args.report {
        inputs::write_json(path, &report)?;
    }
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}

fn run_fit(args: FitArgs) -> Result<ExitCode> {
    inputs::protect(&[&args.layout, &args.take])?;
    inputs::check_outputs(&[Some(args.output.clone()), args.report.clone()].into_iter().flatten().collect::<Vec<_>>())?;
    let layout = read_layout(&args.layout)?;
    let take = read_take(&args.take)?;
    let options = DistanceFitOptions { prior_weight: args.prior_weight, ..Default::default() };
    let (mut fitted, report) = fit_to_distances(&layout, &take, &options)?;
    let name = args.take.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    fitted.description = format!(
        "{}; same-joint offsets fitted to the marker distances of {name} (locap layout fit), RMS distance error {:.1} mm",
        layout.description.trim_end_matches('.'),
        report.rms_after_mm()
    );
    write_layout(&fitted, &args.output)?;
    let mut table = format!(
        "{:<8} {:<8} {:<12} {:>9} {:>9} {:>9} {:>9}\n",
        "marker", "marker", "joint", "real mm", "real sd", "before", "after"
    );
    for p in &report.pairs {
        let _ = writeln!(
            table,
            "{:<8} {:<8} {:<12} {:>9.1} {:>9.1} {:>9.1} {:>9.1}",
            p.a, p.b, p.joint, p.real_mm, p.real_sd_mm, p.before_mm, p.after_mm
        );
    }
    let _ = writeln!(
        table,
        "{} pairs: RMS distance error {:.1} mm before, {:.1} mm after (real distances vary by {:.1} mm RMS)",
        report.pairs.len(),
        report.rms_before_mm(),
        report.rms_after_mm(),
        report.real_spread_mm()
    );
    if !report.unconstrained.is_empty() {
        let _ = writeln!(
            table,
            "not constrained by distances (alone on their joint, blended, or not in the take), kept: {}",
            report.unconstrained.join(" ")
        );
    }
    crate::emit(&table)?;
    if let Some(path) = &args.report {
        inputs::write_json(path, &report)?;
    }
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
