//! Benchmark input for labeling: a labeled take turned into what a capture system delivers
//! (labeling paper section 5: down-sampled CMU takes, random ghost markers).
//!
//! From a labeled take, with a seed:
//! - frames are picked at the target rate (the nearest frame to every `k / fps` second);
//! - with a [`GapModel`], extra samples go missing with real occlusion statistics (gap
//!   lengths count frames of the target rate);
//! - ghost points are added: `ghosts` of them in every frame, each living 0.1-1 s before a new
//!   one replaces it. The paper draws ghosts at the positions of the raw data's noise markers,
//!   or around them with N(0, 2 cm) noise; labeled takes have no noise markers left, so the
//!   body stands in for them: `Near` ghosts stand still where a random marker visible in that
//!   frame was when they appeared, offset by N(0, 20 mm) per axis (reflections close to the
//!   body; never at an occluded marker, which the cameras cannot see); `Riding` ghosts move
//!   with that marker at the same offset (split or doubled markers: the hardest case);
//!   `Random` ghosts stand still anywhere in the take's bounding box grown by 200 mm (stray
//!   reflections in the volume);
//! - every frame's points are shuffled, so the column a point arrives in means nothing.
//!
//! Unlabeled points already in the take (`*N`: real noise markers, as in HDM05) stay in as
//! ghosts, except where one sits within 1 mm of a labeled marker of the same frame: HDM05's
//! `*N` columns partly duplicate labeled markers, and a second point on the same spot can be
//! neither told apart nor scored. The truth (which marker each point is, or a ghost) is kept
//! beside the points.

use crate::gap_model::GapModel;
use locap_core::{MarkerName, Take, Vec3};
use locap_label::PointFrames;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

/// How ghost points are placed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum GhostMode {
    /// Standing still a couple of centimetres from where a marker was.
    #[default]
    Near,
    /// Moving with a marker, a couple of centimetres off (the hardest case).
    Riding,
    /// Standing still anywhere in the capture volume.
    Random,
}

/// Settings of [`unlabel`].
#[derive(Debug, Clone, PartialEq)]
pub struct UnlabelConfig {
    /// Target frame rate (Hz); `None` keeps the take's rate.
    pub frame_rate_hz: Option<f64>,
    /// Ghost points present in every frame.
    pub ghosts: usize,
    /// Where ghosts appear.
    pub ghost_mode: GhostMode,
    /// Extra missing samples with real occlusion statistics, if any.
    pub drop: Option<GapModel>,
    /// Seed of every random choice.
    pub seed: u64,
}

/// A take as unlabeled points plus the hidden truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Unlabeled {
    /// The point clouds.
    pub frames: PointFrames,
    /// For every point (in [`PointFrames`] order, frame after frame), the index of its marker
    /// in `markers`, or -1 for a ghost.
    pub truth: Vec<i32>,
    /// The labeled markers of the source take.
    pub markers: Vec<MarkerName>,
    /// For every output frame, the source frame it came from.
    pub source_frames: Vec<usize>,
}

/// The hidden truth of an unlabeled take, as `locap unlabel` writes it next to the C3D
/// file (`RAW.truth.json`): for every frame, the marker index of each point column (`*0`,
/// `*1`, ... in order), or -1 for a ghost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthFile {
    /// Format tag, `locap-unlabel-truth/1`.
    pub format: String,
    /// Full names of the labeled markers the indices refer to.
    pub markers: Vec<String>,
    /// For every output frame, the source take's frame it was taken from (0-based).
    pub source_frames: Vec<usize>,
    /// For every frame, the truth of its points in column order.
    pub frames: Vec<Vec<i32>>,
}

/// The format tag of [`TruthFile`].
pub const TRUTH_FORMAT: &str = "locap-unlabel-truth/1";

