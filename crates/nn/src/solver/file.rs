//! The solver model file and inference (LocalMoCap section 3.2).
//!
//! # Model file
//!
//! The layout both kinds share ([`crate::file`]) with magic `LOCAPSV\0` and a [`SolverMeta`]:
//! markers, skeleton, graph, local frame, lab frame, input and output normalisation,
//! architecture, training summary.
//!
//! # Inference ([`Solver::solve`])
//!
//! The take is cleaned (`locap_clean::clean`: swaps, outliers, EDM or refiner fill), its markers go to
//! the waist frame, and the network solves every frame on its own. Per frame it gives the local
//! rotations (the root's relative to the waist frame, turned back to the motion frame with the
//! frame's rotation), the root position (waist frame, back to the lab and then the motion
//! frame) and bone offsets; the skeleton's offsets are the offsets averaged over the take (the
//! paper: `S_i = mean(S_i^1 .. S_i^T)`), so bone lengths are constant and fitted to the
//! subject. Joints that never rotate in the training data (end sites, joints without degrees of
//! freedom) get the identity.

use super::data::{Cleaned, LocalInput, lab_rotation};
use super::net::{Gathers, JOINT_OUTPUTS, SolverArchitecture, SolverGraph, SolverNet};
use crate::NnError;
use crate::features::{Normalisation, input_values};
use crate::file::{self, Kind};
use burn::prelude::*;
use locap_clean::local_frame::FrameDefinition;
use locap_clean::{CleanConfig, Filler};
use locap_core::{Joint, Motion, Quat, Skeleton, Take, Vec3};
use locap_synth::synthesize::LabFrame;
use nalgebra::{Matrix3, Rotation3};
use serde::{Deserialize, Serialize};

/// Spread of the network's offset and translation outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputStats {
    /// Mean bone offset per joint over the training subjects, mm.
    pub offset_mean_mm: Vec<[f64; 3]>,
    /// Offset spread per joint and axis, mm (floored).
    pub offset_std_mm: Vec<[f64; 3]>,
    /// Mean root position in the waist frame, mm.
    pub translation_mean_mm: [f64; 3],
    /// Its spread per axis, mm (floored).
    pub translation_std_mm: [f64; 3],
}

/// What a solver model file carries besides its weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolverMeta {
    /// Marker labels, model order.
    pub markers: Vec<String>,
    /// The skeleton solved for (names, parents, rotation orders; offsets: the training mean).
    pub skeleton: Skeleton,
    /// The heterogeneous graph.
    pub graph: SolverGraph,
    /// The local frame the markers are expressed in.
    pub frame: FrameDefinition,
    /// How the skeleton's motion frame sits in the lab frame of the takes.
    pub lab: LabFrame,
    /// Input normalisation.
    pub normalisation: Normalisation,
    /// Output normalisation.
    pub outputs: OutputStats,
    /// Per joint: its rotation is solved (false: always the identity).
    pub rotating: Vec<bool>,
    /// Network size and variant.
    pub architecture: SolverArchitecture,
    /// How the model was trained (written by training).
    #[serde(default)]
    pub training: serde_json::Value,
}

impl SolverMeta {
    fn check(&self) -> Result<(), NnError> {
        let (m, j) = (self.markers.len(), self.skeleton.len());
        let a = &self.architecture;
        let bad = |what: String| Err(NnError::BadModel(what));
        if m == 0 || a.markers != m || a.joints != j || a.channels == 0 || a.global == 0 {
            return bad(format!("{m} markers and {j} joints named, architecture {a:?}"));
        }
        self.graph.check(m, j).map_err(NnError::BadModel)?;
        // A model file is input too: its sizes must not allocate without bound either (the
        // MLP's width is 4 x global).
        let limit = |e: NnError| NnError::BadModel(e.to_string());
        use crate::limits::{self, check};
        check("channels", a.channels, limits::MAX_CHANNELS).map_err(limit)?;
        check("global", a.global, 4 * limits::MAX_GLOBAL).map_err(limit)?;
        limits::check_weights(a.weights(&self.graph)).map_err(limit)?;
        if self.graph.parents.iter().ne(self.skeleton.joints().iter().map(|jj| &jj.parent)) {
            return bad("the graph's parents are not the skeleton's".into());
        }
        let n = &self.normalisation;
        let o = &self.outputs;
        let positive = |v: &[[f64; 3]]| v.iter().flatten().all(|s| s.is_finite() && *s > 0.0);
        if n.mean_mm.len() != m || n.std_mm.len() != m || !positive(&n.std_mm) {
            return bad("input normalisation does not match the markers".into());
        }
        if o.offset_mean_mm.len() != j
            || o.offset_std_mm.len() != j
            || !positive(&o.offset_std_mm)
            || !positive(&[o.translation_std_mm])
            || self.rotating.len() != j
        {
            return bad("output statistics do not match the joints".into());
        }
        Ok(())
    }
}

