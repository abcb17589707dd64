//! Training Ψ further with a loss on the correspondences it induces (the refinement of
//! Atlas-R-ASMG, thesis §5.2, eqs. 5.6–5.10).
//!
//! Every mini-batch stacks its shapes and the atlas into one disjoint graph, runs Ψ (train
//! mode) and keeps its usual loss `L_Ψ`. From the encoder means it forms, per shape, the
//! unit-length embeddings, the scores `S_k = Z_μ Z_kᵀ` (`[N_μ, N_k]`), the attention
//! `Φ_k = softmax_i(λ_k S_k)` and the normalised shape `h_k = Φ_k X_k` (`[N_μ, 3]`, mm),
//! all differentiable, so the refinement's gradient reaches Ψ through the attention.
//!
//! The refinement loss itself (smoothing, Chamfer and Laplacian terms) is computed outside
//! the graph by a [`RefineObjective`], which returns its value and its gradient with respect
//! to `h_k`; the batch adds `Σ_k ⟨h_k, ∂L/∂h_k⟩` (the gradient held constant), whose
//! gradient is exactly the refinement's. Memory stays linear in the vertex counts: no
//! nearest-neighbour search or sparse solve enters the graph. λ_k is held constant within a
//! step (computed from the detached scores).
//!
//! With several atlases (mAtlas-R-ASMG), every atlas rides along in every batch, each shape
//! is normalised to each atlas and its terms on atlas `m` count by its soft weight `w_km`;
//! pairs of weight below [`MIN_PAIR_WEIGHT`] are skipped.

use burn::optim::GradientsParams;
use burn::tensor::{Device, Tensor, TensorData};
use rand_chacha::ChaCha8Rng;

use super::device::{STREAM_NOISE, STREAM_SHUFFLE, rng, training_device};
use super::error::NnError;
use super::graph::{GraphBatch, GraphSample, PositionScaling};
use super::graph_vae::{GraphVae, LossWeights};
use super::graph_vae_train::TrainedGraphVae;
use super::init::standard_normal;
use super::train::{Monitor, adam, check_schedule, epoch_batches, go_on};

/// Mixed into the seed so the refinement's batch order and noise differ from Ψ's training.
const REFINE_SEED_SALT: u64 = 0x5eed_4ef1;
/// Shape–atlas pairs of smaller soft weight add nothing to a refinement step.
pub const MIN_PAIR_WEIGHT: f64 = 1e-3;
/// Squared norms below this count as zero when embeddings are made unit length.
const NORM_FLOOR: f64 = 1e-12;

/// How the refinement trains (shared settings of Ψ).
#[derive(Debug, Clone, PartialEq)]
pub struct RefineTraining {
    /// Shapes per mini-batch (the atlas rides along in every batch).
    pub batch_size: usize,
    /// Adam learning rate.
    pub lr: f64,
    /// KL weight of `L_Ψ`.
    pub w_kl: f64,
    /// Normal-term weight of `L_Ψ` (hybrid features).
    pub w_norm: f64,
    /// Seed of the batch order and the reparameterisation noise.
    pub seed: u64,
}

/// The refinement terms of one shape, weighted, in the objective's units.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RefineTerms {
    /// The Chamfer term `w_cd·CD(g_k, h'_k)`.
    pub chamfer: f64,
    /// The Laplacian term `w_lap·Σ_j‖h'_kj − mean_{q∈N(j)} h'_kq‖²`.
    pub laplacian: f64,
}

/// The refinement loss outside the graph.
pub trait RefineObjective {
    /// The inverse temperature λ for scores of this (population) variance.
    fn lambda(&self, score_variance: f64) -> f64;
    /// The terms of shape `k` for its normalised shape `h` on atlas `m` (`[N_μm, 3]`, mm)
    /// and their gradient with respect to `h` (`[N_μm, 3]`).
    fn shape(
        &mut self,
        k: usize,
        m: usize,
        h: &[[f64; 3]],
    ) -> Result<(RefineTerms, Vec<[f64; 3]>), NnError>;
}

/// Mean losses per shape of one refinement epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RefineEpoch {
    /// `L_Ψ` per graph.
    pub graph: f64,
    /// The Chamfer term per shape.
    pub chamfer: f64,
    /// The Laplacian term per shape.
    pub laplacian: f64,
}

