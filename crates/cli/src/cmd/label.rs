//! `locap label`: names the points of raw takes online, frame after frame (labeling paper
//! sections 3 and 4; see `locap_label`), one take per job.
//!
//! The template is a labeled take of the same marker set (a T-pose, a range-of-motion take,
//! or any labeled take of the subject, in any pose), or, with `--layout` alone, a marker
//! layout that brings its skeleton (`locap layout --from-opensim`: no labeled take at all;
//! `locap_eval::label_layout`, `locap_label::model`), whose first labels only start the
//! calibration on the take; labeling starts by fitting the body the
//! template shows (rigid segments and their joints, `locap_label::body`) to the first raw
//! frame it is sure of, whatever the pose, and runs forwards and backwards from there
//! (`--fit rigid`: the older rigid fit of one template frame to the first frame, for takes
//! that start in the template's pose). A take of another subject, whose joints the template's
//! body does not fit, is labeled with the template calibrated on the take itself
//! (`locap_label::subject`: a first fit with loose joints, then the subject's own distances).
//! Output: one column per template marker (missing where
//! no point was labeled); the points no marker took (ghosts) are dropped, or kept as `*0`,
//! `*1`, ... with `--keep-unlabeled`. Everything else in the file (analog data, parameters)
//! is kept.
//!
//! How sure the labels are is written to the take and summarised (a labeled sample is
//! *confirmed* when it keeps its rigid edges to its labeled neighbours within 20 mm, else
//! *uncertain*; raw points no marker took are *rejected*):
//! - `LOCAP:LABEL_CONFIDENCE`: one line per template marker, `LABEL confidence labeled`, the
//!   share of its labeled samples that are confirmed (0 to 1, `-` when never labeled) and how
//!   many were labeled;
//! - `LOCAP:LABEL_UNCERTAIN`: the uncertain samples, `LABEL first-last` per run in C3D frame
//!   numbers, in the compact form of `LOCAP:FILLED` (`locap_core::range_list`).
//!
//! Flags: `--template FILE` labels with a labeled take; `--layout FILE` without `--template`
//! labels with the layout's own model; `--skeleton FILE --layout FILE` (with or without
//! `--template`) estimates missing markers from a pose of that skeleton fitted every frame.
//!
//! The labeling itself is one call, `locap_label::label_take` (or `label_take_with_pose` with
//! `--skeleton`); this command finds the files, reads and writes them, records `LOCAP:LABELED`
//! and the confidences, and prints the summary.

use crate::inputs;
use anyhow::{Context, Result, bail};
use clap::{Parser, ValueEnum};
use locap_eval::label_bench::score;
use locap_eval::unlabel::{TRUTH_FORMAT, TruthFile};
use locap_io::c3d;
use locap_label::ik::{Attachment, MarkerModel};
use locap_label::{FitConfig, FitMethod, LabelConfig, PointFrames, Template, label_take, label_take_with_pose};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Edge-length tolerance of the truth-free consistency check in the summary (mm).
const EDGE_TOLERANCE_MM: f64 = 20.0;

