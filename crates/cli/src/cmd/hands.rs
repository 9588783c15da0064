//! `locap hands`: hand skeleton motion and the hand marker layout from an ART-Human hand
//! export (joint positions per finger), plus procedural finger motion within joint limits, so
//! `locap synth` can make hand training data (LocalMoCap section 4 uses GRAB hand motion; no
//! open finger-joint motion exists in locap's data). See the locap-synth `hand` module.

use crate::cmd::layout::write_layout;
use crate::inputs::{self, read_take};
use anyhow::{Context, Result};
use clap::Parser;
use locap_core::LengthUnit;
use locap_synth::hand::{FingerLimits, Side, fit_art_hand, hand_layout, procedural_fingers};
use rand::SeedableRng;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `locap hands`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap hands ../shared/data/hands -o hands/ --procedural 20\n  \
                        locap synth --motion hands/*-left*.bvh --layout hands/hand-left.toml --bvh-mm-per-unit 10 -o train-hands/")]
pub struct Args {
    /// ART-Human hand exports (C3D with xHAN and finger points such as xIFI), or folders.
    #[arg(required = true, value_name = "TAKE", help_heading = "Input")]
    takes: Vec<PathBuf>,
    /// Procedural finger takes to make per hand (on the captured wrist motion).
    #[arg(value_parser = crate::values::count(0, crate::values::max(locap_synth::hand::MAX_PROCEDURAL_TAKES)), long, default_value_t = 0, value_name = "N", help_heading = "Synthesis")]
    procedural: usize,
    /// Seed of the procedural motion.
    #[arg(long, default_value_t = 1, help_heading = "Synthesis")]
    seed: u64,
    /// Height of the layout's markers above the bones (back of the hand), mm.
    #[arg(value_parser = crate::values::positive_length_mm, long, default_value_t = 8.0, value_name = "MM", help_heading = "Synthesis")]
    dorsal_mm: f64,
    /// Output folder: `STEM-left.bvh` (fitted), `STEM-left-proc-NNN.bvh`, `hand-left.toml`, and
    /// the same for the right hand. BVH lengths are in centimetres.
    #[arg(short, long, value_name = "DIR", help_heading = "Output")]
    output: PathBuf,
}

/// Runs `locap hands`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.takes, &["c3d", "trc"])?;
    let stem_of =
        |path: &std::path::Path| path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut per_take = Vec::new();
    for path in &files {
        for name in ["left", "right"] {
            per_take.push(args.output.join(format!("{}-{name}.bvh", stem_of(path))));
            for k in 0..args.procedural {
                per_take.push(args.output.join(format!("{}-{name}-proc-{:03}.bvh", stem_of(path), k + 1)));
            }
        }
    }
    inputs::check_outputs(&per_take)?;
    // Every take fits the same hand model, so each rewrites the layouts: only inputs are checked.
    inputs::check_outputs(std::slice::from_ref(&args.output.join("hand-left.toml")))?;
    inputs::check_outputs(std::slice::from_ref(&args.output.join("hand-right.toml")))?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("{}: cannot create output folder", args.output.display()))?;
    let (done, failed) = crate::run_takes(&files, "fitting hands", |i, path| {
        let take = read_take(path)?;
        let stem = stem_of(path);
        let mut text = String::new();
        for side in [Side::Left, Side::Right] {
            let name = if side == Side::Left { "left" } else { "right" };
            let (motion, report) = match fit_art_hand(&take, side) {
                Ok(fit) => fit,
                Err(e) => {
                    let _ = writeln!(text, "{}: {name} hand skipped: {e}", path.display());
                    continue;
                }
            };
            locap_io::bvh::write_bvh_path(
                &motion,
                LengthUnit::Centimetre,
                &args.output.join(format!("{stem}-{name}.bvh")),
            )?;
            let layout = hand_layout(&motion.skeleton, side, args.dorsal_mm)?;
            write_layout(&layout, &args.output.join(format!("hand-{name}.toml")))?;
            let _ = writeln!(
                text,
                "{}: {name} hand, {} frames: joint positions refitted to {:.2} mm RMS (max {:.2} mm)",
                path.display(),
                report.frames,
                report.rms_mm,
                report.max_mm
            );
            for (joint, lo, hi) in &report.flexion_range_deg {
                let _ = writeln!(text, "    {joint:<10} flexion {lo:6.1} .. {hi:6.1} deg");
            }
            for k in 0..args.procedural {
                let seed = args.seed ^ ((i * 2 + usize::from(side == Side::Right)) as u64 * 1000 + k as u64 + 1);
                let mut rng = rand::rngs::StdRng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15));
                let proc = procedural_fingers(&motion, &FingerLimits::default(), &mut rng)?;
                let out = args.output.join(format!("{stem}-{name}-proc-{:03}.bvh", k + 1));
                locap_io::bvh::write_bvh_path(&proc, LengthUnit::Centimetre, &out)?;
            }
            if args.procedural > 0 {
                let _ = writeln!(text, "    wrote {} procedural {name}-hand takes", args.procedural);
            }
        }
        Ok(text)
    });
    let mut out = String::new();
    for (_, text) in &done {
        out.push_str(text);
    }
    let _ = writeln!(out, "wrote {}", args.output.display());
    crate::emit(&out)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}
