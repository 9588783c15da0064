//! Per-gap choice of the fill method by trial gaps in the same take (issue 15, item 1).
//!
//! No single method wins every gap: interpolation is hard to beat over a few frames, the
//! locality EDM fill (LocalMoCap section 3.1, Eq. 1-2) and the rigid-body fill carry a marker
//! with its segment over long gaps, and PCA (Gløersen & Federolf 2016) is strong wherever the
//! whole body moves in a low-dimensional way. Which one wins depends on the marker, the motion
//! and which neighbours are missing with it, so the choice is made per gap, from the take
//! itself: no training, any marker set.
//!
//! # The method
//! For every gap of marker `i` over frames `[s, e)`:
//! 1. *trial gaps*: [`AutoConfig::trials`] windows (more for short gaps) of the same length
//!    where `i` *is* captured, nearest in time to the real gap first (on both sides, seeded
//!    jitter so they do not all fall on one motion phase), within [`AutoConfig::search_s`].
//!    Each trial hides `i` over its window and also every marker that is missing at the
//!    corresponding frame of the real gap, so a gap with simultaneous neighbours is tried
//!    with the same neighbours missing. A window qualifies only where `i` and its borders
//!    are captured and each of `i`'s [`CHECKED_NEIGHBOURS`] best neighbours that is captured
//!    throughout the real gap is captured throughout the window as well (the trial must not
//!    see a poorer neighbourhood than the real gap, nor, by the hiding rule, a richer one).
//!    Where no window of the gap's length qualifies (a short take, a marker seen briefly), an
//!    interior gap is tried on windows of half its length, else a quarter (at least
//!    [`MIN_SHORTER_TRIAL`] frames), which stand for its middle and hide what is missing there,
//!    and spline and linear interpolation are left out of its candidates
//!    ([`AutoConfig::shorter_trials`]);
//!    and [`AutoConfig::neighbour_trials`] trials at the real gap's *own* frames: each of
//!    `i`'s best neighbours that is captured throughout the gap and its borders is hidden
//!    there in its turn (with `i` and whatever else is missing there) and filled. They see the
//!    gap's own motion, which trials elsewhere in time cannot: a pose the take never repeats
//!    defeats a method that learned from the rest of the take (PCA on a short take), and a
//!    short take may have no window of the gap's length to spare;
//! 2. every candidate ([`FillMethod::Edm`], [`FillMethod::PcaAligned`], [`FillMethod::Rigid`],
//!    [`FillMethod::RigidSpline`] for gaps up to [`AutoConfig::rigid_spline_s`],
//!    [`FillMethod::Spline`], [`FillMethod::Linear`], [`FillMethod::Distance`] and the
//!    paper's [`FillMethod::Pca`] for gaps of at least [`AutoConfig::distance_min_s`];
//!    [`FillMethod::PoseMatch`] for those too where [`AutoConfig::pose_match`] is set) fills
//!    each trial; each is scored by its RMSE over the hidden samples of `i` in each trial,
//!    averaged over the trials ([`TrialScore::MeanOfTrials`]; a neighbour trial's RMSE
//!    counts at a quarter, [`AutoConfig::neighbour_weight`]). A sample a candidate leaves missing counts with the
//!    error of the reference candidate there (linear inside the take, EDM at its edges), the
//!    fill it would fall back to;
//! 3. the real gap is filled with the inverse-squared-RMSE blend of the best
//!    [`AutoConfig::blend`] candidates (1: the best alone), per frame over the candidates that
//!    filled that frame (the reference where none did), leaving out a candidate's sample that
//!    is implausible (below). With no qualifying trial window (a short take, a marker almost
//!    never captured) a fixed ranking by gap length is used instead ([`default_ranking`]),
//!    measured once on one take, not per take.
//!
//! [`AutoFilled::choices`] records, per gap, the blend, the trial count and every
//! candidate's trial RMSE, so the clean stage can write which method filled which gap.
//!
//! # Second pass
//! A gap with other markers missing at the same time is filled, and tried, without them:
//! an arm's markers occluded together leave each other's fill a poorer neighbourhood than the
//! body has. Once every gap has its first fill, each gap of at least
//! [`AutoConfig::second_pass_min_s`] during which another labeled marker is missing, and was
//! filled, is filled again (a gap its rigid cluster carried is not: that fill is exact up to
//! the markers' noise). The refill works on the take with every *other* marker's first fills
//! in place (its own taken out): its candidates then carry it with neighbours that are all
//! there, blended with the first pass's blend and weights (no trial and no cluster rule run
//! again). With [`AutoConfig::second_pass_trials`] steps 1-2 run again too, with the others'
//! first fills in place in the trials as well: a better choice, at the cost of a second pass
//! as dear as the first. What is *captured* (the neighbours tried at the gap's own frames,
//! those a window must have, a rigid cluster's partners, the distances that judge a fill
//! plausible) is still read from the input: a fill is no truth to try on. The neighbours'
//! fills bring their own error, which trials on captured neighbours cannot see; on a long gap
//! the fuller neighbourhood outweighs it, on a short one, which interpolation fills within a
//! millimetre or two, it does not: hence the least length. A refill fills only the frames the
//! first pass filled. Every refill reads the first pass's take, never another refill, so the
//! result does not depend on the order ([`AutoConfig::second_pass`],
//! [`GapChoice::second_pass`]).
//!
//! # Cost
//! Candidates never refill the whole take. Each trial and the real gap are filled on
//! *sub-takes*: for EDM, rigid, spline, linear and the distance fill, the gap's frames plus
//! [`AutoConfig::context_s`] (at least the gap's own length) on each side, and only `i` and
//! its [`AutoConfig::markers`] best neighbours (ranked once over the whole take,
//! [`crate::neighbours`]); for PCA and pose matching, up to [`AutoConfig::pca_markers`]
//! markers (the 41 nearest), the gap's frames and [`AutoConfig::pca_fit_frames`] frames
//! spread evenly over [`AutoConfig::pca_context_s`] on each side (PCA treats frames as independent samples, and
//! a covariance settles long before every frame is in it), reconstructing `i` alone
//! ([`crate::baseline::pca::fill_marker`]). So a gap costs a bounded number of small
//! eigen-decompositions however long the take, instead of one `3M x 3M` PCA per gapped marker
//! over every frame. Gaps are independent (each reads only the input take; a refill of the
//! second pass, the first pass's) and are filled in
//! parallel with rayon; the result does not depend on the thread count. The windows make each
//! candidate a *local* version of its method (PCA's covariance comes from the window, and so
//! does EDM's and the rigid fills' neighbour ranking, with each pair's steadiness over the whole
//! take added to it, [`AutoConfig::take_variance_share`]); the trials measure exactly the local
//! version that fills the real gap.
//!
//! The PCA candidates, the costliest, fill an interior gap's windows of its length on one
//! sub-take ([`AutoConfig::shared_pca_fit`]): each window hides what the gap misses, so their
//! frames share their predictors and one model fills them all. The gap itself keeps a
//! sub-take of its own, whose even sample of the context takes in the windows' frames too
//! (they lie nearest to it in time).
//!
//! # Edge gaps
//! A gap touching the take's start or end has one border. Its trials are cut the same way
//! (the sub-take starts or ends at the trial window), and only the frames EDM fills under its
//! edge rules ([`crate::edm`], "Edge gaps") are filled: the candidates that may fill them are
//! EDM, PCA and rigid (spline and linear would hold the border constant, which invents
//! motion), scored on the frames EDM reached. Frames EDM refuses stay missing: no candidate
//! is trusted beyond the point where the marker's neighbours stop riding with it.
//!
//! # Choices made
//! - A candidate's score is the mean of its trials' RMSEs: every trial counts once, a long
//!   failure in one trial weighs less than in the RMSE of all trials pooled, and more than
//!   in their median. Pooled, mean and median ([`TrialScore`], the others kept as options)
//!   were compared on 720 protocol gaps (six takes, three labs, six seeds; each take held
//!   out in turn while the others chose): the mean was chosen with every take held out and
//!   was better than the pooled RMSE on five of the six (docs/benchmarks.md).
//! - Blend of the best three by inverse squared trial RMSE. Blending fills with partly
//!   independent errors beats any of them: the best alone was measured worse, and the
//!   least-squares combination of the candidates' trial errors (Bates & Granger 1969,
//!   [`Weighting::LeastSquares`], kept as an option) no better. The best two were the
//!   default until the PCA candidate was corrected by the residuals of the nearest poses;
//!   with it the best three did better on the tuning takes and other labs' alike, and the
//!   best four no better (docs/benchmarks.md, "The best three blended").
//! - Trial windows nearest in time first: the motion near a gap resembles the motion in it
//!   more than motion elsewhere in the take. Three trials: more cost more and changed little.
//!   A short gap gets more, enough to cover half a second together
//!   ([`AutoConfig::trial_time_s`], at most [`MOST_TRIALS`]): a trial of a few frames
//!   scores the candidates on a few samples, and the interpolations and the rigid fills are
//!   within a millimetre of each other there, so three such trials choose by noise. The
//!   windows are short, so the cost is small.
//! - Shorter windows only where none of the gap's length exists: a shorter window flatters
//!   the interpolations, whose error grows fastest with the gap's length, so beside windows
//!   of the full length (topping up a gap that found one or two) they misled, on short takes
//!   most, and where they decide, spline and linear are no candidates (with them, the real
//!   occlusion statistics' gaps of 1-2 s lost 1.3 mm, without them 0.5, in a first
//!   version); they test the marker's own fills
//!   (which neighbours carry it), where the trials at the gap's own frames test its
//!   neighbours'. Measured on other labs' takes and subjects (docs/benchmarks.md, "Shorter
//!   trial windows").
//! - Two neighbour trials: they cost as much as two more windows, and on the short take of
//!   the tuning set they changed the choice where more windows could not; four changed little.
//!   Their RMSEs count at a quarter ([`AutoConfig::neighbour_weight`]): they see a poorer
//!   neighbourhood than the real gap. Without them another lab's plate-marker take and the
//!   short take gained and an arm gap was lost; scaled down the gains mostly stay and the
//!   arm gap with them (docs/benchmarks.md).
//! - A marker on a rigid plate is not left to the trials: where its three steadiest
//!   neighbours keep their distances to it within 1 mm (standard deviation over the take,
//!   [`AutoConfig::rigid_cluster_mm`]) and are captured throughout the gap, the rigid fill
//!   alone fills it. Physics makes it exact there, and the trials, which on a short take
//!   see few windows and at the gap's own frames a plate with a partner hidden, only add
//!   noise. Under that limit, body-worn markers of the 41-marker set never qualify (the
//!   steadiest head marker's third neighbour varies by 3.3 mm), and a 62-marker set's plates all do
//!   (0.2-1.0 mm; 1.5 changed little, 2 took in the feet and was worse; docs/benchmarks.md).
//!   A plate must also have shown itself over as many frames as the gap: a marker seen for
//!   a few frames beside a long gap keeps its distances to markers on other segments as
//!   steady as a plate's there (a knee marker of a 2.4 s walk, seen 38 frames).
//!   Looser clusters count where they are set apart from the body
//!   ([`AutoConfig::rigid_cluster_apart`]): a head cap's four markers keep their distances
//!   to within 0.4-3.8 mm and to nothing else within 10 mm, so no other marker can say more
//!   about one of them than the other three. The ratio (4) and the loosest third partner
//!   (5 mm) were set from the caps' distances before measuring; another subject of the
//!   62-marker set was the held-out check (docs/benchmarks.md).
//!   The partners are the steadiest that can carry the marker, captured through the gap: one
//!   missing in it gives way to the next. Where no three are captured throughout but at
//!   least three of the strict limit's are at every frame (a box of eight markers whose
//!   markers the cameras lose in turn, another lab's take), the marker is carried frame by
//!   frame with whichever are captured (`Context::cluster_fill`).
//! - The real gap's fill has no truth to check it against, so its samples are checked for
//!   plausibility: a blended candidate's sample must keep the marker's distance to at least
//!   half of its [`PLAUSIBILITY_NEIGHBOURS`] best neighbours captured there within what the
//!   take shows for that pair, widened by the pair's own range and at least
//!   [`PLAUSIBLE_MARGIN_MM`]. One that does not is left out (the other blended candidate, or
//!   the best-ranked one that passes, fills; where none passes, the blend stands). Trials
//!   score a candidate on average, and a candidate that is right on them can still fail
//!   grossly on the real gap (a PCA frame resting on two markers put a foot metres off). Half
//!   of the neighbours, not all: a captured neighbour can be wrong itself for a few frames.
//! - PCA sees a wider window (30 s each side) than the other candidates (2 s): its
//!   covariance gains from more poses, the interpolations do not, and EDM's ranking takes
//!   the take's steadiness from the whole take already.
//! - The PCA candidates are the paper's PCA in the aligned frame ([`FillMethod::PcaAligned`])
//!   and, for interior gaps of at least [`AutoConfig::distance_min_s`], in the paper's own
//!   frame ([`FillMethod::Pca`], [`AutoConfig::paper_pca`]), both meeting the borders and
//!   corrected by the residuals of the nearest poses (below). The aligned frame follows a
//!   body that turns; where the body stays in place and faces one way (a treadmill run, a
//!   lift at a table) turning every frame onto the mean shape only adds the alignment's
//!   noise, and the paper's frame wins. The aligned frame's weights are the PCA's own (no
//!   parameter of its own). The paper's frame was first tried beside the aligned one before
//!   the border fade and the residuals, and was no better then; with them it helped the
//!   tuning takes, OpenSim's and the Vicon take and the real occlusion statistics, and left
//!   another lab's 68-marker take within 0.1 mm (docs/benchmarks.md, "The paper's PCA frame
//!   beside the aligned one").
//! - The PCA candidates meet the gap's borders ([`AutoConfig::pca_border_fade_s`]): each
//!   one's error at each border sample, reconstructed as if missing, is removed from its fill,
//!   fading over half a second. The paper's reconstruction ignores the samples beside a gap
//!   and jumps at both borders, which lost it every short gap to interpolation and the
//!   rigid fill; corrected across the whole gap it lost the 2 s gaps instead. Fades of a
//!   quarter, a half and one second were within 0.01 of each other on the protocol grid;
//!   the half was kept, and two other labs' takes were the held-out check
//!   (docs/benchmarks.md).
//! - The PCA candidates correct what their linear model misses by what it missed in the poses
//!   nearest the gap's ([`AutoConfig::pca_residual_neighbours`], eight frames of its window,
//!   [`crate::baseline::pca`], "Residuals of the nearest poses"). A thigh marker on muscle or
//!   a marker swinging on an arc is not a linear mix of the others, and a take that shows a
//!   pose again shows the same miss again. Measured on the tuning takes and other labs' at
//!   once (four, eight and twelve frames alike; docs/benchmarks.md).
//! - The rigid fill with a spline in the donors' frame ([`FillMethod::RigidSpline`]) is a
//!   candidate for gaps up to half a second only: on the real occlusion statistics it is the
//!   best single method up to 60 frames at 120 Hz and worse than the plain rigid fill beyond,
//!   and as a candidate for every length the trials of long gaps sometimes ranked it first.
//! - Distance-constrained smoothing ([`FillMethod::Distance`]) is a candidate for interior
//!   gaps of at least [`AutoConfig::distance_min_s`] (0.1 s: on shorter gaps it made auto
//!   worse, on the tuning takes and another lab's take alike). Alone it beats EDM on
//!   realistic gaps but not where a whole segment is missing, and its errors differ from
//!   EDM's and the interpolations' (it weighs each neighbour by how steady it is and follows
//!   the border velocities), so the blends gain; it shares the sub-take's EDM fill with the
//!   EDM candidate, which it starts from. Anchoring it to the EDM fill made it better alone
//!   and the choice worse (docs/benchmarks.md).
//! - The other constants of [`AutoConfig::default`] and [`default_ranking`] were chosen on
//!   CMU subject 85 (85_12; the neighbour trials on 85_12 and the short 85_02), with
//!   protocol seeds other than the one reported; another subject (CMU 135_02) and another
//!   lab (HDM05) were held out (`locap bench fill --lengths`; the tuning example
//!   `crates/eval/examples/auto_fill.rs`, the test `crates/eval/tests/auto_real.rs`). The
//!   score and the neighbour weight were chosen by leaving each of six takes out in turn.
//! - Pose matching ([`crate::pose_match`]) can be a candidate for interior gaps, on PCA's
//!   window ([`AutoConfig::pose_match`]); from session 2026-12-06 (4) to 2026-12-07 (6) it
//!   was one by default. Alone it is worse than the aligned PCA on most takes; as a
//!   candidate it helped on OpenSim's pipeline takes, where the runs repeat one cycle and
//!   the aligned PCA was the only good candidate. The paper's PCA frame took its place:
//!   beside it pose matching added little there and nothing on the tuning takes, at about
//!   the same cost, and the two together took the 10-minute take past the issue's 10 s
//!   (docs/benchmarks.md).
//! - Unlabeled points (`*N`) are not filled, as in [`crate::fill_gaps`].

