//! Training the beta-VAE on flattened atlas-domain shapes, sampling and reconstruction with
//! it, and storing its weights.

use burn::module::Module;
use burn::optim::GradientsParams;
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Tensor, TensorData};

use nalgebra::DMatrix;
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

/// A Gaussian over latent codes, `z = centre + mixing · ε` with `ε ~ N(0, I)`, `[L]`.
///
/// The standard normal is the VAE's own prior. Fitted to the codes of the training shapes
/// ([`TrainedBetaVae::aggregate_prior`]) it draws shapes as varied as the training set: with a
/// small β the codes spread far beyond N(0, I), and draws from it were all close to the mean
/// shape (volume sd 1–3 ml against 14 ml on 40 LV phantoms). The codes of the training
/// shapes are correlated, so the Gaussian keeps their full covariance: drawing every
/// dimension independently loses the covariances, and with them much of the spread along
/// directions such as size that several dimensions share.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LatentPrior {
    /// Mean code, `[L]`.
    pub centre: Vec<f32>,
    /// Standard deviation per latent dimension, `[L]` (the square roots of the diagonal of
    /// the covariance).
    pub spread: Vec<f32>,
    /// Lower-triangular Cholesky factor of the covariance, `[L, L]` row-major; empty: the
    /// dimensions are independent with standard deviations `spread`.
    pub mixing: Vec<f32>,
}

impl LatentPrior {
    /// N(0, I) in `latent` dimensions.
    pub fn standard(latent: usize) -> Self {
        Self {
            centre: vec![0.0; latent],
            spread: vec![1.0; latent],
            mixing: Vec::new(),
        }
    }

    /// The Gaussian with mean `centre` and covariance `covariance` (`[L, L]`, symmetric
    /// positive semi-definite; a tiny ridge is added when it is singular).
    pub fn with_covariance(centre: Vec<f32>, covariance: &DMatrix<f64>) -> Self {
        let latent = centre.len();
        let spread = (0..latent)
            .map(|d| covariance[(d, d)].max(0.0).sqrt() as f32)
            .collect();
        let ridge = 1e-9 * covariance.trace().abs().max(1e-12) / latent.max(1) as f64;
        let factor = [0.0, ridge, 1e3 * ridge].into_iter().find_map(|r| {
            let regularised = covariance + DMatrix::<f64>::identity(latent, latent) * r;
            regularised.cholesky().map(|c| c.l())
        });
        let mixing = factor.map_or_else(Vec::new, |l| {
            (0..latent)
                .flat_map(|i| (0..latent).map(move |j| (i, j)))
                .map(|(i, j)| l[(i, j)] as f32)
                .collect()
        });
        Self {
            centre,
            spread,
            mixing,
        }
    }

    /// The code of a standard-normal draw `ε` (`[L]`).
    pub fn code(&self, standard: &[f32]) -> Vec<f32> {
        let latent = self.centre.len();
        if self.mixing.len() != latent * latent {
            return standard
                .iter()
                .zip(self.centre.iter().zip(&self.spread))
                .map(|(e, (c, s))| c + s * e)
                .collect();
        }
        (0..latent)
            .map(|i| {
                let row = &self.mixing[i * latent..(i + 1) * latent];
                self.centre[i] + row.iter().zip(standard).map(|(l, e)| l * e).sum::<f32>()
            })
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
        let centre: Vec<f64> = (0..latent)
            .map(|d| mu.iter().map(|r| f64::from(r[d])).sum::<f64>() / n)
            .collect();
        // Covariance of the encoder means plus the mean of the encoder's own variances: the
        // covariance of the mixture of the training shapes' posteriors.
        let covariance = DMatrix::<f64>::from_fn(latent, latent, |i, j| {
            let between: f64 = mu
                .iter()
                .map(|r| (f64::from(r[i]) - centre[i]) * (f64::from(r[j]) - centre[j]))
                .sum::<f64>()
                / n;
            let within = if i == j {
                log_var.iter().map(|r| f64::from(r[i]).exp()).sum::<f64>() / n
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
