//! glTF 2.0 (`.gltf` and `.glb`): a solved motion as a skinned, animated skeleton for game
//! engines, web viewers and Blender.
//!
//! Written to the Khronos glTF 2.0 specification (the document model is the `gltf-json`
//! crate's): section 3.4 fixes the frame, "+Y is up, +Z is forward (the front of the
//! asset), the units for all linear distances are meters"; 3.7 skins (joints, inverse bind
//! matrices); 3.11 animations; 4.4 the binary container (GLB).
//!
//! # What is written
//! - **One node per joint** (end sites are not joints in glTF; they only mark a BVH bone's
//!   tip), parents first, named as in the skeleton. A node's rest translation is the joint's
//!   offset, its rest rotation the identity, as in [`locap_core::skeleton`].
//! - **A skin** over those nodes with their inverse bind matrices (the inverse of each
//!   joint's global rest transform, a translation), and a stick-figure mesh it deforms: one
//!   vertex per joint, fully weighted to it, one line per bone. Importers build their
//!   armature from the skin; the lines make the skeleton visible in any viewer.
//! - **One animation** at the motion's frame rate: one time per frame (`frame / rate`
//!   seconds), a rotation channel per joint (linear, i.e. spherical, interpolation; each
//!   quaternion on the side of the previous one so no interpolation turns the long way) and
//!   a translation channel for the root.
//! - **Markers, optionally**: one node per marker under a `markers` node, its translation
//!   animated; a marker missing in a frame is scaled to zero there (step interpolation), as
//!   glTF has no "missing".
//!
//! The motion and markers must already be Y-up (see [`crate::axes`]); lengths go from
//! millimetres to metres. Values are stored as 32-bit floats, which the specification
//! requires for animation data: about 0.1 micrometre at 10 m from the origin.

use crate::atomic::write_atomically;
use crate::{Error, Result};
use gltf_json as json;
use json::validation::Checked::Valid;
use json::validation::USize64;
use locap_core::{Motion, Quat, Take, UpAxis, Vec3};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::Path;

/// What goes into a glTF file besides the motion.
#[derive(Debug, Clone, Copy, Default)]
pub struct GltfContent<'a> {
    /// Markers to add as animated nodes, Y-up, with the motion's frames and rate.
    pub markers: Option<&'a Take>,
}

/// Collects the binary buffer and its views and accessors.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
}

