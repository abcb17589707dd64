//! Training the beta-VAE on flattened atlas-domain shapes, sampling and reconstruction with
//! it, and storing its weights.

use burn::module::Module;
use burn::optim::GradientsParams;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Tensor, TensorData};

use nalgebra::DMatrix;

use super::beta_vae::{BetaVae, BetaVaeConfig, ShapeScaling};
use super::device::{
    STREAM_INIT, STREAM_NOISE, STREAM_SAMPLE, inference_device, rng, training_device,
};
use super::error::{NnError, check_finite, require};
use super::init::standard_normal;
use super::latent_prior::LatentPrior;
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
    /// Weight of the KL term on standardised shapes (see [`ShapeScaling`]).
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
/// mini-batches, the monitor after every batch and epoch. Shapes are standardised
/// by the mean and spread of the training shapes ([`ShapeScaling`]).
pub fn train_beta_vae(
    shapes: &[Vec<f32>],
    config: &BetaVaeConfig,
    training: &BetaVaeTraining,
    monitor: &mut dyn Monitor,
) -> Result<TrainedBetaVae, NnError> {
    train_weighted_beta_vae(shapes, None, config, training, monitor)
}

/// Weights `≥ 0`, one per shape, rescaled to mean 1 (so that the step sizes are those of
/// unweighted training); an error when they are not finite, negative or all zero.
fn unit_mean_weights(weights: &[f32], count: usize) -> Result<Vec<f32>, NnError> {
    require(
        weights.len() == count,
        "weights",
        "need one weight per shape",
    )?;
    require(
        weights.iter().all(|w| w.is_finite() && *w >= 0.0),
        "weights",
        "must be finite and non-negative",
    )?;
    let mean = weights.iter().map(|w| f64::from(*w)).sum::<f64>() / count.max(1) as f64;
    require(mean > 0.0, "weights", "must not all be zero")?;
    Ok(weights
        .iter()
        .map(|w| (f64::from(*w) / mean) as f32)
        .collect())
}

/// [`train_beta_vae`] with a weight per shape (`None`: all equal): each shape's loss and
/// its share of the standardisation count by its weight (the generator of one soft
/// cluster, thesis eq. 5.17).
pub fn train_weighted_beta_vae(
    shapes: &[Vec<f32>],
    weights: Option<&[f32]>,
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
    let weights = weights
        .map(|w| unit_mean_weights(w, shapes.len()))
        .transpose()?;
    let device = training_device();
    let scaling = ShapeScaling::fit_weighted(shapes, weights.as_deref());
    let model = config.init(
        scaling.clone(),
        &mut rng(training.seed, STREAM_INIT),
        &device,
    );
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
            let batch_weights = weights.as_ref().map(|w| {
                let values: Vec<f32> = batch.iter().map(|&i| w[i]).collect();
                Tensor::from_data(TensorData::new(values, [batch.len(), 1]), &device)
            });
            let loss = model.loss(x, noise, training.beta, batch_weights);
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
    /// The encoder's latent means and log-variances of flattened shapes (mm), each
    /// `[shapes, L]`.
    fn encode(&self, shapes: &[Vec<f32>]) -> Result<(Tensor<2>, Tensor<2>), NnError> {
        check_shapes(shapes, self.config.d_in)?;
        let scaling = self.model.scaling();
        let x = rows(
            shapes,
            self.config.d_in,
            |s| scaling.normalise(s),
            &inference_device(),
        );
        Ok(self.model.encode(x))
    }

    /// Latent means `[L]` of flattened shapes (mm).
    pub fn encode_mean(&self, shapes: &[Vec<f32>]) -> Result<Vec<Vec<f32>>, NnError> {
        Ok(split(self.encode(shapes)?.0, self.config.latent))
    }

    /// The distribution of the training shapes' codes (see [`LatentPrior`]): per latent
    /// dimension, the mean of the encoder means and the spread of the mixture of the
    /// encoder's Gaussians.
    pub fn aggregate_prior(&self, shapes: &[Vec<f32>]) -> Result<LatentPrior, NnError> {
        self.weighted_aggregate_prior(shapes, None)
    }

    /// [`Self::aggregate_prior`] with a weight per shape (`None`: all equal): the Gaussian
    /// of one soft cluster's codes.
    pub fn weighted_aggregate_prior(
        &self,
        shapes: &[Vec<f32>],
        weights: Option<&[f32]>,
    ) -> Result<LatentPrior, NnError> {
        if shapes.is_empty() {
            return Err(NnError::EmptyDataset);
        }
        let w: Vec<f64> = match weights {
            Some(w) => unit_mean_weights(w, shapes.len())?
                .into_iter()
                .map(f64::from)
                .collect(),
            None => vec![1.0; shapes.len()],
        };
        let (mu, log_var) = self.encode(shapes)?;
        let latent = self.config.latent;
        let (mu, log_var) = (split(mu, latent), split(log_var, latent));
        let n: f64 = w.iter().sum();
        let centre: Vec<f64> = (0..latent)
            .map(|d| {
                mu.iter()
                    .zip(&w)
                    .map(|(r, w)| w * f64::from(r[d]))
                    .sum::<f64>()
                    / n
            })
            .collect();
        // Covariance of the encoder means plus the mean of the encoder's own variances: the
        // covariance of the mixture of the training shapes' posteriors.
        let covariance = DMatrix::<f64>::from_fn(latent, latent, |i, j| {
            let between: f64 = mu
                .iter()
                .zip(&w)
                .map(|(r, w)| w * (f64::from(r[i]) - centre[i]) * (f64::from(r[j]) - centre[j]))
                .sum::<f64>()
                / n;
            let within = if i == j {
                log_var
                    .iter()
                    .zip(&w)
                    .map(|(r, w)| w * f64::from(r[i]).exp())
                    .sum::<f64>()
                    / n
            } else {
                0.0
            };
            between + within
        });
        let centre = centre.into_iter().map(|c| c as f32).collect();
        Ok(LatentPrior::with_covariance(centre, &covariance))
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

    /// `count` standard-normal codes `[L]`; the same seed gives the same codes.
    pub fn sample_codes(&self, count: usize, seed: u64) -> Vec<Vec<f32>> {
        let mut r = rng(seed, STREAM_SAMPLE);
        (0..count)
            .map(|_| standard_normal(self.config.latent, &mut r))
            .collect()
    }

    /// `count` new shapes (mm) decoded from z ~ N(0, I); the same seed gives the same shapes.
    pub fn sample(&self, count: usize, seed: u64) -> Vec<Vec<f32>> {
        // Codes have the right width and are finite by construction.
        self.decode(&self.sample_codes(count, seed))
            .unwrap_or_default()
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
            ShapeScaling::identity(config.d_in),
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