/// Arguments of `locap label`.
#[derive(Parser, Debug)]
#[command(
    after_help = "Examples:\n  locap label raw.c3d --template tpose.c3d -o labeled.c3d\n  \
                  locap label raw_takes/ --template tpose.c3d -o labeled/ --keep-unlabeled\n  \
                  locap layout --from-opensim model.osim MarkerSet.xml -o layout.toml\n  \
                  locap label raw.c3d --layout layout.toml -o labeled.c3d",
    group(clap::ArgGroup::new("source").required(true).multiple(true).args(["template", "layout"]))
)]
pub struct Args {
    /// Raw C3D takes (unlabeled or mislabeled points; labels are ignored), or folders.
    #[arg(required = true, value_name = "FILE")]
    inputs: Vec<PathBuf>,
    /// A labeled C3D take of the same marker set. Without it, --layout is the template.
    #[arg(long, value_name = "FILE", help_heading = "Template")]
    template: Option<PathBuf>,
    /// Frame of the template whose pose the raw takes start in (0-based); default: the first
    /// frame with the most markers visible.
    #[arg(long, value_name = "N", requires = "template", help_heading = "Template")]
    template_frame: Option<usize>,
    /// How the first labels are found: fit the template's articulated body to the first
    /// frame it is sure of (any pose), or fit one template frame rigidly to the first frame.
    #[arg(long, value_enum, default_value_t = FitArg::Articulated, help_heading = "Template")]
    fit: FitArg,
    /// With `--fit rigid`: a template marker matches a first-frame point only within this
    /// distance after the rigid fit (mm).
    #[arg(value_parser = crate::values::positive_length_mm, long, default_value_t = FitConfig::default().accept_mm, value_name = "MM", help_heading = "Template")]
    fit_distance: f64,
    /// Output C3D file (one input) or folder.
    #[arg(short, long, value_name = "PATH", help_heading = "Output")]
    output: PathBuf,
    /// Keep the points no marker took as unlabeled `*N` columns instead of dropping them.
    #[arg(long, help_heading = "Output")]
    keep_unlabeled: bool,
    /// Score the labels against the truth `locap unlabel` wrote (one input only).
    #[arg(long, value_name = "FILE", help_heading = "Output")]
    truth: Option<PathBuf>,
    /// The subject's skeleton (ASF, or BVH in centimetres): with --layout, missing markers are
    /// estimated from a pose fitted every frame (paper section 4) instead of from their rigid
    /// neighbours alone. Slower: hundreds of frames per second.
    #[arg(long, value_name = "FILE", requires = "layout", help_heading = "Skeleton")]
    skeleton: Option<PathBuf>,
    /// Marker layout (TOML or JSON). Without --template: the template itself, a layout that
    /// brings its skeleton (`locap layout --from-opensim`), for labeling with no labeled take
    /// (its first labels start a calibration on the take). With --skeleton: the markers on
    /// that skeleton, for estimating missing markers (e.g. crates/synth/layouts/cmu41.toml);
    /// template markers are matched to layout markers by label.
    #[arg(long, value_name = "FILE", help_heading = "Skeleton")]
    layout: Option<PathBuf>,
    /// Labeling method: soft graph matching (ours), or a baseline.
    #[arg(long, value_enum, default_value_t = MethodArg::Ours, help_heading = "Labeling")]
    method: MethodArg,
}

/// First fits on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum FitArg {
    /// The template's rigid segments and joints, fitted in any pose.
    Articulated,
    /// One template frame, fitted rigidly: the take must start in its pose.
    Rigid,
}

impl From<FitArg> for FitMethod {
    fn from(f: FitArg) -> FitMethod {
        match f {
            FitArg::Articulated => FitMethod::Articulated,
            FitArg::Rigid => FitMethod::Rigid,
        }
    }
}

/// Labeling methods on the command line.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// Soft graph matching with missing-marker estimation.
    Ours,
    /// Unary graph matching: Hungarian on the distance to the Kalman prediction.
    Ugm,
    /// Closest point.
    Cp,
}

impl From<MethodArg> for locap_label::Method {
    fn from(m: MethodArg) -> locap_label::Method {
        match m {
            MethodArg::Ours => locap_label::Method::SoftGraph,
            MethodArg::Ugm => locap_label::Method::Unary,
            MethodArg::Cp => locap_label::Method::ClosestPoint,
        }
    }
}

