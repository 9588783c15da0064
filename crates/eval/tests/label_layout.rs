//! Labeling from the OpenSim-built layout alone (issue 16, item 1b): the real 62-marker take
//! `KneeltoProne01` (240 Hz, points shuffled every frame), no labeled take, through the bench's
//! `layout` rows (the same call `locap label --layout` makes).

use locap_eval::label_bench::{GhostCount, LAYOUT, LabelBenchConfig, run};
use locap_eval::label_layout::template_from_layout;
use locap_label::LabelConfig;
use locap_synth::opensim::{XmlSource, layout_from_opensim};

#[test]
fn kneel_to_prone_from_the_opensim_layout() {
    let Some(dir) = locap_testkit::shared_data().map(|d| d.join("labeling")) else { return };
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).unwrap();
    let (model, markers) = (read("Rajagopal2015_mod.osim"), read("MarkerSet.xml"));
    let layout = layout_from_opensim(
        XmlSource { name: "Rajagopal2015_mod.osim", text: &model },
        Some(XmlSource { name: "MarkerSet.xml", text: &markers }),
    )
    .unwrap();
    let template = template_from_layout(&layout).unwrap();
    assert!(template.is_model() && template.marker_count() == 62);
    // The knees turn about one axis (knee_angle): hinges, from the layout's degrees of freedom.
    let body = template.body().unwrap();
    for shank in ["RSHPA", "LSHPA"] {
        let marker = template.names().iter().position(|n| n.label == shank).unwrap();
        let (segment, _) = body.member[marker].unwrap();
        let knee = body.joints.iter().find(|j| j.child == segment).unwrap();
        assert!(knee.hinge.is_some_and(|h| h.child_axis.z.abs() > 0.99), "{shank}: {knee:?}");
    }
    let take = locap_io::c3d::read_path(&dir.join("KneeltoProne01.c3d")).unwrap().to_take().unwrap();
    let config = LabelBenchConfig {
        frame_rates_hz: vec![240.0, 30.0],
        ghosts: vec![GhostCount::Fixed(0)],
        drop: None,
        methods: vec![LabelConfig::default()],
        cross_trial: false,
        layout: Some(template),
        ..LabelBenchConfig::default()
    };
    let report = run(&[("KneeltoProne01".into(), take)], &config).unwrap();
    let row = |fps: f64| {
        let row = report.rows.iter().find(|r| r.template == LAYOUT && r.frame_rate_hz == fps).expect("a layout row");
        assert_eq!(row.score.failed_fits, 0, "{}", report.table());
        row
    };
    // Measured 100% right (docs/benchmarks.md, "Plates and landmarks"; the issue asks >= 99%,
    // <= 0.5% wrong). Before the landmark allowance the left shank was never labeled (91.9%);
    // with it and before the mirror-image check RFTM and RFTF stayed exchanged (96.8%, 3.2%).
    let full = row(240.0);
    assert!(full.accuracy >= 99.0 && full.wrong_percent <= 0.5, "{}", report.table());
    // Measured 96.8% right, 0% wrong: the hands alone missed (the issue asks >= 95% at 30 fps).
    // Before the segment check against the layout's shape, LFAPP and LULN stayed exchanged.
    let low = row(30.0);
    assert!(low.accuracy >= 95.0 && low.wrong_percent <= 0.5, "{}", report.table());
}
