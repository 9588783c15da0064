//! A marker take: `T` frames of `M` named markers with explicit missing samples.

use crate::{MarkerName, UpAxis, Vec3};
use serde::{Deserialize, Serialize};

/// Errors from building or editing a [`Take`].
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TakeError {
    /// The arrays given do not have `frames x markers` elements.
    #[error("take has {frames} frames x {markers} markers = {expected} samples, but {what} has {found}")]
    ShapeMismatch {
        /// Number of frames.
        frames: usize,
        /// Number of markers.
        markers: usize,
        /// `frames * markers`.
        expected: usize,
        /// Which array was wrong.
        what: &'static str,
        /// Its actual length.
        found: usize,
    },
    /// A valid sample has a non-finite coordinate.
    #[error("sample of marker {marker} at frame {frame} is marked valid but is not finite")]
    NonFinite {
        /// Frame index (0-based).
        frame: usize,
        /// Marker index.
        marker: usize,
    },
    /// The frame rate is not a positive finite number.
    #[error("frame rate {0} Hz is not a positive number")]
    BadFrameRate(f64),
}

/// Per-sample quality as recorded by the capture system, kept so that writers can give it back.
///
/// C3D stores, for each valid sample, a residual (how well the camera rays agreed, in the
/// point unit) and which cameras saw it. locap sets `residual_mm = 0` and `cameras = 0` for
/// samples it computed itself (C3D's own convention for "interpolated").
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SampleQuality {
    /// Reconstruction residual in millimetres (0 = computed / unknown).
    pub residual_mm: f32,
    /// Bit mask of the cameras that saw the marker (bit 0 = camera 1), 0 if unknown.
    pub cameras: u8,
}

/// A marker take.
///
/// Positions are stored frame-major (`frame * markers + marker`) in millimetres. A sample is
/// either valid (finite position) or missing; accessors return `Option` so missing samples
/// cannot enter arithmetic.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Take {
    markers: Vec<MarkerName>,
    /// Kept explicitly: a take with no markers (an analog-only C3D file) still has frames.
    frames: usize,
    positions_mm: Vec<Vec3>,
    valid: Vec<bool>,
    quality: Vec<SampleQuality>,
    frame_rate_hz: f64,
    /// Number of the first frame as the capture system counted it (C3D header word 4, 1-based
    /// in most files). Kept so written files line up with the original.
    pub first_frame: u32,
    /// Which axis of the lab is vertical.
    pub up_axis: UpAxis,
}

impl Take {
    /// A take with `frames` frames in which every sample is missing.
    pub fn empty(markers: Vec<MarkerName>, frames: usize, frame_rate_hz: f64) -> Result<Take, TakeError> {
        check_rate(frame_rate_hz)?;
        let n = frames * markers.len();
        Ok(Take {
            markers,
            frames,
            positions_mm: vec![Vec3::zeros(); n],
            valid: vec![false; n],
            quality: vec![SampleQuality::default(); n],
            frame_rate_hz,
            first_frame: 1,
            up_axis: UpAxis::Z,
        })
    }

    /// Builds a take from frame-major samples: `samples[frame * markers + marker]` is `None`
    /// where the marker is missing.
    pub fn from_samples(
        markers: Vec<MarkerName>,
        samples: &[Option<Vec3>],
        frame_rate_hz: f64,
    ) -> Result<Take, TakeError> {
        check_rate(frame_rate_hz)?;
        let m = markers.len();
        let frames = samples.len().checked_div(m).unwrap_or(0);
        if frames * m != samples.len() {
            return Err(TakeError::ShapeMismatch {
                frames,
                markers: m,
                expected: frames * m,
                what: "samples",
                found: samples.len(),
            });
        }
        let mut take = Take::empty(markers, frames, frame_rate_hz)?;
        for (i, sample) in samples.iter().enumerate() {
            if let Some(p) = sample {
                take.set_position_mm(i / m, i % m, Some(*p))?;
            }
        }
        Ok(take)
    }

    /// Number of frames `T`.
    #[inline]
    pub fn frame_count(&self) -> usize {
        self.frames
    }

    /// Number of markers `M`.
    #[inline]
    pub fn marker_count(&self) -> usize {
        self.markers.len()
    }

    /// The marker names, in storage order.
    #[inline]
    pub fn markers(&self) -> &[MarkerName] {
        &self.markers
    }

    /// Renames markers (for example after labeling). The count must stay the same.
    pub fn set_markers(&mut self, markers: Vec<MarkerName>) -> Result<(), TakeError> {
        if markers.len() != self.markers.len() {
            return Err(TakeError::ShapeMismatch {
                frames: self.frame_count(),
                markers: self.markers.len(),
                expected: self.markers.len(),
                what: "new marker list",
                found: markers.len(),
            });
        }
        self.markers = markers;
        Ok(())
    }

    /// Index of the marker whose label (subject prefix ignored) is `label`.
    pub fn marker_index(&self, label: &str) -> Option<usize> {
        self.markers.iter().position(|m| m.label == label)
    }

    /// Frame rate in Hz.
    pub fn frame_rate_hz(&self) -> f64 {
        self.frame_rate_hz
    }

    /// Changes the frame rate (the samples are not resampled).
    pub fn set_frame_rate_hz(&mut self, hz: f64) -> Result<(), TakeError> {
        check_rate(hz)?;
        self.frame_rate_hz = hz;
        Ok(())
    }

    /// Duration covered by the take in seconds (`T / rate`).
    pub fn duration_s(&self) -> f64 {
        self.frame_count() as f64 / self.frame_rate_hz
    }

