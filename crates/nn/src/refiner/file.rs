//! The refiner model file and inference (LocalMoCap section 3.1).
//!
//! # Model file
//!
//! The layout both kinds share ([`crate::file`]) with magic `LOCAPNN\0` and a [`ModelMeta`]:
//! marker labels, neighbour graph, local-frame definition, normalisation statistics, window,
//! architecture, training summary. A take lacking any of the model's markers is
//! refused ([`NnError::MarkerSet`]); markers of the take that the model does not know are left
//! as EDM filled them.
//!
//! # Inference
//!
//! EDM (or the model's initial fill) fills the take, the model markers go to the waist frame, and the network runs over
//! windows of `window` frames that overlap by half. Each frame's offset is the average of the
//! windows covering it, weighted by a triangle that peaks mid-window (a window's first and last
//! frames see context on one side only). The last window ends at the take's last frame, so no
//! frame is padded; a take shorter than a window is one window of its own length (the LSTM
//! runs on any length). Offsets are applied to the samples EDM filled, never to observed ones,
//! faded in from each gap's captured borders over `taper_frames` frames
//! ([`crate::features::offset_taper`]).

use super::net::{Architecture, RefinerNet, gather_indices};
use crate::NnError;
use crate::features::{LocalTake, Normalisation, input_values, marker_order, offset_taper, prepare};
use crate::file::{self, Kind};
use burn::prelude::*;
use locap_clean::local_frame::FrameDefinition;
use locap_clean::{FillMethod, Filled};
use locap_core::{Take, Vec3};
use serde::{Deserialize, Serialize};

/// What a model file carries besides its weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelMeta {
    /// Marker labels, model order.
    pub markers: Vec<String>,
    /// Per marker its graph neighbours (model indices), most stable first.
    pub neighbours: Vec<Vec<usize>>,
    /// The local frame the markers are expressed in.
    pub frame: FrameDefinition,
    /// Input normalisation.
    pub normalisation: Normalisation,
    /// Frames per window.
    pub window: usize,
    /// `K` of the EDM fill the refiner starts from.
    pub edm_neighbours: usize,
    /// The fill the refiner corrects: EDM (the paper), or linear for the "w/o EDM" ablation.
    #[serde(default = "edm_init")]
    pub init: FillMethod,
    /// Offsets fade in over this many frames from a gap's captured borders
    /// ([`crate::features::offset_taper`]; 0: applied in full).
    #[serde(default)]
    pub taper_frames: usize,
    /// Network size.
    pub architecture: Architecture,
    /// How the model was trained (free-form summary written by training).
    #[serde(default)]
    pub training: serde_json::Value,
}

fn edm_init() -> FillMethod {
    FillMethod::Edm
}

impl ModelMeta {
    fn check(&self) -> Result<(), NnError> {
        let m = self.markers.len();
        let a = &self.architecture;
        let bad = |what: String| Err(NnError::BadModel(what));
        if m == 0 || a.markers != m {
            return bad(format!("{} markers named, architecture has {}", m, a.markers));
        }
        if self.neighbours.len() != m
            || self.neighbours.iter().any(|n| n.len() != a.neighbours || n.iter().any(|&j| j >= m))
        {
            return bad(format!("the neighbour graph is not {m} lists of {} marker indices", a.neighbours));
        }
        let n = &self.normalisation;
        if n.mean_mm.len() != m
            || n.std_mm.len() != m
            || n.std_mm.iter().flatten().any(|s| !(s.is_finite() && *s > 0.0))
            || n.mean_mm.iter().flatten().any(|v| !v.is_finite())
        {
            return bad("normalisation statistics do not match the markers or are not finite and positive".into());
        }
        if !matches!(self.init, FillMethod::Edm | FillMethod::Linear) {
            return bad(format!("initial fill {} (edm or linear)", self.init.name()));
        }
        if self.window < 2 || a.channels == 0 || a.hidden == 0 {
            return bad(format!("window {} / channels {} / hidden {}", self.window, a.channels, a.hidden));
        }
        // A model file is input too: its sizes must not allocate without bound either.
        let limit = |e: NnError| NnError::BadModel(e.to_string());
        use crate::limits::{self, check};
        check("window", self.window, limits::MAX_WINDOW).map_err(limit)?;
        check("channels", a.channels, limits::MAX_CHANNELS).map_err(limit)?;
        check("hidden", a.hidden, limits::MAX_HIDDEN).map_err(limit)?;
        limits::check_weights(a.weights()).map_err(limit)?;
        Ok(())
    }
}

