//! FeaStConv, the feature-steered graph convolution (Verma et al. 2018; thesis eqs. 2.21–2.22,
//! 4.11), in PyTorch Geometric's translation-invariant form with self-loops, `H` heads, mean
//! aggregation and bias:
//!
//! y_i = b + (1/|N(i)|) Σ_{j∈N(i)} Σ_m q_m(x_i, x_j) W_m x_j,
//! q_m = softmax over m of (u_mᵀ(x_j − x_i) + c_m).
//!
//! Because `u` is linear, `x·U` is computed once per node and gathered per edge. The weighted
//! sum over heads is formed on whichever side of `W` is narrower: with `d_in ≥ d_out`, `x·W`
//! per node is gathered per edge and mixed by `q` (`[E, H, d_out]`); with `d_in < d_out`, the
//! per-edge outer product `q ⊗ x_j` (`[E, H, d_in]`) is averaged per node first and then
//! multiplied by the stacked `W` once. Messages are scatter-summed to their targets with
//! `select_assign(.., Add)`, whose gradient is defined for repeated indices.

use burn::config::Config;
use burn::module::{Module, Param};
use burn::tensor::activation::softmax;
use burn::tensor::{Device, IndexingUpdateOp, Tensor};
use rand_chacha::ChaCha8Rng;

use super::graph::GraphTensors;
use super::init::{fan_in_bound, normal, uniform};

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
            weight: uniform([self.heads, self.d_in, self.d_out], bound, rng, device),
            steer: uniform([self.d_in, self.heads], bound, rng, device),
            steer_offset: normal([self.heads], OFFSET_INIT_STD, rng, device),
            bias: normal([self.d_out], OFFSET_INIT_STD, rng, device),
        }
    }
}

/// One FeaStConv layer.
#[derive(Module, Debug)]
pub struct FeaStConv {
    /// The head weight matrices `W_m`, `[H, d_in, d_out]` (acting as `x·W_m`).
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
        let [h, d_in, d_out] = self.weight.shape().dims();
        (h, d_in, d_out)
    }

    /// Applies the layer to node features `x` (`[N, d_in]`) of the graph `graph`;
    /// returns `[N, d_out]`.
    pub fn forward(&self, x: Tensor<2>, graph: &GraphTensors) -> Tensor<2> {
        let (heads, d_in, d_out) = self.dims();
        let e = graph.edge_count;
        let q = self.steering(x.clone(), graph);
        let summed = if d_in < d_out {
            let outer =
                q.reshape([e, heads, 1]) * x.select(0, graph.sources.clone()).reshape([e, 1, d_in]);
            let agg = scatter_sum(outer.reshape([e, heads * d_in]), graph);
            agg.matmul(self.weight.val().reshape([heads * d_in, d_out]))
        } else {
            let w = self
                .weight
                .val()
                .swap_dims(0, 1)
                .reshape([d_in, heads * d_out]);
            let xw = x
                .matmul(w)
                .select(0, graph.sources.clone())
                .reshape([e, heads, d_out]);
            let msg = (xw * q.reshape([e, heads, 1]))
                .sum_dim(1)
                .reshape([e, d_out]);
            scatter_sum(msg, graph)
        };
        summed * graph.inv_degree.clone() + self.bias.val().unsqueeze_dim(0)
    }

    /// Head weights per edge `q` (`[E, H]`): softmax over heads of `u_mᵀ(x_j − x_i) + c_m`.
    fn steering(&self, x: Tensor<2>, graph: &GraphTensors) -> Tensor<2> {
        let xu = x.matmul(self.steer.val());
        let logits = xu.clone().select(0, graph.sources.clone())
            - xu.select(0, graph.targets.clone())
            + self.steer_offset.val().unsqueeze_dim(0);
        softmax(logits, 1)
    }
}

/// Sums per-edge rows `[E, C]` into their target nodes, `[N, C]`.
fn scatter_sum(messages: Tensor<2>, graph: &GraphTensors) -> Tensor<2> {
    let [_, c] = messages.dims();
    let zeros = Tensor::zeros(
        [graph.node_count, c],
        (&messages.device(), messages.dtype()),
    );
    zeros.select_assign(0, graph.targets.clone(), messages, IndexingUpdateOp::Add)
}

#[cfg(test)]
#[path = "feast_tests.rs"]
mod tests;
