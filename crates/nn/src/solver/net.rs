//! The solving networks of LocalMoCap section 3.2 (Fig. 3) and the baselines they are compared
//! with (section 4, Table 1), all with one output: per joint a 9-D rotation and a 3-D bone
//! offset, plus the root translation.
//!
//! # Heterogeneous graph ([`Variant::Graph`])
//!
//! Nodes: the markers, the joints and one global node. Edges:
//! * marker - marker: each marker and its `K` (3) most stable neighbours (lowest variance of
//!   their distance over the training takes, section 3);
//! * joint - joint: each joint, its parent and its children (the bones);
//! * marker - joint: a joint is linked to the markers whose mean distance to it over the
//!   training frames is below a threshold (default [`MARKER_JOINT_THRESHOLD_MM`] for bodies,
//!   about 40 mm suits hands; at least the
//!   [`MIN_MARKERS_PER_JOINT`] nearest, at most [`MAX_MARKERS_PER_JOINT`]); the paper uses the
//!   T-pose distance, the pose-averaged distance is the same for markers on the joint's own
//!   segment and keeps markers that only pass near a joint at rest out;
//! * the global node is linked to every node: it reads all marker features and its feature is
//!   handed to every joint.
//!
//! Every convolution gives each edge its own filter (Eq. 4, [`GraphConv`]). Layers: two
//! intra-graph convolutions on the marker graph; then a *local branch* (one marker -> joint
//! inter-graph convolution) and a *global branch* (the global node: all marker features through
//! a linear layer and two residual blocks); per joint the local feature and the projected
//! global feature are concatenated and go through three joint-graph convolutions, the last of
//! which outputs the 12 numbers of each joint. The root translation comes from the global node.
//!
//! # Ablation and baseline
//! * [`Variant::NoMarkerConv`]: the marker-graph convolutions see only their own marker (one
//!   edge, the node itself): per-marker layers without neighbour information, the paper's
//!   "w/o marker convolution".
//! * [`Variant::Mlp`]: Holden (2018)'s solver: all marker inputs flattened into a residual MLP
//!   (one linear layer, three residual blocks, one linear layer), same outputs, same loss.
//!
//! # Outputs
//! The first six of a joint's 9 rotation numbers are two vectors `a`, `b` (added to the
//! identity's columns, so an untrained net starts near the rest pose); Gram-Schmidt makes them
//! the first two columns of a rotation and the third is `a x b` (the third Gram-Schmidt vector
//! with the sign that gives determinant +1, so the last three numbers carry no information).
//! Offsets and the translation are predicted normalised (mean and spread of the training data).

use crate::refiner::net::GraphConv;
use burn::module::Module;
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::leaky_relu;
use serde::{Deserialize, Serialize};

/// Default pose-averaged marker-joint distance below which they are linked (bodies), mm.
pub const MARKER_JOINT_THRESHOLD_MM: f64 = 150.0;
/// Every joint is linked to at least this many markers (its nearest).
pub const MIN_MARKERS_PER_JOINT: usize = 2;
/// And at most this many (its nearest).
pub const MAX_MARKERS_PER_JOINT: usize = 8;
/// Numbers per joint out of the network: 9 rotation + 3 offset.
pub const JOINT_OUTPUTS: usize = 12;
/// Slope of the leaky ReLUs.
const LEAK: f64 = 0.1;

/// Which network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Variant {
    /// The heterogeneous graph network (the paper's "Ours").
    #[default]
    Graph,
    /// The graph network without marker-graph convolutions ("w/o marker convolution").
    NoMarkerConv,
    /// Holden (2018)'s residual MLP.
    Mlp,
}

impl Variant {
    /// Name on the command line and in tables.
    pub fn name(self) -> &'static str {
        match self {
            Variant::Graph => "graph",
            Variant::NoMarkerConv => "no-marker-conv",
            Variant::Mlp => "mlp",
        }
    }
}

/// The graph of a solver (stored in its model file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SolverGraph {
    /// Per marker its most stable neighbours (marker indices).
    pub marker_neighbours: Vec<Vec<usize>>,
    /// Per joint its linked markers (marker indices), nearest first.
    pub joint_markers: Vec<Vec<usize>>,
    /// Per joint its parent (`None` for the root, joint 0).
    pub parents: Vec<Option<usize>>,
}

