//! Unlabeled input: per frame, an unordered set of 3D points.
//!
//! A capture system hands the labeler a point cloud every frame; which column of a C3D file a
//! point sits in means nothing (raw files name them `*0`, `*1`, ... and reuse columns freely).
//! [`PointFrames`] stores the clouds of a whole take compactly (one flat buffer plus frame
//! offsets) so the per-frame loop never allocates.

use crate::LabelError;
use locap_core::{Take, Vec3};

/// Most points a take may hand the labeler (100 million: 76 points a frame for 1.5 hours at
/// 240 Hz; 2.8 GB of clouds). Labels use the same ceiling for frames x template markers.
pub const MAX_POINTS: usize = 100_000_000;
/// Most frames a take may hand the labeler (10 million: 11.5 hours at 240 Hz).
pub const MAX_FRAMES: usize = 10_000_000;

/// The point clouds of a take, frame after frame, in millimetres.
#[derive(Debug, Clone, PartialEq)]
pub struct PointFrames {
    points_mm: Vec<Vec3>,
    /// Where each point came from in the source take (its column), for writing results back.
    columns: Vec<u32>,
    /// `offsets[f]..offsets[f + 1]` are the points of frame `f`.
    offsets: Vec<usize>,
    frame_rate_hz: f64,
}

impl PointFrames {
    /// Every valid sample of every column of `take` becomes a point of its frame, whatever
    /// the column's name: labels in the input are ignored on purpose.
    ///
    /// The points are counted first and checked against [`MAX_POINTS`] and [`MAX_FRAMES`],
    /// then reserved exactly (no doubling growth), and an allocation the system refuses is an
    /// error too, not an abort.
    ///
    /// # Errors
    /// [`LabelError::TooLarge`] for a take beyond the ceilings or one memory cannot hold.
    pub fn try_from_take(take: &Take) -> Result<PointFrames, LabelError> {
        let (t, m) = (take.frame_count(), take.marker_count());
        if t > MAX_FRAMES {
            return Err(LabelError::TooLarge(format!("{t} frames (the labeler takes at most {MAX_FRAMES})")));
        }
        let n = (0..t).map(|f| (0..m).filter(|&k| take.is_valid(f, k)).count()).sum::<usize>();
        if n > MAX_POINTS {
            return Err(LabelError::TooLarge(format!("{n} points (the labeler takes at most {MAX_POINTS})")));
        }
        let mut frames = PointFrames::with_rate(take.frame_rate_hz());
        let refused = |e: std::collections::TryReserveError| LabelError::TooLarge(format!("{n} points: {e}"));
        frames.points_mm.try_reserve_exact(n).map_err(refused)?;
        frames.columns.try_reserve_exact(n).map_err(refused)?;
        frames.offsets.try_reserve_exact(t).map_err(refused)?;
        frames.fill_from(take);
        Ok(frames)
    }

    /// [`PointFrames::try_from_take`] for takes known to be of a sane size (tests, takes built
    /// in memory): it reserves exactly too, but checks no ceiling.
    pub fn from_take(take: &Take) -> PointFrames {
        let mut frames = PointFrames::with_rate(take.frame_rate_hz());
        let n = (0..take.frame_count()).map(|f| (0..take.marker_count()).filter(|&k| take.is_valid(f, k)).count());
        let n = n.sum::<usize>();
        frames.points_mm.reserve_exact(n);
        frames.columns.reserve_exact(n);
        frames.offsets.reserve_exact(take.frame_count());
        frames.fill_from(take);
        frames
    }

    fn fill_from(&mut self, take: &Take) {
        let frames = self;
        for f in 0..take.frame_count() {
            for m in 0..take.marker_count() {
                if let Some(p) = take.position_mm(f, m) {
                    frames.points_mm.push(p);
                    frames.columns.push(m as u32);
                }
            }
            frames.offsets.push(frames.points_mm.len());
        }
    }

    /// An empty sequence at `frame_rate_hz`; add frames with [`PointFrames::push_frame`].
    pub fn with_rate(frame_rate_hz: f64) -> PointFrames {
        PointFrames { points_mm: Vec::new(), columns: Vec::new(), offsets: vec![0], frame_rate_hz }
    }

    /// Appends one frame; `points` are `(column, position_mm)` pairs.
    pub fn push_frame(&mut self, points: impl IntoIterator<Item = (u32, Vec3)>) {
        for (column, p) in points {
            self.columns.push(column);
            self.points_mm.push(p);
        }
        self.offsets.push(self.points_mm.len());
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Frames per second.
    pub fn frame_rate_hz(&self) -> f64 {
        self.frame_rate_hz
    }

    /// The points of frame `f`, in millimetres.
    pub fn frame(&self, f: usize) -> &[Vec3] {
        &self.points_mm[self.offsets[f]..self.offsets[f + 1]]
    }

    /// The source columns of the points of frame `f` (same order as [`PointFrames::frame`]).
    pub fn columns(&self, f: usize) -> &[u32] {
        &self.columns[self.offsets[f]..self.offsets[f + 1]]
    }

    /// Most points in any one frame.
    pub fn max_points(&self) -> usize {
        self.offsets.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0)
    }

    /// Frames `range` as a sequence of their own (a segment of a take).
    pub fn slice_frames(&self, range: std::ops::Range<usize>) -> PointFrames {
        let mut part = PointFrames::with_rate(self.frame_rate_hz);
        for f in range {
            part.push_frame(self.columns(f).iter().copied().zip(self.frame(f).iter().copied()));
        }
        part
    }

    /// Frames `range` in reverse order, for labeling backwards in time from a frame later
    /// than the first (the first fit may only be sure there).
    pub fn reversed(&self, range: std::ops::Range<usize>) -> PointFrames {
        let mut part = PointFrames::with_rate(self.frame_rate_hz);
        for f in range.rev() {
            part.push_frame(self.columns(f).iter().copied().zip(self.frame(f).iter().copied()));
        }
        part
    }

    /// Total number of points over all frames.
    pub fn point_count(&self) -> usize {
        self.points_mm.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;

    #[test]
    fn keeps_valid_samples_in_column_order() {
        let names = vec![MarkerName::parse("*0"), MarkerName::parse("*1")];
        let samples = [Some(Vec3::new(1.0, 0.0, 0.0)), None, None, Some(Vec3::new(0.0, 2.0, 0.0))];
        let take = Take::from_samples(names, &samples, 100.0).unwrap();
        let frames = PointFrames::from_take(&take);
        assert_eq!(frames.frame_count(), 2);
        assert_eq!(frames.frame(0), &[Vec3::new(1.0, 0.0, 0.0)]);
        assert_eq!(frames.columns(1), &[1]);
        assert_eq!(frames.max_points(), 1);
        assert_eq!(frames.point_count(), 2);
        assert_eq!(PointFrames::try_from_take(&take).unwrap(), frames);
        let second = frames.slice_frames(1..2);
        assert_eq!((second.frame_count(), second.frame(0), second.columns(0)), (1, frames.frame(1), &[1u32][..]));
        let back = frames.reversed(0..2);
        assert_eq!((back.frame(0), back.frame(1)), (frames.frame(1), frames.frame(0)));
    }

    /// A take beyond the frame ceiling is an error before anything is counted or reserved.
    #[test]
    fn too_many_frames_is_an_error() {
        let take = Take::empty(vec![], MAX_FRAMES + 1, 100.0).unwrap();
        let e = PointFrames::try_from_take(&take).unwrap_err();
        assert!(matches!(&e, LabelError::TooLarge(s) if s.starts_with("10000001 frames")), "{e}");
    }
}