impl Unlabeled {
    /// The points as a take of unlabeled columns `*0`, `*1`, ...: frame `f`'s points fill
    /// columns `0..n_f` in their (shuffled) order; the rest are missing.
    pub fn to_take(&self) -> Take {
        let columns = self.frames.max_points();
        let names = (0..columns).map(|k| MarkerName::parse(&format!("*{k}"))).collect();
        // Cannot fail: the rate comes from a valid take.
        let mut take = Take::empty(names, self.frames.frame_count(), self.frames.frame_rate_hz()).expect("valid rate");
        for f in 0..self.frames.frame_count() {
            for (k, p) in self.frames.frame(f).iter().enumerate() {
                let _ = take.set_position_mm(f, k, Some(*p));
            }
        }
        take
    }

    /// The truth in its file form.
    pub fn truth_file(&self) -> TruthFile {
        TruthFile {
            format: TRUTH_FORMAT.to_string(),
            markers: self.markers.iter().map(|m| m.full()).collect(),
            source_frames: self.source_frames.clone(),
            frames: self.truth_by_frame().iter().map(|t| t.to_vec()).collect(),
        }
    }

    /// The truth of the points of frame `f`.
    pub fn frame_truth(&self, f: usize) -> &[i32] {
        let start: usize = (0..f).map(|g| self.frames.frame(g).len()).sum();
        &self.truth[start..start + self.frames.frame(f).len()]
    }

    /// Per frame, the truth of its points (faster than calling [`Unlabeled::frame_truth`]
    /// for every frame).
    pub fn truth_by_frame(&self) -> Vec<&[i32]> {
        let mut start = 0;
        (0..self.frames.frame_count())
            .map(|f| {
                let n = self.frames.frame(f).len();
                let slice = &self.truth[start..start + n];
                start += n;
                slice
            })
            .collect()
    }
}

/// Why a take cannot be unlabeled.
#[derive(Debug, thiserror::Error)]
pub enum UnlabelError {
    /// The target rate is not usable.
    #[error("target frame rate {0} Hz must be positive and at most the take's {1} Hz")]
    Rate(f64, f64),
    /// Nothing to unlabel.
    #[error("the take has no labeled markers or no frames")]
    Empty,
    /// More ghosts per frame than [`MAX_GHOSTS_PER_FRAME`].
    #[error("{0} ghosts per frame asked for (at most {MAX_GHOSTS_PER_FRAME})")]
    TooManyGhosts(usize),
}

/// Most ghosts per frame (1,000: 16 times the largest marker set here, 62; the paper's
/// hardest setting is as many ghosts as markers). Every ghost is a point of every frame, so
/// `bench label --ghosts 100000` grew each frame's assignment problem without bound.
pub const MAX_GHOSTS_PER_FRAME: usize = 1000;

/// A noise point this close to a labeled marker duplicates it.
const DUPLICATE_MM: f64 = 1.0;

struct Ghost {
    frames_left: usize,
    anchor: Option<usize>,
    offset_mm: Vec3,
    position_mm: Vec3,
}