impl SolverGraph {
    /// Per joint the joint-graph edges: itself, its parent, its children.
    pub fn joint_edges(&self) -> Vec<Vec<usize>> {
        (0..self.parents.len())
            .map(|j| {
                let mut e = vec![j];
                e.extend(self.parents[j]);
                e.extend((0..self.parents.len()).filter(|&c| self.parents[c] == Some(j)));
                e
            })
            .collect()
    }

    /// Checks indices and shapes against `markers` and `joints`.
    pub fn check(&self, markers: usize, joints: usize) -> Result<(), String> {
        if self.marker_neighbours.len() != markers || self.marker_neighbours.iter().flatten().any(|&k| k >= markers) {
            return Err(format!("the marker graph is not {markers} lists of marker indices"));
        }
        if self.joint_markers.len() != joints
            || self.joint_markers.iter().flatten().any(|&k| k >= markers)
            || self.joint_markers.iter().any(|l| l.len() > MAX_MARKERS_PER_JOINT)
        {
            return Err(format!("the marker-joint links are not {joints} lists of marker indices"));
        }
        if self.parents.len() != joints
            || self.parents.first() != Some(&None)
            || self.parents.iter().enumerate().skip(1).any(|(j, p)| !matches!(p, Some(p) if *p < j))
        {
            return Err(format!("the joint parents are not a tree of {joints} joints, parents first"));
        }
        let k = self.marker_neighbours.first().map_or(0, Vec::len);
        if self.marker_neighbours.iter().any(|n| n.len() != k) {
            return Err("markers have different neighbour counts".into());
        }
        Ok(())
    }
}

/// The network's settings in a training configuration (with the variant, the data's markers
/// and joints, and the graph they make its [`SolverArchitecture`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NetConfig {
    /// Features per marker and joint node.
    pub channels: usize,
    /// Global-node features (the MLP's width).
    pub global: usize,
    /// Marker-graph neighbours `K` (the paper: 3).
    pub neighbours: usize,
    /// Pose-averaged marker-joint distance that links a marker to a joint, mm.
    #[serde(default = "default_link")]
    pub link_threshold_mm: f64,
}

fn default_link() -> f64 {
    MARKER_JOINT_THRESHOLD_MM
}

/// Size of a solver network (stored in the model file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct SolverArchitecture {
    /// Which network.
    pub variant: Variant,
    /// Markers `M`.
    pub markers: usize,
    /// Joints `J`.
    pub joints: usize,
    /// Features per marker and joint node.
    pub channels: usize,
    /// Features of the global node (the MLP's width).
    pub global: usize,
}

/// Input features per marker: normalised local x, y, z and visibility.
pub const INPUT_FEATURES: usize = 4;

impl SolverArchitecture {
    /// The number of weights [`SolverNet::new`] makes on `graph`, in `f64` so that sizes
    /// read from a file cannot overflow it (checked against [`crate::limits::MAX_WEIGHTS`]
    /// before building).
    pub fn weights(&self, graph: &SolverGraph) -> f64 {
        let (m, j, c, g) = (self.markers as f64, self.joints as f64, self.channels as f64, self.global as f64);
        let linear = |i: f64, o: f64| i * o + o;
        if self.variant == Variant::Mlp {
            let out = j * JOINT_OUTPUTS as f64 + 3.0;
            return linear(m * INPUT_FEATURES as f64, g) + 3.0 * linear(g, g) + linear(g, out);
        }
        let (em, ei, ej) = edge_counts(graph, self.variant);
        let conv =
            |nodes: f64, edges: usize, c_in: f64, c_out: f64| nodes * edges as f64 * c_in * c_out + nodes * c_out;
        conv(m, em, INPUT_FEATURES as f64, c)
            + conv(m, em, c, c)
            + linear(m * c, g)
            + 2.0 * linear(g, g)
            + conv(j, ei, c, c)
            + linear(g, c)
            + conv(j, ej, 2.0 * c, c)
            + conv(j, ej, c, c)
            + conv(j, ej, c, JOINT_OUTPUTS as f64)
            + linear(g, 3.0)
    }
}

