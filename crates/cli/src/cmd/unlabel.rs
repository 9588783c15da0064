//! `locap unlabel`: labeling benchmark input from a labeled take (see
//! `locap_eval::unlabel`): per-frame shuffled `*N` points, ghosts, frame-rate reduction and
//! occlusions with real statistics. The truth goes beside the output as `OUT.truth.json`, so
//! `locap label --truth` can score a labeling.

use crate::cmd::bench::{Drop, GhostModeArg, gap_model_from, parse_ghosts};
use crate::inputs;
use anyhow::Result;
use clap::Parser;
use locap_eval::gap_model::GapModel;
use locap_eval::label_bench::GhostCount;
use locap_eval::unlabel::{UnlabelConfig, unlabel};
use locap_io::c3d;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap unlabel`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap unlabel take.c3d -o raw.c3d --ghosts M --fps 60 --seed 3\n  \
                        locap label raw.c3d --template take.c3d -o labeled.c3d --truth raw.truth.json")]
pub struct Args {
    /// Labeled C3D takes, or folders searched recursively.
    #[arg(required = true, value_name = "FILE")]
    inputs: Vec<PathBuf>,
    /// Output C3D file (one input) or folder; the truth goes beside each as `.truth.json`.
    #[arg(short, long, value_name = "PATH", help_heading = "Output")]
    output: PathBuf,
    /// Ghost points per frame: a number, or `M` for as many as the take has markers.
    #[arg(long, default_value = "0", value_name = "N", value_parser = parse_ghosts, help_heading = "Corruption")]
    ghosts: GhostCount,
    /// Where ghosts appear.
    #[arg(long, value_enum, default_value_t = GhostModeArg::Near, help_heading = "Corruption")]
    ghost_mode: GhostModeArg,
    /// Output frame rate (Hz); default: the take's own.
    #[arg(long, value_name = "HZ", value_parser = crate::values::rate_hz, help_heading = "Corruption")]
    fps: Option<f64>,
    /// Extra occlusions with real statistics, or none.
    #[arg(long, value_enum, default_value_t = Drop::None, help_heading = "Corruption")]
    drop: Drop,
    /// Occlusion statistics for `--drop real` (JSON or a take with real gaps); default: built in.
    #[arg(long, value_name = "FILE", help_heading = "Corruption")]
    gap_source: Option<PathBuf>,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1, help_heading = "Corruption")]
    seed: u64,
}

/// Runs `locap unlabel`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.inputs, &["c3d"])?;
    if let Some(source) = &args.gap_source {
        inputs::protect(&[source])?;
    }
    let targets = inputs::targets(&args.inputs, &files, &args.output)?;
    let truths: Vec<PathBuf> = targets.iter().map(|t| truth_path(t)).collect();
    inputs::check_outputs(&[targets.clone(), truths].concat())?;
    let ghosts = args.ghosts;
    let drop = match (args.drop, &args.gap_source) {
        (Drop::None, _) => None,
        (Drop::Real, None) => Some(GapModel::builtin()),
        (Drop::Real, Some(source)) => Some(gap_model_from(source)?),
    };
    let (done, failed) = crate::run_takes(&files, "unlabeling", |i, input| {
        inputs::create_parent(&targets[i])?;
        unlabel_one(input, &targets[i], &args, ghosts, &drop)
    });
    let text: String = done.iter().map(|(_, line)| line.clone()).collect();
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// `OUT.truth.json` beside `OUT.c3d`.
pub fn truth_path(output: &Path) -> PathBuf {
    output.with_extension("truth.json")
}

fn unlabel_one(
    input: &Path,
    output: &Path,
    args: &Args,
    ghosts: GhostCount,
    drop: &Option<GapModel>,
) -> Result<String> {
    let mut file = inputs::read_c3d(input)?;
    let take = file.to_take().map_err(|e| e.in_file(input))?;
    let markers = take.markers().iter().filter(|m| !m.is_unlabeled()).count();
    let config = UnlabelConfig {
        frame_rate_hz: args.fps,
        ghosts: match ghosts {
            GhostCount::Fixed(n) => n,
            GhostCount::PerMarker => markers,
        },
        ghost_mode: args.ghost_mode.into(),
        drop: drop.clone(),
        seed: args.seed,
    };
    let unlabeled = unlabel(&take, &config).map_err(|e| anyhow::anyhow!("{}: {e}", input.display()))?;
    let mut raw = unlabeled.to_take();
    raw.first_frame = take.first_frame;
    raw.up_axis = take.up_axis;
    // Same frames: keep everything else of the file (analog data, parameters). A new rate
    // changes the frame count, which analog data cannot follow: write points only.
    let same_frames = unlabeled.frames.frame_count() == take.frame_count();
    let out = if same_frames {
        file.set_take(&raw).map_err(|e| e.in_file(input))?;
        file
    } else {
        c3d::C3dFile::from_take(&raw)?
    };
    c3d::write_path(&out, output)?;
    let truth = serde_json::to_string(&unlabeled.truth_file())?;
    let truth_file = truth_path(output);
    locap_io::atomic::write_atomically(&truth_file, |w| Ok(w.write_all(truth.as_bytes())?))?;
    Ok(format!(
        "{}: {} frames at {} Hz, {} points ({} markers, {} ghosts per frame){}; truth in {}\n",
        output.display(),
        unlabeled.frames.frame_count(),
        unlabeled.frames.frame_rate_hz(),
        unlabeled.frames.point_count(),
        markers,
        config.ghosts,
        if same_frames { "" } else { ", analog data dropped (frame rate changed)" },
        truth_file.display()
    ))
}
