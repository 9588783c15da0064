//! Re-acquisition: a body segment whose markers were lost, or whose labels break its rigid
//! shape, for longer than a moment is fitted again with the first fit ([`crate::pose_fit`]),
//! the healthy segments held where their labels put them (anchors) and their points taken.
//! Only the segment's unlabeled markers take points, and only points no marker holds. After
//! a total loss nothing is healthy and the fit is the whole-body first fit again. So a
//! stretch of occlusion or a wrong start of one limb does not spoil the rest of the take
//! (the labeling paper leaves this open: its labeler never re-initialises).
//!
//! A segment is *healthy* in a frame when at least three of its markers are labeled (all of
//! them for a smaller one) and every pair of them keeps its distance in the template's shape
//! within the two markers' tolerances. An unhealthy segment is re-fitted after
//! [`REACQUIRE_AFTER_S`]; a fit that finds nothing sure waits twice as long before the next
//! try (up to [`MAX_WAIT_S`]), so a limb hidden for seconds costs a handful of fits, and
//! tracking keeps its speed.

use crate::body::Body;
use crate::pose_fit::fit_pose;
use locap_clean::procrustes::{RigidTransform, align};
use locap_core::Vec3;

/// A segment unhealthy this long (s) is fitted again.
pub const REACQUIRE_AFTER_S: f64 = 0.1;

/// Longest wait between two fits of a segment that stays unhealthy (s).
pub const MAX_WAIT_S: f64 = 2.0;

/// Per-segment health over the frames, and the re-fits it calls for.
#[derive(Debug, Clone)]
pub struct Reacquirer<'a> {
    body: &'a Body,
    markers: usize,
    first_wait: usize,
    max_wait: usize,
    /// Frames each segment has been unhealthy.
    unhealthy: Vec<usize>,
    /// The unhealthy count at which each segment is fitted next.
    next_try: Vec<usize>,
    /// Re-fits made, and those that changed labels.
    tries: usize,
    successes: usize,
}

