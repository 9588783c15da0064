//! Parsing arbitrary text as an ASF skeleton, and the text after the first NUL byte as an
//! AMC motion of that skeleton, must never panic; with tight limits, what reads stays inside
//! them.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_io::asf_amc;

#[path = "tight.rs"]
mod tight;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let (asf_text, amc_text) = text.split_once('\0').unwrap_or((text, ""));
    let _ = asf_amc::read_asf(asf_text);
    let Ok(asf) = asf_amc::read_asf_with(asf_text, &tight::TIGHT) else { return };
    assert!(asf.bones.len() <= tight::TIGHT.max_joints);
    let Ok(skeleton) = asf.to_skeleton(asf.mm_per_unit()) else { return };
    let _ = skeleton.len();
    let _ = asf_amc::read_amc(amc_text, &asf, 120.0);
    if let Ok(motion) = asf_amc::read_amc_scaled_with(amc_text, &asf, 120.0, asf.mm_per_unit(), &tight::TIGHT) {
        tight::assert_within(motion.frame_count(), motion.skeleton.len());
    }
});
