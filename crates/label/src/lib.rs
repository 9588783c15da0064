//! # locap-label: online marker labeling
//!
//! Implements "Online marker labeling for fully automatic skeleton tracking in optical motion
//! capture" (soft graph matching; `../shared/papers/online-marker-labeling-soft-graph-matching.txt`),
//! sections 3 and 4. A capture system hands over, every frame, an unordered cloud of points:
//! markers, ghosts (reflections), and not every marker. [`Labeler`] names the points frame
//! after frame, using only the frames seen so far (online):
//!
//! - [`template`]: the marker set, a labeled reference pose and each marker's rigid edges;
//!   [`model`]: the same from markers on a skeleton at rest, with no labeled take;
//! - [`initial_fit`]: labels of the first frame by fitting the template (section 3, end);
//! - [`kalman`]: a constant-velocity Kalman filter per marker predicts and gates candidates;
//! - [`labeler`]: the frame loop: soft graph matching on the rigid edges (Eq. 1-5,
//!   [`labeler::edges`]), missing-marker estimation from rigid neighbours or a fitted pose
//!   (section 4, Eq. 13, [`labeler::estimate`]), and the CP / UGM baselines of the paper's
//!   comparison ([`labeler::baselines`]);
//! - [`assignment`]: the Hungarian algorithm with dummies (Eq. 5) on the sparse candidate
//!   graph, split into independent components so a frame costs microseconds;
//! - [`cloud`]: the per-frame point clouds of a take.
//!
//! [`label_take`] labels a whole take in one call (first-frame fit, the online loop, the
//! labeled take), [`label_frames`] runs the loop on point clouds with a known or fitted start.
//! This crate never reads files: the `locap label` command does, with `locap-io`.
//!
//! ```no_run
//! # fn demo(raw: &locap_core::Take, labeled_take: &locap_core::Take) -> Result<(), locap_label::LabelError> {
//! use locap_label::{LabelConfig, Template, label_take};
//! let template = Template::from_take(labeled_take, None)?;
//! let labeled = label_take(raw, &template, &LabelConfig::default())?;
//! println!("{} marker samples labeled", labeled.labeled_samples());
//! # Ok(())
//! # }
//! ```

pub mod assignment;
pub mod body;
pub mod cloud;
pub mod ik;
pub mod initial_fit;
pub mod kalman;
pub mod labeler;
pub mod model;
pub mod pose_fit;
pub mod reacquire;
pub mod segment_swaps;
pub mod start;
pub mod subject;
pub mod template;

pub use cloud::PointFrames;
pub use initial_fit::{FitConfig, FitMethod, InitialFit, fit_first_frame};
pub use labeler::{LabelConfig, Labeler, Method};
pub use model::ModelMarker;
pub use template::Template;

