//! What the training loops share: the monitor the caller implements, seeded mini-batches,
//! the optimiser and the learning-rate schedule.

use burn::optim::{AdamConfig, ModuleOptimizer};
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use super::device::{STREAM_SHUFFLE, rng};
use super::error::{NnError, require};

/// Adam's ε (PyTorch's default, so the same learning rates behave the same).
const ADAM_EPSILON: f32 = 1e-8;

/// What the monitor wants after a batch or an epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    /// Go on training.
    Continue,
    /// Stop now and keep the network as trained so far.
    Finish,
    /// Stop now and discard the network (the caller was cancelled).
    Cancel,
}

/// Receives progress from a training loop; its answers can end training between batches.
pub trait Monitor {
    /// Called after every mini-batch.
    fn batch(&mut self) -> Flow {
        Flow::Continue
    }
    /// Called after every epoch (0-based `epoch` of `epochs`) with the mean loss per sample.
    fn epoch(&mut self, epoch: usize, epochs: usize, mean_loss: f64) -> Flow;
}

/// A monitor that never stops training.
#[derive(Debug, Default, Clone, Copy)]
pub struct Unmonitored;

impl Monitor for Unmonitored {
    fn epoch(&mut self, _epoch: usize, _epochs: usize, _mean_loss: f64) -> Flow {
        Flow::Continue
    }
}

