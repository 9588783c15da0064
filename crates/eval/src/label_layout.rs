//! A labeling template from a marker layout that brings its skeleton (issue 16, item 1b: no
//! labeled take at all), e.g. one `locap layout --from-opensim` built from an OpenSim model and
//! marker set: the layout's markers placed on its skeleton at rest
//! ([`locap_synth::layout::BoundMarker::position_mm`]), handed to
//! [`locap_label::Template::from_model`] (whose module docs say what the template holds and how
//! a take is labeled with it).
//!
//! This bridge lives here because the labeling stage does not depend on the synthesis stage,
//! which owns layouts; both are below evaluation.

use locap_core::skeleton::forward_kinematics;
use locap_core::{MarkerName, Quat, Vec3};
use locap_label::{LabelError, ModelMarker, Template};
use locap_synth::Layout;
use locap_synth::layout::LayoutError;

/// Why a layout gives no template.
#[derive(Debug, thiserror::Error)]
pub enum LayoutTemplateError {
    /// The layout has no `[skeleton]` section to place its markers on.
    #[error(
        "layout {0:?} brings no skeleton: a template needs the bones its markers ride on (build one with `locap layout --from-opensim`)"
    )]
    NoSkeleton(String),
    /// The layout's skeleton or markers do not check.
    #[error("layout {name:?}: {error}")]
    Layout {
        /// The layout's name.
        name: String,
        /// The cause.
        error: LayoutError,
    },
    /// The model makes no template (too few markers, no bone with three).
    #[error("layout {name:?}: {error}")]
    Template {
        /// The layout's name.
        name: String,
        /// The cause.
        error: LabelError,
    },
}

/// The template of `layout`'s markers on its own skeleton at rest, in layout order.
///
/// # Errors
/// [`LayoutTemplateError`] for a layout without a skeleton, one that does not bind to it, or
/// one whose model makes no template.
pub fn template_from_layout(layout: &Layout) -> Result<Template, LayoutTemplateError> {
    let name = layout.name.clone();
    let section = layout.skeleton.as_ref().ok_or_else(|| LayoutTemplateError::NoSkeleton(name.clone()))?;
    let in_layout = |error| LayoutTemplateError::Layout { name: name.clone(), error };
    let skeleton = section.to_skeleton().map_err(in_layout)?;
    let bound = layout.bind(&skeleton).map_err(in_layout)?;
    let rest = forward_kinematics(&skeleton, &vec![Quat::identity(); skeleton.len()], Vec3::zeros());
    let markers: Vec<ModelMarker> = bound
        .names
        .iter()
        .zip(&bound.markers)
        .map(|(n, m)| ModelMarker {
            name: MarkerName::parse(n),
            joint: m.joint,
            rest_mm: m.position_mm(&rest, Vec3::zeros()),
        })
        .collect();
    // Each skeleton joint's rotation axes, where the layout lists its degrees of freedom.
    let axes: Vec<Option<Vec<Vec3>>> = skeleton
        .joints()
        .iter()
        .map(|joint| {
            let listed = section.joints.iter().find(|j| j.name == joint.name)?;
            Some(listed.dofs.as_ref()?.iter().map(|d| Vec3::from(d.axis)).collect())
        })
        .collect();
    Template::from_model_with_axes(&skeleton, &markers, &axes)
        .map_err(|error| LayoutTemplateError::Template { name, error })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_layout_without_skeleton_is_refused() {
        let cmu = Layout::cmu41();
        assert!(cmu.skeleton.is_none());
        assert!(matches!(template_from_layout(&cmu), Err(LayoutTemplateError::NoSkeleton(_))));
    }
}
