//! The articulated first fit: labels of one raw frame from the template's [`Body`], whatever
//! the pose (labeling paper section 3, last paragraph, which fits the subject's model to the
//! first frame; here the model is learned from the template take, [`crate::body`]).
//!
//! 1. *Segment candidates*: for every rigid segment, every triple of its markers is matched
//!    against triples of points with the same three distances (within the markers'
//!    tolerances); each match places the segment (Kabsch), its other markers take their
//!    nearest free points, and the placement is refitted on all of them. A candidate costs,
//!    per marker, its squared distance in tolerances, at most 1 (a missing marker costs 1).
//!    Ghosts and missing markers only add candidates or raise costs: no marker is required.
//! 2. *Labels chosen jointly*: one candidate per segment (or none) along the joint tree, by
//!    dynamic programming: a joint costs the distance between its centre as placed by the
//!    parent and as placed by the child, in its tolerance, squared and truncated; two
//!    segments on one joint may not share a point. Left and right limbs look alike one by
//!    one; their joints tell them apart. A hinge of a model's skeleton (a knee, an elbow)
//!    also costs the cap when the two placements turn its axis around: a rectangular plate
//!    turned over about its long axis keeps every distance and nearly its joint centres, but
//!    not the way its hinge points. Any joint costs the cap when it twists either bone about
//!    its own length more than a quarter turn past the twists the template take showed (a
//!    model's: its rest pose; `body::Twist`): a plate turned over is half a turn off.
//! 3. *Sure or not*: min-marginals of the same programme say, per segment, how much worse the
//!    best configuration with another placement of it (one giving under half of its markers
//!    the same points, or none) would be. A segment is sure when that margin is at least [`MIN_MARGIN`]
//!    (one marker's worth); the markers of unsure segments are left unlabeled, so the caller
//!    can wait for a better frame or re-acquire them later instead of guessing.
//! 4. *One-to-one labels*: the markers of sure segments (and the markers attached to them)
//!    take points by an optimal assignment (Hungarian) on their distance to where the fitted
//!    segments put them.
//!
//! Segments whose pose is already known (re-acquisition during tracking) enter as anchors:
//! their placement is fixed and only the others are fitted.

use crate::assignment::GatedAssignment;
use crate::body::Body;
use locap_clean::procrustes::{RigidTransform, align};
use locap_core::Vec3;

/// A segment's placement is sure when every other choice costs at least this much more.
pub const MIN_MARGIN: f64 = 1.0;

/// Most candidates kept per segment.
const MAX_CANDIDATES: usize = 64;

/// A marker allowed further than this from its place (mm) is loose, and a seed triple holds
/// at most one loose marker while the segment has two others: two landmarks beside a plate
/// (`crate::model`: a torso's acromions) match so many point triples within their
/// allowances that their triples cost half the fit, and the triples of one landmark with
/// two plate markers find the same placements. Without any landmark in the seeds the
/// placements that match the landmark are missed (KneeltoProne01 from its layout: the left
/// ankle landmark labeled on a foot marker). Learned segments' tolerances stay far below.
const SEED_TOLERANCE_MM: f64 = 60.0;

/// Most marker triples of one segment tried.
const MAX_TRIPLES: usize = 10;

/// Largest cost of one joint, in squared tolerances: a joint broken this badly means a
/// wrong placement (or a pose far from any the template showed) and weighs as much as
/// nine missing markers.
const JOINT_CAP: f64 = 9.0;

/// A joint twisting a bone more than this past the twists the template showed (a model's
/// rest pose) costs the cap (radians): a knee, hip or neck turns its bone by tens of
/// degrees, a shoulder or forearm by up to about 90; a plate turned over by half a turn.
const TWIST_ALLOWANCE_RAD: f64 = std::f64::consts::FRAC_PI_2;

/// Cost of two segments on one joint sharing a point.
const SHARED_POINT_COST: f64 = 100.0;

/// One placement of a segment.
#[derive(Debug, Clone)]
struct Candidate {
    pose: Option<RigidTransform>,
    /// For each segment marker, its point.
    points: Vec<Option<u32>>,
    cost: f64,
}

