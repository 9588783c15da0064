//! `locap train fill`: trains the learned gap-fill refiner (LocalMoCap section 3.1, Eq. 3-4) on
//! the shards `locap synth` writes, on the CPU (locap-nn, burn's flex backend). One training run
//! is one job; it uses every core for its batches.
//!
//! Writes the model file (`--out`), its loss curve beside it (`OUT.loss.svg`) and checkpoints
//! (`OUT.checkpoints/`, every `--checkpoint-every` steps); `--resume` continues from them.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use locap_nn::harness::{Checkpoints, Schedule};
use locap_nn::refiner::{NetConfig, TrainConfig, train};
use locap_synth::gap_model::GapModel;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `locap train`.
#[derive(Parser, Debug)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand, Debug)]
enum What {
    /// The gap-fill refiner: EDM's fill corrected by a graph-convolution + biLSTM network.
    Fill(FillArgs),
    /// The motion solver: a heterogeneous marker/joint graph network (or a baseline).
    Solve(super::train_solve::SolveArgs),
}

/// Arguments of `locap train fill`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap synth --motion ../shared/data/cmu-asfamc/01 --format shard -o train/\n  \
                        locap train fill --data train/ --steps 2000 --out refiner.locapnn")]
pub struct FillArgs {
    /// Training takes: `.shard` files written by `locap synth` (synthetic) and labeled `.c3d`
    /// takes (real; their own gaps are not scored), or folders searched recursively for both.
    /// The first take's markers are the model's.
    #[arg(long, value_name = "PATH", num_args = 1.., required = true, help_heading = "Data")]
    data: Vec<PathBuf>,
    /// Occlusion statistics for the on-the-fly Eq. 6 corruption: JSON (`locap stats`) or takes
    /// with real gaps. Default: the built-in statistics.
    #[arg(long, value_name = "STATS", num_args = 1.., help_heading = "Data")]
    augment: Vec<PathBuf>,
    /// Overall occlusion probability of the corruption.
    #[arg(value_parser = crate::values::fraction, long, default_value_t = 0.1, value_name = "P", help_heading = "Data")]
    p_occ: f64,
    /// Fraction of every take held out for validation.
    #[arg(value_parser = crate::values::fraction, long, default_value_t = 0.1, value_name = "F", help_heading = "Data")]
    validation_fraction: f64,
    /// Training length in epochs (every frame seen once on average per epoch).
    #[arg(value_parser = crate::values::count(1, 1 << 20), long, value_name = "N", conflicts_with = "steps", help_heading = "Training")]
    epochs: Option<usize>,
    /// Training length in steps (default 2000).
    #[arg(value_parser = crate::values::count(1, 1 << 30), long, value_name = "N", help_heading = "Training")]
    steps: Option<usize>,
    /// Windows per step.
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_BATCH_WINDOWS)), long, default_value_t = TrainConfig::default().batch, value_name = "N", help_heading = "Training")]
    batch: usize,
    /// Peak learning rate (Adam; linear warm-up, cosine decay to a tenth).
    #[arg(value_parser = crate::values::positive, long, default_value_t = TrainConfig::default().schedule.learning_rate, value_name = "LR", help_heading = "Training")]
    lr: f64,
    /// Seed of every random draw (initial weights, windows, corruption).
    #[arg(long, default_value_t = 1, value_name = "S", help_heading = "Training")]
    seed: u64,
    /// Steps between validations.
    #[arg(value_parser = crate::values::count(1, 1 << 30), long, default_value_t = TrainConfig::default().validate_every, value_name = "N", help_heading = "Training")]
    validate_every: usize,
    /// Steps between checkpoints.
    #[arg(value_parser = crate::values::count(1, 1 << 30), long, default_value_t = TrainConfig::default().checkpoint_every, value_name = "N", help_heading = "Training")]
    checkpoint_every: usize,
    /// Continue from the checkpoints of an earlier run with the same output.
    #[arg(long, help_heading = "Training")]
    resume: bool,
    /// The fill the network corrects: `edm` (the paper) or `linear` (the paper's "w/o EDM
    /// initial value" ablation).
    #[arg(long, default_value = "edm", value_parser = ["edm", "linear"], help_heading = "Network")]
    init: String,
    /// Feed each marker's position centred on a pooled training mean instead of on the take's
    /// own mean (the first-phase behaviour; worse on subjects unlike the training ones).
    #[arg(long, help_heading = "Network")]
    pooled_centre: bool,
    /// Offsets fade in over this many frames from a gap's captured borders, so filled samples
    /// join the captured ones without a step (0: no fade).
    #[arg(value_parser = crate::values::count(0, 1 << 20), long, default_value_t = TrainConfig::default().taper_frames, value_name = "FRAMES", help_heading = "Network")]
    taper: usize,
    /// The fade the model applies at inference, if not `--taper` (a network trained with a
    /// short fade may fill better with a longer one; with `--resume` on a finished run this
    /// rewrites the model without training).
    #[arg(value_parser = crate::values::count(0, 1 << 20), long, value_name = "FRAMES", help_heading = "Network")]
    inference_taper: Option<usize>,
    /// Frames per window.
    #[arg(value_parser = crate::values::count(2, crate::values::max(locap_nn::limits::MAX_WINDOW)), long, default_value_t = TrainConfig::default().window, value_name = "FRAMES", help_heading = "Network")]
    window: usize,
    /// Graph-convolution features per marker.
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_CHANNELS)), long, default_value_t = TrainConfig::default().net.channels, value_name = "N", help_heading = "Network")]
    channels: usize,
    /// LSTM hidden size per direction.
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_HIDDEN)), long, default_value_t = TrainConfig::default().net.hidden, value_name = "N", help_heading = "Network")]
    hidden: usize,
    /// The model file to write.
    #[arg(long, default_value = "refiner.locapnn", value_name = "MODEL", help_heading = "Output")]
    out: PathBuf,
}