use locap_core::{MarkerName, Take, UpAxis};

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
    /// Fit the template to the first frame it is sure of, whose vertical axis is given
    /// (another subject's take: calibrated on the take, [`subject::label_adapting`]).
    Fit(FitConfig, UpAxis),
    /// The first frame's labels are known: for each template marker, its point index.
    Known(&'a [Option<usize>]),
    /// A fit made already ([`fit_start`]): labeling runs from its frame.
    Fitted(&'a InitialFit),
}

/// Labels of a whole take: for every frame and template marker, the index of its point in
/// that frame's cloud, or none.
#[derive(Debug, Clone, PartialEq)]
pub struct Labels {
    markers: usize,
    point: Vec<u32>,
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
        Labels { markers, point }
    }

    /// Exchanges the points of markers `a` and `b` in frame `frame`.
    pub fn exchange(&mut self, frame: usize, a: usize, b: usize) {
        self.point.swap(frame * self.markers + a, frame * self.markers + b);
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
            for i in 0..self.markers {
                match self.check_sample(frames, template, tolerance_mm, f, i) {
                    Some(EdgeCheck::Kept) => {
                        checked += 1;
                        consistent += 1;
                    }
                    Some(EdgeCheck::Broken) => checked += 1,
                    Some(EdgeCheck::Unchecked) | None => {}
                }
            }
        }
        (consistent, checked)
    }

    /// How sure each label is, from the same check as [`Labels::edge_consistency`]: a labeled
    /// sample is *confirmed* when it keeps every edge to its labeled rigid neighbours, and
    /// *uncertain* when it breaks one or has no labeled rigid neighbour to be checked by.
    pub fn confidence(&self, frames: &PointFrames, template: &Template, tolerance_mm: f64) -> Confidence {
        let m = self.markers;
        let mut per_marker = vec![MarkerConfidence::default(); m];
        let mut uncertain = vec![false; self.point.len()];
        for f in 0..self.frame_count() {
            for (i, counts) in per_marker.iter_mut().enumerate() {
                let Some(check) = self.check_sample(frames, template, tolerance_mm, f, i) else { continue };
                counts.labeled += 1;
                match check {
                    EdgeCheck::Kept => counts.confirmed += 1,
                    EdgeCheck::Broken => counts.broken += 1,
                    EdgeCheck::Unchecked => {}
                }
                uncertain[f * m + i] = check != EdgeCheck::Kept;
            }
        }
        let rejected_points = frames.point_count().saturating_sub(per_marker.iter().map(|c| c.labeled).sum());
        Confidence { per_marker, uncertain, rejected_points }
    }

    /// The issue's check of labels of a subject no template was made of: of the labeled
    /// samples with at least one labeled rigid neighbour (template spread at most 12 mm, and
    /// on the same segment of the template's body where both markers are on one), how many
    /// keep every such edge within `tolerance_mm` of the edge's median length over these
    /// labels (not the template's length: another subject's segments differ). Returns
    /// (consistent, checked).
    pub fn median_edge_consistency(
        &self,
        frames: &PointFrames,
        template: &Template,
        tolerance_mm: f64,
    ) -> (usize, usize) {
        let checks = self.median_edge_checks(frames, template, tolerance_mm);
        let checked = checks.iter().filter(|c| matches!(c, Some(EdgeCheck::Kept | EdgeCheck::Broken))).count();
        let consistent = checks.iter().filter(|c| **c == Some(EdgeCheck::Kept)).count();
        (consistent, checked)
    }

    /// Per sample (`[frame * markers + marker]`) the check of
    /// [`Labels::median_edge_consistency`]; `None` for a sample without a label.
    fn median_edge_checks(
        &self,
        frames: &PointFrames,
        template: &Template,
        tolerance_mm: f64,
    ) -> Vec<Option<EdgeCheck>> {
        let m = self.markers;
        let t = self.frame_count();
        // A template take can hold two segments still against each other (a kneeling subject's
        // pelvis and shanks); another take moves them. Where the template's body puts both
        // markers on segments, only a pair on one segment is a segment distance.
        let one_segment = |i: usize, j: usize| {
            template.body().is_none_or(|b| match (b.member[i], b.member[j]) {
                (Some((a, _)), Some((c, _))) => a == c,
                _ => true,
            })
        };
        let rigid = move |i: usize| {
            template.edges()[i]
                .iter()
                .filter(move |e| e.std_mm <= 12.0 && one_segment(i, e.neighbour))
                .map(|e| e.neighbour)
        };
        let distance = |f: usize, i: usize, j: usize| {
            let points = frames.frame(f);
            Some((points[self.get(f, i)?] - points[self.get(f, j)?]).norm())
        };
        // The median of every rigid edge over the frames where both ends are labeled.
        let medians: Vec<Vec<(usize, f64)>> = (0..m)
            .map(|i| {
                rigid(i)
                    .filter_map(|j| {
                        let mut d: Vec<f64> = (0..t).filter_map(|f| distance(f, i, j)).collect();
                        if d.is_empty() {
                            return None;
                        }
                        let k = d.len() / 2;
                        let (_, median, _) = d.select_nth_unstable_by(k, f64::total_cmp);
                        Some((j, *median))
                    })
                    .collect()
            })
            .collect();
        let mut out = vec![None; t * m];
        for f in 0..t {
            for (i, edges) in medians.iter().enumerate() {
                if self.get(f, i).is_none() {
                    continue;
                }
                let (mut any, mut ok) = (false, true);
                for &(j, median) in edges {
                    if let Some(d) = distance(f, i, j) {
                        any = true;
                        ok &= (d - median).abs() <= tolerance_mm;
                    }
                }
                out[f * m + i] = Some(match (any, ok) {
                    (false, _) => EdgeCheck::Unchecked,
                    (true, true) => EdgeCheck::Kept,
                    (true, false) => EdgeCheck::Broken,
                });
            }
        }
        out
    }

    /// The edge check of marker `i`'s label in frame `f`; `None` when it has no label.
    fn check_sample(
        &self,
        frames: &PointFrames,
        template: &Template,
        tolerance_mm: f64,
        f: usize,
        i: usize,
    ) -> Option<EdgeCheck> {
        let points = frames.frame(f);
        let p = self.get(f, i)?;
        let mut any = false;
        let mut ok = true;
        for e in template.edges()[i].iter().filter(|e| e.std_mm <= 12.0) {
            if let Some(q) = self.get(f, e.neighbour) {
                any = true;
                let d = (points[p] - points[q]).norm();
                ok &= (d - e.length_mm).abs() <= tolerance_mm.max(3.0 * e.std_mm);
            }
        }
        Some(match (any, ok) {
            (false, _) => EdgeCheck::Unchecked,
            (true, true) => EdgeCheck::Kept,
            (true, false) => EdgeCheck::Broken,
        })
    }

    fn labeled_in(&self, frame: usize) -> usize {
        (0..self.markers).filter(|&m| self.get(frame, m).is_some()).count()
    }
}