use crate::neighbours::{self, Selection};
use crate::{FillMethod, Filled, baseline, edm, procrustes};
use locap_core::gaps::{Gap, gaps_of};
use locap_core::{Take, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// How many of a marker's best neighbours must be as visible in a trial window as in the
/// real gap for the window to qualify.
pub const CHECKED_NEIGHBOURS: usize = 3;

/// The candidates, in the order ties are broken (the first three: those of gaps at the take's
/// edges).
pub const CANDIDATES: [FillMethod; 9] = [
    FillMethod::Edm,
    FillMethod::PcaAligned,
    FillMethod::Rigid,
    FillMethod::RigidSpline,
    FillMethod::Spline,
    FillMethod::Linear,
    FillMethod::Distance,
    FillMethod::PoseMatch,
    FillMethod::Pca,
];

/// Whether candidate `method` learns from the wide sub-take (PCA's window) rather than the
/// local one.
fn learns_from_wide(method: FillMethod) -> bool {
    matches!(method, FillMethod::Pca | FillMethod::PcaAligned | FillMethod::PoseMatch)
}

/// Markers besides one that fix a rigid body's pose: the partners of a rigid cluster.
const CLUSTER_PARTNERS: usize = 3;

/// Smallest RMSE (mm) used for a blend weight: a trial filled exactly does not take all the
/// weight on the strength of a few samples.
const RMSE_FLOOR_MM: f64 = 0.5;

/// Neighbours whose distances a filled sample must keep ([`GapChoice::implausible`]).
pub const PLAUSIBILITY_NEIGHBOURS: usize = 3;
/// Least margin (mm) beyond the distances a take shows between a marker and a neighbour
/// before a fill of it is implausible; the margin is the distance's own range where that is
/// wider. A guard against a candidate gone wrong (a projection through a degenerate frame put
/// a foot metres away), not a judge of accuracy: a pose the take shows nowhere else stays
/// well inside it.
pub const PLAUSIBLE_MARGIN_MM: f64 = 50.0;

/// Shortest trial window (frames) standing for part of a longer gap. In frames, not
/// seconds: a trial scores the candidates on its samples, and fewer than this choose by
/// noise (a gap of under 20 frames, 0.1-0.17 s at 120-200 Hz, gets no shorter windows).
pub const MIN_SHORTER_TRIAL: usize = 10;

/// Most trial gaps elsewhere in time for one real gap ([`AutoConfig::trial_time_s`]).
pub const MOST_TRIALS: usize = 12;

/// How the blended candidates are weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// `1 / RMSE^2` of each candidate's trials.
    InverseSquare,
    /// The combination with the least squared error on the trials (non-negative, summing to 1).
    LeastSquares,
}

/// How a candidate's trial errors make its score.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrialScore {
    /// The RMSE over every trial's hidden samples pooled: one trial's failure can decide.
    Pooled,
    /// The mean over the trials of each trial's RMSE: every trial counts once.
    MeanOfTrials,
    /// The median over the trials of each trial's RMSE: a failure in a minority of trials
    /// does not count.
    MedianOfTrials,
}

/// Settings of [`fill`] (a setting missing from a serialized config takes its default).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AutoConfig {
    /// Trial gaps per real gap (the least; short gaps get more, [`AutoConfig::trial_time_s`]).
    pub trials: usize,
    /// Least time (seconds) the trial gaps elsewhere in time cover together: a short gap gets
    /// more trials than [`AutoConfig::trials`], up to [`MOST_TRIALS`] (0: always `trials`).
    pub trial_time_s: f64,
    /// How many of the best candidates are blended (1: the best alone).
    pub blend: usize,
    /// How they are weighted.
    pub weighting: Weighting,
    /// How each candidate's trial errors are scored (the ranking and the inverse-square
    /// weights).
    pub score: TrialScore,
    /// Frames of context on each side of a gap, in seconds (at least the gap's length is used).
    pub context_s: f64,
    /// Frames of context of the PCA candidate on each side, in seconds: its covariance gains
    /// from more poses than the other candidates' neighbour ranking does.
    pub pca_context_s: f64,
    /// Frames of its window (besides the gap's own) the PCA candidate sees, evenly spaced.
    pub pca_fit_frames: usize,
    /// Time constant (seconds) with which the PCA candidate's error at a gap's borders is
    /// removed from its fill ([`baseline::pca::PcaConfig::border_fade_s`]; 0: the paper's
    /// reconstruction, which leaves a jump at each border). Interpolation meets the borders
    /// and beats PCA on short gaps because of it; a fill of a long gap owes nothing to its
    /// borders' error a second away.
    pub pca_border_fade_s: f64,
    /// Complete frames of its window whose reconstruction errors correct the PCA candidate's
    /// fill ([`baseline::pca::PcaConfig::residual_neighbours`]; 0: none). The linear model
    /// misses what the posture does not explain linearly, and where the take shows a pose
    /// again it misses it again by about as much.
    pub pca_residual_neighbours: usize,
    /// Longest gap (seconds) spline and linear interpolation are candidates for. By default
    /// every gap: the trials already reject them on long gaps (a limit of a quarter second
    /// changed no choice on the take the defaults were chosen on).
    pub interpolate_s: f64,
    /// Longest gap (seconds) the rigid fill with its relative position splined
    /// ([`FillMethod::RigidSpline`]) is a candidate for: like any spline it drifts over long
    /// gaps, and on the real occlusion statistics it is the best single method up to 60
    /// frames at 120 Hz and worse than the plain rigid fill beyond.
    pub rigid_spline_s: f64,
    /// Neighbours of the marker in the sub-takes of EDM, rigid, spline and linear.
    pub markers: usize,
    /// Most markers (the gap's marker included) the PCA candidate and pose matching see,
    /// nearest first (`usize::MAX`: all). 41, a full-body set's size: PCA's cost grows with
    /// the cube of its markers, and beyond the nearest 41 they carry almost no weight
    /// (`exp(-d^2 / 2 sigma^2)`, sigma 200 mm); on larger sets the fill took a quarter to a
    /// half less time and was as accurate within the seed-to-seed spread
    /// (docs/benchmarks.md, "PCA on the 41 nearest markers").
    pub pca_markers: usize,
    /// EDM's neighbour count `K`.
    pub edm_neighbours: usize,
    /// How neighbours are ranked (EDM, rigid and the sub-takes' marker choice).
    pub selection: Selection,
    /// Share of a pair's distance variance over the whole take added to its variance within
    /// the sub-take when EDM and the rigid fills rank neighbours there, for gaps inside the
    /// take ([`Selection::Variance`]; 0, negative or not finite: the sub-take's alone). EDM
    /// weighs its neighbours by the sum as well ([`Context::window_ranking`]).
    pub take_variance_share: f64,
    /// Farthest a trial window may lie from the real gap, in seconds.
    pub search_s: f64,
    /// Seed of the trial windows' jitter.
    pub seed: u64,
    /// Trials at the real gap's own frames: this many of the marker's best neighbours, each
    /// hidden there in its turn (where captured) and filled by every candidate.
    pub neighbour_trials: usize,
    /// Scale of the neighbour trials' errors in a candidate's score (0.25: a neighbour
    /// trial's RMSE counts a quarter of a window's in the mean). A neighbour trial hides one
    /// of the marker's best neighbours, a poorer neighbourhood than the real gap has for the
    /// methods that carry the marker with its neighbours (the rigid fill on a plate of four
    /// markers loses one of its donors there, not in the real gap), so at full weight it
    /// judges them too harshly; it still decides where the windows elsewhere in time cannot
    /// (an arm gap in a pose the take never repeats). Unlike the other defaults, 0.25 was
    /// chosen on all six protocol takes, the two other labs' takes included, each held out in
    /// turn (docs/benchmarks.md).
    pub neighbour_weight: f64,
    /// Largest standard deviation (mm) of the distance between a marker and each of its three
    /// steadiest neighbours over the take for the four to count as one rigid cluster (a marker
    /// plate): where all three are captured throughout a gap and its borders, the rigid fill
    /// alone fills it, exactly up to the markers' noise, whatever the trials measured (0: never).
    pub rigid_cluster_mm: f64,
    /// A cluster looser than [`AutoConfig::rigid_cluster_mm`] still counts where it is set
    /// apart from the rest of the body: its third partner's standard deviation is at most
    /// [`AutoConfig::rigid_cluster_loose_mm`] and the fourth steadiest neighbour's at least
    /// this many times that (a cap of four head markers: 0.4-3.8 mm within, 10-26 mm to
    /// anything else; a foot whose three steadiest partners ride with it while the shin turns).
    /// Worn on soft tissue or a cap, the four are rigid to within their noise, and no other
    /// marker can tell more about where the fourth is. 0: the strict limit alone.
    pub rigid_cluster_apart: f64,
    /// The loosest third partner (standard deviation, mm) of a cluster set apart
    /// ([`AutoConfig::rigid_cluster_apart`]).
    pub rigid_cluster_loose_mm: f64,
    /// Whether distance-constrained smoothing ([`FillMethod::Distance`]) is a candidate (for
    /// interior gaps; it keeps EDM's fill at the take's edges).
    pub distance: bool,
    /// Shortest gap (seconds) distance-constrained smoothing is a candidate for. Below it the
    /// interpolations and the rigid fill with a spline follow the border motion to within a
    /// millimetre, and one more candidate only adds noise to the choice.
    pub distance_min_s: f64,
    /// Whether pose matching ([`FillMethod::PoseMatch`]) is a candidate (for interior gaps of
    /// at least [`AutoConfig::distance_min_s`], as the distance fill: below it the
    /// interpolations win, and the many trials of the many short gaps made it the costliest
    /// candidate). Off by default: beside the paper's PCA frame ([`AutoConfig::paper_pca`]),
    /// which costs about as much, it added little, and the two together took the 10-minute
    /// take past 10 s.
    pub pose_match: bool,
    /// Whether the paper's PCA in its own frame ([`FillMethod::Pca`], translated by the mean
    /// trajectory, not turned) is a candidate beside the aligned one, for interior gaps of at
    /// least [`AutoConfig::distance_min_s`]. Where the body stays in place and faces one way
    /// (a treadmill, a lift at a table) turning every frame onto the mean shape only adds the
    /// alignment's noise; where it turns, the aligned frame wins; the trials tell which.
    pub paper_pca: bool,
    /// Whether the PCA candidates fill a gap's trial windows elsewhere in time together: one
    /// sub-take holds the windows (each hiding what the gap misses) and the context sampled
    /// around the gap, and since the windows miss the same markers, each model (one per set
    /// of predictors) fills all of them. Off: each window gets its own sub-take, centred on
    /// it, and its own models, at the cost of two eigen-decompositions per window, set of
    /// predictors and PCA frame. The gap itself keeps its own sub-take either way: the windows
    /// lie nearest to it in time, and a model without their frames filled it worse.
    pub shared_pca_fit: bool,
    /// Whether an interior gap with no trial window of its length is tried on shorter
    /// windows of the marker itself (half the gap's length, else a quarter, at least
    /// [`MIN_SHORTER_TRIAL`] frames), standing for the gap's middle, rather than leaving the
    /// choice to the trials at its own frames alone; the interpolations are no candidates
    /// there (a shorter window flatters them).
    pub shorter_trials: bool,
    /// Whether gaps of at least [`AutoConfig::second_pass_min_s`] during which another
    /// labeled marker is missing too, and was filled, are filled a second time once every gap
    /// has its first fill, with the other markers' first fills standing in for their missing samples
    /// ([`fill`], "Second pass").
    pub second_pass: bool,
    /// Shortest gap (seconds) the second pass fills again. A short gap's interpolation is
    /// within a millimetre or two, and the neighbours' first fills, off by several on long
    /// gaps, would only pass their error on: refilled (trials run again) from any length,
    /// gaps of 1-30 frames at 120 Hz came out twice as far off on the real occlusion
    /// statistics, and from 1 s on the refill gains (docs/benchmarks.md, "A second pass for
    /// simultaneous gaps").
    pub second_pass_min_s: f64,
    /// Whether the second pass tries every candidate again, on the take with the neighbours'
    /// first fills in place, rather than refilling each gap with the first pass's choice
    /// (blend and weights). It chose better where measured (real occlusion statistics on
    /// CMU/HDM05: OMPE 15.2 mm against 15.8; held out 5.5 against 5.9 and 3.9 against 4.3;
    /// its trials then still took captured neighbours from the first pass's take), but the
    /// second pass costs as much as the first: the 10-minute take took 12.9 s against
    /// 7.0-7.1 s without a second pass (docs/benchmarks.md, "A second pass for simultaneous
    /// gaps").
    pub second_pass_trials: bool,
}