/// Runs `locap train`.
pub fn run(args: Args) -> Result<ExitCode> {
    match args.what {
        What::Fill(a) => fill(a),
        What::Solve(a) => super::train_solve::run(a),
    }
}

fn fill(args: FillArgs) -> Result<ExitCode> {
    if args.out.is_dir() {
        return Err(crate::inputs::usage(format!(
            "--out {} is a folder; give the model file to write",
            args.out.display()
        )));
    }
    // Only to protect the training files and refuse an output among them before any work.
    crate::inputs::expand(&args.data, &["shard", "c3d"])?;
    crate::inputs::check_outputs(&[args.out.clone(), crate::inputs::with_suffix(&args.out, ".loss.svg")])?;
    let data = crate::training::fill_data(&args.data)?;
    let frame = locap_nn::features::frame_for(&data.markers).with_context(|| {
        format!(
            "no local frame is defined for these markers (the CMU waist LFWT/RFWT/LBWT/RBWT, the paper's \
             wrists xIWR/xOWR/xIHAND/xOHAND or the CMU wrists xWRA/xWRB/xFIN); markers: {}",
            data.markers.join(" ")
        )
    })?;
    let gap_model =
        if args.augment.is_empty() { GapModel::builtin() } else { crate::cmd::synth::read_model(&args.augment, 999)? };
    let defaults = TrainConfig::default();
    let mut config = TrainConfig {
        batch: args.batch,
        schedule: Schedule { learning_rate: args.lr, ..defaults.schedule },
        seed: args.seed,
        validate_every: args.validate_every,
        checkpoint_every: args.checkpoint_every,
        validation_fraction: args.validation_fraction,
        window: args.window,
        net: NetConfig { channels: args.channels, hidden: args.hidden, ..defaults.net },
        frame,
        per_take_centre: !args.pooled_centre,
        taper_frames: args.taper,
        inference_taper_frames: args.inference_taper,
        init: if args.init == "linear" { locap_clean::FillMethod::Linear } else { locap_clean::FillMethod::Edm },
        augment: locap_synth::augment::AugmentConfig { missing_fraction: Some(args.p_occ), ..defaults.augment.clone() },
        ..defaults
    };
    config.schedule.steps = match (args.epochs, args.steps) {
        (Some(e), _) => e * data.steps_per_epoch(&config),
        (None, Some(s)) => s,
        (None, None) => config.schedule.steps,
    };
    eprintln!(
        "training on {} takes, {} frames, {} markers ({} frame): {} steps of {} x {} frames",
        data.takes.len(),
        data.frames(),
        data.markers.len(),
        config.frame.name,
        config.schedule.steps,
        config.batch,
        config.window
    );
    let bar = indicatif::ProgressBar::new(config.schedule.steps as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} ({eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let mut validation = String::new();
    let store = crate::training::FolderCheckpointer::new(crate::inputs::with_suffix(&args.out, ".checkpoints"))?;
    let checkpoints = Checkpoints { store: &store, resume: args.resume };
    let (refiner, report) = train(&data, &config, &gap_model, Some(checkpoints), &mut |p| {
        if let Some(v) = p.validation {
            validation = format!(", validation {v:.2} mm");
        }
        bar.set_position(p.step as u64);
        bar.set_message(format!("loss {:.2} mm{validation}", p.loss));
    })?;
    bar.finish_and_clear();
    let bytes = refiner.to_bytes()?;
    crate::inputs::create_parent(&args.out)?;
    crate::inputs::write_bytes(&args.out, &bytes)?;
    let curve_path = crate::inputs::with_suffix(&args.out, ".loss.svg");
    crate::training::write_loss_curve(report.loss_curve(), "locap train fill", &curve_path)?;
    let last = |v: &[(usize, f64)]| v.last().map(|x| format!("{:.2} mm", x.1)).unwrap_or_else(|| "-".into());
    crate::emit(&format!(
        "{}: {} weights ({:.1} MB), {} steps ({:.3} s/step); training loss {}, validation {} (EDM alone {}); loss curve {}\n",
        args.out.display(),
        report.parameters,
        bytes.len() as f64 / 1e6,
        report.steps,
        report.step_seconds / report.steps_this_run.max(1) as f64,
        last(&report.training_mm),
        last(&report.validation_mm),
        report.edm_validation_mm.map(|v| format!("{v:.2} mm")).unwrap_or_else(|| "-".into()),
        curve_path.display()
    ))?;
    Ok(ExitCode::SUCCESS)
}
