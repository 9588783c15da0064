//! `locap solve`: the whole LocalMoCap pipeline on raw labeled takes (sections 3.1-3.2):
//! swapped labels and outliers repaired, gaps filled (`--fill`, as `locap clean --method`: by
//! default per gap with the method that filled trial gaps of its length best,
//! `locap_clean::auto`; the learned refiner only with `--fill neural` or `--refiner`, since on held-out takes it
//! filled worse than the per-gap choice, `docs/benchmarks.md`), then the motion
//! solver turns every frame into joint rotations and the root position, with bone lengths fitted to the subject (offsets averaged over the take). Writes
//! the motion at the take's own frame rate with exactly its frame count as BVH, glTF / GLB,
//! FBX or OpenSim `.mot` (by the output's extension, `locap_io::export`), in the Y-up frame of
//! the animation tools (`locap_io::axes`: a Z-up lab's `(x, y, z)` is `(x, z, -y)`), so
//! Blender, MotionBuilder and OpenSim show the character upright where its markers were, facing
//! the way they face. BVH lengths are in `--bvh-unit` (centimetres by default).
//!
//! `--method ik` solves with the kinematic solver instead (`locap_nn::kinematic`: the labeler's
//! IK after a subject calibration on the take, no training), for any marker set with a layout:
//! `--layout` (with a skeleton section, e.g. from `locap layout --from-opensim`, or with
//! `--skeleton`), by default the CMU 41-marker layout on the shipped solver's skeleton, or on
//! the subject's own CMU skeleton (`--skeleton SUBJECT.asf` alone).
//! `--method refine` runs the network, then the kinematic solver pulled towards the network's
//! joint rotations (`KinematicSolver::refine`): the network's prior where the markers say
//! little, the markers' fit where they see. The default `--method auto` refines wherever the
//! network's markers are all in the take and solves with the kinematic solver alone elsewhere,
//! saying so (`locap_nn::method`: the rule and why; `--method network` is the network alone).
//! A kinematic solve or refinement reports its marker residual, and every solve its tracking
//! checks of issue 17: the largest joint rotation between consecutive frames, the frame pairs over 20
//! degrees, and the wrist joints' samples within 60 mm of their wrist markers' mean
//! (`locap_eval::solver::wrists_within`), which needs no reference motion.
//!
//! Without `--model`, the solver shipped with locap is used (`locap_nn::shipped::solver`: the
//! three body networks of `models/`, the CMU 41-marker set on the CMU ASF skeleton, as one
//! ensemble, built into the binary); `--model` given more than once makes an ensemble of the
//! files. The cleaning is `locap_clean::clean_with` with its defaults, and `--markers-out`
//! keeps the input file's parameters and analog data and records the cleaning in the `LOCAP`
//! group, as `locap clean` does.

