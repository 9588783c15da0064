//! From a take to the refiner's inputs (LocalMoCap section 3.1): every gap filled by EDM, every
//! marker expressed in the waist's local frame, normalised per marker and axis, with the
//! visibility flag (`[M_EDM,local, 0]` for occluded samples, `[M_local, 1]` for visible ones).
//!
//! The same preparation serves training (on augmented synthetic takes) and inference (on real
//! takes), so the network sees at inference exactly what it was trained on.
//!
//! Two choices of ours, where the paper is silent:
//! * **Per-take centring** ([`Normalisation::per_take_centre`]): a marker's input is its local
//!   position minus its mean local position over the take's observed samples, not minus a mean
//!   pooled over the training subjects. Where a marker sits on the body differs by centimetres
//!   between subjects and labs (HDM05's waist markers sit 1-3 standard deviations away from
//!   CMU's), and a network fed absolute positions reads that placement as pose. Centred, it
//!   sees how each marker moves, which is what carries over to a new subject.
//! * **Initial fill** ([`ModelMeta::init`](crate::ModelMeta)): EDM as in the paper, or linear
//!   interpolation for the paper's "w/o EDM initial value" ablation (Table 1).

use crate::NnError;
use locap_clean::local_frame::{FrameDefinition, LocalFrame, local_frames};
use locap_clean::{FillConfig, FillMethod, Filled, fill_gaps, neighbours};
use locap_core::{Take, Vec3};
use serde::{Deserialize, Serialize};

/// Per marker and axis mean and standard deviation of local positions, mm.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Normalisation {
    /// Mean local position per marker, mm.
    pub mean_mm: Vec<[f64; 3]>,
    /// Standard deviation per marker and axis, mm (at least [`Normalisation::MIN_STD_MM`]);
    /// of the per-take centred positions when [`Normalisation::per_take_centre`] is set.
    pub std_mm: Vec<[f64; 3]>,
    /// Inputs are centred on each take's own mean local position of the marker (see the module
    /// docs); `mean_mm` then only stands in for markers a take never shows.
    #[serde(default)]
    pub per_take_centre: bool,
}

impl Normalisation {
    /// Floor of the standard deviations: a marker that never moves in the local frame (a waist
    /// marker) must not blow its inputs up.
    pub const MIN_STD_MM: f64 = 5.0;

    /// Statistics of the visible samples of `takes` in their local frames (markers in model
    /// order: `takes` must all have the model's markers in that order). With `per_take_centre`
    /// the spreads are those of the positions centred on each take's own means.
    pub fn of_local_takes<'a>(
        takes: impl IntoIterator<Item = &'a LocalTake>,
        markers: usize,
        per_take_centre: bool,
    ) -> Normalisation {
        let mut n = vec![0.0f64; markers];
        let mut sum = vec![[0.0f64; 3]; markers];
        let mut sq = vec![[0.0f64; 3]; markers];
        let mut centred_sq = vec![[0.0f64; 3]; markers];
        for take in takes {
            let own = take.marker_means(markers, None);
            for f in 0..take.frames {
                for m in 0..markers {
                    if let (Some(p), Some(c)) = (take.local_mm[f * markers + m], own[m]) {
                        n[m] += 1.0;
                        for a in 0..3 {
                            sum[m][a] += p[a];
                            sq[m][a] += p[a] * p[a];
                            centred_sq[m][a] += (p[a] - c[a]) * (p[a] - c[a]);
                        }
                    }
                }
            }
        }
        let mut mean_mm = vec![[0.0; 3]; markers];
        let mut std_mm = vec![[Self::MIN_STD_MM; 3]; markers];
        for m in 0..markers {
            if n[m] > 0.0 {
                for a in 0..3 {
                    mean_mm[m][a] = sum[m][a] / n[m];
                    let var = if per_take_centre {
                        centred_sq[m][a] / n[m]
                    } else {
                        (sq[m][a] / n[m] - mean_mm[m][a] * mean_mm[m][a]).max(0.0)
                    };
                    std_mm[m][a] = var.sqrt().max(Self::MIN_STD_MM);
                }
            }
        }
        Normalisation { mean_mm, std_mm, per_take_centre }
    }

    /// What each marker's input is centred on for `local`: its own mean over the samples that
    /// are present and `visible` (all present ones without `visible`) when
    /// [`Normalisation::per_take_centre`] is set, else (or for a marker never seen) the pooled
    /// training mean.
    pub fn centres(&self, local: &LocalTake, visible: Option<&[bool]>) -> Vec<[f64; 3]> {
        if !self.per_take_centre {
            return self.mean_mm.clone();
        }
        let own = local.marker_means(self.mean_mm.len(), visible);
        own.iter().zip(&self.mean_mm).map(|(o, pooled)| o.unwrap_or(*pooled)).collect()
    }
}