/// Result of [`fit_pose`].
#[derive(Debug, Clone, PartialEq)]
pub struct PoseFit {
    /// For each template marker, the index of its point, or `None`.
    pub assignment: Vec<Option<usize>>,
    /// For each template marker on a sure segment, where the fit puts it (mm), also when
    /// it has no point.
    pub expected_mm: Vec<Option<Vec3>>,
    /// Each segment's pose where it is sure.
    pub poses: Vec<Option<RigidTransform>>,
    /// Markers on sure segments (or attached to one).
    pub sure_markers: usize,
    /// Root mean square distance of the labeled points from where the fit expects them (mm).
    pub rms_mm: f64,
    /// Per segment placed by the best configuration, how much more the best configuration
    /// with another placement of it costs (sure from [`MIN_MARGIN`]); `None` where the best
    /// leaves it unplaced or it is an anchor. Says why a fit is not sure of a segment.
    pub margins: Vec<Option<f64>>,
}

impl PoseFit {
    /// Markers labeled.
    pub fn labeled(&self) -> usize {
        self.assignment.iter().flatten().count()
    }
}

/// Fits `body` (of a template with `markers` markers) to the cloud `points` (mm). Points
/// with `taken[j]` are not available (labeled already); segments with `anchors[s]` are placed
/// there. Both may be empty slices (nothing taken, no anchors).
pub fn fit_pose(
    body: &Body,
    markers: usize,
    points: &[Vec3],
    taken: &[bool],
    anchors: &[Option<RigidTransform>],
) -> PoseFit {
    let free: Vec<bool> = (0..points.len()).map(|j| !taken.get(j).copied().unwrap_or(false)).collect();
    let n_seg = body.segments.len();
    let anchor = |s: usize| anchors.get(s).copied().flatten();
    let cloud = FreeCloud::new(points, &free);
    let candidates: Vec<Vec<Candidate>> = (0..n_seg)
        .map(|s| match anchor(s) {
            Some(pose) => {
                vec![Candidate { pose: Some(pose), points: vec![None; body.segments[s].markers.len()], cost: 0.0 }]
            }
            None => {
                let mut c = segment_candidates(body, s, &cloud);
                c.push(Candidate {
                    pose: None,
                    points: vec![None; body.segments[s].markers.len()],
                    cost: body.segments[s].markers.len() as f64,
                });
                c
            }
        })
        .collect();
    let (chosen, margins) = choose(body, &candidates);
    let margins = (0..n_seg).map(|s| if anchor(s).is_some() { None } else { margins[s] }).collect();

    let poses: Vec<Option<RigidTransform>> = (0..n_seg)
        .map(|s| chosen[s].and_then(|c| if anchor(s).is_some() { None } else { candidates[s][c].pose }))
        .collect();
    let placed = body.place(&poses, markers);
    let mut assignment = GatedAssignment::default();
    assignment.begin(points.len());
    for p in &placed {
        assignment.push_marker(1.0);
        if let Some((centre, tolerance)) = p {
            for (j, q) in points.iter().enumerate() {
                let d2 = (centre - q).norm_squared() / (tolerance * tolerance);
                if free[j] && d2 < 1.0 {
                    assignment.push_candidate(j, d2);
                }
            }
        }
    }
    let mut labels: Vec<Option<usize>> = assignment.solve().iter().map(|p| p.map(|p| p as usize)).collect();
    // An attached marker (placed loosely, by a segment it does not ride on) takes its point
    // only when no other free point lies within its tolerance: with a ghost beside it, which
    // is which is a guess, and tracking picks the marker up once it moves with its segment.
    let mut used = vec![false; points.len()];
    for p in labels.iter().flatten() {
        used[*p] = true;
    }
    for a in &body.attached {
        let (Some(p), Some((centre, tolerance))) = (labels[a.marker], placed[a.marker]) else { continue };
        let rivals = (0..points.len())
            .filter(|&j| j != p && free[j] && !used[j] && (points[j] - centre).norm() < tolerance)
            .count();
        if rivals > 0 {
            used[p] = false;
            labels[a.marker] = None;
        }
    }
    let sum2: f64 =
        labels.iter().zip(&placed).filter_map(|(l, p)| Some((points[(*l)?] - p.as_ref()?.0).norm_squared())).sum();
    let labeled = labels.iter().flatten().count();
    PoseFit {
        assignment: labels,
        expected_mm: placed.iter().map(|p| p.map(|(c, _)| c)).collect(),
        sure_markers: placed.iter().flatten().count(),
        poses,
        rms_mm: (sum2 / labeled.max(1) as f64).sqrt(),
        margins,
    }
}

