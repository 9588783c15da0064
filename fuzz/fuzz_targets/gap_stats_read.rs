//! Gap statistics JSON (`locap stats`, `locap info --json`, the paper's form) as `synth
//! --augment`, `train fill --augment`, `unlabel --gap-source` and `bench --gap-source` use it:
//! parsing never panics, and a model that parses drives the Eq. 6 and per-frame occlusion
//! generators on a small take without panicking, keeping the take's shape and never hiding
//! more samples than it has.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_core::{MarkerName, Take, Vec3};
use locap_synth::augment::{AugmentConfig, OcclusionMode, augment};
use locap_synth::gap_model::GapModel;
use rand::SeedableRng;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(model) = GapModel::from_json(text) else { return };
    let names: Vec<MarkerName> = ["LFHD", "RFHD", "C7", "T10"].iter().map(|n| MarkerName::parse(n)).collect();
    let mut take = Take::empty(names, 64, 120.0).unwrap();
    for f in 0..64 {
        for m in 0..4 {
            take.set_position_mm(f, m, Some(Vec3::new(m as f64 * 100.0, f as f64, 1000.0))).unwrap();
        }
    }
    for mode in [OcclusionMode::Eq6, OcclusionMode::PerFrame] {
        let config = AugmentConfig { mode, ..AugmentConfig::default() };
        let mut rng = rand::rngs::StdRng::seed_from_u64(data.len() as u64);
        let Ok(out) = augment(&take, &model, &config, &mut rng) else { continue };
        assert_eq!((out.take.frame_count(), out.take.marker_count()), (64, 4));
    }
});
