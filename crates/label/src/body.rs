//! The articulated body a labeled template take shows: rigid segments (groups of markers
//! whose mutual distances hold over the take), the joints between them, and the markers that
//! ride on no segment of their own, attached to the segment they follow best.
//!
//! This is the subject model the labeling paper fits to the first frame (section 3, last
//! paragraph: "T-pose model and marker offsets relative to the inboard joints"), learned from
//! a labeled take in any pose instead of from a skeleton:
//! - *segments*: complete-linkage clustering of the markers on the spread of their distances
//!   (every pair in a segment varies by at most [`SEGMENT_STD_MM`]), each with its shape in
//!   its own frame and a tolerance per marker (how far the marker strayed from the rigid
//!   shape over the take);
//! - *joints*: for two segments, the point fixed in both frames over the take (the functional
//!   joint centre, a linear least-squares problem in its two local positions, as in the
//!   SCoRE method of Ehrig et al. 2006); segments are joined along a spanning tree of the
//!   best-fitting centres; each keeps the hinge axis it turns about, if one, and how far it
//!   twists each bone about the bone's own length over the take;
//! - *attached markers*: a marker in no segment of three is placed by the segment in whose
//!   frame it moves least.
//!
//! [`crate::pose_fit`] fits this model to a raw frame, whatever the pose.

use locap_clean::procrustes::{RigidTransform, align};
use locap_core::{Take, Vec3};
use nalgebra::{Matrix3, Matrix6, Vector6};

/// Markers whose distances vary by at most this over the template (mm, standard deviation)
/// may share a segment. Skin on one bone moves a marker by a few millimetres against its
/// neighbours; across a joint in motion distances change by centimetres.
pub const SEGMENT_STD_MM: f64 = 8.0;

/// Markers of one segment lie at most this far apart (mm): a thigh or shank cluster, a head
/// band, a pelvis. A longer group is two segments the template take happened not to move
/// against each other (a subject kneeling still holds pelvis, thigh and shank rigid), which
/// would not be rigid in a take that moves them.
pub const MAX_SEGMENT_SPAN_MM: f64 = 300.0;

/// A group of at least six markers spanning more than this (mm) is split in two by place
/// (2-means): six markers are more than one plate holds, and such a group is more likely two
/// segments the template held still (a kneeling subject's pelvis and lower back) than one.
/// Where it really is one segment, the halves stay together through their joint.
pub const SPLIT_SPAN_MM: f64 = 200.0;

/// Reconstruction noise added to every tolerance (mm).
pub const NOISE_MM: f64 = 3.0;

/// A joint centre that misses by more than this over the template (rms, mm) joins nothing.
const MAX_JOINT_RMS_MM: f64 = 40.0;

/// An attached marker that strays more than this from its place in its segment's frame (rms
/// over the template, mm) is left to tracking alone.
const MAX_ATTACHED_RMS_MM: f64 = 40.0;

/// Template frames used to learn the model: evenly spaced, at most this many.
const MAX_MODEL_FRAMES: usize = 2000;

/// A rigid segment: markers and their shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Template marker indices.
    pub markers: Vec<usize>,
    /// Each marker's position in the segment's frame (mm; the origin is the shape's
    /// centroid).
    pub local_mm: Vec<Vec3>,
    /// How far each marker may sit from its place once the segment is fitted (mm).
    pub tolerance_mm: Vec<f64>,
}

/// A joint: the point fixed in two segments' frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Segment index nearer the root of the tree.
    pub parent: usize,
    /// The other segment.
    pub child: usize,
    /// The centre in the parent's frame (mm).
    pub parent_mm: Vec3,
    /// The centre in the child's frame (mm).
    pub child_mm: Vec3,
    /// How far the two placements of the centre may differ (mm).
    pub tolerance_mm: f64,
    /// For a hinge (one rotation between the two segments: a knee, an elbow), its axis;
    /// `None` where the joint turns about more axes or nothing says.
    pub hinge: Option<Hinge>,
    /// How far the joint twists the child about its own bone, and the parent about its
    /// bone, over the template (a model's: none from its rest pose); `None` where a segment's
    /// markers sit on the joint's centre or the template does not say.
    pub twist: Option<[Twist; 2]>,
}

/// The turn of one segment of a joint about its bone (the line from the joint's centre to the
/// segment's markers) relative to the other segment, over the template: no joint turns a bone
/// about its own length by half a turn, but a plate turned over on its long axis (front and
/// back markers swapped) keeps its shape and nearly its joint centres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Twist {
    /// The bone's direction in the segment's frame (unit).
    pub axis: Vec3,
    /// Circular mean of the turn about it over the template (radians).
    pub mean_rad: f64,
    /// Half the width of the turns seen (95% of them within the mean plus or minus this).
    pub half_width_rad: f64,
}

