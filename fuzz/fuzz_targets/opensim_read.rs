//! An OpenSim model (and marker set) as `locap layout --from-opensim` reads it: arbitrary text
//! never panics, every error names the file, and a layout that comes out passes its checks
//! and reads back from its own TOML.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_synth::Layout;
use locap_synth::opensim::{XmlSource, layout_from_opensim};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match layout_from_opensim(XmlSource { name: "fuzz.osim", text }, None) {
        Ok(layout) => {
            assert!(layout.check().is_ok(), "an OpenSim layout passes its checks");
            let again = Layout::from_toml(&layout.to_toml()).expect("its TOML reads back");
            assert_eq!(again, layout);
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.osim: "), "{e}"),
    }
});
