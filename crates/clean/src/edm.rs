//! Locality gap fill by Euclidean distance matrices (LocalMoCap section 3.1, Eq. 1-2).
//!
//! For a marker `i` missing over frames `[s, e]`:
//! 1. pick its `K` best neighbours ([`crate::neighbours`]) among those visible at both gap
//!    borders (`s-1`, `e+1`) and at the frame being filled; one fixed set for the whole gap
//!    when enough neighbours stay visible throughout (a smooth fill), else per frame;
//! 2. at frame `t`, interpolate the squared-distance matrix of `{i} + neighbours` linearly
//!    between the borders, `D_t = ((e-t) D_s + (t-s) D_e) / (e-s)`; a gap touching the take's
//!    start or end has one border and uses its matrix unchanged;
//! 3. classical MDS (Torgerson): the top three eigenpairs of `-1/2 J D_t J` give a point set
//!    with those distances (Eq. 2);
//! 4. rigid Procrustes aligns the neighbours' embedded points onto their observed positions;
//!    the marker's embedded point, carried along, is the fill. The alignment is weighted by
//!    each neighbour's steadiness, `1 / (variance of its distance to the marker + 5^2 mm^2)`:
//!    an addition to the paper's unweighted Procrustes, measured with `locap bench fill` on
//!    real takes (figures in `docs/benchmarks.md`, "EDM"). MDS fixes a point set only up
//!    to a mirror image, so both chiralities are aligned (each with a proper rotation, the
//!    reflection check) and the one nearer the marker carried rigidly with its neighbours
//!    from the borders wins (the better fit where nothing was carried);
//! 5. the fill is evaluated at the border frames too, where the marker is visible, and the
//!    difference is blended out linearly across the gap, so the trajectory has no step at
//!    `s-1` or `e+1`.
//!
//! # Edge gaps
//! A gap at the take's start or end has one border, and the paper's interpolation between two
//! distance matrices becomes a rigid carry: the marker keeps the distances it had at the border
//! while its neighbours move on. That is only as good as the rigidity it assumes, and no second
//! border pulls it back, so edge gaps are filled under three extra rules (interior gaps are
//! filled exactly as above):
//! - neighbours whose distance to the marker varies by at most 8 mm (standard deviation over
//!   the take) carry it: a neighbour on another segment flings the marker when the joint
//!   between them turns. With fewer than 3 of those visible at the border (a whole segment
//!   occluded), any neighbour whose distance was measured may, under the next two rules: while
//!   markers on several segments keep their shape, the joints between them are still;
//! - the fill goes outward from the border and stops at the first frame where the chosen
//!   neighbours, rigidly aligned, are more than 6 mm RMS from the shape they had at the
//!   border, or fewer than 3 are left: beyond, nothing observed says where the marker is;
//! - the neighbours must stand out of a line (RMS distance from their best line at least 0.2
//!   times the marker's distance from their centroid): three markers along a forearm fix no
//!   rotation about it, and keep constant distances to a wrist marker that turns about it
//!   (CMU 85_12: LWRA carried by LWRB, LFRM and LELB drifts away).
//!
//! Frames the rules refuse stay missing, and the caller reports them (all four head markers of
//! KneeltoProne01 hidden over the last 240 frames: left missing, as the nearest neighbours left,
//! the back plate, is too narrow for a head 0.4 m away); the second pass does not
//! restart an edge fill from the sample where the first one stopped. An alternative, moving the
//! marker's distances from the border's towards their means over the take, was measured and
//! rejected: the pose at the border predicts the next frames better.
//!
//! The limits were chosen on real takes by hiding the first or last 240 frames of one marker
//! at a time where it was captured; that measurement (share of samples filled and mean / worst
//! error per take, before and after the rules) is in `docs/benchmarks.md`, "EDM edge gaps".
//! `tests/cleaning_real.rs` checks the result on the real edge occlusions of numediart
//! 03_rolling and CMU 01_01, where fills used to break segment distances.
//!
//! Markers whose neighbours are missing at the same time are first skipped; a second pass lets
//! already-filled markers serve as neighbours (captured neighbours are always preferred).
//! Fewer than 3 usable neighbours leaves the frame missing. nalgebra does the eigen
//! decomposition; the steps around it follow the paper and are written here.