/// What the edge check says of one label.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EdgeCheck {
    Kept,
    Broken,
    Unchecked,
}

/// Labeled samples of one template marker, by what its rigid edges say of them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MarkerConfidence {
    /// Samples that took a point.
    pub labeled: usize,
    /// Of those, samples that keep every edge to their labeled rigid neighbours.
    pub confirmed: usize,
    /// Of those, samples that break an edge (the others had no labeled rigid neighbour).
    pub broken: usize,
}

impl MarkerConfidence {
    /// The share of the marker's labels its edges confirm (0 to 1); `None` for a marker
    /// never labeled.
    pub fn score(&self) -> Option<f64> {
        (self.labeled > 0).then(|| self.confirmed as f64 / self.labeled as f64)
    }
}

/// How sure the labels of a take are ([`Labels::confidence`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Confidence {
    /// Per template marker.
    pub per_marker: Vec<MarkerConfidence>,
    /// Per sample (`[frame * markers + marker]`): labeled but not confirmed.
    pub uncertain: Vec<bool>,
    /// Raw points no marker took (ghosts, and markers the labeler refused or lost).
    pub rejected_points: usize,
}

impl Confidence {
    /// The `LOCAP:LABEL_CONFIDENCE` lines (one per template marker, `LABEL confidence
    /// labeled`, `LABEL - 0` for a marker never labeled) and the `LOCAP:LABEL_UNCERTAIN` runs
    /// (`LABEL first-last` in C3D frame numbers from `first_frame`, in the compact form of
    /// [`locap_core::range_list`]), as `locap label` writes them.
    ///
    /// # Errors
    /// The runs do not fit the compact form's limits.
    pub fn parameters(
        &self,
        template: &Template,
        first_frame: u32,
    ) -> Result<(Vec<String>, Vec<String>), locap_core::range_list::RangeListError> {
        let lines = template
            .names()
            .iter()
            .zip(&self.per_marker)
            .map(|(name, c)| match c.score() {
                Some(score) => format!("{} {score:.4} {}", name.full(), c.labeled),
                None => format!("{} - 0", name.full()),
            })
            .collect();
        let m = template.marker_count();
        let base = first_frame as usize;
        let frames = self.uncertain.len() / m.max(1);
        let mut runs = Vec::new();
        for marker in 0..m {
            let mut f = 0;
            while f < frames {
                if !self.uncertain[f * m + marker] {
                    f += 1;
                    continue;
                }
                let start = f;
                while f < frames && self.uncertain[f * m + marker] {
                    f += 1;
                }
                runs.push(format!("{} {}-{}", template.names()[marker].full(), base + start, base + f - 1));
            }
        }
        Ok((lines, locap_core::range_list::encode(&runs)?))
    }