/// Runs `locap label`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.inputs, &["c3d"])?;
    if args.truth.is_some() && files.len() != 1 {
        return Err(inputs::usage(format!("--truth scores one take; {} were given", files.len())));
    }
    let auxiliary = [args.template.as_ref(), args.truth.as_ref(), args.skeleton.as_ref(), args.layout.as_ref()];
    inputs::protect(&auxiliary.iter().flatten().map(|p| p.as_path()).collect::<Vec<_>>())?;
    let targets = inputs::targets(&args.inputs, &files, &args.output)?;
    let template = match (&args.template, &args.layout) {
        (Some(path), layout) => {
            if layout.is_some() && args.skeleton.is_none() {
                return Err(inputs::usage(
                    "--layout with --template estimates missing markers on --skeleton, which is missing \
                     (to label from the layout alone, leave --template out)",
                ));
            }
            let take = inputs::read_c3d(path)?.to_take().map_err(|e| e.in_file(path))?;
            Template::from_take(&take, args.template_frame).with_context(|| format!("{}", path.display()))?
        }
        (None, Some(layout)) => {
            if matches!(args.fit, FitArg::Rigid) {
                return Err(inputs::usage("--fit rigid fits a template take's frame: it needs --template"));
            }
            let read = crate::cmd::layout::read_layout(layout)?;
            locap_eval::label_layout::template_from_layout(&read).with_context(|| format!("{}", layout.display()))?
        }
        // clap requires one of the two.
        (None, None) => return Err(inputs::usage("--template or --layout is required")),
    };
    let model = match (&args.skeleton, &args.layout) {
        (Some(skeleton), Some(layout)) => Some(marker_model(skeleton, layout, &template)?),
        _ => None,
    };
    let (done, failed) = crate::run_takes(&files, "labeling", |i, input| {
        inputs::create_parent(&targets[i])?;
        label_one(input, &targets[i], &template, model.as_ref(), &args)
    });
    let text: String = done.iter().map(|(_, line)| line.clone()).collect();
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// The template's markers attached to the skeleton by the layout.
fn marker_model(skeleton: &Path, layout: &Path, template: &Template) -> Result<MarkerModel> {
    let skeleton = if inputs::has_extension(skeleton, &["asf"]) {
        let asf = locap_io::asf_amc::read_asf_path(skeleton)?;
        asf.to_skeleton(asf.mm_per_unit()).map_err(|e| e.in_file(skeleton))?
    } else {
        locap_io::bvh::read_bvh_path(skeleton, locap_core::LengthUnit::Centimetre)?.skeleton
    };
    let bound = crate::cmd::layout::read_layout(layout)?
        .bind(&skeleton)
        .with_context(|| format!("{}: does not fit the skeleton", layout.display()))?;
    let attachments: Vec<Option<Attachment>> = template
        .names()
        .iter()
        .map(|name| {
            let k = bound.names.iter().position(|n| *n == name.label)?;
            let m = &bound.markers[k];
            Some(Attachment {
                joint: m.joint,
                offset_mm: m.offset_mm,
                blend: m.blend.as_ref().map(|b| (b.joint, b.weight, b.offset_mm)),
            })
        })
        .collect();
    let attached = attachments.iter().flatten().count();
    if attached * 2 < template.marker_count() {
        bail!(
            "{}: only {attached} of the template's {} markers are in the layout (matched by label)",
            layout.display(),
            template.marker_count()
        );
    }
    Ok(MarkerModel::new(skeleton, attachments)?)
}

