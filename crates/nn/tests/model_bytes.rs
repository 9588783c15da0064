//! Model files are inputs too (`--model`, `--refiner`): damaged or hostile bytes must be an
//! error, never a panic or an allocation abort. libFuzzer cannot reach the model readers here
//! (an instrumented build of burn takes longer than a session), so this test mutates the
//! shipped models the way a fuzzer would start: cuts through the header, the metadata and the
//! weights, and every header and metadata byte replaced four ways.

use locap_nn::Refiner;
use locap_nn::solver::Solver;

const SOLVER: &[u8] = include_bytes!("../../../models/solver-cmu41.locapsv");
const REFINER: &[u8] = include_bytes!("../../../models/refiner-hand-left.locapnn");

/// Cut points: every byte of the first `dense` bytes, then 64 spread over the rest.
fn cuts(len: usize, dense: usize) -> Vec<usize> {
    let mut out: Vec<usize> = (0..dense.min(len)).collect();
    out.extend((0..64).map(|k| dense + (len - dense) * k / 64));
    out
}

/// Offset of the weights: a 16-byte header (magic, version, metadata length), then the JSON.
fn metadata_end(bytes: &[u8]) -> usize {
    16 + u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize
}

fn check(name: &str, bytes: &[u8], read: impl Fn(&[u8]) -> bool) {
    assert!(read(bytes), "{name}: the shipped model reads");
    let meta = metadata_end(bytes);
    for cut in cuts(bytes.len(), meta + 64) {
        assert!(!read(&bytes[..cut]), "{name}: a file cut at byte {cut} of {} reads", bytes.len());
    }
    // Header and metadata bytes (every one of the header, 400 spread over the JSON), replaced
    // by values that break numbers, strings and lengths: an error or a model, never a panic.
    for at in (0..16).chain((16..meta).step_by(((meta - 16) / 400).max(1))) {
        for value in [0x00, b'9', b'"', 0xFF] {
            let mut bad = bytes.to_vec();
            bad[at] = value;
            let _ = read(&bad);
        }
    }
    // A metadata length pointing past the end, or at 4 GiB.
    for length in [u32::MAX, (bytes.len() as u32).saturating_sub(8), 0] {
        let mut bad = bytes.to_vec();
        bad[12..16].copy_from_slice(&length.to_le_bytes());
        assert!(!read(&bad), "{name}: metadata length {length} reads");
    }
}

#[test]
fn damaged_solver_files_are_errors() {
    let device = Default::default();
    check("solver", SOLVER, |b| Solver::from_bytes(b, &device).is_ok());
}

#[test]
fn damaged_refiner_files_are_errors() {
    let device = Default::default();
    check("refiner", REFINER, |b| Refiner::from_bytes(b, &device).is_ok());
}
