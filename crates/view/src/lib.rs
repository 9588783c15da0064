//! # locap-view: seeing what cleaning did
//!
//! Motion capture people judge a clean-up by looking at it: a gap filled with a plausible
//! trajectory, an outlier gone, a skeleton that follows its markers. This crate makes that
//! possible without a DCC package, in two forms:
//!
//! # The viewer page
//! [`page::render`] turns a take (plus, optionally, a solved skeleton motion and a second
//! take to compare with) into **one self-contained HTML file**: three.js and the viewer
//! script are embedded, so the page opens from disk with no network. Markers are spheres
//! coloured by [`states::SampleState`] (captured, filled by locap, outlier replaced, still
//! missing, read back from the `LOCAP:FILLED` / `LOCAP:OUTLIERS` parameters that `locap
//! clean` writes), with names on hover, neighbour edges (given by the caller: the `locap`
//! binary draws the most stable neighbours of LocalMoCap section 3, the ones EDM fills from,
//! ranked by `locap_clean::neighbours::stable_edges`), the skeleton, a timeline and a per-marker
//! gap chart. Data are quantised, delta-coded and compressed ([`encode`]): a 10-minute 120 Hz
//! take stays a page that opens in seconds.
//!
//! # Charts
//! [`plot`] draws PNG or SVG charts with plotters: gap-length histograms and per-marker
//! occlusion rates of takes, and error against gap length for each method of a benchmark,
//! from the data series its report gives (gap lengths in the bins of
//! [`locap_core::gaps::LENGTH_BINS`], as every locap metric).
//!
//! Like the other library crates, this one never touches files: it takes core types and
//! returns text or bytes; the `locap` binary reads and writes. It depends on `locap-core`
//! alone: what it draws is computed by the stages and benchmarks and handed in.

pub mod encode;
pub mod page;
pub mod plot;
pub mod states;

pub use page::{ViewInput, render};
pub use states::{SampleState, sample_states};

/// Errors from building a page or a chart.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// A motion or take shown with the main take has another number of frames.
    #[error("{what} has {found} frames, but the take has {expected}; they must cover the same frames")]
    FrameCountMismatch {
        /// What was given (`the --motion file`, `the --compare take`).
        what: &'static str,
        /// Frames of the take.
        expected: usize,
        /// Frames found.
        found: usize,
    },
    /// The motion's frame rate differs from the take's.
    #[error("the --motion file runs at {motion_hz} Hz, but the take at {take_hz} Hz")]
    RateMismatch {
        /// Frame rate of the take, Hz.
        take_hz: f64,
        /// Frame rate of the motion, Hz.
        motion_hz: f64,
    },
    /// An edge to draw joins a marker the take does not have.
    #[error("edge {edge:?} joins marker {}, but the take has {markers} markers", edge[0].max(edge[1]))]
    BadEdge {
        /// The edge (marker indices).
        edge: [usize; 2],
        /// Markers of the take.
        markers: usize,
    },
    /// The sample states do not have one entry per sample.
    #[error("{found} sample states given for a take of {expected} samples")]
    StateCount {
        /// Samples of the take.
        expected: usize,
        /// States given.
        found: usize,
    },
    /// A data block or page could not be encoded or decoded.
    #[error("page data: {0}")]
    BadBlock(String),
    /// A chart could not be drawn.
    #[error("chart: {0}")]
    Chart(String),
    /// Nothing to draw.
    #[error("nothing to plot: {0}")]
    Empty(String),
}
