//! Acclaim skeleton (ASF) and motion (AMC) files, as in the CMU motion capture database.
//!
//! An ASF file describes bones: each has a rest `direction` (a unit vector in the world frame)
//! and `length`, a local frame given by `axis a b c ORDER`, and the rotational degrees of
//! freedom (`dof rx ry rz`) that an AMC file animates. An AMC file lists, per frame number,
//! one line per bone with its dof values in the ASF's dof order (`root` has six: the ASF
//! root `order`, e.g. `TX TY TZ RX RY RZ`).
//!
//! # Conventions (Acclaim)
//! - **Euler angles are applied in the order they are listed**: `axis a b c XYZ` rotates a
//!   vector about X by `a` first, then Y by `b`, then Z by `c`, i.e. the matrix is
//!   `C = Rz(c) * Ry(b) * Rx(a)`; the dof values of a bone build `M` the same way from the
//!   dof order. (This is the reverse of the core [`EulerOrder`] product for the same letters.
//!   It was checked against CMU take 01_01: with it the C3D markers stay rigidly attached to
//!   the bones (marker-to-joint distances vary by 3-15 mm std over the take); with the
//!   reverse product they drift (75-180 mm std).)
//! - A bone's rotation relative to its parent is `L = C * M * C^-1`, its global rotation
//!   `R = R_parent * L`, and its tip is `start + R * direction * length`, where `start` is the
//!   parent bone's tip (the root's position for the root's children).
//! - **Mapping to [`locap_core::Skeleton`]**: joint 0 is `root`; every bone becomes a joint at
//!   its *start*, whose local rotation is `L` and whose offset is the parent bone's
//!   `direction * length` (zero for children of the root); every leaf bone gets an extra end
//!   site joint `<bone>_End` at its tip. Because `L` is the identity at rest, core offsets in
//!   the parent frame are exactly the ASF world-frame rest vectors. The root joint's rotation
//!   is `C_root * M_root * C_root^-1` with `C_root` from the root's `orientation` (in its
//!   `axis` order) and `M_root` from the AMC `RX RY RZ` values (in the root's `order`); its
//!   position is the AMC `TX TY TZ` (the ASF root `position` where the AMC gives none).
//! - **Units.** ASF lengths are in units of `1/length` inches, where `length` is the
//!   `:units length` value (CMU uses 0.45), so one unit is `25.4 / length` mm: see
//!   [`AsfSkeleton::mm_per_unit`]. Angles are in the `:units angle` unit (`deg` or `rad`);
//!   this reader stores them in degrees. An AMC's `:DEGREES`/`:RADIANS` header decides its
//!   angle unit; without one, the ASF's angle unit applies.
//! - **Frame rate.** AMC files do not store one; the caller supplies it (CMU captures are
//!   120 Hz).
//! - **Strictness.** Frame numbers must be consecutive, every bone line must name a bone of
//!   the ASF and have one value per dof, a bone may appear once per frame, and values must be
//!   finite. A bone missing from a frame is read at its rest rotation (all dofs zero), as a
//!   not fully specified AMC intends. Errors name the 1-based line (and column for values).
//! - **Not supported:** translation and length dofs on bones (`tx`, `ty`, `tz`, `l`), which
//!   give an [`Error::Unsupported`] when an AMC is read against such a skeleton.
//! - **Limits.** The `*_with` readers check the bone count and the `:hierarchy` depth against
//!   [`Limits`], and an AMC's frames × joints against [`Limits::max_samples`] and against the
//!   AMC text's size (bones left out of a frame are samples no byte backs; see
//!   [`crate::limits`]), frame by frame before the frame is stored.

use crate::limits::{self, Limits};
use crate::{Error, Result};
use locap_core::rotation::axis_rotation;
use locap_core::{EulerOrder, Joint, Motion, Quat, Skeleton, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::Path;

const ASF: &str = "ASF";
const AMC: &str = "AMC";

/// Angle unit of an Acclaim file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AngleUnit {
    /// Degrees (`deg`, `:DEGREES`).
    Degree,
    /// Radians (`rad`, `:RADIANS`).
    Radian,
}

impl AngleUnit {
    fn to_degrees(self, v: f64) -> f64 {
        match self {
            AngleUnit::Degree => v,
            AngleUnit::Radian => v.to_degrees(),
        }
    }
}

/// The ASF `:units` section.
#[derive(Debug, Clone, PartialEq)]
pub struct AsfUnits {
    /// `mass` multiplier (unused by locap, kept for completeness); 1 if absent.
    pub mass: f64,
    /// `length` value: lengths are in units of `1/length` inches; 1 if absent.
    pub length: f64,
    /// Angle unit of the file's `axis`, `orientation` and `limits` values.
    pub angle: AngleUnit,
}

/// One degree of freedom of a bone or of the root.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dof {
    /// Rotation about X (`rx`).
    Rx,
    /// Rotation about Y (`ry`).
    Ry,
    /// Rotation about Z (`rz`).
    Rz,
    /// Translation along X (`tx`).
    Tx,
    /// Translation along Y (`ty`).
    Ty,
    /// Translation along Z (`tz`).
    Tz,
    /// Bone length change (`l`).
    L,
}

impl Dof {
    fn parse(text: &str) -> Option<Dof> {
        match text.to_ascii_lowercase().as_str() {
            "rx" => Some(Dof::Rx),
            "ry" => Some(Dof::Ry),
            "rz" => Some(Dof::Rz),
            "tx" => Some(Dof::Tx),
            "ty" => Some(Dof::Ty),
            "tz" => Some(Dof::Tz),
            "l" => Some(Dof::L),
            _ => None,
        }
    }

