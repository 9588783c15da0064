//! `locap info`: what is in a take.

use crate::inputs;
use anyhow::Result;
use clap::Parser;
use locap_core::GapStatistics;
use locap_io::c3d;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `locap info`.
#[derive(Parser, Debug)]
pub struct Args {
    /// Files to describe: C3D, TRC or CSV takes, BVH motions, ASF skeletons, or folders searched
    /// recursively.
    #[arg(required = true, value_name = "FILE")]
    files: Vec<PathBuf>,
    /// Print one JSON document per file (a JSON array for several files) instead of text.
    #[arg(long, help_heading = "Output")]
    json: bool,
}

/// Everything `info` reports about one take.
#[derive(Serialize, Debug)]
pub struct TakeInfo {
    path: String,
    format: &'static str,
    markers: usize,
    frames: usize,
    frame_rate_hz: f64,
    first_frame: u32,
    duration_s: f64,
    units: String,
    up_axis: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    processor: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    storage: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    vendor: Option<String>,
    analog_channels: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    analog_rate_hz: Option<f64>,
    analog_labels: Vec<String>,
    events: usize,
    warnings: Vec<String>,
    gaps: GapStatistics,
}

/// Runs `locap info`.
pub fn run(args: Args) -> Result<ExitCode> {
    let files = inputs::expand(&args.files, &["c3d", "trc", "csv", "bvh", "asf"])?;
    let (done, failed) = crate::run_takes(&files, "reading", |_, path| describe(path));
    let infos: Vec<Info> = done.into_iter().map(|(_, info)| info).collect();
    let text = if args.json {
        let mut text = if infos.len() == 1 && files.len() == 1 {
            serde_json::to_string_pretty(&infos[0])?
        } else {
            serde_json::to_string_pretty(&infos)?
        };
        text.push('\n');
        text
    } else {
        infos
            .iter()
            .map(|info| match info {
                Info::Take(take) => format_text(take),
                Info::Motion(motion) => format_motion(motion),
            })
            .collect()
    };
    crate::emit(&text)?;
    Ok(if failed > 0 { ExitCode::from(1) } else { ExitCode::SUCCESS })
}

/// What `info` reports about one file: a marker take or a skeleton (with motion).
#[derive(Serialize, Debug)]
#[serde(untagged)]
pub enum Info {
    /// A marker take.
    Take(Box<TakeInfo>),
    /// A skeleton, with or without motion.
    Motion(MotionInfo),
}

/// Everything `info` reports about a skeleton file.
#[derive(Serialize, Debug)]
pub struct MotionInfo {
    path: String,
    format: &'static str,
    joints: usize,
    end_sites: usize,
    joint_names: Vec<String>,
    frames: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    frame_rate_hz: Option<f64>,
    /// Largest side of the rest pose's bounding box, millimetres (height or arm span), a
    /// quick check that the length unit is right.
    rest_extent_mm: f64,
}

fn describe(path: &Path) -> Result<Info> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let motion_info = |format, skeleton: &locap_core::Skeleton, frames, rate| {
        let rest = locap_core::skeleton::forward_kinematics(
            skeleton,
            &vec![locap_core::Quat::identity(); skeleton.len()],
            locap_core::Vec3::zeros(),
        );
        let extent = (0..3)
            .map(|axis| {
                let values = rest.positions_mm.iter().map(|p| p[axis]);
                let (lo, hi) = values.fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
                hi - lo
            })
            .fold(0.0, f64::max);
        MotionInfo {
            path: path.display().to_string(),
            format,
            joints: skeleton.joints().iter().filter(|j| !j.is_end_site).count(),
            end_sites: skeleton.joints().iter().filter(|j| j.is_end_site).count(),
            joint_names: skeleton.joints().iter().filter(|j| !j.is_end_site).map(|j| j.name.clone()).collect(),
            frames,
            frame_rate_hz: rate,
            rest_extent_mm: extent,
        }
    };
    match ext.as_str() {
        "bvh" => {
            let motion = locap_io::bvh::read_bvh_path(path, locap_core::LengthUnit::Centimetre)?;
            Ok(Info::Motion(motion_info(
                "BVH (cm)",
                &motion.skeleton,
                motion.frame_count(),
                Some(motion.frame_rate_hz()),
            )))
        }
        "asf" => {
            let asf = locap_io::asf_amc::read_asf_path(path)?;
            let skeleton = asf.to_skeleton(asf.mm_per_unit()).map_err(|e| e.in_file(path))?;
            Ok(Info::Motion(motion_info("ASF", &skeleton, 0, None)))
        }
        _ => Ok(Info::Take(Box::new(describe_take(path)?))),
    }
}