/// A take in a local frame: `local_mm[f * M + m]`, `None` where missing.
#[derive(Debug, Clone)]
pub struct LocalTake {
    /// Frames.
    pub frames: usize,
    /// Positions in the local frame, frame-major, mm.
    pub local_mm: Vec<Option<Vec3>>,
    /// The local frame of every frame.
    pub frames_local: Vec<LocalFrame>,
}

impl LocalTake {
    /// `take`'s markers `order` (take indices, in model order) in the frames `frames_local`.
    pub fn new(take: &Take, order: &[usize], frames_local: Vec<LocalFrame>) -> LocalTake {
        let frames = take.frame_count();
        let mut local_mm = Vec::with_capacity(frames * order.len());
        for (f, frame) in frames_local.iter().enumerate() {
            local_mm.extend(order.iter().map(|&k| take.position_mm(f, k).map(|p| frame.to_local(&p))));
        }
        LocalTake { frames, local_mm, frames_local }
    }

    /// Per marker (`markers` of them, model order) the mean local position over the frames where
    /// it is present and, given `visible`, observed; `None` for a marker never counted.
    pub fn marker_means(&self, markers: usize, visible: Option<&[bool]>) -> Vec<Option<[f64; 3]>> {
        let mut sum = vec![([0.0f64; 3], 0usize); markers];
        for f in 0..self.frames {
            for (m, (s, n)) in sum.iter_mut().enumerate() {
                let i = f * markers + m;
                if let Some(p) = self.local_mm[i]
                    && visible.is_none_or(|v| v[i])
                {
                    for a in 0..3 {
                        s[a] += p[a];
                    }
                    *n += 1;
                }
            }
        }
        sum.into_iter().map(|(s, n)| (n > 0).then(|| s.map(|v| v / n as f64))).collect()
    }

    /// `take`'s markers `order` in its own local frame `definition`.
    ///
    /// # Errors
    /// The frame is never defined on the take, or a reference marker is not in it.
    pub fn of_take(take: &Take, order: &[usize], definition: &FrameDefinition) -> Result<LocalTake, NnError> {
        let frames_local = local_frames(take, definition)?;
        Ok(LocalTake::new(take, order, frames_local))
    }
}

/// The local frame for a marker set: the first of the CMU waist, the paper's left and right
/// wrists, and the CMU left and right wrists whose markers are all in `markers`.
pub fn frame_for(markers: &[String]) -> Option<FrameDefinition> {
    let candidates = [
        FrameDefinition::cmu_waist(),
        FrameDefinition::paper_wrist('L'),
        FrameDefinition::paper_wrist('R'),
        FrameDefinition::cmu_wrist('L'),
        FrameDefinition::cmu_wrist('R'),
    ];
    candidates.into_iter().find(|d| {
        [&d.origin, &d.x_from, &d.x_to, &d.y_from, &d.y_to].iter().all(|list| list.iter().all(|l| markers.contains(l)))
    })
}

/// Where each of the model's markers is in `take`.
///
/// # Errors
/// Some model marker is not in the take ([`NnError::MarkerSet`]).
pub fn marker_order(take: &Take, markers: &[String]) -> Result<Vec<usize>, NnError> {
    let found: Vec<Option<usize>> = markers.iter().map(|label| take.marker_index(label)).collect();
    let missing: Vec<&str> =
        markers.iter().zip(&found).filter(|(_, k)| k.is_none()).map(|(label, _)| label.as_str()).collect();
    if !missing.is_empty() {
        return Err(NnError::MarkerSet {
            missing: missing.len(),
            total: markers.len(),
            first: missing.iter().take(5).copied().collect::<Vec<_>>().join(", "),
        });
    }
    Ok(found.into_iter().flatten().collect())
}

/// The `k` most stable neighbours of each marker of `take` (model order), as model indices.
pub fn neighbour_graph(take: &Take, order: &[usize], k: usize) -> Vec<Vec<usize>> {
    let ranked = neighbours::rank(take, neighbours::Selection::Variance);
    let model_index = |take_index: usize| order.iter().position(|&o| o == take_index);
    order.iter().map(|&t| ranked[t].iter().filter_map(|&n| model_index(n)).take(k).collect::<Vec<usize>>()).collect()
}