    /// The axis of a rotation dof (0 = X, 1 = Y, 2 = Z).
    fn rotation_axis(self) -> Option<usize> {
        match self {
            Dof::Rx => Some(0),
            Dof::Ry => Some(1),
            Dof::Rz => Some(2),
            _ => None,
        }
    }

    fn translation_axis(self) -> Option<usize> {
        match self {
            Dof::Tx => Some(0),
            Dof::Ty => Some(1),
            Dof::Tz => Some(2),
            _ => None,
        }
    }
}

/// The ASF `:root` section.
#[derive(Debug, Clone, PartialEq)]
pub struct AsfRoot {
    /// The order of the root's values on an AMC `root` line (`TX TY TZ RX RY RZ` in CMU).
    pub order: Vec<Dof>,
    /// Axis letters of `orientation`, as written (`XYZ`: X applied first, see the module docs).
    pub axis: EulerOrder,
    /// Rest position of the root, in ASF length units.
    pub position: Vec3,
    /// Rest orientation angles, degrees, in `axis` order.
    pub orientation_deg: [f64; 3],
}

/// One bone of an ASF skeleton.
#[derive(Debug, Clone, PartialEq)]
pub struct AsfBone {
    /// The `id` line, if present.
    pub id: Option<i64>,
    /// Bone name (unique; `root` is reserved).
    pub name: String,
    /// Index of the parent bone in [`AsfSkeleton::bones`]; `None` when the parent is the root.
    pub parent: Option<usize>,
    /// Rest direction in the world frame (a unit vector in well-formed files).
    pub direction: Vec3,
    /// Length, ASF length units.
    pub length: f64,
    /// The `axis` angles, degrees, in `axis_order` order.
    pub axis_deg: [f64; 3],
    /// Axis letters as written (`XYZ`: X applied first, see the module docs).
    pub axis_order: EulerOrder,
    /// Degrees of freedom, in the order AMC lines list their values.
    pub dof: Vec<Dof>,
    /// `(min, max)` per dof (degrees for rotations; may be infinite); empty if not given.
    pub limits: Vec<(f64, f64)>,
}

/// A parsed ASF file. Bones are stored parents first (the `:hierarchy` walked depth-first).
#[derive(Debug, Clone, PartialEq)]
pub struct AsfSkeleton {
    /// The `:version` value, if present.
    pub version: Option<String>,
    /// The `:name` value, if present.
    pub name: Option<String>,
    /// The `:units` section.
    pub units: AsfUnits,
    /// The `:root` section.
    pub root: AsfRoot,
    /// The bones, parents first.
    pub bones: Vec<AsfBone>,
}

/// Rotation applying `angles_deg` about `axes` in the listed order (the first one first to a
/// vector): the Acclaim convention, `R = R_last * ... * R_first`.
fn acclaim_rotation(axes_angles: impl IntoIterator<Item = (usize, f64)>) -> Quat {
    let mut q = Quat::identity();
    for (axis, angle_deg) in axes_angles {
        q = axis_rotation(axis, angle_deg.to_radians()) * q;
    }
    q
}

/// `C` of an `axis` line.
fn axis_frame(order: EulerOrder, angles_deg: [f64; 3]) -> Quat {
    acclaim_rotation(order.axes().into_iter().zip(angles_deg))
}

/// The core order with the same matrix product as Acclaim letters `order` (reversed letters).
fn reversed(order: EulerOrder) -> EulerOrder {
    let [a, b, c] = order.axes();
    EulerOrder::from_axes([c, b, a]).unwrap_or(order)
}

/// Lines without `\r`, numbered from 1, comments (`#`) and blank lines dropped. Lines keep
/// their indentation so that reported columns match what an editor shows.
fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.split('\n').enumerate().filter_map(|(i, l)| {
        let l = l.strip_suffix('\r').unwrap_or(l);
        let t = l.trim();
        (!t.is_empty() && !t.starts_with('#')).then_some((i + 1, l))
    })
}

