//! Seeded parameter initialisation (PyTorch's defaults, drawn from our own random streams).

use burn::module::{Module, ModuleMapper, Param, ParamId, RunningState};
use burn::nn::{BatchNorm, BatchNormConfig};
use burn::tensor::{Device, Tensor, TensorData};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A tensor of shape `shape` from row-major `values` on `device` (default float type).
pub(crate) fn tensor<const D: usize>(
    values: Vec<f32>,
    shape: [usize; D],
    device: &Device,
) -> Tensor<D> {
    Tensor::from_data(TensorData::new(values, shape), device)
}

/// A trainable parameter drawn uniformly from `[-bound, bound)`.
pub(crate) fn uniform<const D: usize>(
    shape: [usize; D],
    bound: f64,
    rng: &mut ChaCha8Rng,
    device: &Device,
) -> Param<Tensor<D>> {
    let n = shape.iter().product();
    let values = (0..n)
        .map(|_| ((2.0 * rng.random::<f64>() - 1.0) * bound) as f32)
        .collect();
    Param::from_tensor(tensor(values, shape, device))
}

/// A trainable parameter drawn from N(0, std²).
pub(crate) fn normal<const D: usize>(
    shape: [usize; D],
    std: f64,
    rng: &mut ChaCha8Rng,
    device: &Device,
) -> Param<Tensor<D>> {
    let values = standard_normal(shape.iter().product(), rng)
        .into_iter()
        .map(|v| v * std as f32)
        .collect();
    Param::from_tensor(tensor(values, shape, device))
}

/// `n` draws from N(0, 1).
pub(crate) fn standard_normal(n: usize, rng: &mut ChaCha8Rng) -> Vec<f32> {
    (0..n)
        .map(|_| {
            let v: f64 = StandardNormal.sample(rng);
            v as f32
        })
        .collect()
}

/// Ids of running states (buffers) start here, far above the trainable parameters' ids.
const RUNNING_ID_BASE: u64 = 1 << 62;

/// Gives every trainable parameter of `model` a fixed id (1, 2, … in visiting order), so that
/// equal weights give equal record bytes and a reloaded model writes the bytes it was read
/// from. Running states keep the ids [`RunningIds`] gave them.
pub(crate) fn number_params<M: Module>(model: M) -> M {
    model.map(&mut Numbering { next: 1 })
}

struct Numbering {
    next: u64,
}

impl ModuleMapper for Numbering {
    fn map_float<const D: usize>(&mut self, mut param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        param.id = ParamId::from(self.next);
        self.next += 1;
        param
    }
}

/// Fixed ids for running states (batch-norm statistics, stored scalings), in creation order.
#[derive(Debug)]
pub(crate) struct RunningIds(u64);

impl Default for RunningIds {
    fn default() -> Self {
        Self(RUNNING_ID_BASE)
    }
}

impl RunningIds {
    /// A running state holding `values` (shape `[len]`) under the next fixed id.
    pub(crate) fn state(&mut self, values: Vec<f32>, device: &Device) -> RunningState<Tensor<1>> {
        self.0 += 1;
        let n = values.len();
        RunningState::with_id(ParamId::from(self.0), tensor(values, [n], device))
    }

    /// Batch norm over `width` features whose running statistics have fixed ids.
    pub(crate) fn batch_norm(&mut self, width: usize, device: &Device) -> BatchNorm {
        let mut norm = BatchNormConfig::new(width).init(device);
        norm.running_mean = self.state(vec![0.0; width], device);
        norm.running_var = self.state(vec![1.0; width], device);
        norm
    }
}

/// PyTorch's default bound for a layer with `fan_in` inputs: `1/√fan_in`
/// (Kaiming uniform with a = √5).
pub(crate) fn fan_in_bound(fan_in: usize) -> f64 {
    1.0 / (fan_in.max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::device::{STREAM_INIT, inference_device, rng};

    #[test]
    fn uniform_stays_in_bounds_and_repeats() {
        let device = inference_device();
        let a = uniform([4, 5], 0.5, &mut rng(1, STREAM_INIT), &device).val();
        let b = uniform([4, 5], 0.5, &mut rng(1, STREAM_INIT), &device).val();
        let a: Vec<f32> = a.into_data().iter::<f32>().collect();
        let b: Vec<f32> = b.into_data().iter::<f32>().collect();
        assert_eq!(a, b);
        assert_eq!(a.len(), 20);
        assert!(a.iter().all(|v| v.abs() <= 0.5));
        assert!(a.iter().any(|v| v.abs() > 0.1));
    }

    #[test]
    fn normal_has_roughly_the_requested_spread() {
        let v = standard_normal(20_000, &mut rng(3, STREAM_INIT));
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / v.len() as f32;
        assert!(mean.abs() < 0.03, "mean {mean}");
        assert!((var - 1.0).abs() < 0.05, "var {var}");
        assert!((fan_in_bound(64) - 0.125).abs() < 1e-12);
    }
}
