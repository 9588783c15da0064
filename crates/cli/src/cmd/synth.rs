//! `locap synth`: training data from skeleton motion (LocalMoCap sections 3.3 and 4): clean
//! markers from a layout on each motion with a random subject, corrupted with real occlusion
//! statistics (Eq. 6) and shifts, written as C3D + BVH pairs and/or training shards.

use crate::cmd::layout::{Lab, read_layout};
use crate::cmd::stats::{bin_label, binned};
use crate::inputs::{self, MotionOptions, read_motion, read_take};
use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use locap_core::gaps::add_histogram;
use locap_core::{GapStatistics, LengthUnit};
use locap_synth::Layout;
use locap_synth::augment::{AugmentConfig, OcclusionMode, Rounding, augment, ks_statistic};
use locap_synth::gap_model::GapModel;
use locap_synth::synthesize::{LabFrame, SynthConfig, Variation, mirror_motion, synthesize};
use rand::SeedableRng;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap synth`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap stats ../shared/data/numediart-c3d -o stats.json\n  \
                        locap synth --motion ../shared/data/cmu-asfamc/01 --augment stats.json --p-occ 0.05 -o train/")]
pub struct Args {
    /// Skeleton motion: BVH or AMC files, or folders of them.
    #[arg(long = "motion", required = true, num_args = 1.., value_name = "MOTION", help_heading = "Input")]
    motions: Vec<PathBuf>,
    /// Marker layout (TOML or JSON). Default: the built-in CMU 41-marker layout.
    #[arg(long, value_name = "LAYOUT", help_heading = "Input")]
    layout: Option<PathBuf>,
    /// ASF skeleton for AMC files (default: the only .asf next to each AMC).
    #[arg(long, value_name = "ASF", help_heading = "Input")]
    asf: Option<PathBuf>,
    /// Millimetres per BVH unit (CMU BVH: 25.4 / 0.45).
    #[arg(value_parser = crate::values::positive, long, default_value_t = 25.4 / 0.45, value_name = "MM", help_heading = "Input")]
    bvh_mm_per_unit: f64,
    /// Frame rate of AMC files, Hz.
    #[arg(value_parser = crate::values::rate_hz, long, default_value_t = 120.0, value_name = "HZ", help_heading = "Input")]
    amc_rate: f64,
    /// Real occlusion statistics to corrupt with: JSON (`locap stats`, or the LocalMoCap
    /// paper's) or takes with real gaps. Without it, only clean markers are written.
    #[arg(long, value_name = "STATS", num_args = 1.., help_heading = "Augmentation")]
    augment: Vec<PathBuf>,
    /// Occlusion generator: Eq. 6, or per-frame random drops (Holden 2018).
    #[arg(long, value_enum, default_value_t = Mode::Eq6, help_heading = "Augmentation")]
    mode: Mode,
    /// Overall occlusion probability p_occ (default: the statistics' own).
    #[arg(value_parser = crate::values::fraction, long, value_name = "P", help_heading = "Augmentation")]
    p_occ: Option<f64>,
    /// Use the paper's floor for Eq. 6 gap counts instead of unbiased stochastic rounding.
    #[arg(long, help_heading = "Augmentation")]
    floor: bool,
    /// Longest gap generated, frames.
    #[arg(value_parser = crate::values::count(1, 1 << 24), long, default_value_t = 999, value_name = "FRAMES", help_heading = "Augmentation")]
    max_gap: usize,
    /// Probability that a visible sample is shifted.
    #[arg(value_parser = crate::values::fraction, long, default_value_t = 0.005, value_name = "P", help_heading = "Augmentation")]
    p_shift: f64,
    /// Largest shift per axis, mm (offsets are U(-sigma, sigma)).
    #[arg(value_parser = crate::values::length_mm, long, default_value_t = 50.0, value_name = "MM", help_heading = "Augmentation")]
    shift_sigma_mm: f64,
    /// Output frame rate, Hz (default: the motion's).
    #[arg(value_parser = crate::values::rate_hz, long, value_name = "HZ", help_heading = "Synthesis")]
    rate: Option<f64>,
    /// Seed: the same seed and inputs give the same files.
    #[arg(long, default_value_t = 1, help_heading = "Synthesis")]
    seed: u64,
    /// No subject variation (markers exactly at the layout's offsets).
    #[arg(long, help_heading = "Synthesis", conflicts_with_all = ["bone_scale", "bone_scale_sd", "offset_jitter_mm", "bone_tilt_deg", "posture_deg"])]
    no_variation: bool,
    /// Range of the global bone-length scale of the random subjects (default 0.92 1.08).
    #[arg(long, num_args = 2, value_names = ["MIN", "MAX"], value_parser = crate::values::positive, help_heading = "Synthesis")]
    bone_scale: Option<Vec<f64>>,
    /// Standard deviation of the extra per-bone length scale (default 0.02).
    #[arg(long, value_name = "SD", value_parser = crate::values::non_negative, help_heading = "Synthesis")]
    bone_scale_sd: Option<f64>,
    /// Standard deviation of the per-take marker placement jitter, mm per axis (default 4).
    #[arg(long, value_name = "MM", value_parser = crate::values::length_mm, help_heading = "Synthesis")]
    offset_jitter_mm: Option<f64>,
    /// Standard deviation of the per-bone tilt of the rest offsets, degrees per axis (default 0).
    #[arg(long, value_name = "DEG", value_parser = crate::values::non_negative, help_heading = "Synthesis")]
    bone_tilt_deg: Option<f64>,
    /// Standard deviation of the per-take held posture of the `--posture-joints`, degrees per
    /// axis (one turn for the whole take, none about the bone itself; default 0).
    #[arg(long, value_name = "DEG", value_parser = crate::values::non_negative, requires = "posture_joints", help_heading = "Synthesis")]
    posture_deg: Option<f64>,
    /// Joints whose held posture varies per take, comma-separated (e.g. `lhand,rhand`).
    #[arg(long, value_name = "JOINTS", value_delimiter = ',', requires = "posture_deg", help_heading = "Synthesis")]
    posture_joints: Vec<String>,
    /// Mirror every motion left to right (across the motion frame's x = 0 plane, the lateral
    /// axis of CMU's ASF and BVH skeletons; left and right joints exchanged) before synthesis.
    #[arg(long, help_heading = "Synthesis")]
    mirror: bool,
    /// How the motion frame maps to the lab frame of the C3D output.
    #[arg(long, value_enum, default_value_t = Lab::ZUpFromYUp, help_heading = "Synthesis")]
    lab: Lab,
    /// Output folder (mirrors the input folders).
    #[arg(short, long, value_name = "DIR", help_heading = "Output")]
    output: PathBuf,
    /// What to write per take: `c3d` (`NAME.clean.c3d`, `NAME.c3d` corrupted, both in the lab
    /// frame; `NAME.bvh`, the subject-scaled motion in its own frame, in centimetres, locap's
    /// default BVH unit),
    /// `shard` (`NAME.shard`, see the locap-synth `shard` docs), or both.
    #[arg(long, value_enum, default_value_t = Format::Both, help_heading = "Output")]
    format: Format,
}

/// Occlusion modes on the command line.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Mode {
    /// LocalMoCap Eq. 6.
    Eq6,
    /// Holden 2018 per-frame random drops.
    PerFrame,
}

/// Output formats.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Format {
    /// C3D markers + BVH motion.
    C3d,
    /// Training shard.
    Shard,
    /// Both.
    Both,
}

/// What one take contributed to the summary.
#[derive(Debug, Default, Serialize)]
struct TakeSummary {
    frames: usize,
    markers: usize,
    hidden: usize,
    shifted: usize,
    dropped_gaps: usize,
    histogram: Vec<usize>,
    per_frame_histogram: Vec<usize>,
}

/// The run summary (`DIR/summary.json`).
#[derive(Debug, Serialize)]
struct Summary {
    takes: usize,
    failed: usize,
    frames: usize,
    markers: usize,
    seed: u64,
    occlusion_rate: f64,
    shift_rate: f64,
    dropped_gaps: usize,
    generated_gap_length_histogram: Vec<usize>,
    real_gap_length_histogram: Vec<usize>,
    per_frame_gap_length_histogram: Vec<usize>,
    ks_generated_vs_real: Option<f64>,
    ks_per_frame_vs_real: Option<f64>,
    seconds: f64,
    frames_per_second: f64,
}

pub(crate) fn read_model(sources: &[PathBuf], max_gap: usize) -> Result<GapModel> {
    let mut stats = Vec::new();
    let mut models = Vec::new();
    for source in sources {
        if inputs::has_extension(source, &["json"]) {
            inputs::protect(&[source])?;
            let text = std::fs::read_to_string(source).with_context(|| format!("{}", source.display()))?;
            models.push(GapModel::from_json(&text).with_context(|| format!("{}", source.display()))?);
        } else {
            for take in inputs::expand(std::slice::from_ref(source), &["c3d", "trc"])? {
                stats.push(GapStatistics::of_take(&read_take(&take)?));
            }
        }
    }
    let mut model = if stats.is_empty() {
        models.pop().context("no gap statistics")?
    } else {
        GapModel::from_statistics(&stats).context("the --augment takes have no gaps to learn from")?
    };
    for m in &models {
        model.merge(m);
    }
    model.max_gap_frames = max_gap.min(model.length_histogram.len().saturating_sub(1)).max(1);
    Ok(model)
}

/// The subject variation the flags ask for: the defaults with each given range replaced.
fn variation(args: &Args) -> Variation {
    if args.no_variation {
        return Variation::none();
    }
    let d = Variation::default();
    Variation {
        bone_scale_range: args.bone_scale.as_deref().map_or(d.bone_scale_range, |r| [r[0], r[1]]),
        bone_scale_sd: args.bone_scale_sd.unwrap_or(d.bone_scale_sd),
        offset_jitter_mm: args.offset_jitter_mm.unwrap_or(d.offset_jitter_mm),
        bone_tilt_sd_deg: args.bone_tilt_deg.unwrap_or(d.bone_tilt_sd_deg),
        posture_sd_deg: args.posture_deg.unwrap_or(d.posture_sd_deg),
        posture_joints: args.posture_joints.clone(),
        ..d
    }
}

/// Runs `locap synth`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.motions, &["bvh", "amc"])?;
    let auxiliary = [args.layout.as_ref(), args.asf.as_ref()];
    inputs::protect(&auxiliary.iter().flatten().map(|p| p.as_path()).collect::<Vec<_>>())?;
    let layout = match &args.layout {
        Some(path) => read_layout(path)?,
        None => Layout::cmu41(),
    };
    let model = if args.augment.is_empty() { None } else { Some(read_model(&args.augment, args.max_gap)?) };
    let lab: LabFrame = args.lab.into();
    let synth_config = SynthConfig { variation: variation(&args), rate_hz: args.rate, lab };
    // Bad ranges are usage errors, before any take is read.
    synth_config.validate().map_err(|e| inputs::usage(e.to_string()))?;
    let augment_config = AugmentConfig {
        mode: match args.mode {
            Mode::Eq6 => OcclusionMode::Eq6,
            Mode::PerFrame => OcclusionMode::PerFrame,
        },
        missing_fraction: args.p_occ,
        rounding: if args.floor { Rounding::Floor } else { Rounding::Stochastic },
        shift_probability: args.p_shift,
        shift_sigma_mm: args.shift_sigma_mm,
    };
    if let Some(p) = args.p_occ
        && !(0.0..0.95).contains(&p)
    {
        return Err(inputs::usage(format!("--p-occ {p} is out of range (0 to 0.95)")));
    }
    let options =
        MotionOptions { asf: args.asf.clone(), bvh_mm_per_unit: args.bvh_mm_per_unit, amc_rate_hz: args.amc_rate };
    let targets = inputs::output_paths(&files, &args.output, None);
    let written: Vec<PathBuf> = targets.iter().flat_map(|t| output_names(t, args.format)).collect();
    inputs::check_outputs(&[written, vec![args.output.join("summary.json")]].concat())?;
    let started = std::time::Instant::now();
    let (done, failed) = crate::run_takes(&files, "synthesizing", |i, path| {
        // One independent stream per take, so results do not depend on scheduling.
        let seed = args.seed ^ (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut motion = read_motion(path, &options)?;
        if args.mirror {
            motion = mirror_motion(&motion, 0)?;
        }
        let synth = synthesize(&motion, &layout, &synth_config, &mut rng)?;
        let mut summary =
            TakeSummary { frames: synth.take.frame_count(), markers: synth.take.marker_count(), ..Default::default() };
        let observed = match &model {
            Some(model) => {
                let a = augment(&synth.take, model, &augment_config, &mut rng)?;
                summary.hidden = a.take.validity().iter().filter(|v| !**v).count();
                summary.shifted = a.shifted.iter().filter(|s| **s).count();
                summary.dropped_gaps = a.dropped_gaps;
                summary.histogram = a.gap_length_histogram();
                // The comparison mode on the same clean take, for the summary only.
                let per_frame =
                    AugmentConfig { mode: OcclusionMode::PerFrame, shift_probability: 0.0, ..augment_config.clone() };
                summary.per_frame_histogram = augment(&synth.take, model, &per_frame, &mut rng)?.gap_length_histogram();
                a.take
            }
            None => synth.take.clone(),
        };
        write_outputs(&targets[i], &synth.take, &observed, &synth.motion, lab, args.format)?;
        Ok(summary)
    });
    let seconds = started.elapsed().as_secs_f64();
    let mut total = TakeSummary::default();
    for (_, s) in &done {
        total.frames += s.frames;
        total.markers = total.markers.max(s.markers);
        total.hidden += s.hidden;
        total.shifted += s.shifted;
        total.dropped_gaps += s.dropped_gaps;
        add_histogram(&mut total.histogram, &s.histogram);
        add_histogram(&mut total.per_frame_histogram, &s.per_frame_histogram);
    }
    let samples = done.iter().map(|(_, s)| s.frames * s.markers).sum::<usize>().max(1) as f64;
    // The real histogram up to the longest length a take could hold.
    let longest = done.iter().map(|(_, s)| s.frames).max().unwrap_or(0);
    let real: Vec<usize> = model
        .as_ref()
        .map(|m| m.length_histogram.iter().take(m.max_gap_frames.min(longest) + 1).copied().collect())
        .unwrap_or_default();
    let summary = Summary {
        takes: done.len(),
        failed,
        frames: total.frames,
        markers: total.markers,
        seed: args.seed,
        occlusion_rate: total.hidden as f64 / samples,
        shift_rate: total.shifted as f64 / samples,
        dropped_gaps: total.dropped_gaps,
        ks_generated_vs_real: model.as_ref().map(|_| ks_statistic(&total.histogram, &real)),
        ks_per_frame_vs_real: model.as_ref().map(|_| ks_statistic(&total.per_frame_histogram, &real)),
        generated_gap_length_histogram: total.histogram,
        per_frame_gap_length_histogram: total.per_frame_histogram,
        real_gap_length_histogram: real,
        seconds,
        frames_per_second: total.frames as f64 / seconds.max(1e-9),
    };
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create folder", args.output.display()))?;
    inputs::write_json(&args.output.join("summary.json"), &summary)?;
    crate::emit(&summary_table(&summary, model.is_some(), args.mode))?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn summary_table(s: &Summary, augmented: bool, mode: Mode) -> String {
    let mut out = format!(
        "{} takes, {} frames, {} markers in {:.2} s ({:.0} frames/s)\n",
        s.takes, s.frames, s.markers, s.seconds, s.frames_per_second
    );
    if !augmented {
        out.push_str("clean markers only (no --augment)\n");
        return out;
    }
    let _ = writeln!(
        out,
        "occlusion rate {:.2}%, shifted {:.2}% of samples, {} gaps found no room",
        100.0 * s.occlusion_rate,
        100.0 * s.shift_rate,
        s.dropped_gaps
    );
    let name = match mode {
        Mode::Eq6 => "generated (Eq. 6)",
        Mode::PerFrame => "generated (per-frame)",
    };
    let _ = writeln!(out, "gap length   {name:>22} {:>12} {:>12}", "per-frame", "real");
    let (g, p, r) = (
        binned(&s.generated_gap_length_histogram),
        binned(&s.per_frame_gap_length_histogram),
        binned(&s.real_gap_length_histogram),
    );
    for b in 0..g.len() {
        let _ = writeln!(
            out,
            "  {:>8}   {:>21.1}% {:>11.1}% {:>11.1}%",
            bin_label(b),
            100.0 * g[b],
            100.0 * p[b],
            100.0 * r[b]
        );
    }
    let _ = writeln!(
        out,
        "KS statistic vs real: generated {:.3}, per-frame random {:.3}",
        s.ks_generated_vs_real.unwrap_or(f64::NAN),
        s.ks_per_frame_vs_real.unwrap_or(f64::NAN)
    );
    out
}

/// What one motion gives: the clean and the observed markers, the motion, the shard.
const SUFFIXES: [&str; 4] = [".clean.c3d", ".c3d", ".bvh", ".shard"];

/// `target`'s stem with `suffix` (`walk.bvh` -> `walk.clean.c3d`).
fn with_suffix(target: &Path, suffix: &str) -> PathBuf {
    let stem = target.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    target.with_file_name(format!("{stem}{suffix}"))
}

/// Every file [`write_outputs`] writes for `target` in `format`.
fn output_names(target: &Path, format: Format) -> Vec<PathBuf> {
    let suffixes = match format {
        Format::C3d => &SUFFIXES[..3],
        Format::Shard => &SUFFIXES[3..],
        Format::Both => &SUFFIXES[..],
    };
    suffixes.iter().map(|s| with_suffix(target, s)).collect()
}

fn write_outputs(
    target: &Path,
    clean: &locap_core::Take,
    observed: &locap_core::Take,
    motion: &locap_core::Motion,
    lab: LabFrame,
    format: Format,
) -> Result<()> {
    inputs::create_parent(target)?;
    let with = |suffix: &str| with_suffix(target, suffix);
    if matches!(format, Format::C3d | Format::Both) {
        locap_io::c3d::write_path(&locap_io::c3d::C3dFile::from_take(clean)?, &with(SUFFIXES[0]))?;
        locap_io::c3d::write_path(&locap_io::c3d::C3dFile::from_take(observed)?, &with(SUFFIXES[1]))?;
        locap_io::bvh::write_bvh_path(motion, LengthUnit::Centimetre, &with(SUFFIXES[2]))?;
    }
    if matches!(format, Format::Shard | Format::Both) {
        locap_io::atomic::write_atomically(&with(SUFFIXES[3]), |w| {
            locap_synth::shard::write_shard(w, clean, observed, Some(motion), lab)
                .map_err(|e| locap_io::Error::from(std::io::Error::other(e)))
        })?;
    }
    Ok(())
}
