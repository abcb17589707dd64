//! Progress of offline fits: lines on stderr, and the timing of epochs for models whose
//! stages report a loss per epoch.

use std::time::{Duration, Instant};

use serde::Serialize;

use crate::models::progress::{Cancelled, Progress, ProgressUpdate};

/// Least time between two progress lines of the same stage.
pub const LINE_INTERVAL: Duration = Duration::from_secs(2);

/// Loss reports seen in one stage.
#[derive(Debug, Clone)]
struct EpochTrack {
    stage: &'static str,
    count: u64,
    /// The step of the latest report: the monitors repeat an epoch's loss after every batch.
    step: u64,
    first: Instant,
    last: Instant,
}

/// Seconds per epoch of one stage that reports a loss per step.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EpochTiming {
    /// Stage name.
    pub stage: String,
    /// Loss reports (epochs) seen.
    pub epochs: u64,
    /// Mean seconds between the first reports of consecutive epochs.
    pub seconds_per_epoch: f64,
}

/// Prints progress lines to stderr (a new stage, every [`LINE_INTERVAL`], the end of a
/// stage) and times epochs. Never cancels.
#[derive(Debug)]
pub struct StderrProgress {
    label: String,
    stage: Option<&'static str>,
    last_line: Instant,
    epochs: Vec<EpochTrack>,
}

impl StderrProgress {
    /// Progress lines prefixed by `label` (e.g. the model type).
    pub fn new(label: &str) -> Self {
        Self {
            label: label.to_owned(),
            stage: None,
            last_line: Instant::now(),
            epochs: Vec::new(),
        }
    }

    /// Seconds per epoch of every stage that reported a loss at least twice.
    pub fn epoch_timings(&self) -> Vec<EpochTiming> {
        self.epochs
            .iter()
            .filter(|t| t.count >= 2)
            .map(|t| EpochTiming {
                stage: t.stage.to_owned(),
                epochs: t.count,
                seconds_per_epoch: (t.last - t.first).as_secs_f64() / (t.count - 1) as f64,
            })
            .collect()
    }

    fn track_epoch(&mut self, stage: &'static str, step: u64, now: Instant) {
        match self.epochs.iter_mut().find(|t| t.stage == stage) {
            Some(track) if track.step == step => {}
            Some(track) => {
                track.count += 1;
                track.step = step;
                track.last = now;
            }
            None => self.epochs.push(EpochTrack {
                stage,
                count: 1,
                step,
                first: now,
                last: now,
            }),
        }
    }
}

impl Progress for StderrProgress {
    fn report(&mut self, update: ProgressUpdate) -> Result<(), Cancelled> {
        let now = Instant::now();
        if update.loss.is_some() {
            self.track_epoch(update.stage, update.step, now);
        }
        let new_stage = self.stage != Some(update.stage);
        let stage_done = update.step == update.total;
        if new_stage || stage_done || now - self.last_line >= LINE_INTERVAL {
            let loss = update
                .loss
                .map(|l| format!(" (loss {l:.4})"))
                .unwrap_or_default();
            eprintln!(
                "[{} {:3.0}%] {} {}/{}: {}{loss}",
                self.label,
                100.0 * update.fraction,
                update.stage,
                update.step,
                update.total,
                update.message
            );
            self.stage = Some(update.stage);
            self.last_line = now;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn update(stage: &'static str, step: u64, loss: Option<f64>) -> ProgressUpdate {
        ProgressUpdate {
            stage,
            step,
            total: 10,
            fraction: step as f64 / 10.0,
            message: String::new(),
            loss,
        }
    }

    #[test]
    fn epochs_are_timed_only_where_a_loss_is_reported() {
        let mut progress = StderrProgress::new("test");
        progress.report(update("alignment", 1, None)).unwrap();
        for step in 1..=3 {
            // Batches repeat the latest epoch's loss with the same step.
            for _batch in 0..4 {
                progress
                    .report(update("training", step, Some(0.5)))
                    .unwrap();
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let timings = progress.epoch_timings();
        assert_eq!(timings.len(), 1);
        assert_eq!(
            (timings[0].stage.as_str(), timings[0].epochs),
            ("training", 3)
        );
        assert!(timings[0].seconds_per_epoch >= 0.01, "{timings:?}");
        assert!(StderrProgress::new("x").epoch_timings().is_empty());
    }
}
