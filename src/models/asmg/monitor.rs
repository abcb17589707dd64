//! Training progress of the networks as fit progress: the loss after every epoch, and a
//! cancellation checkpoint after every mini-batch.

use crate::models::progress::{Progress, Stages};
use crate::nn::{Flow, Monitor};

/// Forwards a network's training loop to the fit's progress within the current stage.
pub(crate) struct StageMonitor<'a> {
    stages: &'a Stages,
    progress: &'a mut dyn Progress,
    network: String,
    epochs_done: u64,
    /// Epochs of the stage before this network's and in all (see [`Self::spanning`]).
    span: (u64, u64),
    last_loss: Option<f64>,
    /// Mean loss of every finished epoch, in order.
    pub(crate) losses: Vec<f64>,
}

impl<'a> StageMonitor<'a> {
    /// Reports for `network` (e.g. `graph VAE`), trained for `epochs` epochs, within the
    /// running stage of `stages`.
    pub(crate) fn new(
        stages: &'a Stages,
        progress: &'a mut dyn Progress,
        network: &str,
        epochs: usize,
    ) -> Self {
        Self {
            stages,
            progress,
            network: network.to_owned(),
            epochs_done: 0,
            span: (0, epochs as u64),
            last_loss: None,
            losses: Vec::new(),
        }
    }

    /// As [`Self::new`], for one of several networks trained in the same stage: progress is
    /// reported as `before + epoch` of `all` epochs of the stage.
    pub(crate) fn spanning(
        stages: &'a Stages,
        progress: &'a mut dyn Progress,
        network: &str,
        epochs: usize,
        (before, all): (usize, usize),
    ) -> Self {
        let mut monitor = Self::new(stages, progress, network, epochs);
        monitor.span = (before as u64, all as u64);
        monitor
    }

    fn answer(&mut self, message: String) -> Flow {
        let (before, all) = self.span;
        match self.stages.report(
            self.progress,
            before + self.epochs_done,
            all,
            message,
            self.last_loss,
        ) {
            Ok(()) => Flow::Continue,
            Err(_) => Flow::Cancel,
        }
    }
}

impl Monitor for StageMonitor<'_> {
    fn batch(&mut self) -> Flow {
        // Progress is cheap to record; this is the cancellation checkpoint between batches.
        let message = format!("training the {}", self.network);
        self.answer(message)
    }

    fn epoch(&mut self, epoch: usize, epochs: usize, mean_loss: f64) -> Flow {
        self.epochs_done = epoch as u64 + 1;
        self.last_loss = Some(mean_loss);
        self.losses.push(mean_loss);
        let message = format!(
            "{} epoch {} of {epochs}: loss {mean_loss:.4}",
            self.network,
            epoch + 1
        );
        self.answer(message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::progress::{Cancelled, ProgressUpdate};

    struct Record {
        updates: Vec<ProgressUpdate>,
        cancel_after: usize,
    }

    impl Progress for Record {
        fn report(&mut self, update: ProgressUpdate) -> Result<(), Cancelled> {
            self.updates.push(update);
            if self.updates.len() >= self.cancel_after {
                Err(Cancelled)
            } else {
                Ok(())
            }
        }
    }

    #[test]
    fn epochs_report_the_loss_and_cancellation_stops_training() {
        let mut stages = Stages::new(&[("graph_vae", 1.0)]);
        stages.enter("graph_vae");
        let mut record = Record {
            updates: vec![],
            cancel_after: 3,
        };
        let mut m = StageMonitor::new(&stages, &mut record, "graph VAE", 4);
        assert_eq!(m.batch(), Flow::Continue);
        assert_eq!(m.epoch(0, 4, 2.5), Flow::Continue);
        assert_eq!(m.batch(), Flow::Cancel);
        let u = &record.updates[1];
        assert_eq!((u.step, u.total, u.loss), (1, 4, Some(2.5)));
        assert!((u.fraction - 0.25).abs() < 1e-12);
        assert!(u.message.contains("epoch 1 of 4"), "{}", u.message);
    }
}
