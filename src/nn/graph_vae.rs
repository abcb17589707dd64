//! The graph variational autoencoder Ψ of thesis table 4.3 (SPEC §2.4): FeaStConv encoder
//! `d_x → 64 → 64 → 128` with batch norm and LeakyReLU, two FeaStConv heads `128 → d_z` for
//! the mean and log σ, and a mirrored decoder `d_z → 128 → 64 → 64 → d_x`.
//!
//! Node features are positions (mm, mapped to network units by the stored
//! [`PositionScaling`]) and, for hybrid features, unit normals. Batch norm normalises over
//! all nodes of a batch of disjoint graphs.

use burn::config::Config;
use burn::module::{Module, RunningState};
use burn::nn::BatchNorm;
use burn::tensor::activation::leaky_relu;
use burn::tensor::{Device, Tensor};
use rand_chacha::ChaCha8Rng;

use super::error::{NnError, require};
use super::feast::{FeaStConfig, FeaStConv};
use super::graph::PositionScaling;
use super::init::{RunningIds, number_params};
use super::slots::GraphTensors;

/// log σ is clamped to ±this before exponentiating, so σ stays finite.
const LOG_SIGMA_LIMIT: f64 = 10.0;

/// Sizes of Ψ.
#[derive(Config, Debug, PartialEq)]
pub struct GraphVaeConfig {
    /// Node feature width: 3 (positions, sGCN) or 6 (positions and normals, hGCN).
    #[config(default = 3)]
    pub d_x: usize,
    /// Widths of the hidden encoder layers; the decoder uses them in reverse.
    #[config(default = "vec![64, 64, 128]")]
    pub hidden: Vec<usize>,
    /// Embedding width `d_z`.
    #[config(default = 128)]
    pub d_z: usize,
    /// FeaStConv heads per layer.
    #[config(default = 8)]
    pub heads: usize,
    /// Negative slope of the LeakyReLU activations (PyTorch's default).
    #[config(default = 0.01)]
    pub leaky_slope: f64,
}

impl Default for GraphVaeConfig {
    fn default() -> Self {
        Self::new()
    }
}

impl GraphVaeConfig {
    /// Checks that every size is usable.
    pub fn validate(&self) -> Result<(), NnError> {
        require(
            self.d_x == 3 || self.d_x == 6,
            "d_x",
            "must be 3 (positions) or 6 (positions and normals)",
        )?;
        require(
            !self.hidden.is_empty(),
            "hidden",
            "needs at least one layer",
        )?;
        require(
            self.hidden.iter().all(|&w| w > 0),
            "hidden",
            "widths must be positive",
        )?;
        require(self.d_z > 0, "d_z", "must be positive")?;
        require(self.heads > 0, "heads", "must be positive")?;
        require(
            self.leaky_slope.is_finite() && self.leaky_slope >= 0.0,
            "leaky_slope",
            "must be a non-negative number",
        )
    }

    /// Ψ with weights drawn from `rng`, on `device`.
    pub fn init(
        &self,
        scaling: PositionScaling,
        rng: &mut ChaCha8Rng,
        device: &Device,
    ) -> GraphVae {
        let mut running = RunningIds::default();
        let mut blocks = |widths: &[usize], rng: &mut ChaCha8Rng| -> Vec<ConvBlock> {
            widths
                .windows(2)
                .map(|w| ConvBlock {
                    conv: FeaStConfig::new(w[0], w[1])
                        .with_heads(self.heads)
                        .init(rng, device),
                    norm: running.batch_norm(w[1], device),
                })
                .collect()
        };
        let last = *self.hidden.last().unwrap_or(&self.d_x);
        let enc_widths: Vec<usize> = std::iter::once(self.d_x)
            .chain(self.hidden.iter().copied())
            .collect();
        let dec_widths: Vec<usize> = std::iter::once(self.d_z)
            .chain(self.hidden.iter().rev().copied())
            .collect();
        let encoder = blocks(&enc_widths, rng);
        let decoder = blocks(&dec_widths, rng);
        let head = |rng: &mut ChaCha8Rng, d_in, d_out| {
            FeaStConfig::new(d_in, d_out)
                .with_heads(self.heads)
                .init(rng, device)
        };
        let first_hidden = self.hidden.first().copied().unwrap_or(self.d_z);
        let mean = head(rng, last, self.d_z);
        let log_sigma = head(rng, last, self.d_z);
        let output = head(rng, first_hidden, self.d_x);
        number_params(GraphVae {
            encoder,
            mean,
            log_sigma,
            decoder,
            output,
            position_shift: running.state(scaling.shift.to_vec(), device),
            position_scale: running.state(vec![scaling.scale], device),
            leaky_slope: self.leaky_slope,
        })
    }
}

/// FeaStConv, then batch norm over all nodes, then LeakyReLU.
#[derive(Module, Debug)]
pub struct ConvBlock {
    /// The graph convolution.
    pub conv: FeaStConv,
    /// Batch norm over the nodes of the batch.
    pub norm: BatchNorm,
}

impl ConvBlock {
    fn forward(&self, x: Tensor<2>, graph: &GraphTensors, slope: f64) -> Tensor<2> {
        leaky_relu(self.norm.forward(self.conv.forward(x, graph)), slope)
    }
}

