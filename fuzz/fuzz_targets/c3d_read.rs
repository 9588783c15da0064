//! Reading arbitrary bytes as C3D must never panic, whatever the options, and a file that
//! reads must yield a take (or a clean error) without panicking. With tight limits, what
//! reads stays inside them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_io::c3d::{self, ReadOptions};

#[path = "tight.rs"]
mod tight;

fuzz_target!(|data: &[u8]| {
    let strict = c3d::read_with(data, ReadOptions { strict: true, ..ReadOptions::default() });
    if let Ok(file) = c3d::read(data) {
        let _ = file.to_take();
        let _ = file.analog_info();
        let _ = file.manufacturer();
        // Strict reading differs only in refusing truncated data sections.
        if let Ok(strict) = strict {
            assert_eq!(strict.frames, file.frames);
        }
    }
    if let Ok(file) = c3d::read_with(data, ReadOptions { strict: false, limits: tight::TIGHT }) {
        tight::assert_within(file.frames, file.point_count + file.header.analog_per_frame as usize);
        if let Ok(take) = file.to_take() {
            tight::assert_within(take.frame_count(), take.marker_count());
        }
    }
});
