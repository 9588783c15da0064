//! How hard should the network's pose hold each joint in the refinement? (issue 17: refined,
//! the spine is further from the truth than the network alone, the hands than the markers
//! alone; docs/benchmarks.md, "The network's pull per joint".)
//!
//! `cargo run --release -p locap-eval --example refine_prior -- INPUT...` solves each input (a
//! folder `locap synth` wrote: every `NAME.c3d` against its `NAME.bvh`) with the network,
//! then refines it under each variant of `VARIANTS`: `;`-separated, each a `,`-separated list
//! of `GROUP=FACTOR` (groups: `spine`, `neck`, `hands`, `wrists`, `arms`, `legs`, `all`, or a
//! joint name; the factor times `KinematicSolver::refine_prior`, replacing the default's),
//! `prior=W` (the pull itself), `offset=W` (the calibration's offset prior), `pass:GROUP=F`
//! (the group's share of its pull in the refinement's first pass) and `kin` (the kinematic
//! solver alone, no network); `base` alone: the default refinement. `MODEL=FILE` refines
//! that network instead of the shipped one, `MODEL=A,B` the mean of several. Prints, pooled by frames,
//! JOE and JPE over all joints and over the joints the markers constrain, then JPE and JOE per
//! joint.

use locap_clean::FillConfig;
use locap_core::{LengthUnit, Motion};
use locap_eval::solver::compare_motions;
use locap_nn::kinematic::KinematicSolver;
use std::path::PathBuf;

