//! FBX (binary, version 7.4): a solved motion as a skeleton with animation curves, for
//! Unreal, Unity, MotionBuilder, Maya and Blender.
//!
//! No well-kept Rust FBX writer exists (looked up on docs.rs: `fbx_direct` is an unmaintained
//! low-level event writer, `fbxcel`'s writer encodes the node container but knows no scene,
//! skeleton or animation; the others read), so this one is written from the format's public
//! documentation: Autodesk's FBX SDK reference
//! for the scene model (`FbxNode`, `FbxSkeleton`, `FbxAnimStack`, `FbxAnimLayer`,
//! `FbxAnimCurveNode`, `FbxAnimCurve`, `FbxGlobalSettings`) and the Blender Foundation's
//! description of the binary container ("FBX binary file format specification", Blender
//! developer blog, 2013), which the binary layout in [`binary`] follows.
//!
//! # What is written
//! - `FBXHeaderExtension` (version 7400, creator), `GlobalSettings`: Y-up (`UpAxis` 1,
//!   `FrontAxis` 2, `CoordAxis` 0, all signs +1, the axes Maya and Blender's own exporter
//!   write), centimetres (`UnitScaleFactor` 1), and the frame rate (`TimeMode`, with
//!   `CustomFrameRate` for a rate FBX has no mode for).
//! - One `Model` of type `LimbNode` with a `Skeleton` `NodeAttribute` per joint (end sites
//!   are not joints in FBX), parented as in the skeleton; its rest `Lcl Translation` is the
//!   joint's offset, its rest rotation zero.
//! - One `AnimationStack` with one `AnimationLayer`: per joint an `AnimationCurveNode` for
//!   `Lcl Rotation` (Euler angles in degrees, `RotationOrder` 0 = `eEulerXYZ`, which applies
//!   X first: `R = Rz * Ry * Rx`), and for the root one for `Lcl Translation` (cm); each with
//!   three `AnimationCurve`s keyed at every frame (`KTime`, 46186158000 ticks per second),
//!   linear. Angles are unwrapped to the turn nearest the previous frame's, so interpolation
//!   never spins a joint the long way.
//! - `Connections` tying them together (`OO` object to object, `OP` object to property).
//!
//! The motion must already be Y-up (see [`crate::axes`]).

use crate::atomic::write_atomically;
use crate::{Error, Result};
use binary::{Node, Property as P};
use locap_core::{EulerOrder, Motion};
use std::io::Write;
use std::path::Path;

/// FBX time units per second (`FbxTime`'s `KTime`).
pub const KTIME_PER_SECOND: i64 = 46_186_158_000;

/// The binary container: nodes with typed properties and nested nodes.
pub mod binary {
    use std::io::Write;

    /// Bytes of a version 7.4 file's magic, `0x1A 0x00` and version.
    pub const HEADER_LEN: usize = 27;
    /// The magic that opens every binary FBX file.
    pub const MAGIC: &[u8; 21] = b"Kaydara FBX Binary  \0";
    /// Version written (7.4; versions from 7.5 use 64-bit record offsets).
    pub const VERSION: u32 = 7400;
    /// The 13 zero bytes that end a list of nested nodes (three u32 and a u8 at version 7.4).
    pub const NULL_RECORD: [u8; 13] = [0; 13];

    /// A property value, with the type code of the binary format.
    #[derive(Debug, Clone, PartialEq)]
    pub enum Property {
        /// `C`: a boolean, one byte.
        Bool(bool),
        /// `I`: a 32-bit integer.
        I32(i32),
        /// `L`: a 64-bit integer (object ids, times).
        I64(i64),
        /// `D`: a 64-bit float.
        F64(f64),
        /// `S`: a string (not NUL-terminated; `\0\x01` separates an object's name and class).
        Str(String),
        /// `R`: raw bytes.
        Raw(Vec<u8>),
        /// `f`: an array of 32-bit floats (written uncompressed).
        F32s(Vec<f32>),
        /// `d`: an array of 64-bit floats.
        F64s(Vec<f64>),
        /// `i`: an array of 32-bit integers.
        I32s(Vec<i32>),
        /// `l`: an array of 64-bit integers.
        I64s(Vec<i64>),
    }