/// A loaded refiner.
#[derive(Debug)]
pub struct Refiner {
    /// The metadata.
    pub meta: ModelMeta,
    /// The network.
    pub net: RefinerNet,
    device: Device,
}

impl Refiner {
    /// A refiner with a freshly initialised network (its offsets are all zero).
    ///
    /// # Errors
    /// Inconsistent metadata.
    pub fn new(meta: ModelMeta, device: &Device) -> Result<Refiner, NnError> {
        meta.check()?;
        let net = RefinerNet::new(&meta.architecture, device);
        Ok(Refiner { meta, net, device: device.clone() })
    }

    /// A refiner from its parts (training uses it to save its network).
    pub fn from_parts(meta: ModelMeta, net: RefinerNet, device: &Device) -> Refiner {
        Refiner { meta, net, device: device.clone() }
    }

    /// The model file bytes.
    ///
    /// # Errors
    /// burn cannot serialise the weights.
    pub fn to_bytes(&self) -> Result<Vec<u8>, NnError> {
        file::write(Kind::Refiner, &self.meta, self.net.clone())
    }

    /// Reads a model file's bytes onto `device`.
    ///
    /// # Errors
    /// Not a model file, another version, damaged metadata or weights.
    pub fn from_bytes(bytes: &[u8], device: &Device) -> Result<Refiner, NnError> {
        let (meta, weights) = file::read::<ModelMeta>(Kind::Refiner, bytes)?;
        let mut refiner = Refiner::new(meta, device)?;
        refiner.net = weights.load(refiner.net)?;
        Ok(refiner)
    }

    /// Fills every gap of `take`: EDM, then the network's offsets on the filled samples of the
    /// model's markers (see the module docs). Returns the filled take and which samples were
    /// filled (as [`locap_clean::fill_gaps`]).
    ///
    /// # Errors
    /// The take lacks model markers, or its local frame is never defined.
    pub fn refine(&self, take: &Take) -> Result<Filled, NnError> {
        let order = marker_order(take, &self.meta.markers)?;
        let prepared = prepare(take, &order, &self.meta.frame, self.meta.init, self.meta.edm_neighbours)?;
        let offsets = self.offsets_mm(&prepared.local, &prepared.visible);
        let taper = offset_taper(&prepared.visible, order.len(), self.meta.taper_frames);
        let mut filled = prepared.filled;
        let (m, mt) = (order.len(), take.marker_count());
        for f in 0..take.frame_count() {
            let frame = &prepared.local.frames_local[f];
            for (k, &t) in order.iter().enumerate() {
                if !filled.filled[f * mt + t] {
                    continue;
                }
                let Some(local) = prepared.local.local_mm[f * m + k] else { continue };
                let world = frame.to_world(&(local + offsets[f * m + k] * taper[f * m + k] as f64));
                if world.iter().all(|v| v.is_finite()) {
                    // A finite position on an existing sample cannot fail.
                    let _ = filled.take.set_position_mm(f, t, Some(world));
                }
            }
        }
        Ok(filled)
    }