impl Twist {
    /// The turn about `axis` of `rotation` (which maps the segment's frame to the other's),
    /// in (-pi, pi] (swing-twist decomposition).
    pub fn angle(axis: &Vec3, rotation: &nalgebra::Rotation3<f64>) -> f64 {
        let q = nalgebra::UnitQuaternion::from_rotation_matrix(rotation);
        wrap_angle(2.0 * q.imag().dot(axis).atan2(q.w))
    }

    /// How far `rotation` twists past what the template showed (radians, 0 inside).
    pub fn excess_rad(&self, rotation: &nalgebra::Rotation3<f64>) -> f64 {
        (wrap_angle(Twist::angle(&self.axis, rotation) - self.mean_rad).abs() - self.half_width_rad).max(0.0)
    }
}

/// `a` wrapped into (-pi, pi].
fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = a.rem_euclid(TAU);
    if w > PI { w - TAU } else { w }
}

/// A hinge's axis: the same line as seen in each of its two segments' frames (unit vectors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hinge {
    /// The axis in the parent's frame.
    pub parent_axis: Vec3,
    /// The axis in the child's frame.
    pub child_axis: Vec3,
}

impl Hinge {
    /// A hinge whose axis is the same vector in both frames (a model's segment frames agree
    /// at its rest pose).
    pub fn shared(axis: Vec3) -> Hinge {
        Hinge { parent_axis: axis, child_axis: axis }
    }

    /// Whether the two placements turn the axis around (more than a right angle apart).
    pub fn reversed(&self, parent: &RigidTransform, child: &RigidTransform) -> bool {
        (parent.rotation * self.parent_axis).dot(&(child.rotation * self.child_axis)) < 0.0
    }
}

/// A marker placed by a segment it does not belong to.
#[derive(Debug, Clone, PartialEq)]
pub struct Attached {
    /// Template marker index.
    pub marker: usize,
    /// Segment index.
    pub segment: usize,
    /// Mean position in the segment's frame (mm).
    pub local_mm: Vec3,
    /// How far it may sit from there (mm).
    pub tolerance_mm: f64,
}

/// The articulated model of a template.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Rigid segments of at least three markers.
    pub segments: Vec<Segment>,
    /// Joints along a spanning forest of the segments; parents before children.
    pub joints: Vec<Joint>,
    /// Markers in no segment, placed by one.
    pub attached: Vec<Attached>,
    /// For every template marker: (segment, index in it) when it belongs to one.
    pub member: Vec<Option<(usize, usize)>>,
}

impl Body {
    /// Learns the body from a labeled take (every column a template marker) and the
    /// variance of every pair's distance (`variance[i * m + j]`, mm^2; infinite for pairs
    /// rarely seen together). `None` when no segment of three markers exists.
    pub fn learn(take: &Take, variance: &[f64]) -> Option<Body> {
        let m = take.marker_count();
        let stride = take.frame_count().div_ceil(MAX_MODEL_FRAMES).max(1);
        let frames: Vec<usize> = (0..take.frame_count()).step_by(stride).collect();
        let mean = mean_distances(take, &frames);
        let clusters = cluster(m, variance, SEGMENT_STD_MM * SEGMENT_STD_MM, &mean, MAX_SEGMENT_SPAN_MM);
        let clusters: Vec<Vec<usize>> = clusters.into_iter().flat_map(|c| split(c, &mean, m)).collect();
        let mut segments = Vec::new();
        for members in clusters.into_iter().filter(|c| c.len() >= 3) {
            if let Some(s) = segment(take, &frames, members) {
                segments.push(s);
            }
        }
        if segments.is_empty() {
            return None;
        }
        let mut member = vec![None; m];
        for (s, seg) in segments.iter().enumerate() {
            for (k, &i) in seg.markers.iter().enumerate() {
                member[i] = Some((s, k));
            }
        }
        // Each segment's pose in every model frame where it shows three markers.
        let poses: Vec<Vec<Option<RigidTransform>>> = segments
            .iter()
            .map(|s| frames.iter().map(|&f| fit_segment(take, f, s).map(|(t, _)| t)).collect())
            .collect();
        let joints = joint_tree(&segments, &poses);
        let attached =
            (0..m).filter(|&i| member[i].is_none()).filter_map(|i| attach(take, &frames, &poses, i)).collect();
        Some(Body { segments, joints, attached, member })
    }