/// The free points of one frame, indexed for the fit's two searches: the points within a
/// marker's tolerance of where a placement puts it (sorted along x, a window of it scanned),
/// and the points at a given distance from a point (each point's others sorted by distance,
/// a ring of them scanned). A frame with as many ghosts as markers holds 120+ points, and a
/// scan of all of them for every seed triple and refit was most of a first fit's time.
struct FreeCloud<'a> {
    points: &'a [Vec3],
    /// Free points as (x, index), by x.
    by_x: Vec<(f64, usize)>,
    /// Free point indices, ascending.
    usable: Vec<usize>,
    /// For each point, (distance, index) of every other free point, nearest first (empty
    /// for a point not free).
    rings: Vec<Vec<(f64, usize)>>,
}

impl<'a> FreeCloud<'a> {
    fn new(points: &'a [Vec3], free: &[bool]) -> FreeCloud<'a> {
        let usable: Vec<usize> = (0..points.len()).filter(|&j| free[j]).collect();
        let mut by_x: Vec<(f64, usize)> = usable.iter().map(|&j| (points[j].x, j)).collect();
        by_x.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut rings = vec![Vec::new(); points.len()];
        for &i in &usable {
            let mut ring: Vec<(f64, usize)> =
                usable.iter().filter(|&&j| j != i).map(|&j| ((points[i] - points[j]).norm(), j)).collect();
            ring.sort_by(|a, b| a.0.total_cmp(&b.0));
            rings[i] = ring;
        }
        FreeCloud { points, by_x, usable, rings }
    }

    /// Free points whose x lies within `radius` of `centre`'s (a superset of those within
    /// `radius` of it), in no particular order.
    fn near_x(&self, centre: &Vec3, radius: f64) -> impl Iterator<Item = usize> + '_ {
        let lo = self.by_x.partition_point(|p| p.0 < centre.x - radius);
        let hi = self.by_x.partition_point(|p| p.0 <= centre.x + radius);
        self.by_x[lo..hi].iter().map(|p| p.1)
    }

    /// Free points other than `i` whose distance `d` from it satisfies
    /// `(d - length).abs() <= tolerance`, ascending by index (the order a scan of all
    /// points finds them in).
    fn at_distance(&self, i: usize, length: f64, tolerance: f64) -> Vec<usize> {
        let ring = &self.rings[i];
        // The window is widened by a hair and tested exactly below, so that what is found
        // does not depend on rounding at its ends.
        let lo = ring.partition_point(|p| p.0 < length - tolerance - 1e-9);
        let hi = ring.partition_point(|p| p.0 <= length + tolerance + 1e-9);
        let mut out: Vec<usize> =
            ring[lo..hi].iter().filter(|p| (p.0 - length).abs() <= tolerance).map(|p| p.1).collect();
        out.sort_unstable();
        out
    }

    fn distance(&self, a: usize, b: usize) -> f64 {
        (self.points[a] - self.points[b]).norm()
    }
}

