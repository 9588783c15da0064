//! Reading arbitrary bytes as a training shard (header, then chunks) must never panic or
//! allocate without bound.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(mut reader) = locap_synth::shard::ShardReader::new(data) else { return };
    for _ in 0..64 {
        match reader.next_chunk(7) {
            Ok(Some(_)) => {}
            _ => break,
        }
    }
});
