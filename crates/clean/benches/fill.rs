//! Fill kernels on a synthetic 41-marker x 72,000-frame take (10 minutes at 120 Hz) with 2%
//! of the samples hidden in 60-frame gaps: EDM against linear interpolation (the baseline,
//! measured in the same run; compare the ratio, the machine is shared).
//!
//! `cargo bench -p locap-clean`

// criterion_group! generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use locap_clean::{FillConfig, FillMethod, fill_gaps};
use locap_core::{MarkerName, Take, Vec3};
use std::hint::black_box;

/// Five rigid clusters of 8-9 markers turning and travelling: body segments, roughly.
fn take() -> Take {
    let markers = 41;
    let frames = 72_000;
    let names = (0..markers).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
    let mut samples = Vec::with_capacity(markers * frames);
    for f in 0..frames {
        let s = f as f64 / 120.0;
        for m in 0..markers {
            let segment = (m / 9) as f64;
            let rot = nalgebra::Rotation3::from_euler_angles(0.3 * (s + segment).sin(), 0.5 * s, 0.2 * segment);
            let local = Vec3::new(60.0 * (m % 3) as f64, 40.0 * (m % 5) as f64, 30.0 * (m % 2) as f64 + 10.0 * segment);
            samples.push(Some(Vec3::new(500.0 * s.sin(), 300.0 * segment, 900.0) + rot * local));
        }
    }
    let mut take = Take::from_samples(names, &samples, 120.0).expect("valid take");
    // 2% of the samples: one 60-frame gap per marker every 3000 frames, staggered.
    for m in 0..markers {
        let mut start = 100 + 71 * m;
        while start + 60 < frames {
            for f in start..start + 60 {
                take.set_position_mm(f, m, None).expect("hiding a sample");
            }
            start += 3000;
        }
    }
    take
}

fn bench(c: &mut Criterion) {
    let take = take();
    let mut group = c.benchmark_group("fill_41x72000_2pct");
    group.sample_size(10);
    for method in [FillMethod::Linear, FillMethod::Edm] {
        let config = FillConfig { method, ..FillConfig::default() };
        group.bench_function(method.name(), |b| b.iter(|| black_box(fill_gaps(black_box(&take), &config))));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
