//! `locap view`: one self-contained HTML page per take that plays it in any browser.
//!
//! The page (built by `locap_view::page`) shows markers coloured by what locap did to each
//! sample, read from the `LOCAP:FILLED` / `LOCAP:OUTLIERS` parameters `locap clean` writes;
//! with `--motion` a solved skeleton on top, with `--compare` a second take (e.g. the ground
//! truth) and the distance to it per frame. No network is needed to open it.

use crate::inputs;
use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use locap_core::{LengthUnit, Provenance, Take, UpAxis};
use locap_io::{bvh, csv};
use locap_view::{SampleState, ViewInput};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap view`.
#[derive(Parser, Debug)]
#[command(after_help = "Examples:\n  locap view cleaned.c3d -o cleaned.html\n  \
                        locap view filled.c3d --compare truth.c3d --motion solved.bvh -o check.html\n  \
                        locap view takes/ -o pages/")]
pub struct Args {
    /// Takes (C3D, TRC or CSV), or folders searched recursively.
    #[arg(required = true, value_name = "FILE")]
    inputs: Vec<PathBuf>,
    /// Output HTML file (one input) or folder (several inputs or a folder).
    #[arg(short, long, value_name = "PATH", help_heading = "Output")]
    output: PathBuf,
    /// Solved skeleton motion (BVH) to draw over the markers; same frames as the take.
    #[arg(long, value_name = "BVH", help_heading = "Overlays")]
    motion: Option<PathBuf>,
    /// Length unit of the BVH file (BVH does not record it).
    #[arg(long, default_value = "cm", value_parser = crate::cmd::convert::parse_unit, value_name = "UNIT", help_heading = "Overlays")]
    bvh_unit: LengthUnit,
    /// Axes of the motion: `y` for Y-up in CMU's convention (a Z-up lab's (x, y, z) is
    /// (y, z, x): BVH converted from CMU's ASF/AMC), `tools` for the Y-up of animation tools
    /// that `locap solve` writes ((x, z, -y)), `z` for Z-up.
    #[arg(long, value_enum, default_value_t = MotionUp::Y, help_heading = "Overlays")]
    motion_up: MotionUp,
    /// A second take to overlay (e.g. ground truth); markers matched by name, same frames.
    #[arg(long, value_name = "TAKE", help_heading = "Overlays")]
    compare: Option<PathBuf>,
    /// Neighbour edges per marker (its most stable neighbours); 0 for none.
    #[arg(long, default_value_t = 2, value_name = "N", help_heading = "Overlays")]
    edges: usize,
}

/// Vertical axis on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Up {
    /// +Y up.
    Y,
    /// +Z up.
    Z,
}

/// Axes of a `--motion` file.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MotionUp {
    /// +Y up, CMU's convention (`locap_core::units::z_up_to_y_up`).
    Y,
    /// +Y up, the animation tools' convention (`locap_core::units::z_up_to_tools_y_up`).
    Tools,
    /// +Z up.
    Z,
}

impl From<Up> for UpAxis {
    fn from(up: Up) -> UpAxis {
        match up {
            Up::Y => UpAxis::Y,
            Up::Z => UpAxis::Z,
        }
    }
}

/// Runs `locap view`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.inputs, &["c3d", "trc", "csv"])?;
    let single = files.len() == 1 && args.inputs.len() == 1 && !args.inputs[0].is_dir() && !args.output.is_dir();
    if !single && (args.motion.is_some() || args.compare.is_some()) {
        return Err(inputs::usage(format!("--motion and --compare go with a single take ({} given)", files.len())));
    }
    let auxiliary = [args.motion.as_ref(), args.compare.as_ref()];
    inputs::protect(&auxiliary.iter().flatten().map(|p| p.as_path()).collect::<Vec<_>>())?;
    let targets =
        if single { vec![args.output.clone()] } else { inputs::output_paths(&files, &args.output, Some("html")) };
    inputs::check_outputs(&targets)?;
    if !single {
        std::fs::create_dir_all(&args.output)
            .with_context(|| format!("{}: cannot create output folder", args.output.display()))?;
    }
    let motion = match &args.motion {
        Some(path) => {
            let motion = bvh::read_bvh_path(path, args.bvh_unit)?;
            Some(match args.motion_up {
                // The viewer places Y-up data by CMU's convention: turn the tools' Y-up back
                // to the lab and into that one.
                MotionUp::Tools => locap_io::axes::motion_from_tools_y_up(
                    &motion,
                    locap_core::units::y_up_to_z_up_rotation(),
                    locap_core::UpAxis::Z,
                ),
                MotionUp::Y | MotionUp::Z => motion,
            })
        }
        None => None,
    };
    let compare = match &args.compare {
        Some(path) => {
            Some((read_take(path)?.0, path.file_name().map_or_else(String::new, |n| n.to_string_lossy().into())))
        }
        None => None,
    };
    let (done, failed) = crate::run_takes(&files, "writing pages", |i, input| {
        inputs::create_parent(&targets[i])?;
        let (take, states) = read_take(input)?;
        let up = match args.motion_up {
            MotionUp::Y | MotionUp::Tools => UpAxis::Y,
            MotionUp::Z => UpAxis::Z,
        };
        let edges = locap_clean::neighbours::stable_edges(&take, args.edges);
        let page = locap_view::render(&ViewInput {
            title: input.file_name().map_or_else(|| input.display().to_string(), |n| n.to_string_lossy().into()),
            take: &take,
            states: &states,
            motion: motion.as_ref().map(|m| (m, up)),
            compare: compare.as_ref().map(|(t, name)| (t, name.clone())),
            edges: &edges,
        })
        .with_context(|| format!("{}", input.display()))?;
        locap_io::atomic::write_atomically(&targets[i], |w| Ok(w.write_all(page.as_bytes())?))?;
        Ok(format!(
            "{} -> {} ({} frames, {} markers, {:.1} MB)\n",
            input.display(),
            targets[i].display(),
            take.frame_count(),
            take.marker_count(),
            page.len() as f64 / 1e6
        ))
    });
    crate::emit(&done.into_iter().map(|(_, line)| line).collect::<String>())?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// Reads a take and the state of its samples (from `LOCAP:FILLED` / `LOCAP:OUTLIERS` in a
/// C3D file that `locap clean` wrote; captured or missing otherwise).
pub(crate) fn read_take(path: &Path) -> Result<(Take, Vec<SampleState>)> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
    let (take, record) = match ext.as_str() {
        "trc" => (crate::inputs::read_trc(path)?, Provenance::default()),
        "csv" => (csv::read_csv_path(path)?, Provenance::default()),
        _ => {
            let file = crate::inputs::read_c3d(path)?;
            let take = file.to_take().map_err(|e| e.in_file(path))?;
            let record = file.provenance(&take).with_context(|| format!("{}", path.display()))?;
            (take, record)
        }
    };
    let states = locap_view::sample_states(&take, &record);
    Ok((take, states))
}
