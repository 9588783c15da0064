//! The cross-trial labeling case of issue 16 on one take, with details: the template body
//! (segments, joints), the first fit, and per marker the samples missed and wrong.
//! `cargo run --release -p locap-eval --example label_cross -- TAKE.c3d [FPS] [GHOSTS] [no-reacquire]`
//! labels each half of TAKE with the other half as template (points shuffled every frame,
//! GHOSTS near ghosts per frame, default 0; FPS default the take's rate).

use locap_eval::label_bench::{marker_errors, score};
use locap_eval::unlabel::{GhostMode, UnlabelConfig, unlabel};
use locap_label::{FitConfig, LabelConfig, Start, Template, label_frames};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args.first().ok_or("usage: label_cross TAKE.c3d [FPS] [GHOSTS]")?;
    let take = locap_io::c3d::read_path(std::path::Path::new(path))?.to_take()?;
    let fps: f64 = args.get(1).map_or(Ok(take.frame_rate_hz()), |s| s.parse())?;
    let ghosts: usize = args.get(2).map_or(Ok(0), |s| s.parse())?;
    let label_config =
        LabelConfig { reacquire: args.get(3).is_none_or(|s| s != "no-reacquire"), ..LabelConfig::default() };
    let half = take.frame_count() / 2;
    let (first, second) = (take.slice_frames(0..half), take.slice_frames(half..take.frame_count()));
    for (name, template, target) in [("second by first", &first, &second), ("first by second", &second, &first)] {
        let template = Template::from_take(template, None)?;
        let names: Vec<String> = template.names().iter().map(|n| n.label.clone()).collect();
        if let Some(body) = template.body() {
            for (s, seg) in body.segments.iter().enumerate() {
                let ms: Vec<&str> = seg.markers.iter().map(|&i| names[i].as_str()).collect();
                let tol: Vec<String> = seg.tolerance_mm.iter().map(|t| format!("{t:.0}")).collect();
                let span = seg
                    .local_mm
                    .iter()
                    .flat_map(|a| seg.local_mm.iter().map(move |b| (a - b).norm()))
                    .fold(0.0, f64::max);
                println!("segment {s}: {} (tolerances {} mm, span {span:.0} mm)", ms.join(" "), tol.join(" "));
            }
            for j in &body.joints {
                println!("joint {} -> {}: tolerance {:.1} mm", j.parent, j.child, j.tolerance_mm);
            }
            for a in &body.attached {
                println!("attached {} to {}: tolerance {:.1} mm", names[a.marker], a.segment, a.tolerance_mm);
            }
        }
        let config =
            UnlabelConfig { frame_rate_hz: Some(fps), ghosts, ghost_mode: GhostMode::Near, drop: None, seed: 11 };
        let u = unlabel(target, &config)?;
        let started = std::time::Instant::now();
        let (labels, fit) =
            label_frames(&u.frames, &template, &label_config, Start::Fit(FitConfig::default(), target.up_axis), None)?;
        let fit = fit.ok_or("no fit")?;
        let truth = u.truth_by_frame();
        let s = score(&truth, &labels, template.marker_count());
        println!(
            "{name}: fit at frame {} sure of {} markers ({} labeled), {:.1} mm rms; {:.3}% correct, {:.3}% wrong, {:.3}% missed ({:.2} s)",
            fit.frame,
            fit.sure_markers,
            fit.assignment.iter().flatten().count(),
            fit.rms_mm,
            s.accuracy(),
            100.0 * s.wrong as f64 / s.samples as f64,
            100.0 * s.missed as f64 / s.samples as f64,
            started.elapsed().as_secs_f64()
        );
        let errors = marker_errors(&truth, &labels, template.marker_count());
        for (m, (n, (wrong, missed))) in names.iter().zip(errors).enumerate() {
            if wrong + missed > 0 {
                println!(
                    "  {n}: {wrong} wrong, {missed} missed; at the fit {:?}",
                    fit.assignment[m].map(|p| truth[fit.frame][p])
                );
            }
        }
    }
    Ok(())
}