impl AutoConfig {
    /// The defaults with `fill`'s EDM neighbour count and ranking (what
    /// `FillConfig { method: FillMethod::Auto, .. }` runs).
    pub fn from_fill(fill: &crate::FillConfig) -> AutoConfig {
        AutoConfig { edm_neighbours: fill.neighbours, selection: fill.selection, ..AutoConfig::default() }
    }

    /// Trial gaps elsewhere in time wanted for a gap of `gap_frames` at `rate_hz`: enough to
    /// cover [`AutoConfig::trial_time_s`] together, at least [`AutoConfig::trials`] and at
    /// most [`MOST_TRIALS`] (or `trials`, if more).
    pub fn trials_for(&self, gap_frames: usize, rate_hz: f64) -> usize {
        let covering = (self.trial_time_s * rate_hz / gap_frames.max(1) as f64).ceil();
        let covering = if covering.is_finite() && covering > 0.0 { covering as usize } else { 0 };
        covering.clamp(self.trials, MOST_TRIALS.max(self.trials))
    }
}

impl Default for AutoConfig {
    fn default() -> AutoConfig {
        AutoConfig {
            trials: 3,
            trial_time_s: 0.5,
            blend: 3,
            weighting: Weighting::InverseSquare,
            score: TrialScore::MeanOfTrials,
            context_s: 2.0,
            pca_context_s: 30.0,
            pca_fit_frames: 500,
            pca_border_fade_s: 0.5,
            pca_residual_neighbours: 8,
            interpolate_s: 100.0,
            rigid_spline_s: 0.5,
            markers: 10,
            pca_markers: 41,
            edm_neighbours: 6,
            selection: Selection::Variance,
            take_variance_share: 10.0,
            search_s: 60.0,
            seed: 15,
            neighbour_trials: 2,
            neighbour_weight: 0.25,
            rigid_cluster_mm: 1.0,
            rigid_cluster_apart: 4.0,
            rigid_cluster_loose_mm: 5.0,
            distance: true,
            distance_min_s: 0.1,
            pose_match: false,
            paper_pca: true,
            shared_pca_fit: true,
            shorter_trials: true,
            second_pass: true,
            second_pass_min_s: 1.0,
            second_pass_trials: false,
        }
    }
}

/// How one gap was filled.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GapChoice {
    /// Marker index in the take.
    pub marker: usize,
    /// The gap's frames.
    pub frames: Range<usize>,
    /// The blended candidates and their weights (summing to 1), best first.
    pub weights: Vec<(FillMethod, f64)>,
    /// Trial gaps used (0: the default ranking chose).
    pub trials: usize,
    /// Each candidate's trial score in mm ([`AutoConfig::score`]: by default its RMSE over
    /// every trial's hidden samples), best first (empty without trials).
    pub trial_rmse_mm: Vec<(FillMethod, f64)>,
    /// Samples of the gap that were filled.
    pub filled: usize,
    /// Samples where a blended candidate was left out as implausible: it put the marker far
    /// outside the distances to its best neighbours that the take shows
    /// ([`PLAUSIBLE_MARGIN_MM`]); the other blended one fills there, or else the best-ranked
    /// candidate that is plausible.
    #[serde(default)]
    pub implausible: usize,
    /// Whether this is the second pass's fill ([`AutoConfig::second_pass`]): the gap
    /// overlapped another marker's gap that the first pass filled, and was filled again with
    /// that first fill in place.
    #[serde(default)]
    pub second_pass: bool,
}

impl GapChoice {
    /// The method as written in provenance: `edm`, or `edm 0.62 + pca 0.38`; `default:`
    /// in front when no trial gap was found.
    pub fn method(&self) -> String {
        let body = match self.weights.as_slice() {
            [(m, _)] => m.name().to_string(),
            many => many.iter().map(|(m, w)| format!("{} {w:.2}", m.name())).collect::<Vec<_>>().join(" + "),
        };
        if self.trials == 0 { format!("default: {body}") } else { body }
    }

    /// The best candidate's trial RMSE in mm, if there were trials.
    pub fn best_trial_rmse_mm(&self) -> Option<f64> {
        self.trial_rmse_mm.first().map(|(_, e)| *e)
    }
}

/// A take filled by [`fill`], with the choice made for every gap.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoFilled {
    /// The filled take.
    pub filled: Filled,
    /// One entry per gap of a labeled marker that was captured somewhere, in marker then time
    /// order.
    pub choices: Vec<GapChoice>,
}

impl AutoFilled {
    /// Gaps and samples filled per leading method (the blend's first), as `(name, gaps,
    /// samples)` sorted by name, `default` counted apart: the summary of a clean.
    pub fn by_method(&self) -> Vec<(String, usize, usize)> {
        let mut counts: std::collections::BTreeMap<String, (usize, usize)> = Default::default();
        for c in &self.choices {
            let Some((lead, _)) = c.weights.first() else { continue };
            let name = if c.trials == 0 { format!("default {}", lead.name()) } else { lead.name().to_string() };
            let entry = counts.entry(name).or_default();
            entry.0 += 1;
            entry.1 += c.filled;
        }
        counts.into_iter().map(|(name, (gaps, samples))| (name, gaps, samples)).collect()
    }
}

/// The ranking used for a gap without trial windows: by gap length in seconds, interpolation
/// for short gaps, the segment-carrying methods for long ones. Edge gaps use the
/// segment-carrying part alone.
pub fn default_ranking(gap_s: f64, edge: bool) -> &'static [FillMethod] {
    if edge {
        &[FillMethod::Edm, FillMethod::Rigid, FillMethod::PcaAligned]
    } else if gap_s <= 0.5 {
        &[FillMethod::Rigid, FillMethod::Edm, FillMethod::PcaAligned, FillMethod::Spline, FillMethod::Linear]
    } else {
        &[FillMethod::PcaAligned, FillMethod::Rigid, FillMethod::Edm, FillMethod::Spline, FillMethod::Linear]
    }
}

/// Fills every gap of every labeled marker of `take`, each with the candidate (or blend) that
/// filled trial gaps of the same length best.
pub fn fill(take: &Take, config: &AutoConfig) -> AutoFilled {
    let m = take.marker_count();
    let frames = take.frame_count();
    let cx = Context::new(take, config);
    let work: Vec<(usize, Gap)> = (0..m)
        .filter(|i| !take.markers()[*i].is_unlabeled())
        .filter(|i| (0..frames).any(|f| take.is_valid(f, *i)))
        .flat_map(|i| gaps_of((0..frames).map(|f| take.is_valid(f, i))).into_iter().map(move |g| (i, g)))
        .collect();
    let results: Vec<GapFill> = work.par_iter().map(|(i, g)| cx.fill_gap(*i, *g, None)).collect();
    let mut out = Filled::unchanged(take);
    let mut choices = Vec::with_capacity(results.len());
    for (choice, samples) in results {
        choices.push(write_fill(&mut out, choice, samples));
    }
    if config.second_pass {
        second_pass(&cx, &work, &mut out, &mut choices);
    }
    AutoFilled { filled: out, choices }
}

/// Writes one gap's `samples` into `out` and returns its `choice` with the gap's filled
/// samples counted. A refill's sample replaces the first fill's; where a refill has none, the
/// first fill's stays (a fill never leaves a hole the first pass had closed).
fn write_fill(out: &mut Filled, mut choice: GapChoice, samples: Vec<(usize, Vec3)>) -> GapChoice {
    let m = out.take.marker_count();
    for (f, p) in samples {
        if out.take.set_position_mm(f, choice.marker, Some(p)).is_ok() {
            out.filled[f * m + choice.marker] = true;
        }
    }
    choice.filled = choice.frames.clone().filter(|f| out.filled[f * m + choice.marker]).count();
    choice
}

/// The second pass ([`AutoConfig::second_pass`]): every gap of `work` of at least
/// [`AutoConfig::second_pass_min_s`] during which another labeled marker is missing too, and
/// was filled by the first pass, is filled again (unless its rigid cluster carried it), on
/// the take as the first pass left it with the gap's own marker's first fills taken out (each
/// marker sees the others' first fills, never its own; so no refill depends on another, and
/// the result does not depend on the order).
///
/// Why: the first pass fills each gap with the markers missing at the same time hidden in its
/// trials and absent from its candidates' sub-takes, so a gap beside another (an arm's
/// markers occluded together, a long gap crossing a neighbour's short one) is filled from a
/// poorer neighbourhood than the body offers once the neighbour has its own fill. Over long
/// gaps that loss outweighs the neighbour fill's error; over short ones it does not
/// ([`AutoConfig::second_pass_min_s`]).
fn second_pass(cx: &Context, work: &[(usize, Gap)], out: &mut Filled, choices: &mut [GapChoice]) {
    let take = cx.take;
    let m = take.marker_count();
    let least = (cx.config.second_pass_min_s * take.frame_rate_hz()).round().max(1.0) as usize;
    let labeled: Vec<usize> = (0..m).filter(|j| !take.markers()[*j].is_unlabeled()).collect();
    // Another marker missing there that the first pass filled (one never captured, or edge
    // frames left open, change nothing).
    let beside = |i: usize, g: &Gap| {
        (g.start..g.end()).any(|f| labeled.iter().any(|j| *j != i && !take.is_valid(f, *j) && out.filled[f * m + *j]))
    };
    // A gap its rigid cluster carried (as the first pass found it, on the input) is filled
    // exactly up to the markers' noise already.
    let carried = |i: usize, g: Gap| {
        let edge = Edge::of(g, take.frame_count());
        cx.rides_a_rigid_cluster(i, g, edge) || cx.cluster_in_turn(i, g, edge).is_some()
    };
    let selected: Vec<usize> = (0..work.len())
        .filter(|k| {
            let (i, g) = work[*k];
            g.len >= least && beside(i, &g) && !carried(i, g)
        })
        .collect();
    if selected.is_empty() {
        return;
    }
    // Without trials of its own a refill keeps the first pass's choice.
    let keep_choice = !cx.config.second_pass_trials;
    let mut second = out.take.clone();
    let mut redone: Vec<(usize, GapFill)> = Vec::with_capacity(selected.len());
    let mut k = 0;
    while k < selected.len() {
        let i = work[selected[k]].0;
        let mine: Vec<usize> = selected[k..].iter().copied().take_while(|x| work[*x].0 == i).collect();
        k += mine.len();
        // Marker `i` as the input has it: its first fills out, everyone else's in.
        let own: Vec<(usize, Option<Vec3>)> =
            (0..take.frame_count()).filter(|f| !take.is_valid(*f, i)).map(|f| (f, second.position_mm(f, i))).collect();
        for (f, _) in &own {
            let _ = second.set_position_mm(*f, i, None);
        }
        let refill = Context { take: &second, ..cx.clone() };
        let filled: Vec<GapFill> = mine
            .par_iter()
            .map(|x| refill.fill_gap(work[*x].0, work[*x].1, keep_choice.then(|| &choices[*x])))
            .collect();
        redone.extend(mine.iter().copied().zip(filled));
        for (f, p) in own {
            let _ = second.set_position_mm(f, i, p);
        }
    }
    for (x, (mut choice, mut samples)) in redone {
        // Only what the first pass filled is filled again (a refill at the take's edges must
        // not reach frames EDM refused there); a refill with nothing keeps the first fill and
        // its record.
        samples.retain(|(f, _)| out.filled[f * m + choice.marker]);
        if samples.is_empty() {
            continue;
        }
        choice.second_pass = true;
        choices[x] = write_fill(out, choice, samples);
    }
}

/// One gap's fill: its choice and its samples `(frame, position)`.
type GapFill = (GapChoice, Vec<(usize, Vec3)>);

/// Which border a gap lacks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Edge {
    Inside,
    Start,
    End,
}

impl Edge {
    /// The border `gap` lacks in a take of `frames` frames.
    fn of(gap: Gap, frames: usize) -> Edge {
        match (gap.start == 0, gap.end() == frames) {
            (true, true) => Edge::Inside, // never visible: excluded before
            (true, false) => Edge::Start,
            (false, true) => Edge::End,
            (false, false) => Edge::Inside,
        }
    }
}

/// What every gap's fill shares.
#[derive(Clone)]
struct Context<'a> {
    take: &'a Take,
    /// The take as given, where [`Context::take`] is the second pass's (others' first fills
    /// in place): what is *captured* is read here (a neighbour's fill is no truth to try on,
    /// nor to judge a fill's plausibility by).
    input: &'a Take,
    config: &'a AutoConfig,
    /// Neighbour ranking of every marker over the whole take, with distance variances.
    ranked: Vec<Vec<(usize, f64)>>,
    /// The same variances by pair: `variance[i * M + j]`, mm^2 (infinite: seen together too
    /// rarely).
    variance: Vec<f64>,
    /// Markers nearest first (empty when PCA sees every marker).
    nearest: Vec<Vec<usize>>,
    /// Context frames each side of a gap (before the gap's own length is taken into account).
    context: usize,
    /// The same for the PCA candidate.
    pca_context: usize,
    /// Farthest trial offset in frames.
    search: usize,
    /// Per marker, the distances to its [`PLAUSIBILITY_NEIGHBOURS`] best neighbours a fill
    /// must keep ([`plausible_distances`]; empty for markers without gaps).
    plausible: Vec<Vec<PlausibleDistance>>,
}

/// The range a filled marker's distance to one neighbour must stay in.
#[derive(Debug, Clone, Copy, PartialEq)]
struct PlausibleDistance {
    neighbour: usize,
    least_mm: f64,
    most_mm: f64,
}

impl<'a> Context<'a> {
    fn new(take: &'a Take, config: &'a AutoConfig) -> Context<'a> {
        let m = take.marker_count();
        let ranked = neighbours::rank_scored(take, config.selection);
        let plausible: Vec<Vec<PlausibleDistance>> = (0..m)
            .into_par_iter()
            .map(|i| {
                let gapped = (0..take.frame_count()).any(|f| !take.is_valid(f, i));
                if gapped { plausible_distances(take, i, &ranked[i]) } else { Vec::new() }
            })
            .collect();
        let mut variance = vec![f64::INFINITY; m * m];
        for (i, list) in ranked.iter().enumerate() {
            for &(j, v) in list {
                variance[i * m + j] = v;
            }
        }
        Context {
            take,
            input: take,
            config,
            variance,
            ranked,
            nearest: if config.pca_markers < m { neighbours::rank(take, Selection::MeanDistance) } else { Vec::new() },
            context: ((config.context_s * take.frame_rate_hz()).round() as usize).max(1),
            pca_context: ((config.pca_context_s * take.frame_rate_hz()).round() as usize).max(1),
            search: (config.search_s * take.frame_rate_hz()).round() as usize,
            plausible,
        }
    }
}