    impl Property {
        /// The type code of this property.
        pub fn code(&self) -> u8 {
            match self {
                Property::Bool(_) => b'C',
                Property::I32(_) => b'I',
                Property::I64(_) => b'L',
                Property::F64(_) => b'D',
                Property::Str(_) => b'S',
                Property::Raw(_) => b'R',
                Property::F32s(_) => b'f',
                Property::F64s(_) => b'd',
                Property::I32s(_) => b'i',
                Property::I64s(_) => b'l',
            }
        }

        fn encode(&self, out: &mut Vec<u8>) {
            out.push(self.code());
            fn array(out: &mut Vec<u8>, count: usize, bytes: impl Iterator<Item = u8>) {
                let start = out.len();
                out.extend_from_slice(&(count as u32).to_le_bytes());
                out.extend_from_slice(&0u32.to_le_bytes()); // encoding 0: not compressed
                out.extend_from_slice(&0u32.to_le_bytes()); // byte length, set below
                out.extend(bytes);
                let len = (out.len() - start - 12) as u32;
                out[start + 8..start + 12].copy_from_slice(&len.to_le_bytes());
            }
            match self {
                Property::Bool(v) => out.push(u8::from(*v)),
                Property::I32(v) => out.extend_from_slice(&v.to_le_bytes()),
                Property::I64(v) => out.extend_from_slice(&v.to_le_bytes()),
                Property::F64(v) => out.extend_from_slice(&v.to_le_bytes()),
                Property::Str(s) => {
                    out.extend_from_slice(&(s.len() as u32).to_le_bytes());
                    out.extend_from_slice(s.as_bytes());
                }
                Property::Raw(b) => {
                    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
                    out.extend_from_slice(b);
                }
                Property::F32s(v) => array(out, v.len(), v.iter().flat_map(|x| x.to_le_bytes())),
                Property::F64s(v) => array(out, v.len(), v.iter().flat_map(|x| x.to_le_bytes())),
                Property::I32s(v) => array(out, v.len(), v.iter().flat_map(|x| x.to_le_bytes())),
                Property::I64s(v) => array(out, v.len(), v.iter().flat_map(|x| x.to_le_bytes())),
            }
        }
    }

