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
use locap_core::{Quat, Skeleton, Take, Vec3};
use locap_synth::shard::ShardReader;
use locap_synth::synthesize::LabFrame;
use nalgebra::{Matrix3, Rotation3};
use std::io::Read;

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

/// The solver data of the shard `reader` reads (`name`, the shard's path, goes into errors),
/// decoded by synth's one shard decoder ([`ShardReader::read_all`]). Give it a reader made
/// with [`ShardReader::with_len`]: its frame count is checked against the file's length, and
/// the buffers are sized from it.
///
/// # Errors
/// Cut short or unreadable ([`NnError::ShardFile`]), or written without skeleton or motion.
pub fn solver_shard<R: Read>(reader: ShardReader<R>, name: &str) -> Result<SolverShard, NnError> {
    let header = reader.header();
    let skeleton = header.skeleton.clone().ok_or_else(|| NnError::NoSkeleton { name: name.to_string() })?;
    if header.joints.is_empty() {
        return Err(NnError::NoMotion { name: name.to_string() });
    }
    let contents = reader.read_all().map_err(|source| NnError::ShardFile { path: name.to_string(), source })?;
    Ok(SolverShard {
        clean: contents.clean,
        observed: contents.observed,
        name: name.to_string(),
        skeleton,
        joint_positions_mm: contents.joint_positions_mm,
        rotations: contents.joint_rotations,
        lab: contents.header.lab,
    })
}

/// `shard` with its skeleton's joints in `order`'s order (its own offsets kept), or `None` if
/// the two skeletons differ in joint names or in any joint's parent.
pub fn in_joint_order(shard: SolverShard, order: &Skeleton) -> Option<SolverShard> {
    let (own, wanted) = (shard.skeleton.joints(), order.joints());
    let parent_name = |joints: &[locap_core::Joint], j: &locap_core::Joint| j.parent.map(|p| joints[p].name.clone());
    if own.len() != wanted.len() {
        return None;
    }
    // `from[k]`: the shard's index of `order`'s joint `k`.
    let from: Vec<usize> = wanted.iter().map(|w| shard.skeleton.index_of(&w.name)).collect::<Option<_>>()?;
    let same_parents = wanted.iter().zip(&from).all(|(w, &k)| parent_name(wanted, w) == parent_name(own, &own[k]));
    if !same_parents {
        return None;
    }
    if from.iter().enumerate().all(|(k, &f)| k == f) {
        return Some(shard);
    }
    let joints: Vec<locap_core::Joint> =
        wanted.iter().zip(&from).map(|(w, &k)| locap_core::Joint { parent: w.parent, ..own[k].clone() }).collect();
    let skeleton = Skeleton::new(joints).ok()?;
    let joint_positions_mm = permute_joints(&shard.joint_positions_mm, &from);
    let rotations = permute_joints(&shard.rotations, &from);
    Some(SolverShard { skeleton, joint_positions_mm, rotations, ..shard })
}

/// Frame-major per-joint `values` with joint `k` of each frame taken from joint `from[k]`.
fn permute_joints<T: Copy>(values: &[T], from: &[usize]) -> Vec<T> {
    values.chunks_exact(from.len().max(1)).flat_map(|frame| from.iter().map(move |&k| frame[k])).collect()
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
/// outliers detected and removed, gaps filled by the default fill (`auto`: per gap the method
/// that filled trial gaps of its length best) or the `refiner`, outlier windows
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

/// The cleaning of training inputs: [`clean_for_solving`]'s stages with the EDM fill (K = 6),
/// as the shipped solver was trained. The per-gap `auto` fill of `locap solve` costs about a
/// hundred times EDM's on synthetic takes (every gap tried on windows and neighbours), which
/// would make data preparation outlast a training run on a CPU. So the network learns from
/// EDM's fills and is given the default fill's when solving (`locap eval` scores it so).
pub fn clean_for_training(take: &Take) -> Cleaned {
    let fill = locap_clean::FillConfig { method: locap_clean::FillMethod::Edm, ..Default::default() };
    locap_clean::clean(take, &CleanConfig { fill, ..CleanConfig::default() })
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
