//! A fully connected layer with seeded initialisation.

use burn::module::{Module, Param};
use burn::tensor::{Device, Tensor};
use rand_chacha::ChaCha8Rng;

use super::init::{fan_in_bound, uniform};

/// `y = x·W + b` with `W` `[d_in, d_out]` and `b` `[d_out]`.
#[derive(Module, Debug)]
pub struct Dense {
    /// Weight `[d_in, d_out]`.
    pub weight: Param<Tensor<2>>,
    /// Bias `[d_out]`.
    pub bias: Param<Tensor<1>>,
}

impl Dense {
    /// A layer with PyTorch's default initialisation: weight and bias uniform in ±1/√d_in.
    pub fn new(d_in: usize, d_out: usize, rng: &mut ChaCha8Rng, device: &Device) -> Self {
        let bound = fan_in_bound(d_in);
        Self {
            weight: uniform([d_in, d_out], bound, rng, device),
            bias: uniform([d_out], bound, rng, device),
        }
    }

    /// Applies the layer to `x` (`[B, d_in]`); returns `[B, d_out]`.
    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        x.matmul(self.weight.val()) + self.bias.val().unsqueeze_dim(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nn::device::{STREAM_INIT, inference_device, rng};
    use crate::nn::init::tensor;

    #[test]
    fn forward_is_an_affine_map() {
        let device = inference_device();
        let mut layer = Dense::new(2, 3, &mut rng(0, STREAM_INIT), &device);
        layer.weight =
            Param::from_tensor(tensor(vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [2, 3], &device));
        layer.bias = Param::from_tensor(tensor(vec![0.5, 0.0, -1.0], [3], &device));
        let y = layer.forward(tensor(vec![1.0, -1.0, 0.0, 2.0], [2, 2], &device));
        let y: Vec<f32> = y.into_data().iter::<f32>().collect();
        assert_eq!(y, vec![-2.5, -3.0, -4.0, 8.5, 10.0, 11.0]);
    }
}