/// Source indices of padded edge lists: node `i`'s edges at `i*E..(i+1)*E`, missing edges
/// pointing at `pad` (a zero node appended to the source features).
fn padded(lists: &[Vec<usize>], pad: usize) -> (Vec<i64>, usize) {
    let e = lists.iter().map(Vec::len).max().unwrap_or(0).max(1);
    let flat = lists.iter().flat_map(|l| (0..e).map(move |i| l.get(i).copied().unwrap_or(pad) as i64)).collect();
    (flat, e)
}

/// The gather indices of a solver's graph on a device.
#[derive(Debug, Clone)]
pub struct Gathers {
    marker: Tensor<1, Int>,
    inter: Tensor<1, Int>,
    joint: Tensor<1, Int>,
}

impl Gathers {
    /// The indices of `graph` for `variant` on `device`.
    pub fn new(graph: &SolverGraph, variant: Variant, device: &Device) -> Gathers {
        let m = graph.marker_neighbours.len();
        let marker_lists: Vec<Vec<usize>> = match variant {
            Variant::NoMarkerConv => (0..m).map(|i| vec![i]).collect(),
            _ => graph.marker_neighbours.iter().enumerate().map(|(i, n)| [vec![i], n.clone()].concat()).collect(),
        };
        let t = |(v, _): (Vec<i64>, usize)| {
            let len = v.len();
            Tensor::<1, Int>::from_data(TensorData::new(v, [len]), device)
        };
        Gathers {
            marker: t(padded(&marker_lists, m)),
            inter: t(padded(&graph.joint_markers, m)),
            joint: t(padded(&graph.joint_edges(), graph.parents.len())),
        }
    }
}

/// Edges per node of each convolution of `graph` for `variant`: marker, inter, joint.
fn edge_counts(graph: &SolverGraph, variant: Variant) -> (usize, usize, usize) {
    let m = graph.marker_neighbours.len();
    let marker = match variant {
        Variant::NoMarkerConv => 1,
        _ => 1 + graph.marker_neighbours.first().map_or(0, Vec::len),
    };
    (marker, padded(&graph.joint_markers, m).1, padded(&graph.joint_edges(), graph.parents.len()).1)
}

/// `x` `[n, nodes, c]` with a zero node appended (the target of padded edges).
fn with_zero_node(x: Tensor<3>) -> Tensor<3> {
    let [n, _, c] = x.dims();
    let zeros = Tensor::zeros([n, 1, c], &x.device());
    Tensor::cat(vec![x, zeros], 1)
}

/// A residual block: `x + leaky(W x + b)`.
#[derive(Module, Debug)]
pub struct Residual {
    /// The layer.
    pub linear: Linear,
}

impl Residual {
    fn new(width: usize, device: &Device) -> Residual {
        Residual { linear: LinearConfig::new(width, width).init(device) }
    }
    fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        x.clone() + leaky_relu(self.linear.forward(x), LEAK)
    }
}

/// The heterogeneous graph network (also the no-marker-convolution ablation).
#[derive(Module, Debug)]
pub struct GraphNet {
    /// Marker-graph convolutions.
    pub marker1: GraphConv,
    /// Second marker-graph convolution.
    pub marker2: GraphConv,
    /// Global node: all marker features in.
    pub global_in: Linear,
    /// Global node: residual blocks.
    pub global_blocks: Vec<Residual>,
    /// Local branch: marker -> joint inter-graph convolution.
    pub inter: GraphConv,
    /// Global feature projected for every joint.
    pub global_to_joint: Linear,
    /// Joint-graph convolutions.
    pub joint1: GraphConv,
    /// Second joint-graph convolution.
    pub joint2: GraphConv,
    /// Output joint-graph convolution (12 per joint).
    pub joint_out: GraphConv,
    /// Root translation from the global node.
    pub translation: Linear,
}