/// Placements of segment `s` among the free points.
fn segment_candidates(body: &Body, s: usize, cloud: &FreeCloud) -> Vec<Candidate> {
    let seg = &body.segments[s];
    let k = seg.markers.len();
    let points = cloud.points;
    let mut triples = Vec::new();
    let seeds = (0..k).filter(|&m| seg.tolerance_mm[m] <= SEED_TOLERANCE_MM).count();
    let loose = |t: &[usize]| t.iter().filter(|&&m| seg.tolerance_mm[m] > SEED_TOLERANCE_MM).count();
    for a in 0..k {
        for b in a + 1..k {
            for c in b + 1..k {
                if seeds >= 2 && loose(&[a, b, c]) > 1 {
                    continue;
                }
                let area = (seg.local_mm[b] - seg.local_mm[a]).cross(&(seg.local_mm[c] - seg.local_mm[a])).norm();
                triples.push((area, [a, b, c]));
            }
        }
    }
    triples.sort_by(|x, y| y.0.total_cmp(&x.0));
    triples.truncate(MAX_TRIPLES);
    let mut found: Vec<Candidate> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    // Triples of (marker, point) pairs some candidate holds already: another triple of the
    // same placement would only find it again.
    let mut covered: std::collections::HashSet<[(usize, usize); 3]> = std::collections::HashSet::new();
    for (area, [a, b, c]) in triples {
        if area < 100.0 {
            // Nearly collinear: the triple does not fix the rotation.
            continue;
        }
        let d = |x: usize, y: usize| (seg.local_mm[x] - seg.local_mm[y]).norm();
        let tol = |x: usize, y: usize| seg.tolerance_mm[x] + seg.tolerance_mm[y];
        let (dab, dac, dbc) = (d(a, b), d(a, c), d(b, c));
        let (tab, tac, tbc) = (tol(a, b), tol(a, c), tol(b, c));
        for &i in &cloud.usable {
            let thirds = cloud.at_distance(i, dac, tac);
            if thirds.is_empty() {
                continue;
            }
            for j in cloud.at_distance(i, dab, tab) {
                for &l in &thirds {
                    if l == j || (cloud.distance(j, l) - dbc).abs() > tbc {
                        continue;
                    }
                    if covered.contains(&[(a, i), (b, j), (c, l)]) {
                        continue;
                    }
                    let from = [seg.local_mm[a], seg.local_mm[b], seg.local_mm[c]];
                    let Some(pose) = align(&from, &[points[i], points[j], points[l]]) else { continue };
                    let Some(candidate) = refine(body, s, cloud, pose) else { continue };
                    let pairs: Vec<(usize, usize)> =
                        candidate.points.iter().enumerate().filter_map(|(m, p)| Some((m, (*p)? as usize))).collect();
                    for x in 0..pairs.len() {
                        for y in x + 1..pairs.len() {
                            for z in y + 1..pairs.len() {
                                covered.insert([pairs[x], pairs[y], pairs[z]]);
                            }
                        }
                    }
                    if seen.insert(candidate.points.clone()) {
                        found.push(candidate);
                    }
                }
            }
        }
    }
    found.sort_by(|x, y| x.cost.total_cmp(&y.cost));
    found.truncate(MAX_CANDIDATES);
    found
}

/// Places segment `s` at `pose`, gives its markers their nearest free points (nearest pairs
/// first, one point each) within tolerance, refits on them twice; `None` below three.
fn refine(body: &Body, s: usize, cloud: &FreeCloud, mut pose: RigidTransform) -> Option<Candidate> {
    let seg = &body.segments[s];
    let points = cloud.points;
    let k = seg.markers.len();
    let mut chosen = vec![None; k];
    let mut cost = 0.0;
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for round in 0..3 {
        pairs.clear();
        for m in 0..k {
            let at = pose.apply(&seg.local_mm[m]);
            let r2 = seg.tolerance_mm[m] * seg.tolerance_mm[m];
            for j in cloud.near_x(&at, seg.tolerance_mm[m]) {
                let d2 = (at - points[j]).norm_squared() / r2;
                if d2 < 1.0 {
                    pairs.push((d2, m, j));
                }
            }
        }
        // Nearest first; ties in marker then point order, as a scan of every point finds them.
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        chosen.fill(None);
        let mut used: Vec<usize> = Vec::with_capacity(k);
        cost = k as f64;
        for &(d2, m, j) in &pairs {
            if chosen[m].is_none() && !used.contains(&j) {
                chosen[m] = Some(j as u32);
                used.push(j);
                cost += d2 - 1.0;
            }
        }
        if used.len() < 3 {
            return None;
        }
        if round < 2 {
            let (from, to): (Vec<Vec3>, Vec<Vec3>) =
                (0..k).filter_map(|m| Some((seg.local_mm[m], points[chosen[m]? as usize]))).unzip();
            pose = align(&from, &to)?;
        }
    }
    Some(Candidate { pose: Some(pose), points: chosen, cost })
}

/// Cost of a joint between candidate `a` of its parent and `b` of its child.
fn joint_cost(joint: &crate::body::Joint, a: &Candidate, b: &Candidate) -> f64 {
    let (Some(pa), Some(pb)) = (&a.pose, &b.pose) else { return 0.0 };
    let d = (pa.apply(&joint.parent_mm) - pb.apply(&joint.child_mm)).norm() / joint.tolerance_mm;
    let shared = a.points.iter().flatten().filter(|p| b.points.contains(&Some(**p))).count();
    // A hinge keeps its axis: placed by the two segments, the axis points the same way, up
    // to how differently the plates sit on their bones. Turned past a right angle, one of
    // the placements is a plate turned over on its own symmetry (a rectangle's front and
    // back markers swapped), which its shape and the joint's centre cannot tell apart.
    let reversed = joint.hinge.is_some_and(|h| h.reversed(pa, pb));
    // Any joint: a bone turned about its own length far past what the template showed is a
    // plate turned over on its long axis.
    let twisted = joint.twist.is_some_and(|[child, parent]| {
        let relative = pa.rotation.inverse() * pb.rotation;
        child.excess_rad(&relative) > TWIST_ALLOWANCE_RAD
            || parent.excess_rad(&relative.inverse()) > TWIST_ALLOWANCE_RAD
    });
    let cost = if reversed || twisted { JOINT_CAP } else { (d * d).min(JOINT_CAP) };
    cost + SHARED_POINT_COST * shared as f64
}

