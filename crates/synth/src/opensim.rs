//! A layout and its skeleton from an OpenSim model and marker set (OpenSim 4 `.osim` XML,
//! `OpenSimDocument Version="40000"`: `BodySet`, `JointSet` with `PhysicalOffsetFrame`s, and a
//! `MarkerSet` in the model or in its own file).
//!
//! What is read, and how it maps onto locap's skeleton (see the layout module's skeleton
//! section):
//! - every body becomes a joint of the same name; its parent is the body on the parent side of
//!   the joint that has it as child; the body jointed to `ground` is the root;
//! - a locap joint sits at the OpenSim joint's centre (the origin of the joint's parent offset
//!   frame), so rotating it turns the body about the same point as OpenSim does;
//! - the rest pose is the one with every coordinate at 0 (the model's defaults are 0 for every
//!   rotation; the root's translation does not enter offsets); each joint's frame is aligned
//!   with `ground` at rest, as locap's skeletons are: offsets, marker positions and rotation
//!   axes are expressed in ground axes, **Y up** (OpenSim's convention), in millimetres;
//! - rotational degrees of freedom: a `CustomJoint`'s `TransformAxis rotation1..3` driven by one
//!   coordinate through a `LinearFunction`, a `PinJoint`'s Z axis, a `UniversalJoint`'s X and Y,
//!   a `BallJoint`/`GimbalJoint`/`FreeJoint`'s X, Y, Z; each with its coordinate's `range` (the
//!   joint limits; an unclamped coordinate is limited to a full turn). Locked coordinates are
//!   fixed at 0. Axes driven through splines (the knee's coupled rotations of a few degrees and
//!   its millimetre translations) are left out: a locap joint has no coupled motion.
//!   `WeldJoint` has no rotation;
//! - markers: `socket_parent_frame` names the body, `location` the point in that body's frame
//!   (metres).
//!
//! Frames: a `PhysicalOffsetFrame`'s `orientation` is X-Y-Z body-fixed Euler angles (radians),
//! `R = Rx Ry Rz`, its `translation` is in its parent body's frame (OpenSim API docs, "Frames").

use crate::layout::{Dof, Layout, LayoutError, LayoutJoint, LayoutMarker, LayoutSkeleton, Region};
use locap_core::{EulerOrder, Quat, UpAxis, Vec3};
use roxmltree::{Document, Node};
use std::collections::HashMap;

/// Largest XML text accepted (bytes): the Rajagopal full-body model is under 1 MB.
pub const MAX_XML_BYTES: usize = 64 << 20;
/// Most bodies, joints or markers accepted.
pub const MAX_ITEMS: usize = 10_000;

/// An XML text and the name (path) its errors carry.
#[derive(Debug, Clone, Copy)]
pub struct XmlSource<'a> {
    /// The file's path or another name for messages.
    pub name: &'a str,
    /// Its text.
    pub text: &'a str,
}

/// Why an OpenSim file does not give a layout: the file, then the problem.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{file}: {problem}")]
pub struct OpenSimError {
    /// The file's name as given.
    pub file: String,
    /// What is wrong.
    pub problem: Problem,
}

/// What is wrong with an OpenSim file.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum Problem {
    /// Not well-formed XML (roxmltree's message, with line and column).
    #[error("not XML: {0}")]
    Xml(String),
    /// Larger than [`MAX_XML_BYTES`] or more than [`MAX_ITEMS`] items.
    #[error("{what}: {found} is more than the limit {limit}")]
    TooLarge {
        /// What was counted.
        what: &'static str,
        /// How many.
        found: usize,
        /// The limit.
        limit: usize,
    },
    /// An element the format requires is missing or empty.
    #[error("line {line}: {what}")]
    Missing {
        /// Line of the element that lacks it.
        line: u32,
        /// What is missing.
        what: String,
    },
    /// A number or vector does not parse.
    #[error("line {line}: {what} {text:?} is not {expected}")]
    BadNumber {
        /// Line.
        line: u32,
        /// The element.
        what: String,
        /// Its text.
        text: String,
        /// What it should be.
        expected: &'static str,
    },
    /// A joint type this reader does not map.
    #[error("line {line}: joint {joint:?} is a {kind}, which locap does not read")]
    UnsupportedJoint {
        /// Line.
        line: u32,
        /// Joint name.
        joint: String,
        /// Element name.
        kind: String,
    },
    /// The bodies do not form one tree hanging from `ground`.
    #[error("{0}")]
    Tree(String),
    /// The result is not a valid layout.
    #[error("{0}")]
    Layout(LayoutError),
}

