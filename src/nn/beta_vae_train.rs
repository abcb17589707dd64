//! Training the beta-VAE on flattened atlas-domain shapes, sampling and reconstruction with
//! it, and storing its weights.

use burn::module::Module;
use burn::optim::GradientsParams;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Tensor, TensorData};

use super::beta_vae::{BetaVae, BetaVaeConfig, CoordinateScaling};
use super::device::{
    STREAM_INIT, STREAM_NOISE, STREAM_SAMPLE, inference_device, rng, training_device,
};
use super::error::{NnError, check_finite, require};
use super::init::standard_normal;
use super::train::{Monitor, adam, check_schedule, run_epochs, step_decay};

/// How the beta-VAE is trained (SPEC §2.6; β per §2.9).
#[derive(Debug, Clone, PartialEq)]
pub struct BetaVaeTraining {
    /// Passes over the training set.
    pub epochs: usize,
    /// Shapes per mini-batch.
    pub batch_size: usize,
    /// Initial Adam learning rate.
    pub lr: f64,
    /// The learning rate is multiplied by `lr_gamma` every `lr_step` epochs (0: never).
    pub lr_step: usize,
    /// Step-decay factor.
    pub lr_gamma: f64,
    /// Weight of the KL term on [0, 1]-normalised coordinates.
    pub beta: f64,
    /// Seed of the weights, the batch order and the sampling noise.
    pub seed: u64,
}

impl Default for BetaVaeTraining {
    fn default() -> Self {
        Self {
            epochs: 300,
            batch_size: 4,
            lr: 1e-3,
            lr_step: 100,
            lr_gamma: 0.5,
            beta: 1e-2,
            seed: 0,
        }
    }
}

impl BetaVaeTraining {
    fn validate(&self) -> Result<(), NnError> {
        check_schedule(self.epochs, self.batch_size, self.lr)?;
        require(
            self.beta.is_finite() && self.beta >= 0.0,
            "beta",
            "must be a non-negative number",
        )?;
        require(
            self.lr_gamma.is_finite() && self.lr_gamma > 0.0,
            "lr_gamma",
            "must be a positive number",
        )
    }
}

/// A trained beta-VAE generator.
#[derive(Debug, Clone)]
pub struct TrainedBetaVae {
    /// The sizes it was built with.
    pub config: BetaVaeConfig,
    /// Mean loss per shape of each epoch (normalised units).
    pub losses: Vec<f64>,
    model: BetaVae,
}

/// Checks flattened shapes against the input width.
fn check_shapes(shapes: &[Vec<f32>], width: usize) -> Result<(), NnError> {
    for s in shapes {
        if s.len() != width {
            return Err(NnError::DimensionMismatch {
                what: "shape",
                expected: width,
                found: s.len(),
            });
        }
        check_finite(s, "shape")?;
    }
    Ok(())
}

/// Rows `[B, width]` from equally long vectors, each first passed through `map`.
fn rows(
    vectors: &[Vec<f32>],
    width: usize,
    map: impl Fn(&mut [f32]),
    device: &burn::tensor::Device,
) -> Tensor<2> {
    let mut flat = Vec::with_capacity(vectors.len() * width);
    for v in vectors {
        let start = flat.len();
        flat.extend_from_slice(v);
        map(&mut flat[start..]);
    }
    Tensor::from_data(TensorData::new(flat, [vectors.len(), width]), device)
}

