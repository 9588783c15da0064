//! Builders shared by the unit tests.

use crate::layout::{Layout, LayoutMarker, Region};
use locap_core::{Joint, Vec3};

/// A joint with a ZXY order, not an end site.
pub fn joint(name: &str, parent: Option<usize>, offset_mm: [f64; 3]) -> Joint {
    Joint::new(name, parent, Vec3::from(offset_mm))
}

/// An unblended body marker.
pub fn marker(name: &str, joint: &str, offset_mm: [f64; 3]) -> LayoutMarker {
    LayoutMarker {
        name: name.into(),
        joint: joint.into(),
        offset_mm,
        region: Region::Body,
        blend: None,
        soft_tissue: 1.0,
    }
}

/// A layout of `markers` without aliases.
pub fn layout(markers: Vec<LayoutMarker>) -> Layout {
    Layout { name: "test".into(), description: String::new(), aliases: Default::default(), markers, skeleton: None }
}