    /// A node record: a name, properties and nested nodes.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct Node {
        /// The record's name (at most 255 bytes).
        pub name: String,
        /// Its properties, in order.
        pub properties: Vec<Property>,
        /// Nested records.
        pub children: Vec<Node>,
    }

    impl Node {
        /// A node without children.
        pub fn new(name: &str, properties: Vec<Property>) -> Node {
            Node { name: name.to_string(), properties, children: Vec::new() }
        }

        /// A node with children.
        pub fn with(name: &str, properties: Vec<Property>, children: Vec<Node>) -> Node {
            Node { name: name.to_string(), properties, children }
        }

        /// Appends this record to `out`, which starts at file offset `base` (record offsets
        /// are absolute).
        fn encode(&self, base: usize, out: &mut Vec<u8>) {
            let start = out.len();
            out.extend_from_slice(&[0; 12]); // end offset, property count, property bytes
            // Names are checked by `check` before encoding.
            out.push(self.name.len() as u8);
            out.extend_from_slice(self.name.as_bytes());
            let props_start = out.len();
            for p in &self.properties {
                p.encode(out);
            }
            let props_len = (out.len() - props_start) as u32;
            // A record with nested records, or with neither properties nor nested records, is
            // closed by a null record (readers rely on it to tell "no children" apart).
            if !self.children.is_empty() || self.properties.is_empty() {
                for c in &self.children {
                    c.encode(base, out);
                }
                out.extend_from_slice(&NULL_RECORD);
            }
            let end = (base + out.len()) as u32;
            out[start..start + 4].copy_from_slice(&end.to_le_bytes());
            out[start + 4..start + 8].copy_from_slice(&(self.properties.len() as u32).to_le_bytes());
            out[start + 8..start + 12].copy_from_slice(&props_len.to_le_bytes());
        }

        /// Bytes this record takes, for the 4 GiB check.
        fn size(&self) -> usize {
            let props: usize = self
                .properties
                .iter()
                .map(|p| {
                    1 + match p {
                        Property::Bool(_) => 1,
                        Property::I32(_) => 4,
                        Property::I64(_) | Property::F64(_) => 8,
                        Property::Str(s) => 4 + s.len(),
                        Property::Raw(b) => 4 + b.len(),
                        Property::F32s(v) => 12 + 4 * v.len(),
                        Property::I32s(v) => 12 + 4 * v.len(),
                        Property::F64s(v) => 12 + 8 * v.len(),
                        Property::I64s(v) => 12 + 8 * v.len(),
                    }
                })
                .sum();
            let nested = if !self.children.is_empty() || self.properties.is_empty() { NULL_RECORD.len() } else { 0 };
            13 + self.name.len() + props + self.children.iter().map(Node::size).sum::<usize>() + nested
        }

        /// A name too long for its length byte, or a string or array too long for its u32
        /// length, anywhere in the tree.
        fn check(&self) -> Result<(), String> {
            if self.name.len() > 255 {
                return Err(format!("node name of {} bytes; at most 255", self.name.len()));
            }
            self.children.iter().try_for_each(Node::check)
        }
    }

    /// Encodes a whole file: header, the top-level records, the closing null record and the
    /// footer. Fails when a name is too long or the file would pass 4 GiB (the format's u32
    /// offsets).
    pub fn encode_file(top: &[Node]) -> Result<Vec<u8>, String> {
        top.iter().try_for_each(Node::check)?;
        let size = HEADER_LEN + top.iter().map(Node::size).sum::<usize>() + NULL_RECORD.len() + 256;
        if u32::try_from(size).is_err() {
            return Err(format!("{size} bytes; a version 7.4 file holds at most 4 GiB"));
        }
        let mut out = Vec::with_capacity(size);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&[0x1A, 0x00]);
        out.extend_from_slice(&VERSION.to_le_bytes());
        for node in top {
            // The records' offsets are absolute: `out` is the file from byte 0.
            let mut record = Vec::new();
            node.encode(out.len(), &mut record);
            out.extend_from_slice(&record);
        }
        out.extend_from_slice(&NULL_RECORD);
        // The footer the FBX SDK writes: an id, padding to 16 bytes, the version, 120 zero
        // bytes and a fixed 16-byte tail.
        out.extend_from_slice(&[
            0xfa, 0xbc, 0xab, 0x09, 0xd0, 0xc8, 0xd4, 0x66, 0xb1, 0x76, 0xfb, 0x83, 0x1c, 0xf7, 0x26, 0x7e,
        ]);
        out.extend_from_slice(&[0; 4]);
        let pad = 16 - out.len() % 16;
        out.extend(std::iter::repeat_n(0u8, pad));
        out.extend_from_slice(&VERSION.to_le_bytes());
        out.extend_from_slice(&[0; 120]);
        out.extend_from_slice(&[
            0xf8, 0x5a, 0x8c, 0x6a, 0xde, 0xf5, 0xd9, 0x7e, 0xec, 0xe9, 0x0c, 0xe3, 0x75, 0x8f, 0x29, 0x0b,
        ]);
        Ok(out)
    }

    /// Writes [`encode_file`]'s bytes.
    pub fn write_file(top: &[Node], w: &mut dyn Write) -> crate::Result<()> {
        let bytes = encode_file(top).map_err(|e| crate::Error::Unwritable(format!("FBX: {e}")))?;
        w.write_all(&bytes)?;
        Ok(())
    }

    /// Decodes a file written by [`encode_file`] back into its top-level records (for tests:
    /// a reader of uncompressed version 7.4 files, strict about every length).
    pub fn decode_file(bytes: &[u8]) -> Result<Vec<Node>, String> {
        if bytes.len() < HEADER_LEN || &bytes[..21] != MAGIC {
            return Err("not a binary FBX file".into());
        }
        let mut at = HEADER_LEN;
        let mut top = Vec::new();
        while let Some(node) = decode_node(bytes, &mut at)? {
            top.push(node);
        }
        Ok(top)
    }

    fn take<'a>(bytes: &'a [u8], at: &mut usize, n: usize) -> Result<&'a [u8], String> {
        let s = bytes.get(*at..*at + n).ok_or_else(|| format!("truncated at byte {at}"))?;
        *at += n;
        Ok(s)
    }

    fn u32_at(bytes: &[u8], at: &mut usize) -> Result<u32, String> {
        let b = take(bytes, at, 4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn decode_node(bytes: &[u8], at: &mut usize) -> Result<Option<Node>, String> {
        let end = u32_at(bytes, at)? as usize;
        let count = u32_at(bytes, at)? as usize;
        let props_len = u32_at(bytes, at)? as usize;
        let name_len = take(bytes, at, 1)?[0] as usize;
        if end == 0 {
            return Ok(None);
        }
        let name = String::from_utf8(take(bytes, at, name_len)?.to_vec()).map_err(|e| e.to_string())?;
        let props_start = *at;
        let mut properties = Vec::with_capacity(count.min(bytes.len()));
        for _ in 0..count {
            properties.push(decode_property(bytes, at)?);
        }
        if *at - props_start != props_len {
            return Err(format!("{name}: property bytes {props_len} declared, {} found", *at - props_start));
        }
        let mut children = Vec::new();
        if *at < end {
            while let Some(child) = decode_node(bytes, at)? {
                children.push(child);
            }
        }
        if *at != end {
            return Err(format!("{name}: record ends at {at}, declared {end}"));
        }
        Ok(Some(Node { name, properties, children }))
    }

    fn decode_property(bytes: &[u8], at: &mut usize) -> Result<Property, String> {
        let code = take(bytes, at, 1)?[0];
        let fixed = |at: &mut usize, n: usize| take(bytes, at, n).map(<[u8]>::to_vec);
        let array = |at: &mut usize, width: usize| -> Result<Vec<u8>, String> {
            let count = u32_at(bytes, at)? as usize;
            let encoding = u32_at(bytes, at)?;
            let len = u32_at(bytes, at)? as usize;
            if encoding != 0 || len != count * width {
                return Err(format!("array of {count} with encoding {encoding} and {len} bytes"));
            }
            fixed(at, len)
        };
        Ok(match code {
            b'C' => Property::Bool(fixed(at, 1)?[0] != 0),
            b'I' => Property::I32(i32::from_le_bytes(fixed(at, 4)?.try_into().map_err(|_| "I")?)),
            b'L' => Property::I64(i64::from_le_bytes(fixed(at, 8)?.try_into().map_err(|_| "L")?)),
            b'D' => Property::F64(f64::from_le_bytes(fixed(at, 8)?.try_into().map_err(|_| "D")?)),
            b'S' | b'R' => {
                let len = u32_at(bytes, at)? as usize;
                let b = fixed(at, len)?;
                if code == b'S' {
                    Property::Str(String::from_utf8(b).map_err(|e| e.to_string())?)
                } else {
                    Property::Raw(b)
                }
            }
            b'f' => {
                Property::F32s(array(at, 4)?.chunks(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
            }
            b'i' => {
                Property::I32s(array(at, 4)?.chunks(4).map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
            }
            b'd' => Property::F64s(
                array(at, 8)?.chunks(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect(),
            ),
            b'l' => Property::I64s(
                array(at, 8)?.chunks(8).map(|c| i64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect(),
            ),
            other => return Err(format!("unknown property type {:?} at byte {}", other as char, *at - 1)),
        })
    }
}

/// `P` records of a `Properties70` block.
fn p(name: &str, kind: &str, label: &str, flags: &str, values: Vec<P>) -> Node {
    let mut props = vec![P::Str(name.into()), P::Str(kind.into()), P::Str(label.into()), P::Str(flags.into())];
    props.extend(values);
    Node::new("P", props)
}

fn p_int(name: &str, v: i32) -> Node {
    p(name, "int", "Integer", "", vec![P::I32(v)])
}

fn p_f64(name: &str, v: f64) -> Node {
    p(name, "double", "Number", "", vec![P::F64(v)])
}

fn p_time(name: &str, v: i64) -> Node {
    p(name, "KTime", "Time", "", vec![P::I64(v)])
}

fn p_vec(name: &str, v: [f64; 3]) -> Node {
    p(name, name, "", "A", v.iter().map(|x| P::F64(*x)).collect())
}

fn props70(children: Vec<Node>) -> Node {
    Node::with("Properties70", vec![], children)
}

/// An object's name property: `name\0\x01Class`.
fn object_name(name: &str, class: &str) -> P {
    P::Str(format!("{name}\0\x01{class}"))
}

/// `FbxGlobalSettings::TimeMode` values with a fixed rate (mode, Hz), from the SDK's
/// `EMode`; anything else is `eCustom` (14) with `CustomFrameRate`.
const TIME_MODES: [(i32, f64); 13] = [
    (1, 120.0),
    (2, 100.0),
    (3, 60.0),
    (4, 50.0),
    (5, 48.0),
    (6, 30.0),
    (10, 25.0),
    (11, 24.0),
    (12, 1000.0),
    (15, 96.0),
    (16, 72.0),
    (17, 59.94),
    (18, 119.88),
];

fn time_mode(rate_hz: f64) -> i32 {
    TIME_MODES.iter().find(|(_, r)| (r - rate_hz).abs() < 1e-9).map_or(14, |(m, _)| *m)
}

/// Angle `a` plus the multiple of 360 degrees nearest `previous`.
fn unwrap_deg(a: f64, previous: f64) -> f64 {
    a - 360.0 * ((a - previous) / 360.0).round()
}

/// Builds the FBX document of `motion` (Y-up, lengths written in centimetres).
pub fn document(motion: &Motion) -> Result<Vec<Node>> {
    let joints = motion.skeleton.joints();
    let frames = motion.frame_count();
    if frames == 0 {
        return Err(Error::Unwritable("FBX: a motion without frames has no animation".into()));
    }
    let rate = motion.frame_rate_hz();
    let kept: Vec<usize> = (0..joints.len()).filter(|&i| !joints[i].is_end_site).collect();
    // Object ids: any unique positive numbers; 0 is the scene root.
    let mut next_id = 1_000_000i64;
    let mut id = || {
        next_id += 1;
        next_id
    };
    let model_ids: Vec<i64> = kept.iter().map(|_| id()).collect();
    let mut model_of = vec![None; joints.len()];
    for (n, &j) in kept.iter().enumerate() {
        model_of[j] = Some(model_ids[n]);
    }
    let times: Vec<i64> = (0..frames).map(|f| (f as f64 * KTIME_PER_SECOND as f64 / rate).round() as i64).collect();
    let stop = times.last().copied().unwrap_or(0);

    let mut objects = Vec::new();
    let mut connections = Vec::new();
    let oo = |child: i64, parent: i64| Node::new("C", vec![P::Str("OO".into()), P::I64(child), P::I64(parent)]);
    let op = |child: i64, parent: i64, property: &str| {
        Node::new("C", vec![P::Str("OP".into()), P::I64(child), P::I64(parent), P::Str(property.into())])
    };
    let (stack_id, layer_id) = (id(), id());
    let mut curve_nodes = 0usize;
    for (n, &j) in kept.iter().enumerate() {
        let joint = &joints[j];
        if joint.name.contains('\0') {
            return Err(Error::Unwritable(format!("FBX: joint name {:?} has a NUL", joint.name)));
        }
        let model = model_ids[n];
        let o = joint.offset_mm / 10.0;
        objects.push(Node::with(
            "Model",
            vec![P::I64(model), object_name(&joint.name, "Model"), P::Str("LimbNode".into())],
            vec![
                Node::new("Version", vec![P::I32(232)]),
                props70(vec![
                    p("RotationOrder", "enum", "", "", vec![P::I32(0)]),
                    p("InheritType", "enum", "", "", vec![P::I32(1)]),
                    p_vec("Lcl Translation", [o.x, o.y, o.z]),
                    p_vec("Lcl Rotation", [0.0; 3]),
                    p_vec("Lcl Scaling", [1.0; 3]),
                ]),
                Node::new("Shading", vec![P::Bool(true)]),
                Node::new("Culling", vec![P::Str("CullingOff".into())]),
            ],
        ));
        let attribute = id();
        objects.push(Node::with(
            "NodeAttribute",
            vec![P::I64(attribute), object_name(&joint.name, "NodeAttribute"), P::Str("LimbNode".into())],
            vec![Node::new("TypeFlags", vec![P::Str("Skeleton".into())]), props70(vec![p_f64("Size", 3.0)])],
        ));
        connections.push(oo(attribute, model));
        connections.push(oo(model, joint.parent.and_then(|p| model_of[p]).unwrap_or(0)));

        // The curves: rotation for every joint, translation for the root.
        let mut channels: Vec<(&str, &str, Vec<[f64; 3]>)> = Vec::new();
        let mut rotation = Vec::with_capacity(frames);
        let mut previous: Option<[f64; 3]> = None;
        for f in 0..frames {
            // Our ZYX order is R = Rz * Ry * Rx, FBX's eEulerXYZ; its angles come z, y, x.
            let [z, y, x] = EulerOrder::ZYX.from_quat_deg(&motion.local_rotations(f)[j]);
            let mut a = [x, y, z];
            if let Some(prev) = previous {
                for (v, p) in a.iter_mut().zip(prev) {
                    *v = unwrap_deg(*v, p);
                }
            }
            previous = Some(a);
            rotation.push(a);
        }
        channels.push(("R", "Lcl Rotation", rotation));
        if joint.parent.is_none() {
            let translation = (0..frames)
                .map(|f| {
                    let p = motion.root_position_mm(f) / 10.0;
                    [p.x, p.y, p.z]
                })
                .collect();
            channels.push(("T", "Lcl Translation", translation));
        }
        for (short, property, values) in channels {
            if values.iter().flatten().any(|v| !v.is_finite()) {
                return Err(Error::Unwritable(format!("FBX: joint {:?} has a non-finite {property}", joint.name)));
            }
            let node_id = id();
            curve_nodes += 1;
            let first = values[0];
            objects.push(Node::with(
                "AnimationCurveNode",
                vec![P::I64(node_id), object_name(short, "AnimCurveNode"), P::Str(String::new())],
                vec![props70(vec![
                    p("d|X", "Number", "", "A", vec![P::F64(first[0])]),
                    p("d|Y", "Number", "", "A", vec![P::F64(first[1])]),
                    p("d|Z", "Number", "", "A", vec![P::F64(first[2])]),
                ])],
            ));
            connections.push(oo(node_id, layer_id));
            connections.push(op(node_id, model, property));
            for (axis, name) in ["d|X", "d|Y", "d|Z"].iter().enumerate() {
                let curve = id();
                let keys: Vec<f32> = values.iter().map(|v| v[axis] as f32).collect();
                objects.push(Node::with(
                    "AnimationCurve",
                    vec![P::I64(curve), object_name("", "AnimCurve"), P::Str(String::new())],
                    vec![
                        Node::new("Default", vec![P::F64(first[axis])]),
                        Node::new("KeyVer", vec![P::I32(4008)]),
                        Node::new("KeyTime", vec![P::I64s(times.clone())]),
                        Node::new("KeyValueFloat", vec![P::F32s(keys)]),
                        // One attribute set for every key: linear interpolation (0x4).
                        Node::new("KeyAttrFlags", vec![P::I32s(vec![0x4])]),
                        Node::new("KeyAttrDataFloat", vec![P::F32s(vec![0.0; 4])]),
                        Node::new("KeyAttrRefCount", vec![P::I32s(vec![frames as i32])]),
                    ],
                ));
                connections.push(op(curve, node_id, name));
            }
        }
    }
    objects.push(Node::with(
        "AnimationStack",
        vec![P::I64(stack_id), object_name("Take 001", "AnimStack"), P::Str(String::new())],
        vec![props70(vec![
            p_time("LocalStart", 0),
            p_time("LocalStop", stop),
            p_time("ReferenceStart", 0),
            p_time("ReferenceStop", stop),
        ])],
    ));
    objects.push(Node::new(
        "AnimationLayer",
        vec![P::I64(layer_id), object_name("BaseLayer", "AnimLayer"), P::Str(String::new())],
    ));
    connections.push(oo(layer_id, stack_id));

    let counts = [
        ("GlobalSettings", 1),
        ("Model", kept.len()),
        ("NodeAttribute", kept.len()),
        ("AnimationStack", 1),
        ("AnimationLayer", 1),
        ("AnimationCurveNode", curve_nodes),
        ("AnimationCurve", 3 * curve_nodes),
    ];
    let mut definitions = vec![
        Node::new("Version", vec![P::I32(100)]),
        Node::new("Count", vec![P::I32(counts.iter().map(|(_, c)| *c as i32).sum())]),
    ];
    for (kind, count) in counts {
        definitions.push(Node::with(
            "ObjectType",
            vec![P::Str(kind.into())],
            vec![Node::new("Count", vec![P::I32(count as i32)])],
        ));
    }

    let creator = format!("locap {}", env!("CARGO_PKG_VERSION"));
    let mode = time_mode(rate);
    Ok(vec![
        Node::with(
            "FBXHeaderExtension",
            vec![],
            vec![
                Node::new("FBXHeaderVersion", vec![P::I32(1003)]),
                Node::new("FBXVersion", vec![P::I32(binary::VERSION as i32)]),
                Node::new("Creator", vec![P::Str(creator.clone())]),
            ],
        ),
        Node::new("Creator", vec![P::Str(creator)]),
        Node::with(
            "GlobalSettings",
            vec![],
            vec![
                Node::new("Version", vec![P::I32(1000)]),
                props70(vec![
                    p_int("UpAxis", 1),
                    p_int("UpAxisSign", 1),
                    p_int("FrontAxis", 2),
                    p_int("FrontAxisSign", 1),
                    p_int("CoordAxis", 0),
                    p_int("CoordAxisSign", 1),
                    p_int("OriginalUpAxis", 1),
                    p_int("OriginalUpAxisSign", 1),
                    p_f64("UnitScaleFactor", 1.0),
                    p_f64("OriginalUnitScaleFactor", 1.0),
                    p("TimeMode", "enum", "", "", vec![P::I32(mode)]),
                    p_time("TimeSpanStart", 0),
                    p_time("TimeSpanStop", stop),
                    p_f64("CustomFrameRate", rate),
                ]),
            ],
        ),
        Node::with("Definitions", vec![], definitions),
        Node::with("Objects", vec![], objects),
        Node::with("Connections", vec![], connections),
    ])
}

/// Writes `motion` (Y-up) as binary FBX 7.4.
pub fn write_fbx(motion: &Motion, w: &mut dyn Write) -> Result<()> {
    binary::write_file(&document(motion)?, w)
}

/// Writes `motion` as an FBX file at `path`, atomically (see [`write_fbx`]).
pub fn write_fbx_path(motion: &Motion, path: &Path) -> Result<()> {
    write_atomically(path, |w| write_fbx(motion, w))
}

#[cfg(test)]
mod tests {
    use super::binary::{Node, Property, decode_file, encode_file};
    use super::*;
    use locap_core::{Joint, Quat, Skeleton, Vec3};
    use proptest::prelude::*;

    fn find<'a>(nodes: &'a [Node], name: &str) -> Vec<&'a Node> {
        nodes.iter().filter(|n| n.name == name).collect()
    }

    fn motion() -> Motion {
        let mut tip = Joint::new("tip", Some(1), Vec3::new(0.0, 80.0, 0.0));
        tip.is_end_site = true;
        let sk = Skeleton::new(vec![
            Joint::new("hips", None, Vec3::new(0.0, 900.0, 0.0)),
            Joint::new("spine", Some(0), Vec3::new(0.0, 100.0, 20.0)),
            tip,
        ])
        .unwrap();
        let mut rotations = Vec::new();
        for f in 0..3 {
            let a = 170.0 + 10.0 * f as f64;
            rotations.extend([EulerOrder::ZYX.to_quat_deg([a, 20.0, 30.0]), Quat::identity(), Quat::identity()]);
        }
        let roots = (0..3).map(|f| Vec3::new(10.0 * f as f64, 950.0, 0.0)).collect();
        Motion::new(sk, rotations, roots, 120.0).unwrap()
    }

    #[test]
    fn the_document_reads_back_with_the_motion() {
        let bytes = encode_file(&document(&motion()).unwrap()).unwrap();
        assert_eq!(&bytes[..23], b"Kaydara FBX Binary  \0\x1a\0");
        assert_eq!(u32::from_le_bytes(bytes[23..27].try_into().unwrap()), 7400);
        // The footer: 16-byte aligned version, zeros and the fixed tail.
        assert_eq!(&bytes[bytes.len() - 16..bytes.len() - 12], &[0xf8, 0x5a, 0x8c, 0x6a]);
        assert_eq!(u32::from_le_bytes(bytes[bytes.len() - 140..bytes.len() - 136].try_into().unwrap()), 7400);
        let top = decode_file(&bytes).unwrap();
        let objects = &find(&top, "Objects")[0].children;
        let models = find(objects, "Model");
        assert_eq!(models.len(), 2, "end sites are not joints");
        assert_eq!(models[0].properties[1], Property::Str("hips\0\x01Model".into()));
        assert_eq!(models[0].properties[2], Property::Str("LimbNode".into()));
        // Lcl Translation at rest: the offset in centimetres.
        let lcl = &models[1].children[1].children[2];
        assert_eq!(lcl.properties[4..], [Property::F64(0.0), Property::F64(10.0), Property::F64(2.0)]);
        // 2 rotation nodes + 1 translation node, three curves each, keyed at every frame.
        assert_eq!(find(objects, "AnimationCurveNode").len(), 3);
        let curves = find(objects, "AnimationCurve");
        assert_eq!(curves.len(), 9);
        let times = &find(&curves[0].children, "KeyTime")[0].properties[0];
        assert_eq!(*times, Property::I64s(vec![0, KTIME_PER_SECOND / 120, 2 * KTIME_PER_SECOND / 120]));
        // The hips' Z rotation crosses 180 degrees: unwrapped, not back to -170.
        let z = &find(&curves[2].children, "KeyValueFloat")[0].properties[0];
        match z {
            Property::F32s(v) => {
                assert!((v[0] - 170.0).abs() < 1e-3 && (v[2] - 190.0).abs() < 1e-3, "{v:?}");
            }
            other => panic!("{other:?}"),
        }
        // Root translation in cm: the hips' second curve node (after their rotation).
        let x = &find(&curves[3].children, "KeyValueFloat")[0].properties[0];
        assert_eq!(*x, Property::F32s(vec![0.0, 1.0, 2.0]));
        // 120 Hz has its own TimeMode (1); Y-up, centimetres.
        let settings = &find(&top, "GlobalSettings")[0].children[1].children;
        let value = |name: &str| {
            settings.iter().find(|p| p.properties[0] == Property::Str(name.into())).map(|p| p.properties[4].clone())
        };
        assert_eq!(value("TimeMode"), Some(Property::I32(1)));
        assert_eq!(value("UpAxis"), Some(Property::I32(1)));
        assert_eq!(value("UnitScaleFactor"), Some(Property::F64(1.0)));
        let connections = &find(&top, "Connections")[0].children;
        assert!(connections.iter().any(|c| c.properties.get(3) == Some(&Property::Str("Lcl Rotation".into()))));
    }

    #[test]
    fn odd_rates_are_custom() {
        assert_eq!(time_mode(120.0), 1);
        assert_eq!(time_mode(25.0), 10);
        assert_eq!(time_mode(128.0), 14);
    }

    fn property() -> impl Strategy<Value = Property> {
        prop_oneof![
            any::<bool>().prop_map(Property::Bool),
            any::<i32>().prop_map(Property::I32),
            any::<i64>().prop_map(Property::I64),
            (-1e9f64..1e9).prop_map(Property::F64),
            "[a-z\\x00\\x01]{0,12}".prop_map(Property::Str),
            proptest::collection::vec(any::<u8>(), 0..20).prop_map(Property::Raw),
            proptest::collection::vec(-1e6f32..1e6, 0..20).prop_map(Property::F32s),
            proptest::collection::vec(-1e6f64..1e6, 0..20).prop_map(Property::F64s),
            proptest::collection::vec(any::<i32>(), 0..20).prop_map(Property::I32s),
            proptest::collection::vec(any::<i64>(), 0..20).prop_map(Property::I64s),
        ]
    }

    fn node() -> impl Strategy<Value = Node> {
        let leaf = ("[A-Za-z]{1,10}", proptest::collection::vec(property(), 0..4))
            .prop_map(|(name, properties)| Node { name, properties, children: vec![] });
        leaf.prop_recursive(3, 24, 4, |inner| {
            ("[A-Za-z]{1,10}", proptest::collection::vec(property(), 0..3), proptest::collection::vec(inner, 1..4))
                .prop_map(|(name, properties, children)| Node { name, properties, children })
        })
    }

    proptest! {
        /// Every tree of records encodes to bytes that decode to the same tree, with every
        /// record's end offset where the next one starts.
        #[test]
        fn encoding_round_trips(top in proptest::collection::vec(node(), 0..4)) {
            let bytes = encode_file(&top).unwrap();
            prop_assert_eq!(decode_file(&bytes).unwrap(), top);
        }
    }

    #[test]
    fn long_names_are_refused() {
        let n = Node::new(&"x".repeat(256), vec![]);
        assert!(encode_file(&[n]).is_err());
    }
}