/// Reads one take and gathers its description.
pub fn describe_take(path: &Path) -> Result<TakeInfo> {
    if inputs::has_extension(path, &["trc", "csv"]) {
        let take = if inputs::has_extension(path, &["trc"]) {
            locap_io::trc::read_trc_path(path)?
        } else {
            locap_io::csv::read_csv_path(path)?
        };
        return Ok(TakeInfo {
            path: path.display().to_string(),
            format: if inputs::has_extension(path, &["trc"]) { "TRC" } else { "CSV" },
            markers: take.marker_count(),
            frames: take.frame_count(),
            frame_rate_hz: take.frame_rate_hz(),
            first_frame: take.first_frame,
            duration_s: take.duration_s(),
            units: "mm".into(),
            up_axis: format!("{:?}", take.up_axis),
            processor: None,
            storage: None,
            vendor: None,
            analog_channels: 0,
            analog_rate_hz: None,
            analog_labels: Vec::new(),
            events: 0,
            warnings: Vec::new(),
            gaps: GapStatistics::of_take(&take),
        });
    }
    let file = c3d::read_path(path)?;
    let take = file.to_take().map_err(|e| e.in_file(path))?;
    let analog = file.analog_info();
    let events = file
        .parameters
        .get("EVENT", "USED")
        .and_then(|p| p.as_i64())
        .map(|n| n.max(0) as usize)
        .unwrap_or(file.header.events.len());
    Ok(TakeInfo {
        path: path.display().to_string(),
        format: "C3D",
        markers: take.marker_count(),
        frames: take.frame_count(),
        frame_rate_hz: take.frame_rate_hz(),
        first_frame: take.first_frame,
        duration_s: take.duration_s(),
        units: file.point_unit().to_string(),
        up_axis: format!("{:?}", take.up_axis),
        processor: Some(file.processor.name()),
        storage: Some(match file.storage {
            c3d::Storage::Int => "int16",
            c3d::Storage::Float => "float32",
        }),
        vendor: file.manufacturer(),
        analog_channels: analog.labels.len(),
        analog_rate_hz: (!analog.labels.is_empty()).then_some(analog.rate_hz),
        analog_labels: analog.labels,
        events,
        warnings: file.warnings.clone(),
        gaps: GapStatistics::of_take(&take),
    })
}

fn format_motion(info: &MotionInfo) -> String {
    let rate = info.frame_rate_hz.map(|r| format!(" at {r} Hz")).unwrap_or_default();
    format!(
        "{}\n  {} skeleton, {} joints + {} end sites, rest pose extent {:.0} mm, {} frames{rate}\n  joints: {}\n",
        info.path,
        info.format,
        info.joints,
        info.end_sites,
        info.rest_extent_mm,
        info.frames,
        info.joint_names.join(" ")
    )
}

fn format_text(info: &TakeInfo) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "{}", info.path);
    let _ = writeln!(
        s,
        "  {} {}, {} markers x {} frames at {} Hz ({:.2} s, first frame {}), units {}, {}-up",
        info.format,
        [info.processor, info.storage].iter().flatten().copied().collect::<Vec<_>>().join(" "),
        info.markers,
        info.frames,
        info.frame_rate_hz,
        info.duration_s,
        info.first_frame,
        info.units,
        info.up_axis
    );
    if let Some(v) = &info.vendor {
        let _ = writeln!(s, "  vendor: {v}");
    }
    if info.analog_channels > 0 {
        let _ = writeln!(s, "  analog: {} channels at {} Hz", info.analog_channels, info.analog_rate_hz.unwrap_or(0.0));
    }
    if info.events > 0 {
        let _ = writeln!(s, "  events: {}", info.events);
    }
    for w in &info.warnings {
        let _ = writeln!(s, "  warning: {w}");
    }
    let g = &info.gaps;
    let _ = writeln!(s, "  missing: {:.2}% of samples in {} gaps", 100.0 * g.missing_fraction(), g.gap_count());
    if !g.markers.is_empty() {
        let width = g.markers.iter().map(|m| m.name.len()).max().unwrap_or(6).max(6);
        let _ = writeln!(s, "  {:<width$}  {:>8}  {:>5}  {:>12}", "marker", "missing", "gaps", "longest gap");
        for m in &g.markers {
            let _ = writeln!(
                s,
                "  {:<width$}  {:>7.2}%  {:>5}  {:>12}",
                m.name,
                100.0 * m.missing_fraction(),
                m.gap_count,
                m.longest_gap
            );
        }
    }
    s
}