/// One trial gap: `target` hidden over `range` together with the `hidden` samples, filled on
/// the sub-takes of `target` and its `local` neighbours.
struct Trial<'a> {
    target: usize,
    local: &'a [usize],
    range: Range<usize>,
    hidden: &'a dyn Fn(usize, usize) -> bool,
}

/// The PCA candidates' fills of a gap's trial windows, from one sub-take
/// ([`Context::shared_pca`]).
struct SharedPca {
    /// `frames[k]` is the take's frame at the sub-take's frame `k`.
    frames: Vec<usize>,
    /// Each PCA candidate's fill of the sub-take (its marker 0).
    fills: Vec<(FillMethod, Filled)>,
}

impl SharedPca {
    /// `method`'s fill of the take's frames `range` (a window, whose frames are consecutive in
    /// the sub-take); None where it has none.
    fn fill(&self, method: FillMethod, range: Range<usize>) -> Option<Vec<Option<Vec3>>> {
        let (_, filled) = self.fills.iter().find(|(m, _)| *m == method)?;
        let first = self.frames.binary_search(&range.start).ok()?;
        // The range whole, or not at all.
        let last = (first + range.len()).checked_sub(1)?;
        if self.frames.get(last) != Some(&(range.end - 1)) {
            return None;
        }
        Some((first..first + range.len()).map(|k| filled.computed(k, 0)).collect())
    }
}

/// A sub-take and the take's frames it holds.
struct Window {
    take: Take,
    /// `frames[k]` is the take's frame at the sub-take's frame `k`.
    frames: Vec<usize>,
    /// `markers[k]` is the take's marker at the sub-take's marker `k`.
    markers: Vec<usize>,
}

/// The sub-takes one fill of a frame range runs on: for the local candidates and for PCA.
struct Windows {
    local: Option<Window>,
    wide: Option<Window>,
    /// EDM's fill of `local`, shared by the EDM candidate and the distance fill it starts.
    edm: std::cell::OnceCell<Filled>,
    /// The neighbour ranking in `local` ([`Context::window_ranking`]), shared by EDM and the
    /// rigid fills.
    ranked: std::cell::OnceCell<Vec<Vec<(usize, f64)>>>,
    /// Which border the filled range lacks.
    edge: Edge,
    /// The frames filled, in the take.
    range: Range<usize>,
}

