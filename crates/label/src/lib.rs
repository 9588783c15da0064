//! # locap-label: online marker labeling
//!
//! Implements "Online marker labeling for fully automatic skeleton tracking in optical motion
//! capture" (soft graph matching; `../shared/papers/online-marker-labeling-soft-graph-matching.txt`),
//! sections 3 and 4. A capture system hands over, every frame, an unordered cloud of points:
//! markers, ghosts (reflections), and not every marker. [`Labeler`] names the points frame
//! after frame, using only the frames seen so far (online):
//!
//! - [`template`]: the marker set, a labeled reference pose and each marker's rigid edges;
//! - [`initial_fit`]: labels of the first frame by fitting the template (section 3, end);
//! - [`kalman`]: a constant-velocity Kalman filter per marker predicts and gates candidates;
//! - [`labeler`]: soft graph matching costs (Eq. 1-4), missing-marker estimation from rigid
//!   neighbours (section 4, Eq. 13), and the CP / UGM baselines of the paper's comparison;
//! - [`assignment`]: the Hungarian algorithm with dummies (Eq. 5) on the sparse candidate
//!   graph, split into independent components so a frame costs microseconds;
//! - [`cloud`]: the per-frame point clouds of a take.
//!
//! [`label_frames`] runs the whole take. This crate never reads files: the `locap label`
//! command does, with `locap-io`.

pub mod assignment;
pub mod cloud;
pub mod ik;
pub mod initial_fit;
pub mod kalman;
pub mod labeler;
pub mod template;

pub use cloud::PointFrames;
pub use initial_fit::{FitConfig, InitialFit, fit_first_frame};
pub use labeler::{LabelConfig, Labeler, Method};
pub use template::Template;

use locap_core::{MarkerName, Take, UpAxis, Vec3};

/// Why labeling cannot proceed.
#[derive(Debug, thiserror::Error)]
pub enum LabelError {
    /// The template take cannot serve as a template.
    #[error("bad template: {0}")]
    Template(String),
    /// The first frame cannot be labeled.
    #[error("cannot label the first frame: {0}")]
    FirstFrame(String),
    /// Settings or inputs that do not fit together.
    #[error("{0}")]
    Config(String),
    /// A take too large to label (see [`cloud::MAX_POINTS`]).
    #[error("the take is too large to label: {0}")]
    TooLarge(String),
}

/// How labeling starts.
#[derive(Debug, Clone, Copy)]
pub enum Start<'a> {
    /// Fit the template to the first frame, whose vertical axis is given.
    Fit(FitConfig, UpAxis),
    /// The first frame's labels are known: for each template marker, its point index.
    Known(&'a [Option<usize>]),
}

/// Labels of a whole take: for every frame and template marker, the index of its point in
/// that frame's cloud, or none.
#[derive(Debug, Clone, PartialEq)]
pub struct Labels {
    markers: usize,
    point: Vec<u32>,
    estimated_mm: Vec<Option<Vec3>>,
}

const NONE: u32 = u32::MAX;

impl Labels {
    /// Labels given frame by frame (for each frame, each marker's point), for scoring
    /// another labeler's output or tests.
    pub fn from_frames(markers: usize, frames: &[Vec<Option<usize>>]) -> Labels {
        let mut point = Vec::with_capacity(frames.len() * markers);
        for frame in frames {
            point.extend((0..markers).map(|m| frame.get(m).copied().flatten().map_or(NONE, |p| p as u32)));
        }
        Labels { markers, estimated_mm: vec![None; point.len()], point }
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.point.len().checked_div(self.markers).unwrap_or(0)
    }

    /// The point (index into the frame's cloud) labeled as marker `marker` in frame `frame`.
    pub fn get(&self, frame: usize, marker: usize) -> Option<usize> {
        let p = self.point[frame * self.markers + marker];
        (p != NONE).then_some(p as usize)
    }

    /// Where the labeler estimated marker `marker` in frame `frame` while it was not seen.
    pub fn estimate_mm(&self, frame: usize, marker: usize) -> Option<Vec3> {
        self.estimated_mm[frame * self.markers + marker]
    }