/// The joints of a group of the CMU skeleton.
fn group(name: &str) -> Vec<&str> {
    match name {
        "spine" => vec!["lowerback", "upperback", "thorax"],
        "neck" => vec!["lowerneck", "upperneck", "head"],
        "hands" => vec!["lhand", "rhand"],
        "wrists" => vec!["lwrist", "rwrist"],
        "arms" => vec!["lhumerus", "lradius", "rhumerus", "rradius"],
        "legs" => vec!["lfemur", "ltibia", "lfoot", "rfemur", "rtibia", "rfoot"],
        "all" => vec![
            "lfemur",
            "ltibia",
            "lfoot",
            "rfemur",
            "rtibia",
            "rfoot",
            "lowerback",
            "upperback",
            "thorax",
            "lowerneck",
            "upperneck",
            "head",
            "lhumerus",
            "lradius",
            "lwrist",
            "lhand",
            "rhumerus",
            "rradius",
            "rwrist",
            "rhand",
        ],
        other => vec![other],
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut takes: Vec<(PathBuf, Motion)> = Vec::new();
    for dir in std::env::args().skip(1) {
        let mut found: Vec<PathBuf> = std::fs::read_dir(&dir)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "c3d") && !p.to_string_lossy().ends_with(".clean.c3d"))
            .collect();
        found.sort();
        for path in found {
            let truth = locap_io::bvh::read_bvh_path(&path.with_extension("bvh"), LengthUnit::Centimetre)?;
            takes.push((path, truth));
        }
    }
    let variants: Vec<String> =
        std::env::var("VARIANTS").unwrap_or_else(|_| "base".into()).split(';').map(str::to_string).collect();
    // `MODEL=FILE` measures another network in place of the shipped one; `MODEL=A,B` the mean
    // of several (`locap_nn::solver::ensemble`).
    let network = match std::env::var("MODEL") {
        Ok(paths) => {
            let files = paths
                .split(',')
                .map(|p| Ok((p.to_string(), std::fs::read(p)?)))
                .collect::<std::io::Result<Vec<_>>>()?;
            locap_nn::solver::ensemble::from_named_files(&files, &Default::default())?
        }
        Err(_) => locap_nn::shipped::solver(&Default::default())?,
    };
    let template = KinematicSolver::cmu41()?;
    let rotating = template.rotating();
    let constrained = template.constrained().to_vec();
    // Per variant: the solver, and whether it runs alone (`kin`) or refines the network.
    let mut solvers = Vec::new();
    for v in &variants {
        let mut factors = Vec::new();
        let mut solver = template.clone();
        let mut alone = false;
        for item in v.split(',').filter(|s| *s != "base" && !s.is_empty()) {
            if item == "kin" {
                alone = true;
                continue;
            }
            let (g, f) = item.split_once('=').ok_or("GROUP=FACTOR")?;
            let f: f64 = f.parse()?;
            match g {
                "offset" => solver.config.offset_prior = f,
                "prior" => solver.refine_prior = f,
                "huber" => solver.config.ik.prior_huber_deg = f,
                "bias" => solver.bias_huber_deg = f,
                "biaswin" => solver.bias_half_window_s = f,
                g if g.starts_with("pass:") => {
                    let joints: Vec<(&str, f64)> = group(&g[5..]).into_iter().map(|j| (j, f)).collect();
                    solver = solver.with_bias_pass_factors(&joints)?;
                }
                _ => factors.extend(group(g).into_iter().map(|j| (j, f))),
            }
        }
        solvers.push((solver.with_refine_prior_factors(&factors)?, alone));
    }
    let names: Vec<String> = std::iter::once("network".to_string()).chain(variants.iter().cloned()).collect();
    // Per method, per joint: frame-weighted JOE and JPE sums.
    let joints = template.skeleton().len();
    let mut joe = vec![vec![0.0; joints]; names.len()];
    let mut jpe = vec![vec![0.0; joints]; names.len()];
    let mut frames = 0.0;
    for (path, truth) in &takes {
        let take = locap_io::c3d::read_path(path)?.to_take()?;
        let (prior, cleaned) = network.solve(&take, &FillConfig::default())?;
        let mut motions = vec![prior.clone()];
        for (k, alone) in &solvers {
            let solved = if *alone {
                k.solve_cleaned(&cleaned, take.frame_rate_hz())?
            } else {
                k.refine(&cleaned, take.frame_rate_hz(), &prior)?
            };
            motions.push(solved.0);
        }
        let n = take.frame_count() as f64;
        for (m, motion) in motions.iter().enumerate() {
            let c = compare_motions(motion, truth, &rotating)?;
            for (name, p, o) in &c.per_joint {
                let Some(j) = template.skeleton().index_of(name) else { continue };
                jpe[m][j] += p * n;
                joe[m][j] += o.unwrap_or(f64::NAN) * n;
            }
        }
        frames += n;
        eprintln!("{} done", path.display());
    }
    let mean = |v: &[f64], keep: &dyn Fn(usize) -> bool| {
        let kept: Vec<f64> = (0..joints).filter(|&j| keep(j) && v[j].is_finite()).map(|j| v[j] / frames).collect();
        kept.iter().sum::<f64>() / kept.len() as f64
    };
    println!("{:<34} {:>7} {:>7} {:>7} {:>7}", "variant", "JOE", "JOEc", "JPE", "JPEc");
    for (m, name) in names.iter().enumerate() {
        println!(
            "{name:<34} {:7.2} {:7.2} {:7.2} {:7.2}",
            mean(&joe[m], &|j| rotating[j]),
            mean(&joe[m], &|j| rotating[j] && constrained[j]),
            mean(&jpe[m], &|_| true),
            mean(&jpe[m], &|j| constrained[j]),
        );
    }
    println!("JPE per joint (mm)");
    for j in 0..joints {
        let mut line = format!("{:<13}", template.skeleton().joints()[j].name);
        for row in &jpe {
            line += &format!(" {:7.2}", row[j] / frames);
        }
        println!("{line}");
    }
    println!("JOE per joint (deg), constrained marked *");
    for j in (0..joints).filter(|&j| rotating[j]) {
        let mut line =
            format!("{:<12}{}", template.skeleton().joints()[j].name, if constrained[j] { "*" } else { " " });
        for row in &joe {
            line += &format!(" {:7.2}", row[j] / frames);
        }
        println!("{line}");
    }
    Ok(())
}