use crate::Filled;
use crate::neighbours::{self, Selection};
use crate::procrustes;
use locap_core::gaps::{Gap, gaps_of};
use locap_core::{Take, Vec3};
use nalgebra::{DMatrix, SymmetricEigen};
use rayon::prelude::*;
use std::ops::Range;

/// Variance floor (mm^2) of the alignment weights (see `fill_gap`).
const STEADY_FLOOR_MM2: f64 = 25.0;

/// Fewest neighbours that fix a rigid alignment in 3D.
pub(crate) const MIN_NEIGHBOURS: usize = 3;

/// Fills every gap of `take` with the EDM method using `k` neighbours ranked by `selection`.
pub fn fill(take: &Take, k: usize, selection: Selection) -> Filled {
    fill_ranked(take, k, &neighbours::rank_scored(take, selection))
}

/// [`fill`] with every marker's neighbours ranked as given: best first, each with a variance of
/// its distance to the marker (mm^2; `f64::INFINITY`: never steady), as
/// [`neighbours::rank_scored`] gives them. The variances weigh the Procrustes alignment and, at
/// the take's edges, decide which neighbours may carry the marker. One entry per marker of
/// `take`, every neighbour index below its marker count.
pub fn fill_ranked(take: &Take, k: usize, ranked: &[Vec<(usize, f64)>]) -> Filled {
    let all = 0..take.frame_count();
    fill_passes(take, k, ranked, [all.clone(), all])
}

/// [`fill_ranked`]'s samples at `frames` and one frame either side, for every marker, at the
/// cost of the gaps near them: elsewhere gaps may stay missing. What the per-gap choice
/// ([`crate::auto`]) reads of its sub-takes' EDM fill (the gap and its borders), without
/// filling every other gap of every marker in them.
///
/// The same samples because a gap's fill reads the take only over the gap and its two
/// borders: the second pass's gaps (what the first left missing) that overlap these frames
/// read the first pass's fill only over themselves and their borders, so the first pass need
/// only fill every gap that overlaps that span.
pub(crate) fn fill_ranked_near(take: &Take, k: usize, ranked: &[Vec<(usize, f64)>], frames: Range<usize>) -> Filled {
    let count = take.frame_count();
    let near = frames.start.saturating_sub(1).min(count)..(frames.end + 1).min(count);
    let mut span = near.clone();
    for marker in 0..take.marker_count() {
        for gap in gaps_of((0..count).map(|f| take.is_valid(f, marker))) {
            if gap.start < near.end && near.start < gap.end() {
                span.start = span.start.min(gap.start.saturating_sub(1));
                span.end = span.end.max((gap.end() + 1).min(count));
            }
        }
    }
    fill_passes(take, k, ranked, [span, near])
}

/// The two passes of [`fill_ranked`], each filling only the gaps that overlap its frames.
fn fill_passes(take: &Take, k: usize, ranked: &[Vec<(usize, f64)>], frames: [Range<usize>; 2]) -> Filled {
    let mut out = Filled::unchanged(take);
    let k = k.max(MIN_NEIGHBOURS);
    let m = take.marker_count();
    for (pass, frames) in frames.iter().enumerate() {
        // Pass 0 uses captured neighbours only; pass 1 also filled ones. Within a pass every
        // marker reads only the pass's starting state, so markers are filled in parallel and
        // the result does not depend on their order.
        let source = if pass == 0 { take.clone() } else { out.take.clone() };
        let fills: Vec<(usize, Vec<(usize, Vec3)>)> = ranked
            .par_iter()
            .enumerate()
            .map(|(marker, ranked)| {
                let gaps = gaps_of((0..source.frame_count()).map(|f| source.is_valid(f, marker)));
                let near = gaps.into_iter().filter(|gap| gap.start < frames.end && frames.start < gap.end());
                (marker, near.flat_map(|gap| fill_gap(&source, take, marker, gap, ranked, k)).collect())
            })
            .collect();
        for (marker, samples) in fills {
            for (t, p) in samples {
                if out.take.set_position_mm(t, marker, Some(p)).is_ok() {
                    out.filled[t * m + marker] = true;
                }
            }
        }
    }
    out
}

