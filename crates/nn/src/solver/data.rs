//! Solver data from training shards (LocalMoCap sections 3.2 and 4): the corrupted markers go
//! through the same cleaning as `locap solve` gives real takes ([`clean_for_solving`]:
//! outliers removed, gaps filled by EDM), are expressed in the waist frame, and are paired per
//! frame with the truth: local joint rotations (the root's relative to the waist frame), bone
//! offsets (the subject's skeleton from the shard header), the root position and the joint
//! positions in the waist frame.

use crate::NnError;
use crate::features::{LocalTake, marker_order};
use crate::refiner::Refiner;
use locap_clean::CleanConfig;
use locap_clean::local_frame::{FrameDefinition, LocalFrame, local_frames};
use locap_core::{MarkerName, Quat, Skeleton, Take, Vec3};
use locap_synth::shard::ShardReader;
use locap_synth::synthesize::LabFrame;
use nalgebra::{Matrix3, Rotation3};
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// One shard with everything a solver needs.
#[derive(Debug, Clone)]
pub struct SolverShard {
    /// Where it came from.
    pub name: String,
    /// Ground-truth markers, lab frame.
    pub clean: Take,
    /// Corrupted markers (occluded samples missing), lab frame.
    pub observed: Take,
    /// The subject's skeleton (motion frame).
    pub skeleton: Skeleton,
    /// Global joint positions, lab frame, `[frame * J + joint]`, mm.
    pub joint_positions_mm: Vec<Vec3>,
    /// Local joint rotations (the root's in the motion frame), `[frame * J + joint]`.
    pub rotations: Vec<Quat>,
    /// How the motion frame maps to the lab frame.
    pub lab: LabFrame,
}

/// Opens the shard file at `path`, its header checked against the file's length (see
/// [`ShardReader::with_len`]): a truncated file or one whose header lies about its frame
/// count is an error naming the file before anything is allocated from the header.
///
/// # Errors
/// [`NnError::Io`] if the file cannot be opened, [`NnError::ShardFile`] if it is not a
/// readable shard.
pub fn open_shard(path: &Path) -> Result<ShardReader<BufReader<File>>, NnError> {
    let name = path.display().to_string();
    let io = |source| NnError::Io { path: name.clone(), source };
    let file = File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    ShardReader::with_len(BufReader::new(file), len).map_err(|source| NnError::ShardFile { path: name, source })
}

/// An empty vector with room for `n` items, or an error naming the shard when memory cannot
/// hold them (the counts are checked against the file's size, but a real file can still be
/// larger than memory).
pub(crate) fn reserve<T>(n: usize, name: &str) -> Result<Vec<T>, NnError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|e| NnError::Data(format!("{name}: cannot hold the shard's {n} samples: {e}")))?;
    Ok(v)
}

/// Reads a shard that carries motion and its skeleton (see [`open_shard`]).
///
/// # Errors
/// Not a shard, cut short, or written without motion or skeleton.
pub fn read_solver_shard(path: &Path) -> Result<SolverShard, NnError> {
    solver_shard(open_shard(path)?, &path.display().to_string())
}

/// The solver data of the shard `reader` reads (`name` goes into errors). Give it a reader
/// made with [`ShardReader::with_len`] (as [`open_shard`] does): its frame count is checked
/// against the data, and the buffers are sized from it.
///
/// # Errors
/// Cut short, or written without motion or skeleton.
pub fn solver_shard<R: Read>(mut reader: ShardReader<R>, name: &str) -> Result<SolverShard, NnError> {
    let header = reader.header().clone();
    let skeleton = header.skeleton.clone().ok_or_else(|| {
        NnError::Data(format!("{name}: the shard has no skeleton (write it again with this locap's `locap synth`)"))
    })?;
    let (m, j, t) = (header.markers.len(), header.joints.len(), header.frames);
    if j == 0 {
        return Err(NnError::Data(format!("{name}: the shard has no joint motion")));
    }
    let (mut clean, mut observed) = (reserve(t.saturating_mul(m), name)?, reserve(t.saturating_mul(m), name)?);
    let mut joint_positions_mm = reserve(t.saturating_mul(j), name)?;
    let mut rotations = reserve(t.saturating_mul(j), name)?;
    let v3 = |p: [f32; 3]| Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
    let at = |source| NnError::ShardFile { path: name.to_string(), source };
    while let Some(chunk) = reader.next_chunk(1024).map_err(at)? {
        for rec in chunk.records() {
            clean.extend(rec.clean_mm().map(|p| Some(v3(p))));
            observed.extend(rec.observed_mm().map(|p| p.map(v3)));
            joint_positions_mm.extend(rec.joint_positions_mm().map(v3));
            rotations.extend(rec.joint_rotations_xyzw().map(|[x, y, z, w]| {
                Quat::from_quaternion(nalgebra::Quaternion::new(w as f64, x as f64, y as f64, z as f64))
            }));
        }
    }
    let names: Vec<MarkerName> = header.markers.iter().map(|l| MarkerName::parse(l)).collect();
    let take = |s: &[Option<Vec3>]| {
        Take::from_samples(names.clone(), s, header.frame_rate_hz).map_err(|e| NnError::Data(format!("{name}: {e}")))
    };
    Ok(SolverShard {
        clean: take(&clean)?,
        observed: take(&observed)?,
        name: name.to_string(),
        skeleton,
        joint_positions_mm,
        rotations,
        lab: header.lab,
    })
}

