//! The beta-VAE generator of SPEC §2.6 (thesis 4.2.2, eq. 4.14): fully connected encoder
//! `3·N_μ → 512 → 256 → 768 → 128 → L` (mean and log-variance heads), LeakyReLU after every
//! hidden layer, mirrored decoder. Shapes are flattened `[x0, y0, z0, x1, …]` in mm and
//! standardised by the stored [`ShapeScaling`] (mean shape and spread).

use burn::config::Config;
use burn::module::{Module, RunningState};
use burn::tensor::activation::leaky_relu;
use burn::tensor::{Device, Tensor};
use rand_chacha::ChaCha8Rng;

use super::dense::Dense;
use super::error::{NnError, require};
use super::init::{RunningIds, number_params};

/// Sizes of the beta-VAE.
#[derive(Config, Debug, PartialEq)]
pub struct BetaVaeConfig {
    /// Input width `3·N_μ` (flattened atlas-domain shape).
    pub d_in: usize,
    /// Widths of the hidden encoder layers; the decoder uses them in reverse.
    #[config(default = "vec![512, 256, 768, 128]")]
    pub hidden: Vec<usize>,
    /// Latent width `L`.
    #[config(default = 16)]
    pub latent: usize,
    /// Negative slope of the LeakyReLU activations (PyTorch's default).
    #[config(default = 0.01)]
    pub leaky_slope: f64,
}

impl BetaVaeConfig {
    /// Checks that every size is usable.
    pub fn validate(&self) -> Result<(), NnError> {
        require(
            self.d_in > 0 && self.d_in.is_multiple_of(3),
            "d_in",
            "must be a positive multiple of 3",
        )?;
        require(
            self.hidden.iter().all(|&w| w > 0),
            "hidden",
            "widths must be positive",
        )?;
        require(self.latent > 0, "latent", "must be positive")?;
        require(
            self.leaky_slope.is_finite() && self.leaky_slope >= 0.0,
            "leaky_slope",
            "must be a non-negative number",
        )
    }

    /// A beta-VAE with weights drawn from `rng`, on `device`.
    pub fn init(&self, scaling: ShapeScaling, rng: &mut ChaCha8Rng, device: &Device) -> BetaVae {
        let mut stack = |widths: Vec<usize>| -> Vec<Dense> {
            widths
                .windows(2)
                .map(|w| Dense::new(w[0], w[1], rng, device))
                .collect()
        };
        let encoder = stack(
            std::iter::once(self.d_in)
                .chain(self.hidden.iter().copied())
                .collect(),
        );
        let decoder = stack(
            std::iter::once(self.latent)
                .chain(self.hidden.iter().rev().copied())
                .collect(),
        );
        let last = self.hidden.last().copied().unwrap_or(self.d_in);
        let first = self.hidden.first().copied().unwrap_or(self.latent);
        let mean = Dense::new(last, self.latent, rng, device);
        let log_var = Dense::new(last, self.latent, rng, device);
        let output = Dense::new(first, self.d_in, rng, device);
        let mut running = RunningIds::default();
        number_params(BetaVae {
            encoder,
            mean,
            log_var,
            decoder,
            output,
            shape_mean: running.state(scaling.mean, device),
            shape_spread: running.state(vec![scaling.spread], device),
            leaky_slope: self.leaky_slope,
        })
    }
}

/// Maps flattened shapes (mm) to network units: `(v − mean shape) / spread`, with `spread`
/// the root-mean-square deviation of all coordinates from the mean shape. Centring on the
/// mean shape lets the encoder see the variation between shapes: on a [0, 1] bounding-box
/// scale (thesis) the shapes differed by a few hundredths and the encoder's means came
/// out the same for every shape (`cargo run --release --example asmg_stages`).
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeScaling {
    /// The mean training shape, `[3·N_μ]`, mm.
    pub mean: Vec<f32>,
    /// RMS deviation of a coordinate from the mean shape, mm (> 0).
    pub spread: f32,
}

impl ShapeScaling {
    /// The identity map for shapes of `width` values.
    pub fn identity(width: usize) -> Self {
        Self {
            mean: vec![0.0; width],
            spread: 1.0,
        }
    }