/// The network's outputs decoded, as plain values.
#[derive(Debug, Clone)]
pub struct Decoded {
    /// Rotation matrices `[n][J][9]`, row-major (the root's relative to the waist frame).
    pub rotations: Vec<f32>,
    /// Bone offsets `[n][J][3]`, mm.
    pub offsets_mm: Vec<f32>,
    /// Root positions in the waist frame `[n][3]`, mm.
    pub translation_mm: Vec<f32>,
}

/// Output statistics as tensors, to decode on a device.
#[derive(Debug, Clone)]
pub struct OutputTensors {
    offset_mean: Tensor<3>,
    offset_std: Tensor<3>,
    translation_mean: Tensor<2>,
    translation_std: Tensor<2>,
}

impl OutputTensors {
    /// `stats` on `device`.
    pub fn new(stats: &OutputStats, device: &Device) -> OutputTensors {
        let j = stats.offset_mean_mm.len();
        let flat = |v: &[[f64; 3]]| v.iter().flatten().map(|x| *x as f32).collect::<Vec<f32>>();
        let t3 = |v: Vec<f32>| Tensor::<3>::from_data(TensorData::new(v, [1, j, 3]), device);
        let t2 = |v: [f64; 3]| Tensor::<2>::from_data(TensorData::new(v.map(|x| x as f32).to_vec(), [1, 3]), device);
        OutputTensors {
            offset_mean: t3(flat(&stats.offset_mean_mm)),
            offset_std: t3(flat(&stats.offset_std_mm)),
            translation_mean: t2(stats.translation_mean_mm),
            translation_std: t2(stats.translation_std_mm),
        }
    }

    /// Raw outputs to rotations `[n, J, 3, 3]`, offsets `[n, J, 3]` mm and root translation
    /// `[n, 3]` mm (see the net module for the 9-D rotation).
    pub fn decode(&self, raw: Tensor<3>, translation: Tensor<2>) -> (Tensor<4>, Tensor<3>, Tensor<2>) {
        let [n, j, _] = raw.dims();
        let device = raw.device();
        let unit = |axis: usize| {
            let mut v = [0.0f32; 3];
            v[axis] = 1.0;
            Tensor::<3>::from_data(TensorData::new(v.to_vec(), [1, 1, 3]), &device).repeat_dim(0, n).repeat_dim(1, j)
        };
        let a = raw.clone().narrow(2, 0, 3) + unit(0);
        let b = raw.clone().narrow(2, 3, 3) + unit(1);
        let rotations = super::net::gram_schmidt(a, b);
        let offsets = raw.narrow(2, 9, 3) * self.offset_std.clone() + self.offset_mean.clone();
        let translation = translation * self.translation_std.clone() + self.translation_mean.clone();
        (rotations, offsets, translation)
    }
}

/// A loaded solver.
#[derive(Debug)]
pub struct Solver {
    /// The metadata.
    pub meta: SolverMeta,
    /// The network.
    pub net: SolverNet,
    /// Networks trained alike that answer beside this one ([`Solver::with_members`]); empty
    /// for a single network.
    members: Vec<Solver>,
    device: Device,
}

impl crate::harness::Model for Solver {
    type Net = SolverNet;

    fn to_bytes(&self) -> Result<Vec<u8>, NnError> {
        Solver::to_bytes(self)
    }

    fn from_bytes(bytes: &[u8], device: &Device) -> Result<Solver, NnError> {
        Solver::from_bytes(bytes, device)
    }