impl<'a> Reacquirer<'a> {
    /// Watches `body` (of a template of `markers` markers) at `frame_rate_hz`.
    pub fn new(body: &'a Body, markers: usize, frame_rate_hz: f64) -> Reacquirer<'a> {
        let frames = |s: f64| ((s * frame_rate_hz).round() as usize).max(2);
        let n = body.segments.len();
        Reacquirer {
            body,
            markers,
            first_wait: frames(REACQUIRE_AFTER_S),
            max_wait: frames(MAX_WAIT_S),
            unhealthy: vec![0; n],
            next_try: vec![frames(REACQUIRE_AFTER_S); n],
            tries: 0,
            successes: 0,
        }
    }

    /// Re-fits made so far, and how many of them changed labels.
    pub fn tries(&self) -> (usize, usize) {
        (self.tries, self.successes)
    }

    /// After a frame was labeled (`labels`: each marker's point in `points`), the labels to
    /// change: `(marker, point)` pairs for [`crate::Labeler::relabel`]; usually none.
    pub fn check(&mut self, points: &[Vec3], labels: &[Option<u32>]) -> Vec<(usize, usize)> {
        let mut due = false;
        for s in 0..self.body.segments.len() {
            if self.healthy(s, points, labels) {
                self.unhealthy[s] = 0;
                self.next_try[s] = self.first_wait;
            } else {
                self.unhealthy[s] += 1;
                due |= self.unhealthy[s] >= self.next_try[s];
            }
        }
        if !due {
            return Vec::new();
        }
        self.refit(points, labels)
    }

    fn healthy(&self, s: usize, points: &[Vec3], labels: &[Option<u32>]) -> bool {
        let seg = &self.body.segments[s];
        let mut labeled = 0;
        for (a, &i) in seg.markers.iter().enumerate() {
            let Some(p) = labels[i] else { continue };
            labeled += 1;
            for (b, &j) in seg.markers.iter().enumerate().skip(a + 1) {
                if let Some(q) = labels[j] {
                    let d = (points[p as usize] - points[q as usize]).norm();
                    let shape = (seg.local_mm[a] - seg.local_mm[b]).norm();
                    if (d - shape).abs() > seg.tolerance_mm[a] + seg.tolerance_mm[b] {
                        return false;
                    }
                }
            }
        }
        labeled >= seg.markers.len().min(3)
    }

    /// Fits the unhealthy segments with the healthy ones as anchors.
    fn refit(&mut self, points: &[Vec3], labels: &[Option<u32>]) -> Vec<(usize, usize)> {
        self.tries += 1;
        let body = self.body;
        let n = body.segments.len();
        let refitting: Vec<bool> = (0..n).map(|s| self.unhealthy[s] > 0).collect();
        // Markers whose labels the fit may replace: those of refitted segments and the ones
        // attached to them.
        let mut open = vec![false; self.markers];
        for (_, seg) in body.segments.iter().enumerate().filter(|(s, _)| refitting[*s]) {
            for &i in &seg.markers {
                open[i] = true;
            }
        }
        for a in body.attached.iter().filter(|a| refitting[a.segment]) {
            open[a.marker] = true;
        }
        let mut taken = vec![false; points.len()];
        for (i, l) in labels.iter().enumerate() {
            if let Some(p) = l
                && !open[i]
            {
                taken[*p as usize] = true;
            }
        }
        let anchors: Vec<Option<RigidTransform>> = (0..n)
            .map(|s| {
                if refitting[s] {
                    return None;
                }
                let seg = &body.segments[s];
                let (from, to): (Vec<Vec3>, Vec<Vec3>) = seg
                    .markers
                    .iter()
                    .zip(&seg.local_mm)
                    .filter_map(|(&i, l)| Some((*l, points[labels[i]? as usize])))
                    .unzip();
                align(&from, &to)
            })
            .collect();
        let fit = fit_pose(body, self.markers, points, &taken, &anchors);
        let mut changes = Vec::new();
        for (s, &refitted) in refitting.iter().enumerate() {
            if !refitted || self.unhealthy[s] < self.next_try[s] {
                continue;
            }
            match fit.poses[s] {
                Some(_) => {
                    let seg = &body.segments[s];
                    let attached = body.attached.iter().filter(|a| a.segment == s).map(|a| a.marker);
                    // Only markers left unlabeled take points nobody holds: a label tracking
                    // kept is not overridden (with ghosts beside the markers, a re-fit can be
                    // sure and still off by a ghost), and a bad one is dropped by the
                    // labeler's own edge check.
                    for i in seg.markers.iter().copied().chain(attached) {
                        if let Some(p) = fit.assignment[i]
                            && labels[i].is_none()
                            && !labels.contains(&Some(p as u32))
                        {
                            changes.push((i, p));
                        }
                    }
                    self.unhealthy[s] = 0;
                    self.next_try[s] = self.first_wait;
                }
                None => {
                    // Wait twice as long as the last time before trying again.
                    let waited = self.next_try[s];
                    self.next_try[s] = self.unhealthy[s] + waited.min(self.max_wait);
                }
            }
        }
        if !changes.is_empty() {
            self.successes += 1;
        }
        changes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::body::tests::hinge_take;
    use crate::template::Template;

    #[test]
    fn a_lost_segment_is_found_again_and_a_hidden_one_waits() {
        let take = hinge_take(200);
        let template = Template::from_take(&take, None).unwrap();
        let body = template.body().unwrap();
        let m = template.marker_count();
        // Frame 150's points in marker order, with a ghost.
        let mut points: Vec<Vec3> = (0..m).map(|i| take.position_mm(150, i).unwrap()).collect();
        points.push(points[5] + Vec3::new(30.0, 0.0, 0.0));
        // The upper segment and the loose marker are labeled; the lower one is lost.
        let labels: Vec<Option<u32>> = (0..m).map(|i| (!(4..8).contains(&i)).then_some(i as u32)).collect();
        let mut r = Reacquirer::new(body, m, 100.0);
        let after = (REACQUIRE_AFTER_S * 100.0).round() as usize;
        for _ in 1..after {
            assert!(r.check(&points, &labels).is_empty());
        }
        let mut changes = r.check(&points, &labels);
        changes.sort_unstable();
        assert_eq!(changes, vec![(4, 4), (5, 5), (6, 6), (7, 7)]);
        assert_eq!(r.tries(), (1, 1));

        // Hidden: only the upper segment's points. The fit finds nothing, and waits longer
        // each time.
        let hidden: Vec<Vec3> = points[..4].to_vec();
        let labels: Vec<Option<u32>> = (0..m).map(|i| (i < 4).then_some(i as u32)).collect();
        let mut r = Reacquirer::new(body, m, 100.0);
        for _ in 0..100 {
            assert!(r.check(&hidden, &labels).is_empty());
        }
        let (tries, found) = r.tries();
        assert_eq!(found, 0);
        assert!((2..=4).contains(&tries), "{tries} fits in 100 frames");
    }
}