    /// Markers the body places: those on a segment and those attached to one.
    pub fn placeable(&self) -> usize {
        self.member.iter().filter(|s| s.is_some()).count() + self.attached.len()
    }

    /// Every marker's expected position and tolerance given the segments' poses (`None`
    /// where its segment is not placed or it belongs to none).
    pub fn place(&self, poses: &[Option<RigidTransform>], markers: usize) -> Vec<Option<(Vec3, f64)>> {
        let mut out = vec![None; markers];
        for (s, seg) in self.segments.iter().enumerate() {
            if let Some(t) = &poses[s] {
                for ((&i, l), &r) in seg.markers.iter().zip(&seg.local_mm).zip(&seg.tolerance_mm) {
                    out[i] = Some((t.apply(l), r));
                }
            }
        }
        for a in &self.attached {
            if let Some(t) = &poses[a.segment] {
                out[a.marker] = Some((t.apply(&a.local_mm), a.tolerance_mm));
            }
        }
        out
    }
}

/// Mean distance of every pair over `frames` (`[i * m + j]`, mm; infinite for pairs never
/// seen together).
fn mean_distances(take: &Take, frames: &[usize]) -> Vec<f64> {
    let m = take.marker_count();
    let (mut sum, mut count) = (vec![0.0; m * m], vec![0usize; m * m]);
    for &f in frames {
        for i in 0..m {
            let Some(a) = take.position_mm(f, i) else { continue };
            for j in 0..m {
                if let Some(b) = take.position_mm(f, j) {
                    sum[i * m + j] += (a - b).norm();
                    count[i * m + j] += 1;
                }
            }
        }
    }
    sum.iter().zip(&count).map(|(s, &n)| if n > 0 { s / n as f64 } else { f64::INFINITY }).collect()
}

/// `members` as one group, or two (2-means on the mean distances, seeded by the farthest
/// pair) when it has six or more markers spanning more than [`SPLIT_SPAN_MM`].
fn split(members: Vec<usize>, distance: &[f64], m: usize) -> Vec<Vec<usize>> {
    let d = |i: usize, j: usize| distance[i * m + j];
    let mut far = (0, 0, 0.0);
    for &i in &members {
        for &j in &members {
            if d(i, j) > far.2 {
                far = (i, j, d(i, j));
            }
        }
    }
    if members.len() < 6 || far.2 <= SPLIT_SPAN_MM {
        return vec![members];
    }
    // Each marker joins the seed whose group it is nearer on average.
    let (mut a, mut b) = (vec![far.0], vec![far.1]);
    for _ in 0..5 {
        let mean_to = |group: &[usize], i: usize| group.iter().map(|&g| d(i, g)).sum::<f64>() / group.len() as f64;
        let (na, nb): (Vec<usize>, Vec<usize>) = members.iter().partition(|&&i| mean_to(&a, i) <= mean_to(&b, i));
        if na.is_empty() || nb.is_empty() || (na == a && nb == b) {
            break;
        }
        (a, b) = (na, nb);
    }
    if a.len() < 3 || b.len() < 3 {
        return vec![members];
    }
    vec![a, b]
}

/// Complete-linkage clustering: groups in which every pair's variance is at most `limit`
/// and every pair's mean distance at most `span`. Merges the closest pair of groups (by
/// their largest pair variance) while one is allowed.
fn cluster(m: usize, variance: &[f64], limit: f64, distance: &[f64], span: f64) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = (0..m).map(|i| vec![i]).collect();
    loop {
        let mut best: Option<(f64, usize, usize)> = None;
        for a in 0..groups.len() {
            for b in a + 1..groups.len() {
                let pairs = || groups[a].iter().flat_map(|&i| groups[b].iter().map(move |&j| i * m + j));
                let worst = pairs().map(|k| variance[k]).fold(0.0, f64::max);
                let far = pairs().map(|k| distance[k]).fold(0.0, f64::max);
                if worst <= limit && far <= span && best.is_none_or(|(w, _, _)| worst < w) {
                    best = Some((worst, a, b));
                }
            }
        }
        let Some((_, a, b)) = best else { break };
        let moved = groups.swap_remove(b);
        groups[a].extend(moved);
    }
    for g in &mut groups {
        g.sort_unstable();
    }
    groups.sort();
    groups
}