/// Trains the beta-VAE on flattened shapes `[3·N_μ]` (mm): Adam with step decay, seeded
/// mini-batches, the monitor after every batch and epoch. Coordinates are mapped to [0, 1]
/// with the bounding box of the training shapes.
pub fn train_beta_vae(
    shapes: &[Vec<f32>],
    config: &BetaVaeConfig,
    training: &BetaVaeTraining,
    monitor: &mut dyn Monitor,
) -> Result<TrainedBetaVae, NnError> {
    config.validate()?;
    training.validate()?;
    if shapes.is_empty() {
        return Err(NnError::EmptyDataset);
    }
    check_shapes(shapes, config.d_in)?;
    let device = training_device();
    let scaling = CoordinateScaling::fit(shapes);
    let model = config.init(scaling, &mut rng(training.seed, STREAM_INIT), &device);
    let mut optimizer = adam();
    let mut noise_rng = rng(training.seed, STREAM_NOISE);
    let schedule = (training.epochs, training.batch_size, training.seed);
    let (model, losses) = run_epochs(
        model,
        shapes.len(),
        schedule,
        monitor,
        |model, batch, epoch| {
            let members: Vec<Vec<f32>> = batch.iter().map(|&i| shapes[i].clone()).collect();
            let x = rows(&members, config.d_in, |s| scaling.normalise(s), &device);
            let noise = standard_normal(batch.len() * config.latent, &mut noise_rng);
            let noise = Tensor::from_data(
                TensorData::new(noise, [batch.len(), config.latent]),
                &device,
            );
            let loss = model.loss(x, noise, training.beta);
            let value = f64::from(loss.clone().into_scalar::<f32>());
            let grads = GradientsParams::from_grads(loss.backward(), &model);
            let lr = step_decay(training.lr, epoch, training.lr_step, training.lr_gamma);
            (optimizer.step(lr, model, grads), value * batch.len() as f64)
        },
    )?;
    Ok(TrainedBetaVae {
        config: config.clone(),
        losses,
        model: model.valid(),
    })
}

impl TrainedBetaVae {
    /// Latent means `[L]` of flattened shapes (mm).
    pub fn encode_mean(&self, shapes: &[Vec<f32>]) -> Result<Vec<Vec<f32>>, NnError> {
        check_shapes(shapes, self.config.d_in)?;
        let scaling = self.model.scaling();
        let x = rows(
            shapes,
            self.config.d_in,
            |s| scaling.normalise(s),
            &inference_device(),
        );
        Ok(split(self.model.encode(x).0, self.config.latent))
    }

    /// Flattened shapes (mm) decoded from latent codes `[L]`.
    pub fn decode(&self, latents: &[Vec<f32>]) -> Result<Vec<Vec<f32>>, NnError> {
        check_shapes(latents, self.config.latent)?;
        let z = rows(latents, self.config.latent, |_| (), &inference_device());
        let scaling = self.model.scaling();
        let mut out = split(self.model.decode(z), self.config.d_in);
        out.iter_mut().for_each(|s| scaling.denormalise(s));
        Ok(out)
    }

    /// Encoder mean then decoder: the model's reconstruction of shapes (mm).
    pub fn reconstruct(&self, shapes: &[Vec<f32>]) -> Result<Vec<Vec<f32>>, NnError> {
        self.decode(&self.encode_mean(shapes)?)
    }

    /// `count` new shapes (mm) decoded from z ~ N(0, I); the same seed gives the same shapes.
    pub fn sample(&self, count: usize, seed: u64) -> Vec<Vec<f32>> {
        let mut r = rng(seed, STREAM_SAMPLE);
        let latent = self.config.latent;
        let z: Vec<Vec<f32>> = (0..count)
            .map(|_| standard_normal(latent, &mut r))
            .collect();
        // Latents have the right width and are finite by construction.
        self.decode(&z).unwrap_or_default()
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

    /// Rebuilds a trained beta-VAE from `config` and bytes written by [`Self::to_bytes`].
    pub fn from_bytes(config: &BetaVaeConfig, bytes: &[u8]) -> Result<Self, NnError> {
        config.validate()?;
        let skeleton = config.init(
            CoordinateScaling::IDENTITY,
            &mut rng(0, STREAM_INIT),
            &inference_device(),
        );
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

/// Rows of a `[B, width]` tensor as vectors.
fn split(t: Tensor<2>, width: usize) -> Vec<Vec<f32>> {
    let values: Vec<f32> = t.into_data().iter::<f32>().collect();
    values.chunks(width.max(1)).map(<[f32]>::to_vec).collect()
}

#[cfg(test)]
#[path = "beta_vae_tests.rs"]
mod tests;