impl GraphNet {
    fn new(arch: &SolverArchitecture, graph: &SolverGraph, device: &Device) -> GraphNet {
        let (em, ei, ej) = edge_counts(graph, arch.variant);
        let (m, j, c, g) = (arch.markers, arch.joints, arch.channels, arch.global);
        GraphNet {
            marker1: GraphConv::new(m, em, INPUT_FEATURES, c, device),
            marker2: GraphConv::new(m, em, c, c, device),
            global_in: LinearConfig::new(m * c, g).init(device),
            global_blocks: (0..2).map(|_| Residual::new(g, device)).collect(),
            inter: GraphConv::new(j, ei, c, c, device),
            global_to_joint: LinearConfig::new(g, c).init(device),
            joint1: GraphConv::new(j, ej, 2 * c, c, device),
            joint2: GraphConv::new(j, ej, c, c, device),
            joint_out: GraphConv::new(j, ej, c, JOINT_OUTPUTS, device),
            translation: LinearConfig::new(g, 3).init(device),
        }
    }

    fn forward(&self, x: Tensor<3>, gathers: &Gathers) -> (Tensor<3>, Tensor<2>) {
        let [n, m, _] = x.dims();
        let h = leaky_relu(self.marker1.forward(x, gathers.marker.clone()), LEAK);
        let h = leaky_relu(self.marker2.forward(h, gathers.marker.clone()), LEAK);
        let c = h.dims()[2];
        let mut global = leaky_relu(self.global_in.forward(h.clone().reshape([n, m * c])), LEAK);
        for block in &self.global_blocks {
            global = block.forward(global);
        }
        let local = leaky_relu(self.inter.forward(with_zero_node(h), gathers.inter.clone()), LEAK);
        let j = local.dims()[1];
        let to_joints =
            leaky_relu(self.global_to_joint.forward(global.clone()), LEAK).reshape([n, 1, c]).repeat_dim(1, j);
        let joints = Tensor::cat(vec![local, to_joints], 2);
        let joints = leaky_relu(self.joint1.forward(with_zero_node(joints), gathers.joint.clone()), LEAK);
        let joints = leaky_relu(self.joint2.forward(with_zero_node(joints), gathers.joint.clone()), LEAK);
        let out = self.joint_out.forward(with_zero_node(joints), gathers.joint.clone());
        (out, self.translation.forward(global))
    }
}

/// Holden (2018)'s residual MLP solver.
#[derive(Module, Debug)]
pub struct MlpNet {
    /// Flattened markers in.
    pub input: Linear,
    /// Residual blocks.
    pub blocks: Vec<Residual>,
    /// All joints' outputs and the translation.
    pub output: Linear,
}

impl MlpNet {
    fn new(arch: &SolverArchitecture, device: &Device) -> MlpNet {
        let w = arch.global;
        MlpNet {
            input: LinearConfig::new(arch.markers * INPUT_FEATURES, w).init(device),
            blocks: (0..3).map(|_| Residual::new(w, device)).collect(),
            output: LinearConfig::new(w, arch.joints * JOINT_OUTPUTS + 3).init(device),
        }
    }

    fn forward(&self, x: Tensor<3>, joints: usize) -> (Tensor<3>, Tensor<2>) {
        let [n, m, c] = x.dims();
        let mut h = leaky_relu(self.input.forward(x.reshape([n, m * c])), LEAK);
        for block in &self.blocks {
            h = block.forward(h);
        }
        let out = self.output.forward(h);
        let per_joint = out.clone().narrow(1, 0, joints * JOINT_OUTPUTS).reshape([n, joints, JOINT_OUTPUTS]);
        (per_joint, out.narrow(1, joints * JOINT_OUTPUTS, 3))
    }
}

/// A solver network of any variant.
#[derive(Module, Debug)]
pub struct SolverNet {
    /// The graph network (graph and no-marker-conv variants).
    pub graph: Option<GraphNet>,
    /// The MLP (mlp variant).
    pub mlp: Option<MlpNet>,
}

impl SolverNet {
    /// A freshly initialised network.
    pub fn new(arch: &SolverArchitecture, graph: &SolverGraph, device: &Device) -> SolverNet {
        match arch.variant {
            Variant::Mlp => SolverNet { graph: None, mlp: Some(MlpNet::new(arch, device)) },
            _ => SolverNet { graph: Some(GraphNet::new(arch, graph, device)), mlp: None },
        }
    }