    fn into_parts(self) -> (SolverNet, serde_json::Value) {
        (self.net, self.meta.training)
    }
}

/// Frames per inference batch.
const BATCH_FRAMES: usize = 512;

impl Solver {
    /// A solver with a freshly initialised network.
    ///
    /// # Errors
    /// Inconsistent metadata.
    pub fn new(meta: SolverMeta, device: &Device) -> Result<Solver, NnError> {
        meta.check()?;
        let net = SolverNet::new(&meta.architecture, &meta.graph, device);
        Ok(Solver { meta, net, members: Vec::new(), device: device.clone() })
    }

    /// A solver from its parts (training uses it to save its network).
    pub fn from_parts(meta: SolverMeta, net: SolverNet, device: &Device) -> Solver {
        Solver { meta, net, members: Vec::new(), device: device.clone() }
    }

    /// This solver with `others` beside it, an ensemble: [`Solver::solve_cleaned`] then
    /// averages the answers of all of them ([`super::ensemble`]). Each keeps its own input and
    /// output normalisation; they must share the marker set, skeleton, local frame and lab.
    ///
    /// # Errors
    /// A member of another marker set, skeleton (joint names and parents), frame or lab.
    pub fn with_members(mut self, others: Vec<Solver>) -> Result<Solver, NnError> {
        for other in &others {
            let (a, b) = (&self.meta, &other.meta);
            let same_skeleton = super::ensemble::same_joints(&a.skeleton, &b.skeleton);
            if a.markers != b.markers
                || !same_skeleton
                || a.frame != b.frame
                || a.lab != b.lab
                || a.rotating != b.rotating
            {
                return Err(NnError::BadModel(
                    "an ensemble's models must share the marker set, skeleton, local frame and lab".into(),
                ));
            }
        }
        self.members.extend(others);
        Ok(self)
    }

    /// How many networks answer: 1, or the ensemble's size.
    pub fn networks(&self) -> usize {
        1 + self.members.iter().map(Solver::networks).sum::<usize>()
    }

    /// The model file bytes (of this network alone: an ensemble's members are files of their
    /// own).
    ///
    /// # Errors
    /// burn cannot serialise the weights.
    pub fn to_bytes(&self) -> Result<Vec<u8>, NnError> {
        file::write(Kind::Solver, &self.meta, self.net.clone())
    }

    /// Reads a model file's bytes onto `device`.
    ///
    /// # Errors
    /// Not a solver model file, another version, damaged metadata or weights.
    pub fn from_bytes(bytes: &[u8], device: &Device) -> Result<Solver, NnError> {
        let (meta, weights) = file::read::<SolverMeta>(Kind::Solver, bytes)?;
        let mut solver = Solver::new(meta, device)?;
        solver.net = weights.load(solver.net)?;
        Ok(solver)
    }

    /// The whole pipeline on a raw take: swaps and outliers repaired, gaps filled by `filler`
    /// (`locap_clean::FillConfig::default()` for EDM, or [`crate::Refiners`]), solving.
    /// Returns the motion (the model's skeleton, bone offsets fitted to the take, the take's
    /// frame rate and frame count) and the cleaned take.
    ///
    /// # Errors
    /// The take lacks model markers, the filler cannot run on it, or its waist frame is never
    /// defined.
    pub fn solve(&self, take: &Take, filler: &dyn Filler) -> Result<(Motion, Cleaned), NnError> {
        // Check the markers before the (slower) cleaning.
        crate::features::marker_order(take, &self.meta.markers)?;
        let cleaned = locap_clean::clean_with(take, &CleanConfig::default(), filler)?;
        let motion = self.solve_cleaned(&cleaned, take.frame_rate_hz())?;
        Ok((motion, cleaned))
    }

    /// Solves a take cleaned by `locap_clean::clean` (see [`Solver::solve`]).
    ///
    /// # Errors
    /// The take lacks model markers, or its waist frame is never defined.
    pub fn solve_cleaned(&self, cleaned: &Cleaned, rate_hz: f64) -> Result<Motion, NnError> {
        let own = self.solve_cleaned_alone(cleaned, rate_hz)?;
        if self.members.is_empty() {
            return Ok(own);
        }
        let mut answers = vec![own];
        for member in &self.members {
            answers.push(member.solve_cleaned(cleaned, rate_hz)?);
        }
        super::ensemble::average_motions(&answers)
    }

