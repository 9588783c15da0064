//! ASF skeletons: the `:units`, `:root`, `:bonedata` and `:hierarchy` sections, and the core
//! [`Skeleton`] they map to (see the parent module for the conventions).

use super::{AngleUnit, Dof, content_lines, num, reversed, text_err, words};
use crate::limits::{self, Limits};
use crate::{Error, Result};
use locap_core::{EulerOrder, Joint, Skeleton, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::Path;

const ASF: &str = "ASF";

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

/// The ASF `:root` section.
#[derive(Debug, Clone, PartialEq)]
pub struct AsfRoot {
    /// The order of the root's values on an AMC `root` line (`TX TY TZ RX RY RZ` in CMU).
    pub order: Vec<Dof>,
    /// Axis letters of `orientation`, as written (`XYZ`: X applied first, see the module docs).
    pub axis: EulerOrder,
    /// Rest position of the root, in ASF length units.
    pub position: Vec3,
    /// Rest orientation angles, radians, in `axis` order.
    pub orientation_rad: [f64; 3],
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
    /// The `axis` angles, radians, in `axis_order` order.
    pub axis_rad: [f64; 3],
    /// Axis letters as written (`XYZ`: X applied first, see the module docs).
    pub axis_order: EulerOrder,
    /// Degrees of freedom, in the order AMC lines list their values.
    pub dof: Vec<Dof>,
    /// `(min, max)` per dof (radians for rotations; may be infinite); empty if not given.
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
                    root_orientation = three(line, rest, "orientation")?;
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
                        bone.axis = Some((angles, order));
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
        let (axis, axis_order) = d.axis.unwrap_or(([0.0; 3], EulerOrder::XYZ));
        let limits = d
            .limits
            .iter()
            .zip(&d.dof)
            .map(|(&(lo, hi), dof)| {
                if dof.rotation_axis().is_some() {
                    (units.angle.to_radians(lo), units.angle.to_radians(hi))
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
            axis_rad: axis.map(|a| units.angle.to_radians(a)),
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
    let orientation_rad = root_orientation.map(|a| units.angle.to_radians(a));
    Ok(AsfSkeleton {
        version,
        name,
        units,
        root: AsfRoot { order, axis: root_axis, position: root_position, orientation_rad },
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

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::Error;

    /// A two-bone skeleton in CMU's layout (CRLF, comments, limits over two lines).
    pub(in crate::asf_amc) const ASF_TEXT: &str = "# test\r\n:version 1.10\r\n:name T\r\n:units\r\n  mass 1.0\r\n  length 0.45\r\n  angle deg\r\n:documentation\r\n  free text: anything\r\n:root\r\n   order TX TY TZ RX RY RZ\r\n   axis XYZ\r\n   position 0 0 0\r\n   orientation 0 0 0\r\n:bonedata\r\n  begin\r\n     id 1\r\n     name a\r\n     direction 1 0 0\r\n     length 2\r\n     axis 90 0 90 XYZ\r\n    dof rx\r\n    limits (-160.0 20.0)\r\n  end\r\n  begin\r\n     id 2\r\n     name b\r\n     direction 0 1 0\r\n     length 1\r\n     axis 0 0 0 XYZ\r\n    dof rx rz\r\n    limits (-inf inf)\r\n           (-70.0 70.0)\r\n  end\r\n:hierarchy\r\n  begin\r\n    root a\r\n    a b\r\n  end\r\n";

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

    /// Every angle is read into radians once, with the file's unit wherever its `:units`
    /// section stands: a radian file whose `:units` come last reads as the degree one.
    #[test]
    fn angles_are_radians_whatever_the_unit() {
        let deg = read_asf(ASF_TEXT).unwrap();
        let units = "\r\n:units\r\n  mass 1.0\r\n  length 0.45\r\n  angle deg";
        let rad = ASF_TEXT.replace(units, "") + &units.replace("deg", "rad") + "\r\n";
        let (half, lo, hi) = (std::f64::consts::FRAC_PI_2, (-160.0f64).to_radians(), 70.0f64.to_radians());
        let rad = rad
            .replace("axis 90 0 90 XYZ", &format!("axis {half} 0 {half} XYZ"))
            .replace("(-160.0 20.0)", &format!("({lo} {})", 20.0f64.to_radians()))
            .replace("(-70.0 70.0)", &format!("({} {hi})", -hi));
        let rad = read_asf(&rad).unwrap();
        assert_eq!(rad.units.angle, AngleUnit::Radian);
        assert_eq!(deg.bones[0].axis_rad, [half, 0.0, half]);
        for (a, b) in deg.bones.iter().zip(&rad.bones) {
            assert_eq!(a.axis_rad, b.axis_rad);
            assert_eq!(a.limits.len(), b.limits.len());
            // Equal, infinite limits included, or within rounding.
            let close = |u: f64, v: f64| u == v || (u - v).abs() < 1e-12;
            for (x, y) in a.limits.iter().zip(&b.limits) {
                assert!(close(x.0, y.0) && close(x.1, y.1), "{x:?} {y:?}");
            }
        }
        assert_eq!(deg.bones[0].limits[0].0, lo);
    }
}