/// Sample indices of one epoch in a seeded random order, cut into mini-batches.
pub(crate) fn epoch_batches(
    count: usize,
    batch_size: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<Vec<usize>> {
    let mut order: Vec<usize> = (0..count).collect();
    order.shuffle(rng);
    order
        .chunks(batch_size.max(1))
        .map(<[usize]>::to_vec)
        .collect()
}

/// Adam with PyTorch's defaults (β = 0.9, 0.999; ε = 1e-8; no weight decay).
pub(crate) fn adam() -> ModuleOptimizer {
    AdamConfig::new().with_epsilon(ADAM_EPSILON).init()
}

/// Step decay: `lr · gamma^⌊epoch / step⌋` (no decay when `step` is 0).
pub fn step_decay(lr: f64, epoch: usize, step: usize, gamma: f64) -> f64 {
    match epoch.checked_div(step) {
        Some(steps) => lr * gamma.powi(steps as i32),
        None => lr,
    }
}

/// Checks the settings every training loop shares.
pub(crate) fn check_schedule(epochs: usize, batch_size: usize, lr: f64) -> Result<(), NnError> {
    require(epochs > 0, "epochs", "must be at least 1")?;
    require(batch_size > 0, "batch_size", "must be at least 1")?;
    require(
        lr.is_finite() && lr > 0.0,
        "lr",
        "must be a positive number",
    )
}

/// The epoch loop both networks share: seeded shuffling into mini-batches, one `step` per
/// batch (returning the updated model and the batch's summed loss), the monitor after every
/// batch and epoch. Returns the model and the mean loss per sample of each finished epoch.
pub(crate) fn run_epochs<M>(
    mut model: M,
    count: usize,
    schedule: (usize, usize, u64),
    monitor: &mut dyn Monitor,
    mut step: impl FnMut(M, &[usize], usize) -> (M, f64),
) -> Result<(M, Vec<f64>), NnError> {
    let (epochs, batch_size, seed) = schedule;
    let mut shuffle = rng(seed, STREAM_SHUFFLE);
    let mut losses = Vec::with_capacity(epochs);
    for epoch in 0..epochs {
        let mut total = 0.0;
        for batch in epoch_batches(count, batch_size, &mut shuffle) {
            let (next, loss) = step(model, &batch, epoch);
            model = next;
            if !loss.is_finite() {
                return Err(NnError::Diverged { epoch });
            }
            total += loss;
            if !go_on(monitor.batch())? {
                return Ok((model, losses));
            }
        }
        let mean = total / count.max(1) as f64;
        losses.push(mean);
        if !go_on(monitor.epoch(epoch, epochs, mean))? {
            break;
        }
    }
    Ok((model, losses))
}

/// Turns a monitor answer into "go on" (`Ok(true)`), "finish" (`Ok(false)`) or cancellation.
pub(crate) fn go_on(flow: Flow) -> Result<bool, NnError> {
    match flow {
        Flow::Continue => Ok(true),
        Flow::Finish => Ok(false),
        Flow::Cancel => Err(NnError::Cancelled),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn batches_cover_every_sample_once_in_a_seeded_order() {
        let a = epoch_batches(10, 4, &mut rng(5, STREAM_SHUFFLE));
        let b = epoch_batches(10, 4, &mut rng(5, STREAM_SHUFFLE));
        assert_eq!(a, b);
        assert_eq!(a.iter().map(Vec::len).collect::<Vec<_>>(), vec![4, 4, 2]);
        let mut all: Vec<usize> = a.concat();
        all.sort_unstable();
        assert_eq!(all, (0..10).collect::<Vec<_>>());
        assert_ne!(a.concat(), (0..10).collect::<Vec<_>>());
    }

    #[test]
    fn step_decay_halves_every_step() {
        assert_eq!(step_decay(1e-3, 0, 100, 0.5), 1e-3);
        assert_eq!(step_decay(1e-3, 99, 100, 0.5), 1e-3);
        assert_eq!(step_decay(1e-3, 100, 100, 0.5), 5e-4);
        assert_eq!(step_decay(1e-3, 250, 100, 0.5), 2.5e-4);
        assert_eq!(step_decay(1e-3, 250, 0, 0.5), 1e-3);
    }

    #[test]
    fn flows_map_to_outcomes() {
        assert_eq!(go_on(Flow::Continue), Ok(true));
        assert_eq!(go_on(Flow::Finish), Ok(false));
        assert_eq!(go_on(Flow::Cancel), Err(NnError::Cancelled));
        assert!(check_schedule(1, 1, 1e-3).is_ok());
        assert_eq!(
            check_schedule(0, 1, 1e-3).unwrap_err().code(),
            "nn.invalid_config"
        );
        assert_eq!(
            check_schedule(1, 1, f64::NAN).unwrap_err().code(),
            "nn.invalid_config"
        );
    }
}

#[cfg(test)]
mod loop_tests {
    use super::*;

    /// Stops with `answer` once `after` batches were seen, recording the epoch losses.
    struct Scripted {
        batches: usize,
        after: usize,
        answer: Flow,
        epochs: Vec<f64>,
    }

    impl Monitor for Scripted {
        fn batch(&mut self) -> Flow {
            self.batches += 1;
            if self.batches >= self.after {
                self.answer
            } else {
                Flow::Continue
            }
        }
        fn epoch(&mut self, _epoch: usize, _epochs: usize, mean_loss: f64) -> Flow {
            self.epochs.push(mean_loss);
            Flow::Continue
        }
    }

    fn counter(answer: Flow, after: usize) -> (Result<(usize, Vec<f64>), NnError>, Scripted) {
        let mut m = Scripted {
            batches: 0,
            after,
            answer,
            epochs: vec![],
        };
        // 5 samples in batches of 2: each step adds one and reports loss = batch length.
        let out = run_epochs(0usize, 5, (3, 2, 9), &mut m, |n, batch, _| {
            (n + 1, batch.len() as f64)
        });
        (out, m)
    }

    #[test]
    fn all_epochs_run_and_report_the_mean_loss_per_sample() {
        let (out, m) = counter(Flow::Continue, usize::MAX);
        let (steps, losses) = out.unwrap();
        assert_eq!(steps, 9);
        assert_eq!(losses, vec![1.0, 1.0, 1.0]);
        assert_eq!(m.epochs, losses);
    }

    #[test]
    fn finish_keeps_the_model_and_cancel_discards_it() {
        let (out, _) = counter(Flow::Finish, 4);
        let (steps, losses) = out.unwrap();
        assert_eq!((steps, losses.len()), (4, 1));
        let (out, _) = counter(Flow::Cancel, 2);
        assert_eq!(out.unwrap_err(), NnError::Cancelled);
    }

    #[test]
    fn a_non_finite_loss_is_reported_as_divergence() {
        let mut m = Unmonitored;
        let out = run_epochs(0usize, 4, (2, 2, 1), &mut m, |n, _, epoch| {
            (n, if epoch == 1 { f64::NAN } else { 1.0 })
        });
        assert_eq!(out.unwrap_err(), NnError::Diverged { epoch: 1 });
    }
}