/// The filled samples `(frame, position)` of one gap of `marker`, from `source` (`captured`
/// is the take as given, before any pass).
fn fill_gap(
    source: &Take,
    captured: &Take,
    marker: usize,
    gap: Gap,
    ranked: &[(usize, f64)],
    k: usize,
) -> Vec<(usize, Vec3)> {
    // Procrustes weights: a neighbour whose distance to the marker varies by `s` mm counts
    // `1 / (s^2 + 5^2)`: the steadiest neighbours carry the alignment, none dominates alone.
    let mut weight_of = vec![0.0; source.marker_count()];
    for (j, variance) in ranked {
        weight_of[*j] = 1.0 / (variance.min(1e12) + STEADY_FLOOR_MM2);
    }
    let frames = source.frame_count();
    let before = gap.start.checked_sub(1);
    let after = (gap.end() < frames).then_some(gap.end());
    if before.is_none() && after.is_none() {
        return Vec::new(); // never visible: nothing to measure distances from
    }
    // A gap at the take's start or end has one border: the fill carries the marker rigidly with
    // its neighbours, so only neighbours that kept their distance (see `edge`) may carry it, or,
    // with fewer than 3 of those at the border, any whose distance was measured at all.
    let edge = before.is_none() || after.is_none();
    if edge && !before.or(after).is_some_and(|b| captured.is_valid(b, marker)) {
        // The first pass stopped this edge fill where the data stopped supporting it; a second
        // pass would start again from that filled sample and creep on.
        return Vec::new();
    }
    let borders: Vec<usize> = before.iter().chain(after.iter()).copied().collect();
    let steady = |variance: f64| variance <= edge::STEADY_MM * edge::STEADY_MM;
    let steady_at_border =
        ranked.iter().filter(|(j, v)| steady(*v) && borders.iter().all(|b| source.is_valid(*b, *j))).count();
    let usable =
        |variance: f64| !edge || steady(variance) || (steady_at_border < MIN_NEIGHBOURS && variance.is_finite());
    let ranked: Vec<usize> = ranked.iter().filter(|(_, v)| usable(*v)).map(|(j, _)| *j).collect();
    let candidates: Vec<usize> =
        ranked.iter().copied().filter(|j| borders.iter().all(|b| source.is_valid(*b, *j))).collect();
    let fixed: Vec<usize> =
        candidates.iter().copied().filter(|j| (gap.start..gap.end()).all(|f| source.is_valid(f, *j))).take(k).collect();
    let choose = |t: usize| -> Vec<usize> {
        if fixed.len() >= MIN_NEIGHBOURS {
            fixed.clone()
        } else {
            candidates.iter().copied().filter(|j| source.is_valid(t, *j)).take(k).collect()
        }
    };
    let Some(border_matrices) = BorderMatrices::new(source, marker, before, after) else { return Vec::new() };
    // MDS cannot tell a point set from its mirror image, and with three (always coplanar)
    // neighbours the fit cannot either. The chirality is decided by the marker carried
    // rigidly with its neighbours from both borders to `t`, the two carries blended as the
    // border offsets are: the mirror image of the right answer lies far from it. The carry
    // from the nearer border alone drifts by more than the two images lie apart in mid-gap
    // where the neighbours are nearly coplanar (a foot); the blend picked fewer wrong images
    // on real gaps (`docs/benchmarks.md`, "EDM: which mirror image").
    let carry = |b: usize, own: Option<Vec3>, t: usize, chosen: &[usize]| -> Option<Vec3> {
        let from: Vec<Vec3> = chosen.iter().map(|j| source.position_mm(b, *j)).collect::<Option<_>>()?;
        let to: Vec<Vec3> = chosen.iter().map(|j| source.position_mm(t, *j)).collect::<Option<_>>()?;
        Some(procrustes::align(&from, &to)?.apply(&own?))
    };
    let hint_at = |t: usize, chosen: &[usize]| -> Option<Vec3> {
        let from_before = before.and_then(|b| carry(b, border_matrices.marker_before, t, chosen));
        let from_after = after.and_then(|a| carry(a, border_matrices.marker_after, t, chosen));
        across(from_before, from_after, border_matrices.weight(t))
    };
    // Offsets at the borders, blended out across the gap.
    let offset_at = |b: usize| -> Option<Vec3> {
        let chosen = choose(b);
        let estimate = estimate(&border_matrices, source, &chosen, &weight_of, b, hint_at(b, &chosen))?;
        Some(estimate - source.position_mm(b, marker)?)
    };
    let offset_before = before.and_then(offset_at);
    let offset_after = after.and_then(offset_at);
    let edge_border = match (before, after) {
        (Some(b), None) => border_matrices.marker_before.map(|p| (b, p)),
        (None, Some(a)) => border_matrices.marker_after.map(|p| (a, p)),
        _ => None,
    };
    let mut filled = Vec::with_capacity(gap.len);
    // An edge gap is filled outward from its border and stops where the neighbours no longer
    // hold the shape they had there: beyond, nothing observed says where the marker is.
    let order: Box<dyn Iterator<Item = usize>> = if after.is_some() && before.is_none() {
        Box::new((gap.start..gap.end()).rev())
    } else {
        Box::new(gap.start..gap.end())
    };
    for t in order {
        let chosen = choose(t);
        if chosen.len() < MIN_NEIGHBOURS {
            if edge {
                break;
            }
            continue;
        }
        if edge && !edge_border.is_some_and(|b| edge::carries(source, &chosen, b, t)) {
            break;
        }
        let Some(mut p) = estimate(&border_matrices, source, &chosen, &weight_of, t, hint_at(t, &chosen)) else {
            continue;
        };
        p -= across(offset_before, offset_after, border_matrices.weight(t)).unwrap_or_else(Vec3::zeros);
        if p.iter().all(|v| v.is_finite()) {
            filled.push((t, p));
        }
    }
    filled
}

