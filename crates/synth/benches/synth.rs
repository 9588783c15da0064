//! Synthesis throughput on real CMU motion (01_01, 2751 frames, 31 joints) with the built-in
//! 41-marker layout: clean markers with subject variation, and Eq. 6 augmentation with the
//! real production gap statistics, in frames per second (criterion reports elements/s).
//!
//! `cargo bench -p locap-synth` (needs `../shared/data`; prints a note and measures nothing
//! without it).

// criterion_group! generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use locap_synth::Layout;
use locap_synth::augment::{AugmentConfig, augment};
use locap_synth::gap_model::GapModel;
use locap_synth::synthesize::{SynthConfig, synthesize};
use rand::SeedableRng;
use std::hint::black_box;
use std::path::Path;

fn bench(c: &mut Criterion) {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let Ok(asf) = locap_io::asf_amc::read_asf_path(&data.join("cmu-asfamc/01/01.asf")) else {
        eprintln!("skipping: ../shared/data not found");
        return;
    };
    let motion = locap_io::asf_amc::read_amc_path(&data.join("cmu-asfamc/01/01_01.amc"), &asf, 120.0).expect("01_01");
    let stats = std::fs::read_to_string(data.join("gap-stats/real-gap-statistics.json")).expect("gap statistics");
    let model = GapModel::from_json(&stats).expect("gap statistics parse");
    let layout = Layout::cmu41();
    let config = SynthConfig::default();
    let mut group = c.benchmark_group("synth_cmu41_01_01");
    group.sample_size(10);
    group.throughput(Throughput::Elements(motion.frame_count() as u64));
    group.bench_function("synthesize", |b| {
        b.iter(|| {
            let mut rng = rand::rngs::StdRng::seed_from_u64(1);
            black_box(synthesize(&motion, &layout, &config, &mut rng).expect("synthesis"))
        })
    });
    let clean = synthesize(&motion, &layout, &config, &mut rand::rngs::StdRng::seed_from_u64(1)).expect("synthesis");
    let augment_config = AugmentConfig { missing_fraction: Some(0.05), ..Default::default() };
    group.bench_function("augment_eq6", |b| {
        b.iter(|| {
            let mut rng = rand::rngs::StdRng::seed_from_u64(2);
            black_box(augment(&clean.take, &model, &augment_config, &mut rng).expect("augment"))
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