    /// Labeled samples, all markers together.
    pub fn labeled(&self) -> usize {
        self.per_marker.iter().map(|c| c.labeled).sum()
    }

    /// Labeled samples not confirmed by their edges.
    pub fn uncertain_samples(&self) -> usize {
        self.per_marker.iter().map(|c| c.labeled - c.confirmed).sum()
    }
}

/// A raw take labeled by [`label_take`], with what labeling found on the way.
#[derive(Debug, Clone)]
pub struct Labeled {
    /// The labeled take: one column per template marker (missing where no point was
    /// labeled), then, with [`LabelConfig::keep_unlabeled`], the points no marker took as
    /// `*0`, `*1`, ...; sample quality, first frame and vertical axis come from the raw take.
    pub take: Take,
    /// Which point of its frame's cloud each template marker took.
    pub labels: Labels,
    /// The raw take's point clouds, which [`Labeled::labels`] index into.
    pub frames: PointFrames,
    /// The first frame's fit of the template.
    pub fit: InitialFit,
    /// When the template's body was sure of no frame (another subject), or the template is a
    /// marker model's ([`Template::from_model`]), the template calibrated on the take that
    /// labeled it ([`subject::label_adapting`]): its edges are this subject's, for
    /// confidences.
    pub calibrated: Option<Template>,
}

impl Labeled {
    /// The template whose distances the labels keep: the calibrated one, else `template`
    /// (the one labeling was given).
    pub fn subject_template<'a>(&'a self, template: &'a Template) -> &'a Template {
        self.calibrated.as_ref().unwrap_or(template)
    }

    /// Marker samples (frame x template marker) that took a point.
    pub fn labeled_samples(&self) -> usize {
        (0..self.labels.frame_count()).map(|f| self.labels.labeled_in(f)).sum()
    }

    /// Raw points that no marker took: ghosts, and markers left missing.
    pub fn unlabeled_points(&self) -> usize {
        self.frames.point_count() - self.labeled_samples()
    }
}

/// Labels the raw take `raw` (its columns' names are ignored: every valid sample is a point)
/// with `template`'s markers: fits the template to the first frame (`config.fit`, about
/// `raw`'s vertical axis), labels every later frame online, and builds the labeled take.
/// Missing markers are estimated from their rigid neighbours only; see
/// [`label_take_with_pose`] for a skeleton.
///
/// # Errors
/// [`LabelError::TooLarge`] for a take beyond [`cloud::MAX_POINTS`], [`LabelError::FirstFrame`]
/// when the first frame does not show the template's pose, [`LabelError::Config`] for bad
/// settings or a take without frames.
pub fn label_take(raw: &Take, template: &Template, config: &LabelConfig) -> Result<Labeled, LabelError> {
    label_take_with(raw, template, config, None)
}

/// [`label_take`] with missing markers estimated from a pose of `model` fitted every frame
/// (paper section 4, [`ik`]). `model` attaches the template's markers, in template order, to
/// a Y-up skeleton (as ASF and BVH skeletons are); a Z-up take sees it turned into its lab.
///
/// # Errors
/// As [`label_take`], and [`LabelError::Config`] when `model` does not attach as many markers
/// as the template has.
pub fn label_take_with_pose(
    raw: &Take,
    template: &Template,
    config: &LabelConfig,
    model: &ik::MarkerModel,
) -> Result<Labeled, LabelError> {
    label_take_with(raw, template, config, Some(model))
}