fn label_one(
    input: &Path,
    output: &Path,
    template: &Template,
    model: Option<&MarkerModel>,
    args: &Args,
) -> Result<String> {
    let mut file = inputs::read_c3d(input)?;
    let raw = file.to_take().map_err(|e| e.in_file(input))?;
    let config = LabelConfig {
        fit: FitConfig { method: args.fit.into(), accept_mm: args.fit_distance, ..FitConfig::default() },
        keep_unlabeled: args.keep_unlabeled,
        ..LabelConfig::with_method(args.method.into())
    };
    let labeled = match model {
        Some(model) => label_take_with_pose(&raw, template, &config, model),
        None => label_take(&raw, template, &config),
    }
    .with_context(|| format!("{}", input.display()))?;
    file.set_take(&labeled.take).map_err(|e| e.in_file(input))?;
    file.parameters.set_strings(
        "LOCAP",
        "LABELED",
        &[match (&args.template, &args.layout) {
            (Some(t), _) => format!("{} template {}", config.method.name(), t.display()),
            (None, l) => format!("{} layout {}", config.method.name(), l.as_deref().unwrap_or(Path::new("")).display()),
        }],
    );
    let m = template.marker_count();
    let t = labeled.labels.frame_count();
    // Another subject's labels are checked against the template calibrated on the take
    // (its distances), not the template subject's.
    let own = labeled.subject_template(template);
    let confidence = labeled.labels.confidence(&labeled.frames, own, EDGE_TOLERANCE_MM);
    let (lines, uncertain) =
        confidence.parameters(template, labeled.take.first_frame).context("LOCAP:LABEL_UNCERTAIN")?;
    file.parameters.set_strings("LOCAP", "LABEL_CONFIDENCE", &lines);
    file.parameters.set_strings("LOCAP", "LABEL_UNCERTAIN", &uncertain);
    c3d::write_path(&file, output)?;

    let (consistent, checked) = labeled.labels.edge_consistency(&labeled.frames, own, EDGE_TOLERANCE_MM);
    let (near_median, of) = labeled.labels.median_edge_consistency(&labeled.frames, template, EDGE_TOLERANCE_MM);
    let labeled_samples = confidence.labeled();
    let uncertain_samples = confidence.uncertain_samples();
    let percent = |n: usize, of: usize| 100.0 * n as f64 / of.max(1) as f64;
    let fit = &labeled.fit;
    let mut line = format!(
        "{}: {t} frames, {m} markers; {labeled_samples} marker samples labeled ({:.2}% of {}), of which \
         {uncertain_samples} uncertain ({:.2}%: a rigid edge broken by more than {EDGE_TOLERANCE_MM} mm, or no \
         labeled rigid neighbour); {} raw points rejected{}; first fit at frame {}, sure of {} markers, {:.1} mm rms; \
         {:.2}% of checked samples keep their rigid edges within {EDGE_TOLERANCE_MM} mm{}, {:.2}% within \
         {EDGE_TOLERANCE_MM} mm of the edges' median over the take\n",
        output.display(),
        percent(labeled_samples, t * m),
        t * m,
        percent(uncertain_samples, labeled_samples),
        confidence.rejected_points,
        if args.keep_unlabeled { " (kept as *N)" } else { " (dropped)" },
        fit.frame,
        fit.sure_markers,
        fit.rms_mm,
        100.0 * consistent as f64 / checked.max(1) as f64,
        if labeled.calibrated.is_some() { " (of the template calibrated on the take: another subject)" } else { "" },
        100.0 * near_median as f64 / of.max(1) as f64,
    );
    let never: Vec<&str> = confidence
        .per_marker
        .iter()
        .zip(template.names())
        .filter(|(c, _)| c.labeled == 0)
        .map(|(_, n)| n.label.as_str())
        .collect();
    if !never.is_empty() {
        line.push_str(&format!("  never labeled: {}\n", never.join(" ")));
    }
    if let Some(path) = &args.truth {
        line.push_str(&score_against(path, &labeled.frames, &labeled.labels, template)?);
    }
    Ok(line)
}

/// Scores `labels` against a truth file; template markers are matched to the truth's by label.
fn score_against(
    path: &Path,
    frames: &PointFrames,
    labels: &locap_label::Labels,
    template: &Template,
) -> Result<String> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let truth: TruthFile =
        serde_json::from_str(&text).with_context(|| format!("{}: not a truth file", path.display()))?;
    if truth.format != TRUTH_FORMAT {
        bail!("{}: format {:?}, expected {TRUTH_FORMAT:?}", path.display(), truth.format);
    }
    if truth.frames.len() != frames.frame_count() {
        bail!("{}: {} frames of truth for a take of {}", path.display(), truth.frames.len(), frames.frame_count());
    }
    // Truth marker index -> template marker index.
    let to_template: Vec<i32> = truth
        .markers
        .iter()
        .map(|name| {
            let label = locap_core::MarkerName::parse(name).label;
            template.names().iter().position(|n| n.label == label).map_or(-1, |k| k as i32)
        })
        .collect();
    let mut per_point: Vec<Vec<i32>> = Vec::with_capacity(frames.frame_count());
    for (f, columns) in truth.frames.iter().enumerate() {
        let mapped = frames
            .columns(f)
            .iter()
            .map(|&c| {
                let t = columns.get(c as usize).copied().unwrap_or(-1);
                if t >= 0 { to_template.get(t as usize).copied().unwrap_or(-1) } else { -1 }
            })
            .collect();
        per_point.push(mapped);
    }
    let slices: Vec<&[i32]> = per_point.iter().map(|v| v.as_slice()).collect();
    let s = score(&slices, labels, template.marker_count());
    Ok(format!(
        "  against {}: {:.3}% of samples correct, {:.3}% wrong, {:.3}% missed; {} of {} trajectories fully correct\n",
        path.display(),
        s.accuracy(),
        100.0 * s.wrong as f64 / s.samples.max(1) as f64,
        100.0 * s.missed as f64 / s.samples.max(1) as f64,
        s.trajectories_correct,
        s.trajectories
    ))
}