/// Words of a line with their 1-based (byte) columns in that line.
fn words<'a>(raw: &'a str) -> impl Iterator<Item = (usize, &'a str)> + 'a {
    let base = raw.as_ptr() as usize;
    raw.split_whitespace().map(move |w| (w.as_ptr() as usize - base + 1, w))
}

fn text_err(format: &'static str, line: usize, column: Option<usize>, message: impl Into<String>) -> Error {
    Error::Text { format, line, column, message: message.into() }
}

/// A finite number (or, where `allow_inf`, an infinite limit).
fn num(format: &'static str, line: usize, col: usize, word: &str, what: &str, allow_inf: bool) -> Result<f64> {
    match word.parse::<f64>() {
        Ok(v) if v.is_finite() || (allow_inf && v.is_infinite()) => Ok(v),
        _ => Err(text_err(format, line, Some(col), format!("expected a number for {what}, found {word:?}"))),
    }
}

fn three(line: usize, ws: &[(usize, &str)], what: &str) -> Result<[f64; 3]> {
    if ws.len() != 3 {
        return Err(text_err(ASF, line, None, format!("{what} needs 3 numbers, found {}", ws.len())));
    }
    let mut v = [0.0; 3];
    for (x, (col, w)) in v.iter_mut().zip(ws) {
        *x = num(ASF, line, *col, w, what, false)?;
    }
    Ok(v)
}

fn order_of(line: usize, col: usize, word: &str) -> Result<EulerOrder> {
    EulerOrder::parse(word)
        .ok_or_else(|| text_err(ASF, line, Some(col), format!("expected an axis order like XYZ, found {word:?}")))
}

/// A bone while its `begin ... end` block is read.
#[derive(Default)]
struct BoneDraft {
    line: usize,
    id: Option<i64>,
    name: Option<String>,
    direction: Option<Vec3>,
    length: Option<f64>,
    axis: Option<([f64; 3], EulerOrder)>,
    dof: Vec<Dof>,
    limits: Vec<(f64, f64)>,
    in_limits: bool,
}

#[derive(Clone, Copy, PartialEq)]
enum Section {
    None,
    Units,
    Root,
    BoneData,
    Hierarchy,
    Skip,
}

/// Parses the `limits` values of `raw` from byte `start` on (`(min max)` pairs, parentheses
/// may touch the numbers). Blanking instead of cutting keeps the columns right.
fn push_limits(line: usize, raw: &str, start: usize, limits: &mut Vec<f64>) -> Result<()> {
    let cleaned: String =
        raw.char_indices().map(|(i, c)| if i < start || c == '(' || c == ')' { ' ' } else { c }).collect();
    for (col, w) in words(&cleaned) {
        limits.push(num(ASF, line, col, w, "a limit", true)?);
    }
    Ok(())
}

/// Reads an ASF file's text.
pub fn read_asf(text: &str) -> Result<AsfSkeleton> {
    read_asf_with(text, &Limits::default())
}

/// [`read_asf`] with explicit [`Limits`] on the bone count and hierarchy depth.
pub fn read_asf_with(text: &str, limits: &Limits) -> Result<AsfSkeleton> {
    let mut section = Section::None;
    let mut version = None;
    let mut name = None;
    let mut units = AsfUnits { mass: 1.0, length: 1.0, angle: AngleUnit::Degree };
    let mut root_order: Option<Vec<Dof>> = None;
    let mut root_axis = EulerOrder::XYZ;
    let mut root_position = Vec3::zeros();
    let mut root_orientation = [0.0; 3];
    let mut drafts: Vec<BoneDraft> = Vec::new();
    let mut current: Option<BoneDraft> = None;
    let mut in_hierarchy_block = false;
    // child name -> (parent name, line)
    let mut parent_of: HashMap<String, (String, usize)> = HashMap::new();
    let mut children_of: HashMap<String, Vec<String>> = HashMap::new();
    let mut last_line = 0;

    for (line, raw) in content_lines(text) {
        last_line = line;
        let ws: Vec<(usize, &str)> = words(raw).collect();
        let Some(&(key_col, key)) = ws.first() else {
            continue;
        };
        let rest = ws.get(1..).unwrap_or(&[]);
        if let Some(keyword) = key.strip_prefix(':') {
            if current.is_some() {
                return Err(text_err(ASF, line, Some(key_col), "section starts inside a bone's begin ... end"));
            }
            section = match keyword.to_ascii_lowercase().as_str() {
                "version" => {
                    version = rest.first().map(|(_, w)| w.to_string());
                    Section::None
                }
                "name" => {
                    name = rest.first().map(|(_, w)| w.to_string());
                    Section::None
                }
                "units" => Section::Units,
                "root" => Section::Root,
                "bonedata" => Section::BoneData,
                "hierarchy" => Section::Hierarchy,
                // `:documentation` and anything unknown: free text we do not interpret.
                _ => Section::Skip,
            };
            continue;
        }
        match section {
            Section::Skip => {}
            Section::None => {
                return Err(text_err(ASF, line, Some(key_col), format!("{key:?} outside any section")));
            }
            Section::Units => {
                let value = rest.first().ok_or_else(|| text_err(ASF, line, None, format!("{key} has no value")))?;
                match key.to_ascii_lowercase().as_str() {
                    "mass" => units.mass = num(ASF, line, value.0, value.1, "mass", false)?,
                    "length" => {
                        let v = num(ASF, line, value.0, value.1, "length", false)?;
                        if v <= 0.0 {
                            return Err(text_err(ASF, line, Some(value.0), "length unit must be positive"));
                        }
                        units.length = v;
                    }
                    "angle" => {
                        units.angle = match value.1.to_ascii_lowercase().as_str() {
                            "deg" | "degree" | "degrees" => AngleUnit::Degree,
                            "rad" | "radian" | "radians" => AngleUnit::Radian,
                            other => {
                                return Err(text_err(
                                    ASF,
                                    line,
                                    Some(value.0),
                                    format!("unknown angle unit {other:?}"),
                                ));
                            }
                        }
                    }
                    _ => {} // other unit lines carry nothing locap needs
                }
            }
            Section::Root => match key.to_ascii_lowercase().as_str() {
                "order" => {
                    let mut order = Vec::with_capacity(rest.len());
                    for &(col, w) in rest {
                        let dof = Dof::parse(w)
                            .ok_or_else(|| text_err(ASF, line, Some(col), format!("unknown root dof {w:?}")))?;
                        if order.contains(&dof) {
                            return Err(text_err(ASF, line, Some(col), format!("root dof {w:?} listed twice")));
                        }
                        order.push(dof);
                    }
                    root_order = Some(order);
                }
                "axis" => {
                    let &(col, w) =
                        rest.first().ok_or_else(|| text_err(ASF, line, None, "axis needs an order like XYZ"))?;
                    root_axis = order_of(line, col, w)?;
                }
                "position" => root_position = Vec3::from(three(line, rest, "position")?),
                "orientation" => {
                    root_orientation = three(line, rest, "orientation")?.map(|a| units.angle.to_degrees(a));
                }
                _ => {
                    return Err(text_err(ASF, line, Some(key_col), format!("unknown root field {key:?}")));
                }
            },
            Section::BoneData => {
                let lower = key.to_ascii_lowercase();
                let Some(bone) = current.as_mut() else {
                    if lower == "begin" {
                        limits.check_hierarchy(ASF, line, 0, drafts.len() + 1)?;
                        current = Some(BoneDraft { line, ..BoneDraft::default() });
                        continue;
                    }
                    return Err(text_err(ASF, line, Some(key_col), format!("expected \"begin\", found {key:?}")));
                };
                if key.starts_with('(') && bone.in_limits {
                    let mut flat = Vec::new();
                    push_limits(line, raw, 0, &mut flat)?;
                    pairs_into(line, &flat, &mut bone.limits)?;
                    continue;
                }
                bone.in_limits = false;
                match lower.as_str() {
                    "end" => {
                        if let Some(done) = current.take() {
                            drafts.push(done);
                        }
                    }
                    "begin" => {
                        return Err(text_err(ASF, line, Some(key_col), "\"begin\" inside a bone"));
                    }
                    "id" => {
                        let &(col, w) = rest.first().ok_or_else(|| text_err(ASF, line, None, "id has no value"))?;
                        bone.id = Some(
                            w.parse()
                                .map_err(|_| text_err(ASF, line, Some(col), format!("expected an id, found {w:?}")))?,
                        );
                    }
                    "name" => {
                        let &(col, w) = rest.first().ok_or_else(|| text_err(ASF, line, None, "name has no value"))?;
                        if w.eq_ignore_ascii_case("root") {
                            return Err(text_err(ASF, line, Some(col), "a bone cannot be called \"root\""));
                        }
                        bone.name = Some(w.to_string());
                    }
                    "direction" => bone.direction = Some(Vec3::from(three(line, rest, "direction")?)),
                    "length" => {
                        let &(col, w) = rest.first().ok_or_else(|| text_err(ASF, line, None, "length has no value"))?;
                        let v = num(ASF, line, col, w, "length", false)?;
                        if v < 0.0 {
                            return Err(text_err(ASF, line, Some(col), "negative bone length"));
                        }
                        bone.length = Some(v);
                    }
                    "axis" => {
                        let (angles, order) = match rest {
                            [a, b, c, o] => (three(line, &[*a, *b, *c], "axis")?, order_of(line, o.0, o.1)?),
                            _ => {
                                return Err(text_err(ASF, line, None, "axis needs 3 angles and an order like XYZ"));
                            }
                        };
                        bone.axis = Some((angles.map(|a| units.angle.to_degrees(a)), order));
                    }
                    "dof" => {
                        for &(col, w) in rest {
                            let dof = Dof::parse(w)
                                .ok_or_else(|| text_err(ASF, line, Some(col), format!("unknown dof {w:?}")))?;
                            if bone.dof.contains(&dof) {
                                return Err(text_err(ASF, line, Some(col), format!("dof {w:?} listed twice")));
                            }
                            bone.dof.push(dof);
                        }
                    }
                    "limits" => {
                        let mut flat = Vec::new();
                        push_limits(line, raw, key_col - 1 + key.len(), &mut flat)?;
                        pairs_into(line, &flat, &mut bone.limits)?;
                        bone.in_limits = true;
                    }
                    // bodymass, cofmass and other extensions: nothing locap uses.
                    _ => {}
                }
            }
            Section::Hierarchy => {
                let lower = key.to_ascii_lowercase();
                if !in_hierarchy_block {
                    if lower == "begin" {
                        in_hierarchy_block = true;
                        continue;
                    }
                    return Err(text_err(ASF, line, Some(key_col), format!("expected \"begin\", found {key:?}")));
                }
                if lower == "end" {
                    in_hierarchy_block = false;
                    section = Section::Skip;
                    continue;
                }
                for &(col, child) in rest {
                    if child.eq_ignore_ascii_case("root") {
                        return Err(text_err(ASF, line, Some(col), "the root cannot be a child"));
                    }
                    if parent_of.insert(child.to_string(), (key.to_string(), line)).is_some() {
                        return Err(text_err(ASF, line, Some(col), format!("bone {child:?} has a second parent")));
                    }
                    children_of.entry(key.to_string()).or_default().push(child.to_string());
                }
            }
        }
    }
    if current.is_some() {
        return Err(text_err(ASF, last_line, None, "file ends inside a bone's begin ... end"));
    }
    if in_hierarchy_block {
        return Err(text_err(ASF, last_line, None, "file ends inside the :hierarchy block"));
    }
    let order = root_order.ok_or_else(|| text_err(ASF, last_line, None, "no root \"order\" in the :root section"))?;

    // Check every draft, then order bones parents first by walking the hierarchy.
    let mut by_name: HashMap<String, BoneDraft> = HashMap::new();
    let mut file_order = Vec::new();
    for d in drafts {
        let bone_name = d.name.clone().ok_or_else(|| text_err(ASF, d.line, None, "bone without a name"))?;
        if d.direction.is_none() || d.length.is_none() {
            return Err(text_err(ASF, d.line, None, format!("bone {bone_name:?} lacks a direction or length")));
        }
        if !d.limits.is_empty() && d.limits.len() != d.dof.len() {
            return Err(text_err(
                ASF,
                d.line,
                None,
                format!("bone {bone_name:?} has {} dofs but {} limits", d.dof.len(), d.limits.len()),
            ));
        }
        if by_name.contains_key(&bone_name) {
            return Err(text_err(ASF, d.line, None, format!("bone name {bone_name:?} is used twice")));
        }
        file_order.push(bone_name.clone());
        by_name.insert(bone_name, d);
    }
    for (child, (parent, line)) in &parent_of {
        if !by_name.contains_key(child) {
            return Err(text_err(ASF, *line, None, format!(":hierarchy names unknown bone {child:?}")));
        }
        if !parent.eq_ignore_ascii_case("root") && !by_name.contains_key(parent) {
            return Err(text_err(ASF, *line, None, format!(":hierarchy names unknown bone {parent:?}")));
        }
    }
    let mut bones: Vec<AsfBone> = Vec::with_capacity(by_name.len());
    let mut index_of: HashMap<String, usize> = HashMap::new();
    // Depth-first, explicit stack: (parent index, child name, depth; the root is depth 0).
    let root_children =
        children_of.iter().find(|(k, _)| k.eq_ignore_ascii_case("root")).map(|(_, v)| v.clone()).unwrap_or_default();
    let mut stack: Vec<(Option<usize>, String, usize)> =
        root_children.into_iter().rev().map(|c| (None, c, 1)).collect();
    while let Some((parent, child, depth)) = stack.pop() {
        let Some(d) = by_name.get(&child) else {
            continue;
        };
        let line = parent_of.get(&child).map_or(d.line, |(_, line)| *line);
        limits.check_hierarchy(ASF, line, depth, bones.len() + 1)?;
        if index_of.contains_key(&child) {
            continue; // impossible: a bone has one parent; kept as a cycle guard
        }
        let (axis_deg, axis_order) = d.axis.unwrap_or(([0.0; 3], EulerOrder::XYZ));
        let limits = d
            .limits
            .iter()
            .zip(&d.dof)
            .map(|(&(lo, hi), dof)| {
                if dof.rotation_axis().is_some() {
                    (units.angle.to_degrees(lo), units.angle.to_degrees(hi))
                } else {
                    (lo, hi)
                }
            })
            .collect();
        bones.push(AsfBone {
            id: d.id,
            name: child.clone(),
            parent,
            direction: d.direction.unwrap_or_else(Vec3::zeros),
            length: d.length.unwrap_or(0.0),
            axis_deg,
            axis_order,
            dof: d.dof.clone(),
            limits,
        });
        let me = bones.len() - 1;
        index_of.insert(child.clone(), me);
        if let Some(kids) = children_of.get(&child) {
            stack.extend(kids.iter().rev().map(|k| (Some(me), k.clone(), depth + 1)));
        }
    }
    for bone_name in &file_order {
        if !index_of.contains_key(bone_name) {
            let line = by_name.get(bone_name).map(|d| d.line).unwrap_or(last_line);
            return Err(text_err(
                ASF,
                line,
                None,
                format!("bone {bone_name:?} is not connected to the root in :hierarchy"),
            ));
        }
    }
    Ok(AsfSkeleton {
        version,
        name,
        units,
        root: AsfRoot { order, axis: root_axis, position: root_position, orientation_deg: root_orientation },
        bones,
    })
}

fn pairs_into(line: usize, flat: &[f64], limits: &mut Vec<(f64, f64)>) -> Result<()> {
    if !flat.len().is_multiple_of(2) {
        return Err(text_err(ASF, line, None, "limits come in (min max) pairs"));
    }
    limits.extend(flat.chunks_exact(2).map(|p| (p[0], p[1])));
    Ok(())
}

/// Reads an ASF file (see [`read_asf`]); errors name the file.
pub fn read_asf_path(path: &Path) -> Result<AsfSkeleton> {
    read_asf_path_with(path, &Limits::default())
}

/// [`read_asf_path`] with explicit [`Limits`]. A path that is not a regular file (a named
/// pipe, a device, a directory) is refused before it is opened.
pub fn read_asf_path_with(path: &Path, limits: &Limits) -> Result<AsfSkeleton> {
    let text = limits::read_utf8(path, limits)?;
    read_asf_with(&text, limits).map_err(|e| e.in_file(path))
}

impl AsfSkeleton {
    /// Millimetres per ASF length unit: `25.4 / length`, the CMU reading of `:units length`
    /// (lengths are in units of `1/length` inches; CMU's `length 0.45` gives 56.44 mm).
    pub fn mm_per_unit(&self) -> f64 {
        25.4 / self.units.length
    }

    /// The core skeleton: joint 0 `root`, one joint per bone at the bone's start (same order
    /// as [`AsfSkeleton::bones`], so bone `i` is joint `i + 1`), then an end site
    /// `<bone>_End` at the tip of every leaf bone. Lengths are multiplied by
    /// `mm_per_length_unit` (usually [`AsfSkeleton::mm_per_unit`]).
    pub fn to_skeleton(&self, mm_per_length_unit: f64) -> Result<Skeleton> {
        let s = mm_per_length_unit;
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::Unsupported(format!("length scale {s} mm per unit is not a positive number")));
        }
        let mut names: HashSet<&str> = self.bones.iter().map(|b| b.name.as_str()).collect();
        names.insert("root");
        let mut joints = Vec::with_capacity(2 * self.bones.len() + 1);
        joints.push(Joint {
            name: "root".into(),
            parent: None,
            offset_mm: self.root.position * s,
            rotation_order: root_rotation_order(&self.root),
            is_end_site: false,
        });
        let mut has_child = vec![false; self.bones.len()];
        for (i, bone) in self.bones.iter().enumerate() {
            let offset_mm = match bone.parent {
                Some(p) => {
                    let parent = self.bones.get(p).ok_or_else(|| bad_parent(bone))?;
                    if p >= i {
                        return Err(bad_parent(bone));
                    }
                    if let Some(flag) = has_child.get_mut(p) {
                        *flag = true;
                    }
                    parent.direction * parent.length * s
                }
                None => Vec3::zeros(),
            };
            joints.push(Joint {
                name: bone.name.clone(),
                parent: Some(bone.parent.map_or(0, |p| p + 1)),
                offset_mm,
                rotation_order: bone_rotation_order(bone),
                is_end_site: false,
            });
        }
        let mut taken: HashSet<String> = names.iter().map(|n| n.to_string()).collect();
        for (i, bone) in self.bones.iter().enumerate() {
            if has_child.get(i).copied().unwrap_or(true) {
                continue;
            }
            let base = format!("{}_End", bone.name);
            let mut name = base.clone();
            let mut k = 2;
            while taken.contains(&name) {
                name = format!("{base}{k}");
                k += 1;
            }
            taken.insert(name.clone());
            joints.push(Joint {
                name,
                parent: Some(i + 1),
                offset_mm: bone.direction * bone.length * s,
                rotation_order: bone_rotation_order(bone),
                is_end_site: true,
            });
        }
        Ok(Skeleton::new(joints)?)
    }
}

