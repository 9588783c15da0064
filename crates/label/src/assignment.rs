//! Gated assignment of markers to points with "missing" and "ghost" outcomes (labeling paper
//! Eq. 5: Hungarian algorithm on the soft matching costs, dummy rows and columns at cost
//! `w_max` so that `M != N` is allowed).
//!
//! Only candidate pairs (points inside a marker's gate) are ever scored, so the cost matrix is
//! sparse. Markers and points that share no candidates cannot influence each other, and the
//! optimal assignment of the whole frame is the union of the optimal assignments of the
//! connected components of the candidate graph. Most components hold one marker (its own
//! point, maybe a ghost): those are solved by a comparison; only crossing markers and nearby
//! ghosts build a small dense matrix for the Hungarian algorithm (`pathfinding`'s
//! Kuhn-Munkres). On 41 markers this turns an `O((M+N)^3)` frame into a few microseconds.
//!
//! Dummies: marker `i` may stay unassigned at cost `missing_cost[i]` (the paper's `w_max`);
//! a point left unassigned (a ghost) costs nothing, so a match is taken only when it is
//! cheaper than declaring the marker missing.

use pathfinding::kuhn_munkres::{Weights, kuhn_munkres};

/// Costs are turned into integers for the assignment (Kuhn-Munkres needs `Ord`): this many
/// units per mm^2 of cost keeps sub-micrometre resolution.
const COST_SCALE: f64 = 1000.0;
/// Weight of a forbidden pair: far below any real one, far from overflow when summed.
const FORBIDDEN: i64 = -(1 << 50);

/// Reusable buffers for assigning markers to points frame after frame without allocating
/// (once the buffers have grown to the largest frame).
#[derive(Debug, Default, Clone)]
pub struct GatedAssignment {
    // Candidates in compressed rows: those of marker i are start[i]..start[i + 1].
    start: Vec<usize>,
    point: Vec<u32>,
    cost: Vec<f64>,
    missing_cost: Vec<f64>,
    points: usize,
    // Union-find over markers (0..M) and points (M..M+N).
    parent: Vec<u32>,
    order: Vec<u32>,
    local_point: Vec<u32>,
    component_points: Vec<u32>,
    dense: Vec<i64>,
    result: Vec<Option<u32>>,
}

/// A dense block `rows x columns` of weights, borrowed from [`GatedAssignment`]'s buffer.
struct Block<'a> {
    rows: usize,
    columns: usize,
    weights: &'a [i64],
}

impl Weights<i64> for Block<'_> {
    fn rows(&self) -> usize {
        self.rows
    }
    fn columns(&self) -> usize {
        self.columns
    }
    fn at(&self, row: usize, col: usize) -> i64 {
        self.weights[row * self.columns + col]
    }
    fn neg(&self) -> Self {
        // kuhn_munkres (maximising) never negates; kuhn_munkres_min is not used here.
        unreachable!("Block weights are never negated")
    }
}

impl GatedAssignment {
    /// Starts a frame with `points` points; then add every marker in order with
    /// [`GatedAssignment::push_marker`] and its candidates with
    /// [`GatedAssignment::push_candidate`].
    pub fn begin(&mut self, points: usize) {
        self.start.clear();
        self.point.clear();
        self.cost.clear();
        self.missing_cost.clear();
        self.points = points;
    }

    /// Adds the next marker; leaving it unassigned costs `missing_cost`.
    pub fn push_marker(&mut self, missing_cost: f64) {
        self.start.push(self.point.len());
        self.missing_cost.push(missing_cost);
    }

    /// Adds a candidate point of the marker added last, at `cost` (finite, >= 0).
    pub fn push_candidate(&mut self, point: usize, cost: f64) {
        debug_assert!(point < self.points && !self.missing_cost.is_empty());
        self.point.push(point as u32);
        self.cost.push(cost);
    }

