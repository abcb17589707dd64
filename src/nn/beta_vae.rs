//! The beta-VAE generator of SPEC §2.6 (thesis 4.2.2, eq. 4.14): fully connected encoder
//! `3·N_μ → 512 → 256 → 768 → 128 → L` (mean and log-variance heads), LeakyReLU after every
//! hidden layer, mirrored decoder. Shapes are flattened `[x0, y0, z0, x1, …]` in mm and mapped
//! to [0, 1] coordinates by the stored [`CoordinateScaling`].

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
    pub fn init(
        &self,
        scaling: CoordinateScaling,
        rng: &mut ChaCha8Rng,
        device: &Device,
    ) -> BetaVae {
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
            coordinate_min: running.state(scaling.min.to_vec(), device),
            coordinate_range: running.state(vec![scaling.range], device),
            leaky_slope: self.leaky_slope,
        })
    }
}

/// Maps coordinates (mm) to [0, 1]: `(v − min_axis) / range`, one range for all axes so the
/// aspect ratio is kept.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoordinateScaling {
    /// Smallest coordinate per axis over the training shapes, mm.
    pub min: [f32; 3],
    /// Largest extent over the axes, mm.
    pub range: f32,
}

impl CoordinateScaling {
    /// The identity map.
    pub const IDENTITY: Self = Self {
        min: [0.0; 3],
        range: 1.0,
    };

    /// The bounding box of all training shapes (flattened `[x, y, z, …]`).
    pub fn fit(shapes: &[Vec<f32>]) -> Self {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for shape in shapes {
            for p in shape.chunks_exact(3) {
                for d in 0..3 {
                    lo[d] = lo[d].min(p[d]);
                    hi[d] = hi[d].max(p[d]);
                }
            }
        }
        if lo.iter().any(|v| !v.is_finite()) {
            return Self::IDENTITY;
        }
        let range = (0..3).map(|d| hi[d] - lo[d]).fold(0.0f32, f32::max);
        Self {
            min: lo,
            range: if range > 0.0 { range } else { 1.0 },
        }
    }

    /// mm to [0, 1], in place.
    pub fn normalise(&self, shape: &mut [f32]) {
        for (k, v) in shape.iter_mut().enumerate() {
            *v = (*v - self.min[k % 3]) / self.range;
        }
    }

    /// [0, 1] back to mm, in place.
    pub fn denormalise(&self, shape: &mut [f32]) {
        for (k, v) in shape.iter_mut().enumerate() {
            *v = *v * self.range + self.min[k % 3];
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
    /// Coordinate minimum per axis (mm), `[3]`.
    pub coordinate_min: RunningState<Tensor<1>>,
    /// Coordinate range (mm), `[1]`.
    pub coordinate_range: RunningState<Tensor<1>>,
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

    /// The coordinate scaling stored with the weights.
    pub fn scaling(&self) -> CoordinateScaling {
        let min: Vec<f32> = self
            .coordinate_min
            .value()
            .into_data()
            .iter::<f32>()
            .collect();
        let range: Vec<f32> = self
            .coordinate_range
            .value()
            .into_data()
            .iter::<f32>()
            .collect();
        CoordinateScaling {
            min: [0, 1, 2].map(|d| min.get(d).copied().unwrap_or(0.0)),
            range: range.first().copied().unwrap_or(1.0),
        }
    }

    /// Loss of a batch, averaged over its shapes: ½‖x̂ − x‖² + β·KL(q(z|x) ‖ N(0, I)), with
    /// `z = μ + exp(½ log σ²)·noise` and `noise` `[B, L]` standard normal.
    pub fn loss(&self, x: Tensor<2>, noise: Tensor<2>, beta: f64) -> Tensor<1> {
        let [b, _] = x.dims();
        let (mu, log_var) = self.encode(x.clone());
        let z = mu.clone() + log_var.clone().mul_scalar(0.5).exp() * noise;
        let reconstruction = (self.decode(z) - x).powi_scalar(2).sum().mul_scalar(0.5);
        // KL = ½ Σ (μ² + σ² − 1 − log σ²).
        let kl = (mu.powi_scalar(2) + log_var.clone().exp() - log_var)
            .sub_scalar(1.0)
            .sum()
            .mul_scalar(0.5);
        (reconstruction + kl.mul_scalar(beta)).div_scalar(b.max(1) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::device::{STREAM_INIT, inference_device, rng};
    use crate::nn::init::tensor;

    #[test]
    fn scaling_maps_the_box_to_the_unit_range_and_back() {
        let shapes = vec![vec![0.0, 10.0, 5.0, 20.0, 12.0, 5.0], vec![10.0, 11.0, 9.0]];
        let s = CoordinateScaling::fit(&shapes);
        assert_eq!(s.min, [0.0, 10.0, 5.0]);
        assert_eq!(s.range, 20.0);
        let mut v = shapes[0].clone();
        s.normalise(&mut v);
        assert_eq!(v, vec![0.0, 0.0, 0.0, 1.0, 0.1, 0.0]);
        s.denormalise(&mut v);
        assert_eq!(v, shapes[0]);
    }

    #[test]
    fn shapes_and_loss_terms() {
        let device = inference_device();
        let config = BetaVaeConfig::new(6).with_hidden(vec![5, 4]).with_latent(2);
        let model = config.init(
            CoordinateScaling::IDENTITY,
            &mut rng(0, STREAM_INIT),
            &device,
        );
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
                    .loss(x.clone(), zero.clone(), beta)
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
