//! A marker layout file (TOML, or JSON) as `locap layout`, `synth`, `hands` and `label
//! --layout` read it: parsing arbitrary text never panics, a layout that parses passes its own
//! checks (finite, bounded offsets: an offset of 1e308 once hung the labeler's pose search),
//! and writing it back as TOML gives the same layout.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_synth::Layout;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    for parsed in [Layout::from_toml(text), Layout::from_json(text)] {
        let Ok(layout) = parsed else { continue };
        assert!(layout.check().is_ok(), "a parsed layout passes its checks");
        let again = Layout::from_toml(&layout.to_toml()).expect("a layout's own TOML reads back");
        assert_eq!(again, layout, "TOML round trip");
    }
});
