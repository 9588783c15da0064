//! From a take to the refiner's inputs (LocalMoCap section 3.1): every gap filled by EDM, every
//! marker expressed in the waist's local frame, normalised per marker and axis, with the
//! visibility flag (`[M_EDM,local, 0]` for occluded samples, `[M_local, 1]` for visible ones).
//!
//! The same preparation serves training (on augmented synthetic takes) and inference (on real
//! takes), so the network sees at inference exactly what it was trained on.

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
    /// Standard deviation per marker and axis, mm (at least [`Normalisation::MIN_STD_MM`]).
    pub std_mm: Vec<[f64; 3]>,
}

impl Normalisation {
    /// Floor of the standard deviations: a marker that never moves in the local frame (a waist
    /// marker) must not blow its inputs up.
    pub const MIN_STD_MM: f64 = 5.0;

    /// Statistics of the visible samples of `takes` in their local frames (markers in model
    /// order: `takes` must all have the model's markers in that order).
    pub fn of_local_takes<'a>(takes: impl IntoIterator<Item = &'a LocalTake>, markers: usize) -> Normalisation {
        let mut n = vec![0.0f64; markers];
        let mut sum = vec![[0.0f64; 3]; markers];
        let mut sq = vec![[0.0f64; 3]; markers];
        for take in takes {
            for f in 0..take.frames {
                for m in 0..markers {
                    if let Some(p) = take.local_mm[f * markers + m] {
                        n[m] += 1.0;
                        for a in 0..3 {
                            sum[m][a] += p[a];
                            sq[m][a] += p[a] * p[a];
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
                    let var = (sq[m][a] / n[m] - mean_mm[m][a] * mean_mm[m][a]).max(0.0);
                    std_mm[m][a] = var.sqrt().max(Self::MIN_STD_MM);
                }
            }
        }
        Normalisation { mean_mm, std_mm }
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

    /// `take`'s markers `order` in its own local frame `definition`.
    ///
    /// # Errors
    /// The frame is never defined on the take, or a reference marker is not in it.
    pub fn of_take(take: &Take, order: &[usize], definition: &FrameDefinition) -> Result<LocalTake, NnError> {
        let frames_local = local_frames(take, definition)?;
        Ok(LocalTake::new(take, order, frames_local))
    }
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
    FillConfig { method: FillMethod::Edm, neighbours, selection: neighbours::Selection::Variance }
}

/// Fills `take` with EDM and expresses the model markers `order` in the local frame.
///
/// # Errors
/// The local frame is never defined on the filled take.
pub fn prepare(
    take: &Take,
    order: &[usize],
    definition: &FrameDefinition,
    edm_neighbours: usize,
) -> Result<Prepared, NnError> {
    let filled = fill_gaps(take, &edm_config(edm_neighbours));
    let local = LocalTake::of_take(&filled.take, order, definition)?;
    let visible = (0..take.frame_count()).flat_map(|f| order.iter().map(move |&k| take.is_valid(f, k))).collect();
    Ok(Prepared { filled, local, visible })
}

/// Network input for frames `range` of `prepared`: `[frames, M, 4]` values, normalised local
/// position then the visibility flag. Samples EDM could not fill are at the mean (0) and
/// flagged invisible.
pub fn input_values(
    local: &LocalTake,
    visible: &[bool],
    norm: &Normalisation,
    range: std::ops::Range<usize>,
    out: &mut Vec<f32>,
) {
    let m = norm.mean_mm.len();
    for f in range {
        for k in 0..m {
            let i = f * m + k;
            match local.local_mm[i] {
                Some(p) => {
                    for a in 0..3 {
                        out.push(((p[a] - norm.mean_mm[k][a]) / norm.std_mm[k][a]) as f32);
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
        let n = Normalisation::of_local_takes([&local], 1);
        assert_eq!(n.mean_mm[0], [50.0, 0.0, 0.0]);
        assert_eq!(n.std_mm[0], [50.0, Normalisation::MIN_STD_MM, Normalisation::MIN_STD_MM]);
        let mut out = Vec::new();
        input_values(&local, &[true, false], &n, 0..2, &mut out);
        assert_eq!(out, vec![-1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0]);
    }
}