/// Makes labeling benchmark input from a labeled take.
pub fn unlabel(take: &Take, config: &UnlabelConfig) -> Result<Unlabeled, UnlabelError> {
    if config.ghosts > MAX_GHOSTS_PER_FRAME {
        return Err(UnlabelError::TooManyGhosts(config.ghosts));
    }
    let source_rate = take.frame_rate_hz();
    let rate = config.frame_rate_hz.unwrap_or(source_rate);
    if !(rate > 0.0 && rate <= source_rate * (1.0 + 1e-9)) {
        return Err(UnlabelError::Rate(rate, source_rate));
    }
    let labeled: Vec<usize> = (0..take.marker_count()).filter(|&m| !take.markers()[m].is_unlabeled()).collect();
    let noise: Vec<usize> = (0..take.marker_count()).filter(|&m| take.markers()[m].is_unlabeled()).collect();
    if labeled.is_empty() || take.frame_count() == 0 {
        return Err(UnlabelError::Empty);
    }
    let step = source_rate / rate;
    let source_frames: Vec<usize> =
        (0..).map(|k| (k as f64 * step).round() as usize).take_while(|&f| f < take.frame_count()).collect();
    let mut rng = StdRng::seed_from_u64(config.seed);
    let t = source_frames.len();
    let m = labeled.len();
    let mut hidden = vec![false; t * m];
    if let Some(model) = &config.drop {
        let gaps = model.sample(t, m, |f, k| take.is_valid(source_frames[f], labeled[k]), &mut rng);
        for (k, marker_gaps) in gaps.iter().enumerate() {
            for gap in marker_gaps {
                for f in gap.start..gap.end() {
                    hidden[f * m + k] = true;
                }
            }
        }
    }
    let (low, high) = bounding_box(take);
    let lifetime = |rng: &mut StdRng| ((rate * rng.random_range(0.1..1.0)).round() as usize).max(1);
    let mut ghosts: Vec<Ghost> = Vec::with_capacity(config.ghosts);
    let mut frames = PointFrames::with_rate(rate);
    let mut truth = Vec::new();
    let mut cloud: Vec<(i32, Vec3)> = Vec::new();
    for (f, &source) in source_frames.iter().enumerate() {
        cloud.clear();
        for (k, &marker) in labeled.iter().enumerate() {
            if let (false, Some(p)) = (hidden[f * m + k], take.position_mm(source, marker)) {
                cloud.push((k as i32, p));
            }
        }
        let markers_in_frame = cloud.len();
        for &marker in &noise {
            if let Some(p) = take.position_mm(source, marker)
                && !cloud[..markers_in_frame].iter().any(|(_, q)| (p - q).norm() < DUPLICATE_MM)
            {
                cloud.push((-1, p));
            }
        }
        ghosts.retain(|g| g.frames_left > 0);
        while ghosts.len() < config.ghosts {
            let ghost = match config.ghost_mode {
                GhostMode::Near | GhostMode::Riding => {
                    // Next to a marker the cameras see in this frame: a reflection needs light
                    // and a line of sight, so none appears where a marker is occluded.
                    let seen = cloud[..markers_in_frame].len();
                    let anchor =
                        if seen > 0 { cloud[rng.random_range(0..seen)].0 as usize } else { rng.random_range(0..m) };
                    let offset_mm = Vec3::from_fn(|_, _| gaussian(&mut rng) * 20.0);
                    let position_mm = take.position_mm(source, labeled[anchor]).unwrap_or(low) + offset_mm;
                    let anchor = (config.ghost_mode == GhostMode::Riding).then_some(anchor);
                    Ghost { frames_left: lifetime(&mut rng), anchor, offset_mm, position_mm }
                }
                GhostMode::Random => {
                    let position_mm = Vec3::from_fn(|i, _| rng.random_range(low[i]..=high[i]));
                    Ghost { frames_left: lifetime(&mut rng), anchor: None, offset_mm: Vec3::zeros(), position_mm }
                }
            };
            ghosts.push(ghost);
        }
        for ghost in &mut ghosts {
            if let Some(anchor) = ghost.anchor
                && let Some(p) = take.position_mm(source, labeled[anchor])
            {
                ghost.position_mm = p + ghost.offset_mm;
            }
            ghost.frames_left -= 1;
            cloud.push((-1, ghost.position_mm));
        }
        cloud.shuffle(&mut rng);
        truth.extend(cloud.iter().map(|c| c.0));
        frames.push_frame(cloud.iter().enumerate().map(|(j, c)| (j as u32, c.1)));
    }
    Ok(Unlabeled {
        frames,
        truth,
        markers: labeled.iter().map(|&k| take.markers()[k].clone()).collect(),
        source_frames,
    })
}

/// Smallest and largest coordinates of all samples, grown by 200 mm.
fn bounding_box(take: &Take) -> (Vec3, Vec3) {
    let mut low = Vec3::repeat(f64::INFINITY);
    let mut high = Vec3::repeat(f64::NEG_INFINITY);
    for f in 0..take.frame_count() {
        for k in 0..take.marker_count() {
            if let Some(p) = take.position_mm(f, k) {
                low = low.inf(&p);
                high = high.sup(&p);
            }
        }
    }
    if !low.x.is_finite() {
        return (Vec3::zeros(), Vec3::repeat(1.0));
    }
    (low - Vec3::repeat(200.0), high + Vec3::repeat(200.0))
}