/// A rigid transform: `p_parent = rotation * p_child + translation_m`.
#[derive(Debug, Clone, Copy)]
struct Transform {
    rotation: Quat,
    translation_m: Vec3,
}

impl Transform {
    fn identity() -> Transform {
        Transform { rotation: Quat::identity(), translation_m: Vec3::zeros() }
    }

    fn then(&self, child: &Transform) -> Transform {
        Transform {
            rotation: self.rotation * child.rotation,
            translation_m: self.translation_m + self.rotation * child.translation_m,
        }
    }

    fn inverse(&self) -> Transform {
        let r = self.rotation.inverse();
        Transform { rotation: r, translation_m: -(r * self.translation_m) }
    }
}

/// A joint as read: parent and child body, their offset frames, rotation axes.
struct OsimJoint {
    name: String,
    line: u32,
    parent: String,
    parent_frame: Transform,
    child: String,
    child_frame: Transform,
    /// Axes in the parent offset frame with their ranges (radians).
    dofs: Vec<(String, Vec3, f64, f64)>,
}

struct Reader<'a> {
    file: &'a str,
    doc: &'a Document<'a>,
}

impl<'a> Reader<'a> {
    fn err(&self, problem: Problem) -> OpenSimError {
        OpenSimError { file: self.file.to_string(), problem }
    }

    fn line(&self, node: Node) -> u32 {
        self.doc.text_pos_at(node.range().start).row
    }