    /// This network's answer alone, whatever members it has.
    fn solve_cleaned_alone(&self, cleaned: &Cleaned, rate_hz: f64) -> Result<Motion, NnError> {
        let input = LocalInput::new(cleaned, &self.meta.markers, &self.meta.frame)?;
        let decoded = self.run(&input);
        let t = input.local.frames;
        let j = self.meta.skeleton.len();
        if t == 0 {
            return Err(NnError::EmptyTake);
        }
        if decoded.rotations.len() != t * j * 9 || decoded.translation_mm.len() != t * 3 {
            return Err(NnError::BadModel("the network gave outputs of the wrong size".into()));
        }
        // Bone offsets averaged over the take.
        let mut mean = vec![Vec3::zeros(); j];
        for f in 0..t {
            for (k, m) in mean.iter_mut().enumerate() {
                let o = &decoded.offsets_mm[(f * j + k) * 3..][..3];
                *m += Vec3::new(o[0] as f64, o[1] as f64, o[2] as f64) / t as f64;
            }
        }
        let joints: Vec<Joint> = self
            .meta
            .skeleton
            .joints()
            .iter()
            .zip(&mean)
            .enumerate()
            .map(|(k, (joint, m))| Joint { offset_mm: if k == 0 { joint.offset_mm } else { *m }, ..joint.clone() })
            .collect();
        let skeleton = Skeleton::new(joints).map_err(|e| NnError::BadModel(e.to_string()))?;
        let lab = lab_rotation(self.meta.lab);
        let mut rotations = Vec::with_capacity(t * j);
        let mut root = Vec::with_capacity(t);
        for f in 0..t {
            let frame = &input.local.frames_local[f];
            for k in 0..j {
                if !self.meta.rotating[k] && k != 0 {
                    rotations.push(Quat::identity());
                    continue;
                }
                let r = &decoded.rotations[(f * j + k) * 9..][..9];
                let mut m = Matrix3::from_fn(|a, b| r[a * 3 + b] as f64);
                if k == 0 {
                    m = lab.transpose() * frame.rotation.matrix() * m;
                }
                let q = Quat::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
                rotations.push(Quat::new_normalize(q.into_inner()));
            }
            let tr = &decoded.translation_mm[f * 3..][..3];
            let lab_mm = frame.to_world(&Vec3::new(tr[0] as f64, tr[1] as f64, tr[2] as f64));
            root.push(self.meta.lab.to_motion(lab_mm));
        }
        Motion::new(skeleton, rotations, root, rate_hz).map_err(NnError::Skeleton)
    }

    /// The network on every frame of `input`.
    pub fn run(&self, input: &LocalInput) -> Decoded {
        let (t, m, j) = (input.local.frames, self.meta.markers.len(), self.meta.skeleton.len());
        let gathers = Gathers::new(&self.meta.graph, self.meta.architecture.variant, &self.device);
        let stats = OutputTensors::new(&self.meta.outputs, &self.device);
        let mut out = Decoded { rotations: Vec::new(), offsets_mm: Vec::new(), translation_mm: Vec::new() };
        let mut values = Vec::new();
        for start in (0..t).step_by(BATCH_FRAMES) {
            let n = BATCH_FRAMES.min(t - start);
            values.clear();
            input_values(
                &input.local,
                &input.visible,
                &self.meta.normalisation,
                &self.meta.normalisation.mean_mm,
                start..start + n,
                &mut values,
            );
            let x = Tensor::<3>::from_data(TensorData::new(values.clone(), [n, m, 4]), &self.device);
            let (raw, tr) = self.net.forward(x, &gathers, j);
            debug_assert_eq!(raw.dims()[2], JOINT_OUTPUTS);
            let (r, o, tr) = stats.decode(raw, tr);
            let v = |x: TensorData| x.try_to_vec::<f32>().unwrap_or_default();
            out.rotations.extend(v(r.into_data()));
            out.offsets_mm.extend(v(o.into_data()));
            out.translation_mm.extend(v(tr.into_data()));
        }
        out
    }
}