impl Builder {
    /// Appends `data` (4-byte aligned) as a buffer view and an accessor of `count` elements.
    fn accessor(
        &mut self,
        data: &[u8],
        count: usize,
        component: json::accessor::ComponentType,
        kind: json::accessor::Type,
        min_max: Option<(Vec<f32>, Vec<f32>)>,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::Accessor> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(data);
        let view = self.root.push(json::buffer::View {
            buffer: json::Index::new(0),
            byte_length: USize64::from(data.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            target: target.map(Valid),
        });
        let (min, max) = match min_max {
            Some((min, max)) => (Some(json::Value::from(min)), Some(json::Value::from(max))),
            None => (None, None),
        };
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: Default::default(),
            extras: Default::default(),
            type_: Valid(kind),
            min,
            max,
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    fn floats(
        &mut self,
        values: &[f32],
        kind: json::accessor::Type,
        width: usize,
        bounds: bool,
    ) -> json::Index<json::Accessor> {
        self.floats_for(values, kind, width, bounds, None)
    }

    /// [`Builder::floats`] in a buffer view with a GPU `target` (vertex attributes).
    fn floats_for(
        &mut self,
        values: &[f32],
        kind: json::accessor::Type,
        width: usize,
        bounds: bool,
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::Accessor> {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let min_max = bounds.then(|| bounds_of(values, width));
        self.accessor(&bytes, values.len() / width, json::accessor::ComponentType::F32, kind, min_max, target)
    }
}

/// Per-component minimum and maximum of `values` taken `width` at a time.
fn bounds_of(values: &[f32], width: usize) -> (Vec<f32>, Vec<f32>) {
    let mut min = vec![f32::INFINITY; width];
    let mut max = vec![f32::NEG_INFINITY; width];
    for chunk in values.chunks(width) {
        for (i, v) in chunk.iter().enumerate() {
            min[i] = min[i].min(*v);
            max[i] = max[i].max(*v);
        }
    }
    (min, max)
}

fn metres(p: Vec3) -> [f32; 3] {
    [(p.x / 1000.0) as f32, (p.y / 1000.0) as f32, (p.z / 1000.0) as f32]
}

fn finite(values: &[f32], what: &str) -> Result<()> {
    match values.iter().find(|v| !v.is_finite()) {
        Some(v) => Err(Error::Unwritable(format!("glTF: {what} is {v} (or too large for a 32-bit float)"))),
        None => Ok(()),
    }
}

/// Builds the glTF document and its binary buffer (not yet referenced by a buffer).
fn build(motion: &Motion, content: GltfContent<'_>) -> Result<(json::Root, Vec<u8>)> {
    let joints = motion.skeleton.joints();
    let frames = motion.frame_count();
    if frames == 0 {
        return Err(Error::Unwritable("glTF: a motion without frames has no animation".into()));
    }
    if let Some(take) = content.markers {
        if take.frame_count() != frames {
            return Err(Error::Unwritable(format!(
                "glTF: {} marker frames for a motion of {frames} frames",
                take.frame_count()
            )));
        }
        if take.up_axis != UpAxis::Y {
            return Err(Error::Unwritable("glTF: markers must be Y-up (see locap_io::axes)".into()));
        }
    }
    // The joints glTF gets: every joint but the end sites, numbered in skeleton order.
    let kept: Vec<usize> = (0..joints.len()).filter(|&i| !joints[i].is_end_site).collect();
    if kept.len() > usize::from(u16::MAX) {
        return Err(Error::Unwritable(format!("glTF: {} joints; a skin holds at most 65535", kept.len())));
    }
    let mut node_of = vec![None; joints.len()];
    for (n, &j) in kept.iter().enumerate() {
        node_of[j] = Some(n);
    }

    let mut b = Builder { root: json::Root::default(), bin: Vec::new() };
    b.root.asset = json::Asset {
        copyright: None,
        extensions: Default::default(),
        extras: Default::default(),
        generator: Some(format!(
            "locap {}: metres, Y-up (a Z-up lab's (x, y, z) written as (x, z, -y)), {} Hz",
            env!("CARGO_PKG_VERSION"),
            motion.frame_rate_hz()
        )),
        min_version: None,
        version: "2.0".into(),
    };

    // Joint nodes at rest; children filled in once every node exists.
    let mut rest_global_m: Vec<[f32; 3]> = Vec::with_capacity(kept.len());
    for &j in &kept {
        let joint = &joints[j];
        let offset = metres(joint.offset_mm);
        finite(&offset, "a joint offset")?;
        let parent_global = joint.parent.and_then(|p| node_of[p]).map(|n| rest_global_m[n]).unwrap_or([0.0; 3]);
        rest_global_m.push([parent_global[0] + offset[0], parent_global[1] + offset[1], parent_global[2] + offset[2]]);
        b.root.push(json::Node { name: Some(joint.name.clone()), translation: Some(offset), ..node() });
    }
    for (n, &j) in kept.iter().enumerate() {
        let children: Vec<json::Index<json::Node>> = kept
            .iter()
            .enumerate()
            .filter(|(_, c)| joints[**c].parent == Some(j))
            .map(|(m, _)| json::Index::new(m as u32))
            .collect();
        if !children.is_empty() {
            b.root.nodes[n].children = Some(children);
        }
    }

    // The skin: inverse bind matrices (column-major 4x4, a translation by minus the rest
    // position) and the stick figure it deforms.
    let mut ibm = Vec::with_capacity(16 * kept.len());
    for p in &rest_global_m {
        ibm.extend_from_slice(&[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -p[0], -p[1], -p[2], 1.0]);
    }
    let ibm = b.floats(&ibm, json::accessor::Type::Mat4, 16, false);
    let skin = b.root.push(json::Skin {
        extensions: Default::default(),
        extras: Default::default(),
        inverse_bind_matrices: Some(ibm),
        joints: (0..kept.len()).map(|n| json::Index::new(n as u32)).collect(),
        name: Some("skeleton".into()),
        skeleton: Some(json::Index::new(0)),
    });
    let positions: Vec<f32> = rest_global_m.iter().flatten().copied().collect();
    let vertex = Some(json::buffer::Target::ArrayBuffer);
    let positions = b.floats_for(&positions, json::accessor::Type::Vec3, 3, true, vertex);
    let influences: Vec<u8> = (0..kept.len() as u16).flat_map(|n| [n, 0, 0, 0]).flat_map(u16::to_le_bytes).collect();
    let influences = b.accessor(
        &influences,
        kept.len(),
        json::accessor::ComponentType::U16,
        json::accessor::Type::Vec4,
        None,
        vertex,
    );
    let weights: Vec<f32> = (0..kept.len()).flat_map(|_| [1.0, 0.0, 0.0, 0.0]).collect();
    let weights = b.floats_for(&weights, json::accessor::Type::Vec4, 4, false, vertex);
    let mut lines: Vec<u32> = Vec::new();
    for (n, &j) in kept.iter().enumerate() {
        if let Some(p) = joints[j].parent.and_then(|p| node_of[p]) {
            lines.extend([p as u32, n as u32]);
        }
    }
    let mut attributes = BTreeMap::new();
    attributes.insert(Valid(json::mesh::Semantic::Positions), positions);
    attributes.insert(Valid(json::mesh::Semantic::Joints(0)), influences);
    attributes.insert(Valid(json::mesh::Semantic::Weights(0)), weights);
    // A single joint has no bone: a point then, so the mesh still shows where it is.
    let (mode, indices) = if lines.is_empty() {
        (json::mesh::Mode::Points, None)
    } else {
        let bytes: Vec<u8> = lines.iter().flat_map(|v| v.to_le_bytes()).collect();
        let count = lines.len();
        let indices = b.accessor(
            &bytes,
            count,
            json::accessor::ComponentType::U32,
            json::accessor::Type::Scalar,
            None,
            Some(json::buffer::Target::ElementArrayBuffer),
        );
        (json::mesh::Mode::Lines, Some(indices))
    };
    let mesh = b.root.push(json::Mesh {
        extensions: Default::default(),
        extras: Default::default(),
        name: Some("bones".into()),
        primitives: vec![json::mesh::Primitive {
            attributes,
            extensions: Default::default(),
            extras: Default::default(),
            indices,
            material: None,
            mode: Valid(mode),
            targets: None,
        }],
        weights: None,
    });
    let figure = b.root.push(json::Node { name: Some("bones".into()), mesh: Some(mesh), skin: Some(skin), ..node() });
    let mut scene_nodes = vec![json::Index::new(0), figure];

    // The animation.
    let rate = motion.frame_rate_hz();
    let times: Vec<f32> = (0..frames).map(|f| (f as f64 / rate) as f32).collect();
    let times = b.floats(&times, json::accessor::Type::Scalar, 1, true);
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    let mut channel = |node: json::Index<json::Node>,
                       path: json::animation::Property,
                       output: json::Index<json::Accessor>,
                       interpolation: json::animation::Interpolation| {
        samplers.push(json::animation::Sampler {
            extensions: Default::default(),
            extras: Default::default(),
            input: times,
            interpolation: Valid(interpolation),
            output,
        });
        channels.push(json::animation::Channel {
            sampler: json::Index::new(samplers.len() as u32 - 1),
            target: json::animation::Target {
                extensions: Default::default(),
                extras: Default::default(),
                node,
                path: Valid(path),
            },
            extensions: Default::default(),
            extras: Default::default(),
        });
    };
    let mut root_track = Vec::with_capacity(3 * frames);
    for f in 0..frames {
        root_track.extend(metres(motion.root_position_mm(f)));
    }
    finite(&root_track, "a root position")?;
    let out = b.floats(&root_track, json::accessor::Type::Vec3, 3, false);
    channel(json::Index::new(0), json::animation::Property::Translation, out, json::animation::Interpolation::Linear);
    for (n, &j) in kept.iter().enumerate() {
        let mut track = Vec::with_capacity(4 * frames);
        let mut previous: Option<Quat> = None;
        for f in 0..frames {
            let mut q = motion.local_rotations(f)[j];
            // q and -q are one rotation; interpolation takes the short way only between
            // quaternions on the same side.
            if let Some(p) = previous
                && p.coords.dot(&q.coords) < 0.0
            {
                q = Quat::new_unchecked(-q.into_inner());
            }
            previous = Some(q);
            let c = q.coords; // (i, j, k, w): glTF's (x, y, z, w) order.
            track.extend([c.x as f32, c.y as f32, c.z as f32, c.w as f32]);
        }
        finite(&track, "a rotation")?;
        let out = b.floats(&track, json::accessor::Type::Vec4, 4, false);
        channel(
            json::Index::new(n as u32),
            json::animation::Property::Rotation,
            out,
            json::animation::Interpolation::Linear,
        );
    }

    if let Some(take) = content.markers {
        let first_marker = b.root.nodes.len() as u32 + 1;
        let markers: Vec<json::Index<json::Node>> =
            (0..take.marker_count()).map(|m| json::Index::new(first_marker + m as u32)).collect();
        let group = b.root.push(json::Node { name: Some("markers".into()), children: Some(markers), ..node() });
        scene_nodes.push(group);
        for m in 0..take.marker_count() {
            let trajectory = take.trajectory_mm(m);
            // Where a marker is missing it keeps its last position (its first before it is
            // seen) and is scaled to zero.
            let first_seen = trajectory.iter().flatten().next().copied();
            let mut track = Vec::with_capacity(3 * frames);
            let mut scale = Vec::with_capacity(3 * frames);
            let mut last = first_seen.unwrap_or_else(Vec3::zeros);
            for p in &trajectory {
                if let Some(p) = p {
                    last = *p;
                }
                track.extend(metres(last));
                let s = if p.is_some() { 1.0 } else { 0.0 };
                scale.extend([s, s, s]);
            }
            finite(&track, "a marker position")?;
            let always_missing = first_seen.is_none();
            let node_index = b.root.push(json::Node {
                name: Some(take.markers()[m].full()),
                translation: Some(metres(last)),
                scale: always_missing.then_some([0.0; 3]),
                ..node()
            });
            if always_missing {
                continue;
            }
            let out = b.floats(&track, json::accessor::Type::Vec3, 3, false);
            channel(node_index, json::animation::Property::Translation, out, json::animation::Interpolation::Linear);
            if trajectory.iter().any(Option::is_none) {
                let out = b.floats(&scale, json::accessor::Type::Vec3, 3, false);
                channel(node_index, json::animation::Property::Scale, out, json::animation::Interpolation::Step);
            }
        }
    }
    b.root.push(json::Animation {
        extensions: Default::default(),
        extras: Default::default(),
        channels,
        name: Some("take".into()),
        samplers,
    });
    let scene = b.root.push(json::Scene {
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        nodes: scene_nodes,
    });
    b.root.scene = Some(scene);
    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    Ok((b.root, b.bin))
}

/// A node with nothing set.
fn node() -> json::Node {
    json::Node {
        camera: None,
        children: None,
        extensions: Default::default(),
        extras: Default::default(),
        matrix: None,
        mesh: None,
        name: None,
        rotation: None,
        scale: None,
        translation: None,
        skin: None,
        weights: None,
    }
}

fn buffer(length: usize, uri: Option<String>) -> json::Buffer {
    json::Buffer {
        byte_length: USize64::from(length),
        extensions: Default::default(),
        extras: Default::default(),
        name: None,
        uri,
    }
}

fn to_json(root: &json::Root) -> Result<Vec<u8>> {
    json::serialize::to_vec(root).map_err(|e| Error::Unwritable(format!("glTF: {e}")))
}

/// Writes `motion` (Y-up) as a `.gltf` JSON file with its buffer embedded as a base64 data
/// URI, so the file stands alone.
pub fn write_gltf(motion: &Motion, content: GltfContent<'_>, w: &mut dyn Write) -> Result<()> {
    use base64::Engine;
    let (mut root, bin) = build(motion, content)?;
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    root.buffers.push(buffer(bin.len(), Some(uri)));
    w.write_all(&to_json(&root)?)?;
    Ok(())
}

/// Writes `motion` (Y-up) as a binary glTF (`.glb`): the 12-byte header, the JSON chunk
/// (padded with spaces) and the BIN chunk (padded with zeros), as section 4.4 lays them out.
pub fn write_glb(motion: &Motion, content: GltfContent<'_>, w: &mut dyn Write) -> Result<()> {
    let (mut root, bin) = build(motion, content)?;
    root.buffers.push(buffer(bin.len(), None));
    let mut text = to_json(&root)?;
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let total = 12 + 8 + text.len() + 8 + bin.len();
    let total = u32::try_from(total).map_err(|_| Error::Unwritable(format!("GLB: {total} bytes; at most 4 GiB")))?;
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    // Both lengths are below `total`, which fits a u32.
    w.write_all(&(text.len() as u32).to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(&text)?;
    w.write_all(&(bin.len() as u32).to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    w.write_all(&bin)?;
    Ok(())
}

/// Writes `motion` to `path`, atomically: binary glTF if the name ends in `.glb`, else JSON
/// glTF.
pub fn write_gltf_path(motion: &Motion, content: GltfContent<'_>, path: &Path) -> Result<()> {
    let binary = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    write_atomically(path, |w| if binary { write_glb(motion, content, w) } else { write_gltf(motion, content, w) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{EulerOrder, Joint, MarkerName, Skeleton};

    /// A three-joint chain with an end site, turning over four frames.
    pub(crate) fn chain() -> Motion {
        let mut tip = Joint::new("tip", Some(2), Vec3::new(0.0, 80.0, 0.0));
        tip.is_end_site = true;
        let sk = Skeleton::new(vec![
            Joint::new("hips", None, Vec3::new(0.0, 900.0, 0.0)),
            Joint::new("spine", Some(0), Vec3::new(0.0, 100.0, 0.0)),
            Joint::new("neck", Some(1), Vec3::new(0.0, 400.0, 50.0)),
            tip,
        ])
        .unwrap();
        let mut rotations = Vec::new();
        let mut roots = Vec::new();
        for f in 0..4 {
            let a = f as f64 * 60.0;
            rotations.extend([
                EulerOrder::ZXY.to_quat_deg([a, 10.0, -a / 2.0]),
                EulerOrder::ZXY.to_quat_deg([0.0, a, 0.0]),
                EulerOrder::XYZ.to_quat_deg([-a, 5.0, 175.0]),
                Quat::identity(),
            ]);
            roots.push(Vec3::new(100.0 * f as f64, 950.0, -20.0));
        }
        Motion::new(sk, rotations, roots, 120.0).unwrap()
    }

    /// The bytes of accessor `index` of a document whose buffer is `bin`, as f32s.
    fn floats(root: &json::Root, bin: &[u8], index: json::Index<json::Accessor>) -> Vec<f32> {
        let accessor = &root.accessors[index.value()];
        let view = &root.buffer_views[accessor.buffer_view.unwrap().value()];
        let start = view.byte_offset.unwrap().0 as usize;
        bin[start..start + view.byte_length.0 as usize]
            .chunks(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    }

    /// Reads a written file back through `gltf-json` and the buffer, rebuilds every joint's
    /// global position from the nodes and the animation, and compares it with the motion's
    /// forward kinematics.
    fn check_round_trip(root: &json::Root, bin: &[u8], motion: &Motion) {
        assert_eq!(root.asset.version, "2.0");
        let skin = &root.skins[0];
        assert_eq!(skin.joints.len(), 3, "end sites are not joints");
        let animation = &root.animations[0];
        let times = floats(root, bin, animation.samplers[0].input);
        assert_eq!(times.len(), motion.frame_count());
        assert!((times[1] - 1.0 / 120.0).abs() < 1e-7);
        // Per node, its animated rotation and translation tracks.
        let mut rotation: Vec<Option<Vec<f32>>> = vec![None; root.nodes.len()];
        let mut translation: Vec<Option<Vec<f32>>> = vec![None; root.nodes.len()];
        for channel in &animation.channels {
            let sampler = &animation.samplers[channel.sampler.value()];
            let values = floats(root, bin, sampler.output);
            match channel.target.path {
                Valid(json::animation::Property::Rotation) => rotation[channel.target.node.value()] = Some(values),
                Valid(json::animation::Property::Translation) => {
                    translation[channel.target.node.value()] = Some(values)
                }
                _ => {}
            }
        }
        let mut parent = vec![None; root.nodes.len()];
        for (i, n) in root.nodes.iter().enumerate() {
            for c in n.children.iter().flatten() {
                parent[c.value()] = Some(i);
            }
        }
        for f in 0..motion.frame_count() {
            let fk = motion.forward_kinematics(f);
            let mut global: Vec<(Quat, Vec3)> = Vec::new();
            for (i, node) in root.nodes.iter().enumerate().take(3) {
                let t = match &translation[i] {
                    Some(v) => Vec3::new(v[3 * f] as f64, v[3 * f + 1] as f64, v[3 * f + 2] as f64),
                    None => {
                        let t = node.translation.unwrap();
                        Vec3::new(t[0] as f64, t[1] as f64, t[2] as f64)
                    }
                };
                let r = rotation[i].as_ref().unwrap();
                let q = Quat::from_quaternion(nalgebra::Quaternion::new(
                    r[4 * f + 3] as f64,
                    r[4 * f] as f64,
                    r[4 * f + 1] as f64,
                    r[4 * f + 2] as f64,
                ));
                global.push(match parent[i] {
                    None => (q, t),
                    Some(p) => (global[p].0 * q, global[p].1 + global[p].0 * t),
                });
                let expect = fk.positions_mm[motion.skeleton.index_of(node.name.as_deref().unwrap()).unwrap()] / 1000.0;
                assert!((global[i].1 - expect).norm() < 1e-6, "frame {f}, node {i}: {} vs {expect}", global[i].1);
            }
        }
        // The inverse bind matrices undo the rest positions.
        let ibm = floats(root, bin, skin.inverse_bind_matrices.unwrap());
        for (got, want) in ibm[16 * 2 + 12..16 * 2 + 15].iter().zip([0.0, -1.4, -0.05]) {
            assert!((got - want).abs() < 1e-6, "{ibm:?}");
        }
    }

    #[test]
    fn gltf_and_glb_read_back_to_the_motion() {
        use base64::Engine;
        let motion = chain();
        let mut out = Vec::new();
        write_gltf(&motion, GltfContent::default(), &mut out).unwrap();
        let root = json::Root::from_slice(&out).unwrap();
        let uri = root.buffers[0].uri.as_deref().unwrap();
        let bin = base64::engine::general_purpose::STANDARD
            .decode(uri.strip_prefix("data:application/octet-stream;base64,").unwrap())
            .unwrap();
        assert_eq!(bin.len() as u64, root.buffers[0].byte_length.0);
        check_round_trip(&root, &bin, &motion);

        let mut glb = Vec::new();
        write_glb(&motion, GltfContent::default(), &mut glb).unwrap();
        assert_eq!(&glb[..4], b"glTF");
        assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
        let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
        assert_eq!(&glb[16..20], b"JSON");
        let root = json::Root::from_slice(&glb[20..20 + json_len]).unwrap();
        let bin_at = 20 + json_len;
        assert_eq!(&glb[bin_at + 4..bin_at + 8], b"BIN\0");
        check_round_trip(&root, &glb[bin_at + 8..], &motion);
    }

    #[test]
    fn markers_are_animated_nodes_hidden_where_missing() {
        let motion = chain();
        let mut take = Take::from_samples(
            vec![MarkerName::parse("LFWT"), MarkerName::parse("NEVER")],
            &[Some(Vec3::new(1000.0, 0.0, 0.0)), None, None, None, Some(Vec3::new(0.0, 2000.0, 0.0)), None, None, None],
            120.0,
        )
        .unwrap();
        assert!(write_gltf(&motion, GltfContent { markers: Some(&take) }, &mut Vec::new()).is_err(), "Z-up markers");
        take.up_axis = UpAxis::Y;
        let mut out = Vec::new();
        write_gltf(&motion, GltfContent { markers: Some(&take) }, &mut out).unwrap();
        let root = json::Root::from_slice(&out).unwrap();
        let names: Vec<&str> = root.nodes.iter().filter_map(|n| n.name.as_deref()).collect();
        assert_eq!(names, ["hips", "spine", "neck", "bones", "markers", "LFWT", "NEVER"]);
        // A marker never seen is a node scaled to zero; the other one gets a translation and a
        // step scale track (it is missing in frames 1 and 3).
        assert_eq!(root.nodes[6].scale, Some([0.0; 3]));
        let tracks: Vec<_> = root.animations[0].channels.iter().filter(|c| c.target.node.value() == 5).collect();
        assert_eq!(tracks.len(), 2);
        assert!(
            root.animations[0].samplers.iter().any(|s| s.interpolation == Valid(json::animation::Interpolation::Step))
        );
    }

    #[test]
    fn unwritable_motions_are_errors() {
        let m = chain();
        let empty = Motion::new(m.skeleton.clone(), vec![], vec![], 120.0).unwrap();
        assert!(matches!(write_glb(&empty, GltfContent::default(), &mut Vec::new()), Err(Error::Unwritable(_))));
        let far = Motion::new(m.skeleton.clone(), vec![Quat::identity(); 4], vec![Vec3::new(1e300, 0.0, 0.0)], 120.0)
            .unwrap();
        assert!(matches!(write_glb(&far, GltfContent::default(), &mut Vec::new()), Err(Error::Unwritable(_))));
    }
}
