//! Scenarios for the labeler's tests: a rigid limb and a free marker, labeled from the truth
//! of the first frame.

use super::{LabelConfig, Labeler, Method};
use crate::template::Template;
use locap_core::{MarkerName, Take, Vec3};

/// Four markers on a rigid bar-shaped "limb" and one on another moving at its own pace.
pub(super) fn limb(t: f64) -> Vec<Vec3> {
    let origin = Vec3::new(500.0 * (0.7 * t).sin(), 300.0 * t, 1000.0);
    let angle = 1.3 * t;
    let (c, s) = (angle.cos(), angle.sin());
    let rotate = |x: f64, y: f64, z: f64| origin + Vec3::new(c * x - s * y, s * x + c * y, z);
    vec![
        rotate(0.0, 0.0, 0.0),
        rotate(120.0, 0.0, 0.0),
        rotate(0.0, 90.0, 10.0),
        rotate(60.0, 40.0, 150.0),
        Vec3::new(-400.0 + 50.0 * t, 200.0 * (2.0 * t).cos(), 800.0),
    ]
}

/// A template from the truth of the first 60 frames of a scenario (markers missing there
/// are missing in the template).
pub(super) fn template_of(rate: f64, frame: &impl Fn(usize) -> Vec<(Option<usize>, Vec3)>) -> Template {
    let names = (0..5).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
    let mut samples = vec![None; 60 * 5];
    for f in 0..60 {
        for (truth, p) in frame(f) {
            if let Some(m) = truth {
                samples[f * 5 + m] = Some(p);
            }
        }
    }
    Template::from_take(&Take::from_samples(names, &samples, rate).unwrap(), Some(0)).unwrap()
}

pub(super) fn run(
    method: Method,
    rate: f64,
    frames: usize,
    frame: impl Fn(usize) -> Vec<(Option<usize>, Vec3)>,
) -> usize {
    let template = template_of(rate, &frame);
    let mut labeler = Labeler::new(&template, LabelConfig::with_method(method), rate).unwrap();
    let first = frame(0);
    let points: Vec<Vec3> = first.iter().map(|p| p.1).collect();
    let mut initial = vec![None; 5];
    for (j, (truth, _)) in first.iter().enumerate() {
        if let Some(m) = truth {
            initial[*m] = Some(j);
        }
    }
    labeler.start(&template, &points, &initial).unwrap();
    let mut wrong = 0;
    for f in 1..frames {
        let cloud = frame(f);
        let points: Vec<Vec3> = cloud.iter().map(|p| p.1).collect();
        let labels = labeler.step(&points).to_vec();
        for (m, label) in labels.iter().enumerate() {
            let truth = cloud.iter().position(|p| p.0 == Some(m));
            if label.map(|l| l as usize) != truth {
                wrong += 1;
            }
        }
    }
    wrong
}
