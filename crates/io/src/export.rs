//! One call to write a skeleton motion in the format its file name asks for.
//!
//! `.bvh` ([`crate::bvh`]), `.gltf` / `.glb` ([`crate::gltf`]), `.fbx` ([`crate::fbx`]) and
//! `.mot` ([`crate::mot`]); the axes and units of each are in [`crate::axes`]. The motion is
//! written in its own axes, which every format here expects to be Y-up.

use crate::{Error, Result, bvh, fbx, gltf, mot};
use locap_core::{LengthUnit, Motion, Take, UpAxis};
use std::path::Path;

/// File extensions [`write_motion_path`] writes (lower case).
pub const MOTION_EXTENSIONS: &[&str] = &["bvh", "gltf", "glb", "fbx", "mot"];

/// Choices for [`write_motion_path`] that some formats use.
#[derive(Debug, Clone, Copy)]
pub struct MotionOutput<'a> {
    /// Length unit of a BVH file (BVH cannot record it).
    pub bvh_unit: LengthUnit,
    /// Markers to add to a glTF file as animated nodes (Y-up, the motion's frames).
    pub markers: Option<&'a Take>,
}

impl Default for MotionOutput<'_> {
    fn default() -> Self {
        MotionOutput { bvh_unit: LengthUnit::Centimetre, markers: None }
    }
}

/// Writes `motion` (Y-up) to `path` in the format of its extension, atomically.
pub fn write_motion_path(motion: &Motion, output: &MotionOutput<'_>, path: &Path) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
    let result = match ext.as_str() {
        "bvh" => bvh::write_bvh_path(motion, output.bvh_unit, path),
        "gltf" | "glb" => gltf::write_gltf_path(motion, gltf::GltfContent { markers: output.markers }, path),
        "fbx" => fbx::write_fbx_path(motion, path),
        "mot" => mot::write_mot_path(motion, UpAxis::Y, path),
        other => Err(Error::Unsupported(format!(
            "skeleton motion as {other:?}: the formats are {}",
            MOTION_EXTENSIONS.join(", ")
        ))),
    };
    result.map_err(|e| e.in_file(path))
}