    /// Blended offsets in the local frame, mm, for every frame and model marker.
    fn offsets_mm(&self, local: &LocalTake, visible: &[bool]) -> Vec<Vec3> {
        let (t, m) = (local.frames, self.meta.markers.len());
        let w = self.meta.window.min(t);
        let starts = window_starts(t, w);
        let gather = gather_indices(&self.meta.neighbours, &self.device);
        let norm = &self.meta.normalisation;
        let centres = norm.centres(local, Some(visible));
        let mut acc = vec![Vec3::zeros(); t * m];
        let mut weight = vec![0.0f64; t];
        const BATCH: usize = 32;
        let mut values = Vec::new();
        for group in starts.chunks(BATCH) {
            values.clear();
            for &s in group {
                input_values(local, visible, norm, &centres, s..s + w, &mut values);
            }
            let x = Tensor::<4>::from_data(TensorData::new(values.clone(), [group.len(), w, m, 4]), &self.device);
            let out = self.net.forward(x, gather.clone()).into_data().try_to_vec::<f32>().unwrap_or_default();
            if out.len() != group.len() * w * m * 3 {
                continue;
            }
            for (b, &s) in group.iter().enumerate() {
                for i in 0..w {
                    let wi = triangle(i, w);
                    weight[s + i] += wi;
                    for k in 0..m {
                        let o = &out[((b * w + i) * m + k) * 3..][..3];
                        let sd = norm.std_mm[k];
                        acc[(s + i) * m + k] +=
                            Vec3::new(o[0] as f64 * sd[0], o[1] as f64 * sd[1], o[2] as f64 * sd[2]) * wi;
                    }
                }
            }
        }
        for f in 0..t {
            if weight[f] > 0.0 {
                acc[f * m..(f + 1) * m].iter_mut().for_each(|v| *v /= weight[f]);
            }
        }
        acc
    }
}

impl crate::harness::Model for Refiner {
    type Net = RefinerNet;

    fn to_bytes(&self) -> Result<Vec<u8>, NnError> {
        Refiner::to_bytes(self)
    }

    fn from_bytes(bytes: &[u8], device: &Device) -> Result<Refiner, NnError> {
        Refiner::from_bytes(bytes, device)
    }

    fn into_parts(self) -> (RefinerNet, serde_json::Value) {
        (self.net, self.meta.training)
    }
}

/// Fills every gap of `take` with EDM and refines the markers of each of `refiners` (a body
/// model and hand models together): each model's markers come from its own refinement, the
/// other markers from EDM.
///
/// # Errors
/// No refiners, or one whose markers the take lacks.
pub fn refine_all(take: &Take, refiners: &[Refiner]) -> Result<Filled, NnError> {
    refine_all_of(take, &refiners.iter().collect::<Vec<_>>())
}

/// [`refine_all`] with borrowed refiners.
///
/// # Errors
/// As [`refine_all`].
pub fn refine_all_of(take: &Take, refiners: &[&Refiner]) -> Result<Filled, NnError> {
    let (first, rest) = refiners.split_first().ok_or(NnError::NoRefiner)?;
    let mut out = first.refine(take)?;
    for refiner in rest {
        let order = marker_order(take, &refiner.meta.markers)?;
        let refined = refiner.refine(take)?;
        let mt = take.marker_count();
        for f in 0..take.frame_count() {
            for &k in &order {
                if refined.filled[f * mt + k] {
                    // Copying a sample between takes of the same shape cannot fail.
                    let _ = out.take.set_position_mm(f, k, refined.take.position_mm(f, k));
                    out.filled[f * mt + k] = true;
                }
            }
        }
    }
    Ok(out)
}

/// First frames of the windows of `w` frames covering `t` frames, overlapping by half; the last
/// one ends at the last frame.
pub fn window_starts(t: usize, w: usize) -> Vec<usize> {
    if t == 0 || w == 0 {
        return Vec::new();
    }
    if t <= w {
        return vec![0];
    }
    let stride = (w / 2).max(1);
    let mut starts: Vec<usize> = (0..=t - w).step_by(stride).collect();
    if *starts.last().unwrap_or(&0) != t - w {
        starts.push(t - w);
    }
    starts
}

/// Blending weight of frame `i` of a window of `w` frames: 1 at the ends, `w / 2` mid-window.
fn triangle(i: usize, w: usize) -> f64 {
    (i + 1).min(w - i) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_cover_every_frame_without_padding() {
        assert_eq!(window_starts(0, 64), Vec::<usize>::new());
        assert_eq!(window_starts(10, 64), vec![0]);
        assert_eq!(window_starts(64, 64), vec![0]);
        assert_eq!(window_starts(100, 64), vec![0, 32, 36]);
        assert_eq!(window_starts(128, 64), vec![0, 32, 64]);
        for t in 1..300 {
            let w = 64.min(t);
            let starts = window_starts(t, 64);
            let mut covered = vec![0; t];
            for s in starts {
                assert!(s + w <= t);
                covered[s..s + w].iter_mut().for_each(|c| *c += 1);
            }
            assert!(covered.iter().all(|c| *c > 0), "t = {t}");
        }
    }
}