fn bad_parent(bone: &AsfBone) -> Error {
    Error::Unsupported(format!("bone {:?}: its parent does not come before it", bone.name))
}

/// The core order closest to how the file rotates this bone: its rotation dofs in listed
/// order, completed with the missing axes, reversed into the core product convention.
fn dof_order(dofs: impl Iterator<Item = Dof>, fallback: EulerOrder) -> EulerOrder {
    let mut axes: Vec<usize> = dofs.filter_map(Dof::rotation_axis).collect();
    if axes.is_empty() {
        return reversed(fallback);
    }
    for a in 0..3 {
        if !axes.contains(&a) {
            axes.push(a);
        }
    }
    match axes.as_slice() {
        [a, b, c] => EulerOrder::from_axes([*c, *b, *a]).unwrap_or(EulerOrder::ZYX),
        _ => EulerOrder::ZYX,
    }
}

fn bone_rotation_order(bone: &AsfBone) -> EulerOrder {
    dof_order(bone.dof.iter().copied(), bone.axis_order)
}

fn root_rotation_order(root: &AsfRoot) -> EulerOrder {
    dof_order(root.order.iter().copied(), root.axis)
}

/// Reads an AMC file's text against its skeleton, at `frame_rate_hz` (AMC files do not say;
/// CMU captures are 120 Hz). Root translations are scaled by [`AsfSkeleton::mm_per_unit`].
pub fn read_amc(text: &str, asf: &AsfSkeleton, frame_rate_hz: f64) -> Result<Motion> {
    read_amc_scaled(text, asf, frame_rate_hz, asf.mm_per_unit())
}