impl RefineEpoch {
    /// The whole loss per shape.
    pub fn total(&self) -> f64 {
        self.graph + self.chamfer + self.laplacian
    }
}

/// Ψ under refinement: the network on the training device, its optimiser state and the
/// seeded streams, kept across epochs (the caller moves the atlas between them).
pub struct GraphRefiner {
    /// `None` only while an optimiser step holds it.
    model: Option<GraphVae>,
    optimizer: burn::optim::ModuleOptimizer,
    trained: TrainedGraphVae,
    training: RefineTraining,
    scaling: PositionScaling,
    shuffle: ChaCha8Rng,
    noise: ChaCha8Rng,
    device: Device,
    losses: Vec<f64>,
}

impl GraphRefiner {
    /// Starts from a trained Ψ.
    pub fn new(trained: &TrainedGraphVae, training: RefineTraining) -> Result<Self, NnError> {
        check_schedule(1, training.batch_size, training.lr)?;
        Ok(Self {
            model: Some(trained.trainable()?),
            optimizer: adam(),
            scaling: trained.scaling(),
            trained: trained.clone(),
            shuffle: rng(training.seed ^ REFINE_SEED_SALT, STREAM_SHUFFLE),
            noise: rng(training.seed ^ REFINE_SEED_SALT, STREAM_NOISE),
            training,
            device: training_device(),
            losses: Vec::new(),
        })
    }

    /// One pass over `samples` with `atlases` as the atlas graphs; `weights[k][m]` is shape
    /// `k`'s soft weight on atlas `m` (one atlas: all 1). `None` when the monitor asked to
    /// finish early.
    pub fn epoch(
        &mut self,
        samples: &[GraphSample],
        atlases: &[GraphSample],
        weights: &[Vec<f64>],
        objective: &mut dyn RefineObjective,
        monitor: &mut dyn Monitor,
    ) -> Result<Option<RefineEpoch>, NnError> {
        if samples.is_empty() || atlases.is_empty() {
            return Err(NnError::EmptyDataset);
        }
        if weights.len() != samples.len() || weights.iter().any(|w| w.len() != atlases.len()) {
            return Err(NnError::Objective(format!(
                "{} weight rows for {} shapes and {} atlases",
                weights.len(),
                samples.len(),
                atlases.len()
            )));
        }
        let mut sums = RefineEpoch::default();
        for batch in epoch_batches(samples.len(), self.training.batch_size, &mut self.shuffle) {
            let step = self.step(samples, atlases, weights, &batch, objective)?;
            sums.graph += step.graph * batch.len() as f64;
            sums.chamfer += step.chamfer;
            sums.laplacian += step.laplacian;
            if !sums.total().is_finite() {
                return Err(NnError::Diverged {
                    epoch: self.losses.len(),
                });
            }
            if !go_on(monitor.batch())? {
                return Ok(None);
            }
        }
        let n = samples.len() as f64;
        let mean = RefineEpoch {
            graph: sums.graph / n,
            chamfer: sums.chamfer / n,
            laplacian: sums.laplacian / n,
        };
        self.losses.push(mean.total());
        Ok(Some(mean))
    }