/// A segment's shape from the frame whose distances are nearest the take's mean ones, and
/// each marker's tolerance from its rms residual over the take. Markers seen in no frame
/// with all the others are dropped; `None` when fewer than three remain.
fn segment(take: &Take, frames: &[usize], mut members: Vec<usize>) -> Option<Segment> {
    loop {
        if members.len() < 3 {
            return None;
        }
        let full: Vec<usize> =
            frames.iter().copied().filter(|&f| members.iter().all(|&i| take.is_valid(f, i))).collect();
        if full.is_empty() {
            // Drop the marker seen least and try again.
            let least = *members.iter().min_by_key(|&&i| frames.iter().filter(|&&f| take.is_valid(f, i)).count())?;
            members.retain(|&i| i != least);
            continue;
        }
        let at = |f: usize, k: usize| take.position_mm(f, members[k]).unwrap_or_default();
        let n = members.len();
        let mut mean = vec![0.0; n * n];
        for &f in &full {
            for a in 0..n {
                for b in a + 1..n {
                    mean[a * n + b] += (at(f, a) - at(f, b)).norm() / full.len() as f64;
                }
            }
        }
        let deviation = |f: usize| -> f64 {
            let mut sum = 0.0;
            for a in 0..n {
                for b in a + 1..n {
                    sum += ((at(f, a) - at(f, b)).norm() - mean[a * n + b]).powi(2);
                }
            }
            sum
        };
        let reference = full.iter().copied().min_by(|&a, &b| deviation(a).total_cmp(&deviation(b)))?;
        let shape: Vec<Vec3> = (0..n).map(|k| at(reference, k)).collect();
        let centroid = shape.iter().sum::<Vec3>() / n as f64;
        let local_mm: Vec<Vec3> = shape.iter().map(|p| p - centroid).collect();
        let mut seg = Segment { markers: members, local_mm, tolerance_mm: vec![0.0; n] };
        let (mut sum2, mut count) = (vec![0.0; n], vec![0usize; n]);
        for &f in frames {
            if let Some((t, _)) = fit_segment(take, f, &seg) {
                for k in 0..n {
                    if let Some(p) = take.position_mm(f, seg.markers[k]) {
                        sum2[k] += (t.apply(&seg.local_mm[k]) - p).norm_squared();
                        count[k] += 1;
                    }
                }
            }
        }
        for k in 0..n {
            let rms = (sum2[k] / count[k].max(1) as f64).sqrt();
            seg.tolerance_mm[k] = 3.0 * rms.hypot(NOISE_MM);
        }
        return Some(seg);
    }
}

/// The segment's pose in frame `f` from its visible markers (at least three), and how many
/// were visible.
fn fit_segment(take: &Take, f: usize, seg: &Segment) -> Option<(RigidTransform, usize)> {
    let (from, to): (Vec<Vec3>, Vec<Vec3>) =
        seg.markers.iter().zip(&seg.local_mm).filter_map(|(&i, l)| Some((*l, take.position_mm(f, i)?))).unzip();
    Some((align(&from, &to)?, from.len()))
}

/// The functional joint centre of two segments: local points `a` (in the first's frame) and
/// `b` (the second's) minimising `sum |T1 a - T2 b|^2` over the frames both are placed in,
/// with a light pull towards the midpoint of the two segments so that a joint the take
/// barely moves stays defined. Returns `(a, b, rms_mm)`.
fn joint_centre(first: &[Option<RigidTransform>], second: &[Option<RigidTransform>]) -> Option<(Vec3, Vec3, f64)> {
    let pairs: Vec<(&RigidTransform, &RigidTransform)> =
        first.iter().zip(second).filter_map(|(a, b)| Some((a.as_ref()?, b.as_ref()?))).collect();
    if pairs.len() < 10 {
        return None;
    }
    let mut normal = Matrix6::zeros();
    let mut rhs = Vector6::zeros();
    // Midpoint of the two centroids, in each frame (averaged over the frames).
    let (mut mid_a, mut mid_b) = (Vec3::zeros(), Vec3::zeros());
    for (ta, tb) in &pairs {
        let mid = (ta.translation + tb.translation) / 2.0;
        mid_a += ta.apply_inverse(&mid);
        mid_b += tb.apply_inverse(&mid);
    }
    mid_a /= pairs.len() as f64;
    mid_b /= pairs.len() as f64;
    for (ta, tb) in &pairs {
        // Row block [Ra, -Rb] x = tb - ta.
        let ra = *ta.rotation.matrix();
        let rb = -*tb.rotation.matrix();
        let d = tb.translation - ta.translation;
        let blocks = [ra, rb];
        for (i, bi) in blocks.iter().enumerate() {
            for (j, bj) in blocks.iter().enumerate() {
                let block: Matrix3<f64> = bi.transpose() * bj;
                let mut view = normal.fixed_view_mut::<3, 3>(3 * i, 3 * j);
                view += block;
            }
            let r = bi.transpose() * d;
            let mut rows = rhs.fixed_rows_mut::<3>(3 * i);
            rows += r;
        }
    }
    // The pull: weight 1e-3 per frame, so a joint that rotates over the take is set by its
    // rotation, one that does not by the midpoint.
    let lambda = 1e-3 * pairs.len() as f64;
    for k in 0..3 {
        normal[(k, k)] += lambda;
        normal[(3 + k, 3 + k)] += lambda;
        rhs[k] += lambda * mid_a[k];
        rhs[3 + k] += lambda * mid_b[k];
    }
    let x = normal.cholesky()?.solve(&rhs);
    let a = Vec3::new(x[0], x[1], x[2]);
    let b = Vec3::new(x[3], x[4], x[5]);
    let sum2: f64 = pairs.iter().map(|(ta, tb)| (ta.apply(&a) - tb.apply(&b)).norm_squared()).sum();
    Some((a, b, (sum2 / pairs.len() as f64).sqrt()))
}

