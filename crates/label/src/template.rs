//! The labeled template: which markers exist, one labeled reference frame, and each marker's
//! rigid edges (labeling paper section 3: "we connect two markers by an edge if they are
//! neighbors on the same limb and their relative position keeps fixed over time").
//!
//! Edges are the marker's most stable neighbours: the markers whose distance to it varies
//! least over the template take ([`locap_clean::neighbours`], the same ranking as the LocalMoCap
//! fill). A one-frame template has no variance to rank by; its edges go to the nearest
//! markers instead, which on a body are mostly on the same segment.

use crate::LabelError;
use crate::body::Body;
use locap_clean::neighbours::{Selection, rank_scored};
use locap_core::{MarkerName, Take, Vec3};

/// Default number of rigid edges per marker used for matching. Three to four markers ride on
/// most body segments; four edges keep the local-geometry cost meaningful when one neighbour
/// is occluded.
pub const DEFAULT_EDGES: usize = 4;

/// Ranked neighbours a template keeps per marker (matching uses the first few, missing-marker
/// estimation a few more).
pub const RANKED_NEIGHBOURS: usize = 8;

/// Templates shorter than this rank edges by distance, not by variance.
const MIN_FRAMES_FOR_VARIANCE: usize = 30;

/// A rigid edge from a marker to one of its stable neighbours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// Index of the neighbour marker.
    pub neighbour: usize,
    /// Mean length over the template (mm).
    pub length_mm: f64,
    /// Standard deviation of the length over the template (mm); 0 for one-frame templates.
    pub std_mm: f64,
}

/// A labeled marker set to label raw takes with.
#[derive(Debug, Clone, PartialEq)]
pub struct Template {
    names: Vec<MarkerName>,
    reference_mm: Vec<Option<Vec3>>,
    edges: Vec<Vec<Edge>>,
    body: Option<Body>,
    /// Built from a marker model, not a labeled take ([`crate::model`]).
    model: bool,
}

impl Template {
    /// Builds a template from the labeled markers of `take` (unlabeled `*N` columns are left
    /// out). `reference_frame` is the frame whose pose initialises labeling; by default the
    /// first frame in which at least 90% of the most markers ever visible together are. Each marker keeps its
    /// [`RANKED_NEIGHBOURS`] most stable neighbours.
    pub fn from_take(take: &Take, reference_frame: Option<usize>) -> Result<Template, LabelError> {
        let keep: Vec<usize> = (0..take.marker_count()).filter(|&m| !take.markers()[m].is_unlabeled()).collect();
        if keep.len() < 2 {
            return Err(LabelError::Template(format!(
                "the template has {} labeled markers; at least 2 are needed",
                keep.len()
            )));
        }
        if take.frame_count() == 0 {
            return Err(LabelError::Template("the template has no frames".into()));
        }
        let visible_in = |f: usize| keep.iter().filter(|&&m| take.is_valid(f, m)).count();
        let reference = match reference_frame {
            Some(f) if f >= take.frame_count() => {
                return Err(LabelError::Template(format!(
                    "reference frame {f} is outside the template's {} frames",
                    take.frame_count()
                )));
            }
            Some(f) => f,
            None => {
                // The first frame showing nearly all markers: templates (a T-pose, a labeled
                // take) start in their reference pose, and a frame much later would be a
                // different pose from the raw take's start.
                let most = (0..take.frame_count()).map(visible_in).max().unwrap_or(0);
                (0..take.frame_count()).find(|&f| visible_in(f) * 10 >= most * 9).unwrap_or(0)
            }
        };
        if visible_in(reference) < 3 {
            return Err(LabelError::Template(format!(
                "template frame {reference} shows {} labeled markers; at least 3 are needed",
                visible_in(reference)
            )));
        }
        let names: Vec<MarkerName> = keep.iter().map(|&m| take.markers()[m].clone()).collect();
        let samples: Vec<Option<Vec3>> =
            (0..take.frame_count()).flat_map(|f| keep.iter().map(move |&m| take.position_mm(f, m))).collect();
        // Cannot fail: same rate, shape built above.
        let labeled = Take::from_samples(names.clone(), &samples, take.frame_rate_hz())
            .map_err(|e| LabelError::Template(e.to_string()))?;
        let reference_mm: Vec<Option<Vec3>> = (0..keep.len()).map(|m| labeled.position_mm(reference, m)).collect();
        let (edges, body) = rigid_edges(&labeled, RANKED_NEIGHBOURS);
        Ok(Template { names, reference_mm, edges, body, model: false })
    }

    /// A template from its parts ([`crate::model`]).
    pub(crate) fn from_parts(
        names: Vec<MarkerName>,
        reference_mm: Vec<Option<Vec3>>,
        edges: Vec<Vec<Edge>>,
        body: Option<Body>,
        model: bool,
    ) -> Template {
        Template { names, reference_mm, edges, body, model }
    }

    /// True for a template built from a marker model ([`Template::from_model`]) rather than
    /// a labeled take: its distances are a generic model's, so a take is always labeled with
    /// it calibrated on the take ([`crate::subject::label_adapting`]).
    pub fn is_model(&self) -> bool {
        self.model
    }

