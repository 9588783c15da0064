//! # locap-core: the data model every stage of locap shares
//!
//! locap moves marker data through four stages (label, clean, solve, train); each of them
//! reads and writes the types of this crate and nothing else, so no stage ever sees a file.
//!
//! # Markers
//! A [`Take`] is what a capture system records: `T` frames of `M` named markers, positions in
//! millimetres, and an explicit per-sample validity mask. A missing sample is *never* a magic
//! zero or NaN: [`Take::position_mm`] returns `None` for it, so no arithmetic can use it by
//! accident. Marker names keep the subject prefix that vendors add (`Male:LFWT`) apart from the
//! marker's own name, see [`MarkerName`].
//!
//! # Skeletons and motion
//! A [`Skeleton`] is a joint tree (names, parents, rest offsets in millimetres); a [`Motion`]
//! is a per-frame local rotation for every joint plus a root translation. [`Motion::forward_kinematics`]
//! turns one frame into global joint positions and rotations.
//!
//! # Occlusion statistics
//! [`gaps::GapStatistics`] summarises which samples are missing (per-marker missing fraction,
//! gap count and lengths, and a gap-length histogram). It is the input of the LocalMoCap
//! paper's Eq. 6 occlusion augmentation (section 3.3), and `locap info` prints it.
//!
//! # Units and axes
//! Lengths carry their unit in the name (`_mm`) or in a [`LengthUnit`]; the vertical axis of a
//! take is an explicit [`UpAxis`].

pub mod gaps;
pub mod marker;
pub mod provenance;
pub mod range_list;
pub mod rotation;
pub mod skeleton;
pub mod take;
pub mod units;

pub use gaps::GapStatistics;
pub use marker::MarkerName;
pub use provenance::Provenance;
pub use rotation::EulerOrder;
pub use skeleton::{GlobalPose, Joint, Motion, Skeleton, SkeletonError};
pub use take::{Take, TakeError};
pub use units::{LengthUnit, UpAxis};

/// A 3D vector of `f64`, the coordinate type used throughout locap.
pub type Vec3 = nalgebra::Vector3<f64>;
/// A unit quaternion of `f64`, the rotation type used throughout locap.
pub type Quat = nalgebra::UnitQuaternion<f64>;