/// A standard normal draw (Box-Muller): the only distribution needed here, not worth a crate.
fn gaussian(rng: &mut StdRng) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn take() -> Take {
        let mut names: Vec<MarkerName> = (0..4).map(|i| MarkerName::parse(&format!("M{i}"))).collect();
        names.push(MarkerName::parse("*0"));
        let samples: Vec<Option<Vec3>> =
            (0..120).flat_map(|f| (0..5).map(move |m| Some(Vec3::new(m as f64 * 100.0, f as f64, 1000.0)))).collect();
        Take::from_samples(names, &samples, 120.0).unwrap()
    }

    #[test]
    fn keeps_truth_with_shuffled_points_ghosts_and_rate() {
        let config =
            UnlabelConfig { frame_rate_hz: Some(30.0), ghosts: 3, ghost_mode: GhostMode::Near, drop: None, seed: 7 };
        let u = unlabel(&take(), &config).unwrap();
        assert_eq!(u.frames.frame_count(), 30);
        assert_eq!(u.frames.frame_rate_hz(), 30.0);
        assert_eq!(u.markers.len(), 4);
        let by_frame = u.truth_by_frame();
        let mut shuffled = false;
        for (f, &truth) in by_frame.iter().enumerate() {
            assert_eq!(truth.len(), 4 + 1 + 3, "4 markers, the *0 noise point, 3 ghosts");
            assert_eq!(truth.iter().filter(|&&t| t < 0).count(), 4);
            for (p, &t) in u.frames.frame(f).iter().zip(truth) {
                if t >= 0 {
                    assert_eq!(*p, Vec3::new(t as f64 * 100.0, (4 * f) as f64, 1000.0));
                }
            }
            shuffled |= truth.iter().filter(|&&t| t >= 0).collect::<Vec<_>>().windows(2).any(|w| w[0] > w[1]);
        }
        assert!(shuffled);
        let written = u.to_take();
        assert_eq!(written.marker_count(), 8);
        let back = PointFrames::from_take(&written);
        for f in 0..30 {
            assert_eq!(back.frame(f), u.frames.frame(f), "column order is point order");
        }
        let truth = u.truth_file();
        assert_eq!(truth.frames.len(), 30);
        assert_eq!(truth.frames[5], u.frame_truth(5));
        assert_eq!(u.frame_truth(3), by_frame[3]);
        assert_eq!(unlabel(&take(), &config).unwrap(), u, "seeded");
    }

    #[test]
    fn random_ghosts_stay_in_the_volume_and_bad_rates_fail() {
        let config =
            UnlabelConfig { frame_rate_hz: None, ghosts: 5, ghost_mode: GhostMode::Random, drop: None, seed: 1 };
        let u = unlabel(&take(), &config).unwrap();
        for f in 0..u.frames.frame_count() {
            for p in u.frames.frame(f) {
                assert!(p.x >= -200.0 && p.x <= 600.0 && p.z >= 800.0 && p.z <= 1200.0);
            }
        }
        let bad = UnlabelConfig { frame_rate_hz: Some(240.0), ..config.clone() };
        assert!(matches!(unlabel(&take(), &bad), Err(UnlabelError::Rate(..))));
        let crowded = UnlabelConfig { ghosts: 100_000, ..config };
        assert!(matches!(unlabel(&take(), &crowded), Err(UnlabelError::TooManyGhosts(100_000))));
    }

    #[test]
    fn drops_samples_with_real_statistics() {
        let config = UnlabelConfig {
            frame_rate_hz: None,
            ghosts: 0,
            ghost_mode: GhostMode::Near,
            drop: Some(GapModel::uniform(0.2, 10)),
            seed: 3,
        };
        let u = unlabel(&take(), &config).unwrap();
        let markers = u.truth.iter().filter(|&&t| t >= 0).count();
        assert!(markers < 4 * 120 && markers > 4 * 120 / 2, "{markers}");
    }
}
