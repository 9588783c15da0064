//! Where labeling starts: the first frame the articulated fit ([`crate::pose_fit`]) is sure
//! of. A take that starts mid-motion, with the subject half occluded or in a pose the
//! template never showed, may give an unsure fit in its first frame; rather than guess, the
//! fit moves on through the take until it is sure, and labeling then runs forwards and
//! backwards from there ([`crate::label_take`]).

use crate::body::Body;
use crate::cloud::PointFrames;
use crate::initial_fit::{FitConfig, InitialFit};
use crate::pose_fit::{PoseFit, fit_pose};
use crate::{LabelError, Template};
use locap_clean::procrustes::{RigidTransform, align};

/// A fit sure of this share of the markers the body can place starts labeling at once.
pub const START_SURE_FRACTION: f64 = 0.9;

/// Frames tried are this far apart (s).
const TRY_EVERY_S: f64 = 0.1;

/// Most frames tried.
const MAX_TRIES: usize = 100;

/// Fits `body` to frames of `frames` from the first on until a fit is sure (see
/// [`START_SURE_FRACTION`] and [`FitConfig::min_matched_fraction`]).
///
/// # Errors
/// [`LabelError::FirstFrame`] when no frame tried gives a fit sure of enough markers.
pub fn find_start(
    frames: &PointFrames,
    template: &Template,
    body: &Body,
    config: &FitConfig,
) -> Result<InitialFit, LabelError> {
    let m = template.marker_count();
    find_start_with(frames, template, body.placeable(), config, |points| fit_pose(body, m, points, &[], &[]))
}

/// [`find_start`] with the fit of one frame's points given (the body places `placeable`
/// markers).
pub(crate) fn find_start_with(
    frames: &PointFrames,
    template: &Template,
    placeable: usize,
    config: &FitConfig,
    fit_frame: impl Fn(&[locap_core::Vec3]) -> PoseFit,
) -> Result<InitialFit, LabelError> {
    let step = ((TRY_EVERY_S * frames.frame_rate_hz()).round() as usize).max(1);
    let mut best: Option<InitialFit> = None;
    for f in (0..frames.frame_count()).step_by(step).take(MAX_TRIES) {
        let points = frames.frame(f);
        let fit = fit_frame(points);
        let better = best.as_ref().is_none_or(|b| fit.sure_markers > b.sure_markers);
        if better {
            let (from, to): (Vec<_>, Vec<_>) = fit
                .assignment
                .iter()
                .zip(template.reference_mm())
                .filter_map(|(p, r)| Some(((*r)?, points[(*p)?])))
                .unzip();
            let transform = align(&from, &to).unwrap_or(RigidTransform {
                rotation: nalgebra::Rotation3::identity(),
                translation: locap_core::Vec3::zeros(),
            });
            best = Some(InitialFit {
                assignment: fit.assignment.clone(),
                transform,
                rms_mm: fit.rms_mm,
                frame: f,
                sure_markers: fit.sure_markers,
                expected_mm: fit.expected_mm.clone(),
            });
        }
        if fit.sure_markers as f64 >= START_SURE_FRACTION * placeable as f64 {
            break;
        }
    }
    let needed = ((placeable as f64 * config.min_matched_fraction).ceil() as usize).max(3);
    match best {
        Some(fit) if fit.sure_markers >= needed => Ok(fit),
        best => Err(LabelError::FirstFrame(format!(
            "the articulated fit was sure of at most {} of the {placeable} markers the template's body places \
             in the {} frames tried ({needed} needed): the take does not show the template's subject and marker set",
            best.map_or(0, |b| b.sure_markers),
            frames.frame_count().div_ceil(step).min(MAX_TRIES),
        ))),
    }
}