/// Every `*.shard` under `path` (searched recursively, sorted), or `path` itself if it is a file.
///
/// # Errors
/// A folder cannot be listed, or there are no shards.
pub fn shard_paths(path: &Path) -> Result<Vec<PathBuf>, NnError> {
    let paths = if path.is_dir() { crate::train::files_under(path, "shard")? } else { vec![path.to_path_buf()] };
    if paths.is_empty() {
        return Err(NnError::Data(format!("{}: no .shard files (write them with `locap synth`)", path.display())));
    }
    Ok(paths)
}

/// The rotation taking motion-frame coordinates to lab coordinates.
pub fn lab_rotation(lab: LabFrame) -> Matrix3<f64> {
    let (x, y, z) = (lab.to_lab(Vec3::x()), lab.to_lab(Vec3::y()), lab.to_lab(Vec3::z()));
    Matrix3::from_columns(&[x, y, z])
}

/// A take cleaned as `locap solve` cleans it, and which samples were observed.
pub use locap_clean::Cleaned;

/// LocalMoCap section 3.1 before solving, as `locap clean` does it with its defaults
/// (`locap_clean::clean` with `CleanConfig::default()`): swapped labels exchanged back,
/// outliers detected and removed, gaps filled by EDM (K = 6) or the `refiner`, outlier windows
/// refilled by spline.
///
/// # Errors
/// The refiner cannot run on the take.
pub fn clean_for_solving(take: &Take, refiner: Option<&Refiner>) -> Result<Cleaned, NnError> {
    let config = CleanConfig::default();
    match refiner {
        Some(r) => locap_clean::clean_with(take, &config, r).map_err(NnError::from),
        None => Ok(locap_clean::clean(take, &config)),
    }
}

/// A cleaned take's model markers in the waist frame, with visibility (model order).
#[derive(Debug, Clone)]
pub struct LocalInput {
    /// Positions in the waist frame.
    pub local: LocalTake,
    /// Visibility per frame and model marker.
    pub visible: Vec<bool>,
}

impl LocalInput {
    /// `cleaned`'s markers `markers` (labels, model order) in `frame`.
    ///
    /// # Errors
    /// Markers missing from the take, or the frame is never defined.
    pub fn new(cleaned: &Cleaned, markers: &[String], frame: &FrameDefinition) -> Result<LocalInput, NnError> {
        let take = &cleaned.filled.take;
        let order = marker_order(take, markers)?;
        let frames = local_frames(take, frame)?;
        let mt = take.marker_count();
        let visible = (0..take.frame_count())
            .flat_map(|f| order.iter().map(move |&k| (f, k)))
            .map(|(f, k)| cleaned.visible[f * mt + k]);
        Ok(LocalInput { visible: visible.collect(), local: LocalTake::new(take, &order, frames) })
    }
}

/// The truth of one frame in the waist frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTruth {
    /// Rotation matrices, row-major, `[J][9]` (the root's relative to the waist frame).
    pub rotations: Vec<f32>,
    /// Root position in the waist frame, mm.
    pub translation_mm: [f32; 3],
    /// Joint positions in the waist frame, `[J][3]`, mm.
    pub positions_mm: Vec<f32>,
}

/// The truth of frame `f` of `shard` in the local frame `frame`.
pub fn frame_truth(shard: &SolverShard, f: usize, frame: &LocalFrame) -> FrameTruth {
    let j = shard.skeleton.len();
    let to_local = frame.rotation.inverse();
    let lab = Rotation3::from_matrix_unchecked(lab_rotation(shard.lab));
    let mut rotations = Vec::with_capacity(9 * j);
    for (k, q) in shard.rotations[f * j..(f + 1) * j].iter().enumerate() {
        let m = if k == 0 { to_local * lab * q.to_rotation_matrix() } else { q.to_rotation_matrix() };
        rotations.extend((0..9).map(|i| m[(i / 3, i % 3)] as f32));
    }
    let positions: Vec<Vec3> = shard.joint_positions_mm[f * j..(f + 1) * j].iter().map(|p| frame.to_local(p)).collect();
    let root = positions[0];
    FrameTruth {
        rotations,
        translation_mm: [root.x as f32, root.y as f32, root.z as f32],
        positions_mm: positions.iter().flat_map(|p| p.iter().map(|v| *v as f32)).collect(),
    }
}

/// Mean distance, mm, between every marker and every joint over the frames of `shards`
/// (every `stride`-th frame), lab frame: `[joint][marker]`.
pub fn marker_joint_distances(shards: &[SolverShard], markers: &[String], stride: usize) -> Vec<Vec<f64>> {
    let j = shards.first().map_or(0, |s| s.skeleton.len());
    let mut sum = vec![vec![0.0; markers.len()]; j];
    let mut n = 0.0;
    for s in shards {
        let Ok(order) = marker_order(&s.clean, markers) else { continue };
        for f in (0..s.clean.frame_count()).step_by(stride.max(1)) {
            for (jj, row) in sum.iter_mut().enumerate() {
                let p = s.joint_positions_mm[f * j + jj];
                for (k, &t) in order.iter().enumerate() {
                    if let Some(x) = s.clean.position_mm(f, t) {
                        row[k] += (x - p).norm();
                    }
                }
            }
            n += 1.0;
        }
    }
    sum.iter_mut().flatten().for_each(|v| *v /= f64::max(n, 1.0));
    sum
}