/// Joins the segments along a minimum spanning forest of their joint centres' misfit
/// (Prim's algorithm from the largest segment of each tree); parents come before children.
fn joint_tree(segments: &[Segment], poses: &[Vec<Option<RigidTransform>>]) -> Vec<Joint> {
    let n = segments.len();
    let mut centre = vec![None; n * n];
    for a in 0..n {
        for b in a + 1..n {
            if let Some((ca, cb, rms)) = joint_centre(&poses[a], &poses[b]) {
                // A centre far outside both segments joins segments that merely move little
                // against each other, not through a joint.
                let reach = |s: &Segment, c: &Vec3| s.local_mm.iter().map(|l| (l - c).norm()).fold(f64::MAX, f64::min);
                if rms <= MAX_JOINT_RMS_MM && reach(&segments[a], &ca) < 400.0 && reach(&segments[b], &cb) < 400.0 {
                    centre[a * n + b] = Some((ca, cb, rms));
                    centre[b * n + a] = Some((cb, ca, rms));
                }
            }
        }
    }
    let mut in_tree = vec![false; n];
    let mut joints = Vec::new();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&s| std::cmp::Reverse(segments[s].markers.len()));
    for &root in &order {
        if in_tree[root] {
            continue;
        }
        in_tree[root] = true;
        loop {
            let mut best: Option<(f64, usize, usize)> = None;
            for p in (0..n).filter(|&p| in_tree[p]) {
                for c in (0..n).filter(|&c| !in_tree[c]) {
                    if let Some((_, _, rms)) = centre[p * n + c]
                        && best.is_none_or(|(r, _, _)| rms < r)
                    {
                        best = Some((rms, p, c));
                    }
                }
            }
            let Some((rms, p, c)) = best else { break };
            in_tree[c] = true;
            let (pa, ca, _) = centre[p * n + c].expect("chosen above");
            // Three times the misfit, plus room for poses the template never showed.
            joints.push(Joint {
                parent: p,
                child: c,
                parent_mm: pa,
                child_mm: ca,
                tolerance_mm: 3.0 * rms + 15.0,
                hinge: learn_hinge(&poses[p], &poses[c]),
                twist: learn_twist(&segments[p], &segments[c], pa, ca, &poses[p], &poses[c]),
            });
        }
    }
    joints
}

/// A hinge is learned where the template bends a joint by at least this (degrees, between
/// the 5th and 95th percentile of its turn about the axis): below it every axis stays put and
/// the one found means nothing.
const MIN_HINGE_RANGE_DEG: f64 = 30.0;

/// ... and where, in 95% of the template's frames, the axis as placed by the child stays
/// within this of where the parent puts it (degrees). Knees and elbows stay within 10-20
/// (soft tissue, the knee's screw-home turn); a hip or shoulder that only flexes in the
/// template would pass too, and the hinge's cost only refuses an axis turned past a right
/// angle, which such a joint does not do either.
const MAX_HINGE_SPREAD_DEG: f64 = 25.0;

