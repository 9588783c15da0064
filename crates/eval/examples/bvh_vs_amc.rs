//! A solved take against CMU's own solution, joint by joint (issue 17's real-take check).
//! `cargo run --release -p locap-eval --example bvh_vs_amc -- SOLVED.bvh (ASF AMC | TRUTH.bvh)`
//! reads the BVH `locap solve` wrote (centimetres, the animation tools' Y-up), turns it back
//! into the motion's own frame and compares it with CMU's AMC, or with the motion `locap synth`
//! made the take from (`NAME.bvh`); it prints JPE (also with the roots aligned), the root's
//! error, JOE, and each joint's JPE / JOE, worst first. Then how much of each joint's position error is a constant
//! offset in its reference parent's frame (a skeleton or calibration difference: the joint
//! centre sits elsewhere on its bone), and the JPE left with that offset removed.

use locap_core::units::y_up_to_z_up_rotation;
use locap_core::{LengthUnit, Motion, UpAxis, Vec3};
use locap_eval::solver::compare_motions;
use locap_io::axes::motion_from_tools_y_up;
use std::path::Path;

/// `motion` without its first `frames` frames.
fn skip(motion: &Motion, frames: usize) -> Result<Motion, Box<dyn std::error::Error>> {
    let n = motion.frame_count();
    let rotations = (frames..n).flat_map(|f| motion.local_rotations(f).to_vec()).collect();
    let roots = (frames..n).map(|f| motion.root_position_mm(f)).collect();
    Ok(Motion::new(motion.skeleton.clone(), rotations, roots, motion.frame_rate_hz())?)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: bvh_vs_amc SOLVED.bvh (ASF AMC | TRUTH.bvh)";
    let bvh = args.first().ok_or(usage)?;
    let solved = locap_io::bvh::read_bvh_path(Path::new(bvh), LengthUnit::Centimetre)?;
    let solved = motion_from_tools_y_up(&solved, y_up_to_z_up_rotation(), UpAxis::Z);
    let reference = match &args[1..] {
        // The motion `locap synth` made a take from (its `NAME.bvh`: the motion's own frame).
        [truth] => locap_io::bvh::read_bvh_path(Path::new(truth), LengthUnit::Centimetre)?,
        [asf, amc] => {
            let asf = locap_io::asf_amc::read_asf_path(Path::new(asf))?;
            locap_io::asf_amc::read_amc_path(Path::new(amc), &asf, solved.frame_rate_hz())?
        }
        _ => return Err(usage.into()),
    };
    // `LAG=k` compares solved frame f with reference frame f + k (a timing check).
    let lag: i64 = std::env::var("LAG").ok().and_then(|v| v.parse().ok()).unwrap_or(0);
    let (solved, reference) = (skip(&solved, (-lag).max(0) as usize)?, skip(&reference, lag.max(0) as usize)?);
    let c = compare_motions(&solved, &reference, &vec![true; solved.skeleton.len()])?;
    println!(
        "{} frames, {} joints: JPE {:.1} mm (roots aligned {:.1}, root {:.1}), JOE {:.2} deg",
        c.frames, c.joints, c.jpe_mm, c.jpe_root_aligned_mm, c.root_mm, c.joe_deg
    );
    let mut joints = c.per_joint.clone();
    joints.sort_by(|a, b| b.1.total_cmp(&a.1));
    let text: Vec<String> = joints
        .iter()
        .map(|(n, jpe, joe)| format!("{n} {jpe:.0}/{}", joe.map_or("-".into(), |j| format!("{j:.0}"))))
        .collect();
    println!("per joint (JPE mm / JOE deg), worst first: {}", text.join(", "));

    // The error of each joint in its reference parent's frame, per frame.
    let pairs: Vec<(usize, usize, usize)> = solved
        .skeleton
        .joints()
        .iter()
        .enumerate()
        .filter_map(|(i, j)| {
            let r = reference.skeleton.index_of(&j.name)?;
            Some((i, r, reference.skeleton.joints()[r].parent.unwrap_or(r)))
        })
        .collect();
    let mut local: Vec<Vec<Vec3>> = vec![Vec::with_capacity(c.frames); pairs.len()];
    for f in 0..c.frames {
        let (a, b) = (solved.forward_kinematics(f), reference.forward_kinematics(f));
        for (k, &(i, r, p)) in pairs.iter().enumerate() {
            local[k].push(b.rotations[p].inverse() * (a.positions_mm[i] - b.positions_mm[r]));
        }
    }
    let (mut total, mut left, mut n) = (0.0, 0.0, 0.0);
    let mut rows = Vec::new();
    let mut steps = Vec::new();
    for (k, errors) in local.iter().enumerate() {
        let bias = errors.iter().fold(Vec3::zeros(), |s, e| s + e) / errors.len() as f64;
        let rest = errors.iter().map(|e| (e - bias).norm()).sum::<f64>() / errors.len() as f64;
        let all = errors.iter().map(|e| e.norm()).sum::<f64>() / errors.len() as f64;
        // How fast the error changes: frame-to-frame (jitter) against its size.
        let step = errors.windows(2).map(|w| (w[1] - w[0]).norm()).sum::<f64>() / (errors.len().max(2) - 1) as f64;
        steps.push((solved.skeleton.joints()[pairs[k].0].name.clone(), step));
        total += all * errors.len() as f64;
        left += rest * errors.len() as f64;
        n += errors.len() as f64;
        rows.push((solved.skeleton.joints()[pairs[k].0].name.clone(), all, bias, rest));
    }
    println!(
        "JPE {:.1} mm; with each joint's constant offset in its parent's frame removed {:.1} mm",
        total / n,
        left / n
    );
    rows.sort_by(|a, b| b.2.norm().total_cmp(&a.2.norm()));
    let text: Vec<String> = rows
        .iter()
        .map(|(name, all, bias, rest)| {
            format!(
                "{name} {all:.0} = offset {:.0} ({:.0} {:.0} {:.0}) + {rest:.0}",
                bias.norm(),
                bias.x,
                bias.y,
                bias.z
            )
        })
        .collect();
    let changes: Vec<String> = steps.iter().map(|(n, s)| format!("{n} {s:.1}")).collect();
    println!("error change per frame (mm): {}", changes.join(", "));
    println!("per joint, largest offset first (mm, parent frame):\n  {}", text.join("\n  "));
    Ok(())
}