/// [`read_amc`] with an explicit length scale, to match [`AsfSkeleton::to_skeleton`].
pub fn read_amc_scaled(text: &str, asf: &AsfSkeleton, frame_rate_hz: f64, mm_per_length_unit: f64) -> Result<Motion> {
    read_amc_scaled_with(text, asf, frame_rate_hz, mm_per_length_unit, &Limits::default())
}

/// [`read_amc_scaled`] with explicit [`Limits`] on frames and samples (frames × joints).
pub fn read_amc_scaled_with(
    text: &str,
    asf: &AsfSkeleton,
    frame_rate_hz: f64,
    mm_per_length_unit: f64,
    limits: &Limits,
) -> Result<Motion> {
    // Checked first: a rate the caller got wrong should not cost a pass over the file.
    if !(frame_rate_hz.is_finite() && frame_rate_hz > 0.0) {
        return Err(locap_core::SkeletonError::BadFrameRate(frame_rate_hz).into());
    }
    let skeleton = asf.to_skeleton(mm_per_length_unit)?;
    for bone in &asf.bones {
        if bone.dof.iter().any(|d| d.rotation_axis().is_none()) {
            return Err(Error::Unsupported(format!(
                "bone {:?} has translation or length dofs, which locap does not read",
                bone.name
            )));
        }
    }
    if asf.root.order.contains(&Dof::L) {
        return Err(Error::Unsupported("root dof \"l\"".into()));
    }
    let s = mm_per_length_unit;
    let joints = skeleton.len();
    let bone_count = asf.bones.len();
    // Slot 0 is the root; slot i + 1 is bone i. Value vectors are reused frame to frame.
    let mut slots: HashMap<&str, usize> = HashMap::with_capacity(bone_count + 1);
    slots.insert("root", 0);
    for (i, b) in asf.bones.iter().enumerate() {
        slots.insert(b.name.as_str(), i + 1);
    }
    let dofs: Vec<&[Dof]> =
        std::iter::once(asf.root.order.as_slice()).chain(asf.bones.iter().map(|b| b.dof.as_slice())).collect();
    // The constant frames C and C^-1 of every bone (and the root).
    let frames: Vec<(Quat, Quat)> = std::iter::once(axis_frame(asf.root.axis, asf.root.orientation_deg))
        .chain(asf.bones.iter().map(|b| axis_frame(b.axis_order, b.axis_deg)))
        .map(|c| (c, c.inverse()))
        .collect();

    let mut angle_unit = asf.units.angle;
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); bone_count + 1];
    let mut seen = vec![false; bone_count + 1];
    let mut frame_number: Option<i64> = None;
    let mut frames_started = 0usize;
    let mut rotations: Vec<Quat> = Vec::new();
    let mut root_positions: Vec<Vec3> = Vec::new();

    let mut finish = |values: &mut Vec<Vec<f64>>, seen: &mut Vec<bool>, unit: AngleUnit| {
        let mut p = asf.root.position * s;
        for (slot, (vals, ((c, c_inv), dof))) in values.iter().zip(frames.iter().zip(&dofs)).enumerate() {
            let m = acclaim_rotation(
                dof.iter().zip(vals).filter_map(|(d, v)| d.rotation_axis().map(|a| (a, unit.to_degrees(*v)))),
            );
            rotations.push(c * m * c_inv);
            if slot == 0 {
                for (d, v) in dof.iter().zip(vals) {
                    if let Some(a) = d.translation_axis() {
                        p[a] = v * s;
                    }
                }
            }
        }
        root_positions.push(p);
        // End sites never rotate.
        rotations.extend(std::iter::repeat_n(Quat::identity(), joints.saturating_sub(bone_count + 1)));
        for v in values.iter_mut() {
            v.clear();
        }
        seen.fill(false);
    };

    for (line, raw) in content_lines(text) {
        let ws: Vec<(usize, &str)> = words(raw).collect();
        let Some(&(col, key)) = ws.first() else {
            continue;
        };
        if let Some(keyword) = key.strip_prefix(':') {
            if frame_number.is_some() {
                return Err(text_err(AMC, line, Some(col), "header keyword after the first frame"));
            }
            match keyword.to_ascii_uppercase().as_str() {
                "DEGREES" => angle_unit = AngleUnit::Degree,
                "RADIANS" => angle_unit = AngleUnit::Radian,
                _ => {} // :FULLY-SPECIFIED and others: nothing to change
            }
            continue;
        }
        if ws.len() == 1
            && let Ok(n) = key.parse::<i64>()
        {
            if let Some(prev) = frame_number {
                if prev.checked_add(1) != Some(n) {
                    return Err(text_err(AMC, line, Some(col), format!("frame {n} follows frame {prev}")));
                }
                finish(&mut values, &mut seen, angle_unit);
            }
            // The frame starting here will be stored: count it before it is.
            frames_started += 1;
            limits.check_text_samples(AMC, frames_started, joints, "joints", text.len())?;
            frame_number = Some(n);
            continue;
        }
        if frame_number.is_none() {
            return Err(text_err(AMC, line, Some(col), format!("expected a frame number, found {key:?}")));
        }
        let slot = *slots
            .get(key)
            .ok_or_else(|| text_err(AMC, line, Some(col), format!("unknown bone {key:?} (not in the ASF)")))?;
        let (Some(vals), Some(dof), Some(flag)) = (values.get_mut(slot), dofs.get(slot), seen.get_mut(slot)) else {
            continue;
        };
        if *flag {
            return Err(text_err(AMC, line, Some(col), format!("bone {key:?} appears twice in one frame")));
        }
        *flag = true;
        let given = ws.get(1..).unwrap_or(&[]);
        if given.len() != dof.len() {
            return Err(text_err(
                AMC,
                line,
                None,
                format!("bone {key:?} has {} dofs, the line gives {} values", dof.len(), given.len()),
            ));
        }
        for &(c, w) in given {
            vals.push(num(AMC, line, c, w, "a dof value", false)?);
        }
    }
    if frame_number.is_some() {
        finish(&mut values, &mut seen, angle_unit);
    }
    Ok(Motion::new(skeleton, rotations, root_positions, frame_rate_hz)?)
}

