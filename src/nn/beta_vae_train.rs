//! Training the beta-VAE on flattened atlas-domain shapes, sampling and reconstruction with
//! it, and storing its weights.

use burn::module::Module;
use burn::optim::GradientsParams;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Tensor, TensorData};

use serde::{Deserialize, Serialize};

use super::beta_vae::{BetaVae, BetaVaeConfig, ShapeScaling};
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

/// A Gaussian over latent codes, `z = centre + spread ⊙ ε` with `ε ~ N(0, I)`, `[L]` each.
///
/// The standard normal is the VAE's own prior. Fitted to the codes of the training shapes
/// ([`TrainedBetaVae::aggregate_prior`]) it draws shapes as varied as the training set: with a
/// small β the codes spread far beyond N(0, I), and draws from it were all close to the mean
/// shape (volume sd 1–3 ml against 14 ml on 40 LV phantoms).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatentPrior {
    /// Mean code, `[L]`.
    pub centre: Vec<f32>,
    /// Standard deviation per latent dimension, `[L]`.
    pub spread: Vec<f32>,
}

impl LatentPrior {
    /// N(0, I) in `latent` dimensions.
    pub fn standard(latent: usize) -> Self {
        Self {
            centre: vec![0.0; latent],
            spread: vec![1.0; latent],
        }
    }

    /// The code of a standard-normal draw `ε` (`[L]`).
    pub fn code(&self, standard: &[f32]) -> Vec<f32> {
        standard
            .iter()
            .zip(self.centre.iter().zip(&self.spread))
            .map(|(e, (c, s))| c + s * e)
            .collect()
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
    config.validate()?;
    training.validate()?;
    if shapes.is_empty() {
        return Err(NnError::EmptyDataset);
    }
    check_shapes(shapes, config.d_in)?;
    let device = training_device();
    let scaling = ShapeScaling::fit(shapes);
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
        if shapes.is_empty() {
            return Err(NnError::EmptyDataset);
        }
        let (mu, log_var) = self.encode(shapes)?;
        let latent = self.config.latent;
        let (mu, log_var) = (split(mu, latent), split(log_var, latent));
        let n = shapes.len() as f64;
        let column = |rows: &[Vec<f32>], d: usize, f: &dyn Fn(f64) -> f64| -> f64 {
            rows.iter().map(|r| f(f64::from(r[d]))).sum::<f64>() / n
        };
        let mut prior = LatentPrior::standard(latent);
        for d in 0..latent {
            let centre = column(&mu, d, &|v| v);
            let spread_of_means = column(&mu, d, &|v| (v - centre).powi(2));
            let mean_variance = column(&log_var, d, &f64::exp);
            prior.centre[d] = centre as f32;
            prior.spread[d] = (spread_of_means + mean_variance).sqrt() as f32;
        }
        Ok(prior)
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
