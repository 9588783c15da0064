//! `locap train solve`: trains a motion solver (LocalMoCap section 3.2, Eq. 4-5) on the shards
//! `locap synth` writes (they carry the skeleton), on the CPU, with the refiner's machinery:
//! Adam, warm-up and cosine learning rate, validation on held-out frames, checkpoints and
//! `--resume`, loss curve beside the model (`OUT.loss.svg`).
//!
//! `--arch` picks the network: the heterogeneous graph network (`graph`), its ablation without
//! marker convolutions (`no-marker-conv`) or Holden (2018)'s residual MLP (`mlp`), all with the
//! same data, loss and budget so `locap eval` compares like with like.

use anyhow::Result;
use clap::{Parser, ValueEnum};
use locap_clean::local_frame::FrameDefinition;
use locap_nn::harness::{Checkpoints, Schedule};
use locap_nn::solver::{NetConfig, SolverTrainConfig, Variant, train_solver};
use std::path::PathBuf;
use std::process::ExitCode;

/// Networks on the command line.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Arch {
    /// Heterogeneous marker/joint graph network (the paper's solver).
    Graph,
    /// The graph network without marker-graph convolutions (ablation).
    NoMarkerConv,
    /// Holden (2018)'s per-frame residual MLP (baseline).
    Mlp,
}

impl From<Arch> for Variant {
    fn from(a: Arch) -> Variant {
        match a {
            Arch::Graph => Variant::Graph,
            Arch::NoMarkerConv => Variant::NoMarkerConv,
            Arch::Mlp => Variant::Mlp,
        }
    }
}

/// Local frames on the command line.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Frame {
    /// The waist of the CMU 41-marker set (body solvers).
    Waist,
    /// The left wrist of the paper's hand set (`LIWR`, `LOWR`, `LIHAND`, `LOHAND`).
    LeftWrist,
    /// The right wrist of the paper's hand set.
    RightWrist,
}

/// Arguments of `locap train solve`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap synth --motion ../shared/data/cmu-asfamc/01 --augment \
                        ../shared/data/gap-stats/real-gap-statistics.json --format shard -o train/\n  \
                        locap train solve --data train/ --steps 3000 --out solver.locapsv")]
pub struct SolveArgs {
    /// Folder of `.shard` files written by `locap synth` with motion (or one shard).
    #[arg(long, value_name = "DIR", help_heading = "Data")]
    data: PathBuf,
    /// Fraction of every take held out for validation.
    #[arg(value_parser = crate::values::fraction, long, default_value_t = 0.1, value_name = "F", help_heading = "Data")]
    validation_fraction: f64,
    /// Network.
    #[arg(long, value_enum, default_value_t = Arch::Graph, help_heading = "Network")]
    arch: Arch,
    /// Local frame the markers are expressed in (LocalMoCap section 3.1).
    #[arg(long, value_enum, default_value_t = Frame::Waist, help_heading = "Network")]
    frame: Frame,
    /// Mean marker-joint distance that links a marker to a joint, mm (about 40 for hands).
    #[arg(value_parser = crate::values::positive_length_mm, long, default_value_t = SolverTrainConfig::default().net.link_threshold_mm, value_name = "MM", help_heading = "Network")]
    link_mm: f64,
    /// Features per marker and joint node.
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_CHANNELS)), long, default_value_t = SolverTrainConfig::default().net.channels, value_name = "N", help_heading = "Network")]
    channels: usize,
    /// Features of the global node (the MLP is 4 times as wide).
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_GLOBAL)), long, default_value_t = SolverTrainConfig::default().net.global, value_name = "N", help_heading = "Network")]
    global: usize,
    /// Training steps.
    #[arg(value_parser = crate::values::count(1, 1 << 30), long, default_value_t = SolverTrainConfig::default().schedule.steps, value_name = "N", help_heading = "Training")]
    steps: usize,
    /// Frames per step.
    #[arg(value_parser = crate::values::count(1, crate::values::max(locap_nn::limits::MAX_BATCH_FRAMES)), long, default_value_t = SolverTrainConfig::default().batch, value_name = "N", help_heading = "Training")]
    batch: usize,
    /// Peak learning rate (Adam; linear warm-up, cosine decay to a tenth).
    #[arg(value_parser = crate::values::positive, long, default_value_t = SolverTrainConfig::default().schedule.learning_rate, value_name = "LR", help_heading = "Training")]
    lr: f64,
    /// Seed of every random draw.
    #[arg(long, default_value_t = 1, value_name = "S", help_heading = "Training")]
    seed: u64,
    /// Steps between validations.
    #[arg(long, default_value_t = SolverTrainConfig::default().validate_every, value_name = "N", help_heading = "Training")]
    validate_every: usize,
    /// Steps between checkpoints.
    #[arg(long, default_value_t = SolverTrainConfig::default().checkpoint_every, value_name = "N", help_heading = "Training")]
    checkpoint_every: usize,
    /// Continue from the checkpoints of an earlier run with the same output.
    #[arg(long, help_heading = "Training")]
    resume: bool,
    /// The model file to write.
    #[arg(long, default_value = "solver.locapsv", value_name = "MODEL", help_heading = "Output")]
    out: PathBuf,
}