    fn candidates(&self, marker: usize) -> std::ops::Range<usize> {
        self.start[marker]..self.start[marker + 1]
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let up = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = up;
            x = up;
        }
        x
    }

    /// Solves the frame: for every marker the point it is assigned to, or `None` (missing).
    /// Each point is used at most once; the total cost is minimal.
    pub fn solve(&mut self) -> &[Option<u32>] {
        let markers = self.missing_cost.len();
        // Close the last marker's candidate row (`start` has one entry per marker so far).
        self.start.truncate(markers);
        self.start.push(self.point.len());
        let nodes = markers + self.points;
        self.parent.clear();
        self.parent.extend(0..nodes as u32);
        for marker in 0..markers {
            for c in self.candidates(marker) {
                let (a, b) = (self.find(marker as u32), self.find((markers + self.point[c] as usize) as u32));
                if a != b {
                    self.parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
        // Markers grouped by component, in marker order within a component.
        self.order.clear();
        self.order.extend(0..markers as u32);
        for marker in 0..markers {
            let root = self.find(marker as u32);
            self.parent[marker] = root;
        }
        let parent = &self.parent;
        self.order.sort_unstable_by_key(|&m| (parent[m as usize], m));

        self.result.clear();
        self.result.resize(markers, None);
        self.local_point.clear();
        self.local_point.resize(self.points, u32::MAX);
        let mut begin = 0;
        while begin < markers {
            let root = self.parent[self.order[begin] as usize];
            let mut end = begin + 1;
            while end < markers && self.parent[self.order[end] as usize] == root {
                end += 1;
            }
            if end - begin == 1 {
                self.solve_single(self.order[begin] as usize);
            } else {
                self.solve_block(begin, end);
            }
            begin = end;
        }
        &self.result
    }

    /// One marker alone in its component: its cheapest candidate, if cheaper than missing.
    fn solve_single(&mut self, marker: usize) {
        let mut best = (self.missing_cost[marker], None);
        for c in self.candidates(marker) {
            if self.cost[c] < best.0 {
                best = (self.cost[c], Some(self.point[c]));
            }
        }
        self.result[marker] = best.1;
    }

    /// Markers `order[begin..end]` compete for points: Hungarian algorithm on a dense block
    /// of `k` rows and `l + k` columns (the points, then one "missing" column per marker).
    fn solve_block(&mut self, begin: usize, end: usize) {
        let k = end - begin;
        self.component_points.clear();
        for r in begin..end {
            let marker = self.order[r] as usize;
            for c in self.candidates(marker) {
                let p = self.point[c] as usize;
                if self.local_point[p] == u32::MAX {
                    self.local_point[p] = self.component_points.len() as u32;
                    self.component_points.push(p as u32);
                }
            }
        }
        let l = self.component_points.len();
        let columns = l + k;
        self.dense.clear();
        self.dense.resize(k * columns, FORBIDDEN);
        for r in 0..k {
            let marker = self.order[begin + r] as usize;
            for c in self.candidates(marker) {
                let col = self.local_point[self.point[c] as usize] as usize;
                let weight = -to_units(self.cost[c]);
                // With duplicate candidates, keep the cheaper.
                let slot = &mut self.dense[r * columns + col];
                *slot = (*slot).max(weight);
            }
            self.dense[r * columns + l + r] = -to_units(self.missing_cost[marker]);
        }
        let block = Block { rows: k, columns, weights: &self.dense };
        let (_, columns_of_rows) = kuhn_munkres(&block);
        for (r, &col) in columns_of_rows.iter().enumerate() {
            let marker = self.order[begin + r] as usize;
            self.result[marker] = (col < l).then(|| self.component_points[col]);
        }
        for &p in &self.component_points {
            self.local_point[p as usize] = u32::MAX;
        }
    }
}

fn to_units(cost: f64) -> i64 {
    // Costs above 1e12 mm^2 mean "never": clamp so the sum of a block cannot overflow.
    (cost.clamp(0.0, 1.0e12) * COST_SCALE).round() as i64
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn solve(points: usize, markers: &[(f64, &[(usize, f64)])]) -> Vec<Option<u32>> {
        let mut a = GatedAssignment::default();
        a.begin(points);
        for (missing, candidates) in markers {
            a.push_marker(*missing);
            for &(p, c) in *candidates {
                a.push_candidate(p, c);
            }
        }
        a.solve().to_vec()
    }

    #[test]
    fn more_points_than_markers_leaves_ghosts_unassigned() {
        // Two markers, four points: points 1 and 3 are ghosts.
        let got = solve(4, &[(100.0, &[(0, 1.0), (1, 5.0)]), (100.0, &[(2, 2.0), (3, 3.0)])]);
        assert_eq!(got, vec![Some(0), Some(2)]);
    }

    #[test]
    fn fewer_points_than_markers_leaves_markers_missing() {
        // Both markers want point 0; marker 1 is cheaper to declare missing.
        let got = solve(1, &[(100.0, &[(0, 1.0)]), (10.0, &[(0, 2.0)])]);
        assert_eq!(got, vec![Some(0), None]);
        let got = solve(1, &[(100.0, &[(0, 50.0)]), (100.0, &[(0, 2.0)])]);
        assert_eq!(got, vec![None, Some(0)]);
    }

    #[test]
    fn a_match_dearer_than_missing_is_refused() {
        assert_eq!(solve(1, &[(10.0, &[(0, 11.0)])]), vec![None]);
        assert_eq!(solve(0, &[(10.0, &[])]), vec![None]);
    }

    #[test]
    fn crossing_markers_take_the_globally_cheapest_pairing() {
        // Greedy would give marker 0 point 0 (cost 1) and marker 1 point 1 (cost 100);
        // the optimum is the cross (2 + 3).
        let got = solve(2, &[(1000.0, &[(0, 1.0), (1, 2.0)]), (1000.0, &[(0, 3.0), (1, 100.0)])]);
        assert_eq!(got, vec![Some(1), Some(0)]);
    }

    /// Exhaustive search of the optimum, for small problems.
    fn brute_force(points: usize, markers: &[(f64, Vec<(usize, f64)>)]) -> f64 {
        fn go(i: usize, used: &mut Vec<bool>, markers: &[(f64, Vec<(usize, f64)>)]) -> f64 {
            if i == markers.len() {
                return 0.0;
            }
            let mut best = markers[i].0 + go(i + 1, used, markers);
            for &(p, c) in &markers[i].1 {
                if !used[p] {
                    used[p] = true;
                    best = best.min(c + go(i + 1, used, markers));
                    used[p] = false;
                }
            }
            best
        }
        go(0, &mut vec![false; points], markers)
    }

    proptest! {
        #[test]
        fn optimal_and_consistent(
            points in 1usize..6,
            raw in proptest::collection::vec(
                (1.0f64..50.0, proptest::collection::vec((0usize..6, 0.0f64..60.0), 0..4)), 1..6),
        ) {
            let markers: Vec<(f64, Vec<(usize, f64)>)> = raw
                .into_iter()
                .map(|(miss, cands)| {
                    let mut seen = Vec::new();
                    let cands = cands
                        .into_iter()
                        .map(|(p, c)| (p % points, c))
                        .filter(|(p, _)| if seen.contains(p) { false } else { seen.push(*p); true })
                        .collect();
                    (miss, cands)
                })
                .collect();
            let mut a = GatedAssignment::default();
            a.begin(points);
            for (miss, cands) in &markers {
                a.push_marker(*miss);
                for &(p, c) in cands {
                    a.push_candidate(p, c);
                }
            }
            let got = a.solve().to_vec();
            let mut used = vec![false; points];
            let mut total = 0.0;
            for (i, g) in got.iter().enumerate() {
                match g {
                    Some(p) => {
                        prop_assert!(!used[*p as usize], "point used twice");
                        used[*p as usize] = true;
                        let c = markers[i].1.iter().find(|(q, _)| *q == *p as usize);
                        prop_assert!(c.is_some(), "assigned a non-candidate");
                        total += c.unwrap().1;
                    }
                    None => total += markers[i].0,
                }
            }
            let best = brute_force(points, &markers);
            prop_assert!((total - best).abs() < 1e-2, "total {total} vs optimum {best}");
        }
    }
}
