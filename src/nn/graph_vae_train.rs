//! Training Ψ on a set of graphs, embedding with the trained encoder, and storing the weights.

use burn::module::Module;
use burn::optim::GradientsParams;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device, Tensor, TensorData};

use super::device::{STREAM_INIT, STREAM_NOISE, inference_device, rng, training_device};
use super::error::{NnError, require};
use super::graph::{GraphBatch, GraphSample, PositionScaling};
use super::graph_vae::{GraphVae, GraphVaeConfig, LossWeights};
use super::init::standard_normal;
use super::train::{Monitor, adam, check_schedule, run_epochs};

/// How Ψ is trained (SPEC §2.4 defaults).
#[derive(Debug, Clone, PartialEq)]
pub struct GraphVaeTraining {
    /// Passes over the training set.
    pub epochs: usize,
    /// Graphs per mini-batch (one disjoint-graph forward pass).
    pub batch_size: usize,
    /// Adam learning rate.
    pub lr: f64,
    /// Weight of the KL term `w_kl`.
    pub w_kl: f64,
    /// Weight of the normal term `w_norm` (hybrid features only).
    pub w_norm: f64,
    /// Seed of the weights, the batch order and the sampling noise.
    pub seed: u64,
}

impl Default for GraphVaeTraining {
    fn default() -> Self {
        Self {
            epochs: 100,
            batch_size: 4,
            lr: 1e-3,
            w_kl: 1e-3,
            w_norm: 1e-2,
            seed: 0,
        }
    }
}

impl GraphVaeTraining {
    fn validate(&self) -> Result<(), NnError> {
        check_schedule(self.epochs, self.batch_size, self.lr)?;
        require(
            self.w_kl.is_finite() && self.w_kl >= 0.0,
            "w_kl",
            "must be a non-negative number",
        )?;
        require(
            self.w_norm.is_finite() && self.w_norm >= 0.0,
            "w_norm",
            "must be a non-negative number",
        )
    }
}

/// A trained Ψ, ready to embed graphs.
#[derive(Debug, Clone)]
pub struct TrainedGraphVae {
    /// The sizes it was built with.
    pub config: GraphVaeConfig,
    /// Mean loss per graph of each epoch.
    pub losses: Vec<f64>,
    model: GraphVae,
}

/// Checks the samples against the configuration.
fn check_samples(samples: &[GraphSample], config: &GraphVaeConfig) -> Result<(), NnError> {
    for (i, s) in samples.iter().enumerate() {
        s.validate(i)?;
        let width = s.features().width();
        if width != config.d_x {
            return Err(NnError::DimensionMismatch {
                what: "node features",
                expected: config.d_x,
                found: width,
            });
        }
    }
    Ok(())
}

/// Trains Ψ: Adam on mini-batches of disjoint graphs in a seeded order, the monitor after
/// every batch and epoch. The position scaling is fitted to all training vertices.
pub fn train_graph_vae(
    samples: &[GraphSample],
    config: &GraphVaeConfig,
    training: &GraphVaeTraining,
    monitor: &mut dyn Monitor,
) -> Result<TrainedGraphVae, NnError> {
    config.validate()?;
    training.validate()?;
    if samples.is_empty() {
        return Err(NnError::EmptyDataset);
    }
    check_samples(samples, config)?;
    let device = training_device();
    let scaling = PositionScaling::fit(samples);
    let model = config.init(scaling, &mut rng(training.seed, STREAM_INIT), &device);
    let weights = LossWeights {
        kl: training.w_kl,
        normals: training.w_norm,
    };
    let mut optimizer = adam();
    let mut noise_rng = rng(training.seed, STREAM_NOISE);
    let schedule = (training.epochs, training.batch_size, training.seed);
    let (model, losses) = run_epochs(
        model,
        samples.len(),
        schedule,
        monitor,
        |model, batch, _| {
            let members: Vec<&GraphSample> = batch.iter().map(|&i| &samples[i]).collect();
            let graph = GraphBatch::new(&members, &scaling);
            let tensors = graph.tensors(&device);
            let noise = standard_normal(graph.node_count() * config.d_z, &mut noise_rng);
            let noise = Tensor::from_data(
                TensorData::new(noise, [graph.node_count(), config.d_z]),
                &device,
            );
            let loss = model.loss(
                graph.feature_tensor(&device),
                &tensors,
                noise,
                members.len(),
                weights,
            );
            let value = f64::from(loss.clone().into_scalar::<f32>());
            let grads = GradientsParams::from_grads(loss.backward(), &model);
            let model = optimizer.step(training.lr, model, grads);
            (model, value * members.len() as f64)
        },
    )?;
    Ok(TrainedGraphVae {
        config: config.clone(),
        losses,
        model: model.valid(),
    })
}

