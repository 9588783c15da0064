//! Issue 14, "never lose a take": a 100-byte shard, or one whose header lies about its frame
//! count, aborted `locap train fill` and `locap eval` (exit 134) because nn decoded shards by
//! hand and reserved what the header promised. Both data loaders now go through synth's
//! bounded reader: a clear error naming the file. Sizes from a command line get documented
//! ceilings ([`locap_nn::limits`]) before anything is allocated.

use locap_core::{Joint, MarkerName, Motion, Quat, Skeleton, Take, Vec3};
use locap_nn::NnError;
use locap_nn::solver::{SolverData, SolverTrainConfig};
use locap_nn::train::TrainingData;
use locap_nn::{TrainConfig, limits};
use locap_synth::shard::{MAGIC, VERSION, write_shard};
use locap_synth::synthesize::LabFrame;
use std::path::{Path, PathBuf};

/// A real shard with motion: 3 markers, 2 joints, 40 frames.
fn shard_bytes() -> Vec<u8> {
    let names: Vec<MarkerName> = ["A", "B", "C"].iter().map(|n| MarkerName::parse(n)).collect();
    let samples: Vec<Option<Vec3>> =
        (0..40 * 3).map(|i| Some(Vec3::new(i as f64, (i % 3) as f64 * 100.0, 1000.0))).collect();
    let take = Take::from_samples(names, &samples, 120.0).unwrap();
    let skeleton =
        Skeleton::new(vec![Joint::new("root", None, Vec3::zeros()), Joint::new("knee", Some(0), Vec3::y() * -400.0)])
            .unwrap();
    let motion = Motion::new(skeleton, vec![Quat::identity(); 2 * 40], vec![Vec3::zeros(); 40], 120.0).unwrap();
    let mut bytes = Vec::new();
    write_shard(&mut bytes, &take, &take, Some(&motion), LabFrame::ZUpFromYUp).unwrap();
    bytes
}

/// `bytes` with the header's frame count replaced by `frames` (the records left as they are).
fn with_frames(bytes: &[u8], frames: u64) -> Vec<u8> {
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&bytes[16..16 + len]).unwrap();
    header["frames"] = frames.into();
    let text = serde_json::to_vec(&header).unwrap();
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&[0u8; 3][..(4 - text.len() % 4) % 4]);
    out.extend_from_slice(&bytes[16 + len.next_multiple_of(4)..]);
    out
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Both loaders, on one file: the refiner's and the solver's.
fn load_errors(path: &Path) -> [NnError; 2] {
    [TrainingData::from_paths(&[path.to_path_buf()]).unwrap_err(), SolverData::from_path(path).unwrap_err()]
}

#[test]
fn a_good_shard_loads_in_both() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "good.shard", &shard_bytes());
    let data = TrainingData::from_paths(std::slice::from_ref(&path)).unwrap();
    assert_eq!((data.frames(), data.markers.len()), (40, 3));
    let solver = SolverData::from_path(&path).unwrap();
    assert_eq!(solver.shards[0].joint_positions_mm.len(), 80);
    assert_eq!(solver.shards[0].observed.frame_count(), 40);
}

#[test]
fn a_100_byte_shard_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "short.shard", &shard_bytes()[..100]);
    for e in load_errors(&path) {
        let text = e.to_string();
        assert!(matches!(e, NnError::ShardFile { .. }), "{e:?}");
        assert!(text.starts_with(&path.display().to_string()), "{text}");
        assert!(text.contains("size does not match its header"), "{text}");
    }
}

#[test]
fn a_header_lying_about_its_frames_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = shard_bytes();
    for frames in [1_000_000_000_000u64, 41, 39, u64::MAX / 4] {
        let path = write(dir.path(), &format!("liar-{frames}.shard"), &with_frames(&bytes, frames));
        for e in load_errors(&path) {
            let text = e.to_string();
            assert!(text.starts_with(&path.display().to_string()), "{text}");
            assert!(text.contains("frames"), "{text}");
        }
    }
}

/// nn's two decoders on every prefix of a real shard and on the shard with each header byte
/// replaced: an error or a result, never a panic (the byte-level half of the fuzz target,
/// which cannot build nn under cargo-fuzz; see `fuzz/README.md`).
#[test]
fn every_cut_and_every_header_byte_is_an_error_or_data() {
    use locap_nn::solver::data::solver_shard;
    use locap_nn::train::read_shard;
    use locap_synth::shard::ShardReader;
    let decode = |bytes: &[u8]| -> (bool, bool) {
        let open = || ShardReader::with_len(bytes, bytes.len() as u64);
        let take = open().map_err(NnError::from).and_then(|r| read_shard(r, "x.shard"));
        let solver = open().map_err(NnError::from).and_then(|r| solver_shard(r, "x.shard"));
        (take.is_ok(), solver.is_ok())
    };
    let bytes = shard_bytes();
    assert_eq!(decode(&bytes), (true, true));
    for cut in 0..bytes.len() {
        assert_eq!(decode(&bytes[..cut]), (false, false), "cut at {cut}");
    }
    let data_start = 16 + (u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize).next_multiple_of(4);
    for at in 0..data_start {
        for value in [0x00, b'9', b'"', 0xFF] {
            let mut bad = bytes.clone();
            bad[at] = value;
            let _ = decode(&bad);
        }
    }
}

#[test]
fn sizes_above_their_ceilings_are_refused_before_training() {
    let limit = |e: NnError| match e {
        NnError::Limit { what, value, max } => (what, value, max),
        other => panic!("{other:?}"),
    };
    let fill = |c: TrainConfig| limit(c.validate().unwrap_err());
    assert_eq!(fill(TrainConfig { hidden: 100_000, ..TrainConfig::default() }), ("hidden", 100_000, 2048));
    assert_eq!(fill(TrainConfig { batch: 100_000, ..TrainConfig::default() }).0, "batch");
    assert_eq!(fill(TrainConfig { channels: 100_000, ..TrainConfig::default() }).0, "channels");
    assert_eq!(fill(TrainConfig { window: 1 << 30, ..TrainConfig::default() }).0, "window");
    assert!(TrainConfig::default().validate().is_ok());
    let solve = |c: SolverTrainConfig| limit(c.validate().unwrap_err());
    assert_eq!(solve(SolverTrainConfig { global: 100_000, ..SolverTrainConfig::default() }).0, "global");
    assert_eq!(solve(SolverTrainConfig { channels: 100_000, ..SolverTrainConfig::default() }).0, "channels");
    assert_eq!(
        solve(SolverTrainConfig { batch: 100_000, ..SolverTrainConfig::default() }),
        ("batch", 100_000, limits::MAX_BATCH_FRAMES as u64)
    );
    assert!(SolverTrainConfig::default().validate().is_ok());
}
