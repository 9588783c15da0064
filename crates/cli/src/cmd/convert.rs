//! `locap convert`: between formats, chosen from the file extensions.
//!
//! Marker formats (C3D, TRC, CSV) convert into each other, with `--up` turning them to another
//! vertical axis; skeleton motion (BVH, ASF/AMC) converts to BVH, glTF / GLB, FBX and OpenSim
//! `.mot` (`locap_io::export`). C3D to C3D keeps every parameter and the analog data (see
//! `locap_io::c3d`), which together with `--frames` cuts a take without losing anything.

use crate::inputs;
use anyhow::{Context, Result, bail};
use clap::Parser;
use locap_core::{LengthUnit, Take, UpAxis};
use locap_io::{asf_amc, axes, bvh, c3d, csv, export, trc};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap convert`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Examples:\n  locap convert take.c3d take.trc\n  locap convert take.c3d opensim.trc --up y --trc-unit m --trc-missing nan\n  \
                        locap convert take.c3d cut.c3d --frames 0..1200\n  \
                        locap convert 01_01.amc 01_01.bvh --asf 01.asf\n  locap convert solved.bvh solved.glb\n  \
                        locap convert takes/ out/ --to trc\n\n\
                  Axes and units of what is written:\n  \
                  C3D, TRC, CSV: the input's axes (C3D labs are Z-up) unless --up; mm (TRC: --trc-unit)\n  \
                  BVH: Y-up as read, lengths in --bvh-unit (cm by default); angles in degrees\n  \
                  glTF / GLB: Y-up, metres (the glTF 2.0 convention)\n  \
                  FBX: Y-up, centimetres (GlobalSettings UpAxis 1, UnitScaleFactor 1); angles in degrees\n  \
                  MOT (OpenSim): Y-up, root translation in metres, joint angles in degrees (inDegrees=yes)\n\
                  --up y turns a Z-up lab's (x, y, z) into (x, z, -y): upright in OpenSim, Blender and Maya."
)]
pub struct Args {
    /// Input file(s) or folder(s), then the output: a file for one input, a folder (with --to) for several.
    #[arg(required = true, num_args = 2.., value_name = "PATH")]
    paths: Vec<PathBuf>,
    /// Output format for batch conversion into a folder: c3d, trc or csv for markers; bvh,
    /// gltf, glb, fbx or mot for skeleton motion.
    #[arg(long, value_name = "EXT", value_parser = ["c3d", "trc", "csv", "bvh", "gltf", "glb", "fbx", "mot"], help_heading = "Output")]
    to: Option<String>,
    /// Vertical axis of the markers written (C3D, TRC, CSV): `y` turns a Z-up lab's (x, y, z)
    /// into (x, z, -y), as OpenSim expects. Default: the input's own axes.
    #[arg(long, value_enum, value_name = "AXIS", help_heading = "Output")]
    up: Option<crate::cmd::view::Up>,
    /// Keep only these frames, as 0-based indices `START..END` (END excluded).
    #[arg(long, value_name = "START..END", value_parser = parse_range, help_heading = "Input")]
    frames: Option<std::ops::Range<usize>>,
    /// ASF skeleton for AMC input.
    #[arg(long, value_name = "FILE", help_heading = "Input")]
    asf: Option<PathBuf>,
    /// Frame rate of AMC input (AMC files do not record it; CMU captures are 120 Hz).
    #[arg(value_parser = crate::values::rate_hz, long, default_value_t = 120.0, value_name = "HZ", help_heading = "Input")]
    amc_rate: f64,
    /// Length unit of BVH files read or written (BVH does not record it; MotionBuilder expects
    /// cm, Blender imports 1 unit as 1 m, so use m or import cm with scale 0.01).
    #[arg(long, default_value = "cm", value_parser = parse_unit, value_name = "UNIT", help_heading = "Input")]
    bvh_unit: LengthUnit,
    /// How TRC files write a missing sample: `empty` fields (Motion Analysis) or `nan`
    /// (OpenSim 4.6 refuses rows that end in empty fields).
    #[arg(long, value_enum, default_value_t = TrcMissing::Empty, value_name = "AS", help_heading = "Output")]
    trc_missing: TrcMissing,
    /// Length unit of TRC files written.
    #[arg(long, default_value = "mm", value_parser = parse_unit, value_name = "UNIT", help_heading = "Output")]
    trc_unit: LengthUnit,
}

/// `--trc-missing` on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum TrcMissing {
    /// Three empty fields.
    Empty,
    /// `NaN` three times.
    Nan,
}

fn parse_range(text: &str) -> Result<std::ops::Range<usize>, String> {
    let (a, b) = text.split_once("..").ok_or("expected START..END, e.g. 0..1200")?;
    let a: usize = a.trim().parse().map_err(|_| format!("bad start {a:?}"))?;
    let b: usize = b.trim().parse().map_err(|_| format!("bad end {b:?}"))?;
    if a >= b {
        return Err(format!("empty range {a}..{b}"));
    }
    Ok(a..b)
}

pub(crate) fn parse_unit(text: &str) -> Result<LengthUnit, String> {
    LengthUnit::parse(text).ok_or_else(|| format!("unknown length unit {text:?} (mm, cm, m, in)"))
}

/// Runs `locap convert`.
pub fn run(args: Args) -> Result<ExitCode> {
    let (output, inputs) = args.paths.split_last().ok_or_else(|| inputs::usage("need an input and an output"))?;
    if let Some(asf) = &args.asf {
        inputs::protect(&[asf])?;
    }
    let single = inputs.len() == 1 && !inputs[0].is_dir() && !output.is_dir() && args.to.is_none();
    if single {
        inputs::protect(&[&inputs[0]])?;
        inputs::check_outputs(std::slice::from_ref(output))?;
        convert(&inputs[0], output, &args)?;
        eprintln!("wrote {}", output.display());
        return Ok(ExitCode::SUCCESS);
    }
    let ext = args
        .to
        .as_deref()
        .ok_or_else(|| inputs::usage("converting several files needs --to EXT (see --help) and an output folder"))?;
    let files = inputs::expand(inputs, &["c3d", "trc", "csv", "bvh", "amc"])?;
    let targets = inputs::output_paths(&files, output, Some(ext));
    inputs::check_outputs(&targets)?;
    std::fs::create_dir_all(output).with_context(|| format!("{}: cannot create output folder", output.display()))?;
    let (_, failed) = crate::run_takes(&files, "converting", |i, input| {
        inputs::create_parent(&targets[i])?;
        convert(input, &targets[i], &args)
    });
    eprintln!("converted {} of {} files into {}", files.len() - failed, files.len(), output.display());
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// What a file holds.
enum Content {
    /// A C3D file, kept whole so C3D output loses nothing.
    C3d(Box<c3d::C3dFile>),
    Markers(Take),
    Motion(locap_core::Motion),
}

fn convert(input: &Path, output: &Path, args: &Args) -> Result<()> {
    let content = match extension(input).as_str() {
        "c3d" => Content::C3d(Box::new(inputs::read_c3d(input)?)),
        "trc" => Content::Markers(inputs::read_trc(input)?),
        "csv" => Content::Markers(csv::read_csv_path(input)?),
        "bvh" => Content::Motion(bvh::read_bvh_path(input, args.bvh_unit)?),
        "amc" => {
            let asf_path = args.asf.as_ref().context("AMC input needs its skeleton: --asf FILE.asf")?;
            let asf = asf_amc::read_asf_path(asf_path)?;
            Content::Motion(asf_amc::read_amc_path(input, &asf, args.amc_rate)?)
        }
        other => bail!("{}: unknown input format {other:?} (c3d, trc, csv, bvh, amc)", input.display()),
    };
    let content = match (content, &args.frames) {
        (Content::C3d(mut file), Some(range)) => {
            file.cut_frames(range.clone()).map_err(|e| e.in_file(input))?;
            Content::C3d(file)
        }
        (Content::Markers(take), Some(range)) => {
            if range.end > take.frame_count() {
                bail!("{}: --frames {range:?} is outside the take's {} frames", input.display(), take.frame_count());
            }
            Content::Markers(take.slice_frames(range.clone()))
        }
        (Content::Motion(_), Some(_)) => bail!("--frames is not supported for skeleton motion yet"),
        (content, None) => content,
    };
    let out_ext = extension(output);
    match (content, out_ext.as_str()) {
        (Content::C3d(mut file), "c3d") => {
            if let Some(up) = args.up {
                axes::set_c3d_up_axis(&mut file, up.into()).map_err(|e| e.in_file(input))?;
            }
            c3d::write_path(&file, output)?
        }
        (Content::C3d(file), _) => {
            let take = file.to_take().map_err(|e| e.in_file(input))?;
            write_markers(&take, output, args)?
        }
        (Content::Markers(take), _) => write_markers(&take, output, args)?,
        (Content::Motion(_), _) if args.up.is_some() => {
            bail!("--up turns markers; skeleton motion is written Y-up as it is read")
        }
        (Content::Motion(motion), ext) if export::MOTION_EXTENSIONS.contains(&ext) => {
            let choices = export::MotionOutput { bvh_unit: args.bvh_unit, markers: None };
            export::write_motion_path(&motion, &choices, output)?
        }
        (Content::Motion(_), other) => bail!(
            "{}: skeleton motion is written as {}, not {other:?}",
            input.display(),
            export::MOTION_EXTENSIONS.join(", ")
        ),
    }
    Ok(())
}

fn write_markers(take: &Take, output: &Path, args: &Args) -> Result<()> {
    let turned;
    let take = match args.up {
        Some(up) if UpAxis::from(up) != take.up_axis => {
            turned = axes::take_with_up_axis(take, up.into());
            &turned
        }
        _ => take,
    };
    match extension(output).as_str() {
        "c3d" => c3d::write_path(&c3d::C3dFile::from_take(take)?, output)?,
        "trc" => {
            let missing = match args.trc_missing {
                TrcMissing::Empty => trc::Missing::Empty,
                TrcMissing::Nan => trc::Missing::NaN,
            };
            trc::write_trc_path_with(take, args.trc_unit, missing, output)?
        }
        "csv" => csv::write_csv_path(take, output)?,
        ext if export::MOTION_EXTENSIONS.contains(&ext) => bail!(
            "{}: markers cannot be written as {}: that needs a skeleton solver (locap solve)",
            output.display(),
            ext.to_ascii_uppercase()
        ),
        other => {
            bail!("{}: unknown output format {other:?} (c3d, trc, csv; bvh, gltf, glb, fbx, mot)", output.display())
        }
    }
    Ok(())
}
