//! Local coordinate systems of the waist and the wrists (LocalMoCap section 3.1, last
//! paragraph): the solver and the learned refiner see markers in these frames, so the global
//! position and heading of the subject do not have to be learned.
//!
//! A frame is defined by groups of reference markers ([`FrameDefinition`]):
//! - origin: the mean of the `origin` markers that are visible;
//! - primary axis (local **X**): from the mean of `x_from` to the mean of `x_to`;
//! - secondary direction: from the mean of `y_from` to the mean of `y_to`, made orthogonal to
//!   X by Gram-Schmidt (local **Y**);
//! - local **Z** = X x Y (right-handed).
//!
//! For the waist preset that is X = subject's right, Y = forward, Z = up; for the wrist presets
//! X runs across the wrist from the thumb side to the little-finger side and Y towards the
//! fingers.
//!
//! Robustness: each group uses whichever of its markers are visible, so one missing reference
//! marker still gives a frame. If a group is entirely missing, or the two directions are
//! (nearly) parallel, the frame of the nearest earlier frame is held (before the first good
//! frame, the first good one is used). A take in which the frame is never defined is an
//! error. No NaN can come out: every normalisation is checked.

use locap_core::{Take, Vec3};
use nalgebra::{Matrix3, Rotation3};
use serde::{Deserialize, Serialize};

/// Errors building local frames.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LocalFrameError {
    /// A reference marker name is not in the take at all.
    #[error("local frame {frame}: marker {marker} is not in the take")]
    UnknownMarker {
        /// Frame definition name.
        frame: String,
        /// Missing marker label.
        marker: String,
    },
    /// The frame could not be built in any frame of the take.
    #[error("local frame {0}: its reference markers never give a well-defined frame in this take")]
    NeverDefined(String),
}

/// Which markers define a local frame (see the module doc for the construction).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameDefinition {
    /// Name (`waist`, `left_wrist`, ...).
    pub name: String,
    /// Markers whose mean is the origin.
    pub origin: Vec<String>,
    /// Primary axis tail markers.
    pub x_from: Vec<String>,
    /// Primary axis head markers.
    pub x_to: Vec<String>,
    /// Secondary direction tail markers.
    pub y_from: Vec<String>,
    /// Secondary direction head markers.
    pub y_to: Vec<String>,
}

fn names(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

impl FrameDefinition {
    /// Waist of the CMU/HDM05 41-marker Vicon set: X to the subject's right, Y forward, Z up.
    pub fn cmu_waist() -> FrameDefinition {
        FrameDefinition {
            name: "waist".into(),
            origin: names(&["LFWT", "RFWT", "LBWT", "RBWT"]),
            x_from: names(&["LFWT", "LBWT"]),
            x_to: names(&["RFWT", "RBWT"]),
            y_from: names(&["LBWT", "RBWT"]),
            y_to: names(&["LFWT", "RFWT"]),
        }
    }

    /// A wrist of the CMU set (`side` is `L` or `R`): origin between the wrist bar markers
    /// `WRA` (thumb side) and `WRB` (little-finger side), X from `WRA` to `WRB`, Y towards
    /// the hand marker `FIN`.
    pub fn cmu_wrist(side: char) -> FrameDefinition {
        let s = |m: &str| format!("{side}{m}");
        FrameDefinition {
            name: if side == 'L' { "left_wrist".into() } else { "right_wrist".into() },
            origin: vec![s("WRA"), s("WRB")],
            x_from: vec![s("WRA")],
            x_to: vec![s("WRB")],
            y_from: vec![s("WRA"), s("WRB")],
            y_to: vec![s("FIN")],
        }
    }

    /// A wrist of the paper's hand set (`side` is `L` or `R`): inner/outer wrist markers
    /// `IWR`/`OWR` and back-of-hand markers `IHAND`/`OHAND`.
    pub fn paper_wrist(side: char) -> FrameDefinition {
        let s = |m: &str| format!("{side}{m}");
        FrameDefinition {
            name: if side == 'L' { "left_wrist".into() } else { "right_wrist".into() },
            origin: vec![s("IWR"), s("OWR")],
            x_from: vec![s("IWR"), s("IHAND")],
            x_to: vec![s("OWR"), s("OHAND")],
            y_from: vec![s("IWR"), s("OWR")],
            y_to: vec![s("IHAND"), s("OHAND")],
        }
    }
}

/// A local coordinate system in one frame: `world = rotation * local + origin_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    /// Origin in world millimetres.
    pub origin_mm: Vec3,
    /// Rotation from local to world axes.
    pub rotation: Rotation3<f64>,
}

impl LocalFrame {
    /// World point to local coordinates.
    pub fn to_local(&self, world_mm: &Vec3) -> Vec3 {
        self.rotation.inverse() * (world_mm - self.origin_mm)
    }

    /// Local point to world coordinates.
    pub fn to_world(&self, local_mm: &Vec3) -> Vec3 {
        self.rotation * local_mm + self.origin_mm
    }
}

/// Resolved marker indices of a definition in one take.
struct Indices {
    origin: Vec<usize>,
    x_from: Vec<usize>,
    x_to: Vec<usize>,
    y_from: Vec<usize>,
    y_to: Vec<usize>,
}

