//! # locap-clean: filling occlusion gaps and removing outliers
//!
//! The cleaning stage of the LocalMoCap pipeline (paper section 3.1, "Preprocess"): raw
//! marker data has occlusion gaps and outliers; this crate turns it into complete, smooth
//! marker trajectories without learning anything. The learned refinement of the fill (the
//! biLSTM of Eq. 3) lives in the `nn` crate and starts from the result of this one.
//!
//! # Locality
//! Every method here that looks at other markers uses the paper's *neighbour markers*: for
//! marker `i`, the markers whose distance to `i` varies least over the take
//! ([`neighbours`]). Markers on one body segment keep almost constant distances, so they
//! predict each other well.
//!
//! # The stage in one call
//! [`clean`] (or [`clean_with`] and any [`Filler`], such as a learned refiner) runs the whole
//! stage on a take: swaps, outliers, fill, outlier refill, and returns a [`Cleaned`] take with
//! a per-marker report and the [`locap_core::Provenance`] to store with it ([`stage`]).
//!
//! # Gap filling
//! [`fill_gaps`] fills every gap of every marker with one [`FillMethod`]:
//! - [`FillMethod::Edm`], the paper's method ([`edm`]): interpolate the squared-distance
//!   matrix of the marker and its visible neighbours across the gap, embed it with classical
//!   MDS (Eq. 2) and align the embedding onto the visible neighbours with Procrustes;
//! - baselines to measure it against, run on the same gaps: [`FillMethod::Linear`],
//!   [`FillMethod::Spline`] (cubic), [`FillMethod::Pca`] (Gløersen & Federolf 2016) and
//!   [`FillMethod::Rigid`] (the rigid-body fill of Vicon and QTM, from 3 neighbours);
//! - [`FillMethod::PcaAligned`]: the same PCA on coordinates turned, frame by frame, into the
//!   frame of the gap's neighbourhood ([`baseline::pca`], "Aligned frame");
//! - [`FillMethod::Auto`] ([`auto`]): per gap, the method or blend of methods that filled
//!   trial gaps of the same length, hidden where the marker is captured in the same take, best.
//!
//! Every method returns a [`Filled`] take with the mask of the samples it computed, so a
//! writer can mark them and a benchmark can score exactly them. Gaps at the take's start or end
//! have one border only: EDM fills them from neighbours as long as the data shows those
//! neighbours ride with the marker, and leaves the rest missing (see [`edm`], "Edge gaps").
//!
//! # Outliers and swaps
//! [`outliers`] finds acceleration spikes that reverse direction and markers frozen while
//! their segment moves, with thresholds that follow the frame rate and the take's noise;
//! [`outliers::remove`] turns them into gaps and [`refill_outliers`]
//! refills them with a cubic spline after the main fill, as the paper does. [`swaps`] finds
//! two markers that trade labels and exchanges them back.
//!
//! # Local frames
//! [`local_frame`] builds the waist and wrist coordinate systems in which the learned stages
//! see the markers (section 3.1, last paragraph).
//!
//! Nothing here reads files or knows about the command line: every function takes and returns
//! `locap-core` types, so tests and the benchmark call them directly.

pub mod auto;
pub mod baseline;
pub mod distance;
pub mod edm;
pub mod filler;
pub mod local_frame;
pub mod neighbours;
pub mod outliers;
pub mod pose_match;
pub mod procrustes;
pub mod stage;
pub mod swaps;

pub use filler::{FillError, Filler};
use locap_core::{Take, Vec3};
use serde::{Deserialize, Serialize};
pub use stage::{CleanConfig, Cleaned, MarkerReport, clean, clean_with};

/// A gap-filling method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FillMethod {
    /// Locality EDM fill (LocalMoCap section 3.1, Eq. 1-2): distances to the most stable
    /// neighbours interpolated across the gap, MDS, Procrustes.
    Edm,
    /// Linear interpolation between the gap's borders (held constant at take ends).
    Linear,
    /// Natural cubic spline through the visible samples near the gap.
    Spline,
    /// PCA over all markers (Gløersen & Federolf 2016).
    Pca,
    /// The same PCA in a frame that turns with the marker's neighbourhood
    /// ([`baseline::pca::PcaFrame::Aligned`]): locap's, not the paper's.
    PcaAligned,
    /// Rigid-body fill from the 3 best neighbours (Vicon / QTM "rigid body" fill).
    Rigid,
    /// The rigid-body fill with the marker's position relative to its donors splined across
    /// the gap ([`baseline::rigid::Across::Spline`]): locap's, for short gaps.
    RigidSpline,
    /// Distance-constrained smoothing ([`distance`]): every missing sample of a gap and of
    /// the neighbours missing with it, as the least-squares trajectory that keeps the steady
    /// distances and moves smoothly: locap's.
    Distance,
    /// Pose matching ([`pose_match`]): each missing sample from the frames where the marker's
    /// neighbours stood in the same shape, carried onto them: locap's.
    PoseMatch,
    /// Per gap, the method (or blend) that filled trial gaps of the same length in the same
    /// take best ([`auto`]).
    Auto,
}

impl FillMethod {
    /// The single methods, the paper's first ([`FillMethod::Auto`] chooses among them and is
    /// not listed).
    pub const ALL: [FillMethod; 9] = [
        FillMethod::Edm,
        FillMethod::Linear,
        FillMethod::Spline,
        FillMethod::Pca,
        FillMethod::PcaAligned,
        FillMethod::Rigid,
        FillMethod::RigidSpline,
        FillMethod::Distance,
        FillMethod::PoseMatch,
    ];