/// Runs `locap train solve`.
pub fn run(args: SolveArgs) -> Result<ExitCode> {
    if args.out.is_dir() {
        return Err(crate::inputs::usage(format!(
            "--out {} is a folder; give the model file to write",
            args.out.display()
        )));
    }
    // Only to protect the training files and refuse an output among them before any work.
    crate::inputs::expand(std::slice::from_ref(&args.data), &["shard"])?;
    crate::inputs::check_outputs(&[args.out.clone(), crate::inputs::with_suffix(&args.out, ".loss.svg")])?;
    let data = crate::training::solver_data(&args.data)?;
    let defaults = SolverTrainConfig::default();
    let config = SolverTrainConfig {
        variant: args.arch.into(),
        batch: args.batch,
        schedule: Schedule { steps: args.steps, learning_rate: args.lr, ..defaults.schedule },
        seed: args.seed,
        validate_every: args.validate_every,
        checkpoint_every: args.checkpoint_every,
        validation_fraction: args.validation_fraction,
        net: NetConfig {
            channels: args.channels,
            global: args.global,
            link_threshold_mm: args.link_mm,
            ..defaults.net
        },
        frame: match args.frame {
            Frame::Waist => FrameDefinition::cmu_waist(),
            Frame::LeftWrist => FrameDefinition::paper_wrist('L'),
            Frame::RightWrist => FrameDefinition::paper_wrist('R'),
        },
        ..defaults
    };
    eprintln!(
        "training the {} solver on {} takes, {} frames, {} markers, {} joints: {} steps of {} frames",
        config.variant.name(),
        data.shards.len(),
        data.frames(),
        data.markers.len(),
        data.skeleton.len(),
        config.schedule.steps,
        config.batch
    );
    let bar = crate::progress(config.schedule.steps.max(2), "training");
    let mut validation = String::new();
    let store = crate::training::FolderCheckpointer::new(crate::inputs::with_suffix(&args.out, ".checkpoints"))?;
    let checkpoints = Checkpoints { store: &store, resume: args.resume };
    let (solver, report) = train_solver(&data, &config, Some(checkpoints), &mut |p| {
        if let Some(v) = p.validation {
            validation = format!(", validation JPE {:.1} mm, JOE {:.2} deg", v.jpe_mm, v.joe_deg);
        }
        bar.set_position(p.step as u64);
        bar.set_message(format!("loss {:.3}{validation}", p.loss));
    })?;
    bar.finish_and_clear();
    let bytes = solver.to_bytes()?;
    crate::inputs::create_parent(&args.out)?;
    crate::inputs::write_bytes(&args.out, &bytes)?;
    let curve_path = crate::inputs::with_suffix(&args.out, ".loss.svg");
    crate::training::write_loss_curve(report.loss_curve(), "locap train solve", &curve_path)?;
    let last = |v: &[(usize, f64)], unit: &str| v.last().map(|x| format!("{:.2} {unit}", x.1)).unwrap_or("-".into());
    crate::emit(&format!(
        "{}: {} solver, {} weights ({:.1} MB), {} steps ({:.3} s/step, {:.0} s); validation JPE {}, JOE {} (per-frame offsets); loss curve {}\n",
        args.out.display(),
        config.variant.name(),
        report.parameters,
        bytes.len() as f64 / 1e6,
        report.steps,
        report.step_seconds / report.steps_this_run.max(1) as f64,
        report.step_seconds,
        last(&report.validation_jpe_mm, "mm"),
        last(&report.validation_joe_deg, "deg"),
        curve_path.display()
    ))?;
    Ok(ExitCode::SUCCESS)
}