/// Limits of the edge-gap fill (see `fill_gap` and the module doc).
mod edge {
    use crate::procrustes;
    use locap_core::{Take, Vec3};

    /// Largest standard deviation (mm) of a neighbour's distance to the marker over the take
    /// for it to carry the marker across an edge gap (unless fewer than 3 such neighbours are
    /// visible at the border).
    pub const STEADY_MM: f64 = 8.0;

    /// Largest RMS distance (mm) between the neighbours at a filled frame and their shape at the
    /// border, rigidly aligned.
    pub const SHAPE_MM: f64 = 6.0;

    /// Smallest spread of the neighbours out of a line (RMS distance from their best-fitting
    /// line), as a fraction of the marker's distance from their centroid: neighbours nearly in
    /// a line fix no rotation about it, and the marker swings with the noise.
    pub const SPREAD: f64 = 0.2;

    /// Whether `chosen` carry the marker, at `own` at `border`, to frame `t`: spread out of a
    /// line at the border, and at `t` still of the shape they had there, up to a rigid motion.
    pub fn carries(source: &Take, chosen: &[usize], (border, own): (usize, Vec3), t: usize) -> bool {
        let at = |f: usize| chosen.iter().map(|j| source.position_mm(f, *j)).collect::<Option<Vec<Vec3>>>();
        let (Some(from), Some(to)) = (at(border), at(t)) else { return false };
        let centroid = from.iter().sum::<Vec3>() / from.len().max(1) as f64;
        off_line_mm(&from) >= SPREAD * (own - centroid).norm()
            && procrustes::align(&from, &to).is_some_and(|r| procrustes::rms_error(&r, &from, &to) <= SHAPE_MM)
    }

