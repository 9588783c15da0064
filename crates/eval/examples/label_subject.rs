//! Labeling the raw captures of other subjects (issue 16): `cargo run --release -p locap-eval
//! --example label_subject -- TEMPLATE RAW.c3d...` labels each raw take with defaults (TEMPLATE a
//! labeled C3D take, or a layout `.toml` from `locap layout --from-opensim`) and
//! prints the share of marker samples labeled and, of the labeled samples checked, the share
//! within 20 mm of their rigid edges' median lengths over the labeled take (the issue's
//! check), with how labeling started and its time, and the hinges of the template and of the
//! template calibrated on each take.

use locap_label::{LabelConfig, Template, label_take};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (template_path, raws) = args.split_first().ok_or("usage: label_subject TEMPLATE.c3d|LAYOUT.toml RAW.c3d...")?;
    // A layout (`locap layout --from-opensim`) or a labeled take.
    let template = if template_path.ends_with(".toml") {
        let layout = locap_synth::Layout::from_toml(&std::fs::read_to_string(template_path)?)?;
        locap_eval::label_layout::template_from_layout(&layout)?
    } else {
        Template::from_take(&locap_io::c3d::read_path(std::path::Path::new(template_path))?.to_take()?, None)?
    };
    if let Some(body) = template.body() {
        for j in body.joints.iter().filter(|j| j.hinge.is_some()) {
            let names = |s| segment_names(body, &template, s);
            println!("template hinge between {} and {}", names(j.parent), names(j.child));
        }
    }
    for path in raws {
        let raw = locap_io::c3d::read_path(std::path::Path::new(path))?.to_take()?;
        let started = std::time::Instant::now();
        let labeled = match label_take(&raw, &template, &LabelConfig::default()) {
            Ok(l) => l,
            Err(e) => {
                println!("{path}: {e}");
                continue;
            }
        };
        let seconds = started.elapsed().as_secs_f64();
        let samples = labeled.labels.frame_count() * template.marker_count();
        let (consistent, checked) = labeled.labels.median_edge_consistency(&labeled.frames, &template, 20.0);
        let own = labeled.subject_template(&template);
        let (kept, of) = labeled.labels.edge_consistency(&labeled.frames, own, 20.0);
        println!(
            "{path}: {:.2}% of samples labeled; {:.2}% of {checked} checked within 20 mm of their edges' median \
             ({:.2}% of {of} of the {} template's lengths); fit at frame {}, sure of {}; {:.1} s",
            100.0 * labeled.labeled_samples() as f64 / samples as f64,
            100.0 * consistent as f64 / checked.max(1) as f64,
            100.0 * kept as f64 / of.max(1) as f64,
            if labeled.calibrated.is_some() { "calibrated" } else { "given" },
            labeled.fit.frame,
            labeled.fit.sure_markers,
            seconds
        );
        let t = labeled.labels.frame_count();
        let low: Vec<String> = (0..template.marker_count())
            .filter_map(|m| {
                let n = (0..t).filter(|&f| labeled.labels.get(f, m).is_some()).count();
                (n * 2 < t).then(|| format!("{} {:.0}%", template.names()[m].label, 100.0 * n as f64 / t as f64))
            })
            .collect();
        println!("  labeled in under half the frames: {}", low.join(", "));
        if let Some(body) = own.body() {
            let names = |s| segment_names(body, &template, s);
            for s in 0..body.segments.len() {
                println!("  segment {}", names(s));
            }
            for j in body.joints.iter().filter(|j| j.hinge.is_some()) {
                println!("  hinge between {} and {}", names(j.parent), names(j.child));
            }
        }
    }
    Ok(())
}

/// Segment `s`'s marker labels, separated by spaces.
fn segment_names(body: &locap_label::body::Body, template: &Template, s: usize) -> String {
    body.segments[s].markers.iter().map(|&i| template.names()[i].label.as_str()).collect::<Vec<_>>().join(" ")
}