    /// The mean shape and spread of the training shapes (equally long, flattened
    /// `[x, y, z, …]`); a spread of zero (one shape, or identical ones) becomes 1 mm.
    pub fn fit(shapes: &[Vec<f32>]) -> Self {
        Self::fit_weighted(shapes, None)
    }

    /// [`Self::fit`] with a weight `≥ 0` per shape (`None`: all equal), for a generator of
    /// one soft cluster.
    pub fn fit_weighted(shapes: &[Vec<f32>], weights: Option<&[f32]>) -> Self {
        let width = shapes.first().map_or(0, Vec::len);
        let weight = |k: usize| {
            weights
                .and_then(|w| w.get(k))
                .map_or(1.0, |w| f64::from(*w))
        };
        let n: f64 = (0..shapes.len()).map(weight).sum::<f64>();
        let n = if n > 0.0 { n } else { 1.0 };
        let mut mean = vec![0.0f64; width];
        for (k, shape) in shapes.iter().enumerate() {
            for (m, v) in mean.iter_mut().zip(shape) {
                *m += weight(k) * f64::from(*v) / n;
            }
        }
        let squares: f64 = shapes
            .iter()
            .enumerate()
            .flat_map(|(k, s)| {
                let mean = &mean;
                s.iter()
                    .zip(mean)
                    .map(move |(v, m)| weight(k) * (f64::from(*v) - m).powi(2))
            })
            .sum();
        let spread = (squares / (n * width.max(1) as f64)).sqrt() as f32;
        Self {
            mean: mean.into_iter().map(|m| m as f32).collect(),
            spread: if spread.is_finite() && spread > 0.0 {
                spread
            } else {
                1.0
            },
        }
    }

    /// mm to network units, in place.
    pub fn normalise(&self, shape: &mut [f32]) {
        for (v, m) in shape.iter_mut().zip(&self.mean) {
            *v = (*v - m) / self.spread;
        }
    }

    /// Network units back to mm, in place.
    pub fn denormalise(&self, shape: &mut [f32]) {
        for (v, m) in shape.iter_mut().zip(&self.mean) {
            *v = *v * self.spread + m;
        }
    }
}

/// The beta-VAE: encoder, mean and log-variance heads, decoder, and its coordinate scaling.
#[derive(Module, Debug)]
pub struct BetaVae {
    /// Hidden encoder layers.
    pub encoder: Vec<Dense>,
    /// Head for the latent mean, `[B, L]`.
    pub mean: Dense,
    /// Head for the latent log-variance, `[B, L]`.
    pub log_var: Dense,
    /// Hidden decoder layers.
    pub decoder: Vec<Dense>,
    /// Last decoder layer back to `3·N_μ`.
    pub output: Dense,
    /// The mean training shape (mm), `[3·N_μ]`.
    pub shape_mean: RunningState<Tensor<1>>,
    /// RMS deviation from the mean shape (mm), `[1]`.
    pub shape_spread: RunningState<Tensor<1>>,
    /// LeakyReLU negative slope.
    pub leaky_slope: f64,
}

impl BetaVae {
    /// Latent mean and log-variance of normalised shapes `[B, 3·N_μ]`, each `[B, L]`.
    pub fn encode(&self, x: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let h = self
            .encoder
            .iter()
            .fold(x, |h, l| leaky_relu(l.forward(h), self.leaky_slope));
        (self.mean.forward(h.clone()), self.log_var.forward(h))
    }

    /// Normalised shapes `[B, 3·N_μ]` from latent codes `[B, L]`.
    pub fn decode(&self, z: Tensor<2>) -> Tensor<2> {
        let h = self
            .decoder
            .iter()
            .fold(z, |h, l| leaky_relu(l.forward(h), self.leaky_slope));
        self.output.forward(h)
    }

    /// The shape scaling stored with the weights.
    pub fn scaling(&self) -> ShapeScaling {
        let mean: Vec<f32> = self.shape_mean.value().into_data().iter::<f32>().collect();
        let spread: Vec<f32> = self
            .shape_spread
            .value()
            .into_data()
            .iter::<f32>()
            .collect();
        ShapeScaling {
            mean,
            spread: spread.first().copied().unwrap_or(1.0),
        }
    }

