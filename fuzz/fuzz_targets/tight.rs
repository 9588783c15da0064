//! The tight [`Limits`] every io fuzz target also reads with (included by each target, since
//! cargo-fuzz targets are separate binaries). Run with `-malloc_limit_mb=256`: with these
//! limits, no input may make a reader allocate more, and what it returns stays inside them.

use locap_io::Limits;

pub const TIGHT: Limits =
    Limits { max_file_bytes: 1 << 20, max_frames: 1 << 12, max_samples: 1 << 16, max_depth: 32, max_joints: 256 };

/// Asserts that `frames` frames of `channels` samples each are within [`TIGHT`].
pub fn assert_within(frames: usize, channels: usize) {
    assert!(frames <= TIGHT.max_frames, "{frames} frames read past the limit");
    assert!(frames * channels <= TIGHT.max_samples, "{frames} x {channels} samples read past the limit");
}
