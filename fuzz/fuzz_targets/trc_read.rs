//! Parsing arbitrary text as TRC must never panic; with tight limits, a take that reads
//! stays inside them.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "tight.rs"]
mod tight;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = locap_io::trc::read_trc(text);
    if let Ok(file) = locap_io::trc::read_trc_file_with(text, &tight::TIGHT) {
        tight::assert_within(file.take.frame_count(), file.take.marker_count());
    }
});