use crate::cmd::clean::Method as FillArg;
use crate::inputs;
use anyhow::{Context, Result};
use clap::{Parser, ValueEnum};
use locap_clean::FillConfig;
use locap_core::{LengthUnit, UpAxis};
use locap_eval::solver::{rotation_jumps, wrists_within};
use locap_io::{axes, export};
use locap_nn::kinematic::KinematicSolver;
use locap_nn::method::{SolveMethod, TakeSolve};
use locap_nn::solver::Solver;
use locap_nn::{Refiner, RefinerSource};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap solve`.
#[derive(Parser, Debug)]
#[command(after_help = "Examples:\n  locap solve ../shared/data/cmu-c3d/85_02.c3d -o out.bvh\n  \
                        locap solve take.c3d -o take.glb --with-markers\n  \
                        locap solve takes/ -o solved/ --to fbx --markers-out cleaned/\n\n\
                  Axes and units: every motion is Y-up, a Z-up lab's (x, y, z) written as (x, z, -y)\n  \
                  (Blender, MotionBuilder, Maya and OpenSim show it upright where the markers were).\n  \
                  BVH: lengths in --bvh-unit (cm by default; Blender: import with scale 0.01), degrees\n  \
                  glTF / GLB: metres, quaternions\n  \
                  FBX: centimetres (UnitScaleFactor 1), degrees\n  \
                  MOT: root translation in metres, joint angles in degrees\n  \
                  --markers-out C3D: the input's axes (Z-up) unless --up y, millimetres")]
pub struct Args {
    /// Labeled C3D or TRC takes, or folders searched recursively.
    #[arg(required = true, value_name = "FILE")]
    inputs: Vec<PathBuf>,
    /// Output file (one input): .bvh, .gltf, .glb, .fbx or .mot; or a folder (several inputs or
    /// a folder), with --to.
    #[arg(short, long, value_name = "PATH", help_heading = "Output")]
    output: PathBuf,
    /// Format of the files written into an output folder.
    #[arg(long, value_name = "EXT", default_value = "bvh", value_parser = ["bvh", "gltf", "glb", "fbx", "mot"], help_heading = "Output")]
    to: String,
    /// Length unit of BVH output (BVH cannot record it; MotionBuilder expects cm).
    #[arg(long, default_value = "cm", value_parser = crate::cmd::convert::parse_unit, value_name = "UNIT", help_heading = "Output")]
    bvh_unit: LengthUnit,
    /// Add the cleaned markers to glTF / GLB output as animated nodes.
    #[arg(long, help_heading = "Output")]
    with_markers: bool,
    /// Vertical axis of the --markers-out C3D: `y` turns a Z-up lab's (x, y, z) into (x, z, -y).
    /// Default: the input's.
    #[arg(long, value_enum, value_name = "AXIS", help_heading = "Output")]
    up: Option<crate::cmd::view::Up>,
    /// Also write the cleaned markers as C3D: a file (one input) or a folder.
    #[arg(long, value_name = "PATH", help_heading = "Output")]
    markers_out: Option<PathBuf>,
    /// Solver model (from `locap train solve`); given more than once, an ensemble whose
    /// answers are averaged per frame and joint (models of one marker set and skeleton).
    /// Default: the built-in CMU 41-marker solver.
    #[arg(long, value_name = "MODEL", help_heading = "Models")]
    model: Vec<PathBuf>,
    /// Gap-filling method, as `locap clean --method`. `neural` refines EDM with the shipped
    /// refiners that fit the take's markers (or `--refiner`).
    #[arg(long, value_enum, default_value_t = FillArg::Auto, value_name = "METHOD", help_heading = "Filling")]
    fill: FillArg,
    /// Gap-fill refiner model (from `locap train fill`) to refine EDM's fill with (implies
    /// `--fill neural`).
    #[arg(long, value_name = "MODEL", help_heading = "Models")]
    refiner: Option<PathBuf>,
    /// No refiner: what `solve` does by default now (kept so older scripts still run).
    #[arg(long, hide = true, conflicts_with = "refiner")]
    no_refiner: bool,
    /// How to solve: `network` (the solver model), `ik` (the kinematic solver: a layout and a
    /// skeleton, no training), `refine` (the network's answer refined by the kinematic
    /// solver: the network's joint rotations pull, the markers place), `auto`: `refine` where
    /// the network's markers are all in the take, else `ik` (`network` is 30 times faster,
    /// and its wrists leave their markers: docs/benchmarks.md).
    #[arg(long, value_enum, default_value_t = Method::Auto, help_heading = "Solver")]
    method: Method,
    /// Layout for the kinematic solver (TOML or JSON) with a skeleton section (e.g. from
    /// `locap layout --from-opensim`) or with --skeleton. Default: the CMU 41-marker layout
    /// on the shipped solver's skeleton.
    #[arg(long, value_name = "LAYOUT", help_heading = "Solver")]
    layout: Option<PathBuf>,
    /// Skeleton (ASF or BVH, Y up, in its rest pose) for a --layout without a skeleton
    /// section; without --layout, the subject's own CMU skeleton (e.g. the subject's ASF): the
    /// CMU layout's bones take its lengths and directions, joint by joint.
    #[arg(long, value_name = "FILE", help_heading = "Solver")]
    skeleton: Option<PathBuf>,
    /// The CMU kinematic solver (no --layout) keeps the template's forearm lengths instead of
    /// calibrating and holding each wrist within 45 mm of the mean of its two wrist markers.
    #[arg(long, conflicts_with = "layout", help_heading = "Solver")]
    no_wrist_centres: bool,
}

/// Solving methods on the command line.
#[derive(Debug, Clone, Copy, ValueEnum, PartialEq, Eq)]
pub enum Method {
    /// The network refined by the kinematic solver where the network's markers are all in
    /// the take, else the kinematic solver (`locap_nn::method`).
    Auto,
    /// The network solver (`--model` or the shipped one).
    Network,
    /// The kinematic solver (`--layout`, or the CMU 41-marker layout).
    Ik,
    /// The network's answer refined by the kinematic solver (both as above).
    Refine,
}

impl From<Method> for SolveMethod {
    fn from(method: Method) -> SolveMethod {
        match method {
            Method::Auto => SolveMethod::Auto,
            Method::Network => SolveMethod::Network,
            Method::Ik => SolveMethod::Kinematic,
            Method::Refine => SolveMethod::Refine,
        }
    }
}

/// The kinematic solver the arguments ask for.
pub(crate) fn kinematic_solver(layout: Option<&Path>, skeleton: Option<&Path>) -> Result<KinematicSolver> {
    let Some(path) = layout else {
        return match skeleton {
            Some(sk) => {
                KinematicSolver::cmu41_on_bones_of(&read_skeleton(sk)?).with_context(|| format!("{}", sk.display()))
            }
            None => Ok(KinematicSolver::cmu41()?),
        };
    };
    let layout = crate::cmd::layout::read_layout(path)?;
    let solver = match skeleton {
        Some(sk) => KinematicSolver::new(&layout, &read_skeleton(sk)?, None),
        None => KinematicSolver::from_layout(&layout),
    };
    solver.with_context(|| format!("{}", path.display()))
}

/// A skeleton from an ASF (its own length unit) or a BVH (centimetres).
fn read_skeleton(path: &Path) -> Result<locap_core::Skeleton> {
    Ok(if inputs::has_extension(path, &["asf"]) {
        let asf = locap_io::asf_amc::read_asf_path(path)?;
        asf.to_skeleton(asf.mm_per_unit()).map_err(|e| e.in_file(path))?
    } else {
        locap_io::bvh::read_bvh_path(path, LengthUnit::Centimetre)?.skeleton
    })
}

/// What one take gave.
struct Solved {
    target: PathBuf,
    frames: usize,
    rate_hz: f64,
    seconds: f64,
    /// The method that solved it (`auto` resolved).
    method: SolveMethod,
    /// The kinematic solver's marker residual (mm RMS), calibration residual before and after
    /// (mm RMS) and subject scale, when it solved.
    residual_mm: Option<(f64, (f64, f64), f64)>,
    /// The tracking checks (issue 17): the largest rotation of a joint between consecutive
    /// frames (deg) and its joint, the frame pairs over 20 degrees, and the share of wrist
    /// samples within 60 mm of their markers' mean (`None`: no known wrist).
    tracking: (f64, String, usize, Option<f64>),
}

/// Where each input's output goes: `output` itself for one named file, else a mirror of the
/// inputs under the folder `output` with `extension`.
/// A named file must have one of `allowed` extensions: `-o x.c3d` must not silently get a BVH.
fn outputs(
    given: &[PathBuf],
    files: &[PathBuf],
    output: &Path,
    extension: &str,
    allowed: &[&str],
) -> Result<Vec<PathBuf>> {
    if files.len() == 1 && given.len() == 1 && !given[0].is_dir() && !output.is_dir() {
        if !inputs::has_extension(output, allowed) {
            return Err(inputs::usage(format!(
                "{}: name this output .{} (or give a folder)",
                output.display(),
                allowed.join(", .")
            )));
        }
        return Ok(vec![output.to_path_buf()]);
    }
    Ok(inputs::output_paths(files, output, Some(extension)))
}

fn read_model(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("{}: cannot read the model", path.display()))
}

/// Runs `locap solve`.
pub fn run(args: Args) -> Result<ExitCode> {
    let auxiliary = [args.refiner.as_ref(), args.layout.as_ref(), args.skeleton.as_ref()];
    let given = args.model.iter().chain(auxiliary.iter().flatten().copied());
    inputs::protect(&given.map(|p| p.as_path()).collect::<Vec<_>>())?;
    let models =
        args.model.iter().map(|p| Ok((p.display().to_string(), read_model(p)?))).collect::<Result<Vec<_>>>()?;
    let refiner = args.refiner.as_deref().map(read_model).transpose()?;
    // Check the models once up front, so a bad file is one clear error and not one per take.
    let device = Default::default();
    let load_solver = |device: &_| -> Result<Solver> {
        if models.is_empty() {
            return locap_nn::shipped::solver(device).context("the built-in solver");
        }
        Ok(locap_nn::solver::ensemble::from_named_files(&models, device)?)
    };
    let probe = load_solver(&device)?;
    if let (Some(bytes), Some(path)) = (&refiner, &args.refiner) {
        Refiner::from_bytes(bytes, &device).with_context(|| format!("{}", path.display()))?;
    }
    drop(probe);
    // As `locap clean --method`: a refiner only when asked for, by file or by `--fill neural`.
    let refiners = match (&refiner, &args.refiner, args.fill) {
        (Some(bytes), Some(path), _) => {
            let name = path.file_name().unwrap_or_default().to_string_lossy().into_owned();
            RefinerSource::Given(vec![(name, bytes.clone())])
        }
        (_, _, FillArg::Neural) => RefinerSource::Shipped,
        _ => RefinerSource::None,
    };
    if args.method == Method::Network && args.skeleton.is_some() {
        return Err(inputs::usage("--skeleton goes with the kinematic solver: --method ik, refine or auto"));
    }
    let kinematic = match args.method {
        Method::Network => None,
        Method::Ik | Method::Auto | Method::Refine => {
            let mut k = kinematic_solver(args.layout.as_deref(), args.skeleton.as_deref())?;
            if args.no_wrist_centres {
                k = k.without_joint_centres();
            }
            Some(k)
        }
    };
    let files = inputs::expand(&args.inputs, &["c3d", "trc"])?;
    let targets = outputs(&args.inputs, &files, &args.output, &args.to, export::MOTION_EXTENSIONS)?;
    if args.with_markers && !targets.iter().all(|t| inputs::has_extension(t, &["gltf", "glb"])) {
        return Err(inputs::usage("--with-markers goes with glTF output (.gltf, .glb)"));
    }
    let marker_targets = match &args.markers_out {
        Some(p) => Some(outputs(&args.inputs, &files, p, "c3d", &["c3d"])?),
        None => None,
    };
    inputs::check_outputs(&[targets.clone(), marker_targets.clone().unwrap_or_default()].concat())?;
    let started = std::time::Instant::now();
    let (done, failed) = crate::run_takes(&files, "solving", |i, input| {
        let marker_target = marker_targets.as_ref().map(|t| t[i].as_path());
        // A C3D input is kept whole, so the cleaned markers keep its parameters (subjects,
        // trial, events, ...) and analog data.
        let c3d_input = if inputs::has_extension(input, &["trc"]) { None } else { Some(inputs::read_c3d(input)?) };
        let take = match &c3d_input {
            Some(file) => file.to_take().map_err(|e| e.in_file(input))?,
            None => inputs::read_take(input)?,
        };
        let t0 = std::time::Instant::now();
        // One solver per job: a burn module is not shared between threads.
        let device = Default::default();
        let solver = load_solver(&device)?;
        let filler =
            locap_nn::filler_for(&take, FillConfig { method: args.fill.into(), ..FillConfig::default() }, &refiners)?;
        let solved =
            locap_nn::method::solve_take(&take, filler.as_ref(), &solver, kinematic.as_ref(), args.method.into())?;
        if args.method == Method::Auto && solved.method == SolveMethod::Kinematic {
            eprintln!(
                "{}: the solver model was trained on another marker set; solving with the kinematic solver (--method ik{})",
                input.display(),
                args.layout.as_ref().map_or(String::new(), |p| format!(", layout {}", p.display()))
            );
        }
        let TakeSolve { motion, cleaned, method, report } = solved;
        // The tracking checks, for every method; the motion is still in the skeleton's frame,
        // as they compare it.
        let rotating = match (&kinematic, &report) {
            (Some(k), Some(_)) => k.rotating(),
            _ => solver.meta.rotating.clone(),
        };
        let (jump, joint, over) = rotation_jumps(&motion, &rotating, 20.0);
        let wrists = wrists_within(&motion, cleaned.take(), 60.0).map(|(share, _)| share);
        let tracking = (jump, joint, over, wrists);
        let residual_mm = report.map(|r| (r.residual_rms_mm, r.calibration_rms_mm, r.scale));
        let seconds = t0.elapsed().as_secs_f64();
        inputs::create_parent(&targets[i])?;
        let lab = solver.meta.lab;
        let motion = axes::motion_to_tools_y_up(&motion, lab.motion_to_lab_rotation(), lab.up_axis());
        let markers = args.with_markers.then(|| axes::take_with_up_axis(cleaned.take(), UpAxis::Y));
        let choices = export::MotionOutput { bvh_unit: args.bvh_unit, markers: markers.as_ref() };
        export::write_motion_path(&motion, &choices, &targets[i])?;
        if let Some(path) = marker_target {
            inputs::create_parent(path)?;
            let mut file = match c3d_input {
                Some(mut file) => {
                    file.set_take(cleaned.take()).map_err(|e| e.in_file(input))?;
                    file
                }
                None => locap_io::c3d::C3dFile::from_take(cleaned.take())?,
            };
            if let Some(up) = args.up {
                axes::set_c3d_up_axis(&mut file, up.into()).map_err(|e| e.in_file(input))?;
            }
            // What this cleaning did, recorded as `locap clean` records it.
            let mut record = cleaned.provenance();
            record.method = Some(format!("locap solve: {}", cleaned.method));
            file.set_provenance(cleaned.take(), &record).with_context(|| format!("{}", path.display()))?;
            locap_io::c3d::write_path(&file, path)?;
        }
        Ok(Solved {
            target: targets[i].clone(),
            frames: motion.frame_count(),
            rate_hz: motion.frame_rate_hz(),
            seconds,
            method,
            residual_mm,
            tracking,
        })
    });
    let total: usize = done.iter().map(|(_, s)| s.frames).sum();
    let mut text = String::new();
    for (path, s) in &done {
        let mut method = match s.residual_mm {
            Some((r, (before, after), scale)) => format!(
                ", {}, marker residual {r:.1} mm RMS; calibration {before:.1} -> {after:.1} mm, scale {scale:.3}",
                s.method.describe()
            ),
            None => format!(", {}", s.method.describe()),
        };
        let (jump, joint, over, wrists) = &s.tracking;
        method.push_str(&format!("; largest rotation jump {jump:.1} deg ({joint}), {over} frame pairs over 20 deg"));
        if let Some(share) = wrists {
            method.push_str(&format!(", wrists within 60 mm of their markers {:.1}%", 100.0 * share));
        }
        text.push_str(&format!(
            "{}: {} frames at {} Hz -> {} ({:.0} frames/s{method})\n",
            path.display(),
            s.frames,
            s.rate_hz,
            s.target.display(),
            s.frames as f64 / s.seconds.max(1e-9)
        ));
    }
    if done.len() > 1 {
        let seconds = started.elapsed().as_secs_f64();
        text.push_str(&format!("{} takes, {total} frames in {seconds:.1} s\n", done.len()));
    }
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}
