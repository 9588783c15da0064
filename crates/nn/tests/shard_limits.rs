//! Issue 14, "never lose a take": a 100-byte shard, or one whose header lies about its frame
//! count, aborted `locap train fill` and `locap eval` (exit 134) because nn decoded shards by
//! hand and reserved what the header promised. Both consumers now decode through synth's one
//! bounded decoder (`ShardReader::read_clean`, `read_all`); the files themselves are the CLI's
//! (`crates/cli/tests/train.rs` gives it the 100-byte shard). Sizes from a command line get
//! documented ceilings ([`locap_nn::limits`]) before anything is allocated.

use locap_core::{Joint, MarkerName, Motion, Quat, Skeleton, Take, Vec3};
use locap_nn::NnError;
use locap_nn::refiner::{NetConfig, TrainingData, shard_take};
use locap_nn::solver::{SolverData, SolverTrainConfig, solver_shard};
use locap_nn::{TrainConfig, limits};
use locap_synth::shard::{MAGIC, ShardReader, VERSION, write_shard};
use locap_synth::synthesize::LabFrame;

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

/// Both consumers on `bytes` read as a file of their length: the refiner's and the solver's.
fn decode(bytes: &[u8]) -> [Result<(), NnError>; 2] {
    let open = || {
        ShardReader::with_len(bytes, bytes.len() as u64)
            .map_err(|source| NnError::ShardFile { path: "x.shard".into(), source })
    };
    [open().and_then(|r| shard_take(r, "x.shard")).map(drop), open().and_then(|r| solver_shard(r, "x.shard")).map(drop)]
}

#[test]
fn a_good_shard_loads_in_both() {
    let bytes = shard_bytes();
    let reader = ShardReader::with_len(bytes.as_slice(), bytes.len() as u64).unwrap();
    let data = TrainingData::new(vec![shard_take(reader, "good.shard").unwrap()], vec!["good.shard".into()]).unwrap();
    assert_eq!((data.frames(), data.markers.len()), (40, 3));
    let reader = ShardReader::with_len(bytes.as_slice(), bytes.len() as u64).unwrap();
    let solver = SolverData::new(vec![solver_shard(reader, "good.shard").unwrap()]).unwrap();
    assert_eq!(solver.shards[0].joint_positions_mm.len(), 80);
    assert_eq!(solver.shards[0].observed.frame_count(), 40);
}

#[test]
fn a_shard_cut_short_or_lying_about_its_frames_is_an_error_naming_it() {
    let bytes = shard_bytes();
    let cases = [bytes[..100].to_vec(), with_frames(&bytes, 1_000_000_000_000), with_frames(&bytes, 39)];
    for bad in cases {
        for e in decode(&bad) {
            let e = e.unwrap_err();
            assert!(matches!(e, NnError::ShardFile { .. }), "{e:?}");
            assert!(e.to_string().starts_with("x.shard: "), "{e}");
        }
    }
    // A stream of unknown length that lies: the decoder ends at the data, it does not reserve.
    let liar = with_frames(&bytes, 1_000_000_000_000);
    let e = shard_take(ShardReader::new(liar.as_slice()).unwrap(), "x.shard").unwrap_err();
    assert!(e.to_string().contains("cut short"), "{e}");
}

#[test]
fn a_shard_without_motion_is_refused_by_the_solver_by_name() {
    let names: Vec<MarkerName> = ["A", "B", "C"].iter().map(|n| MarkerName::parse(n)).collect();
    let take = Take::from_samples(names, &vec![Some(Vec3::new(1.0, 2.0, 3.0)); 30], 120.0).unwrap();
    let mut bytes = Vec::new();
    write_shard(&mut bytes, &take, &take, None, LabFrame::ZUpFromYUp).unwrap();
    let reader = ShardReader::with_len(bytes.as_slice(), bytes.len() as u64).unwrap();
    let e = solver_shard(reader, "clean-only.shard").unwrap_err();
    assert!(matches!(&e, NnError::NoSkeleton { name } if name == "clean-only.shard"), "{e:?}");
}

/// nn's two decoders on every prefix of a real shard and on the shard with each header byte
/// replaced: an error or a result, never a panic (the byte-level half of the fuzz target,
/// which cannot build nn under cargo-fuzz; see `fuzz/README.md`).
#[test]
fn every_cut_and_every_header_byte_is_an_error_or_data() {
    let decode = |bytes: &[u8]| -> (bool, bool) {
        let [take, solver] = decode(bytes);
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
    let net = |hidden, channels| NetConfig { hidden, channels, ..TrainConfig::default().net };
    assert_eq!(fill(TrainConfig { net: net(100_000, 16), ..TrainConfig::default() }), ("hidden", 100_000, 2048));
    assert_eq!(fill(TrainConfig { batch: 100_000, ..TrainConfig::default() }).0, "batch");
    assert_eq!(fill(TrainConfig { net: net(128, 100_000), ..TrainConfig::default() }).0, "channels");
    assert_eq!(fill(TrainConfig { window: 1 << 30, ..TrainConfig::default() }).0, "window");
    assert!(TrainConfig::default().validate().is_ok());
    let solve = |c: SolverTrainConfig| limit(c.validate().unwrap_err());
    let net = |global, channels| locap_nn::solver::NetConfig { global, channels, ..SolverTrainConfig::default().net };
    assert_eq!(solve(SolverTrainConfig { net: net(100_000, 32), ..SolverTrainConfig::default() }).0, "global");
    assert_eq!(solve(SolverTrainConfig { net: net(128, 100_000), ..SolverTrainConfig::default() }).0, "channels");
    assert_eq!(
        solve(SolverTrainConfig { batch: 100_000, ..SolverTrainConfig::default() }),
        ("batch", 100_000, limits::MAX_BATCH_FRAMES as u64)
    );
    assert!(SolverTrainConfig::default().validate().is_ok());
    // Out of range (not a ceiling): typed, named.
    let e = TrainConfig { window: 1, ..TrainConfig::default() }.validate().unwrap_err();
    assert!(matches!(e, NnError::Setting { what: "window", .. }), "{e:?}");
    assert_eq!(e.to_string(), "window 1 must be 2 or more");
}