    /// RMS distance of `points` from their best-fitting line: the square root of the sum of the
    /// two smaller eigenvalues of their covariance.
    fn off_line_mm(points: &[Vec3]) -> f64 {
        let n = points.len().max(1) as f64;
        let mean = points.iter().sum::<Vec3>() / n;
        let cov = points.iter().map(|p| (p - mean) * (p - mean).transpose()).sum::<nalgebra::Matrix3<f64>>() / n;
        let mut eig: Vec<f64> = nalgebra::SymmetricEigen::new(cov).eigenvalues.iter().copied().collect();
        eig.sort_by(f64::total_cmp);
        (eig[0].max(0.0) + eig[1].max(0.0)).sqrt()
    }
}

/// Positions at the gap borders, from which distance matrices are built for any neighbour set.
struct BorderMatrices {
    before: Option<usize>,
    after: Option<usize>,
    /// The marker's own position at each border (captured, or filled by an earlier pass).
    marker_before: Option<Vec3>,
    marker_after: Option<Vec3>,
}

impl BorderMatrices {
    fn new(source: &Take, marker: usize, before: Option<usize>, after: Option<usize>) -> Option<Self> {
        let marker_before = before.map(|b| source.position_mm(b, marker)).transpose_none()?;
        let marker_after = after.map(|b| source.position_mm(b, marker)).transpose_none()?;
        Some(BorderMatrices { before, after, marker_before, marker_after })
    }

    /// Interpolation weight of the later border at frame `t` (0 at `s-1`, 1 at `e+1`).
    fn weight(&self, t: usize) -> f64 {
        match (self.before, self.after) {
            (Some(b), Some(a)) if a > b => (t.saturating_sub(b)) as f64 / (a - b) as f64,
            (None, Some(_)) => 1.0,
            _ => 0.0,
        }
    }

    /// Squared-distance matrix of `{marker} + chosen` at frame `t`, interpolated between the
    /// borders.
    fn squared_distances(&self, source: &Take, chosen: &[usize], t: usize) -> Option<DMatrix<f64>> {
        let at = |frame: Option<usize>, own: Option<Vec3>| -> Option<DMatrix<f64>> {
            let frame = frame?;
            let mut points = vec![own?];
            for j in chosen {
                points.push(source.position_mm(frame, *j)?);
            }
            let n = points.len();
            Some(DMatrix::from_fn(n, n, |a, b| (points[a] - points[b]).norm_squared()))
        };
        let d_before = at(self.before, self.marker_before);
        let d_after = at(self.after, self.marker_after);
        across(d_before, d_after, self.weight(t))
    }
}

/// What is known at the two borders, blended across the gap with the later border's weight
/// `w`; where only one border has it, that one.
pub(crate) fn across<T>(before: Option<T>, after: Option<T>, w: f64) -> Option<T>
where
    T: std::ops::Mul<f64, Output = T> + std::ops::Add<Output = T>,
{
    match (before, after) {
        (Some(a), Some(b)) => Some(a * (1.0 - w) + b * w),
        (a, b) => a.or(b),
    }
}

/// Option<Option<T>> where the outer `None` means "no border" (fine) and an inner `None` means
/// "border sample missing" (cannot fill).
trait TransposeNone<T> {
    fn transpose_none(self) -> Option<Option<T>>;
}

impl<T> TransposeNone<T> for Option<Option<T>> {
    fn transpose_none(self) -> Option<Option<T>> {
        match self {
            None => Some(None),
            Some(Some(v)) => Some(Some(v)),
            Some(None) => None,
        }
    }
}