impl Context<'_> {
    /// Fills one gap of `marker`: the choice and the samples `(frame, position)`. With
    /// `given` (a first fill's choice) no trial is run: its blend and weights fill, and its
    /// scores rank the spare candidates (the rules that need no trial, a rigid cluster's,
    /// still apply).
    fn fill_gap(&self, marker: usize, gap: Gap, given: Option<&GapChoice>) -> GapFill {
        let frames = self.take.frame_count();
        let edge = Edge::of(gap, frames);
        // The sub-takes' markers are chosen by who is captured during the real gap, for the
        // real gap and for its trials alike (the trials hide what is missing there).
        let captured = |f: usize, j: usize| self.take.is_valid(f, j);
        let local = self.local_markers(marker, gap.start..gap.end(), &captured);
        let wide = self.pca_markers(marker);
        let interpolates = gap.len as f64 <= self.config.interpolate_s * self.take.frame_rate_hz();
        let rigid_spline = gap.len as f64 <= self.config.rigid_spline_s * self.take.frame_rate_hz();
        // Rounded: 0.1 s at 120 Hz is 12 frames, not 12.000000000000002.
        let from_min = gap.len >= (self.config.distance_min_s * self.take.frame_rate_hz()).round() as usize;
        let distance = self.config.distance && from_min;
        let pose_match = self.config.pose_match && from_min;
        let paper_pca = self.config.paper_pca && from_min;
        let candidates: Vec<FillMethod> = if edge == Edge::Inside && interpolates {
            CANDIDATES
                .iter()
                .copied()
                .filter(|c| rigid_spline || *c != FillMethod::RigidSpline)
                .filter(|c| distance || *c != FillMethod::Distance)
                .filter(|c| pose_match || *c != FillMethod::PoseMatch)
                .filter(|c| paper_pca || *c != FillMethod::Pca)
                .collect()
        } else {
            CANDIDATES[..3].to_vec()
        };
        // A refill that keeps a first fill's choice runs no trial.
        let elsewhere = if given.is_none() { self.trial_windows(marker, gap, edge) } else { Vec::new() };
        // A shorter window flatters the interpolations, whose error grows fastest with the
        // gap's length: scored on one, they are left out.
        let shorter = elsewhere.iter().any(|(_, tried)| *tried != gap);
        let candidates: Vec<FillMethod> = if shorter {
            candidates.into_iter().filter(|c| !matches!(c, FillMethod::Spline | FillMethod::Linear)).collect()
        } else {
            candidates
        };
        let candidates = candidates.as_slice();
        // Error vectors per candidate over the trials' hidden samples.
        let mut errors: Vec<Vec<Vec3>> = vec![Vec::new(); candidates.len()];
        let mut bounds: Vec<usize> = vec![0];
        // One PCA model fills the windows of the gap's own length; shorter ones fit their own.
        let starts: Vec<usize> = elsewhere.iter().filter(|(_, tried)| *tried == gap).map(|(s, _)| *s).collect();
        let shared =
            if given.is_none() { self.shared_pca(candidates, marker, gap, edge, &starts, &wide) } else { None };
        let mut score = |target: usize, local: &[usize], range: Range<usize>, hidden: &dyn Fn(usize, usize) -> bool| {
            // The neighbour trials count for less ([`AutoConfig::neighbour_weight`]).
            let w = if target == marker { 1.0 } else { self.config.neighbour_weight };
            // A window elsewhere in time has the shared PCA fills; a neighbour trial, whose
            // target is another marker, does not.
            let shared = if target == marker { shared.as_ref() } else { None };
            let new = self.trial_errors(candidates, edge, &Trial { target, local, range, hidden }, shared);
            for (all, new) in errors.iter_mut().zip(new) {
                all.extend(new.into_iter().map(|e| e * w));
            }
            bounds.push(errors[0].len());
        };
        for &(start, tried) in elsewhere.iter().filter(|_| given.is_none()) {
            let hidden = |f: usize, j: usize| self.trial_hides(marker, start, tried, f, j);
            score(marker, &local, start..start + tried.len, &hidden);
        }
        // Trials at the gap's own frames, on neighbours: the motion of the real gap itself
        // (a pose the rest of the take never repeats defeats a method that learned from the
        // rest, and no trial elsewhere in time shows it).
        let neighbours = if given.is_none() { self.neighbour_trials(marker, gap, edge) } else { Vec::new() };
        for &j in &neighbours {
            let hidden =
                |f: usize, k: usize| (gap.start..gap.end()).contains(&f) && (k == j || !self.take.is_valid(f, k));
            let local = self.local_markers(j, gap.start..gap.end(), &captured);
            score(j, &local, gap.start..gap.end(), &hidden);
        }
        let mut scores: Vec<(FillMethod, f64)> = candidates
            .iter()
            .zip(&errors)
            .filter(|(_, e)| !e.is_empty())
            .map(|(c, e)| (*c, trial_score(e, &bounds, self.config.score)))
            .collect();
        if let Some(g) = given {
            scores = g.trial_rmse_mm.clone();
        }
        scores.sort_by(|a, b| a.1.total_cmp(&b.1));
        let trials = match given {
            Some(g) => g.trials,
            None if scores.is_empty() => 0,
            None => elsewhere.len() + neighbours.len(),
        };
        let ranking: Vec<FillMethod> = if scores.is_empty() {
            default_ranking(gap.len as f64 / self.take.frame_rate_hz(), edge != Edge::Inside).to_vec()
        } else {
            scores.iter().map(|(c, _)| *c).collect()
        };
        // A cluster whose partners are hidden in turn (a box of eight markers, one or two
        // missing at any time) carries the marker with whichever are captured, frame by
        // frame.
        // (Not for a refill that keeps a first fill's choice: that choice was made with the
        // cluster rule already, on what was captured.)
        let rides = given.is_none() && self.rides_a_rigid_cluster(marker, gap, edge);
        let in_turn = if rides || given.is_some() { None } else { self.cluster_in_turn(marker, gap, edge) };
        let cluster = rides || in_turn.is_some();
        // A refill that keeps a first fill's choice blends as it did.
        let kept = given.filter(|g| !cluster && !g.weights.is_empty());
        let chosen: Vec<FillMethod> = if cluster {
            vec![FillMethod::Rigid]
        } else if let Some(g) = kept {
            g.weights.iter().map(|(c, _)| *c).collect()
        } else {
            ranking.iter().copied().take(self.config.blend.max(1)).collect()
        };
        let weights: Vec<f64> = if let Some(g) = kept {
            g.weights.iter().map(|(_, w)| *w).collect()
        } else if scores.is_empty() || cluster {
            // The default ranking has no errors, and a rigid cluster's one fill needs none.
            vec![1.0; chosen.len()]
        } else {
            let rmse: Vec<f64> =
                chosen.iter().map(|c| scores.iter().find(|(s, _)| s == c).map_or(0.0, |s| s.1)).collect();
            match self.config.weighting {
                Weighting::InverseSquare => rmse.iter().map(|e| 1.0 / e.max(RMSE_FLOOR_MM).powi(2)).collect(),
                Weighting::LeastSquares => {
                    let errs: Vec<&[Vec3]> = chosen
                        .iter()
                        .map(|c| errors[candidates.iter().position(|x| x == c).unwrap_or(0)].as_slice())
                        .collect();
                    combination_weights(&errs)
                }
            }
        };
        let reference = reference_of(edge);
        let weight = |c: FillMethod| -> f64 { chosen.iter().position(|x| *x == c).map_or(0.0, |k| weights[k]) };
        let range = gap.start..gap.end();
        let none = |_: usize, _: usize| false;
        let need_wide = candidates.iter().any(|c| learns_from_wide(*c));
        let windows = self.windows(range.clone(), edge, &local, &wide, &none, need_wide);
        let run = |c: FillMethod| self.candidate(c, &windows);
        let fills: Vec<Vec<Option<Vec3>>> = match &in_turn {
            Some(partners) => vec![self.cluster_fill(marker, gap, partners)],
            None => chosen.iter().map(|c| run(*c)).collect(),
        };
        // The fallback where no chosen candidate filled a frame, and at edges the support.
        let fallback: Option<Vec<Option<Vec3>>> = match chosen.iter().position(|c| *c == reference) {
            Some(k) => Some(fills[k].clone()),
            None => Some(run(reference)),
        };
        // Candidates further down the ranking, filled only where every chosen one is
        // implausible at a frame.
        let spare: Vec<(FillMethod, std::cell::OnceCell<Vec<Option<Vec3>>>)> =
            ranking.iter().filter(|c| !chosen.contains(c)).map(|c| (*c, std::cell::OnceCell::new())).collect();
        let mut samples = Vec::with_capacity(gap.len);
        let mut rejected = 0;
        for (k, f) in range.clone().enumerate() {
            let support = fallback.as_ref().and_then(|fb| fb[k]);
            if edge != Edge::Inside && support.is_none() {
                continue;
            }
            // The blend of the chosen candidates that keep the marker plausible; where none
            // does, the best-ranked other candidate that does; where none at all, the blend
            // unguarded (a guard must not make a fill worse than every candidate's). Each
            // chosen candidate's sample here, with whether it is plausible (checked once):
            let here: Vec<(f64, Vec3, bool)> = chosen
                .iter()
                .zip(&fills)
                .filter_map(|(c, fill)| fill[k].map(|p| (weight(*c), p, self.is_plausible(marker, f, &p))))
                .collect();
            let blend = |guarded: bool| -> Option<Vec3> {
                let kept = here.iter().filter(|(_, _, plausible)| *plausible || !guarded);
                let (sum, total) = kept.fold((Vec3::zeros(), 0.0), |(sum, total), (w, p, _)| (sum + p * *w, total + w));
                (total > 0.0).then(|| sum / total)
            };
            if here.iter().any(|(_, _, plausible)| !plausible) {
                rejected += 1;
            }
            let (guarded, unguarded) = (blend(true), blend(false));
            let p = match (guarded, unguarded) {
                (Some(p), _) => Some(p),
                (None, Some(unguarded)) => spare
                    .iter()
                    .find_map(|(c, fill)| fill.get_or_init(|| run(*c))[k].filter(|p| self.is_plausible(marker, f, p)))
                    .or(Some(unguarded)),
                (None, None) => support,
            };
            if let Some(p) = p.filter(|p| p.iter().all(|v| v.is_finite())) {
                samples.push((f, p));
            }
        }
        let total: f64 = weights.iter().sum();
        let choice = GapChoice {
            marker,
            frames: range,
            weights: chosen.iter().zip(&weights).filter(|(_, w)| **w > 0.0).map(|(c, w)| (*c, w / total)).collect(),
            trials,
            trial_rmse_mm: scores,
            filled: samples.len(),
            implausible: rejected,
            second_pass: false,
        };
        (choice, samples)
    }

    /// One `trial` filled on the sub-takes of its target and its neighbours by every candidate
    /// (the PCA candidates' fills taken from `shared` where given); each candidate's error
    /// vectors over the hidden samples of the target that the reference ([`reference_of`])
    /// fills. A sample a candidate leaves missing counts with the reference's error there, the
    /// fill it would fall back to.
    fn trial_errors(
        &self,
        candidates: &[FillMethod],
        edge: Edge,
        trial: &Trial,
        shared: Option<&SharedPca>,
    ) -> Vec<Vec<Vec3>> {
        let (target, range) = (trial.target, trial.range.clone());
        // The shared fills first: a candidate left without one (none shared, or none for this
        // window) is filled on the trial's own sub-takes, the wide one built only if needed.
        let shared: Vec<Option<Vec<Option<Vec3>>>> =
            candidates.iter().map(|c| shared.and_then(|s| s.fill(*c, range.clone()))).collect();
        let need_wide = candidates.iter().zip(&shared).any(|(c, fill)| learns_from_wide(*c) && fill.is_none());
        let windows =
            self.windows(range.clone(), edge, trial.local, &self.pca_markers(target), trial.hidden, need_wide);
        let fills: Vec<Vec<Option<Vec3>>> = candidates
            .iter()
            .zip(shared)
            .map(|(c, fill)| fill.unwrap_or_else(|| self.candidate(*c, &windows)))
            .collect();
        let reference = reference_of(edge);
        let reference = match candidates.iter().position(|c| *c == reference) {
            Some(r) => fills[r].clone(),
            None => self.candidate(reference, &windows),
        };
        let mut errors = vec![Vec::new(); candidates.len()];
        for (k, f) in range.enumerate() {
            let Some(truth) = self.take.position_mm(f, target) else { continue };
            let Some(reference) = reference[k] else { continue };
            for (c, fill) in fills.iter().enumerate() {
                errors[c].push(fill[k].unwrap_or(reference) - truth);
            }
        }
        errors
    }

    /// `marker` and the neighbours of its sub-takes, marker first: its best neighbours (finite
    /// variance only) that are `captured(frame, neighbour)` somewhere in `frames`, at least
    /// [`AutoConfig::markers`] of them, and further down the ranking (up to twice as many)
    /// while a frame of `frames` has fewer than EDM's `K` of them captured; where fewer are
    /// captured at all, the best of the others make up the number.
    ///
    /// Why: the best-ranked neighbours can be missing for the whole gap (a pair seen together
    /// only while the subject lay still ranks as rigid), and a sub-take of neighbours that are
    /// all missing leaves every segment-carrying candidate with nothing to carry the marker:
    /// the gap fell back to linear interpolation. The whole-take EDM never had this problem,
    /// since it picks among every captured marker per frame.
    fn local_markers(
        &self,
        marker: usize,
        frames: Range<usize>,
        captured: &dyn Fn(usize, usize) -> bool,
    ) -> Vec<usize> {
        let need = self.config.edm_neighbours.max(edm::MIN_NEIGHBOURS);
        let most = 2 * self.config.markers;
        let finite = || self.ranked[marker].iter().filter(|(_, v)| v.is_finite()).map(|(j, _)| *j);
        let mut list = vec![marker];
        let mut cover = vec![0usize; frames.len()];
        for j in finite() {
            let chosen = list.len() - 1;
            let short = cover.iter().any(|c| *c < need);
            if chosen >= most || (chosen >= self.config.markers && !short) {
                break;
            }
            let seen: Vec<bool> = frames.clone().map(|f| captured(f, j)).collect();
            let helps = if chosen < self.config.markers {
                seen.iter().any(|s| *s)
            } else {
                seen.iter().zip(&cover).any(|(s, c)| *s && *c < need)
            };
            if helps {
                list.push(j);
                for (c, s) in cover.iter_mut().zip(&seen) {
                    *c += usize::from(*s);
                }
            }
        }
        // Too few captured in the gap: the best of the rest, as their borders may still help.
        for j in finite() {
            if list.len() > self.config.markers {
                break;
            }
            if !list.contains(&j) {
                list.push(j);
            }
        }
        list
    }

    /// Whether `p` as `marker`'s position at frame `f` keeps its distances to its best
    /// neighbours captured there within what the take shows ([`plausible_distances`]), for
    /// at least half of them: one neighbour can be wrong itself (a glitch of a few frames in
    /// a captured marker), and must not veto a fill that every other neighbour agrees with.
    fn is_plausible(&self, marker: usize, f: usize, p: &Vec3) -> bool {
        let (mut seen, mut outside) = (0, 0);
        for d in &self.plausible[marker] {
            if let Some(q) = self.input.position_mm(f, d.neighbour) {
                seen += 1;
                outside += usize::from(!(d.least_mm..=d.most_mm).contains(&(p - q).norm()));
            }
        }
        2 * outside <= seen
    }

    /// `marker` and the markers PCA sees, marker first.
    fn pca_markers(&self, marker: usize) -> Vec<usize> {
        let mut list = vec![marker];
        if self.nearest.is_empty() {
            list.extend((0..self.take.marker_count()).filter(|j| *j != marker));
        } else {
            list.extend(self.nearest[marker].iter().copied().take(self.config.pca_markers.saturating_sub(1)));
        }
        list
    }

    /// Neighbours of `marker` (best first, at most [`AutoConfig::neighbour_trials`]) captured
    /// throughout `gap` and its borders: they are hidden at the gap's own frames as trials.
    fn neighbour_trials(&self, marker: usize, gap: Gap, edge: Edge) -> Vec<usize> {
        self.ranked[marker]
            .iter()
            .filter(|(_, v)| v.is_finite())
            .map(|(j, _)| *j)
            .filter(|j| !self.take.markers()[*j].is_unlabeled())
            .filter(|j| self.captured_around(*j, gap, edge))
            .take(self.config.neighbour_trials)
            .collect()
    }

    /// Whether marker `j` is captured throughout `gap` and its borders (one border at the
    /// take's edges).
    fn captured_around(&self, j: usize, gap: Gap, edge: Edge) -> bool {
        let frames = self.take.frame_count();
        let span = captured_span(edge, gap.start, gap.len);
        (span.start.min(frames)..span.end.min(frames)).all(|f| self.input.is_valid(f, j))
    }

    /// Whether `marker` and its three steadiest neighbours captured throughout `gap` and its
    /// borders, and with `marker` in at least as many frames as the gap is long, form a rigid
    /// cluster ([`AutoConfig::rigid_cluster_mm`], or looser but set apart from the rest of
    /// the body, [`AutoConfig::rigid_cluster_apart`], the next steadiest neighbour of all
    /// being that many times less steady).
    ///
    /// The last because a cluster's steadiness is only shown over the frames where it was
    /// seen: a knee marker seen in 38 frames of a 238-frame walk, around a 2 s gap, kept its
    /// distances to the ankle and shank markers within 1 mm there, and it rides on no plate
    /// (their distances vary by 3-4 mm over the whole walk, and the rigid fill put it 98 mm
    /// off). A plate must show itself rigid over as much motion as it is to carry the marker
    /// through.
    fn rides_a_rigid_cluster(&self, marker: usize, gap: Gap, edge: Edge) -> bool {
        let config = &self.config;
        if config.rigid_cluster_mm <= 0.0 {
            return false;
        }
        let mut spread_mm: Vec<(usize, f64)> =
            self.ranked[marker].iter().filter(|(_, v)| v.is_finite()).map(|&(j, v)| (j, v.sqrt())).collect();
        spread_mm.sort_by(|a, b| a.1.total_cmp(&b.1));
        // The partners that can carry the marker through: a steady partner missing in the gap
        // carries nothing, and the next steadiest that is captured takes its place (a box of
        // eight markers carries one of them through a gap in another).
        let carries = |j: usize| self.captured_around(j, gap, edge) && self.seen_together(marker, j, gap.len);
        let Some(third_at) =
            spread_mm.iter().enumerate().filter(|(_, (j, _))| carries(*j)).map(|(k, _)| k).nth(CLUSTER_PARTNERS - 1)
        else {
            return false;
        };
        let third = spread_mm[third_at].1;
        let set_apart = config.rigid_cluster_apart > 0.0
            && third <= config.rigid_cluster_loose_mm
            && spread_mm.get(third_at + 1).is_some_and(|&(_, fourth)| fourth >= config.rigid_cluster_apart * third);
        third <= config.rigid_cluster_mm || set_apart
    }

    /// The partners of `marker` on a rigid cluster by the strict limit
    /// ([`AutoConfig::rigid_cluster_mm`]), each captured with it in at least as many frames as
    /// `gap` is long, where at least three of them are captured at every frame of `gap` and
    /// its two borders but not the same three throughout (else [`Self::rides_a_rigid_cluster`]
    /// holds): a box or a plate whose markers the cameras lose in turn. Inside the take only.
    fn cluster_in_turn(&self, marker: usize, gap: Gap, edge: Edge) -> Option<Vec<usize>> {
        if edge != Edge::Inside || self.config.rigid_cluster_mm <= 0.0 {
            return None;
        }
        let limit = self.config.rigid_cluster_mm * self.config.rigid_cluster_mm;
        let partners: Vec<usize> = self.ranked[marker]
            .iter()
            .filter(|(_, v)| *v <= limit)
            .map(|(j, _)| *j)
            .filter(|&j| self.seen_together(marker, j, gap.len))
            .collect();
        let span = captured_span(edge, gap.start, gap.len);
        let frames = self.take.frame_count();
        let enough = |f: usize| partners.iter().filter(|&&j| self.input.is_valid(f, j)).count() >= CLUSTER_PARTNERS;
        (span.end <= frames && span.clone().all(enough)).then_some(partners)
    }

    /// The fill of `gap` carried from each border with the cluster `partners` captured both
    /// there and at the frame (a rigid fill whose donors change with what is captured),
    /// the two carries blended linearly across the gap as the rigid fill blends them.
    fn cluster_fill(&self, marker: usize, gap: Gap, partners: &[usize]) -> Vec<Option<Vec3>> {
        let take = self.input;
        let (before, after) = baseline::borders(gap.start, gap.end(), take.frame_count());
        let carry = |b: usize, t: usize| -> Option<Vec3> {
            let own = take.position_mm(b, marker)?;
            let both: Vec<usize> =
                partners.iter().copied().filter(|&j| take.is_valid(t, j) && take.is_valid(b, j)).collect();
            let from: Vec<Vec3> = both.iter().map(|&j| take.position_mm(b, j)).collect::<Option<_>>()?;
            let to: Vec<Vec3> = both.iter().map(|&j| take.position_mm(t, j)).collect::<Option<_>>()?;
            Some(procrustes::align(&from, &to)?.apply(&own))
        };
        (gap.start..gap.end())
            .map(|t| {
                // The later border's weight (used only where both borders carry).
                let w = match (before, after) {
                    (Some(b0), Some(b1)) => (t - b0) as f64 / (b1 - b0) as f64,
                    _ => 0.0,
                };
                edm::across(before.and_then(|b| carry(b, t)), after.and_then(|b| carry(b, t)), w)
            })
            .collect()
    }

    /// Whether markers `a` and `b` are captured together in at least `frames` frames.
    fn seen_together(&self, a: usize, b: usize, frames: usize) -> bool {
        let take = self.input;
        (0..take.frame_count()).filter(|&f| take.is_valid(f, a) && take.is_valid(f, b)).take(frames).count() >= frames
    }

    /// The trial windows elsewhere in time of `marker`'s `gap`: each window's start and the
    /// part of the gap it stands for (the frames whose missing markers it hides). The gap
    /// itself, or where the take has no window of its length (a short take, a marker seen
    /// briefly), its middle half, else its middle quarter, of at least [`MIN_SHORTER_TRIAL`]
    /// frames ([`AutoConfig::shorter_trials`], interior gaps).
    fn trial_windows(&self, marker: usize, gap: Gap, edge: Edge) -> Vec<(usize, Gap)> {
        let whole = self.trial_starts(marker, gap, gap, edge);
        if !whole.is_empty() || !self.config.shorter_trials || edge != Edge::Inside {
            return whole.into_iter().map(|s| (s, gap)).collect();
        }
        for parts in [2, 4] {
            let len = gap.len / parts;
            if len < MIN_SHORTER_TRIAL {
                break;
            }
            let middle = Gap { start: gap.start + (gap.len - len) / 2, len };
            let starts = self.trial_starts(marker, middle, gap, edge);
            if !starts.is_empty() {
                return starts.into_iter().map(|s| (s, middle)).collect();
            }
        }
        Vec::new()
    }

    /// Whether the trial window at `start`, standing for `tried` (a gap of `marker` or part of
    /// one), hides marker `j` at frame `f`: `marker` over the window, and every marker that is
    /// missing at the corresponding frame of `tried`.
    fn trial_hides(&self, marker: usize, start: usize, tried: Gap, f: usize, j: usize) -> bool {
        (start..start + tried.len).contains(&f) && (j == marker || !self.take.is_valid(f - start + tried.start, j))
    }

    /// Starts of the trial windows of `tried.len` frames for `tried`, a part of (or the whole)
    /// gap `real` of `marker`, nearest to `real` first.
    fn trial_starts(&self, marker: usize, tried: Gap, real: Gap, edge: Edge) -> Vec<usize> {
        let take = self.take;
        let frames = take.frame_count();
        let len = tried.len;
        if self.config.trials == 0 || len + 2 > frames {
            return Vec::new();
        }
        let wanted = self.config.trials_for(len, take.frame_rate_hz());
        let span = |s: usize| captured_span(edge, s, len);
        let checked: Vec<usize> = self.ranked[marker]
            .iter()
            .filter(|(_, v)| v.is_finite())
            .map(|(j, _)| *j)
            .take(CHECKED_NEIGHBOURS)
            .filter(|j| self.captured_around(*j, tried, edge))
            .collect();
        let fits = |s: usize| -> bool {
            let r = span(s);
            if s == 0 && edge == Edge::Inside || r.end > frames || s + len > frames {
                return false;
            }
            r.clone().all(|f| take.is_valid(f, marker))
                && checked.iter().all(|j| r.clone().all(|f| self.input.is_valid(f, *j)))
        };
        // Windows as near as the real gap allows (one frame apart, beyond its borders): on a
        // short take the farther ones do not exist, and the nearest motion is the likest.
        // `away` frames lie between a window and the real gap's border frame, after it or
        // before it.
        let step = len + 2;
        let mut offsets: Vec<(usize, bool)> = Vec::new();
        for k in 1..=self.search.div_ceil(step).min(4000) {
            let jitter = splitmix(self.config.seed ^ ((marker as u64) << 40) ^ ((tried.start as u64) << 8) ^ k as u64)
                % (len as u64 / 2 + 1);
            let away = (k - 1) * step + jitter as usize;
            offsets.push((away, true));
            offsets.push((away, false));
        }
        offsets.sort_by_key(|(away, after)| (*away, !*after));
        let mut starts: Vec<usize> = Vec::new();
        for (away, after) in offsets {
            if starts.len() >= wanted {
                break;
            }
            let s = if after { Some(real.end() + 2 + away) } else { real.start.checked_sub(2 + len + away) };
            let Some(s) = s else { continue };
            if fits(s) && starts.iter().all(|o| s + len + 2 <= *o || *o + len + 2 <= s) {
                starts.push(s);
            }
        }
        starts
    }

    /// The sub-takes of a fill of frames `range` (the real gap or a trial), with
    /// `hidden(frame, marker)` samples of frames in `range` removed (it is asked nowhere
    /// else: what a trial hides lies in its range).
    fn windows(
        &self,
        range: Range<usize>,
        edge: Edge,
        local: &[usize],
        wide: &[usize],
        hidden: &dyn Fn(usize, usize) -> bool,
        need_wide: bool,
    ) -> Windows {
        let frames = self.take.frame_count();
        // At an edge the sub-take ends where the take does, relative to `range`, so a trial has
        // one border as the real gap has.
        let span = |context: usize| -> Range<usize> {
            let context = context.max(range.len());
            let first = if edge == Edge::Start { range.start } else { range.start.saturating_sub(context) };
            let last = if edge == Edge::End { range.end } else { (range.end + context).min(frames) };
            first..last
        };
        let local_frames: Vec<usize> = span(self.context).collect();
        // PCA treats frames as independent samples: the gap's frames and an even sample of
        // the rest of its window are all its covariance needs.
        let around = span(self.pca_context);
        let stride = self.pca_stride(around.len() - range.len());
        let mut wide_frames: Vec<usize> = around.clone().filter(|f| !range.contains(f)).step_by(stride).collect();
        // The borders too, where they exist, for the PCA candidate to meet them.
        let borders = [range.start.checked_sub(1), Some(range.end)];
        wide_frames.retain(|f| !borders.contains(&Some(*f)));
        wide_frames.extend(borders.into_iter().flatten().filter(|f| around.contains(f)));
        wide_frames.extend(range.clone());
        wide_frames.sort_unstable();
        let hides = |f: usize, j: usize| range.contains(&f) && hidden(f, j);
        Windows {
            local: self.window(local_frames, local, &hides),
            wide: if need_wide { self.window(wide_frames, wide, &hides) } else { None },
            edm: std::cell::OnceCell::new(),
            ranked: std::cell::OnceCell::new(),
            edge,
            range,
        }
    }

    /// The stride that samples about [`AutoConfig::pca_fit_frames`] of `others` context frames.
    fn pca_stride(&self, others: usize) -> usize {
        others.div_ceil(self.config.pca_fit_frames.max(1)).max(1)
    }

    /// The PCA candidate `method`'s fill of marker 0 of `take` within frames `only`, both
    /// frames meeting the gaps' borders and corrected by the nearest poses' residuals.
    fn pca_fill(&self, method: FillMethod, take: &Take, only: Range<usize>) -> Filled {
        let paper = if method == FillMethod::PcaAligned {
            baseline::pca::PcaConfig::aligned()
        } else {
            baseline::pca::PcaConfig::default()
        };
        let fade_s = self.config.pca_border_fade_s;
        let config = baseline::pca::PcaConfig {
            border_fade_s: (fade_s > 0.0).then_some(fade_s),
            residual_neighbours: self.config.pca_residual_neighbours,
            ..paper
        };
        baseline::pca::fill_marker(take, 0, only, &config)
    }

    /// The PCA candidates' fills of the trial windows at `starts` of an interior `gap` of
    /// `marker`, on one sub-take ([`Context::shared_window`], [`AutoConfig::shared_pca_fit`]).
    /// The windows miss the same markers, so the frames of all of them fall in the same
    /// groups of predictors, and each group's model (two eigen-decompositions per PCA frame)
    /// fills every window at once; a marker missing in one window only, or in the context,
    /// adds a group. None without windows, at the take's edges (their windows end where the
    /// take does) or without a PCA candidate.
    fn shared_pca(
        &self,
        candidates: &[FillMethod],
        marker: usize,
        gap: Gap,
        edge: Edge,
        starts: &[usize],
        wide: &[usize],
    ) -> Option<SharedPca> {
        let methods: Vec<FillMethod> =
            candidates.iter().copied().filter(|c| matches!(c, FillMethod::Pca | FillMethod::PcaAligned)).collect();
        if !self.config.shared_pca_fit || edge != Edge::Inside || methods.is_empty() || starts.is_empty() {
            return None;
        }
        let window = self.shared_window(marker, gap, starts, wide)?;
        let only = 0..window.frames.len();
        let fills = methods.into_iter().map(|m| (m, self.pca_fill(m, &window.take, only.clone()))).collect();
        Some(SharedPca { frames: window.frames, fills })
    }

    /// The sub-take of the `wide` markers that holds the trial windows at `starts` of an
    /// interior `gap` of `marker`: the gap's context, sampled at the stride [`Context::windows`]
    /// uses for the gap alone, from the frames outside the gap and the windows, less those
    /// where `marker` is missing (no model learns from them, and each would be one more gap to
    /// fill); then every window and its two borders, each window hiding `marker` and whatever
    /// the gap misses at the same offset.
    fn shared_window(&self, marker: usize, gap: Gap, starts: &[usize], wide: &[usize]) -> Option<Window> {
        let take = self.take;
        let frames = take.frame_count();
        let ranges: Vec<Range<usize>> = starts.iter().map(|s| *s..*s + gap.len).collect();
        let in_ranges = |f: usize| (gap.start..gap.end()).contains(&f) || ranges.iter().any(|r| r.contains(&f));
        let context = self.pca_context.max(gap.len);
        let around = gap.start.saturating_sub(context)..(gap.end() + context).min(frames);
        let stride = self.pca_stride(around.len() - gap.len);
        let mut chosen: Vec<usize> =
            around.filter(|f| !in_ranges(*f)).step_by(stride).filter(|f| take.is_valid(*f, marker)).collect();
        for r in &ranges {
            chosen.extend(r.start.checked_sub(1));
            chosen.extend((r.end < frames).then_some(r.end));
            chosen.extend(r.clone());
        }
        chosen.sort_unstable();
        chosen.dedup();
        // Each window hides as a trial window of the gap does.
        let hidden = |f: usize, j: usize| {
            ranges.iter().find(|r| r.contains(&f)).is_some_and(|r| self.trial_hides(marker, r.start, gap, f, j))
        };
        self.window(chosen, wide, &hidden)
    }

    /// Candidate `method`'s fill of the windows' marker over their frames `range`.
    fn candidate(&self, method: FillMethod, windows: &Windows) -> Vec<Option<Vec3>> {
        let range = windows.range.clone();
        // PCA and pose matching learn from other frames: the wide window's.
        let wide = learns_from_wide(method);
        let window = if wide { &windows.wide } else { &windows.local };
        let Some(window) = window else { return vec![None; range.len()] };
        let Ok(first) = window.frames.binary_search(&range.start) else { return vec![None; range.len()] };
        let config = self.config;
        let ranked = || windows.ranked.get_or_init(|| self.window_ranking(window, windows.edge));
        // Only the range and its borders are read of the EDM fill (by EDM and the distance
        // fill alike).
        let near = first..first + range.len();
        let edm = || {
            windows
                .edm
                .get_or_init(|| edm::fill_ranked_near(&window.take, config.edm_neighbours, ranked(), near.clone()))
        };
        let filled = match method {
            FillMethod::Edm => edm().clone(),
            FillMethod::Pca | FillMethod::PcaAligned => self.pca_fill(method, &window.take, first..first + range.len()),
            FillMethod::Rigid => {
                baseline::rigid::fill_across_ranked(&window.take, ranked(), baseline::rigid::Across::Linear)
            }
            FillMethod::RigidSpline => {
                baseline::rigid::fill_across_ranked(&window.take, ranked(), baseline::rigid::Across::Spline)
            }
            FillMethod::Spline => baseline::spline::fill(&window.take),
            FillMethod::Linear => baseline::linear::fill(&window.take),
            FillMethod::Distance => {
                let distance = crate::distance::DistanceConfig {
                    edm_neighbours: config.edm_neighbours,
                    selection: config.selection,
                    ..crate::distance::DistanceConfig::default()
                };
                return crate::distance::fill_marker_from(
                    &window.take,
                    edm(),
                    0,
                    first..first + range.len(),
                    &distance,
                );
            }
            FillMethod::PoseMatch => {
                // The wide window is its library: it reaches as far as it should, and its
                // frames, sampled, are no longer evenly spaced in time.
                let pose = crate::pose_match::PoseMatchConfig {
                    selection: config.selection,
                    library_s: None,
                    ..crate::pose_match::PoseMatchConfig::default()
                };
                let ranked = neighbours::rank_scored_of(&window.take, 0, config.selection);
                crate::pose_match::fill_marker(&window.take, 0, first..first + range.len(), &ranked, &pose)
            }
            // Not a candidate: the per-gap choice does not recurse.
            FillMethod::Auto => return vec![None; range.len()],
        };
        // The range's frames are consecutive in every window.
        (first..first + range.len()).map(|k| filled.computed(k, 0)).collect()
    }

    /// The neighbour ranking of every marker of `window` (its indices) for a gap inside the
    /// take: each neighbour scored by the variance of its distance within the window plus
    /// [`AutoConfig::take_variance_share`] times its variance over the whole take, in mm^2,
    /// best first. Within a few seconds two markers on different limbs can keep their
    /// distance by chance (an arm at rest beside the thigh) and rank as one segment; the
    /// take-wide variance tells them apart, the window's what holds now. The score is what EDM
    /// then weighs its neighbours by too (steady over the take counts more); ordering by it and
    /// weighing by the window's variance alone did worse on held-out takes
    /// (docs/benchmarks.md). At the take's edges EDM also gates its carriers by the variance
    /// (at most 8 mm of spread), a gate the take's variance would tighten: there, and with
    /// another [`Selection`], the window's own ranking.
    fn window_ranking(&self, window: &Window, edge: Edge) -> Vec<Vec<(usize, f64)>> {
        let local = neighbours::rank_scored(&window.take, self.config.selection);
        let share = self.config.take_variance_share;
        if !(share.is_finite() && share > 0.0) || self.config.selection != Selection::Variance || edge != Edge::Inside {
            return local;
        }
        let m = self.take.marker_count();
        local
            .into_iter()
            .enumerate()
            .map(|(a, list)| {
                let ga = window.markers[a];
                let mut list: Vec<(usize, f64)> =
                    list.into_iter().map(|(b, v)| (b, v + share * self.variance[ga * m + window.markers[b]])).collect();
                // Never steady (infinite) last, by index, as the ranking puts them.
                list.sort_by(|x, y| {
                    x.1.is_infinite().cmp(&y.1.is_infinite()).then(if x.1.is_infinite() {
                        x.0.cmp(&y.0)
                    } else {
                        x.1.total_cmp(&y.1)
                    })
                });
                list
            })
            .collect()
    }

    /// The sub-take of `markers` (the gap's marker first) at `frames` (increasing), with
    /// `hidden(frame, marker)` samples removed.
    fn window(&self, frames: Vec<usize>, markers: &[usize], hidden: &dyn Fn(usize, usize) -> bool) -> Option<Window> {
        let take = self.take;
        let names = markers.iter().map(|j| take.markers()[*j].clone()).collect();
        let mut samples = Vec::with_capacity(frames.len() * markers.len());
        for f in &frames {
            for j in markers {
                samples.push(if hidden(*f, *j) { None } else { take.position_mm(*f, *j) });
            }
        }
        let sub = Take::from_samples(names, &samples, take.frame_rate_hz()).ok()?;
        Some(Window { take: sub, frames, markers: markers.to_vec() })
    }
}

