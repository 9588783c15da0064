//! Labeling throughput on the example take shipped with locap (a 10 s cut of CMU 01_01,
//! 41 markers at 120 Hz, real gaps), points shuffled every frame: soft graph matching against
//! the unary (UGM) and closest-point baselines measured in the same run. Compare ratios; the
//! machine is shared. One iteration labels the whole take on one core.
//!
//! `cargo bench -p locap-label`

// criterion_group! generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use locap_label::{LabelConfig, Method, PointFrames, Start, Template, label_frames};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/cmu_01_01_last10s.c3d");
    let take = locap_io::c3d::read_path(std::path::Path::new(path)).expect("example take").to_take().expect("take");
    let template = Template::from_take(&take, None).expect("template");
    // Shuffled clouds with the truth of frame 0 to start from.
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let mut frames = PointFrames::with_rate(take.frame_rate_hz());
    let mut initial = vec![None; template.marker_count()];
    for f in 0..take.frame_count() {
        let mut cloud: Vec<(usize, locap_core::Vec3)> =
            (0..take.marker_count()).filter_map(|m| take.position_mm(f, m).map(|p| (m, p))).collect();
        cloud.shuffle(&mut rng);
        if f == 0 {
            for (j, (m, _)) in cloud.iter().enumerate() {
                initial[*m] = Some(j);
            }
        }
        frames.push_frame(cloud.iter().map(|(m, p)| (*m as u32, *p)));
    }
    let mut group =
        c.benchmark_group(format!("label {} frames x {} markers", frames.frame_count(), template.marker_count()));
    group.sample_size(20);
    for method in Method::ALL {
        let config = LabelConfig::with_method(method);
        group.bench_function(method.name(), |b| {
            b.iter(|| {
                black_box(label_frames(&frames, &template, &config, Start::Known(&initial), None).expect("labels"))
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