/// The best candidate of every segment (dynamic programming along the joint forest), or
/// `None` for a segment left unplaced or unsure; and each placed segment's margin.
fn choose(body: &Body, candidates: &[Vec<Candidate>]) -> (Vec<Option<usize>>, Vec<Option<f64>>) {
    let n = candidates.len();
    let mut parent_joint: Vec<Option<usize>> = vec![None; n];
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (j, joint) in body.joints.iter().enumerate() {
        parent_joint[joint.child] = Some(j);
        children[joint.parent].push(j);
    }
    // Pairwise costs per joint: parent candidates x child candidates.
    let pair: Vec<Vec<f64>> = body
        .joints
        .iter()
        .map(|joint| {
            let (pc, cc) = (&candidates[joint.parent], &candidates[joint.child]);
            pc.iter().flat_map(|a| cc.iter().map(move |b| joint_cost(joint, a, b))).collect()
        })
        .collect();
    // Upward pass (joints were listed parents first, so in reverse children come first).
    let mut up: Vec<Vec<f64>> = candidates.iter().map(|c| c.iter().map(|c| c.cost).collect()).collect();
    let mut message: Vec<Vec<f64>> = vec![Vec::new(); body.joints.len()];
    for (j, joint) in body.joints.iter().enumerate().rev() {
        let cc = candidates[joint.child].len();
        let msg: Vec<f64> = (0..candidates[joint.parent].len())
            .map(|a| (0..cc).map(|b| up[joint.child][b] + pair[j][a * cc + b]).fold(f64::INFINITY, f64::min))
            .collect();
        for (a, m) in msg.iter().enumerate() {
            up[joint.parent][a] += m;
        }
        message[j] = msg;
    }
    // Downward pass: the best cost of everything outside each subtree.
    let mut down: Vec<Vec<f64>> = candidates.iter().map(|c| vec![0.0; c.len()]).collect();
    for (j, joint) in body.joints.iter().enumerate() {
        let cc = candidates[joint.child].len();
        let pc = candidates[joint.parent].len();
        let outside: Vec<f64> = (0..pc).map(|a| down[joint.parent][a] + up[joint.parent][a] - message[j][a]).collect();
        down[joint.child] =
            (0..cc).map(|b| (0..pc).map(|a| outside[a] + pair[j][a * cc + b]).fold(f64::INFINITY, f64::min)).collect();
    }
    // Backtrack the best configuration from each root.
    let mut best: Vec<usize> = vec![0; n];
    let argmin = |v: &[f64]| (0..v.len()).min_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap_or(0);
    for s in 0..n {
        if parent_joint[s].is_none() {
            let total: Vec<f64> = (0..up[s].len()).map(|c| up[s][c] + down[s][c]).collect();
            best[s] = argmin(&total);
        }
    }
    for (j, joint) in body.joints.iter().enumerate() {
        let a = best[joint.parent];
        let cc = candidates[joint.child].len();
        let cost: Vec<f64> = (0..cc).map(|b| up[joint.child][b] + pair[j][a * cc + b]).collect();
        best[joint.child] = argmin(&cost);
    }
    // Sure: every placement sharing under half of the best one's points costs MIN_MARGIN more.
    let margins: Vec<Option<f64>> = (0..n)
        .map(|s| {
            let c = &candidates[s][best[s]];
            c.pose?;
            let marginal = |x: usize| up[s][x] + down[s][x];
            let own = marginal(best[s]);
            let mine = c.points.iter().flatten().count();
            // A rival labels under half of the best one's markers as it does: the same points
            // under other labels (a triangle turned over) are a rival too.
            let rival = (0..candidates[s].len())
                .filter(|&x| {
                    let same =
                        candidates[s][x].points.iter().zip(&c.points).filter(|(a, b)| a.is_some() && a == b).count();
                    2 * same < mine
                })
                .map(marginal)
                .fold(f64::INFINITY, f64::min);
            Some(rival - own)
        })
        .collect();
    let chosen = (0..n).map(|s| margins[s].is_some_and(|m| m >= MIN_MARGIN).then_some(best[s])).collect();
    (chosen, margins)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::tests::hinge_take;
    use crate::template::Template;
    use nalgebra::Rotation3;

    fn body() -> (Template, Body) {
        let template = Template::from_take(&hinge_take(200), None).unwrap();
        let body = template.body().unwrap().clone();
        (template, body)
    }

    /// The hinge take's pose at `bend` radians of the knee, turned by `heading` and moved.
    fn posed(bend: f64, heading: f64) -> Vec<Vec3> {
        let take = hinge_take(200);
        let upper: Vec<Vec3> = (0..4).map(|m| take.position_mm(0, m).unwrap() - Vec3::new(0.0, 0.0, 1000.0)).collect();
        let lower: Vec<Vec3> = (4..8).map(|m| take.position_mm(0, m).unwrap() - Vec3::new(0.0, 0.0, 1000.0)).collect();
        let turn = Rotation3::from_euler_angles(0.0, 0.0, heading);
        let knee = Rotation3::from_euler_angles(bend, 0.0, 0.0);
        let at = Vec3::new(-700.0, 1200.0, 900.0);
        let mut p: Vec<Vec3> = upper.iter().map(|u| at + turn * u).collect();
        p.extend(lower.iter().map(|l| at + turn * knee * l));
        p.push(at + turn * Vec3::new(100.0, 100.0, 100.0));
        p
    }

    #[test]
    fn labels_a_pose_the_template_never_showed_among_ghosts() {
        let (template, body) = body();
        // The template bends the knee to 1.5 rad; 1.9 is beyond it.
        let truth = posed(1.9, 2.5);
        let order = [6usize, 0, 8, 3, 5, 1, 7, 2];
        let mut points: Vec<Vec3> = order.iter().map(|&m| truth[m]).collect();
        points.push(truth[4] + Vec3::new(40.0, -30.0, 10.0));
        points.push(Vec3::new(0.0, 0.0, 0.0));
        let fit = fit_pose(&body, template.marker_count(), &points, &[], &[]);
        for (m, a) in fit.assignment.iter().enumerate() {
            match a {
                Some(p) => assert_eq!(order.get(*p), Some(&m), "marker {m}"),
                None => assert_eq!(m, 4, "marker {m} unlabeled"),
            }
        }
        assert_eq!(fit.sure_markers, 9);
        assert!(fit.rms_mm < 1.0);
    }

    /// A joint 200 mm from the origins of both its segments' frames (each bone runs from the
    /// centre to its segment's origin), with the given hinge and twists.
    fn joint_between_origins(
        hinge: Option<crate::body::Hinge>,
        twist: Option<[crate::body::Twist; 2]>,
    ) -> crate::body::Joint {
        crate::body::Joint {
            parent: 0,
            child: 1,
            parent_mm: Vec3::new(0.0, -200.0, 0.0),
            child_mm: Vec3::new(0.0, 200.0, 0.0),
            tolerance_mm: 50.0,
            hinge,
            twist,
        }
    }

    /// The parent at the world's origin, and the child turned by `rotation` with its joint
    /// centre where the parent puts it.
    fn parent_and_child(rotation: Rotation3<f64>) -> (Candidate, Candidate) {
        let at = |rotation: Rotation3<f64>, translation: Vec3| Candidate {
            pose: Some(RigidTransform { rotation, translation }),
            points: vec![],
            cost: 0.0,
        };
        let centre = Vec3::new(0.0, -200.0, 0.0);
        (at(Rotation3::identity(), Vec3::zeros()), at(rotation, centre - rotation * Vec3::new(0.0, 200.0, 0.0)))
    }

    #[test]
    fn a_hinge_turned_over_costs_the_cap() {
        let joint = joint_between_origins(Some(crate::body::Hinge::shared(Vec3::z())), None);
        // Bent 100 degrees about the hinge, the centre where the parent puts it: free.
        let bend = Rotation3::from_euler_angles(0.0, 0.0, 100f64.to_radians());
        let (parent, bent) = parent_and_child(bend);
        assert!(joint_cost(&joint, &parent, &bent) < 1e-9);
        // The same child turned over about its long axis (a plate's front and back swapped):
        // the centre stays, the axis points the other way.
        let (_, turned) = parent_and_child(bend * Rotation3::from_euler_angles(0.0, std::f64::consts::PI, 0.0));
        assert!((joint_cost(&joint, &parent, &turned) - JOINT_CAP).abs() < 1e-9);
        let no_hinge = crate::body::Joint { hinge: None, ..joint };
        assert!(joint_cost(&no_hinge, &parent, &turned) < 1e-9);
    }

    #[test]
    fn a_bone_twisted_past_the_templates_turns_costs_the_cap() {
        // A ball joint (no hinge) bent 100 degrees across its bones; the template showed it
        // within 0.3 rad of that pose's twists.
        let bend = Rotation3::from_euler_angles(0.0, 0.0, 100f64.to_radians());
        let (child_axis, parent_axis) = (-Vec3::y(), Vec3::y());
        let seen = |axis: Vec3, relative: Rotation3<f64>| crate::body::Twist {
            axis,
            mean_rad: crate::body::Twist::angle(&axis, &relative),
            half_width_rad: 0.3,
        };
        let joint = joint_between_origins(None, Some([seen(child_axis, bend), seen(parent_axis, bend.inverse())]));
        // Twisted 0.2 rad more on its bone: within what was seen.
        let (parent, bent) = parent_and_child(bend * Rotation3::from_euler_angles(0.0, 0.2, 0.0));
        assert!(joint_cost(&joint, &parent, &bent) < 1e-9);
        // Turned over on its bone: the centres agree, the twist is half a turn off.
        let (_, turned) = parent_and_child(bend * Rotation3::from_euler_angles(0.0, std::f64::consts::PI, 0.0));
        assert!((joint_cost(&joint, &parent, &turned) - JOINT_CAP).abs() < 1e-9);
        let untold = crate::body::Joint { twist: None, ..joint };
        assert!(joint_cost(&untold, &parent, &turned) < 1e-9);
    }

    #[test]
    fn the_free_cloud_finds_what_a_scan_of_every_point_finds() {
        // A deterministic scatter with ties in x and duplicated points.
        let points: Vec<Vec3> = (0..60)
            .map(|i| {
                let t = i as f64;
                Vec3::new(((t * 37.0) % 400.0).round(), (t * 91.0) % 300.0, (t * t * 13.0) % 250.0)
            })
            .chain([Vec3::new(10.0, 20.0, 30.0), Vec3::new(10.0, 20.0, 30.0)])
            .collect();
        let free: Vec<bool> = (0..points.len()).map(|j| j % 7 != 3).collect();
        let cloud = FreeCloud::new(&points, &free);
        for i in (0..points.len()).filter(|&i| free[i]) {
            for (length, tolerance) in [(0.0, 0.0), (100.0, 20.0), (250.0, 60.0), (37.0, 0.5)] {
                let scan: Vec<usize> = (0..points.len())
                    .filter(|&j| free[j] && j != i && ((points[i] - points[j]).norm() - length).abs() <= tolerance)
                    .collect();
                assert_eq!(cloud.at_distance(i, length, tolerance), scan, "point {i}, {length} +- {tolerance}");
            }
        }
        for centre in [Vec3::new(10.0, 20.0, 30.0), Vec3::new(200.0, 0.0, 0.0), Vec3::new(-50.0, 5.0, 5.0)] {
            for radius in [0.0, 25.0, 120.0] {
                let near: Vec<usize> = cloud.near_x(&centre, radius).collect();
                for j in 0..points.len() {
                    let within = free[j] && (points[j] - centre).norm() <= radius;
                    assert!(!within || near.contains(&j), "point {j} within {radius} of {centre:?}");
                    assert!(!near.contains(&j) || free[j], "taken point {j} offered");
                }
            }
        }
    }

    #[test]
    fn a_frame_without_the_body_is_not_sure() {
        let (template, body) = body();
        let points: Vec<Vec3> = (0..9).map(|i| Vec3::new(i as f64 * 700.0, (i * i) as f64 * 90.0, 0.0)).collect();
        let fit = fit_pose(&body, template.marker_count(), &points, &[], &[]);
        assert_eq!(fit.sure_markers, 0);
        assert_eq!(fit.labeled(), 0);
    }
}