    /// The labeled take: one column per template marker (missing where no point was labeled),
    /// then, with `keep_unlabeled`, the points no marker took as `*0`, `*1`, ... columns.
    /// Sample quality (residual, cameras) is copied from `raw` when given: `frames` must then
    /// have been made from it by [`PointFrames::from_take`].
    pub fn to_take(
        &self,
        frames: &PointFrames,
        names: &[MarkerName],
        raw: Option<&Take>,
        keep_unlabeled: bool,
    ) -> Take {
        let t = self.frame_count();
        let extra = if keep_unlabeled {
            (0..t).map(|f| frames.frame(f).len().saturating_sub(self.labeled_in(f))).max().unwrap_or(0)
        } else {
            0
        };
        let mut all_names = names.to_vec();
        all_names.extend((0..extra).map(|k| MarkerName::parse(&format!("*{k}"))));
        // Cannot fail: the rate came from a valid take.
        let mut take = Take::empty(all_names, t, frames.frame_rate_hz()).expect("valid frame rate");
        if let Some(raw) = raw {
            take.first_frame = raw.first_frame;
            take.up_axis = raw.up_axis;
        }
        let mut used = Vec::new();
        for f in 0..t {
            let points = frames.frame(f);
            let columns = frames.columns(f);
            used.clear();
            used.resize(points.len(), false);
            let put = |take: &mut Take, column: usize, p: usize| {
                let _ = take.set_position_mm(f, column, Some(points[p]));
                if let Some(raw) = raw {
                    take.set_quality(f, column, raw.quality(f, columns[p] as usize));
                }
            };
            for m in 0..self.markers {
                if let Some(p) = self.get(f, m) {
                    used[p] = true;
                    put(&mut take, m, p);
                }
            }
            if keep_unlabeled {
                let unlabeled = used.iter().enumerate().filter(|(_, used)| !**used).map(|(p, _)| p);
                for (column, p) in (self.markers..).zip(unlabeled) {
                    put(&mut take, column, p);
                }
            }
        }
        take
    }

    /// A check that needs no truth, for real takes: of the labeled samples that have at least
    /// one labeled rigid neighbour (template spread at most 12 mm), how many keep every such
    /// edge within `tolerance_mm` (or three spreads) of its template length. A marker given a
    /// ghost or another marker's point breaks its edges. Returns (consistent, checked).
    pub fn edge_consistency(&self, frames: &PointFrames, template: &Template, tolerance_mm: f64) -> (usize, usize) {
        let (mut consistent, mut checked) = (0, 0);
        for f in 0..self.frame_count() {
            let points = frames.frame(f);
            for (i, edges) in template.edges().iter().enumerate() {
                let Some(p) = self.get(f, i) else { continue };
                let mut any = false;
                let mut ok = true;
                for e in edges.iter().filter(|e| e.std_mm <= 12.0) {
                    if let Some(q) = self.get(f, e.neighbour) {
                        any = true;
                        let d = (points[p] - points[q]).norm();
                        ok &= (d - e.length_mm).abs() <= tolerance_mm.max(3.0 * e.std_mm);
                    }
                }
                if any {
                    checked += 1;
                    consistent += usize::from(ok);
                }
            }
        }
        (consistent, checked)
    }

    fn labeled_in(&self, frame: usize) -> usize {
        (0..self.markers).filter(|&m| self.get(frame, m).is_some()).count()
    }
}

/// Labels every frame of `frames` with `template`'s markers. Returns the labels and, when
/// the start was fitted, the fit. With a skeleton `pose_model`, missing markers are estimated
/// from a pose fitted every frame ([`ik`]).
pub fn label_frames(
    frames: &PointFrames,
    template: &Template,
    config: &LabelConfig,
    start: Start<'_>,
    pose_model: Option<ik::MarkerModel>,
) -> Result<(Labels, Option<InitialFit>), LabelError> {
    if frames.frame_count() == 0 {
        return Err(LabelError::Config("the take has no frames".into()));
    }
    let m = template.marker_count();
    // Labels hold one entry per frame and template marker: bound them like the clouds.
    if frames.frame_count().saturating_mul(m) > cloud::MAX_POINTS {
        return Err(LabelError::TooLarge(format!(
            "{} frames x {m} template markers (at most {} labels)",
            frames.frame_count(),
            cloud::MAX_POINTS
        )));
    }
    let first = frames.frame(0);
    let (initial, fit) = match start {
        Start::Fit(fit_config, up) => {
            let fit = fit_first_frame(template, first, up, &fit_config)?;
            (fit.assignment.clone(), Some(fit))
        }
        Start::Known(initial) => (initial.to_vec(), None),
    };
    let mut labeler = Labeler::new(template, *config, frames.frame_rate_hz())?;
    if let Some(model) = pose_model {
        labeler = labeler.with_pose_model(model, ik::IkConfig::default())?;
    }
    labeler.start(template, first, &initial)?;
    let mut point = Vec::with_capacity(frames.frame_count() * m);
    let mut estimated_mm = Vec::with_capacity(frames.frame_count() * m);
    point.extend(initial.iter().map(|p| p.map_or(NONE, |p| p as u32)));
    estimated_mm.extend(std::iter::repeat_n(None, m));
    for f in 1..frames.frame_count() {
        let labels = labeler.step(frames.frame(f));
        point.extend(labels.iter().map(|p| p.unwrap_or(NONE)));
        estimated_mm
            .extend(labeler.positions_mm().iter().zip(labeler.estimated()).map(|(p, &e)| if e { *p } else { None }));
    }
    Ok((Labels { markers: m, point, estimated_mm }, fit))
}