    fn child<'b>(&self, node: Node<'b, 'a>, tag: &str) -> Option<Node<'b, 'a>> {
        node.children().find(|c| c.has_tag_name(tag))
    }

    fn text<'b>(&self, node: Node<'b, 'a>, tag: &str) -> Result<&'b str, OpenSimError> {
        match self.child(node, tag).and_then(|c| c.text()) {
            Some(t) if !t.trim().is_empty() => Ok(t.trim()),
            _ => Err(self.err(Problem::Missing { line: self.line(node), what: format!("no <{tag}>") })),
        }
    }

    fn numbers<const N: usize>(&self, node: Node, tag: &str) -> Result<[f64; N], OpenSimError> {
        let text = self.text(node, tag)?;
        let bad = || {
            self.err(Problem::BadNumber {
                line: self.line(node),
                what: format!("<{tag}>"),
                text: text.chars().take(80).collect(),
                expected: if N == 1 { "a finite number" } else { "finite numbers, as many as expected" },
            })
        };
        let values: Vec<f64> =
            text.split_whitespace().map(|v| v.parse::<f64>().map_err(|_| bad())).collect::<Result<_, _>>()?;
        let out: [f64; N] = values.try_into().map_err(|_| bad())?;
        if out.iter().any(|v| !v.is_finite()) {
            return Err(bad());
        }
        Ok(out)
    }

    fn name(&self, node: Node) -> Result<String, OpenSimError> {
        match node.attribute("name") {
            Some(n) if !n.is_empty() => Ok(n.to_string()),
            _ => Err(self.err(Problem::Missing {
                line: self.line(node),
                what: format!("<{}> has no name", node.tag_name().name()),
            })),
        }
    }

    /// The element `path` (tags from `node` down), e.g. `JointSet/objects`.
    fn at<'b>(&self, node: Node<'b, 'a>, path: &[&str]) -> Result<Node<'b, 'a>, OpenSimError> {
        let mut n = node;
        for tag in path {
            n = self.child(n, tag).ok_or_else(|| {
                self.err(Problem::Missing { line: self.line(n), what: format!("no <{}>", path.join("/")) })
            })?;
        }
        Ok(n)
    }

    fn frame(&self, node: Node) -> Result<Transform, OpenSimError> {
        let [tx, ty, tz] = self.numbers::<3>(node, "translation")?;
        let [a, b, c] = self.numbers::<3>(node, "orientation")?;
        let rotation = EulerOrder::XYZ.to_quat_deg([a.to_degrees(), b.to_degrees(), c.to_degrees()]);
        Ok(Transform { rotation, translation_m: Vec3::new(tx, ty, tz) })
    }

    /// A socket path's last component (`/bodyset/femur_r` -> `femur_r`).
    fn last(path: &str) -> &str {
        path.rsplit('/').find(|s| !s.is_empty() && *s != "..").unwrap_or(path)
    }

    fn joint(&self, node: Node) -> Result<OsimJoint, OpenSimError> {
        let name = self.name(node)?;
        let line = self.line(node);
        let kind = node.tag_name().name().to_string();
        let mut frames = HashMap::new();
        if let Some(list) = self.child(node, "frames") {
            for f in list.children().filter(|c| c.has_tag_name("PhysicalOffsetFrame")) {
                let body = Self::last(self.text(f, "socket_parent")?).to_string();
                frames.insert(self.name(f)?, (body, self.frame(f)?));
            }
        }
        let side = |tag: &str| -> Result<(String, Transform), OpenSimError> {
            let socket = self.text(node, tag)?;
            let key = Self::last(socket);
            Ok(frames.get(key).cloned().unwrap_or((key.to_string(), Transform::identity())))
        };
        let (parent, parent_frame) = side("socket_parent_frame")?;
        let (child, child_frame) = side("socket_child_frame")?;
        // Coordinates in order, with their ranges (radians; unclamped: a full turn).
        let mut coordinates = Vec::new();
        if let Some(list) = self.child(node, "coordinates") {
            for c in list.children().filter(|c| c.has_tag_name("Coordinate")) {
                let cname = self.name(c)?;
                let flag = |tag| self.child(c, tag).and_then(|n| n.text()).is_some_and(|t| t.trim() == "true");
                let [lo, hi] =
                    if self.child(c, "range").is_some() { self.numbers::<2>(c, "range")? } else { [-1e9, 1e9] };
                let turn = std::f64::consts::PI;
                let (lo, hi) = if flag("clamped") { (lo.max(-turn), hi.min(turn)) } else { (-turn, turn) };
                coordinates.push((cname, lo.min(hi), hi.max(lo), flag("locked")));
            }
        }
        let mut dofs = Vec::new();
        let fixed_axes: &[(usize, [f64; 3])] = match kind.as_str() {
            "PinJoint" => &[(0, [0.0, 0.0, 1.0])],
            "UniversalJoint" => &[(0, [1.0, 0.0, 0.0]), (1, [0.0, 1.0, 0.0])],
            "BallJoint" | "GimbalJoint" | "FreeJoint" => {
                &[(0, [1.0, 0.0, 0.0]), (1, [0.0, 1.0, 0.0]), (2, [0.0, 0.0, 1.0])]
            }
            "WeldJoint" | "SliderJoint" | "CustomJoint" => &[],
            _ => return Err(self.err(Problem::UnsupportedJoint { line, joint: name, kind })),
        };
        for &(k, axis) in fixed_axes {
            if let Some((cname, lo, hi, locked)) = coordinates.get(k)
                && !locked
            {
                dofs.push((cname.clone(), Vec3::from(axis), *lo, *hi));
            }
        }
        if kind == "CustomJoint" {
            let transform = self.at(node, &["SpatialTransform"])?;
            for axis in transform.children().filter(|c| c.has_tag_name("TransformAxis")) {
                if !axis.attribute("name").is_some_and(|n| n.starts_with("rotation")) {
                    continue;
                }
                let Some(cname) = self.child(axis, "coordinates").and_then(|c| c.text()).map(str::trim) else {
                    continue;
                };
                let Some((_, lo, hi, locked)) = coordinates.iter().find(|c| c.0 == cname) else { continue };
                let Some(linear) = self.child(axis, "LinearFunction") else { continue };
                let [slope, intercept] = self.numbers::<2>(linear, "coefficients")?;
                let direction = Vec3::from(self.numbers::<3>(axis, "axis")?);
                if *locked || slope == 0.0 || direction.norm() < 1e-9 {
                    continue;
                }
                let (a, b) = (slope * lo + intercept, slope * hi + intercept);
                dofs.push((cname.to_string(), direction.normalize(), a.min(b), a.max(b)));
            }
        }
        Ok(OsimJoint { name, line, parent, parent_frame, child, child_frame, dofs })
    }
}

fn parse<'a>(source: &XmlSource<'a>) -> Result<Document<'a>, OpenSimError> {
    let err = |problem| OpenSimError { file: source.name.to_string(), problem };
    if source.text.len() > MAX_XML_BYTES {
        return Err(err(Problem::TooLarge { what: "bytes", found: source.text.len(), limit: MAX_XML_BYTES }));
    }
    Document::parse(source.text).map_err(|e| err(Problem::Xml(e.to_string())))
}

fn count_check(reader: &Reader, what: &'static str, found: usize) -> Result<(), OpenSimError> {
    if found > MAX_ITEMS {
        return Err(reader.err(Problem::TooLarge { what, found, limit: MAX_ITEMS }));
    }
    Ok(())
}