    /// Lower-case name, as on the command line.
    pub fn name(self) -> &'static str {
        match self {
            FillMethod::Edm => "edm",
            FillMethod::Linear => "linear",
            FillMethod::Spline => "spline",
            FillMethod::Pca => "pca",
            FillMethod::PcaAligned => "pca-aligned",
            FillMethod::Rigid => "rigid",
            FillMethod::RigidSpline => "rigid-spline",
            FillMethod::Distance => "distance",
            FillMethod::PoseMatch => "pose-match",
            FillMethod::Auto => "auto",
        }
    }
}

/// A take after filling, with the samples that were computed rather than captured.
#[derive(Debug, Clone, PartialEq)]
pub struct Filled {
    /// The filled take (samples that could not be filled stay missing).
    pub take: Take,
    /// `filled[frame * markers + marker]` is true where the method computed the sample.
    pub filled: Vec<bool>,
}

impl Filled {
    /// Starts from `take` with nothing filled.
    pub fn unchanged(take: &Take) -> Filled {
        Filled { take: take.clone(), filled: vec![false; take.validity().len()] }
    }

    /// The sample the method computed at `frame` for `marker`; `None` where it computed none
    /// (captured, or left missing).
    pub fn computed(&self, frame: usize, marker: usize) -> Option<Vec3> {
        let m = self.take.marker_count();
        if marker < m && self.filled.get(frame * m + marker).copied().unwrap_or(false) {
            self.take.position_mm(frame, marker)
        } else {
            None
        }
    }

    /// Number of computed samples.
    pub fn filled_count(&self) -> usize {
        self.filled.iter().filter(|f| **f).count()
    }
}

/// Settings of [`fill_gaps`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FillConfig {
    /// Method to use.
    pub method: FillMethod,
    /// How many neighbours EDM uses (the paper's K; 6 by default).
    pub neighbours: usize,
    /// How neighbours are ranked.
    pub selection: neighbours::Selection,
}

impl Default for FillConfig {
    fn default() -> FillConfig {
        FillConfig { method: FillMethod::Edm, neighbours: 6, selection: neighbours::Selection::Variance }
    }
}

/// Fills every gap of every marker of `take` with `config.method`.
///
/// Unlabeled points (`*N`) are left as they are: they are not markers yet, and a gap of a
/// point that may be a ghost has no meaning.
pub fn fill_gaps(take: &Take, config: &FillConfig) -> Filled {
    let mut filled = fill_with_method(take, config);
    let m = take.marker_count();
    for (marker, name) in take.markers().iter().enumerate() {
        if name.is_unlabeled() {
            for f in 0..take.frame_count() {
                if filled.filled[f * m + marker] {
                    // Removing a sample cannot fail.
                    let _ = filled.take.set_position_mm(f, marker, None);
                    filled.filled[f * m + marker] = false;
                }
            }
        }
    }
    filled
}

fn fill_with_method(take: &Take, config: &FillConfig) -> Filled {
    match config.method {
        FillMethod::Edm => edm::fill(take, config.neighbours, config.selection),
        FillMethod::Linear => baseline::linear::fill(take),
        FillMethod::Spline => baseline::spline::fill(take),
        FillMethod::Pca => baseline::pca::fill(take, &baseline::pca::PcaConfig::default()),
        FillMethod::PcaAligned => baseline::pca::fill(take, &baseline::pca::PcaConfig::aligned()),
        FillMethod::Rigid => baseline::rigid::fill(take, config.selection),
        FillMethod::RigidSpline => {
            baseline::rigid::fill_across(take, config.selection, baseline::rigid::Across::Spline)
        }
        FillMethod::Distance => distance::fill(
            take,
            &distance::DistanceConfig {
                edm_neighbours: config.neighbours,
                selection: config.selection,
                ..distance::DistanceConfig::default()
            },
        ),
        FillMethod::PoseMatch => pose_match::fill(
            take,
            &pose_match::PoseMatchConfig { selection: config.selection, ..pose_match::PoseMatchConfig::default() },
        ),
        FillMethod::Auto => auto::fill(take, &auto::AutoConfig::from_fill(config)).filled,
    }
}

/// Refills the windows of removed outliers with a cubic spline through the trajectory around
/// them (LocalMoCap section 3.1: "fill the gap with spline interpolation"), after the main
/// fill has completed the neighbourhood. Samples that the spline cannot reach stay as the
/// main fill left them, and so does a window with no sample on one side (at the take's start or
/// end, or next to an edge gap the main fill left open): a spline from one side only would hold
/// the marker still while the body moves, where the main fill carried it with its neighbours.
pub fn refill_outliers(filled: &mut Filled, found: &[outliers::Outlier]) {
    let m = filled.take.marker_count();
    for o in found {
        let present = |f: usize| filled.take.is_valid(f, o.marker);
        if !(0..o.frames.start).any(present) || !(o.frames.end..filled.take.frame_count()).any(present) {
            continue;
        }
        let saved: Vec<(usize, Option<locap_core::Vec3>, bool)> = o
            .frames
            .clone()
            .map(|f| (f, filled.take.position_mm(f, o.marker), filled.filled[f * m + o.marker]))
            .collect();
        let refilled = baseline::spline::spline_fill_range(filled, o.marker, o.frames.clone());
        if refilled < o.frames.len() {
            // Keep the main fill's samples where the spline had no support.
            for (f, p, was_filled) in saved {
                if !filled.take.is_valid(f, o.marker)
                    && let Some(p) = p
                    && filled.take.set_position_mm(f, o.marker, Some(p)).is_ok()
                {
                    filled.filled[f * m + o.marker] = was_filled;
                }
            }
        }
    }
}
