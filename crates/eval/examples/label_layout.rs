//! Labeling from a layout alone (issue 16, item 1b), with details: the layout's template body,
//! the first fit, and per marker the samples missed and wrong.
//! `cargo run --release -p locap-eval --example label_layout -- LAYOUT.toml TAKE.c3d [FPS] [GHOSTS]`
//! shuffles the points of the labeled TAKE every frame (GHOSTS near ghosts per frame, default 0;
//! FPS default the take's rate, seed 11) and labels it with the layout's template; TAKE's
//! labels are the truth (matched to the layout's markers by label). Before labeling it prints
//! how far the model is from the take's subject: per segment the rigid residual of the model's
//! shape fitted to the take's markers and the pair distance that differs most, per joint how
//! far the centre as placed by the two segments' true placements misses.

use locap_eval::label_bench::{marker_errors, score, truth_in_template_order};
use locap_eval::label_layout::template_from_layout;
use locap_eval::unlabel::{GhostMode, UnlabelConfig, unlabel};
use locap_label::{FitConfig, LabelConfig, Start, label_frames};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: label_layout LAYOUT.toml TAKE.c3d [FPS] [GHOSTS]";
    let layout = locap_synth::Layout::from_toml(&std::fs::read_to_string(args.first().ok_or(usage)?)?)?;
    let take = locap_io::c3d::read_path(std::path::Path::new(args.get(1).ok_or(usage)?))?.to_take()?;
    let fps: f64 = args.get(2).map_or(Ok(take.frame_rate_hz()), |s| s.parse())?;
    let ghosts: usize = args.get(3).map_or(Ok(0), |s| s.parse())?;
    let template = template_from_layout(&layout)?;
    let names: Vec<String> = template.names().iter().map(|n| n.label.clone()).collect();
    if let Some(body) = template.body() {
        for (s, seg) in body.segments.iter().enumerate() {
            let ms: Vec<&str> = seg.markers.iter().map(|&i| names[i].as_str()).collect();
            let tol: Vec<String> = seg.tolerance_mm.iter().map(|t| format!("{t:.0}")).collect();
            println!("segment {s}: {} (tolerances {} mm)", ms.join(" "), tol.join(" "));
        }
        // The model's distances against the take's (mean over the frames both are seen).
        let column = |i: usize| take.markers().iter().position(|n| n.label == names[i]);
        for (s, seg) in body.segments.iter().enumerate() {
            let mut worst = (0.0f64, String::new());
            for a in 0..seg.markers.len() {
                for b in a + 1..seg.markers.len() {
                    let (Some(ca), Some(cb)) = (column(seg.markers[a]), column(seg.markers[b])) else { continue };
                    let d: Vec<f64> = (0..take.frame_count())
                        .filter_map(|f| Some((take.position_mm(f, ca)? - take.position_mm(f, cb)?).norm()))
                        .collect();
                    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
                    let model = (seg.local_mm[a] - seg.local_mm[b]).norm();
                    if (mean - model).abs() > worst.0.abs() {
                        worst = (
                            mean - model,
                            format!(
                                "{}-{} take {mean:.0} model {model:.0}",
                                names[seg.markers[a]], names[seg.markers[b]]
                            ),
                        );
                    }
                }
            }
            // The model's shape fitted to the take's markers (Kabsch), residual per marker.
            let mut res = vec![0.0; seg.markers.len()];
            let mut n = 0;
            for f in (0..take.frame_count()).step_by(20) {
                let pts: Option<Vec<_>> = seg.markers.iter().map(|&i| take.position_mm(f, column(i)?)).collect();
                let Some(pts) = pts else { continue };
                let Some(t) = locap_clean::procrustes::align(&seg.local_mm, &pts) else { continue };
                for k in 0..pts.len() {
                    res[k] += (t.apply(&seg.local_mm[k]) - pts[k]).norm();
                }
                n += 1;
            }
            let res: Vec<String> = res.iter().map(|r| format!("{:.0}", r / n.max(1) as f64)).collect();
            println!("segment {s}: rigid residuals {} mm", res.join(" "));
            println!("segment {s}: worst distance {:+.0} mm ({})", worst.0, worst.1);
        }
        let place = |s: usize, f: usize| {
            let seg = &body.segments[s];
            let (from, to): (Vec<_>, Vec<_>) = seg
                .markers
                .iter()
                .zip(&seg.local_mm)
                .filter_map(|(&i, l)| Some((*l, take.position_mm(f, column(i)?)?)))
                .unzip();
            locap_clean::procrustes::align(&from, &to)
        };
        for j in &body.joints {
            let misses: Vec<f64> = (0..take.frame_count())
                .step_by(20)
                .filter_map(|f| {
                    Some((place(j.parent, f)?.apply(&j.parent_mm) - place(j.child, f)?.apply(&j.child_mm)).norm())
                })
                .collect();
            let mean = misses.iter().sum::<f64>() / misses.len().max(1) as f64;
            let max = misses.iter().copied().fold(0.0, f64::max);
            // The miss in the child's frame (the model's rest axes: y along a limb's bone).
            let mut axes = [0.0f64; 3];
            let mut n = 0usize;
            for f in (0..take.frame_count()).step_by(20) {
                let (Some(p), Some(c)) = (place(j.parent, f), place(j.child, f)) else { continue };
                let miss = c.rotation.inverse() * (p.apply(&j.parent_mm) - c.apply(&j.child_mm));
                for (a, v) in axes.iter_mut().zip(miss.iter()) {
                    *a += v.abs();
                }
                n += 1;
            }
            let axes = axes.map(|a| a / n.max(1) as f64);
            println!(
                "joint {} -> {}: tolerance {:.1} mm, miss on the take mean {mean:.0} max {max:.0} mm \
                 (in the child's frame x {:.0} y {:.0} z {:.0})",
                j.parent, j.child, j.tolerance_mm, axes[0], axes[1], axes[2]
            );
        }
        for a in &body.attached {
            println!("attached {} to {}: tolerance {:.1} mm", names[a.marker], a.segment, a.tolerance_mm);
        }
    }
    let config = UnlabelConfig { frame_rate_hz: Some(fps), ghosts, ghost_mode: GhostMode::Near, drop: None, seed: 11 };
    let u = unlabel(&take, &config)?;
    let truth = truth_in_template_order(&u.truth_by_frame(), &template, &take);
    let truth: Vec<&[i32]> = truth.iter().map(Vec::as_slice).collect();
    let started = std::time::Instant::now();
    let (labels, fit) = label_frames(
        &u.frames,
        &template,
        &LabelConfig::default(),
        Start::Fit(FitConfig::default(), take.up_axis),
        None,
    )?;
    let fit = fit.ok_or("no fit")?;
    let s = score(&truth, &labels, template.marker_count());
    println!(
        "fit at frame {} sure of {} markers, {:.1} mm rms; {:.3}% correct, {:.3}% wrong, {:.3}% missed ({:.2} s)",
        fit.frame,
        fit.sure_markers,
        fit.rms_mm,
        s.accuracy(),
        100.0 * s.wrong as f64 / s.samples as f64,
        100.0 * s.missed as f64 / s.samples as f64,
        started.elapsed().as_secs_f64()
    );
    for ((wrong, missed), n) in marker_errors(&truth, &labels, template.marker_count()).into_iter().zip(&names) {
        if wrong + missed > 0 {
            println!("  {n}: {wrong} wrong, {missed} missed");
        }
    }
    Ok(())
}
