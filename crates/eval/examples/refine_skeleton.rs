//! Does the refinement place joints better on the skeleton the network predicted for the take
//! than on the shipped template? (issue 17: the kinematic solver's JPE on synthetic takes is
//! almost all a constant offset per joint, where its calibrated skeleton differs from the
//! subject's; docs/benchmarks.md, "The network's skeleton in the refinement".)
//!
//! `cargo run --release -p locap-eval --example refine_skeleton -- INPUT...` solves each input:
//! a folder `locap synth` wrote (every `NAME.c3d` against its `NAME.bvh`, the truth), `TAKE.c3d
//! ASF AMC` (a real take against CMU's solution) or `TAKE.c3d -` (no reference: the tracking
//! checks only). Each is solved by the network alone and refined with
//! `KinematicSolver::network_skeleton` at each share of `SHARES` (comma-separated, default
//! `0,0.5,1`; 0 is the default refinement). Prints JOE / JPE against the reference per take
//! and pooled by frames, and each refinement's marker residual, largest rotation jump and
//! wrists within 60 mm of their markers.

use locap_clean::FillConfig;
use locap_core::{LengthUnit, Motion};
use locap_eval::solver::{compare_motions, rotation_jumps, wrists_within};
use locap_nn::kinematic::KinematicSolver;
use std::path::{Path, PathBuf};

/// A take and its reference motion, if any.
type Job = (PathBuf, Option<Motion>);

/// A job for each input.
fn jobs(args: &[String]) -> Result<Vec<Job>, Box<dyn std::error::Error>> {
    let mut jobs = Vec::new();
    let mut at = 0;
    while at < args.len() {
        let arg = Path::new(&args[at]);
        if arg.extension().is_some_and(|e| e == "c3d") {
            if args.get(at + 1).is_some_and(|a| a == "-") {
                jobs.push((arg.to_path_buf(), None));
                at += 2;
                continue;
            }
            let (asf, amc) = (args.get(at + 1).ok_or("TAKE.c3d ASF AMC")?, args.get(at + 2).ok_or("TAKE.c3d ASF AMC")?);
            let asf = locap_io::asf_amc::read_asf_path(Path::new(asf))?;
            jobs.push((arg.to_path_buf(), Some(locap_io::asf_amc::read_amc_path(Path::new(amc), &asf, 120.0)?)));
            at += 3;
            continue;
        }
        let mut takes: Vec<_> = std::fs::read_dir(arg)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "c3d") && !p.to_string_lossy().ends_with(".clean.c3d"))
            .collect();
        takes.sort();
        for path in takes {
            let truth = locap_io::bvh::read_bvh_path(&path.with_extension("bvh"), LengthUnit::Centimetre)?;
            jobs.push((path, Some(truth)));
        }
        at += 1;
    }
    Ok(jobs)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let shares: Vec<f64> = std::env::var("SHARES")
        .unwrap_or_else(|_| "0,0.5,1".into())
        .split(',')
        .map(|s| s.trim().parse())
        .collect::<Result<_, _>>()?;
    let network = locap_nn::shipped::solver(&Default::default())?;
    let template = KinematicSolver::cmu41()?;
    let rotating = template.rotating();
    let solvers: Vec<KinematicSolver> = shares
        .iter()
        .map(|&w| {
            let mut k = template.clone();
            k.network_skeleton = w;
            k
        })
        .collect();
    let mut names = vec!["network".to_string()];
    names.extend(shares.iter().map(|w| format!("refined, share {w}")));
    // Per method: frame-weighted sums of JOE, JPE, JPE with roots aligned, root error.
    let mut sums = vec![[0.0; 4]; names.len()];
    let mut frames = 0.0;
    for (path, reference) in jobs(&args)? {
        let take = locap_io::c3d::read_path(&path)?.to_take()?;
        let (prior, cleaned) = network.solve(&take, &FillConfig::default())?;
        let mut motions = vec![prior.clone()];
        let mut checks = format!("{}: residual mm, largest jump deg, wrists within 60 mm:", path.display());
        for k in &solvers {
            let (motion, report) = k.refine(&cleaned, take.frame_rate_hz(), &prior)?;
            let (jump, _, over) = rotation_jumps(&motion, &rotating, 20.0);
            let wrists = wrists_within(&motion, cleaned.take(), 60.0).map_or(f64::NAN, |w| 100.0 * w.0);
            checks += &format!("  {:.1} {jump:.1} ({over} over 20) {wrists:.1}%", report.residual_rms_mm);
            motions.push(motion);
        }
        println!("{checks}");
        let Some(reference) = reference else { continue };
        let n = take.frame_count() as f64;
        let mut line = format!("{}: JOE / JPE (root):", path.display());
        for (k, motion) in motions.iter().enumerate() {
            let joints = if k == 0 { &network.meta.rotating } else { &rotating };
            let c = compare_motions(motion, &reference, joints)?;
            for (sum, v) in sums[k].iter_mut().zip([c.joe_deg, c.jpe_mm, c.jpe_root_aligned_mm, c.root_mm]) {
                *sum += v * n;
            }
            line += &format!("  {:.2} / {:.2} ({:.1})", c.joe_deg, c.jpe_mm, c.root_mm);
        }
        frames += n;
        println!("{line}");
    }
    for (name, s) in names.iter().zip(sums) {
        println!(
            "{name}: JOE {:.2} deg, JPE {:.2} mm (roots aligned {:.2}, root {:.2})",
            s[0] / frames,
            s[1] / frames,
            s[2] / frames,
            s[3] / frames
        );
    }
    Ok(())
}
