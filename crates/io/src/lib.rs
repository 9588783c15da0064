//! # locap-io: capture file formats
//!
//! Every reader turns a file into the types of `locap-core` ([`locap_core::Take`] for marker
//! data, [`locap_core::Motion`] for skeleton motion); every writer goes the other way and
//! writes atomically (see [`atomic`]), so a failed write never leaves half a file behind and
//! never touches the input.
//!
//! # Formats
//! - [`c3d`]: the binary C3D format of every optical capture system, read and written
//!   *losslessly*: parameters and analog data locap does not interpret are carried through.
//! - [`bvh`]: Biovision hierarchy, skeleton motion in and out.
//! - [`asf_amc`]: Acclaim skeleton (ASF) and motion (AMC), as in the CMU database (read).
//! - [`trc`]: OpenSim / Motion Analysis marker text files, in and out.
//! - [`csv`]: a plain marker table for spreadsheets, written and read back (same layout).
//! - [`gltf`]: glTF 2.0 (`.gltf`, `.glb`), a solved motion as a skinned, animated skeleton
//!   (written).
//! - [`fbx`]: binary FBX 7.4, a solved motion as a skeleton with animation curves (written).
//! - [`mot`]: OpenSim motion tables of joint angles (written).
//!
//! [`export`] picks a motion writer by file extension; [`axes`] says which axes and units
//! every writer uses and converts takes and motions into them.
//!
//! # Errors
//! [`Error`] says where a file is broken: byte offset and section for binary files, line and
//! column for text files, and (through [`Error::in_file`]) which file.
//!
//! # Limits and warnings
//! Counts read from a file (frames, markers, joints, nesting depth) are checked against
//! [`Limits`] before anything is allocated; every `*_with` reader takes them, the others use
//! the defaults. Path readers refuse named pipes, devices and directories before opening
//! them. Things a reader resolved but the user should hear about are returned, not printed:
//! [`c3d::C3dFile::warnings`], [`trc::TrcFile::notes`].
//!
//! No existing crate was fit to build on (the `c3dio` writer produces files that ezc3d and
//! py-c3d reject; `bvh_anim` is unmaintained alpha), so the formats are implemented here.

pub mod asf_amc;
pub mod atomic;
pub mod axes;
pub mod bvh;
pub mod c3d;
pub mod csv;
mod error;
pub mod export;
pub mod fbx;
pub mod gltf;
pub mod limits;
pub mod mot;
pub mod trc;

pub use error::{Error, Result};
pub use limits::Limits;
