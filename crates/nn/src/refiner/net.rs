//! The refiner network of LocalMoCap section 3.1: marker-graph convolutions (Eq. 4) over the
//! stable-neighbour graph, a bidirectional LSTM over the frames of a window, and a linear head
//! that predicts a residual offset per marker (`M_off` of Eq. 3).
//!
//! Shapes: the input is `[batch, frames, markers, 4]` (normalised local position and the
//! visibility flag, see [`crate::features`]); the output is `[batch, frames, markers, 3]`
//! offsets in units of each marker's position standard deviation.
//!
//! The graph convolution gives every edge its own filter (the paper: "unlike traditional
//! convolution operations, our convolution operation employs different filters and biases for
//! different edges"): node `i` sums `W_ij f_j` over itself and its `K` neighbours, plus `b_i`.
//! It is computed as one batched matrix product per layer: the neighbour features are gathered
//! into `[markers, batch*frames, (K+1)*C_in]` and multiplied by the per-marker filter bank
//! `[markers, (K+1)*C_in, C_out]`.
//!
//! The head starts at zero, so an untrained refiner returns EDM's fill unchanged and training
//! starts from EDM's error.

use burn::module::{Module, Param};
use burn::nn::{BiLstm, BiLstmConfig, Initializer, Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::leaky_relu;
use serde::{Deserialize, Serialize};

/// The network's settings in a training configuration; with the marker count they make its
/// [`Architecture`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetConfig {
    /// Graph-convolution features per marker.
    pub channels: usize,
    /// LSTM hidden size per direction.
    pub hidden: usize,
    /// Graph neighbours per marker.
    pub neighbours: usize,
}

impl NetConfig {
    /// The network of these settings for `markers` markers.
    pub fn architecture(&self, markers: usize) -> Architecture {
        Architecture { markers, neighbours: self.neighbours, channels: self.channels, hidden: self.hidden }
    }
}

/// Size of the network (stored in the model file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Architecture {
    /// Number of markers `M`.
    pub markers: usize,
    /// Neighbours per marker in the graph convolution (`K`, the node itself not counted).
    pub neighbours: usize,
    /// Features per marker after each graph convolution.
    pub channels: usize,
    /// Hidden size of each LSTM direction.
    pub hidden: usize,
}

impl Architecture {
    /// Number of input features per marker: local x, y, z and the visibility flag.
    pub const INPUT_FEATURES: usize = 4;

    /// The number of weights [`RefinerNet::new`] makes, in `f64` so that sizes read from a
    /// file cannot overflow it (checked against [`crate::limits::MAX_WEIGHTS`] before
    /// building).
    pub fn weights(&self) -> f64 {
        let (m, e, c, h) =
            (self.markers as f64, (self.neighbours + 1) as f64, self.channels as f64, self.hidden as f64);
        let conv = |c_in: f64| m * e * c_in * c + m * c;
        // burn's LSTM gate: an input and a hidden linear layer, each with a bias.
        let lstm = 2.0 * 4.0 * (m * c * h + h * h + 2.0 * h);
        conv(Self::INPUT_FEATURES as f64) + conv(c) + lstm + 2.0 * h * 3.0 * m + 3.0 * m
    }
}

/// One Eq. 4 graph convolution layer: a filter `W_ij` per edge and a bias `b_i` per node.
#[derive(Module, Debug)]
pub struct GraphConv {
    /// `[markers, (K+1) * c_in, c_out]`: the filters of node `i`'s edges, the node itself first.
    pub weight: Param<Tensor<3>>,
    /// `[markers, c_out]`.
    pub bias: Param<Tensor<2>>,
}

impl GraphConv {
    /// A layer for `markers` destination nodes with `edges` incoming edges each (the node
    /// itself counted where it is one of them), `c_in` features in and `c_out` out.
    pub fn new(markers: usize, edges: usize, c_in: usize, c_out: usize, device: &Device) -> GraphConv {
        let fan_in = edges * c_in;
        let weight = Initializer::KaimingUniform { gain: 1.0 / 3.0f64.sqrt(), fan_out_only: false }.init_with(
            [markers, fan_in, c_out],
            Some(fan_in),
            Some(c_out),
            device,
        );
        let bias = Initializer::Zeros.init([markers, c_out], device);
        GraphConv { weight, bias }
    }