/// The local frame of every frame of `take` (see the module doc for missing markers).
pub fn local_frames(take: &Take, definition: &FrameDefinition) -> Result<Vec<LocalFrame>, LocalFrameError> {
    let resolve = |group: &[String]| -> Result<Vec<usize>, LocalFrameError> {
        group
            .iter()
            .map(|label| {
                take.marker_index(label).ok_or_else(|| LocalFrameError::UnknownMarker {
                    frame: definition.name.clone(),
                    marker: label.clone(),
                })
            })
            .collect()
    };
    let idx = Indices {
        origin: resolve(&definition.origin)?,
        x_from: resolve(&definition.x_from)?,
        x_to: resolve(&definition.x_to)?,
        y_from: resolve(&definition.y_from)?,
        y_to: resolve(&definition.y_to)?,
    };
    let per_frame: Vec<Option<LocalFrame>> = (0..take.frame_count()).map(|f| frame_at(take, &idx, f)).collect();
    let first = per_frame
        .iter()
        .flatten()
        .next()
        .copied()
        .ok_or_else(|| LocalFrameError::NeverDefined(definition.name.clone()))?;
    let mut held = first;
    Ok(per_frame
        .into_iter()
        .map(|f| {
            if let Some(f) = f {
                held = f;
            }
            held
        })
        .collect())
}

fn mean_of(take: &Take, frame: usize, group: &[usize]) -> Option<Vec3> {
    let visible: Vec<Vec3> = group.iter().filter_map(|m| take.position_mm(frame, *m)).collect();
    (!visible.is_empty()).then(|| visible.iter().sum::<Vec3>() / visible.len() as f64)
}

/// Directions shorter than this (mm) or closer to parallel than this sine are degenerate.
const MIN_LENGTH_MM: f64 = 1e-3;
const MIN_SINE: f64 = 1e-3;

fn frame_at(take: &Take, idx: &Indices, f: usize) -> Option<LocalFrame> {
    let origin = mean_of(take, f, &idx.origin)?;
    let x = mean_of(take, f, &idx.x_to)? - mean_of(take, f, &idx.x_from)?;
    let y = mean_of(take, f, &idx.y_to)? - mean_of(take, f, &idx.y_from)?;
    let (xn, yn) = (x.norm(), y.norm());
    if !(xn > MIN_LENGTH_MM && yn > MIN_LENGTH_MM) {
        return None;
    }
    let x = x / xn;
    let y = y - x * x.dot(&y);
    let y_len = y.norm();
    if !(y_len > MIN_SINE * yn) {
        return None;
    }
    let y = y / y_len;
    let z = x.cross(&y);
    let rotation = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    origin.iter().all(|v| v.is_finite()).then_some(LocalFrame { origin_mm: origin, rotation })
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::MarkerName;

    fn waist_take(samples: Vec<Option<Vec3>>, frames: usize) -> Take {
        let names = ["LFWT", "RFWT", "LBWT", "RBWT"].iter().map(|n| MarkerName::parse(n)).collect();
        assert_eq!(samples.len(), frames * 4);
        Take::from_samples(names, &samples, 120.0).unwrap()
    }

    fn pelvis(shift: Vec3, yaw: f64) -> Vec<Option<Vec3>> {
        let r = Rotation3::from_euler_angles(0.0, 0.0, yaw);
        [
            Vec3::new(-130.0, 60.0, 0.0),
            Vec3::new(130.0, 60.0, 0.0),
            Vec3::new(-90.0, -100.0, 20.0),
            Vec3::new(90.0, -100.0, 20.0),
        ]
        .iter()
        .map(|p| Some(r * p + shift))
        .collect()
    }

    #[test]
    fn waist_axes_follow_the_subject() {
        let shift = Vec3::new(1000.0, 500.0, 950.0);
        let take = waist_take(pelvis(shift, std::f64::consts::FRAC_PI_2), 1);
        let frame = local_frames(&take, &FrameDefinition::cmu_waist()).unwrap()[0];
        // Turned 90 degrees left: the subject's right (local X) points along world +Y.
        let right = frame.rotation * Vec3::x();
        assert!((right - Vec3::y()).norm() < 1e-9, "{right:?}");
        let up = frame.rotation * Vec3::z();
        assert!(up.z > 0.99, "{up:?}");
        let p = Vec3::new(10.0, 20.0, 30.0);
        assert!((frame.to_world(&frame.to_local(&p)) - p).norm() < 1e-9);
    }

    #[test]
    fn survives_missing_and_degenerate_references() {
        let mut samples = pelvis(Vec3::zeros(), 0.0);
        samples.extend(pelvis(Vec3::new(5.0, 0.0, 0.0), 0.1));
        samples.extend(pelvis(Vec3::new(9.0, 0.0, 0.0), 0.2));
        // Frame 1: one reference marker gone. Frame 2: all at one point (degenerate).
        samples[4 + 3] = None;
        for s in &mut samples[8..12] {
            *s = Some(Vec3::new(1.0, 1.0, 1.0));
        }
        let take = waist_take(samples, 3);
        let frames = local_frames(&take, &FrameDefinition::cmu_waist()).unwrap();
        assert_eq!(frames.len(), 3);
        for f in &frames {
            assert!(f.rotation.matrix().iter().all(|v| v.is_finite()));
            assert!(f.origin_mm.iter().all(|v| v.is_finite()));
        }
        // The degenerate frame holds the previous one.
        assert_eq!(frames[2], frames[1]);
        assert!((frames[1].rotation.matrix().determinant() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn errors_are_clear() {
        let take = waist_take(vec![None; 4], 1);
        assert_eq!(
            local_frames(&take, &FrameDefinition::cmu_waist()),
            Err(LocalFrameError::NeverDefined("waist".into()))
        );
        let err = local_frames(&take, &FrameDefinition::cmu_wrist('L')).unwrap_err();
        assert!(err.to_string().contains("LWRA"));
    }
}