    /// Loss of a batch, averaged over its shapes: ½‖x̂ − x‖² + β·KL(q(z|x) ‖ N(0, I)), with
    /// `z = μ + exp(½ log σ²)·noise` and `noise` `[B, L]` standard normal. With `weights`
    /// (`[B, 1]`), each shape's loss is multiplied by its weight before the average (the
    /// generator of one soft cluster, thesis eq. 5.17).
    pub fn loss(
        &self,
        x: Tensor<2>,
        noise: Tensor<2>,
        beta: f64,
        weights: Option<Tensor<2>>,
    ) -> Tensor<1> {
        let [b, _] = x.dims();
        let (mu, log_var) = self.encode(x.clone());
        let z = mu.clone() + log_var.clone().mul_scalar(0.5).exp() * noise;
        let reconstruction = (self.decode(z) - x)
            .powi_scalar(2)
            .sum_dim(1)
            .mul_scalar(0.5);
        // KL = ½ Σ (μ² + σ² − 1 − log σ²).
        let kl = (mu.powi_scalar(2) + log_var.clone().exp() - log_var)
            .sub_scalar(1.0)
            .sum_dim(1)
            .mul_scalar(0.5);
        let per_shape = reconstruction + kl.mul_scalar(beta);
        let per_shape = match weights {
            Some(w) => per_shape * w,
            None => per_shape,
        };
        per_shape.sum().div_scalar(b.max(1) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::device::{STREAM_INIT, inference_device, rng};
    use crate::nn::init::tensor;

    #[test]
    fn scaling_centres_on_the_mean_shape_and_back() {
        let shapes = vec![vec![0.0, 10.0, 5.0], vec![2.0, 14.0, 5.0]];
        let s = ShapeScaling::fit(&shapes);
        assert_eq!(s.mean, vec![1.0, 12.0, 5.0]);
        // Deviations ±1, ±2, 0: mean square (1 + 4 + 0 + 1 + 4 + 0) / 6.
        assert!((s.spread - (10.0f32 / 6.0).sqrt()).abs() < 1e-6);
        let mut v = shapes[1].clone();
        s.normalise(&mut v);
        assert!((v[0] - 1.0 / s.spread).abs() < 1e-6 && v[2] == 0.0);
        s.denormalise(&mut v);
        assert!(v.iter().zip(&shapes[1]).all(|(a, b)| (a - b).abs() < 1e-5));
        assert_eq!(ShapeScaling::fit(&shapes[..1]).spread, 1.0);
    }

    #[test]
    fn shapes_and_loss_terms() {
        let device = inference_device();
        let config = BetaVaeConfig::new(6).with_hidden(vec![5, 4]).with_latent(2);
        let model = config.init(ShapeScaling::identity(6), &mut rng(0, STREAM_INIT), &device);
        let x = tensor(
            vec![0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.0, 0.1, 0.0, 0.1, 0.0, 0.1],
            [2, 6],
            &device,
        );
        let (mu, log_var) = model.encode(x.clone());
        assert_eq!(mu.dims(), [2, 2]);
        assert_eq!(model.decode(mu.clone()).dims(), [2, 6]);
        // With zero noise the loss is the reconstruction of μ plus β times the KL.
        let zero = Tensor::zeros([2, 2], &device);
        let at = |beta| {
            f64::from(
                model
                    .loss(x.clone(), zero.clone(), beta, None)
                    .into_scalar::<f32>(),
            )
        };
        let rec: f64 = (model.decode(mu.clone()) - x.clone())
            .powi_scalar(2)
            .sum()
            .into_scalar::<f32>()
            .into();
        let mu: Vec<f32> = mu.into_data().iter::<f32>().collect();
        let lv: Vec<f32> = log_var.into_data().iter::<f32>().collect();
        let kl: f64 = mu
            .iter()
            .zip(&lv)
            .map(|(&m, &l)| 0.5 * f64::from(m * m + l.exp() - 1.0 - l))
            .sum();
        assert!((at(0.0) - rec / 4.0).abs() < 1e-5);
        assert!((at(2.0) - (rec / 2.0 + 2.0 * kl) / 2.0).abs() < 1e-5);
        assert_eq!(
            config.clone().with_latent(0).validate().unwrap_err().code(),
            "nn.invalid_config"
        );
        assert_eq!(
            BetaVaeConfig::new(7).validate().unwrap_err().code(),
            "nn.invalid_config"
        );
    }
}