/// The EDM estimate of the marker (index 0 of the distance matrix) at frame `t`, from the
/// distance matrix interpolated at `t` and the neighbours' observed positions at `t`.
///
/// Both chiralities of the MDS embedding are aligned (each by a proper rotation); the one whose
/// marker lands nearer the `hint` wins, or, without a hint, the one that fits the neighbours
/// better.
fn estimate(
    borders: &BorderMatrices,
    source: &Take,
    chosen: &[usize],
    weight_of: &[f64],
    t: usize,
    hint: Option<Vec3>,
) -> Option<Vec3> {
    if chosen.len() < MIN_NEIGHBOURS {
        return None;
    }
    let d = borders.squared_distances(source, chosen, t)?;
    let embedded = classical_mds(&d)?;
    let observed: Vec<Vec3> = chosen.iter().map(|j| source.position_mm(t, *j)).collect::<Option<_>>()?;
    let weights: Vec<f64> = chosen.iter().map(|j| weight_of[*j]).collect();
    let transforms = procrustes::align_weighted_and_mirrored(&embedded[1..], &observed, &weights)?;
    let mirror = |p: &Vec3, mirrored: bool| if mirrored { Vec3::new(p.x, p.y, -p.z) } else { *p };
    let candidates = transforms.iter().zip([false, true]).map(|(transform, mirrored)| {
        let position = transform.apply(&mirror(&embedded[0], mirrored));
        let score = match hint {
            Some(h) => (position - h).norm(),
            None => {
                let squared: f64 = embedded[1..]
                    .iter()
                    .zip(&observed)
                    .map(|(p, o)| (transform.apply(&mirror(p, mirrored)) - o).norm_squared())
                    .sum();
                (squared / observed.len() as f64).sqrt()
            }
        };
        (score, position)
    });
    candidates.min_by(|a, b| a.0.total_cmp(&b.0)).map(|c| c.1)
}