/// The layout (markers on bodies, mm) and its skeleton (one joint per body, Y up, mm, with the
/// joints' rotation axes and limits) of the OpenSim `model`, with the markers of `markers`
/// (a `MarkerSet` file) or, without it, of the model's own `MarkerSet`.
///
/// # Errors
/// Not XML, too large, a required element missing or a number not parsing (with the line), a
/// joint type this reader does not map, bodies that are not one tree hanging from `ground`,
/// a marker on a body the model lacks. The error names the file.
pub fn layout_from_opensim(model: XmlSource, markers: Option<XmlSource>) -> Result<Layout, OpenSimError> {
    let model_doc = parse(&model)?;
    let r = Reader { file: model.name, doc: &model_doc };
    let root = model_doc.root_element();
    let model_node = root.children().find(|c| c.has_tag_name("Model")).unwrap_or(root);
    let model_name = model_node.attribute("name").unwrap_or("opensim").to_string();
    let bodies: Vec<String> = match r.child(model_node, "BodySet") {
        Some(set) => r
            .at(set, &["objects"])?
            .children()
            .filter(|c| c.has_tag_name("Body"))
            .map(|b| r.name(b))
            .collect::<Result<_, _>>()?,
        None => Vec::new(),
    };
    count_check(&r, "bodies", bodies.len())?;
    let joint_set = r.at(model_node, &["JointSet", "objects"]).map_err(|_| {
        r.err(Problem::Missing {
            line: r.line(model_node),
            what: "no <JointSet>/<objects> (OpenSim 4 models list their joints there; open and save an OpenSim 3 model in OpenSim 4 first)".into(),
        })
    })?;
    let joints: Vec<OsimJoint> =
        joint_set.children().filter(|c| c.is_element()).map(|j| r.joint(j)).collect::<Result<_, _>>()?;
    count_check(&r, "joints", joints.len())?;
    let tree = |what: String| r.err(Problem::Tree(what));
    let mut by_child: HashMap<&str, &OsimJoint> = HashMap::new();
    for j in &joints {
        if !bodies.contains(&j.child) {
            return Err(tree(format!(
                "line {}: joint {:?} has child {:?}, which is not a body",
                j.line, j.name, j.child
            )));
        }
        if j.parent != "ground" && !bodies.contains(&j.parent) {
            return Err(tree(format!(
                "line {}: joint {:?} has parent {:?}, which is not a body",
                j.line, j.name, j.parent
            )));
        }
        if by_child.insert(j.child.as_str(), j).is_some() {
            return Err(tree(format!("body {:?} is the child of two joints (a closed loop)", j.child)));
        }
    }
    let roots: Vec<&OsimJoint> = joints.iter().filter(|j| j.parent == "ground").collect();
    let root_joint = match roots.as_slice() {
        [one] => *one,
        [] => return Err(tree("no joint has ground as its parent".into())),
        many => {
            let names: Vec<&str> = many.iter().map(|j| j.child.as_str()).collect();
            return Err(tree(format!(
                "several bodies are jointed to ground ({}); locap needs one root",
                names.join(", ")
            )));
        }
    };
    // Parents first: breadth first from the root.
    let mut order: Vec<&OsimJoint> = vec![root_joint];
    let mut k = 0;
    while k < order.len() {
        let body = order[k].child.as_str();
        order.extend(joints.iter().filter(|j| j.parent == body));
        k += 1;
    }
    if let Some(b) = bodies.iter().find(|b| !order.iter().any(|j| j.child == **b)) {
        return Err(tree(format!("body {b:?} is not connected to ground by joints")));
    }
    // Rest pose (every coordinate 0): each body's frame and joint centre in ground.
    let mut body_pose: HashMap<&str, Transform> = HashMap::new();
    let mut centre_m: HashMap<&str, Vec3> = HashMap::new();
    let mut layout_joints = Vec::with_capacity(order.len());
    for j in &order {
        let parent_pose = if j.parent == "ground" { Transform::identity() } else { body_pose[j.parent.as_str()] };
        let joint_frame = parent_pose.then(&j.parent_frame);
        let pose = joint_frame.then(&j.child_frame.inverse());
        body_pose.insert(j.child.as_str(), pose);
        centre_m.insert(j.child.as_str(), joint_frame.translation_m);
        let is_root = j.parent == "ground";
        let offset_m = if is_root { Vec3::zeros() } else { joint_frame.translation_m - centre_m[j.parent.as_str()] };
        let dofs = (!is_root).then(|| {
            j.dofs
                .iter()
                .map(|(name, axis, lo, hi)| {
                    let a = (joint_frame.rotation * axis).normalize();
                    Dof {
                        name: name.clone(),
                        axis: [a.x, a.y, a.z],
                        min_deg: lo.to_degrees(),
                        max_deg: hi.to_degrees(),
                    }
                })
                .collect()
        });
        layout_joints.push(LayoutJoint {
            name: j.child.clone(),
            parent: (!is_root).then(|| j.parent.clone()),
            offset_mm: (offset_m * 1000.0).into(),
            dofs,
            follows: None,
        });
    }
    // Markers: the marker file's, or the model's own.
    let marker_doc;
    let (mr, set) = match &markers {
        Some(source) => {
            marker_doc = parse(source)?;
            let mr = Reader { file: source.name, doc: &marker_doc };
            let root = marker_doc.root_element();
            let set = if root.has_tag_name("MarkerSet") {
                Some(root)
            } else {
                root.descendants().find(|c| c.has_tag_name("MarkerSet"))
            };
            (mr, set)
        }
        None => (Reader { file: model.name, doc: &model_doc }, r.child(model_node, "MarkerSet")),
    };
    let set = set.ok_or_else(|| mr.err(Problem::Missing { line: 1, what: "no <MarkerSet>".into() }))?;
    let objects = mr.at(set, &["objects"])?;
    let mut layout_markers = Vec::new();
    for m in objects.children().filter(|c| c.has_tag_name("Marker")) {
        count_check(&mr, "markers", layout_markers.len() + 1)?;
        let name = mr.name(m)?;
        let body = Reader::last(mr.text(m, "socket_parent_frame")?).to_string();
        let Some(pose) = body_pose.get(body.as_str()) else {
            return Err(mr.err(Problem::Tree(format!(
                "line {}: marker {name:?} is on {body:?}, which is not a body of {}",
                mr.line(m),
                model.name
            ))));
        };
        let location = Vec3::from(mr.numbers::<3>(m, "location")?);
        let at_rest = pose.rotation * location + pose.translation_m;
        let offset_mm = (at_rest - centre_m[body.as_str()]) * 1000.0;
        layout_markers.push(LayoutMarker {
            name,
            joint: body,
            offset_mm: offset_mm.into(),
            region: Region::Body,
            blend: None,
            soft_tissue: 1.0,
        });
    }
    let layout = Layout {
        name: model_name.clone(),
        description: format!(
            "{} markers on the OpenSim model {model_name} ({}), rest pose with every coordinate at 0, Y up, mm (locap layout from-opensim)",
            layout_markers.len(),
            model.name,
        ),
        aliases: Default::default(),
        markers: layout_markers,
        skeleton: Some(LayoutSkeleton { up_axis: UpAxis::Y, smoothness: None, joints: layout_joints }),
    };
    layout.check().map_err(|e| r.err(Problem::Layout(e)))?;
    Ok(layout)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const MODEL: &str = r#"<?xml version="1.0"?>
<OpenSimDocument Version="40000"><Model name="arm">
<BodySet><objects><Body name="trunk"/><Body name="upper"/><Body name="fore"/></objects></BodySet>
<JointSet><objects>
 <FreeJoint name="ground_trunk"><socket_parent_frame>/ground</socket_parent_frame><socket_child_frame>/bodyset/trunk</socket_child_frame></FreeJoint>
 <PinJoint name="shoulder">
  <socket_parent_frame>trunk_offset</socket_parent_frame><socket_child_frame>upper_offset</socket_child_frame>
  <coordinates><Coordinate name="sh"><range>-1 2</range><clamped>true</clamped></Coordinate></coordinates>
  <frames>
   <PhysicalOffsetFrame name="trunk_offset"><socket_parent>/bodyset/trunk</socket_parent><translation>0.2 0.5 0</translation><orientation>0 0 0</orientation></PhysicalOffsetFrame>
   <PhysicalOffsetFrame name="upper_offset"><socket_parent>/bodyset/upper</socket_parent><translation>0 0.1 0</translation><orientation>0 1.5707963267948966 0</orientation></PhysicalOffsetFrame>
  </frames>
 </PinJoint>
 <WeldJoint name="elbow"><socket_parent_frame>/bodyset/upper</socket_parent_frame><socket_child_frame>/bodyset/fore</socket_child_frame></WeldJoint>
</objects></JointSet>
<MarkerSet><objects>
 <Marker name="A"><socket_parent_frame>/bodyset/upper</socket_parent_frame><location>0 0 0</location></Marker>
 <Marker name="B"><socket_parent_frame>/bodyset/fore</socket_parent_frame><location>0.01 0 0</location></Marker>
</objects></MarkerSet>
</Model></OpenSimDocument>"#;

    #[test]
    fn a_hand_computed_model() {
        let layout = layout_from_opensim(XmlSource { name: "arm.osim", text: MODEL }, None).unwrap();
        let sk = layout.skeleton.as_ref().unwrap();
        let names: Vec<&str> = sk.joints.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["trunk", "upper", "fore"]);
        // The shoulder centre is 0.2 0.5 0 in the trunk (at the origin).
        assert_eq!(sk.joints[1].offset_mm, [200.0, 500.0, 0.0]);
        // The upper arm's frame is turned -90 degrees about Y relative to the joint frame;
        // its origin is 0.1 m below the joint centre along its own Y (= ground Y).
        let a = layout.markers[0].offset_mm;
        assert!((Vec3::from(a) - Vec3::new(0.0, -100.0, 0.0)).norm() < 1e-9, "{a:?}");
        // The pin axis (Z of the trunk-side frame) in ground axes, with its range.
        let dof = &sk.joints[1].dofs.as_ref().unwrap()[0];
        assert!((Vec3::from(dof.axis) - Vec3::z()).norm() < 1e-12);
        assert!((dof.min_deg + 57.29577951308232).abs() < 1e-9 && (dof.max_deg - 114.59155902616465).abs() < 1e-9);
        // The weld: no rotation; its centre is the upper body's origin.
        assert_eq!(sk.joints[2].dofs, Some(vec![]));
        assert!((Vec3::from(sk.joints[2].offset_mm) - Vec3::new(0.0, -100.0, 0.0)).norm() < 1e-9);
        // B is 0.01 m along the upper body's X, which is ground's +Z after the -90 degree turn.
        let b = Vec3::from(layout.markers[1].offset_mm);
        assert!((b - Vec3::new(0.0, 0.0, 10.0)).norm() < 1e-9, "{b:?}");
        assert!(sk.to_skeleton().is_ok());
    }

    #[test]
    fn errors_name_the_file_and_the_line() {
        let broken = MODEL.replace("<translation>0.2 0.5 0</translation>", "<translation>0.2 x 0</translation>");
        let e = layout_from_opensim(XmlSource { name: "arm.osim", text: &broken }, None).unwrap_err();
        assert!(e.to_string().starts_with("arm.osim: line "), "{e}");
        let other = MODEL
            .replace("/bodyset/fore</socket_parent_frame><location>", "/bodyset/hand</socket_parent_frame><location>");
        let e = layout_from_opensim(XmlSource { name: "arm.osim", text: &other }, None).unwrap_err();
        assert!(e.to_string().contains("\"hand\""), "{e}");
        let two_roots = MODEL.replace(
            "<socket_parent_frame>/bodyset/upper</socket_parent_frame><socket_child_frame>/bodyset/fore",
            "<socket_parent_frame>/ground</socket_parent_frame><socket_child_frame>/bodyset/fore",
        );
        assert!(matches!(
            layout_from_opensim(XmlSource { name: "m", text: &two_roots }, None).unwrap_err().problem,
            Problem::Tree(_)
        ));
        let ball = MODEL.replace("PinJoint", "ScapulothoracicJoint");
        assert!(matches!(
            layout_from_opensim(XmlSource { name: "m", text: &ball }, None).unwrap_err().problem,
            Problem::UnsupportedJoint { .. }
        ));
    }

    proptest! {
        /// Cut or damaged text never panics, and every error names the file.
        #[test]
        fn bad_xml_is_an_error_naming_the_file(cut in 0usize..MODEL.len(), at in 0usize..MODEL.len(), byte in proptest::char::range(' ', '~')) {
            let mut text: String = MODEL.chars().take(cut).collect();
            if at < text.len() && text.is_char_boundary(at) && text.is_char_boundary(at + 1) {
                text.replace_range(at..at + 1, &byte.to_string());
            }
            match layout_from_opensim(XmlSource { name: "cut.osim", text: &text }, None) {
                Ok(layout) => prop_assert!(layout.check().is_ok()),
                Err(e) => prop_assert!(e.to_string().starts_with("cut.osim: ")),
            }
        }
    }
}