    /// `x` `[n, M, 4]` -> raw joint outputs `[n, J, 12]` and normalised translation `[n, 3]`.
    pub fn forward(&self, x: Tensor<3>, gathers: &Gathers, joints: usize) -> (Tensor<3>, Tensor<2>) {
        match (&self.graph, &self.mlp) {
            (Some(g), _) => g.forward(x, gathers),
            (None, Some(m)) => m.forward(x, joints),
            // `new` always builds one of the two.
            (None, None) => unreachable!("a solver network has a graph or an MLP"),
        }
    }
}

/// Gram-Schmidt: two vectors `[n, J, 3]` to rotation matrices `[n, J, 3, 3]` whose columns
/// are `a/|a|`, the part of `b` orthogonal to it normalised, and their cross product.
pub fn gram_schmidt(a: Tensor<3>, b: Tensor<3>) -> Tensor<4> {
    let norm = |v: Tensor<3>| v.clone() / (v.powf_scalar(2.0).sum_dim(2) + 1e-8).sqrt();
    let a = norm(a);
    let b = norm(b.clone() - a.clone() * (a.clone() * b).sum_dim(2));
    let comp = |v: &Tensor<3>, i: usize| v.clone().narrow(2, i, 1);
    let c = Tensor::cat(
        vec![
            comp(&a, 1) * comp(&b, 2) - comp(&a, 2) * comp(&b, 1),
            comp(&a, 2) * comp(&b, 0) - comp(&a, 0) * comp(&b, 2),
            comp(&a, 0) * comp(&b, 1) - comp(&a, 1) * comp(&b, 0),
        ],
        2,
    );
    Tensor::stack(vec![a, b, c], 3)
}