/// The distance ranges a fill of `marker` must keep to its [`PLAUSIBILITY_NEIGHBOURS`]
/// best neighbours (`ranked`, best first): the least and most distance over the frames both
/// are captured, widened by the range itself and at least [`PLAUSIBLE_MARGIN_MM`].
fn plausible_distances(take: &Take, marker: usize, ranked: &[(usize, f64)]) -> Vec<PlausibleDistance> {
    ranked
        .iter()
        .filter(|(_, v)| v.is_finite())
        .take(PLAUSIBILITY_NEIGHBOURS)
        .filter_map(|&(j, _)| {
            let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
            for f in 0..take.frame_count() {
                if let (Some(a), Some(b)) = (take.position_mm(f, marker), take.position_mm(f, j)) {
                    let d = (a - b).norm();
                    least = least.min(d);
                    most = most.max(d);
                }
            }
            let margin = (most - least).max(PLAUSIBLE_MARGIN_MM);
            (least <= most).then_some(PlausibleDistance {
                neighbour: j,
                least_mm: least - margin,
                most_mm: most + margin,
            })
        })
        .collect()
}

/// A candidate's score from its errors `errors`, trial `k` being `errors[bounds[k]..bounds[k +
/// 1]]` (trials with no scored sample are skipped).
fn trial_score(errors: &[Vec3], bounds: &[usize], score: TrialScore) -> f64 {
    let rms = |e: &[Vec3]| (e.iter().map(|v| v.norm_squared()).sum::<f64>() / e.len() as f64).sqrt();
    // Only the per-trial scores need each trial's RMSE.
    let each = || -> Vec<f64> { bounds.windows(2).filter(|w| w[1] > w[0]).map(|w| rms(&errors[w[0]..w[1]])).collect() };
    match score {
        TrialScore::Pooled => rms(errors),
        TrialScore::MeanOfTrials => {
            let each = each();
            if each.is_empty() { rms(errors) } else { each.iter().sum::<f64>() / each.len() as f64 }
        }
        TrialScore::MedianOfTrials => {
            let mut each = each();
            each.sort_by(f64::total_cmp);
            match each.len() {
                0 => rms(errors),
                n if n % 2 == 1 => each[n / 2],
                n => 0.5 * (each[n / 2 - 1] + each[n / 2]),
            }
        }
    }
}

/// The fill a gap falls back to where no chosen candidate filled a frame, and by which a
/// trial's samples are scored: linear interpolation inside the take, EDM at its edges (where
/// it alone decides how far a fill may reach).
fn reference_of(edge: Edge) -> FillMethod {
    if edge == Edge::Inside { FillMethod::Linear } else { FillMethod::Edm }
}

/// Frames that must be captured around a window of `len` frames from `start` for it to stand
/// in for a gap: the window and its borders (one border at the take's edges, as the real gap
/// has), not clipped to the take.
fn captured_span(edge: Edge, start: usize, len: usize) -> Range<usize> {
    match edge {
        Edge::Inside => start.saturating_sub(1)..start + len + 1,
        Edge::Start => start..start + len + 1,
        Edge::End => start.saturating_sub(1)..start + len,
    }
}

/// Weights summing to 1, none negative, that minimise the squared error of the combination
/// of fills whose trial errors are `errors` (one vector per fill, same samples): the optimal
/// forecast combination of Bates & Granger (1969), `w = G^-1 1 / (1^T G^-1 1)` with `G` the
/// Gram matrix of the errors, a small ridge for fills whose errors are nearly equal, and the
/// most negative weight dropped until none is.
fn combination_weights(errors: &[&[Vec3]]) -> Vec<f64> {
    let n = errors.len();
    let mut active: Vec<usize> = (0..n).collect();
    let gram = nalgebra::DMatrix::from_fn(n, n, |a, b| {
        errors[a].iter().zip(errors[b]).map(|(x, y)| x.dot(y)).sum::<f64>() / errors[a].len().max(1) as f64
    });
    loop {
        let k = active.len();
        if k <= 1 {
            let mut w = vec![0.0; n];
            if let Some(a) = active.first() {
                w[*a] = 1.0;
            }
            return w;
        }
        let ridge =
            RIDGE * (0..k).map(|i| gram[(active[i], active[i])]).sum::<f64>() / k as f64 + RMSE_FLOOR_MM.powi(2);
        let g =
            nalgebra::DMatrix::from_fn(k, k, |a, b| gram[(active[a], active[b])] + if a == b { ridge } else { 0.0 });
        let Some(inv) = g.try_inverse() else {
            active.pop();
            continue;
        };
        let raw: Vec<f64> = (0..k).map(|a| inv.row(a).sum()).collect();
        let total: f64 = raw.iter().sum();
        if total.abs() < f64::EPSILON || !total.is_finite() {
            active.pop();
            continue;
        }
        let w: Vec<f64> = raw.iter().map(|r| r / total).collect();
        match (0..k).filter(|a| w[*a] < 0.0).min_by(|a, b| w[*a].total_cmp(&w[*b])) {
            Some(worst) => {
                active.remove(worst);
            }
            None => {
                let mut out = vec![0.0; n];
                for (a, wa) in active.iter().zip(w) {
                    out[*a] = wa;
                }
                return out;
            }
        }
    }
}