    /// `x`: `[n, nodes, c_in]`; `gather`: the `markers * (K+1)` source node indices, node `i`'s
    /// edges at `i*(K+1)..(i+1)*(K+1)`. Returns `[n, markers, c_out]`. The source nodes may
    /// be another graph's (an inter-graph convolution, LocalMoCap section 3.2).
    pub fn forward(&self, x: Tensor<3>, gather: Tensor<1, Int>) -> Tensor<3> {
        let [n, _, c_in] = x.dims();
        let [m, fan_in, c_out] = self.weight.dims();
        let edges = fan_in / c_in;
        let gathered = x.select(1, gather).reshape([n, m, edges * c_in]).swap_dims(0, 1);
        let y = gathered.matmul(self.weight.val()) + self.bias.val().reshape([m, 1, c_out]);
        y.swap_dims(0, 1)
    }
}

/// The refiner network.
#[derive(Module, Debug)]
pub struct RefinerNet {
    /// First graph convolution, 4 -> channels.
    pub conv1: GraphConv,
    /// Second graph convolution, channels -> channels.
    pub conv2: GraphConv,
    /// Bidirectional LSTM over the frames.
    pub lstm: BiLstm,
    /// Offset head, 2 * hidden -> markers * 3 (starts at zero).
    pub head: Linear,
}

/// Slope of the leaky ReLU after each graph convolution.
const LEAK: f64 = 0.1;

impl RefinerNet {
    /// A freshly initialised network on `device`.
    pub fn new(arch: &Architecture, device: &Device) -> RefinerNet {
        let edges = arch.neighbours + 1;
        RefinerNet {
            conv1: GraphConv::new(arch.markers, edges, Architecture::INPUT_FEATURES, arch.channels, device),
            conv2: GraphConv::new(arch.markers, edges, arch.channels, arch.channels, device),
            lstm: BiLstmConfig::new(arch.markers * arch.channels, arch.hidden, true).init(device),
            head: LinearConfig::new(2 * arch.hidden, arch.markers * 3)
                .with_initializer(Initializer::Zeros)
                .init(device),
        }
    }

    /// `x`: `[batch, frames, markers, 4]` -> offsets `[batch, frames, markers, 3]`.
    pub fn forward(&self, x: Tensor<4>, gather: Tensor<1, Int>) -> Tensor<4> {
        let [b, t, m, c] = x.dims();
        let h = leaky_relu(self.conv1.forward(x.reshape([b * t, m, c]), gather.clone()), LEAK);
        let h = leaky_relu(self.conv2.forward(h, gather), LEAK);
        let channels = h.dims()[2];
        let (h, _) = self.lstm.forward(h.reshape([b, t, m * channels]), None);
        self.head.forward(h).reshape([b, t, m, 3])
    }
}

/// The gather indices of a neighbour graph: for node `i`, `i` itself then its neighbours.
pub fn gather_indices(graph: &[Vec<usize>], device: &Device) -> Tensor<1, Int> {
    let flat: Vec<i64> = graph
        .iter()
        .enumerate()
        .flat_map(|(i, n)| std::iter::once(i).chain(n.iter().copied()))
        .map(|i| i as i64)
        .collect();
    let len = flat.len();
    Tensor::from_data(TensorData::new(flat, [len]), device)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn graph_conv_uses_only_the_edges_of_each_node() {
        let device = Device::default();
        // 3 markers, 1 neighbour each: 0 <- 1, 1 <- 0, 2 <- 0.
        let graph = vec![vec![1], vec![0], vec![0]];
        let conv = GraphConv::new(3, 2, 1, 1, &device);
        let gather = gather_indices(&graph, &device);
        let x = |v: [f32; 3]| Tensor::<3>::from_data(TensorData::new(v.to_vec(), [1, 3, 1]), &device);
        let base = conv.forward(x([1.0, 2.0, 3.0]), gather.clone()).into_data().try_to_vec::<f32>().unwrap();
        // Changing marker 2 changes only marker 2's output: nobody has it as a neighbour.
        let moved = conv.forward(x([1.0, 2.0, 7.0]), gather).into_data().try_to_vec::<f32>().unwrap();
        assert_eq!(base[0], moved[0]);
        assert_eq!(base[1], moved[1]);
        assert_ne!(base[2], moved[2]);
    }

    #[test]
    fn untrained_network_predicts_zero_offsets() {
        let device = Device::default();
        let arch = Architecture { markers: 5, neighbours: 2, channels: 4, hidden: 8 };
        let graph: Vec<Vec<usize>> = (0..5).map(|i| vec![(i + 1) % 5, (i + 2) % 5]).collect();
        let net = RefinerNet::new(&arch, &device);
        // The estimate the ceiling is checked on is the network's exact size.
        assert_eq!(arch.weights(), net.num_params() as f64);
        let x = Tensor::<4>::ones([2, 7, 5, 4], &device);
        let y = net.forward(x, gather_indices(&graph, &device));
        assert_eq!(y.dims(), [2, 7, 5, 3]);
        assert!(y.into_data().try_to_vec::<f32>().unwrap().iter().all(|v| *v == 0.0));
    }
}
