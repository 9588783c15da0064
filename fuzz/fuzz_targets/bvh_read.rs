//! Parsing arbitrary text as BVH must never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_core::LengthUnit;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = locap_io::bvh::read_bvh(text, LengthUnit::Centimetre);
});
