//! Building the viewer page of a 10-minute take: 41 markers x 72,000 frames at 120 Hz, each
//! marker on its own smooth path with 0.2 mm of jitter (a repeating signal would flatter the
//! compressor). `render` is the whole page (neighbour edges, quantising, second differences,
//! zlib, base64, template); `pack` is zlib + base64 of the positions alone.
//!
//! `cargo bench -p locap-view`

// criterion_group! generates a public function that cannot carry a doc comment.
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use locap_core::{MarkerName, Take, Vec3};
use locap_view::encode::{self, Quantiser};
use std::hint::black_box;

fn take() -> Take {
    let (markers, frames) = (41usize, 72_000usize);
    let names = (0..markers).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
    let mut jitter = 0x2545_F491_4F6C_DD1Du64;
    let samples: Vec<Option<Vec3>> = (0..frames * markers)
        .map(|i| {
            let (t, m) = ((i / markers) as f64 / 120.0, (i % markers) as f64);
            jitter ^= jitter << 13;
            jitter ^= jitter >> 7;
            jitter ^= jitter << 17;
            let noise = (jitter % 1000) as f64 / 1000.0 * 0.4 - 0.2;
            Some(Vec3::new(
                1500.0 * (0.21 * t).sin() + 80.0 * (m * 0.7 + 3.1 * t).cos() + noise,
                1500.0 * (0.17 * t).cos() + 60.0 * (m * 1.3 + 2.3 * t).sin() - noise,
                100.0 + 40.0 * m + 50.0 * (m + 4.0 * t).sin() + noise,
            ))
        })
        .collect();
    Take::from_samples(names, &samples, 120.0).expect("valid take")
}

fn bench(c: &mut Criterion) {
    let take = take();
    let states = locap_view::sample_states(&take, &locap_core::Provenance::default());
    let mut group = c.benchmark_group("page_41x72000");
    group.sample_size(10);
    group.bench_function("render", |b| {
        b.iter(|| {
            // Ranked inside the loop: the CLI ranks the edges for every page it writes.
            let edges = locap_clean::neighbours::stable_edges(black_box(&take), 2);
            let input = locap_view::ViewInput {
                title: "bench".into(),
                take: black_box(&take),
                states: &states,
                motion: None,
                compare: None,
                edges: &edges,
            };
            black_box(locap_view::render(&input).expect("page"))
        })
    });
    let tracks: Vec<Vec<Option<Vec3>>> = (0..take.marker_count()).map(|m| take.trajectory_mm(m)).collect();
    let q = Quantiser::covering(tracks.iter().flat_map(|t| t.iter().flatten().copied()));
    let bytes = encode::i16_bytes(&encode::encode_tracks(&tracks, &q));
    group.bench_function("pack_positions", |b| b.iter(|| black_box(encode::pack(black_box(&bytes)))));
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
