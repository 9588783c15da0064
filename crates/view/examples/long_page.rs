//! Writes the viewer page for a long take, to measure page size and opening time.
//!
//! `cargo run --release -p locap-view --example long_page -- TAKE.c3d FRAMES OUT.html`
//!
//! The take is played forwards and backwards until it has FRAMES frames (so the motion stays
//! continuous, as in a real long capture), e.g. 72,000 frames = 10 minutes at 120 Hz. Each
//! pass is moved 100 mm along X and every coordinate gets uniform noise of +-0.25 mm (the
//! size of real reconstruction noise): without it, the compressor would find the repeated
//! passes and the page would look smaller than a real 10-minute capture's. Prints the page
//! size and the time to build it.

use locap_core::{Take, Vec3};
use std::time::Instant;

/// Uniform noise in +-0.25 mm per axis, the same for the same sample index (splitmix64).
fn noise_mm(index: usize) -> Vec3 {
    let mut z = (index as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    Vec3::from_fn(|_, _| {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = z;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^= x >> 31;
        ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.5
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, input, frames, output] = args.as_slice() else {
        return Err("usage: long_page TAKE.c3d FRAMES OUT.html".into());
    };
    let frames: usize = frames.parse()?;
    let source = locap_io::c3d::read_path(std::path::Path::new(input))?.to_take()?;
    let (t, m) = (source.frame_count(), source.marker_count());
    if t < 2 {
        return Err("the take needs at least 2 frames".into());
    }
    let samples: Vec<Option<Vec3>> = (0..frames)
        .flat_map(|f| {
            // Ping-pong through the source frames: 0, 1, ..., t-1, t-2, ..., 1, 0, 1, ...
            let period = 2 * (t - 1);
            let k = f % period;
            let src = if k < t { k } else { period - k };
            (0..m).map(move |marker| (f, src, marker))
        })
        .map(|(f, src, marker)| {
            let pass = (f / (t - 1)) as f64;
            source.position_mm(src, marker).map(|p| p + Vec3::new(100.0 * pass, 0.0, 0.0) + noise_mm(f * m + marker))
        })
        .collect();
    let mut take = Take::from_samples(source.markers().to_vec(), &samples, source.frame_rate_hz())?;
    take.up_axis = source.up_axis;
    let states = locap_view::sample_states(&take, &locap_core::Provenance::default());
    let started = Instant::now();
    let edges = locap_clean::neighbours::stable_edges(&take, 2);
    let html = locap_view::render(&locap_view::ViewInput {
        title: format!("{input} x {frames} frames"),
        take: &take,
        states: &states,
        motion: None,
        compare: None,
        edges: &edges,
    })?;
    let seconds = started.elapsed().as_secs_f64();
    std::fs::write(output, &html)?;
    println!(
        "{frames} frames x {m} markers at {} Hz: page {:.1} MB, built in {seconds:.2} s",
        take.frame_rate_hz(),
        html.len() as f64 / 1e6
    );
    Ok(())
}