/// Ridge added to the error Gram matrix, as a fraction of its mean diagonal.
const RIDGE: f64 = 0.05;

/// SplitMix64: a well-mixed 64-bit hash of `x`, for the seeded jitter.
fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trial_scores() {
        // Two trials: one filled 1 mm off on 4 samples, one 7 mm off on 1 sample.
        let errors = [Vec3::new(1.0, 0.0, 0.0); 4].into_iter().chain([Vec3::new(0.0, 7.0, 0.0)]).collect::<Vec<_>>();
        let bounds = [0, 4, 5];
        assert!((trial_score(&errors, &bounds, TrialScore::Pooled) - (53.0f64 / 5.0).sqrt()).abs() < 1e-12);
        assert!((trial_score(&errors, &bounds, TrialScore::MeanOfTrials) - 4.0).abs() < 1e-12);
        assert!((trial_score(&errors, &bounds, TrialScore::MedianOfTrials) - 4.0).abs() < 1e-12);
        // A trial with no scored sample is skipped; the odd count's median is the middle one.
        let bounds = [0, 2, 2, 4, 5];
        assert!((trial_score(&errors, &bounds, TrialScore::MedianOfTrials) - 1.0).abs() < 1e-12);
    }

    /// The second pass fills again the gaps of at least a second during which another
    /// labeled marker is missing (and was filled), from the take with the others' first fills
    /// in place, blended as first chosen, and records it; every other gap keeps its first
    /// fill, exactly as with the pass off.
    #[test]
    fn long_gaps_beside_another_are_filled_again_with_its_first_fill_in_place() {
        // Markers that slide on the body (no rigid cluster decides), so the candidates differ.
        let wobble = |f: usize, k: usize| {
            let t = f as f64 * 0.02 + k as f64;
            [6.0 * t.sin(), 4.0 * (1.3 * t).cos(), 3.0 * (0.7 * t).sin()]
        };
        let truth = locap_testkit::rigid_cluster(1200, 6, |i| format!("M{i}"), wobble);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..450); // 1.25 s, marker 2 missing over part of it
        hide(&mut holed, 2, 380..520); // 1.17 s, beside marker 0's gap
        hide(&mut holed, 1, 330..350); // beside marker 0's gap, but short
        hide(&mut holed, 3, 700..840); // long, alone
        let config = AutoConfig { rigid_cluster_mm: 0.0, rigid_cluster_apart: 0.0, ..AutoConfig::default() };
        let on = fill(&holed, &config);
        let off = fill(&holed, &AutoConfig { second_pass: false, ..config });
        let again: Vec<(usize, Range<usize>)> =
            on.choices.iter().filter(|c| c.second_pass).map(|c| (c.marker, c.frames.clone())).collect();
        assert_eq!(again, vec![(0, 300..450), (2, 380..520)]);
        assert!(off.choices.iter().all(|c| !c.second_pass));
        assert_eq!(on.filled.filled_count(), off.filled.filled_count());
        for (a, b) in on.choices.iter().zip(&off.choices) {
            assert_eq!((a.marker, &a.frames, a.filled), (b.marker, &b.frames, a.frames.len()));
            let moved = a
                .frames
                .clone()
                .any(|f| on.filled.take.position_mm(f, a.marker) != off.filled.take.position_mm(f, a.marker));
            if a.second_pass {
                // The first choice kept, its trials not run again...
                assert_eq!((&a.weights, a.trials, &a.trial_rmse_mm), (&b.weights, b.trials, &b.trial_rmse_mm));
                assert!(a.weights.len() > 1, "{}", a.method());
                // ...and the fill carried with the other marker's first fill in place, which
                // the first pass did not have.
                assert!(moved, "marker {}", a.marker);
            } else {
                assert_eq!(a, b);
                assert!(!moved);
            }
        }
        // With its trials run again, a refill tries the marker with the other's first fill
        // in place: other trial errors, and the same gaps refilled.
        let anew = fill(&holed, &AutoConfig { second_pass_trials: true, ..config });
        for (a, b) in anew.choices.iter().zip(&off.choices) {
            assert_eq!(a.second_pass, (a.marker == 0 || a.marker == 2));
            if a.second_pass {
                assert_ne!(a.trial_rmse_mm, b.trial_rmse_mm, "marker {}", a.marker);
            }
        }
        // A labeled marker that is never captured gets no first fill, and leaves the others
        // as they were: nothing beside marker 3's gap was filled.
        let mut lost = truth.clone();
        hide(&mut lost, 3, 700..840);
        hide(&mut lost, 5, 0..1200);
        let alone = fill(&lost, &config);
        assert_eq!(alone.choices.len(), 1);
        assert!(!alone.choices[0].second_pass);
        // A marker its rigid cluster carries is not filled again: that fill is exact already.
        let plate = cluster(1200, |i| format!("M{i}"));
        let mut holed = plate.clone();
        hide(&mut holed, 0, 300..450);
        hide(&mut holed, 1, 330..350);
        let out = fill(&holed, &AutoConfig::default());
        assert_eq!(out.choices[0].method(), "rigid");
        assert!(out.choices.iter().all(|c| !c.second_pass));
    }

    /// Marker 0 rides a rigid cluster with markers 1-5 that moves and turns; names from `name`.
    fn cluster(frames: usize, name: impl Fn(usize) -> String) -> Take {
        locap_testkit::rigid_cluster(frames, 6, name, |_, _| [0.0; 3])
    }

    /// Within a window a marker on another limb can keep its distance by chance; over the take
    /// it does not, and the take's variance ranks it below the marker's true segment partner.
    #[test]
    fn a_window_ranks_neighbours_by_the_takes_variance_too() {
        let frames = 600;
        let names: Vec<locap_core::MarkerName> =
            ["A", "B", "C"].iter().map(|n| locap_core::MarkerName::parse(n)).collect();
        let mut samples = Vec::new();
        for f in 0..frames {
            let t = f as f64 / 120.0;
            let a = Vec3::new(100.0 * t, 0.0, 1000.0);
            // B rides with A, 2 mm of skin wobble; C swings away but for frames 0..120, where
            // it stays put relative to A.
            let b = a + Vec3::new(100.0 + 2.0 * (7.0 * t).sin(), 0.0, 0.0);
            let swing = if f < 120 { 0.0 } else { 200.0 * (2.0 * t).sin() };
            let c = a + Vec3::new(0.0, 300.0 + swing, 0.0);
            samples.extend([Some(a), Some(b), Some(c)]);
        }
        let take = Take::from_samples(names, &samples, 120.0).unwrap();
        let first = |share: f64| {
            let config = AutoConfig { take_variance_share: share, ..AutoConfig::default() };
            let cx = Context::new(&take, &config);
            let window = cx.window((0..120).collect(), &[0, 1, 2], &|_, _| false).unwrap();
            cx.window_ranking(&window, Edge::Inside)[0][0].0
        };
        // Window indices: 1 is B, 2 is C.
        assert_eq!(first(0.0), 2, "the window alone ranks the still limb first");
        assert_eq!(first(AutoConfig::default().take_variance_share), 1);
    }

    fn hide(take: &mut Take, marker: usize, frames: Range<usize>) {
        for f in frames {
            take.set_position_mm(f, marker, None).unwrap();
        }
    }

    /// Distance-constrained smoothing is tried on gaps of a tenth of a second and longer only
    /// (12 frames at 120 Hz, whatever the rounding of 0.1 x 120).
    /// Short gaps get more trial windows, to cover half a second together; long gaps keep
    /// three, and no gap gets more than [`MOST_TRIALS`].
    #[test]
    fn short_gaps_get_more_trials() {
        let config = AutoConfig::default();
        assert_eq!(config.trials_for(12, 120.0), 5);
        assert_eq!(config.trials_for(60, 120.0), 3);
        assert_eq!(config.trials_for(600, 120.0), 3);
        assert_eq!(config.trials_for(1, 120.0), MOST_TRIALS);
        assert_eq!(config.trials_for(0, 120.0), MOST_TRIALS);
        assert_eq!(AutoConfig { trial_time_s: 0.0, ..config }.trials_for(1, 120.0), 3);
        assert_eq!(AutoConfig { trials: 20, ..config }.trials_for(1, 120.0), 20);
    }

    /// A fill is implausible where it leaves the distances to its best neighbours that the
    /// take shows, by the margin, for most of them; one neighbour gone wrong cannot veto it.
    #[test]
    fn a_fill_far_from_every_neighbour_is_implausible_and_one_glitch_cannot_veto() {
        let truth = cluster(300, |i| format!("M{i}"));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 100..140);
        let config = AutoConfig::default();
        let cx = Context::new(&holed, &config);
        assert_eq!(cx.plausible[0].len(), PLAUSIBILITY_NEIGHBOURS);
        assert!(cx.plausible[1].is_empty(), "a marker without gaps needs no bounds");
        let at = |f: usize| truth.position_mm(f, 0).unwrap();
        assert!(cx.is_plausible(0, 120, &at(120)));
        assert!(cx.is_plausible(0, 120, &(at(120) + Vec3::new(30.0, 0.0, 0.0))), "within the margin");
        assert!(!cx.is_plausible(0, 120, &(at(120) + Vec3::new(2000.0, 0.0, 0.0))));
        // One best neighbour a metre off for a frame: the true position stays plausible.
        let glitched = cx.plausible[0][0].neighbour;
        let mut wrong = holed.clone();
        let away = wrong.position_mm(120, glitched).unwrap() + Vec3::new(1000.0, 0.0, 0.0);
        wrong.set_position_mm(120, glitched, Some(away)).unwrap();
        let cx = Context { take: &wrong, ..Context::new(&holed, &config) };
        assert!(cx.is_plausible(0, 120, &at(120)));
    }

    /// A gap's trial windows elsewhere in time share one PCA model: every window is filled
    /// from it (each hiding the neighbour the gap misses for 20 of its frames) as closely as
    /// from a model of its own.
    #[test]
    fn a_gap_and_its_trial_windows_share_one_pca_model() {
        // Six markers of a turning cluster, each wobbling a few millimetres on its own.
        let wobble = |f: usize, k: usize| {
            let t = f as f64 * 0.05 + k as f64;
            [3.0 * t.sin(), 2.0 * (1.3 * t).cos(), 2.5 * (0.7 * t).sin()]
        };
        let truth = locap_testkit::rigid_cluster(900, 6, |i| format!("M{i}"), wobble);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 400..460);
        hide(&mut holed, 1, 420..440);
        let config = AutoConfig::default();
        let cx = Context::new(&holed, &config);
        let gap = Gap { start: 400, len: 60 };
        let starts = cx.trial_starts(0, gap, gap, Edge::Inside);
        assert!(starts.len() >= config.trials, "{starts:?}");
        let wide = cx.pca_markers(0);
        let methods = [FillMethod::PcaAligned, FillMethod::Pca];
        let shared = cx.shared_pca(&methods, 0, gap, Edge::Inside, &starts, &wide).expect("an interior gap shares");
        let rmse = |fill: &[Option<Vec3>], range: Range<usize>| -> f64 {
            let squares: Vec<f64> = range
                .zip(fill)
                .map(|(f, p)| (p.expect("every frame filled") - truth.position_mm(f, 0).unwrap()).norm_squared())
                .collect();
            (squares.iter().sum::<f64>() / squares.len() as f64).sqrt()
        };
        let local = cx.local_markers(0, gap.start..gap.end(), &|f, j| holed.is_valid(f, j));
        for method in methods {
            assert!(shared.fill(method, gap.start..gap.end()).is_none(), "the gap keeps a model of its own");
            for &s in &starts {
                let range = s..s + gap.len;
                let together = rmse(&shared.fill(method, range.clone()).unwrap(), range.clone());
                // The window's own model, as without the shared fit.
                let hidden = |f: usize, j: usize| j == 0 || !holed.is_valid(f - s + gap.start, j);
                let windows = cx.windows(range.clone(), Edge::Inside, &local, &wide, &hidden, true);
                let alone = rmse(&cx.candidate(method, &windows), range.clone());
                assert!(together < alone + 0.5 && together < 5.0, "{}: {together} vs {alone} at {s}", method.name());
            }
        }
        // The sub-take: every window whole with both borders, `marker` hidden over it and the
        // neighbour exactly where the gap misses it, at the same offset; the context captured.
        let window = cx.shared_window(0, gap, &starts, &wide).unwrap();
        let at = |f: usize| window.frames.binary_search(&f).ok();
        let neighbour = window.markers.iter().position(|j| *j == 1).expect("the neighbour is in the sub-take");
        for &s in &starts {
            assert!(at(s - 1).is_some() && at(s + gap.len).is_some(), "the borders of {s}");
            for f in s - 1..=s + gap.len {
                let k = at(f).expect("a window's frames are all there");
                let inside = (s..s + gap.len).contains(&f);
                assert_eq!(window.take.is_valid(k, 0), !inside, "frame {f}");
                let missed = (s + 20..s + 40).contains(&f);
                assert_eq!(window.take.is_valid(k, neighbour), !missed, "frame {f}");
            }
        }
        let context: Vec<usize> = (0..window.frames.len())
            .filter(|k| !starts.iter().any(|s| (s - 1..=s + gap.len).contains(&window.frames[*k])))
            .collect();
        assert!(context.len() > 100 && context.iter().all(|k| window.take.is_valid(*k, 0)));
        assert!(window.frames.iter().all(|f| !(gap.start..gap.end()).contains(f)), "the gap has its own");
        // `fill` scores the PCA candidates on the shared fills, and nothing else changes.
        let scores = |config: &AutoConfig| {
            let out = fill(&holed, config);
            out.choices.into_iter().find(|c| c.marker == 0).expect("the gap is recorded").trial_rmse_mm
        };
        let (together, apart) = (scores(&config), scores(&AutoConfig { shared_pca_fit: false, ..config }));
        let score = |all: &[(FillMethod, f64)], m: FillMethod| all.iter().find(|(c, _)| *c == m).map(|(_, e)| *e);
        for m in CANDIDATES {
            let same = score(&together, m) == score(&apart, m);
            assert_eq!(same, !matches!(m, FillMethod::Pca | FillMethod::PcaAligned), "{}", m.name());
        }
        // Not at the take's edges, without windows, nor when turned off.
        assert!(cx.shared_pca(&methods, 0, gap, Edge::Start, &starts, &wide).is_none());
        assert!(cx.shared_pca(&methods, 0, gap, Edge::Inside, &[], &wide).is_none());
        let off = AutoConfig { shared_pca_fit: false, ..config };
        assert!(Context::new(&holed, &off).shared_pca(&methods, 0, gap, Edge::Inside, &starts, &wide).is_none());
    }

    #[test]
    fn distance_smoothing_and_the_papers_pca_are_tried_from_a_tenth_of_a_second() {
        let mut holed = cluster(900, |i| format!("M{i}"));
        hide(&mut holed, 0, 300..311);
        hide(&mut holed, 0, 600..612);
        let out = fill(&holed, &AutoConfig::default());
        let tried = |frames: Range<usize>, method: FillMethod| {
            let choice = out.choices.iter().find(|c| c.frames == frames).expect("the gap is recorded");
            choice.trial_rmse_mm.iter().any(|(m, _)| *m == method)
        };
        for method in [FillMethod::Distance, FillMethod::Pca] {
            assert!(!tried(300..311, method), "{}", method.name());
            assert!(tried(600..612, method), "{}", method.name());
        }
        // Pose matching only where asked for; the aligned PCA at every length.
        assert!(!tried(600..612, FillMethod::PoseMatch));
        assert!(tried(300..311, FillMethod::PcaAligned));
    }

    /// On a rigid cluster EDM and rigid are exact and win every trial; their blend is exact
    /// too, and every gap is recorded with its trials.
    #[test]
    fn rigid_motion_is_filled_exactly_and_every_gap_is_recorded() {
        let truth = cluster(900, |i| format!("M{i}"));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..360);
        hide(&mut holed, 0, 600..612);
        hide(&mut holed, 2, 450..500);
        let out = fill(&holed, &AutoConfig::default());
        assert_eq!(out.filled.filled_count(), 60 + 12 + 50);
        for (m, f) in (300..360).map(|f| (0, f)).chain((600..612).map(|f| (0, f))).chain((450..500).map(|f| (2, f))) {
            let (a, b) = (out.filled.take.position_mm(f, m).unwrap(), truth.position_mm(f, m).unwrap());
            assert!((a - b).norm() < 1e-6, "marker {m} frame {f}: {a:?} vs {b:?}");
        }
        let recorded: Vec<(usize, Range<usize>)> = out.choices.iter().map(|c| (c.marker, c.frames.clone())).collect();
        assert_eq!(recorded, vec![(0, 300..360), (0, 600..612), (2, 450..500)]);
        for c in &out.choices {
            let config = AutoConfig::default();
            let windows = config.trials_for(c.frames.len(), truth.frame_rate_hz());
            assert_eq!(c.trials, windows + config.neighbour_trials, "{:?}", c.frames);
            assert_eq!(c.filled, c.frames.len());
            let methods: Vec<FillMethod> = c.weights.iter().map(|(m, _)| *m).collect();
            assert!(methods.iter().all(|m| matches!(m, FillMethod::Edm | FillMethod::Rigid)), "{}", c.method());
            assert!((c.weights.iter().map(|(_, w)| w).sum::<f64>() - 1.0).abs() < 1e-9);
            assert!(c.best_trial_rmse_mm().unwrap() < 1e-6);
        }
        // The same through `fill_gaps` and the `Filler` trait.
        let via = crate::fill_gaps(&holed, &crate::FillConfig { method: FillMethod::Auto, ..Default::default() });
        assert_eq!(via, out.filled);
        let filler: &dyn crate::Filler = &AutoConfig::default();
        assert_eq!(filler.fill(&holed).unwrap(), out.filled);
        assert_eq!(filler.describe(), "Auto trials=3 blend=3");
        let leads: usize = out.by_method().iter().map(|(_, gaps, _)| gaps).sum();
        let samples: usize = out.by_method().iter().map(|(_, _, samples)| samples).sum();
        assert_eq!((leads, samples), (3, 122));
    }

    /// A marker riding a rigid cluster (a plate) whose other markers are captured is filled by
    /// the rigid fill alone, recorded with its trials; with the rule off, by the trials' blend.
    #[test]
    fn a_marker_plate_is_filled_by_the_rigid_fill_alone() {
        let truth = cluster(900, |i| format!("M{i}"));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..360);
        let out = fill(&holed, &AutoConfig::default());
        let [choice] = out.choices.as_slice() else { panic!("{:?}", out.choices) };
        assert_eq!(choice.weights, vec![(FillMethod::Rigid, 1.0)]);
        assert_eq!(choice.method(), "rigid");
        assert!(choice.trials > 0 && !choice.trial_rmse_mm.is_empty());
        let off = fill(&holed, &AutoConfig { rigid_cluster_mm: 0.0, ..AutoConfig::default() });
        assert_eq!(off.choices[0].weights.len(), AutoConfig::default().blend, "{}", off.choices[0].method());
    }

    /// A plate seen for fewer frames than the gap is long has not shown itself rigid over
    /// the motion it would carry the marker through: the trials decide; seen as long as the
    /// gap, the rigid fill alone.
    #[test]
    fn a_plate_seen_for_less_than_the_gap_is_left_to_the_trials() {
        let truth = cluster(300, |i| format!("M{i}"));
        let mut holed = truth.clone();
        // Captured in frames 0..40 and 260..300 (80 frames) around a 220-frame gap.
        hide(&mut holed, 0, 40..260);
        let out = fill(&holed, &AutoConfig::default());
        assert_eq!(out.choices[0].weights.len(), AutoConfig::default().blend, "{}", out.choices[0].method());
        let mut holed = truth.clone();
        hide(&mut holed, 0, 110..190);
        let out = fill(&holed, &AutoConfig::default());
        assert_eq!(out.choices[0].weights, vec![(FillMethod::Rigid, 1.0)], "{}", out.choices[0].method());
    }

    /// A box whose markers the cameras lose in turn: no three partners are captured through
    /// the gap, but at least three at every frame, and those carry the marker exactly.
    #[test]
    fn a_cluster_whose_markers_are_lost_in_turn_carries_the_marker() {
        let truth = cluster(900, |i| format!("M{i}"));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..360);
        for (partner, frames) in [(1, 305..315), (2, 320..330), (3, 335..345)] {
            hide(&mut holed, partner, frames);
        }
        let out = fill(&holed, &AutoConfig::default());
        let choice = out.choices.iter().find(|c| c.marker == 0).expect("marker 0's gap");
        assert_eq!(choice.weights, vec![(FillMethod::Rigid, 1.0)], "{}", choice.method());
        for f in 300..360 {
            let (got, want) = (out.filled.take.position_mm(f, 0).unwrap(), truth.position_mm(f, 0).unwrap());
            assert!((got - want).norm() < 1e-6, "frame {f}: {got:?} vs {want:?}");
        }
    }

    /// A cluster of four that wobbles by a few millimetres (a head cap), set apart from the
    /// other markers that move tens of millimetres against it, is filled rigidly too; with
    /// the strict limit alone it is left to the trials.
    #[test]
    fn a_cluster_set_apart_is_filled_by_the_rigid_fill_alone() {
        let wobble = |f: usize, k: usize| {
            let a = f as f64 * 0.07 + k as f64;
            match k {
                0 => [0.0; 3],
                1..=3 => [3.0 * a.sin(), 3.0 * (1.3 * a).cos(), 3.0 * (0.7 * a).sin()],
                _ => [60.0 * (0.3 * a).sin(), 40.0 * (0.2 * a).cos(), 0.0],
            }
        };
        let truth = locap_testkit::rigid_cluster(900, 6, |i| format!("M{i}"), wobble);
        let mut holed = truth.clone();
        hide(&mut holed, 0, 300..360);
        let out = fill(&holed, &AutoConfig::default());
        assert_eq!(out.choices[0].weights, vec![(FillMethod::Rigid, 1.0)], "{}", out.choices[0].method());
        let strict = fill(&holed, &AutoConfig { rigid_cluster_apart: 0.0, ..AutoConfig::default() });
        assert_eq!(strict.choices[0].weights.len(), AutoConfig::default().blend, "{}", strict.choices[0].method());
    }

    /// An edge gap is filled only where EDM's edge rules reach; unlabeled points not at all.
    #[test]
    fn edge_gaps_go_no_further_than_edm_and_unlabeled_points_stay() {
        let truth = cluster(600, |i| if i == 5 { "*5".into() } else { format!("M{i}") });
        let mut holed = truth.clone();
        hide(&mut holed, 0, 520..600);
        hide(&mut holed, 1, 0..40);
        hide(&mut holed, 5, 100..120);
        // Marker 1 drifts off the cluster at the end: the end gap of marker 0 must stop.
        for f in 560..600 {
            let p = holed.position_mm(f, 1).unwrap() + Vec3::new((f - 559) as f64 * 2.0, 0.0, 0.0);
            holed.set_position_mm(f, 1, Some(p)).unwrap();
        }
        let edm = edm::fill(&holed, 6, Selection::Variance);
        let out = fill(&holed, &AutoConfig::default());
        for f in 0..600 {
            for m in 0..2 {
                if out.filled.filled[f * 6 + m] {
                    assert!(edm.filled[f * 6 + m], "frame {f} marker {m} filled beyond EDM");
                }
            }
        }
        assert!((0..40).all(|f| out.filled.take.is_valid(f, 1)), "the start gap is carried by the cluster");
        let reached = (520..600).filter(|f| out.filled.take.is_valid(*f, 0)).count();
        assert!((30..80).contains(&reached), "end gap: {reached} of 80 frames filled");
        assert!((100..120).all(|f| !out.filled.take.is_valid(f, 5)));
        assert!(out.choices.iter().all(|c| c.marker != 5));
    }

    #[test]
    fn without_trial_windows_the_default_ranking_fills() {
        let truth = cluster(70, |i| format!("M{i}"));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 10..60);
        let config = AutoConfig { neighbour_trials: 0, ..AutoConfig::default() };
        let out = fill(&holed, &config);
        let [choice] = out.choices.as_slice() else { panic!("{:?}", out.choices) };
        assert_eq!(choice.trials, 0);
        assert!(choice.trial_rmse_mm.is_empty());
        assert!(choice.method().starts_with("default: "), "{}", choice.method());
        assert_eq!(choice.filled, 50);
    }

    /// A gap too long for any trial window elsewhere in a short take is still tried: on its
    /// neighbours at its own frames, which ride the same rigid motion, so the choice is exact.
    #[test]
    fn a_short_take_is_tried_on_the_neighbours_at_the_gaps_own_frames() {
        let truth = cluster(70, |i| format!("M{i}"));
        let mut holed = truth.clone();
        hide(&mut holed, 0, 10..60);
        // Marker 1 is missing over part of the gap: it is no trial, the others are.
        hide(&mut holed, 1, 30..35);
        let out = fill(&holed, &AutoConfig::default());
        let choice = out.choices.iter().find(|c| c.marker == 0).unwrap();
        assert_eq!(choice.trials, AutoConfig::default().neighbour_trials);
        assert!(!choice.method().starts_with("default"), "{}", choice.method());
        assert!(choice.best_trial_rmse_mm().unwrap() < 1e-6, "{:?}", choice.trial_rmse_mm);
        for f in 10..60 {
            let (a, b) = (out.filled.take.position_mm(f, 0).unwrap(), truth.position_mm(f, 0).unwrap());
            assert!((a - b).norm() < 1e-6, "frame {f}: {a:?} vs {b:?}");
        }
    }

    /// A gap whose length fits nowhere else in the take is tried on shorter windows of its
    /// own marker, as near to it as they fit, standing for the gap's middle and hiding what
    /// is missing there; the interpolations are left out of its candidates.
    #[test]
    fn a_gap_too_long_for_any_window_is_tried_on_shorter_ones() {
        let truth = cluster(130, |i| format!("M{i}"));
        let mut holed = truth.clone();
        // 60 frames hidden, 40 captured before and 30 after: no window of 60 fits, and one of
        // 30 (with its borders) fits before the gap only.
        hide(&mut holed, 0, 40..100);
        // Marker 1 is missing in the gap's middle part, 5 frames into it.
        hide(&mut holed, 1, 60..65);
        let gap = Gap { start: 40, len: 60 };
        let middle = Gap { start: 55, len: 30 };
        let config = AutoConfig::default();
        let cx = Context::new(&holed, &config);
        let windows = cx.trial_windows(0, gap, Edge::Inside);
        assert!(!windows.is_empty());
        for &(start, tried) in &windows {
            assert_eq!(tried, middle);
            // The window and its borders are captured, before the gap.
            assert!(start >= 1 && start + 30 < 40, "{start}");
            for f in 0..130 {
                assert_eq!(cx.trial_hides(0, start, tried, f, 0), (start..start + 30).contains(&f), "frame {f}");
                assert_eq!(cx.trial_hides(0, start, tried, f, 1), (start + 5..start + 10).contains(&f), "frame {f}");
                assert!(!cx.trial_hides(0, start, tried, f, 2));
            }
        }
        let out = fill(&holed, &config);
        let choice = out.choices.iter().find(|c| c.marker == 0).unwrap();
        assert_eq!(choice.trials, config.neighbour_trials + windows.len(), "{choice:?}");
        let scored: Vec<FillMethod> = choice.trial_rmse_mm.iter().map(|(c, _)| *c).collect();
        assert!(!scored.contains(&FillMethod::Spline) && !scored.contains(&FillMethod::Linear), "{scored:?}");
        assert!(scored.contains(&FillMethod::Edm), "{scored:?}");

        let off = AutoConfig { shorter_trials: false, ..AutoConfig::default() };
        assert!(Context::new(&holed, &off).trial_windows(0, gap, Edge::Inside).is_empty());
        let out = fill(&holed, &off);
        let choice = out.choices.iter().find(|c| c.marker == 0).unwrap();
        assert_eq!(choice.trials, off.neighbour_trials, "{choice:?}");
    }

    #[test]
    fn combination_weights_favour_the_smaller_independent_error() {
        let a: Vec<Vec3> = (0..200).map(|k| Vec3::new(if k % 2 == 0 { 10.0 } else { -10.0 }, 0.0, 0.0)).collect();
        let b: Vec<Vec3> = (0..200).map(|k| Vec3::new(0.0, if k % 3 == 0 { 20.0 } else { -10.0 }, 0.0)).collect();
        let w = combination_weights(&[&a, &b]);
        assert!((w[0] + w[1] - 1.0).abs() < 1e-12);
        assert!(w[0] > w[1] && w[1] > 0.0, "{w:?}");
        // A fill whose error is a larger copy of another's gets no (negative) weight.
        let c: Vec<Vec3> = a.iter().map(|e| e * 3.0).collect();
        assert_eq!(combination_weights(&[&a, &c]), vec![1.0, 0.0]);
    }
}
