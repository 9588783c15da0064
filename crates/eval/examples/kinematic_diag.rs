//! Where the kinematic solver's marker residual comes from, on one take (issue 17).
//! `cargo run --release -p locap-eval --example kinematic_diag -- TAKE.c3d [MODEL.osim MARKERS.xml] [--amc ASF AMC]`
//! solves TAKE with the CMU 41-marker layout (or the OpenSim-built one) and prints the
//! residual per frame (median, 90th percentile, worst), per marker and per body, the rotation
//! jumps and the wrists' distances from their markers; with `--amc`, the comparison with that
//! reference solution. Settings of `SequenceConfig` and `IkConfig` are read from environment
//! variables (`CAL_FRAMES`, `CAL_ROUNDS`, `ITER`, `HUBER_MM`, `SMOOTH`, ...; see `config`), the CMU
//! joints' degrees of freedom from `DOFS` (`asf`, `asf-only`, `axes`, `free`; see `main`).

use locap_eval::solver::{compare_motions, rotation_jumps, wrists_within};
use locap_label::ik::solve_sequence;
use locap_nn::kinematic::{CmuLimits, KinematicSolver, cmu_asf_dofs};
use locap_synth::opensim::{XmlSource, layout_from_opensim};
use std::path::Path;

fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

fn config(solver: &mut KinematicSolver) {
    let c = &mut solver.config;
    if let Some(v) = env("CAL_FRAMES") {
        c.calibration_frames = v;
    }
    if let Some(v) = env("CAL_ROUNDS") {
        c.calibration_rounds = v;
    }
    if let Some(v) = env("OFFSET_PRIOR") {
        c.offset_prior = v;
    }
    if let Some(v) = env("BONE_PRIOR") {
        c.bone_prior_mm = v;
    }
    if let Some(v) = env("ITER") {
        c.ik.iterations = v;
    }
    if let Some(v) = env("HUBER_MM") {
        c.ik.huber_mm = v;
    }
    if let Some(v) = env("SMOOTH") {
        c.ik.smooth = v;
    }
    if let Some(v) = env("REST") {
        c.ik.rest = v;
    }
    if let Some(v) = env("CENTRE_W") {
        c.joint_centre_weight = v;
    }
    if let Some(v) = env("CENTRE_PULL") {
        c.ik.centre = v;
    }
    if let Some(v) = env("CENTRE_RADIUS") {
        c.ik.centre_radius_mm = v;
    }
    if let Some(v) = env("LOCKED") {
        c.ik.locked = v;
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

/// Median, 90th and 99th percentile and worst of sorted distances (mm).
fn spread(sorted: &[f64]) -> String {
    format!(
        "median {:.2}, p90 {:.2}, p99 {:.2}, worst {:.2} mm",
        percentile(sorted, 0.5),
        percentile(sorted, 0.9),
        percentile(sorted, 0.99),
        sorted.last().copied().unwrap_or(f64::NAN)
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let take_path = args.first().ok_or("usage: kinematic_diag TAKE.c3d [MODEL.osim MARKERS.xml] [--amc ASF AMC]")?;
    let take = locap_io::c3d::read_path(Path::new(take_path))?.to_take()?;
    let amc_at = args.iter().position(|a| a == "--amc");
    let mut solver = match args.get(1).filter(|a| a.ends_with(".osim")) {
        Some(osim) => {
            let text = std::fs::read_to_string(osim)?;
            let markers_path = args.get(2).ok_or("the OpenSim model needs its MarkerSet.xml")?;
            let markers = std::fs::read_to_string(markers_path)?;
            let layout = layout_from_opensim(
                XmlSource { name: osim, text: &text },
                Some(XmlSource { name: markers_path, text: &markers }),
            )?;
            KinematicSolver::from_layout(&layout)?
        }
        // `DOFS`: the CMU joints' freedom: by default `cmu41()` (the ASF's axes within the
        // ranges CMU's solutions use, wrist centres); `asf` (the ASF's own limits, wrist
        // centres), `asf-only` (the same without wrist centres), `axes` (the ASF's axes, no
        // limits), `free` (three axes each, the solver before the ASF's).
        None => match std::env::var("DOFS").as_deref() {
            Ok("free") => KinematicSolver::cmu41_with(|s| vec![locap_label::ik::JointDofs::Free; s.len()])?,
            Ok("axes") => KinematicSolver::cmu41_with(|s| cmu_asf_dofs(s, CmuLimits::None))?,
            Ok("asf") => KinematicSolver::cmu41_with(|s| cmu_asf_dofs(s, CmuLimits::Asf))?
                .with_joint_centres(locap_nn::kinematic::CMU_WRIST_CENTRES)?,
            Ok("asf-only") => KinematicSolver::cmu41_with(|s| cmu_asf_dofs(s, CmuLimits::Asf))?,
            _ => KinematicSolver::cmu41()?,
        },
    };
    // `SKELETON_ASF`: the CMU solver on that ASF's bones (`KinematicSolver::cmu41_on_bones_of`,
    // as `locap solve --skeleton SUBJECT.asf`; bones held harder with `BONE_PRIOR`).
    if let Ok(path) = std::env::var("SKELETON_ASF") {
        let asf = locap_io::asf_amc::read_asf_path(Path::new(&path))?;
        solver = KinematicSolver::cmu41_on_bones_of(&asf.to_skeleton(asf.mm_per_unit())?)?;
    }
    config(&mut solver);
    let cleaned =
        locap_clean::clean_with(&take, &locap_clean::CleanConfig::default(), &locap_clean::FillConfig::default())?;
    let frames = solver.observed_frames(&cleaned);
    let started = std::time::Instant::now();
    let fit = solve_sequence(solver.lab_model(take.up_axis), &frames, take.frame_rate_hz(), &solver.config)?;
    let seconds = started.elapsed().as_secs_f64();
    println!(
        "{take_path}: {} frames, {:.0} frames/s; residual {:.2} mm RMS; calibration {:.2} -> {:.2} mm, scale {:.3}",
        frames.len(),
        frames.len() as f64 / seconds,
        fit.rms_mm(&frames),
        fit.calibration_rms_mm.0,
        fit.calibration_rms_mm.1,
        fit.scale
    );
    let mut per_frame: Vec<f64> = fit.residual_rms_mm.iter().flatten().copied().collect();
    per_frame.sort_by(f64::total_cmp);
    println!("per frame: {}", spread(&per_frame));
    // Per marker and per body: RMS over the frames where the marker is seen.
    let model = &fit.model;
    let joints = model.skeleton().joints();
    let (mut marker_sum, mut marker_n) = (vec![0.0; model.marker_count()], vec![0usize; model.marker_count()]);
    let mut all_d = Vec::new();
    for (f, (local, root)) in fit.poses.iter().enumerate() {
        for (i, (m, o)) in model.markers_at(local, *root).iter().zip(&frames[f]).enumerate() {
            if let (Some(m), Some(o)) = (m, o) {
                let d = (m - o).norm();
                marker_sum[i] += d * d;
                marker_n[i] += 1;
                all_d.push(d);
            }
        }
    }
    all_d.sort_by(f64::total_cmp);
    let over = all_d.iter().filter(|d| **d > 30.0).count() as f64 / all_d.len().max(1) as f64;
    println!("per sample: {}; share over 30 mm {:.1}%", spread(&all_d), 100.0 * over);
    let mut body: std::collections::BTreeMap<String, (f64, usize)> = Default::default();
    let mut rows: Vec<(f64, String)> = Vec::new();
    for (i, att) in model.attachments().iter().enumerate() {
        let Some(att) = att else { continue };
        if marker_n[i] == 0 {
            continue;
        }
        let e = body.entry(joints[att.joint].name.clone()).or_default();
        e.0 += marker_sum[i];
        e.1 += marker_n[i];
        rows.push(((marker_sum[i] / marker_n[i] as f64).sqrt(), solver.markers()[i].clone()));
    }
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let text: Vec<String> = rows.iter().map(|(r, n)| format!("{n} {r:.1}")).collect();
    println!("per marker (mm RMS): {}", text.join(", "));
    let text: Vec<String> = body.iter().map(|(n, (s, k))| format!("{n} {:.1}", (s / *k as f64).sqrt())).collect();
    println!("per body (mm RMS): {}", text.join(", "));
    // The shipped network on the same cleaned take, where its markers are all there: the
    // throughput ratio of issue 17 in one run.
    let device = Default::default();
    let network = locap_nn::shipped::solver(&device)?;
    if locap_nn::features::marker_order(&take, &network.meta.markers).is_ok() {
        let t0 = std::time::Instant::now();
        let solved = network.solve_cleaned(&cleaned, take.frame_rate_hz())?;
        let network_fps = solved.frame_count() as f64 / t0.elapsed().as_secs_f64();
        println!(
            "throughput: kinematic {:.0} frames/s, network {network_fps:.0} frames/s ({:.0} times)",
            frames.len() as f64 / seconds,
            network_fps * seconds / frames.len() as f64
        );
    }
    let skeleton = fit.model.skeleton().clone();
    let rotations = fit.poses.iter().flat_map(|(local, _)| local.iter().copied()).collect();
    let roots = fit.poses.iter().map(|(_, root)| *root).collect();
    let motion = locap_core::Motion::new(skeleton, rotations, roots, take.frame_rate_hz())?;
    let rotating = solver.rotating();
    let (max, joint, over) = rotation_jumps(&motion, &rotating, 20.0);
    // Each frame pair over 20 degrees: the joint, the frame, the marker residual around it.
    for (f, seen) in frames.iter().enumerate().take(motion.frame_count()).skip(1) {
        let (a, b) = (motion.local_rotations(f - 1), motion.local_rotations(f));
        for (k, (qa, qb)) in a.iter().zip(b).enumerate() {
            let turn = qa.angle_to(qb).to_degrees();
            if rotating[k] && turn > 20.0 {
                let r = |f: usize| fit.residual_rms_mm[f].map_or("-".into(), |r| format!("{r:.1}"));
                println!(
                    "jump: frames {}-{f}, {} {turn:.1} deg, residual {} -> {} mm, markers seen {}",
                    f - 1,
                    motion.skeleton.joints()[k].name,
                    r(f - 1),
                    r(f),
                    seen.iter().flatten().count()
                );
            }
        }
    }
    let wrists = wrists_within(&motion, &take, 60.0);
    println!(
        "largest rotation jump {max:.1} deg ({joint}), {over} frame pairs > 20 deg; wrists within 60 mm: {}",
        wrists.map_or("-".into(), |(share, worst)| format!("{:.1}% (worst {worst:.0} mm)", 100.0 * share))
    );
    // The wrist markers' mean against each joint of the wrist's chain: which joint they straddle.
    for (markers, chain) in [(["LWRA", "LWRB"], ["lwrist", "lhand"]), (["RWRA", "RWRB"], ["rwrist", "rhand"])] {
        let ids: Vec<usize> = markers.iter().filter_map(|m| take.marker_index(m)).collect();
        for joint in chain {
            let Some(j) = motion.skeleton.index_of(joint) else { continue };
            let mut d = Vec::new();
            for f in 0..motion.frame_count() {
                let seen: Vec<locap_core::Vec3> = ids.iter().filter_map(|&m| take.position_mm(f, m)).collect();
                if seen.len() == ids.len() && !seen.is_empty() {
                    let mean = seen.iter().sum::<locap_core::Vec3>() / seen.len() as f64;
                    let p = motion.forward_kinematics(f).positions_mm[j];
                    d.push((locap_core::units::y_up_to_z_up(p) - mean).norm());
                }
            }
            d.sort_by(f64::total_cmp);
            println!(
                "{joint} from its wrist markers' mean: median {:.0}, p99 {:.0} mm",
                percentile(&d, 0.5),
                percentile(&d, 0.99)
            );
        }
    }
    if let Some(at) = amc_at {
        let (asf, amc) = (args.get(at + 1).ok_or("--amc ASF AMC")?, args.get(at + 2).ok_or("--amc ASF AMC")?);
        let asf = locap_io::asf_amc::read_asf_path(Path::new(asf))?;
        let reference = locap_io::asf_amc::read_amc_path(Path::new(amc), &asf, take.frame_rate_hz())?;
        let c = compare_motions(&motion, &reference, &rotating)?;
        // The same wrist check on the reference: where CMU's own skeleton puts the hand joint.
        let (rmax, rjoint, rover) = rotation_jumps(&reference, &vec![true; reference.skeleton.len()], 20.0);
        println!(
            "reference: largest rotation jump {rmax:.1} deg ({rjoint}), {rover} frame pairs > 20 deg; wrists within 60 mm: {}",
            wrists_within(&reference, &take, 60.0)
                .map_or("-".into(), |(share, worst)| format!("{:.1}% (worst {worst:.0} mm)", 100.0 * share))
        );
        println!(
            "against the reference: JPE {:.1} mm (roots aligned {:.1}), JOE {:.2} deg",
            c.jpe_mm, c.jpe_root_aligned_mm, c.joe_deg
        );
        let text: Vec<String> = c
            .per_joint
            .iter()
            .map(|(n, jpe, joe)| format!("{n} {jpe:.0}/{}", joe.map_or("-".into(), |j| format!("{j:.0}"))))
            .collect();
        println!("per joint (JPE mm / JOE deg): {}", text.join(", "));
    }
    Ok(())
}