fn label_take_with(
    raw: &Take,
    template: &Template,
    config: &LabelConfig,
    model: Option<&ik::MarkerModel>,
) -> Result<Labeled, LabelError> {
    // Before the fit, which reads `config.fit`.
    config.check()?;
    let frames = PointFrames::try_from_take(raw)?;
    let model = model.map(|m| match raw.up_axis {
        UpAxis::Z => m.clone().in_lab(ik::MarkerModel::y_up_in_z_up_lab()),
        UpAxis::Y => m.clone(),
    });
    check_size(&frames, template)?;
    let subject::Adapted { labels, fit, calibrated } =
        subject::label_adapting(&frames, template, config, raw.up_axis, model)?;
    let take = labels.to_take(&frames, template.names(), Some(raw), config.keep_unlabeled);
    Ok(Labeled { take, labels, frames, fit, calibrated })
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
    check_size(frames, template)?;
    match start {
        Start::Fit(fit, up) => {
            let config = LabelConfig { fit, ..*config };
            let adapted = subject::label_adapting(frames, template, &config, up, pose_model)?;
            Ok((adapted.labels, Some(adapted.fit)))
        }
        Start::Fitted(fit) => {
            if fit.assignment.len() != template.marker_count() || fit.frame >= frames.frame_count() {
                return Err(LabelError::Config(format!(
                    "a fit of {} markers at frame {} for {} template markers and {} frames",
                    fit.assignment.len(),
                    fit.frame,
                    template.marker_count(),
                    frames.frame_count()
                )));
            }
            Ok((run(frames, template, config, fit, pose_model)?, Some(fit.clone())))
        }
        Start::Known(initial) => {
            if initial.len() != template.marker_count() {
                return Err(LabelError::Config(format!(
                    "{} initial labels for {} template markers",
                    initial.len(),
                    template.marker_count()
                )));
            }
            let known = InitialFit {
                assignment: initial.to_vec(),
                transform: locap_clean::procrustes::RigidTransform {
                    rotation: nalgebra::Rotation3::identity(),
                    translation: locap_core::Vec3::zeros(),
                },
                rms_mm: 0.0,
                frame: 0,
                sure_markers: initial.iter().flatten().count(),
                // The template's reference pose places the markers not in the frame.
                expected_mm: Vec::new(),
            };
            Ok((run(frames, template, config, &known, pose_model)?, None))
        }
    }
}

/// The first labels of `frames` (whose vertical axis is `up`): the articulated fit
/// ([`start::find_start`]) where the template has a body and `config` asks for it, else the
/// rigid fit of the template's reference frame to the first frame ([`fit_first_frame`]).
/// An articulated fit sure of less than [`start::START_SURE_FRACTION`] of the body gives way
/// to a rigid fit that succeeds.
///
/// # Errors
/// [`LabelError::FirstFrame`] when the fit is sure of no frame tried.
pub fn fit_start(
    frames: &PointFrames,
    template: &Template,
    up: UpAxis,
    config: &FitConfig,
) -> Result<InitialFit, LabelError> {
    let Some(body) = template.body().filter(|_| config.method == FitMethod::Articulated) else {
        return fit_first_frame(template, frames.frame(0), up, config);
    };
    match start::find_start(frames, template, body, config) {
        Ok(fit) if fit.sure_markers as f64 >= start::START_SURE_FRACTION * body.placeable() as f64 => Ok(fit),
        // A body of sparse segments (a marker or two per bone, as CMU's 41) leaves the
        // articulated fit unsure of much of it; a take that starts in the template's pose
        // is then better started by the rigid fit, which sees every marker at once.
        articulated => match fit_first_frame(template, frames.frame(0), up, config) {
            Ok(rigid) => Ok(rigid),
            Err(rigid) => articulated.map_err(|a| {
                let reason = |e: LabelError| match e {
                    LabelError::FirstFrame(reason) => reason,
                    other => other.to_string(),
                };
                LabelError::FirstFrame(format!("{}; rigid fit: {}", reason(a), reason(rigid)))
            }),
        },
    }
}

