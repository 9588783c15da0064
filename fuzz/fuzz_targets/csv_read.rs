//! Parsing arbitrary text as a CSV marker table must never panic; with tight limits, a take
//! that reads stays inside them, and a take that reads writes back to a table that reads the
//! same frames and markers.
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "tight.rs"]
mod tight;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = locap_io::csv::read_csv(text);
    if let Ok(take) = locap_io::csv::read_csv_with(text, &tight::TIGHT) {
        tight::assert_within(take.frame_count(), take.marker_count());
        let mut out = Vec::new();
        locap_io::csv::write_csv(&take, &mut out).expect("write of a take that read");
        let again = locap_io::csv::read_csv(std::str::from_utf8(&out).expect("CSV output is UTF-8"));
        let again = again.expect("re-read of a written table");
        assert_eq!((again.frame_count(), again.marker_count()), (take.frame_count(), take.marker_count()));
        assert_eq!(again.validity(), take.validity());
    }
});