    /// Marker names, in the order labels are reported.
    pub fn names(&self) -> &[MarkerName] {
        &self.names
    }

    /// Number of markers.
    pub fn marker_count(&self) -> usize {
        self.names.len()
    }

    /// The reference pose (mm), `None` where the marker was not visible.
    pub fn reference_mm(&self) -> &[Option<Vec3>] {
        &self.reference_mm
    }

    /// Rigid edges of every marker, most stable first.
    pub fn edges(&self) -> &[Vec<Edge>] {
        &self.edges
    }

    /// The articulated body the template take shows ([`crate::body`]): `None` for a
    /// template too short to tell rigid neighbours from the others, or without a rigid
    /// segment of three markers.
    pub fn body(&self) -> Option<&Body> {
        self.body.as_ref()
    }

    /// The template with its body replaced (another subject's first fit, [`crate::subject`]).
    pub(crate) fn with_body(&self, body: Body) -> Template {
        Template { body: Some(body), ..self.clone() }
    }
}

/// The `k` most stable neighbours of each marker with their mean distances, and the body
/// learned from the same distance statistics.
fn rigid_edges(take: &Take, k: usize) -> (Vec<Vec<Edge>>, Option<Body>) {
    let m = take.marker_count();
    let selection =
        if take.frame_count() >= MIN_FRAMES_FOR_VARIANCE { Selection::Variance } else { Selection::MeanDistance };
    let ranked = rank_scored(take, selection);
    let body = (selection == Selection::Variance).then(|| {
        let mut variance = vec![f64::INFINITY; m * m];
        for (i, list) in ranked.iter().enumerate() {
            for &(j, v) in list {
                variance[i * m + j] = v;
            }
        }
        Body::learn(take, &variance)
    });
    let edges = (0..m)
        .map(|i| {
            ranked[i]
                .iter()
                .filter_map(|&(j, variance)| {
                    // One-frame templates know nothing of variance: their edges count as rigid.
                    let std_mm = if selection == Selection::Variance { variance.sqrt() } else { 0.0 };
                    mean_distance(take, i, j).map(|length_mm| Edge { neighbour: j, length_mm, std_mm })
                })
                .take(k)
                .collect()
        })
        .collect();
    (edges, body.flatten())
}

/// Mean distance between markers `i` and `j` over the frames where both are visible.
fn mean_distance(take: &Take, i: usize, j: usize) -> Option<f64> {
    let (mut sum, mut n) = (0.0, 0usize);
    for f in 0..take.frame_count() {
        if let (Some(a), Some(b)) = (take.position_mm(f, i), take.position_mm(f, j)) {
            sum += (a - b).norm();
            n += 1;
        }
    }
    (n > 0).then(|| sum / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: usize) -> Vec<MarkerName> {
        (0..n).map(|i| MarkerName::parse(&format!("M{i}"))).collect()
    }

    #[test]
    fn edges_prefer_rigid_partners() {
        // Markers 0,1,2 on one rigid body moving as a whole; 3 moves on its own.
        let frames = 50;
        let mut samples = Vec::new();
        for f in 0..frames {
            let t = f as f64 * 0.1;
            let offset = Vec3::new(100.0 * t.sin(), 0.0, 0.0);
            samples.push(Some(Vec3::new(0.0, 0.0, 0.0) + offset));
            samples.push(Some(Vec3::new(50.0, 0.0, 0.0) + offset));
            samples.push(Some(Vec3::new(0.0, 80.0, 0.0) + offset));
            samples.push(Some(Vec3::new(30.0, 30.0, 300.0 * t.cos())));
        }
        let take = Take::from_samples(names(4), &samples, 100.0).unwrap();
        let template = Template::from_take(&take, None).unwrap();
        let of_0: Vec<usize> = template.edges()[0].iter().take(2).map(|e| e.neighbour).collect();
        assert_eq!(of_0.len(), 2);
        assert!(of_0.contains(&1) && of_0.contains(&2), "{of_0:?}");
        let edge = template.edges()[0].iter().find(|e| e.neighbour == 1).unwrap();
        assert!((edge.length_mm - 50.0).abs() < 1e-9 && edge.std_mm < 1e-6);
        assert!(template.edges()[0].iter().find(|e| e.neighbour == 3).unwrap().std_mm > 50.0);
    }

    #[test]
    fn unlabeled_columns_and_bad_templates() {
        let mut n = names(3);
        n.push(MarkerName::parse("*7"));
        let p = |x: f64| Some(Vec3::new(x, x * x, 1.0));
        let take = Take::from_samples(n, &[p(0.0), p(1.0), p(2.0), p(3.0)], 100.0).unwrap();
        let template = Template::from_take(&take, None).unwrap();
        assert_eq!(template.marker_count(), 3);
        assert_eq!(template.edges()[0].len(), 2);
        assert!(Template::from_take(&take, Some(5)).is_err());
        let two = Take::from_samples(names(2), &[p(0.0), p(1.0)], 100.0).unwrap();
        assert!(matches!(Template::from_take(&two, None), Err(LabelError::Template(_))));
    }
}