/// A take with frames, and labels for it that fit under the ceiling of the clouds.
fn check_size(frames: &PointFrames, template: &Template) -> Result<(), LabelError> {
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
    Ok(())
}

/// The online loop from the fitted frame's labels on, forwards to the end and, when the fit
/// was made later than the first frame, backwards to the first.
fn run(
    frames: &PointFrames,
    template: &Template,
    config: &LabelConfig,
    fit: &InitialFit,
    pose_model: Option<ik::MarkerModel>,
) -> Result<Labels, LabelError> {
    let m = template.marker_count();
    let t = frames.frame_count();
    let k = fit.frame.min(t - 1);
    let mut point = vec![NONE; t * m];
    // A fit of the first frame (the usual case) labels the clouds as they are, uncopied.
    let forward = (k > 0).then(|| frames.slice_frames(k..t));
    let ahead = run_one_way(forward.as_ref().unwrap_or(frames), template, config, fit, pose_model.clone())?;
    point[k * m..].copy_from_slice(&ahead);
    if k > 0 {
        let backward = frames.reversed(0..k + 1);
        let behind = run_one_way(&backward, template, config, fit, pose_model)?;
        for (i, labels) in behind.chunks(m).enumerate().skip(1) {
            let f = k - i;
            point[f * m..(f + 1) * m].copy_from_slice(labels);
        }
    }
    Ok(Labels { markers: m, point })
}

