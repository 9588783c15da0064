//! The shipped CMU 41-marker layout against real data: it is what calibration on CMU 01_01
//! and 02_01 gives (reproducible), its residuals are those of a rigid attachment, and a
//! take synthesized with it has the neighbour-distance structure of a real CMU take.

mod common;

use locap_core::{Motion, Take};
use locap_io::asf_amc::{read_amc_path, read_asf_path};
use locap_synth::Layout;
use locap_synth::calibrate::{CalibrationOptions, calibrate};
use locap_synth::synthesize::{LabFrame, SynthConfig, synthesize};
use rand::SeedableRng;
use std::path::Path;

fn pair(data: &Path, take: &str) -> (Take, Motion) {
    let subject = &take[..2];
    let c3d = locap_io::c3d::read_path(&data.join(format!("cmu-c3d/{take}.c3d"))).unwrap().to_take().unwrap();
    let asf = read_asf_path(&data.join(format!("cmu-asfamc/{subject}/{subject}.asf"))).unwrap();
    let motion = read_amc_path(&data.join(format!("cmu-asfamc/{subject}/{take}.amc")), &asf, 120.0).unwrap();
    (LabFrame::ZUpFromYUp.take_to_motion(&c3d), motion)
}

#[test]
fn shipped_layout_is_the_calibration_of_01_01_and_02_01() {
    let Some(data) = common::shared_data() else { return };
    let template = Layout::from_toml(include_str!("../layouts/cmu41-template.toml")).expect("template parses");
    let (a, b) = (pair(&data, "01_01"), pair(&data, "02_01"));
    let (fitted, report) = calibrate(&template, &[(&a.0, &a.1), (&b.0, &b.1)], &CalibrationOptions::default()).unwrap();
    let shipped = Layout::cmu41();
    for (f, s) in fitted.markers.iter().zip(&shipped.markers) {
        assert_eq!(f.name, s.name);
        assert_eq!(f.offset_mm, s.offset_mm, "{}: shipped offsets differ from a fresh calibration", f.name);
    }
    for m in &report.markers {
        eprintln!("{:<5} rms {:5.1} mm  per take {:?}", m.name, m.rms_mm, m.rms_mm_per_take);
        // Rigid attachment to a solved skeleton: a few cm at most (the AMC solve itself is
        // not exact, and one offset serves two subjects).
        assert!(m.rms_mm < 50.0, "{}: {:.1} mm", m.name, m.rms_mm);
    }
    let rms = report.rms_mm();
    eprintln!("all markers: {rms:.1} mm");
    assert!(rms < 30.0, "{rms}");
    // Markers really follow their bones: the ankle marker sits within a few mm.
    let lank = report.markers.iter().find(|m| m.name == "LANK").unwrap();
    assert!(lank.rms_mm < 10.0);
}

/// Per marker, the mean variance (mm^2) of its distances to its 6 most stable neighbours.
fn profile(take: &Take, layout: &Layout) -> Vec<f64> {
    let scored = locap_clean::neighbours::rank_scored(take, locap_clean::neighbours::Selection::Variance);
    layout
        .markers
        .iter()
        .map(|lm| {
            let i = take.marker_index(&lm.name).unwrap();
            let mut v: Vec<f64> = scored[i].iter().map(|(_, v)| *v).filter(|v| v.is_finite()).collect();
            v.sort_by(f64::total_cmp);
            v.iter().take(6).sum::<f64>() / 6.0
        })
        .collect()
}

#[test]
fn synthesized_take_has_real_neighbour_structure() {
    let Some(data) = common::shared_data() else { return };
    let (real, motion) = pair(&data, "01_01");
    let layout = Layout::cmu41();
    let synth =
        synthesize(&motion, &layout, &SynthConfig::default(), &mut rand::rngs::StdRng::seed_from_u64(1)).unwrap();
    let (p_real, p_synth) = (profile(&real, &layout), profile(&synth.take, &layout));
    let median = |v: &[f64]| {
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    };
    let mut ratios = Vec::new();
    for ((lm, r), s) in layout.markers.iter().zip(&p_real).zip(&p_synth) {
        eprintln!("{:<5} real {:8.1} synth {:8.1} mm^2", lm.name, r, s);
        ratios.push(s / r);
    }
    let (mr, ms) = (median(&p_real), median(&p_synth));
    eprintln!("median neighbour variance: real {mr:.1} mm^2, synthesized {ms:.1} mm^2");
    // Comparable structure: same order of magnitude overall and per marker for most markers,
    // and the profiles rank markers alike (rigid head vs sliding knee).
    assert!(ms / mr > 0.5 && ms / mr < 2.0, "median ratio {}", ms / mr);
    let within = ratios.iter().filter(|r| **r > 1.0 / 3.0 && **r < 3.0).count();
    assert!(within >= 35, "only {within} of 41 markers within 3x");
    let rank = |v: &[f64]| {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|a, b| v[*a].total_cmp(&v[*b]));
        let mut r = vec![0.0; v.len()];
        for (k, i) in idx.into_iter().enumerate() {
            r[i] = k as f64;
        }
        r
    };
    let spearman = |a: &[f64], b: &[f64]| {
        let (ra, rb) = (rank(a), rank(b));
        let n = ra.len() as f64;
        let d2: f64 = ra.iter().zip(&rb).map(|(a, b)| (a - b) * (a - b)).sum();
        1.0 - 6.0 * d2 / (n * (n * n - 1.0))
    };
    let rho = spearman(&p_real, &p_synth);
    eprintln!("Spearman rank correlation of the profiles: {rho:.2}");
    assert!(rho > 0.8, "{rho}");
    // For scale: another real subject and lab day (CMU 85_02, gap-free) against 01_01.
    let other = locap_io::c3d::read_path(&data.join("cmu-c3d/85_02.c3d")).unwrap().to_take().unwrap();
    let p_other = profile(&other, &layout);
    eprintln!(
        "real 85_02: median {:.1} mm^2, Spearman vs real 01_01 {:.2}, vs synthesized {:.2}",
        median(&p_other),
        spearman(&p_real, &p_other),
        spearman(&p_synth, &p_other)
    );
}