/// The hinge between two segments, from their poses over the template: the child-frame
/// vector `u` that the relative rotations `R_f = Rp_f^T Rc_f` map to the most constant
/// parent-frame vector (the top right singular vector of the mean of the `R_f`: `sum |R_f u
/// - mean|^2 = N (1 - |M u|^2)`), kept when the joint turns about it by at least
/// [`MIN_HINGE_RANGE_DEG`] and keeps it within [`MAX_HINGE_SPREAD_DEG`].
fn learn_hinge(parent: &[Option<RigidTransform>], child: &[Option<RigidTransform>]) -> Option<Hinge> {
    let relative: Vec<Matrix3<f64>> = parent
        .iter()
        .zip(child)
        .filter_map(|(p, c)| Some(*(p.as_ref()?.rotation.inverse() * c.as_ref()?.rotation).matrix()))
        .collect();
    if relative.len() < 10 {
        return None;
    }
    let mean = relative.iter().sum::<Matrix3<f64>>() / relative.len() as f64;
    let svd = mean.svd(true, true);
    let v_t = svd.v_t?;
    let top = (0..3).max_by(|&a, &b| svd.singular_values[a].total_cmp(&svd.singular_values[b]))?;
    let child_axis: Vec3 = v_t.row(top).transpose();
    let parent_axis = (mean * child_axis).try_normalize(1e-9)?;
    let percentile = |mut v: Vec<f64>, q: f64| {
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q).round() as usize]
    };
    let spread = relative.iter().map(|r| (r * child_axis).dot(&parent_axis).clamp(-1.0, 1.0).acos().to_degrees());
    if percentile(spread.collect(), 0.95) > MAX_HINGE_SPREAD_DEG {
        return None;
    }
    // The turn about the axis: a child-frame vector across it, seen in the parent's frame,
    // measured around the parent's axis from where the first frame puts it.
    let across = child_axis.cross(&if child_axis.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() }).normalize();
    let flat = |r: &Matrix3<f64>| {
        let w = r * across;
        w - parent_axis * w.dot(&parent_axis)
    };
    let reference = flat(&relative[0]);
    let angles: Vec<f64> = relative
        .iter()
        .map(|r| {
            let w = flat(r);
            parent_axis.dot(&reference.cross(&w)).atan2(reference.dot(&w)).to_degrees()
        })
        .collect();
    let range = percentile(angles.clone(), 0.95) - percentile(angles, 0.05);
    (range >= MIN_HINGE_RANGE_DEG).then_some(Hinge { parent_axis, child_axis })
}

/// A segment's bone direction is only defined where its markers sit at least this far from
/// the joint's centre (mm).
pub(crate) const MIN_TWIST_ARM_MM: f64 = 30.0;

/// The twist of each segment of a joint about its bone relative to the other, over the
/// template's frames (child first, then parent); `None` where a segment's markers sit on the
/// joint's centre or the two are seen together in too few frames.
fn learn_twist(
    parent: &Segment,
    child: &Segment,
    parent_mm: Vec3,
    child_mm: Vec3,
    parent_poses: &[Option<RigidTransform>],
    child_poses: &[Option<RigidTransform>],
) -> Option<[Twist; 2]> {
    let relative: Vec<nalgebra::Rotation3<f64>> = parent_poses
        .iter()
        .zip(child_poses)
        .filter_map(|(p, c)| Some(p.as_ref()?.rotation.inverse() * c.as_ref()?.rotation))
        .collect();
    if relative.len() < 10 {
        return None;
    }
    let axis = |seg: &Segment, centre: Vec3| {
        let centroid = seg.local_mm.iter().sum::<Vec3>() / seg.local_mm.len() as f64;
        (centroid - centre).try_normalize(MIN_TWIST_ARM_MM)
    };
    let range = |axis: Vec3, rotations: &mut dyn Iterator<Item = nalgebra::Rotation3<f64>>| {
        let angles: Vec<f64> = rotations.map(|r| Twist::angle(&axis, &r)).collect();
        let mean_rad = angles.iter().map(|a| a.sin()).sum::<f64>().atan2(angles.iter().map(|a| a.cos()).sum::<f64>());
        let mut off: Vec<f64> = angles.iter().map(|a| wrap_angle(a - mean_rad).abs()).collect();
        off.sort_by(f64::total_cmp);
        let half_width_rad = off[((off.len() - 1) as f64 * 0.95).round() as usize];
        Twist { axis, mean_rad, half_width_rad }
    };
    let child_twist = range(axis(child, child_mm)?, &mut relative.iter().copied());
    let parent_twist = range(axis(parent, parent_mm)?, &mut relative.iter().map(|r| r.inverse()));
    Some([child_twist, parent_twist])
}