/// Classical (Torgerson) MDS: points in 3D whose squared distances best match `d`.
///
/// `B = -1/2 J D J` with the centering matrix `J = I - 11^T/n`; the coordinates are the top
/// three eigenvectors scaled by the square roots of their eigenvalues (negative eigenvalues,
/// from distances no 3D point set has exactly, count as zero).
pub fn classical_mds(d: &DMatrix<f64>) -> Option<Vec<Vec3>> {
    let n = d.nrows();
    if n == 0 || d.ncols() != n || d.iter().any(|x| !x.is_finite()) {
        return None;
    }
    // Double centring, `B = -1/2 J D J` written out: subtract row and column means, add the
    // grand mean (no dense products with `J`).
    let means: Vec<f64> = (0..n).map(|r| d.row(r).sum() / n as f64).collect();
    let grand = means.iter().sum::<f64>() / n as f64;
    let b = DMatrix::from_fn(n, n, |r, c| -0.5 * (d[(r, c)] - means[r] - means[c] + grand));
    let eigen = SymmetricEigen::new(b);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|a, c| eigen.eigenvalues[*c].total_cmp(&eigen.eigenvalues[*a]));
    let mut points = vec![Vec3::zeros(); n];
    for (axis, &k) in order.iter().take(3).enumerate() {
        let scale = eigen.eigenvalues[k].max(0.0).sqrt();
        for (row, p) in points.iter_mut().enumerate() {
            p[axis] = eigen.eigenvectors[(row, k)] * scale;
        }
    }
    Some(points)
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;
    use proptest::prelude::*;

    fn squared_distances(points: &[Vec3]) -> DMatrix<f64> {
        let n = points.len();
        DMatrix::from_fn(n, n, |a, b| (points[a] - points[b]).norm_squared())
    }

    proptest! {
        /// MDS reproduces any point set's distances exactly (up to rounding).
        #[test]
        fn mds_is_exact_on_rigid_sets(coords in proptest::collection::vec(proptest::array::uniform3(-500.0f64..500.0), 4..9)) {
            let points: Vec<Vec3> = coords.into_iter().map(Vec3::from).collect();
            let embedded = classical_mds(&squared_distances(&points)).unwrap();
            for a in 0..points.len() {
                for b in 0..points.len() {
                    let want = (points[a] - points[b]).norm();
                    let got = (embedded[a] - embedded[b]).norm();
                    prop_assert!((want - got).abs() < 1e-6 * want.max(1.0), "{want} vs {got}");
                }
            }
        }
    }

    /// A rigid cluster moving and turning: any gap of one marker is recovered exactly, at
    /// the start, in the middle and at the end of the take, whatever the mirror image MDS
    /// returns.
    #[test]
    fn rigid_motion_is_filled_exactly() {
        let frames = 200;
        // No marker drifts off the cluster.
        let truth = cluster_take(frames, usize::MAX);
        let mut holed = truth.clone();
        for f in (0..15).chain(80..140).chain(185..200) {
            holed.set_position_mm(f, 0, None).unwrap();
        }
        let filled = fill(&holed, 6, Selection::Variance);
        assert_eq!(filled.filled_count(), 15 + 60 + 15);
        for f in 0..frames {
            let (a, b) = (filled.take.position_mm(f, 0).unwrap(), truth.position_mm(f, 0).unwrap());
            assert!((a - b).norm() < 1e-6, "frame {f}: {a:?} vs {b:?}");
        }
    }

    /// Around the frames asked for, the restricted fill is the whole fill to the bit, for
    /// every marker (marker 1's gap overlaps them and reaches beyond, marker 4's lies within),
    /// and a gap far away is left missing.
    #[test]
    fn the_fill_near_some_frames_is_the_whole_fill_there() {
        let truth = crate::baseline::testing::take_from(300, 6, |f, m| {
            let t = f as f64 * 0.03 + m as f64;
            Vec3::new(
                100.0 * m as f64 + 30.0 * t.sin(),
                50.0 * (m % 3) as f64 + 20.0 * (1.3 * t).cos(),
                900.0 + 15.0 * t,
            )
        });
        let mut holed = truth.clone();
        for (marker, frames) in [(0, 100..140), (1, 130..170), (2, 160..200), (3, 20..50), (4, 138..139)] {
            crate::baseline::testing::hide(&mut holed, marker, frames);
        }
        let ranked = neighbours::rank_scored(&holed, Selection::Variance);
        let whole = fill_ranked(&holed, 6, &ranked);
        let near = fill_ranked_near(&holed, 6, &ranked, 100..140);
        for f in 99..141 {
            for m in 0..6 {
                assert_eq!(near.take.position_mm(f, m), whole.take.position_mm(f, m), "frame {f}, marker {m}");
            }
        }
        assert!(whole.take.is_valid(30, 3) && !near.take.is_valid(30, 3));
    }

    #[test]
    fn too_few_neighbours_leave_the_gap() {
        let names = (0..3).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let p = Some(Vec3::new(1.0, 2.0, 3.0));
        let q = Some(Vec3::new(5.0, 2.0, 3.0));
        let r = Some(Vec3::new(1.0, 9.0, 3.0));
        let take = Take::from_samples(names, &[p, q, r, None, q, r, p, q, r], 100.0).unwrap();
        let filled = fill(&take, 6, Selection::Variance);
        assert_eq!(filled.filled_count(), 0);
        assert_eq!(filled.take.position_mm(1, 0), None);
    }

    /// Marker 0 rides a rigid cluster with markers 1-4 that moves and turns; from frame
    /// `drift_from` marker 1 slides off the cluster at 1 mm per frame.
    fn cluster_take(frames: usize, drift_from: usize) -> Take {
        let drift =
            |f: usize, k: usize| if k == 1 { [f.saturating_sub(drift_from) as f64, 0.0, 0.0] } else { [0.0; 3] };
        locap_testkit::rigid_cluster(frames, 5, |k| format!("M{k}"), drift)
    }

    #[test]
    fn an_edge_gap_stops_where_the_neighbours_lose_their_shape() {
        // Over 600 frames the drift of the last 30 keeps marker 1 steady enough to be chosen.
        let truth = cluster_take(600, 570);
        let mut holed = truth.clone();
        for f in 540..600 {
            holed.set_position_mm(f, 0, None).unwrap();
        }
        let filled = fill(&holed, 6, Selection::Variance);
        let reached: Vec<usize> = (540..600).filter(|f| filled.take.is_valid(*f, 0)).collect();
        // A prefix of the gap: the rigid frames and a few of the drift, never its end.
        assert_eq!(reached, (540..540 + reached.len()).collect::<Vec<_>>());
        assert!((30..55).contains(&reached.len()), "{} frames filled", reached.len());
        for f in 540..570 {
            let (a, b) = (filled.take.position_mm(f, 0).unwrap(), truth.position_mm(f, 0).unwrap());
            assert!((a - b).norm() < 1e-6, "frame {f}: {a:?} vs {b:?}");
        }
        // The same gap inside the take is filled throughout, as the paper does.
        let mut inner = truth.clone();
        for f in 540..595 {
            inner.set_position_mm(f, 0, None).unwrap();
        }
        assert_eq!(fill(&inner, 6, Selection::Variance).filled_count(), 55);
    }

    #[test]
    fn an_edge_gap_is_carried_by_its_own_segment_while_another_one_turns() {
        // Markers 0-3 ride one rigid segment; markers 4-6 a second one that swings about it. The
        // second segment is never chosen at the edge, so its swing does not stop the fill.
        let own = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(120.0, 10.0, 0.0),
            Vec3::new(0.0, 90.0, 30.0),
            Vec3::new(40.0, 40.0, 110.0),
        ];
        let other = [Vec3::new(300.0, 0.0, 0.0), Vec3::new(380.0, 0.0, 0.0), Vec3::new(300.0, 80.0, 40.0)];
        let names = (0..7).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let mut samples = Vec::new();
        for f in 0..300 {
            let a = f as f64 * 0.02;
            let rot = nalgebra::Rotation3::from_euler_angles(0.3 * a, a, 0.0);
            let swing = nalgebra::Rotation3::from_euler_angles(0.0, 0.0, 1.5 * (5.0 * a).sin());
            let base = Vec3::new(4.0 * f as f64, 0.0, 900.0);
            samples.extend(own.iter().map(|o| Some(base + rot * o)));
            // The swing turns about marker 4, the joint.
            samples.extend(other.iter().map(|o| Some(base + rot * (other[0] + swing * (o - other[0])))));
        }
        let truth = Take::from_samples(names, &samples, 120.0).unwrap();
        let mut holed = truth.clone();
        for f in 250..300 {
            holed.set_position_mm(f, 0, None).unwrap();
        }
        let filled = fill(&holed, 6, Selection::Variance);
        assert_eq!(filled.filled_count(), 50);
        for f in 250..300 {
            let (a, b) = (filled.take.position_mm(f, 0).unwrap(), truth.position_mm(f, 0).unwrap());
            assert!((a - b).norm() < 1e-6, "frame {f}: {a:?} vs {b:?}");
        }
    }

    #[test]
    fn an_edge_gap_is_not_carried_by_neighbours_in_a_line() {
        // Marker 0 turns 80 mm about the line of markers 1-3 (a wrist about a forearm): its
        // distances to them never change, yet no rotation of theirs tells where it is.
        let names = (0..4).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let mut samples = Vec::new();
        for f in 0..300 {
            let a = f as f64 * 0.04;
            let base = Vec3::new(3.0 * f as f64, 0.0, 900.0);
            samples.push(Some(base + Vec3::new(100.0, 80.0 * a.cos(), 80.0 * a.sin())));
            for x in [0.0, 100.0, 200.0] {
                samples.push(Some(base + Vec3::new(x, 0.5 * (x / 100.0 - 1.0).powi(2), 0.0)));
            }
        }
        let mut take = Take::from_samples(names, &samples, 120.0).unwrap();
        for f in 250..300 {
            take.set_position_mm(f, 0, None).unwrap();
        }
        assert_eq!(fill(&take, 6, Selection::Variance).filled_count(), 0);
    }
}