/// Forward kinematics in burn: local rotations `[n, J, 3, 3]` (the root's global), offsets
/// `[n, J, 3]` in the parent's frame, root positions `[n, 3]` -> joint positions `[n, J, 3]`,
/// with the conventions of `locap_core::skeleton` (`P_j = P_p + G_p o_j`, `G_j = G_p L_j`).
pub fn forward_kinematics(
    rotations: Tensor<4>,
    offsets: Tensor<3>,
    root: Tensor<2>,
    parents: &[Option<usize>],
) -> Tensor<3> {
    let [n, j, _, _] = rotations.dims();
    let locals = rotations.chunk(j, 1);
    let offs = offsets.chunk(j, 1);
    let mut global: Vec<Tensor<3>> = Vec::with_capacity(j);
    let mut positions: Vec<Tensor<2>> = Vec::with_capacity(j);
    for (k, (local, off)) in locals.into_iter().zip(offs).enumerate() {
        let local = local.reshape([n, 3, 3]);
        match parents.get(k).copied().flatten() {
            Some(p) if p < k => {
                let moved = global[p].clone().matmul(off.reshape([n, 3, 1])).reshape([n, 3]);
                positions.push(positions[p].clone() + moved);
                global.push(global[p].clone().matmul(local));
            }
            _ => {
                positions.push(root.clone());
                global.push(local);
            }
        }
    }
    Tensor::stack(positions, 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use locap_core::{EulerOrder, Joint, Quat, Skeleton, Vec3};

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    #[test]
    fn gram_schmidt_gives_rotations() {
        let device = Device::default();
        let raw: Vec<f32> = (0..2 * 5 * 3).map(|i| ((i * 37 % 11) as f32 - 5.0) / 3.0 + 0.1).collect();
        let a = Tensor::<3>::from_data(TensorData::new(raw[..15].to_vec(), [1, 5, 3]), &device);
        let b = Tensor::<3>::from_data(TensorData::new(raw[15..].to_vec(), [1, 5, 3]), &device);
        let r = values(gram_schmidt(a, b));
        for k in 0..5 {
            let m = nalgebra::Matrix3::from_fn(|i, j| r[k * 9 + i * 3 + j] as f64);
            assert!((m.transpose() * m - nalgebra::Matrix3::identity()).norm() < 1e-5, "{m}");
            assert!((m.determinant() - 1.0).abs() < 1e-5);
            // The first column is the first vector's direction.
            let a0 = Vec3::new(raw[3 * k] as f64, raw[3 * k + 1] as f64, raw[3 * k + 2] as f64).normalize();
            assert!((m.column(0) - a0).norm() < 1e-5);
        }
    }

    #[test]
    fn burn_fk_matches_core_fk() {
        let device = Device::default();
        let joint = |name: &str, parent: Option<usize>, o: [f64; 3]| Joint {
            name: name.into(),
            parent,
            offset_mm: Vec3::from(o),
            rotation_order: EulerOrder::ZXY,
            is_end_site: false,
        };
        let sk = Skeleton::new(vec![
            joint("root", None, [0.0; 3]),
            joint("a", Some(0), [100.0, 20.0, 0.0]),
            joint("b", Some(1), [0.0, -300.0, 10.0]),
            joint("c", Some(0), [-100.0, 20.0, 5.0]),
            joint("d", Some(2), [0.0, 0.0, 150.0]),
        ])
        .unwrap();
        let rots: Vec<Quat> = (0..5)
            .map(|i| EulerOrder::ZXY.to_quat_deg([10.0 * i as f64, -25.0 + 7.0 * i as f64, 40.0 - 3.0 * i as f64]))
            .collect();
        let root = Vec3::new(12.0, 900.0, -40.0);
        let expected = locap_core::skeleton::forward_kinematics(&sk, &rots, root);
        let mats: Vec<f32> = rots
            .iter()
            .flat_map(|q| {
                let m = q.to_rotation_matrix().into_inner();
                (0..9).map(move |i| m[(i / 3, i % 3)] as f32)
            })
            .collect();
        let offs: Vec<f32> = sk.joints().iter().flat_map(|j| j.offset_mm.iter().map(|v| *v as f32)).collect();
        let parents: Vec<Option<usize>> = sk.joints().iter().map(|j| j.parent).collect();
        let p = values(forward_kinematics(
            Tensor::from_data(TensorData::new(mats, [1, 5, 3, 3]), &device),
            Tensor::from_data(TensorData::new(offs, [1, 5, 3]), &device),
            Tensor::from_data(TensorData::new(vec![12.0f32, 900.0, -40.0], [1, 3]), &device),
            &parents,
        ));
        for (k, e) in expected.positions_mm.iter().enumerate() {
            let got = Vec3::new(p[3 * k] as f64, p[3 * k + 1] as f64, p[3 * k + 2] as f64);
            assert!((got - e).norm() < 1e-3, "joint {k}: {got} vs {e}");
        }
    }

    #[test]
    fn every_variant_has_the_output_shapes() {
        let device = Device::default();
        let graph = SolverGraph {
            marker_neighbours: (0..6).map(|i| vec![(i + 1) % 6, (i + 2) % 6, (i + 3) % 6]).collect(),
            joint_markers: vec![vec![0, 1], vec![2], vec![3, 4, 5], vec![]],
            parents: vec![None, Some(0), Some(1), Some(0)],
        };
        graph.check(6, 4).unwrap();
        assert_eq!(graph.joint_edges(), vec![vec![0, 1, 3], vec![1, 0, 2], vec![2, 1], vec![3, 0]]);
        for variant in [Variant::Graph, Variant::NoMarkerConv, Variant::Mlp] {
            let arch = SolverArchitecture { variant, markers: 6, joints: 4, channels: 5, global: 7 };
            let net = SolverNet::new(&arch, &graph, &device);
            // The estimate the ceiling is checked on is the network's exact size.
            assert_eq!(arch.weights(&graph), net.num_params() as f64, "{variant:?}");
            let (out, t) = net.forward(Tensor::ones([3, 6, 4], &device), &Gathers::new(&graph, variant, &device), 4);
            assert_eq!(out.dims(), [3, 4, JOINT_OUTPUTS], "{variant:?}");
            assert_eq!(t.dims(), [3, 3]);
        }
        let bad = SolverGraph { parents: vec![None, Some(2), Some(1), Some(0)], ..graph };
        assert!(bad.check(6, 4).is_err());
    }
}