/// A take prepared for the network: EDM-filled and local.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The EDM fill of the take (all markers, take order).
    pub filled: Filled,
    /// The filled take's model markers in the local frame.
    pub local: LocalTake,
    /// Model marker `m` of frame `f` was observed (`visible[f * M + m]`).
    pub visible: Vec<bool>,
}

/// EDM settings used before the refiner (the cleaning default: K = 6, variance ranking).
pub fn edm_config(neighbours: usize) -> FillConfig {
    init_config(FillMethod::Edm, neighbours)
}

/// Settings of the initial fill `method` the refiner corrects (EDM; linear for the "w/o EDM"
/// ablation), `neighbours` as in [`edm_config`].
pub fn init_config(method: FillMethod, neighbours: usize) -> FillConfig {
    FillConfig { method, neighbours, selection: neighbours::Selection::Variance }
}

/// Fills `take` with `init` (EDM, or the ablation's linear fill) and expresses the model
/// markers `order` in the local frame.
///
/// # Errors
/// The local frame is never defined on the filled take.
pub fn prepare(
    take: &Take,
    order: &[usize],
    definition: &FrameDefinition,
    init: FillMethod,
    edm_neighbours: usize,
) -> Result<Prepared, NnError> {
    let filled = fill_gaps(take, &init_config(init, edm_neighbours));
    let local = LocalTake::of_take(&filled.take, order, definition)?;
    let visible = (0..take.frame_count()).flat_map(|f| order.iter().map(move |&k| take.is_valid(f, k))).collect();
    Ok(Prepared { filled, local, visible })
}

/// How strongly the offset applies to each sample (`[f * M + m]`, 0..=1): `0` on observed
/// samples, `min(1, d / taper_frames)` on the others, `d` being the frames to the nearest
/// observed sample of the same marker (1 next to it; a gap open at both ends of the take counts
/// from neither and gets 1). `taper_frames == 0` applies offsets in full.
///
/// Why: EDM's fill meets the captured trajectory at the gap's borders (it blends into them), and
/// a filled sample next to a captured one is already close to right; an offset there would put
/// a step into the trajectory. The taper keeps the border continuous and leaves short gaps,
/// where EDM is within a millimetre, to EDM (measured: without it the refiner put ~10 mm on
/// gaps of 1-10 frames that EDM fills to 0.2 mm).
pub fn offset_taper(visible: &[bool], markers: usize, taper_frames: usize) -> Vec<f32> {
    let frames = visible.len() / markers.max(1);
    let mut out = vec![0.0f32; visible.len()];
    for m in 0..markers {
        let mut since = vec![usize::MAX; frames];
        let mut last = None;
        for f in 0..frames {
            if visible[f * markers + m] {
                last = Some(f);
            } else if let Some(l) = last {
                since[f] = f - l;
            }
        }
        let mut next = None;
        for f in (0..frames).rev() {
            let i = f * markers + m;
            if visible[i] {
                next = Some(f);
                continue;
            }
            let d = since[f].min(next.map_or(usize::MAX, |n| n - f));
            out[i] = if taper_frames == 0 || d == usize::MAX { 1.0 } else { (d as f32 / taper_frames as f32).min(1.0) };
        }
    }
    out
}