    /// Position of `marker` at `frame` in millimetres, `None` if missing.
    ///
    /// # Panics
    /// If `frame` or `marker` is out of range (a programming error, not bad data).
    #[inline]
    pub fn position_mm(&self, frame: usize, marker: usize) -> Option<Vec3> {
        let i = self.index(frame, marker);
        self.valid[i].then(|| self.positions_mm[i])
    }

    /// True if and only if `marker` is present at `frame`.
    #[inline]
    pub fn is_valid(&self, frame: usize, marker: usize) -> bool {
        self.valid[self.index(frame, marker)]
    }

    /// Sets (or, with `None`, removes) a sample. A non-finite position is rejected. The
    /// sample's quality is reset to "computed" (`residual 0`, no cameras).
    pub fn set_position_mm(&mut self, frame: usize, marker: usize, position: Option<Vec3>) -> Result<(), TakeError> {
        let i = self.index(frame, marker);
        match position {
            Some(p) if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) => {
                return Err(TakeError::NonFinite { frame, marker });
            }
            Some(p) => {
                self.positions_mm[i] = p;
                self.valid[i] = true;
            }
            None => {
                self.positions_mm[i] = Vec3::zeros();
                self.valid[i] = false;
            }
        }
        self.quality[i] = SampleQuality::default();
        Ok(())
    }

    /// Quality of a sample as recorded by the capture system.
    pub fn quality(&self, frame: usize, marker: usize) -> SampleQuality {
        self.quality[self.index(frame, marker)]
    }

    /// Records the capture system's quality for a sample (readers use this).
    pub fn set_quality(&mut self, frame: usize, marker: usize, quality: SampleQuality) {
        let i = self.index(frame, marker);
        self.quality[i] = quality;
    }

    /// The trajectory of one marker: one `Option` per frame.
    pub fn trajectory_mm(&self, marker: usize) -> Vec<Option<Vec3>> {
        (0..self.frame_count()).map(|f| self.position_mm(f, marker)).collect()
    }

    /// All samples of one frame, `None` where missing.
    pub fn frame_mm(&self, frame: usize) -> Vec<Option<Vec3>> {
        (0..self.marker_count()).map(|m| self.position_mm(frame, m)).collect()
    }

    /// Validity of every sample, frame-major.
    pub fn validity(&self) -> &[bool] {
        &self.valid
    }

    /// Number of missing samples.
    pub fn missing_count(&self) -> usize {
        self.valid.iter().filter(|v| !**v).count()
    }

    /// A copy of frames `range` (clamped to the take).
    pub fn slice_frames(&self, range: std::ops::Range<usize>) -> Take {
        let t = self.frame_count();
        let (start, end) = (range.start.min(t), range.end.min(t).max(range.start.min(t)));
        let m = self.marker_count();
        let (a, b) = (start * m, end * m);
        Take {
            markers: self.markers.clone(),
            frames: end - start,
            positions_mm: self.positions_mm[a..b].to_vec(),
            valid: self.valid[a..b].to_vec(),
            quality: self.quality[a..b].to_vec(),
            frame_rate_hz: self.frame_rate_hz,
            first_frame: self.first_frame.saturating_add(start as u32),
            up_axis: self.up_axis,
        }
    }

    #[inline]
    fn index(&self, frame: usize, marker: usize) -> usize {
        let m = self.markers.len();
        assert!(marker < m && frame < self.frame_count(), "sample ({frame}, {marker}) outside take");
        frame * m + marker
    }
}

fn check_rate(hz: f64) -> Result<(), TakeError> {
    if hz.is_finite() && hz > 0.0 { Ok(()) } else { Err(TakeError::BadFrameRate(hz)) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(n: usize) -> Vec<MarkerName> {
        (0..n).map(|i| MarkerName::parse(&format!("M{i}"))).collect()
    }

    #[test]
    fn missing_samples_are_none() {
        let samples = vec![Some(Vec3::new(1.0, 2.0, 3.0)), None, None, Some(Vec3::new(4.0, 5.0, 6.0))];
        let take = Take::from_samples(names(2), &samples, 120.0).unwrap();
        assert_eq!(take.frame_count(), 2);
        assert_eq!(take.position_mm(0, 1), None);
        assert_eq!(take.position_mm(1, 1), Some(Vec3::new(4.0, 5.0, 6.0)));
        assert_eq!(take.missing_count(), 2);
        assert_eq!(take.trajectory_mm(0), vec![Some(Vec3::new(1.0, 2.0, 3.0)), None]);
    }

    #[test]
    fn rejects_bad_shapes_and_values() {
        assert!(matches!(
            Take::from_samples(names(2), &[None, None, None], 120.0),
            Err(TakeError::ShapeMismatch { .. })
        ));
        assert_eq!(Take::empty(names(1), 1, 0.0), Err(TakeError::BadFrameRate(0.0)));
        let mut take = Take::empty(names(1), 1, 60.0).unwrap();
        assert!(take.set_position_mm(0, 0, Some(Vec3::new(f64::NAN, 0.0, 0.0))).is_err());
        assert!(!take.is_valid(0, 0));
    }

    #[test]
    fn slices_keep_frame_numbers() {
        let take = Take::empty(names(3), 10, 100.0).unwrap();
        let cut = take.slice_frames(4..7);
        assert_eq!(cut.frame_count(), 3);
        assert_eq!(cut.first_frame, 5);
        assert_eq!(take.slice_frames(8..20).frame_count(), 2);
    }
}