/// Ψ: encoder, mean and log σ heads, decoder, and the position scaling it was trained with.
#[derive(Module, Debug)]
pub struct GraphVae {
    /// Hidden encoder blocks.
    pub encoder: Vec<ConvBlock>,
    /// Head for the embedding mean, `[N, d_z]`.
    pub mean: FeaStConv,
    /// Head for the embedding log σ, `[N, d_z]`.
    pub log_sigma: FeaStConv,
    /// Hidden decoder blocks.
    pub decoder: Vec<ConvBlock>,
    /// Last decoder layer back to `d_x`.
    pub output: FeaStConv,
    /// Position scaling shift (mm), `[3]`.
    pub position_shift: RunningState<Tensor<1>>,
    /// Position scaling divisor (mm), `[1]`.
    pub position_scale: RunningState<Tensor<1>>,
    /// LeakyReLU negative slope.
    pub leaky_slope: f64,
}

/// Weights of the terms of Ψ's loss.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossWeights {
    /// Weight of the KL divergence `w_kl`.
    pub kl: f64,
    /// Weight of the normal term `w_norm` (used only with hybrid features).
    pub normals: f64,
}

impl GraphVae {
    /// The encoder's mean and log σ, each `[N, d_z]`.
    pub fn encode(&self, x: Tensor<2>, graph: &GraphTensors) -> (Tensor<2>, Tensor<2>) {
        let h = self
            .encoder
            .iter()
            .fold(x, |h, b| b.forward(h, graph, self.leaky_slope));
        (
            self.mean.forward(h.clone(), graph),
            self.log_sigma.forward(h, graph),
        )
    }

    /// The decoder: embeddings `[N, d_z]` to features `[N, d_x]`.
    pub fn decode(&self, z: Tensor<2>, graph: &GraphTensors) -> Tensor<2> {
        let h = self
            .decoder
            .iter()
            .fold(z, |h, b| b.forward(h, graph, self.leaky_slope));
        self.output.forward(h, graph)
    }

    /// The scaling from mm to network units stored with the weights.
    pub fn scaling(&self) -> PositionScaling {
        let shift: Vec<f32> = self
            .position_shift
            .value()
            .into_data()
            .iter::<f32>()
            .collect();
        let scale: Vec<f32> = self
            .position_scale
            .value()
            .into_data()
            .iter::<f32>()
            .collect();
        PositionScaling {
            shift: [0, 1, 2].map(|d| shift.get(d).copied().unwrap_or(0.0)),
            scale: scale.first().copied().unwrap_or(1.0),
        }
    }

    /// Loss of a batch of `graphs` graphs, averaged over the graphs: per graph
    /// ½Σ‖x̂ − x‖² + w_kl·KL(q(Z|X) ‖ N(0, I)) [+ w_norm·Σ(1 − ‖n̂‖²) with hybrid features].
    /// `noise` (`[N, d_z]`, standard normal) draws `z = μ + σ·noise`.
    pub fn loss(
        &self,
        x: Tensor<2>,
        graph: &GraphTensors,
        noise: Tensor<2>,
        graphs: usize,
        weights: LossWeights,
    ) -> Tensor<1> {
        self.loss_and_mean(x, graph, noise, graphs, weights).0
    }

    /// [`GraphVae::loss`] and the encoder mean `[N, d_z]` it was computed from (for losses
    /// on the embeddings, such as the refinement of Atlas-R-ASMG).
    pub fn loss_and_mean(
        &self,
        x: Tensor<2>,
        graph: &GraphTensors,
        noise: Tensor<2>,
        graphs: usize,
        weights: LossWeights,
    ) -> (Tensor<1>, Tensor<2>) {
        let (mu, log_sigma) = self.encode(x.clone(), graph);
        let log_sigma = log_sigma.clamp(-LOG_SIGMA_LIMIT, LOG_SIGMA_LIMIT);
        let sigma = log_sigma.clone().exp();
        let z = mu.clone() + sigma.clone() * noise;
        let x_hat = self.decode(z, graph);
        let [_, d_x] = x_hat.dims();
        let entries = mu.dims().iter().product::<usize>();
        let reconstruction = (x_hat.clone() - x).powi_scalar(2).sum().mul_scalar(0.5);
        // KL(N(μ, σ²) ‖ N(0, 1)) = −log σ + (μ² + σ²)/2 − 1/2 per dimension.
        let kl = (mu.clone().powi_scalar(2) + sigma.powi_scalar(2)).mul_scalar(0.5) - log_sigma;
        let kl = kl.sum().sub_scalar(0.5 * entries as f64);
        let mut total = reconstruction + kl.mul_scalar(weights.kl);
        if d_x == 6 {
            let normals = x_hat.narrow(1, 3, 3);
            let length2 = normals.powi_scalar(2).sum_dim(1);
            let term = length2.neg().add_scalar(1.0).sum();
            total = total + term.mul_scalar(weights.normals);
        }
        (total.div_scalar(graphs.max(1) as f64), mu)
    }
}

#[cfg(test)]
#[path = "graph_vae_tests.rs"]
mod tests;