/// The online loop over `frames` from the fit's labels of its first frame.
fn run_one_way(
    frames: &PointFrames,
    template: &Template,
    config: &LabelConfig,
    fit: &InitialFit,
    pose_model: Option<ik::MarkerModel>,
) -> Result<Vec<u32>, LabelError> {
    let m = template.marker_count();
    let mut labeler = Labeler::new(template, *config, frames.frame_rate_hz())?;
    if let Some(model) = pose_model {
        labeler = labeler.with_pose_model(model, ik::IkConfig::default())?;
    }
    if fit.expected_mm.is_empty() {
        labeler.start(template, frames.frame(0), &fit.assignment)?;
    } else {
        labeler.start_fitted(template, frames.frame(0), &fit.assignment, &fit.expected_mm)?;
    }
    // Re-acquisition fits segments: a body whose segments leave many markers out (CMU's 41,
    // a marker or two per bone) is not fitted sure enough to re-acquire from, and on such
    // takes re-fits cost speed for no gain.
    let covered = |b: &body::Body| b.placeable() as f64 >= start::START_SURE_FRACTION * m as f64;
    let mut reacquirer = match (config.reacquire && config.method == Method::SoftGraph, template.body()) {
        (true, Some(body)) if covered(body) => Some(reacquire::Reacquirer::new(body, m, frames.frame_rate_hz())),
        _ => None,
    };
    let mut point = Vec::with_capacity(frames.frame_count() * m);
    point.extend(fit.assignment.iter().map(|p| p.map_or(NONE, |p| p as u32)));
    for f in 1..frames.frame_count() {
        let points = frames.frame(f);
        labeler.step(points);
        if let Some(r) = &mut reacquirer {
            let changes = r.check(points, labeler.labels());
            if !changes.is_empty() {
                labeler.relabel(points, &changes)?;
            }
        }
        point.extend(labeler.labels().iter().map(|p| p.unwrap_or(NONE)));
    }
    Ok(point)
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::Vec3;

    const RATE: f64 = 120.0;
    const FRAMES: usize = 240;

    /// Five markers of one rigid body, turning and travelling.
    fn body(f: usize) -> Vec<Vec3> {
        let t = f as f64 / RATE;
        let (c, s) = ((0.8 * t).cos(), (0.8 * t).sin());
        [[0.0, 0.0, 0.0], [150.0, 0.0, 0.0], [0.0, 100.0, 0.0], [40.0, 60.0, 120.0], [-80.0, 30.0, 50.0]]
            .iter()
            .map(|&[x, y, z]| Vec3::new(c * x - s * y + 300.0 * t, s * x + c * y, z + 1000.0))
            .collect()
    }

    const GHOST: [f64; 3] = [600.0, -500.0, 900.0];

    /// The labeled take, and its raw version: the five markers and, from the second frame
    /// on (the first-frame fit of so small a template needs a clean frame), a ghost, in
    /// columns `*0`..`*5` that change every frame.
    fn takes() -> (Take, Take) {
        let names: Vec<MarkerName> = (0..5).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let labeled: Vec<Option<Vec3>> = (0..FRAMES).flat_map(|f| body(f).into_iter().map(Some)).collect();
        let mut raw = Vec::with_capacity(FRAMES * 6);
        for f in 0..FRAMES {
            let mut points = body(f);
            points.push(Vec3::from(GHOST));
            raw.extend((0..6).map(|c| Some(points[(c + f) % 6]).filter(|_| f > 0 || (c + f) % 6 < 5)));
        }
        let raw_names = (0..6).map(|i| MarkerName::parse(&format!("*{i}"))).collect();
        (Take::from_samples(names, &labeled, RATE).unwrap(), Take::from_samples(raw_names, &raw, RATE).unwrap())
    }

    #[test]
    fn label_take_names_the_raw_points() {
        let (labeled, raw) = takes();
        let template = Template::from_take(&labeled, Some(0)).unwrap();
        let config = LabelConfig::default();
        let out = label_take(&raw, &template, &config).unwrap();
        assert_eq!(out.take.markers(), labeled.markers());
        for f in 0..FRAMES {
            for m in 0..5 {
                assert_eq!(out.take.position_mm(f, m), labeled.position_mm(f, m), "frame {f}, marker {m}");
            }
        }
        assert_eq!((out.labeled_samples(), out.unlabeled_points()), (FRAMES * 5, FRAMES - 1));
        assert!(out.fit.rms_mm < 1e-6, "{}", out.fit.rms_mm);
        // The same labels as the loop on the clouds with a fitted start.
        let (labels, fit) =
            label_frames(&out.frames, &template, &config, Start::Fit(config.fit, raw.up_axis), None).unwrap();
        assert_eq!((labels, fit), (out.labels, Some(out.fit)));

        // Kept, the ghost is the one unlabeled column.
        let kept = label_take(&raw, &template, &LabelConfig { keep_unlabeled: true, ..config }).unwrap();
        assert_eq!(kept.take.marker_count(), 6);
        assert_eq!(kept.take.markers()[5].full(), "*0");
        assert!((1..FRAMES).all(|f| kept.take.position_mm(f, 5) == Some(Vec3::from(GHOST))));
    }

    #[test]
    fn label_take_refuses_bad_settings_and_a_foreign_model() {
        let (labeled, raw) = takes();
        let template = Template::from_take(&labeled, Some(0)).unwrap();
        let bad =
            LabelConfig { fit: FitConfig { accept_mm: f64::NAN, ..FitConfig::default() }, ..LabelConfig::default() };
        assert!(matches!(label_take(&raw, &template, &bad), Err(LabelError::Config(_))));
        let model = ik::tests::arm_model();
        assert_ne!(model.marker_count(), template.marker_count());
        let error = label_take_with_pose(&raw, &template, &LabelConfig::default(), &model).unwrap_err();
        assert!(matches!(error, LabelError::Config(_)), "{error}");
    }
}