/// Reads an AMC file (see [`read_amc`]); errors name the file.
pub fn read_amc_path(path: &Path, asf: &AsfSkeleton, frame_rate_hz: f64) -> Result<Motion> {
    read_amc_path_with(path, asf, frame_rate_hz, &Limits::default())
}

/// [`read_amc_path`] with explicit [`Limits`]. A path that is not a regular file (a named
/// pipe, a device, a directory) is refused before it is opened.
pub fn read_amc_path_with(path: &Path, asf: &AsfSkeleton, frame_rate_hz: f64, limits: &Limits) -> Result<Motion> {
    let text = limits::read_utf8(path, limits)?;
    read_amc_scaled_with(&text, asf, frame_rate_hz, asf.mm_per_unit(), limits).map_err(|e| e.in_file(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASF_TEXT: &str = "# test\r\n:version 1.10\r\n:name T\r\n:units\r\n  mass 1.0\r\n  length 0.45\r\n  angle deg\r\n:documentation\r\n  free text: anything\r\n:root\r\n   order TX TY TZ RX RY RZ\r\n   axis XYZ\r\n   position 0 0 0\r\n   orientation 0 0 0\r\n:bonedata\r\n  begin\r\n     id 1\r\n     name a\r\n     direction 1 0 0\r\n     length 2\r\n     axis 90 0 90 XYZ\r\n    dof rx\r\n    limits (-160.0 20.0)\r\n  end\r\n  begin\r\n     id 2\r\n     name b\r\n     direction 0 1 0\r\n     length 1\r\n     axis 0 0 0 XYZ\r\n    dof rx rz\r\n    limits (-inf inf)\r\n           (-70.0 70.0)\r\n  end\r\n:hierarchy\r\n  begin\r\n    root a\r\n    a b\r\n  end\r\n";

    fn amc(frames: &[&str]) -> String {
        let mut s = String::from("#!OML:ASF x\r\n:FULLY-SPECIFIED\r\n:DEGREES\r\n");
        for (i, f) in frames.iter().enumerate() {
            s.push_str(&format!("{}\r\n{f}", i + 1));
        }
        s
    }

    #[test]
    fn reads_the_test_skeleton() {
        let asf = read_asf(ASF_TEXT).unwrap();
        assert_eq!(asf.version.as_deref(), Some("1.10"));
        assert_eq!(asf.bones.len(), 2);
        assert_eq!(asf.bones[1].parent, Some(0));
        assert_eq!(asf.bones[1].dof, [Dof::Rx, Dof::Rz]);
        assert_eq!(asf.bones[1].limits[0].0, f64::NEG_INFINITY);
        assert!((asf.mm_per_unit() - 25.4 / 0.45).abs() < 1e-12);
        let sk = asf.to_skeleton(1.0).unwrap();
        let names: Vec<&str> = sk.joints().iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["root", "a", "b", "b_End"]);
        assert_eq!(sk.joints()[2].offset_mm, Vec3::new(2.0, 0.0, 0.0));
    }

    /// Hand-computed Acclaim convention: the first listed axis is applied first.
    #[test]
    fn acclaim_axis_and_dof_order() {
        let asf = read_asf(ASF_TEXT).unwrap();
        // Bone a: C = Rz(90) Rx(90) maps X to Y, so `rx 90` turns about world Y, and the tip
        // of a (2, 0, 0) goes to (0, 0, -2). (The reverse product would turn about Z.)
        // Bone b: M = Rz(90) Rx(90) takes its direction Y to Z (Rx first), not to -X.
        let m = read_amc(
            &amc(&["root 0 0 0 0 0 0\r\na 90\r\nb 0 0\r\n", "root 1 2 3 0 0 0\r\na 0\r\nb 90 90\r\n"]),
            &asf,
            120.0,
        )
        .unwrap();
        assert_eq!(m.frame_count(), 2);
        let s = asf.mm_per_unit();
        let p = m.forward_kinematics(0).positions_mm;
        assert!((p[2] - Vec3::new(0.0, 0.0, -2.0 * s)).norm() < 1e-9, "{:?}", p[2]);
        let p = m.forward_kinematics(1).positions_mm;
        assert!((p[0] - Vec3::new(1.0, 2.0, 3.0) * s).norm() < 1e-9);
        assert!((p[3] - Vec3::new(3.0, 2.0, 4.0) * s).norm() < 1e-9, "{:?}", p[3]);
    }

    #[test]
    fn radians_header_is_honoured() {
        let asf = read_asf(ASF_TEXT).unwrap();
        let text = amc(&["root 0 0 0 0 0 0\r\na 1.5707963267948966\r\n"]).replace(":DEGREES", ":RADIANS");
        let m = read_amc(&text, &asf, 120.0).unwrap();
        let p = m.forward_kinematics(0).positions_mm;
        assert!((p[2] - Vec3::new(0.0, 0.0, -2.0 * asf.mm_per_unit())).norm() < 1e-9);
    }

    #[test]
    fn amc_errors_name_the_line() {
        let asf = read_asf(ASF_TEXT).unwrap();
        let check = |text: String, want_line: usize| match read_amc(&text, &asf, 120.0) {
            Err(Error::Text { format: "AMC", line, .. }) => assert_eq!(line, want_line, "{text}"),
            other => panic!("{other:?}"),
        };
        check(amc(&["root 0 0 0 0 0 0\r\nzzz 1\r\n"]), 6);
        check(amc(&["root 0 0 0 0 0 0\r\na x\r\n"]), 6);
        check(amc(&["root 0 0 0 0 0\r\n"]), 5);
        check(amc(&["a 1\r\na 2\r\n"]), 6);
        check(amc(&["a 1\r\n"]).replace("\r\n2\r\n", "\r\n3\r\n") + "3\r\n", 6);
        check("a 1\r\n".into(), 1);
        // Skipped frame number.
        check(amc(&["a 1\r\n", "a 1\r\n"]).replace("\r\n2\r\n", "\r\n4\r\n"), 6);
    }

    #[test]
    fn asf_errors_name_the_line() {
        let check = |text: String, want_line: usize| match read_asf(&text) {
            Err(Error::Text { format: "ASF", line, .. }) => assert_eq!(line, want_line, "{text}"),
            other => panic!("{other:?}"),
        };
        check(ASF_TEXT.replace("length 2", "length two"), 20);
        check(ASF_TEXT.replace("a b\r\n", "a c\r\n"), 38);
        check(ASF_TEXT.replace("direction 0 1 0", "direction 0 1"), 28);
        check(ASF_TEXT.replace("axis 90 0 90 XYZ", "axis 90 0 90 XXZ"), 21);
        check(ASF_TEXT.replace("dof rx rz", "dof rx rq"), 31);
    }

    #[test]
    fn every_truncation_is_an_error_or_ok_never_a_panic() {
        let asf = read_asf(ASF_TEXT).unwrap();
        for (i, _) in ASF_TEXT.char_indices() {
            if let Err(e) = read_asf(&ASF_TEXT[..i]) {
                assert!(matches!(e, Error::Text { .. }), "cut at {i}: {e:?}");
            }
        }
        let text = amc(&["root 0 0 0 0 0 0\r\na 90\r\nb 0 0\r\n", "root 1 2 3 0 0 0\r\na 0\r\nb 90 90\r\n"]);
        for (i, _) in text.char_indices() {
            if let Err(e) = read_amc(&text[..i], &asf, 120.0) {
                assert!(matches!(e, Error::Text { .. }), "cut at {i}: {e:?}");
            }
        }
    }
}
