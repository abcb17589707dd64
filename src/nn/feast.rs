//! FeaStConv, the feature-steered graph convolution (Verma et al. 2018; thesis eqs. 2.21–2.22,
//! 4.11), in PyTorch Geometric's translation-invariant form with self-loops, `H` heads, mean
//! aggregation and bias:
//!
//! y_i = b + (1/|N(i)|) Σ_{j∈N(i)} Σ_m q_m(x_i, x_j) W_m x_j,
//! q_m = softmax over m of (u_mᵀ(x_j − x_i) + c_m).
//!
//! Because `u` and `W` are linear, `x·U` (`[N, H]`) and `x·W` (`[N, H, d_out]`) are computed
//! once per node. Edges are grouped by source node in rows of `D` slots ([`SlotLayout`]), so
//! the messages of a row are one small matrix product `q_row [D, H] · (x_j W) [H, d_out]` (a
//! batched matmul over rows) and no per-edge `[E, H, d_out]` tensor is formed in the forward
//! or the backward pass. Messages are scatter-summed into their targets with
//! `select_assign(.., Add)`, whose gradient is defined for repeated indices.
//!
//! [`SlotLayout`]: super::slots::SlotLayout

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::activation::softmax;
use burn::tensor::{Device, IndexingUpdateOp, Tensor};
use rand_chacha::ChaCha8Rng;

use super::init::{fan_in_bound, normal, uniform};
use super::slots::GraphTensors;

/// Standard deviation of the initial steering offsets `c` and biases `b` (as in PyG).
const OFFSET_INIT_STD: f64 = 0.1;

/// Sizes of one FeaStConv layer.
#[derive(Config, Debug, PartialEq)]
pub struct FeaStConfig {
    /// Input feature width `d_in`.
    pub d_in: usize,
    /// Output feature width `d_out`.
    pub d_out: usize,
    /// Number of heads (weight matrices) `H`.
    #[config(default = 8)]
    pub heads: usize,
}

impl FeaStConfig {
    /// A layer with weights drawn from `rng` (PyTorch Geometric's initialisation): `W` and
    /// `u` uniform in ±1/√d_in, `c` and `b` normal with std 0.1.
    pub fn init(&self, rng: &mut ChaCha8Rng, device: &Device) -> FeaStConv {
        let bound = fan_in_bound(self.d_in);
        FeaStConv {
            weight: uniform([self.d_in, self.heads, self.d_out], bound, rng, device),
            steer: uniform([self.d_in, self.heads], bound, rng, device),
            steer_offset: normal([self.heads], OFFSET_INIT_STD, rng, device),
            bias: normal([self.d_out], OFFSET_INIT_STD, rng, device),
        }
    }
}

/// One FeaStConv layer.
#[derive(Module, Debug)]
pub struct FeaStConv {
    /// The head weight matrices, `[d_in, H, d_out]`: `W_m = weight[:, m, :]` acts as `x·W_m`.
    pub weight: Param<Tensor<3>>,
    /// The steering directions `u_m` as columns, `[d_in, H]`.
    pub steer: Param<Tensor<2>>,
    /// The steering offsets `c_m`, `[H]`.
    pub steer_offset: Param<Tensor<1>>,
    /// The bias `b`, `[d_out]`.
    pub bias: Param<Tensor<1>>,
}

impl FeaStConv {
    /// `(H, d_in, d_out)`.
    pub fn dims(&self) -> (usize, usize, usize) {
        let [d_in, h, d_out] = self.weight.shape().dims();
        (h, d_in, d_out)
    }

    /// Applies the layer to node features `x` (`[N, d_in]`) of the graph `graph`;
    /// returns `[N, d_out]`.
    pub fn forward(&self, x: Tensor<2>, graph: &GraphTensors) -> Tensor<2> {
        let (heads, d_in, d_out) = self.dims();
        let (n, r, d) = (graph.node_count, graph.row_count, graph.slots);
        let w = self.weight.val().reshape([d_in, heads * d_out]);
        let xw = x.clone().matmul(w);
        let xu = x.matmul(self.steer.val());
        let (xw, xu_rows) = match &graph.row_sources {
            Some(rows) => (
                xw.select(0, rows.clone()),
                xu.clone().select(0, rows.clone()),
            ),
            None => (xw, xu.clone()),
        };
        let q = self.steering(xu_rows, xu, graph);
        let messages = q.matmul(xw.reshape([r, heads, d_out]));
        let summed = Tensor::zeros([n, d_out], (&messages.device(), messages.dtype()))
            .select_assign(
                0,
                graph.slot_targets.clone(),
                messages.reshape([r * d, d_out]),
                IndexingUpdateOp::Add,
            );
        summed * graph.inv_degree.clone() + self.bias.val().unsqueeze_dim(0)
    }

    /// Head weights of every slot `q` (`[R, D, H]`, zero on padding): softmax over heads of
    /// `u_mᵀ(x_j − x_i) + c_m`, from `x·U` of each row's source (`[R, H]`) and of every node.
    fn steering(&self, xu_rows: Tensor<2>, xu: Tensor<2>, graph: &GraphTensors) -> Tensor<3> {
        let (r, d) = (graph.row_count, graph.slots);
        let heads = self.dims().0;
        let at_target = xu
            .select(0, graph.slot_targets.clone())
            .reshape([r, d, heads]);
        let logits = xu_rows.unsqueeze_dim::<3>(1) - at_target
            + self.steer_offset.val().unsqueeze_dims::<3>(&[0, 1]);
        softmax(logits, 2) * graph.slot_mask.clone()
    }
}

#[cfg(test)]
#[path = "feast_tests.rs"]
mod tests;