    /// One optimiser step on `batch`: returns `L_Ψ` per graph and the summed terms.
    fn step(
        &mut self,
        samples: &[GraphSample],
        atlases: &[GraphSample],
        weights: &[Vec<f64>],
        batch: &[usize],
        objective: &mut dyn RefineObjective,
    ) -> Result<RefineEpoch, NnError> {
        let mut members: Vec<&GraphSample> = batch.iter().map(|&i| &samples[i]).collect();
        members.extend(atlases);
        let graph = GraphBatch::new(&members, &self.scaling);
        let d_z = self.trained.config.d_z;
        let noise = standard_normal(graph.node_count() * d_z, &mut self.noise);
        let noise = Tensor::from_data(
            TensorData::new(noise, [graph.node_count(), d_z]),
            &self.device,
        );
        let loss_weights = LossWeights {
            kl: self.training.w_kl,
            normals: self.training.w_norm,
        };
        let model = self
            .model
            .take()
            .ok_or_else(|| NnError::Objective("a failed step left no network".to_owned()))?;
        let (loss_psi, mu) = model.loss_and_mean(
            graph.feature_tensor(&self.device),
            &graph.tensors(&self.device),
            noise,
            members.len(),
            loss_weights,
        );
        let ranges = &graph.node_ranges;
        let rows_of = |i: usize| unit_rows(mu.clone().narrow(0, ranges[i].start, ranges[i].len()));
        let z_atlases: Vec<Tensor<2>> = (batch.len()..members.len()).map(rows_of).collect();
        let mut terms = RefineEpoch {
            graph: f64::from(loss_psi.clone().into_scalar::<f32>()),
            ..RefineEpoch::default()
        };
        let mut surrogate: Option<Tensor<1>> = None;
        for (b, &k) in batch.iter().enumerate() {
            let z_k = rows_of(b);
            for (m, z_atlas) in z_atlases.iter().enumerate() {
                let w = weights[k][m];
                if w < MIN_PAIR_WEIGHT {
                    continue;
                }
                let h = normalised_shape(
                    z_atlas.clone(),
                    z_k.clone(),
                    &samples[k],
                    objective,
                    &self.device,
                );
                let (t, gradient) = objective.shape(k, m, &to_rows(h.clone()))?;
                terms.chamfer += w * t.chamfer;
                terms.laplacian += w * t.laplacian;
                let g: Vec<f32> = gradient
                    .iter()
                    .flat_map(|p| p.map(|c| (w * c) as f32))
                    .collect();
                let g = Tensor::from_data(TensorData::new(g, [gradient.len(), 3]), &self.device);
                let inner = (h * g).sum();
                surrogate = Some(match surrogate {
                    Some(acc) => acc + inner,
                    None => inner,
                });
            }
        }
        let mut loss = loss_psi;
        if let Some(s) = surrogate {
            loss = loss + s.div_scalar(batch.len().max(1) as f64);
        }
        let grads = GradientsParams::from_grads(loss.backward(), &model);
        self.model = Some(self.optimizer.step(self.training.lr, model, grads));
        Ok(terms)
    }

    /// Ψ as refined so far, with the loss per shape of every epoch appended to its losses.
    pub fn trained(&self) -> TrainedGraphVae {
        let mut losses = self.trained.losses.clone();
        losses.extend(&self.losses);
        match &self.model {
            Some(model) => TrainedGraphVae::from_training(&self.trained.config, model, losses),
            None => self.trained.clone(),
        }
    }
}

/// Rows scaled to unit length, `[n, d]`.
fn unit_rows(z: Tensor<2>) -> Tensor<2> {
    let norms = z
        .clone()
        .powi_scalar(2)
        .sum_dim(1)
        .clamp_min(NORM_FLOOR)
        .sqrt();
    z / norms
}

/// `h_k = softmax_i(λ_k · Z_μ Z_kᵀ) X_k`, `[N_μ, 3]` mm, with λ_k from the detached scores.
fn normalised_shape(
    z_atlas: Tensor<2>,
    z_k: Tensor<2>,
    sample: &GraphSample,
    objective: &dyn RefineObjective,
    device: &Device,
) -> Tensor<2> {
    let scores = z_atlas.matmul(z_k.transpose());
    let detached = scores.clone().detach();
    let mean = f64::from(detached.clone().mean().into_scalar::<f32>());
    let mean_sq = f64::from(detached.powi_scalar(2).mean().into_scalar::<f32>());
    let lambda = objective.lambda((mean_sq - mean * mean).max(0.0));
    let logits = scores.mul_scalar(lambda);
    let shifted = logits.clone() - logits.max_dim(1).detach();
    let weights = shifted.exp();
    let phi = weights.clone() / weights.sum_dim(1);
    let positions: Vec<f32> = sample.positions.iter().flatten().copied().collect();
    let x = Tensor::from_data(
        TensorData::new(positions, [sample.vertex_count(), 3]),
        device,
    );
    phi.matmul(x)
}

/// A `[n, 3]` tensor as rows of `f64`.
fn to_rows(t: Tensor<2>) -> Vec<[f64; 3]> {
    let values: Vec<f32> = t.into_data().iter::<f32>().collect();
    values
        .chunks_exact(3)
        .map(|p| [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])
        .collect()
}
