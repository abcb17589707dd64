//! Where the networks run, chosen at run time, and the seeded random streams they draw from.
//!
//! The CPU backend is burn-flex by default; the cargo feature `ndarray` switches to the
//! (deprecated) burn-ndarray backend for comparison. Training runs on the same device with
//! autodiff enabled. Weights, shuffling and sampling noise all come from ChaCha streams seeded
//! by the caller (never from the backend's global generator), so the same seed gives the same
//! weights, the same training and the same samples, whatever else runs in the process.

use burn::tensor::Device;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// Random stream for initial weights.
pub(crate) const STREAM_INIT: u64 = 1;
/// Random stream for the order of samples in each epoch.
pub(crate) const STREAM_SHUFFLE: u64 = 2;
/// Random stream for the reparameterisation noise during training.
pub(crate) const STREAM_NOISE: u64 = 3;
/// Random stream for drawing latent codes when sampling a trained generator.
pub(crate) const STREAM_SAMPLE: u64 = 4;

/// The device that runs inference (no autodiff).
pub fn inference_device() -> Device {
    #[cfg(feature = "ndarray")]
    {
        #[allow(deprecated)]
        Device::ndarray()
    }
    #[cfg(not(feature = "ndarray"))]
    {
        Device::flex()
    }
}

/// The device that trains: the inference device with autodiff enabled.
pub fn training_device() -> Device {
    inference_device().autodiff()
}

/// Name of the compiled-in CPU backend (`flex` or `ndarray`), for logs and benchmarks.
pub fn backend_name() -> &'static str {
    if cfg!(feature = "ndarray") {
        "ndarray"
    } else {
        "flex"
    }
}

/// A reproducible random stream: the same `(seed, stream)` always gives the same numbers.
pub(crate) fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    rng
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: u64 = rng(7, STREAM_INIT).random();
        let b: u64 = rng(7, STREAM_INIT).random();
        let c: u64 = rng(7, STREAM_SHUFFLE).random();
        let d: u64 = rng(8, STREAM_INIT).random();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
    }

    #[test]
    fn training_device_has_autodiff() {
        assert!(training_device().is_autodiff());
        assert!(!inference_device().is_autodiff());
        assert_eq!(training_device(), inference_device());
    }
}