/// Network input for frames `range` of `prepared`: `[frames, M, 4]` values, local position
/// minus `centres` (from [`Normalisation::centres`]) over the spread, then the visibility flag.
/// Samples EDM could not fill are at the centre (0) and flagged invisible.
pub fn input_values(
    local: &LocalTake,
    visible: &[bool],
    norm: &Normalisation,
    centres: &[[f64; 3]],
    range: std::ops::Range<usize>,
    out: &mut Vec<f32>,
) {
    let m = norm.mean_mm.len();
    for f in range {
        for (k, (centre, std)) in centres.iter().zip(&norm.std_mm).enumerate() {
            let i = f * m + k;
            match local.local_mm[i] {
                Some(p) => {
                    for a in 0..3 {
                        out.push(((p[a] - centre[a]) / std[a]) as f32);
                    }
                }
                None => out.extend([0.0; 3]),
            }
            out.push(if visible[i] { 1.0 } else { 0.0 });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;

    fn take(labels: &[&str]) -> Take {
        let names = labels.iter().map(|l| MarkerName::parse(l)).collect::<Vec<_>>();
        let samples: Vec<Option<Vec3>> =
            (0..3 * labels.len()).map(|i| Some(Vec3::new(i as f64, 1.0, 2.0 * i as f64))).collect();
        Take::from_samples(names, &samples, 100.0).unwrap()
    }

    #[test]
    fn offsets_taper_towards_the_captured_samples() {
        // One marker: captured, a 5-frame gap, captured, then missing to the end.
        let visible = [true, false, false, false, false, false, true, false, false];
        let t = offset_taper(&visible, 1, 4);
        assert_eq!(t, vec![0.0, 0.25, 0.5, 0.75, 0.5, 0.25, 0.0, 0.25, 0.5]);
        assert_eq!(offset_taper(&visible, 1, 0), vec![0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 1.0, 1.0]);
        assert_eq!(offset_taper(&[false, false], 1, 4), vec![1.0, 1.0]);
        // Markers are independent: frame-major layout with two markers.
        let two = offset_taper(&[true, false, false, false, true, true], 2, 2);
        assert_eq!(two, vec![0.0, 1.0, 0.5, 0.5, 0.0, 0.0]);
    }

    #[test]
    fn the_local_frame_follows_the_marker_set() {
        let labels = |l: &[&str]| l.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let body = labels(&["LFWT", "RFWT", "LBWT", "RBWT", "LKNE"]);
        assert_eq!(frame_for(&body).unwrap().name, "waist");
        let hand = labels(&["RIWR", "ROWR", "RIHAND", "ROHAND", "RIDX3"]);
        assert_eq!(frame_for(&hand).unwrap(), FrameDefinition::paper_wrist('R'));
        assert!(frame_for(&labels(&["LFWT", "RFWT", "LBWT"])).is_none());
    }

    #[test]
    fn marker_order_maps_by_label_and_names_what_is_missing() {
        let t = take(&["B", "A", "C"]);
        assert_eq!(marker_order(&t, &["A".into(), "C".into()]).unwrap(), vec![1, 2]);
        let e = marker_order(&t, &["A".into(), "X".into(), "Y".into()]).unwrap_err().to_string();
        assert!(e.contains("another marker set") && e.contains("2 of its 3") && e.contains("X, Y"), "{e}");
    }

    #[test]
    fn normalisation_floors_the_spread() {
        let local = LocalTake {
            frames: 2,
            local_mm: vec![Some(Vec3::new(0.0, 0.0, 0.0)), Some(Vec3::new(100.0, 0.0, 0.0))],
            frames_local: vec![],
        };
        let n = Normalisation::of_local_takes([&local], 1, false);
        assert_eq!(n.mean_mm[0], [50.0, 0.0, 0.0]);
        assert_eq!(n.std_mm[0], [50.0, Normalisation::MIN_STD_MM, Normalisation::MIN_STD_MM]);
        let mut out = Vec::new();
        input_values(&local, &[true, false], &n, &n.centres(&local, None), 0..2, &mut out);
        assert_eq!(out, vec![-1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn per_take_centring_removes_where_a_subject_wears_a_marker() {
        // Two subjects moving a marker alike, one wearing it 200 mm further along x.
        let subject = |shift: f64| LocalTake {
            frames: 3,
            local_mm: [-10.0, 0.0, 10.0].iter().map(|x| Some(Vec3::new(x + shift, 0.0, 0.0))).collect(),
            frames_local: vec![],
        };
        let (a, b) = (subject(0.0), subject(200.0));
        let pooled = Normalisation::of_local_takes([&a, &b], 1, false);
        let centred = Normalisation::of_local_takes([&a, &b], 1, true);
        assert!(pooled.std_mm[0][0] > 99.0, "{:?}", pooled.std_mm);
        assert!((centred.std_mm[0][0] - Normalisation::MIN_STD_MM.max((200.0f64 / 3.0).sqrt())).abs() < 1e-9);
        let inputs = |t: &LocalTake, visible: &[bool]| {
            let mut out = Vec::new();
            input_values(t, visible, &centred, &centred.centres(t, Some(visible)), 0..3, &mut out);
            out
        };
        let all = [true; 3];
        assert_eq!(inputs(&a, &all), inputs(&b, &all));
        // An occluded sample does not move the centre.
        let mut moved = b.clone();
        moved.local_mm[2] = Some(Vec3::new(900.0, 0.0, 0.0));
        assert_eq!(centred.centres(&moved, Some(&[true, true, false]))[0][0], 195.0);
    }
}