/// Attaches marker `i` to the segment in whose frame it moves least.
fn attach(take: &Take, frames: &[usize], poses: &[Vec<Option<RigidTransform>>], i: usize) -> Option<Attached> {
    let mut best: Option<Attached> = None;
    for (s, per_frame) in poses.iter().enumerate() {
        let local: Vec<Vec3> = frames
            .iter()
            .zip(per_frame)
            .filter_map(|(&f, t)| Some(t.as_ref()?.apply_inverse(&take.position_mm(f, i)?)))
            .collect();
        if local.len() < 10 {
            continue;
        }
        let mean = local.iter().sum::<Vec3>() / local.len() as f64;
        let rms = (local.iter().map(|l| (l - mean).norm_squared()).sum::<f64>() / local.len() as f64).sqrt();
        let tolerance_mm = 3.0 * rms.hypot(NOISE_MM);
        if rms <= MAX_ATTACHED_RMS_MM && best.as_ref().is_none_or(|b| tolerance_mm < b.tolerance_mm) {
            best = Some(Attached { marker: i, segment: s, local_mm: mean, tolerance_mm });
        }
    }
    best
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use locap_core::MarkerName;
    use nalgebra::Rotation3;

    /// Two rigid 4-marker segments joined by a hinge at the origin of both, the second
    /// swinging through 90 degrees, and a fifth marker on the first one only loosely.
    pub(crate) fn hinge_take(frames: usize) -> Take {
        jointed_take(frames, |s| Rotation3::from_euler_angles(1.5 * s, 0.0, 0.0))
    }

    /// The hinge take's two segments with the second turned by `knee(s)`, `s` from 0 to 1
    /// over the take.
    fn jointed_take(frames: usize, knee: impl Fn(f64) -> Rotation3<f64>) -> Take {
        let upper = [[0.0, 0.0, 60.0], [80.0, 0.0, 200.0], [-50.0, 40.0, 320.0], [0.0, -60.0, 150.0]];
        let lower = [[0.0, 30.0, -80.0], [70.0, 0.0, -220.0], [-40.0, -50.0, -300.0], [20.0, 60.0, -150.0]];
        let names: Vec<MarkerName> = (0..9).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        let mut samples = Vec::new();
        for f in 0..frames {
            let s = f as f64 / frames as f64;
            let body = Rotation3::from_euler_angles(0.0, 0.0, 2.0 * s);
            let knee = knee(s);
            let origin = Vec3::new(500.0 * s, 0.0, 1000.0);
            for p in upper {
                samples.push(Some(origin + body * Vec3::from(p)));
            }
            for p in lower {
                samples.push(Some(origin + body * knee * Vec3::from(p)));
            }
            let wobble = Vec3::new(0.0, 30.0 * (f as f64 * 0.3).sin(), 0.0);
            samples.push(Some(origin + body * (Vec3::new(100.0, 100.0, 100.0) + wobble)));
        }
        Take::from_samples(names, &samples, 100.0).unwrap()
    }

    fn learn(take: &Take) -> Body {
        let m = take.marker_count();
        let ranked = locap_clean::neighbours::rank_scored(take, locap_clean::neighbours::Selection::Variance);
        let mut variance = vec![f64::INFINITY; m * m];
        for (i, list) in ranked.iter().enumerate() {
            for &(j, v) in list {
                variance[i * m + j] = v;
            }
        }
        Body::learn(take, &variance).unwrap()
    }

    #[test]
    fn finds_segments_joint_and_attached_marker() {
        let body = learn(&hinge_take(200));
        let mut groups: Vec<Vec<usize>> = body.segments.iter().map(|s| s.markers.clone()).collect();
        groups.sort();
        assert_eq!(groups, vec![vec![0, 1, 2, 3], vec![4, 5, 6, 7]]);
        assert_eq!(body.joints.len(), 1);
        let j = &body.joints[0];
        assert!(j.tolerance_mm < 20.0, "{j:?}");
        // The hinge sits at the shared origin: 0 in world, so the centres agree in frame 0.
        assert_eq!(body.attached.len(), 1);
        assert_eq!(body.attached[0].marker, 8);
        assert!(body.attached[0].tolerance_mm < 80.0);
        assert!(body.segments.iter().all(|s| s.tolerance_mm.iter().all(|&r| r < 10.0)));
    }

    #[test]
    fn a_joint_that_turns_about_one_axis_is_a_hinge() {
        let take = hinge_take(200);
        let body = learn(&take);
        let hinge = body.joints[0].hinge.expect("the knee turns about x only");
        let (p, c) = (body.joints[0].parent, body.joints[0].child);
        for f in (0..200).step_by(20) {
            let place = |s: usize| fit_segment(&take, f, &body.segments[s]).unwrap().0;
            let (tp, tc) = (place(p), place(c));
            // Both placements put the axis on the body's x axis, pointing the same way.
            let body_x = Rotation3::from_euler_angles(0.0, 0.0, 2.0 * f as f64 / 200.0) * Vec3::x();
            let (ap, ac) = (tp.rotation * hinge.parent_axis, tc.rotation * hinge.child_axis);
            assert!(ap.dot(&ac) > 0.999 && ap.dot(&body_x).abs() > 0.999, "frame {f}: {ap:?} {ac:?}");
            assert!(!hinge.reversed(&tp, &tc));
        }
        // A ball joint (turning about x and y) and a joint the take barely bends: no hinge.
        let ball = jointed_take(200, |s| Rotation3::from_euler_angles(1.5 * s, (9.0 * s).sin(), 0.0));
        assert_eq!(learn(&ball).joints[0].hinge, None);
        let still = jointed_take(200, |s| Rotation3::from_euler_angles(0.3 * s, 0.0, 0.0));
        assert_eq!(learn(&still).joints[0].hinge, None);
    }

    #[test]
    fn twist_is_the_turn_about_the_axis_alone() {
        let axis = Vec3::z();
        let turn = |deg: f64| Rotation3::from_axis_angle(&Vec3::z_axis(), deg.to_radians());
        let swing = Rotation3::from_axis_angle(&Vec3::x_axis(), 70f64.to_radians());
        for deg in [-170.0, -45.0, 0.0, 30.0, 120.0] {
            // Twist first (about the segment's own axis), then any swing off it.
            let angle = Twist::angle(&axis, &(swing * turn(deg))).to_degrees();
            assert!((angle - deg).abs() < 1e-6, "{deg}: {angle}");
        }
        assert!(Twist::angle(&axis, &swing).abs() < 1e-9);
        let seen = Twist { axis, mean_rad: 0.2, half_width_rad: 0.3 };
        assert_eq!(seen.excess_rad(&turn(20.0)), 0.0);
        // Half a turn on from what the template showed: a plate turned over.
        let over = seen.excess_rad(&(swing * turn(0.2f64.to_degrees() + 180.0)));
        assert!((over - (std::f64::consts::PI - 0.3)).abs() < 1e-6, "{over}");
    }

    #[test]
    fn a_joint_learns_how_far_it_twists_and_a_turned_over_plate_twists_further() {
        let take = hinge_take(200);
        let body = learn(&take);
        let joint = &body.joints[0];
        let [child, parent] = joint.twist.expect("both segments sit off the joint's centre");
        // The knee bends about x, roughly across both bones (from the joint, neither segment's
        // markers lie square to x): neither turns about its own length by more than ~15
        // degrees either way.
        assert!(child.half_width_rad < 0.25 && parent.half_width_rad < 0.25, "{child:?} {parent:?}");
        let place = |s: usize, f: usize| fit_segment(&take, f, &body.segments[s]).unwrap().0;
        let (tp, tc) = (place(joint.parent, 100), place(joint.child, 100));
        let relative = tp.rotation.inverse() * tc.rotation;
        assert!(child.excess_rad(&relative) < 1e-6 && parent.excess_rad(&relative.inverse()) < 1e-6);
        // The child turned over on its bone: half a turn about the child's own axis.
        let over =
            relative * Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(child.axis), std::f64::consts::PI);
        // Past the quarter turn the first fit allows beyond the template's twists, seen from
        // either bone.
        let (c, p) = (child.excess_rad(&over), parent.excess_rad(&over.inverse()));
        assert!(c > 2.0 && p > 2.0, "{c} {p}");
    }

    #[test]
    fn clustering_is_complete_linkage() {
        // 0-1 and 1-2 are rigid, 0-2 is not: no segment holds all three.
        let big = 1e4;
        let v = [0.0, 1.0, big, 1.0, 0.0, 1.0, big, 1.0, 0.0];
        let near = [0.0; 9];
        let groups = cluster(3, &v, 4.0, &near, 300.0);
        assert_eq!(groups.len(), 2);
        assert!(groups.iter().all(|g| g.len() <= 2));
        // Rigid but far apart: two segments held still against each other.
        let far = [0.0, 100.0, 500.0, 100.0, 0.0, 100.0, 500.0, 100.0, 0.0];
        let groups = cluster(3, &[0.0; 9], 4.0, &far, 300.0);
        assert_eq!(groups.len(), 2);
    }
}