impl TrainedGraphVae {
    /// Embeddings `Z` (encoder mean, eval mode) of one graph: `[n, d_z]` row-major.
    pub fn embed(&self, sample: &GraphSample) -> Result<Vec<f32>, NnError> {
        Ok(self.embed_many(std::slice::from_ref(sample))?.remove(0))
    }

    /// Embeddings of several graphs in one forward pass; one `[n_k, d_z]` row-major block each.
    pub fn embed_many(&self, samples: &[GraphSample]) -> Result<Vec<Vec<f32>>, NnError> {
        check_samples(samples, &self.config)?;
        let (mu, batch) = self.run(samples, |m, x, g| m.encode(x, g).0);
        Ok(split_rows(mu, &batch, self.config.d_z))
    }

    /// Reconstructed features (decoder of the encoder mean), `[n, d_x]` row-major, positions
    /// back in mm.
    pub fn reconstruct(&self, sample: &GraphSample) -> Result<Vec<f32>, NnError> {
        check_samples(std::slice::from_ref(sample), &self.config)?;
        let (x_hat, batch) = self.run(std::slice::from_ref(sample), |m, x, g| {
            m.decode(m.encode(x, g).0, g)
        });
        let scaling = self.model.scaling();
        let mut out = split_rows(x_hat, &batch, self.config.d_x).remove(0);
        for row in out.chunks_mut(self.config.d_x) {
            for (v, shift) in row.iter_mut().zip(scaling.shift) {
                *v = *v * scaling.scale + shift;
            }
        }
        Ok(out)
    }

    /// Runs `f` on the batch of `samples` on the inference device.
    fn run(
        &self,
        samples: &[GraphSample],
        f: impl Fn(&GraphVae, Tensor<2>, &super::slots::GraphTensors) -> Tensor<2>,
    ) -> (Tensor<2>, GraphBatch) {
        let device: Device = inference_device();
        let members: Vec<&GraphSample> = samples.iter().collect();
        let batch = GraphBatch::new(&members, &self.model.scaling());
        let out = f(
            &self.model,
            batch.feature_tensor(&device),
            &batch.tensors(&device),
        );
        (out, batch)
    }

    /// Ψ on the training device, ready to train further (the refinement).
    pub(crate) fn trainable(&self) -> Result<GraphVae, NnError> {
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(self.to_bytes()?))
            .map_err(|e| NnError::Weights(e.to_string()))?;
        let skeleton = self.config.init(
            PositionScaling::IDENTITY,
            &mut rng(0, STREAM_INIT),
            &training_device(),
        );
        skeleton
            .try_load_record(record)
            .map_err(|e| NnError::Weights(e.to_string()))
    }

    /// A trained Ψ from a network trained on the training device.
    pub(crate) fn from_training(
        config: &GraphVaeConfig,
        model: &GraphVae,
        losses: Vec<f64>,
    ) -> Self {
        Self {
            config: config.clone(),
            losses,
            model: model.valid(),
        }
    }

    /// The position scaling Ψ was trained with (mm to network units).
    pub fn scaling(&self) -> PositionScaling {
        self.model.scaling()
    }

    /// The weights as a burn record (burnpack bytes), for storing as a blob.
    pub fn to_bytes(&self) -> Result<Vec<u8>, NnError> {
        let bytes = self
            .model
            .clone()
            .into_record()
            .into_bytes()
            .map_err(|e| NnError::Weights(e.to_string()))?;
        Ok(bytes.to_vec())
    }

    /// Rebuilds a trained Ψ from `config` and bytes written by [`Self::to_bytes`].
    pub fn from_bytes(config: &GraphVaeConfig, bytes: &[u8]) -> Result<Self, NnError> {
        config.validate()?;
        let device = inference_device();
        let skeleton = config.init(PositionScaling::IDENTITY, &mut rng(0, STREAM_INIT), &device);
        let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes.to_vec()))
            .map_err(|e| NnError::Weights(e.to_string()))?;
        let model = skeleton
            .try_load_record(record)
            .map_err(|e| NnError::Weights(e.to_string()))?;
        Ok(Self {
            config: config.clone(),
            losses: Vec::new(),
            model: model.valid(),
        })
    }
}

/// Splits node rows `[N, width]` into one row-major block per graph.
fn split_rows(t: Tensor<2>, batch: &GraphBatch, width: usize) -> Vec<Vec<f32>> {
    let values: Vec<f32> = t.into_data().iter::<f32>().collect();
    batch
        .node_ranges
        .iter()
        .map(|r| values[r.start * width..r.end * width].to_vec())
        .collect()
}
