//! Parsing arbitrary text as BVH must never panic; with tight limits, a motion that reads
//! stays inside them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_core::LengthUnit;

#[path = "tight.rs"]
mod tight;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let _ = locap_io::bvh::read_bvh(text, LengthUnit::Centimetre);
    if let Ok(motion) = locap_io::bvh::read_bvh_with(text, LengthUnit::Centimetre, &tight::TIGHT) {
        assert!(motion.skeleton.len() <= tight::TIGHT.max_joints);
        tight::assert_within(motion.frame_count(), motion.skeleton.len());
    }
});
