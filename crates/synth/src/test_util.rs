//! Builders shared by the unit tests.

use crate::layout::{Layout, LayoutMarker, Region};
use locap_core::{EulerOrder, Joint, Vec3};

/// A joint with a ZXY order, not an end site.
pub fn joint(name: &str, parent: Option<usize>, offset_mm: [f64; 3]) -> Joint {
    Joint {
        name: name.into(),
        parent,
        offset_mm: Vec3::from(offset_mm),
        rotation_order: EulerOrder::ZXY,
        is_end_site: false,
    }
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
    Layout { name: "test".into(), description: String::new(), aliases: Default::default(), markers }
}
