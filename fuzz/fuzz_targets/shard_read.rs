//! Arbitrary bytes as a training shard must never panic or allocate without bound, read as a
//! stream of unknown length ([`ShardReader::new`]) or as a file of known length
//! ([`ShardReader::with_len`], what `locap train` and `locap eval` open), with every record
//! decoded through the typed [`Record`] accessors, and the whole shard through the one decoder
//! both nn consumers call ([`ShardReader::read_clean`] for the refiner, [`ShardReader::read_all`]
//! for the solver). A shard accepted with its length must then yield exactly the frames its
//! header promises, and the consumers' takes must have them too.
#![no_main]

use libfuzzer_sys::fuzz_target;
use locap_synth::shard::{Chunk, ShardReader};

/// Touches every field of every record; returns the records seen.
fn decode(chunk: &Chunk) -> usize {
    let mut sum = 0.0f32;
    for r in chunk.records() {
        sum += r.clean_mm().map(|p| p[0]).sum::<f32>();
        sum += r.observed_mm().flatten().map(|p| p[1]).sum::<f32>();
        sum += r.joint_positions_mm().map(|p| p[2]).sum::<f32>();
        sum += r.joint_rotations_xyzw().map(|q| q[3]).sum::<f32>();
    }
    std::hint::black_box(sum);
    chunk.records().len()
}

fuzz_target!(|data: &[u8]| {
    // Chunk sizes vary with the input (nn's loaders ask for 1024, tests for a few); taken
    // from the length, not a byte, so real shards stay valid seeds.
    let max_frames = data.len() % 16 + 1;
    if let Ok(mut reader) = ShardReader::new(data) {
        for _ in 0..64 {
            match reader.next_chunk(max_frames) {
                Ok(Some(chunk)) => {
                    assert_eq!(decode(&chunk), chunk.frames);
                }
                _ => break,
            }
        }
    }
    if let Ok(mut reader) = ShardReader::with_len(data, data.len() as u64) {
        let promised = reader.header().frames;
        let mut seen = 0;
        // The length check makes the frame count true: reading can no longer fail.
        while let Some(chunk) = reader.next_chunk(max_frames).expect("a length-checked shard reads to its end") {
            assert_eq!(chunk.first_frame, seen);
            seen += decode(&chunk);
        }
        assert_eq!(seen, promised);
    }
    // The consumers' decoder, over a stream (buffers grow with the data) and a length-checked
    // file (buffers sized from the checked frame count).
    if let Ok(reader) = ShardReader::new(data) {
        let _ = reader.read_clean();
    }
    if let Ok(reader) = ShardReader::with_len(data, data.len() as u64) {
        let header = reader.header().clone();
        // Only a non-finite sample can stop a length-checked shard here.
        if let Ok(all) = reader.read_all() {
            assert_eq!((all.clean.frame_count(), all.observed.frame_count()), (header.frames, header.frames));
            assert_eq!(all.joint_positions_mm.len(), header.frames * header.joints.len());
            assert_eq!(all.joint_rotations.len(), header.frames * header.joints.len());
        }
    }
});
