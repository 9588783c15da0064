//! Hand motion from the real ART-Human hand export: joint angles refit the captured finger
//! joint positions within a few millimetres, and the hand layout drives synthesis on it.

mod common;

use locap_synth::hand::{FingerLimits, Side, fit_art_hand, hand_layout, procedural_fingers};
use locap_synth::synthesize::{SynthConfig, Variation, synthesize};
use rand::SeedableRng;

#[test]
fn art_hands_fit_and_synthesize() {
    let Some(data) = common::shared_data() else { return };
    let take =
        locap_io::c3d::read_path(&data.join("hands/ART-Human_hands_real_no6dof.c3d")).unwrap().to_take().unwrap();
    for side in [Side::Left, Side::Right] {
        let (motion, report) = fit_art_hand(&take, side).unwrap();
        eprintln!("{side:?}: {} frames, RMS {:.2} mm, max {:.2} mm", report.frames, report.rms_mm, report.max_mm);
        assert_eq!(report.frames, 969);
        // ART's own bone lengths vary by 0-2 mm and its palm is not rigid: a few mm.
        assert!(report.rms_mm < 5.0 && report.max_mm < 20.0, "{report:?}");
        // Real fingers flex, and within anatomical range.
        for (joint, lo, hi) in &report.flexion_range_deg {
            assert!(*lo > -30.0 && *hi < 110.0 && hi - lo > 20.0, "{joint}: {lo}..{hi}");
        }
        let layout = hand_layout(&motion.skeleton, side, 8.0).unwrap();
        let shipped = if side == Side::Left {
            include_str!("../layouts/hand-left.toml")
        } else {
            include_str!("../layouts/hand-right.toml")
        };
        assert_eq!(locap_synth::Layout::from_toml(shipped).unwrap(), layout, "shipped hand layout is stale");
        let proc =
            procedural_fingers(&motion, &FingerLimits::default(), &mut rand::rngs::StdRng::seed_from_u64(1)).unwrap();
        let config = SynthConfig { variation: Variation::none(), ..Default::default() };
        let synth = synthesize(&proc, &layout, &config, &mut rand::rngs::StdRng::seed_from_u64(2)).unwrap();
        assert_eq!(synth.take.marker_count(), 14);
        // Markers stay on the hand: within 25 cm of the wrist marker in every frame.
        let iwr = synth.take.marker_index(&format!("{}IWR", &format!("{side:?}")[..1])).unwrap();
        for f in (0..synth.take.frame_count()).step_by(7) {
            let w = synth.take.position_mm(f, iwr).unwrap();
            for m in 0..14 {
                assert!((synth.take.position_mm(f, m).unwrap() - w).norm() < 250.0);
            }
        }
    }
}
