//! `locap eval`: the motion-solver comparison of LocalMoCap section 4 (Table 1) on held-out
//! synthetic shards: JOE (degrees), JPE (mm) and OMPE (mm, occluded samples only) for every
//! solver model given (graph network, ablations, MLP baseline), all on the same cleaning, each
//! take solved as `locap solve` solves a real one. Prints the table, writes it as JSON with the
//! per-joint and per-gap-length errors, and draws the error by gap length and the error per
//! joint (`--plots DIR`, SVG and PNG).

use anyhow::{Context, Result};
use clap::Parser;
use locap_eval::solver::{
    Method, MethodScores, MotionComparison, compare_motions, evaluate_methods, gap_bin_labels, rotation_jumps, table,
    wrists_within,
};
use locap_nn::Refiner;
use locap_nn::kinematic::KinematicSolver;
use locap_nn::solver::Solver;
use locap_view::plot::{Chart, Format};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap eval`.
#[derive(Parser, Debug)]
#[command(after_help = "Example:\n  locap synth --motion ../shared/data/cmu-asfamc/02 --augment \
                        ../shared/data/gap-stats/real-gap-statistics.json --format shard -o test/\n  \
                        locap eval --data test/ --models graph.locapsv mlp.locapsv --json table1.json --plots plots/")]
pub struct Args {
    /// Held-out `.shard` files from `locap synth` (with motion), or folders of them.
    #[arg(long, value_name = "DIR", help_heading = "Input")]
    data: PathBuf,
    /// Solver models to compare (from `locap train solve`); named by file stem.
    #[arg(long, required = true, num_args = 1.., value_name = "MODEL", help_heading = "Input")]
    models: Vec<PathBuf>,
    /// Also score these models as one ensemble, their answers averaged per frame and joint
    /// (`locap solve --model A --model B`); named by their file stems joined with `&`.
    #[arg(long, num_args = 2.., value_name = "MODEL", help_heading = "Input")]
    ensemble: Vec<PathBuf>,
    /// Gap-fill refiner for the cleaning (default: EDM alone).
    #[arg(long, value_name = "MODEL", help_heading = "Input")]
    refiner: Option<PathBuf>,
    /// Real labeled takes (C3D) to solve and compare with a reference solution of the same
    /// frames (`--reference`, same order): a real, not synthetic, accuracy figure.
    #[arg(long, num_args = 1.., value_name = "C3D", help_heading = "Real takes")]
    real: Vec<PathBuf>,
    /// Reference motion of each `--real` take: AMC (with the ASF next to it) or BVH, the same
    /// skeleton definition as the models' (joints matched by name).
    #[arg(long, num_args = 1.., value_name = "MOTION", help_heading = "Real takes")]
    reference: Vec<PathBuf>,
    /// Also score the kinematic solver (the CMU 41-marker layout on the shipped solver's
    /// skeleton, calibrated on each take; no training): Table 1's optimization-based column.
    #[arg(long, help_heading = "Input")]
    kinematic: bool,
    /// The kinematic solver keeps the template's forearm lengths instead of calibrating and
    /// holding each wrist within 45 mm of the mean of its two wrist markers.
    #[arg(long, requires = "kinematic", help_heading = "Input")]
    no_wrist_centres: bool,
    /// The kinematic solver on this layout and the skeleton it carries (from `locap hands` or
    /// `locap layout --from-opensim`) instead of the CMU 41-marker layout; the data's
    /// skeleton must have the same joints.
    #[arg(long, value_name = "LAYOUT", requires = "kinematic", help_heading = "Input")]
    kinematic_layout: Option<PathBuf>,
    /// Also score each model's answer refined by the kinematic solver (the network's joint
    /// rotations as its prior; named `MODEL+ik`).
    #[arg(long, requires = "kinematic", help_heading = "Input")]
    refine: bool,
    /// How hard the network's joint rotations hold against the markers in `--refine`, per
    /// rad^2 (default: the solver's, `locap_nn::kinematic::BODY_REFINE_PRIOR` for the CMU
    /// body, `REFINE_PRIOR` on a layout's skeleton).
    #[arg(long, value_name = "WEIGHT", requires = "refine", help_heading = "Input")]
    refine_prior: Option<f64>,
    /// Half-width (seconds) of the window the network's joint rotations are averaged over
    /// before they pull in `--refine` (default: `locap_nn::kinematic::PRIOR_HALF_WINDOW_S`; 0:
    /// each frame's own).
    #[arg(long, value_name = "SECONDS", requires = "refine", help_heading = "Input")]
    prior_window: Option<f64>,
    /// How far `--refine` moves the CMU template's bone offsets towards the skeleton the
    /// network predicted for each take, 0 (the template) to 1 (default:
    /// `locap_nn::kinematic::BODY_NETWORK_SKELETON`). The CMU body solver only: a layout's
    /// skeleton is the user's, not moved.
    #[arg(
        long,
        value_name = "SHARE",
        requires = "refine",
        conflicts_with = "kinematic_layout",
        help_heading = "Input"
    )]
    network_skeleton: Option<f64>,
    /// Pull a joint more than this many degrees from the network's pose back linearly, not
    /// squared, in `--refine` (Huber; default 0: plain squares). Lets the markers overrule the
    /// network where they see a joint clearly, and lets fast motion jitter the hands and feet
    /// more (docs/benchmarks.md, "The network's pull, robust").
    #[arg(long, value_name = "DEGREES", requires = "refine", help_heading = "Input")]
    prior_huber: Option<f64>,
    /// The network's bias the CMU body refinement's second pass removes beyond this many
    /// degrees (0: one pass; default `locap_nn::kinematic::BODY_BIAS_HUBER_DEG`).
    #[arg(long, value_name = "DEGREES", requires = "refine", help_heading = "Input")]
    refine_bias: Option<f64>,
    /// Pull of each marker's offset towards the layout's in the kinematic solver's subject
    /// calibration, per mm of offset change and calibration frame (default: the solver's,
    /// `locap_label::ik::SequenceConfig::offset_prior`).
    #[arg(long, value_name = "WEIGHT", requires = "kinematic", help_heading = "Input")]
    offset_prior: Option<f64>,
    /// Write the results as JSON.
    #[arg(long, value_name = "FILE", help_heading = "Output")]
    json: Option<PathBuf>,
    /// Folder for the charts (error by gap length, error per joint; SVG and PNG).
    #[arg(long, value_name = "DIR", help_heading = "Output")]
    plots: Option<PathBuf>,
}

/// The JSON report.
#[derive(Debug, Serialize)]
struct Report {
    data: String,
    takes: usize,
    frames: usize,
    refiner: Option<String>,
    joints: Vec<String>,
    gap_bins: Vec<String>,
    methods: Vec<MethodScores>,
    real: Vec<RealRow>,
    region: &'static str,
}

/// One real take solved by one model, against its reference.
#[derive(Debug, Serialize)]
struct RealRow {
    take: String,
    reference: String,
    model: String,
    comparison: MotionComparison,
    /// Largest rotation of a joint between consecutive frames, degrees, and that joint.
    max_jump_deg: f64,
    max_jump_joint: String,
    /// Frame pairs where some joint turns by more than 20 degrees.
    jumps_over_20_deg: usize,
    /// Share of wrist samples within 60 mm of the wrist markers, and the largest distance (mm).
    wrists_within_60_mm: Option<(f64, f64)>,
    /// Frames solved per second (cleaning included).
    frames_per_s: f64,
}

fn stem(p: &Path) -> String {
    p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| p.display().to_string())
}

fn write_chart(chart: &Chart, path_stem: &Path) -> Result<()> {
    for (format, ext) in [(Format::Svg, "svg"), (Format::Png, "png")] {
        let path = path_stem.with_extension(ext);
        let bytes = chart.render(format, chart.default_size())?;
        crate::inputs::write_bytes(&path, &bytes)?;
    }
    Ok(())
}

/// Runs `locap eval`.
pub fn run(args: Args) -> Result<ExitCode> {
    if args.real.len() != args.reference.len() {
        return Err(crate::inputs::usage(format!(
            "--real has {} takes but --reference {} motions; give one reference per take",
            args.real.len(),
            args.reference.len()
        )));
    }
    let given = args.models.iter().chain(&args.ensemble).chain(&args.refiner).chain(&args.real).chain(&args.reference);
    crate::inputs::protect(&given.map(PathBuf::as_path).collect::<Vec<_>>())?;
    crate::inputs::check_outputs(args.json.as_slice())?;
    crate::inputs::expand(std::slice::from_ref(&args.data), &["shard"])?;
    crate::inputs::check_outputs(args.json.as_slice())?;
    let device = Default::default();
    let mut solvers = Vec::new();
    let read =
        |path: &PathBuf| std::fs::read(path).with_context(|| format!("{}: cannot read the model", path.display()));
    let load = |path: &PathBuf| -> Result<Solver> {
        Solver::from_bytes(&read(path)?, &device).with_context(|| format!("{}", path.display()))
    };
    for path in &args.models {
        solvers.push((stem(path), load(path)?));
    }
    if !args.ensemble.is_empty() {
        let files =
            args.ensemble.iter().map(|p| Ok((p.display().to_string(), read(p)?))).collect::<Result<Vec<_>>>()?;
        let name = args.ensemble.iter().map(|p| stem(p)).collect::<Vec<_>>().join("&");
        solvers.push((name, locap_nn::solver::ensemble::from_named_files(&files, &device)?));
    }
    let names: Vec<&String> = solvers.iter().map(|(n, _)| n).collect();
    if (1..names.len()).any(|i| names[..i].contains(&names[i])) {
        return Err(crate::inputs::usage("two models have the same file name; the table names methods by file stem"));
    }
    let refiner = match &args.refiner {
        Some(p) => {
            let bytes = std::fs::read(p).with_context(|| format!("{}: cannot read the model", p.display()))?;
            Some(Refiner::from_bytes(&bytes, &device).with_context(|| format!("{}", p.display()))?)
        }
        None => None,
    };
    let data = crate::training::solver_data(&args.data)?;
    eprintln!("evaluating {} models on {} takes, {} frames", solvers.len(), data.shards.len(), data.frames());
    let kinematic = if args.kinematic {
        let mut k = crate::cmd::solve::kinematic_solver(args.kinematic_layout.as_deref(), None)?;
        if args.no_wrist_centres {
            k = k.without_joint_centres();
        }
        if let Some(w) = args.refine_prior {
            anyhow::ensure!(w.is_finite() && w >= 0.0, "--refine-prior {w} is not a weight (finite, at least 0)");
            k.refine_prior = w;
        }
        if let Some(s) = args.prior_window {
            anyhow::ensure!(s.is_finite() && (0.0..=10.0).contains(&s), "--prior-window {s}: 0 to 10 seconds");
            k.prior_half_window_s = s;
        }
        if let Some(w) = args.network_skeleton {
            anyhow::ensure!((0.0..=1.0).contains(&w), "--network-skeleton {w}: a share from 0 to 1");
            k.network_skeleton = w;
        }
        if let Some(d) = args.prior_huber {
            anyhow::ensure!(d.is_finite() && d >= 0.0, "--prior-huber {d} is not an angle (finite, at least 0)");
            k.config.ik.prior_huber_deg = d;
        }
        if let Some(w) = args.offset_prior {
            anyhow::ensure!(w.is_finite() && w >= 0.0, "--offset-prior {w} is not a weight (finite, at least 0)");
            k.config.offset_prior = w;
        }
        if let Some(d) = args.refine_bias {
            anyhow::ensure!(d.is_finite() && d >= 0.0, "--refine-bias {d} is not an angle (finite, at least 0)");
            k.bias_huber_deg = d;
        }
        Some(k)
    } else {
        None
    };
    let mut refs: Vec<(String, Method)> = Vec::new();
    if let Some(k) = &kinematic {
        refs.push(("kinematic".into(), Method::Kinematic(k)));
    }
    refs.extend(solvers.iter().map(|(n, s)| (n.clone(), Method::Network(s))));
    if let (Some(k), true) = (&kinematic, args.refine) {
        refs.extend(solvers.iter().map(|(n, s)| (format!("{n}+ik"), Method::Refined(s, k))));
    }
    // The joints the CMU layout's markers constrain, when the data is on the CMU skeleton.
    let names = |sk: &locap_core::Skeleton| sk.joints().iter().map(|j| j.name.clone()).collect::<Vec<_>>();
    let constrained = match &kinematic {
        Some(k) => Some(k.constrained().to_vec()),
        None => KinematicSolver::cmu41()
            .ok()
            .filter(|k| names(k.skeleton()) == names(&data.skeleton))
            .map(|k| k.constrained().to_vec()),
    };
    let scores = evaluate_methods(&refs, &data.shards, refiner.as_ref(), constrained.as_deref())?;
    let joints: Vec<String> = data.skeleton.joints().iter().map(|j| j.name.clone()).collect();
    let mut text = format!(
        "{} held-out takes, {} frames, cleaning: {}\n",
        data.shards.len(),
        data.frames(),
        if refiner.is_some() { "EDM + refiner" } else { "EDM" }
    );
    // A waist frame solves a body; a wrist frame a hand.
    let region = if solvers[0].1.meta.frame.name.contains("wrist") { "hand" } else { "body" };
    text.push_str(&table(region, &scores));
    let real = real_rows(&args, &solvers, kinematic.as_ref(), refiner.as_ref())?;
    if !real.is_empty() {
        text.push_str(&format!(
            "\nreal takes vs their reference solution\n{:<24} {:<16} {:>8} {:>10} {:>14} {:>9} {:>9} {:>10} {:>8} {:>10} {:>9}\n",
            "take", "model", "frames", "JPE (mm)", "JPE root-aln", "root (mm)", "JOE (deg)", "max jump", ">20 deg", "wrist<=60", "frames/s"
        ));
        for r in &real {
            let c = &r.comparison;
            text.push_str(&format!(
                "{:<24} {:<16} {:>8} {:>10.1} {:>14.1} {:>9.1} {:>9.2} {:>10.1} {:>8} {:>10} {:>9.0}\n",
                stem(Path::new(&r.take)),
                r.model,
                c.frames,
                c.jpe_mm,
                c.jpe_root_aligned_mm,
                c.root_mm,
                c.joe_deg,
                r.max_jump_deg,
                r.jumps_over_20_deg,
                r.wrists_within_60_mm.map_or("-".into(), |(f, _)| format!("{:.1}%", 100.0 * f)),
                r.frames_per_s
            ));
        }
    }
    crate::emit(&text)?;
    if let Some(path) = &args.json {
        let report = Report {
            data: args.data.display().to_string(),
            takes: data.shards.len(),
            frames: data.frames(),
            refiner: args.refiner.as_ref().map(|p| p.display().to_string()),
            joints: joints.clone(),
            gap_bins: gap_bin_labels(),
            methods: scores.clone(),
            real,
            region,
        };
        crate::inputs::create_parent(path)?;
        crate::inputs::write_json(path, &report)?;
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
        let buckets = gap_bin_labels();
        let mut methods: Vec<(String, Vec<Option<f64>>)> =
            scores.iter().map(|s| (format!("{} JPE", s.name), s.jpe_by_gap_mm.clone())).collect();
        if let Some(first) = scores.first() {
            methods.push(("OMPE (cleaning)".into(), first.ompe_by_gap_mm.clone()));
        }
        let chart = Chart::FillError {
            title: "error by gap length (JPE: longest gap open in the frame)".into(),
            buckets,
            methods,
        };
        write_chart(&chart, &dir.join("error-by-gap-length"))?;
        for s in &scores {
            let items = joints.iter().cloned().zip(s.jpe_per_joint_mm.iter().copied()).collect();
            let chart = Chart::Bars { title: format!("{}: JPE per joint", s.name), x_desc: "JPE, mm".into(), items };
            write_chart(&chart, &dir.join(format!("{}-jpe-per-joint", s.name)))?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Every `--real` take solved by every model (and the kinematic solver) and compared with its
/// reference.
fn real_rows(
    args: &Args,
    solvers: &[(String, Solver)],
    kinematic: Option<&KinematicSolver>,
    refiner: Option<&Refiner>,
) -> Result<Vec<RealRow>> {
    let options = crate::inputs::MotionOptions { asf: None, bvh_mm_per_unit: 25.4 / 0.45, amc_rate_hz: 120.0 };
    let mut rows = Vec::new();
    for (take_path, reference_path) in args.real.iter().zip(&args.reference) {
        let take = crate::inputs::read_take(take_path)?;
        let reference = crate::inputs::read_motion(reference_path, &options)?;
        let edm = locap_clean::FillConfig::default();
        let filler: &dyn locap_clean::Filler = match refiner {
            Some(r) => r,
            None => &edm,
        };
        let mut solved = Vec::new();
        if let Some(k) = kinematic {
            let t0 = std::time::Instant::now();
            let (motion, _, _) = k.solve(&take, filler).with_context(|| format!("{}", take_path.display()))?;
            solved.push(("kinematic".to_string(), motion, k.rotating(), t0.elapsed().as_secs_f64()));
        }
        for (name, solver) in solvers {
            let t0 = std::time::Instant::now();
            let (motion, cleaned) = solver.solve(&take, filler).with_context(|| format!("{}", take_path.display()))?;
            let seconds = t0.elapsed().as_secs_f64();
            if let (Some(k), true) = (kinematic, args.refine) {
                let (refined, _) = k
                    .refine(&cleaned, take.frame_rate_hz(), &motion)
                    .with_context(|| format!("{}", take_path.display()))?;
                let total = t0.elapsed().as_secs_f64();
                solved.push((format!("{name}+ik"), refined, k.rotating(), total));
            }
            solved.push((name.clone(), motion, solver.meta.rotating.clone(), seconds));
        }
        for (name, motion, rotating, seconds) in solved {
            let comparison = compare_motions(&motion, &reference, &rotating)
                .with_context(|| format!("{} vs {}", take_path.display(), reference_path.display()))?;
            let (max_jump_deg, max_jump_joint, jumps_over_20_deg) = rotation_jumps(&motion, &rotating, 20.0);
            rows.push(RealRow {
                take: take_path.display().to_string(),
                reference: reference_path.display().to_string(),
                model: name,
                comparison,
                max_jump_deg,
                max_jump_joint,
                jumps_over_20_deg,
                wrists_within_60_mm: wrists_within(&motion, &take, 60.0),
                frames_per_s: motion.frame_count() as f64 / seconds.max(1e-9),
            });
        }
    }
    Ok(rows)
}
