//! Progress reporting and cancellation checkpoints of a fit.

use std::cell::Cell;
use std::time::Instant;

/// The job was asked to stop; the fit returns at the checkpoint that noticed it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the fit was cancelled")]
pub struct Cancelled;

/// One progress report.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgressUpdate {
    /// Stage name, e.g. `alignment`.
    pub stage: &'static str,
    /// Steps done in the stage.
    pub step: u64,
    /// Steps in the stage.
    pub total: u64,
    /// Fraction of the whole fit done, 0–1.
    pub fraction: f64,
    /// What is happening.
    pub message: String,
    /// Latest loss, for stages that have one.
    pub loss: Option<f64>,
}

/// Receives progress; each call is also a cancellation checkpoint.
pub trait Progress {
    /// Records progress; `Err(Cancelled)` tells the fit to stop.
    fn report(&mut self, update: ProgressUpdate) -> Result<(), Cancelled>;
}

/// Ignores progress and never cancels (offline fits and tests).
#[derive(Debug, Default)]
pub struct Silent;

impl Progress for Silent {
    fn report(&mut self, _update: ProgressUpdate) -> Result<(), Cancelled> {
        Ok(())
    }
}

/// Stages of a fit with their share of the total work, turning per-stage steps into an
/// overall fraction, and timing each stage.
#[derive(Debug)]
pub struct Stages {
    plan: Vec<(&'static str, f64)>,
    current: usize,
    running: bool,
    started: Instant,
    /// Seconds spent in each finished stage.
    pub seconds: Vec<(&'static str, f64)>,
    /// The largest fraction reported so far: what a dashboard sees never moves back, even
    /// when a stage trains several networks one after another.
    reported: Cell<f64>,
}

impl Stages {
    /// A plan of `(stage, weight)`; weights are normalised to sum to one.
    pub fn new(plan: &[(&'static str, f64)]) -> Self {
        let total: f64 = plan.iter().map(|(_, w)| w).sum();
        Self {
            plan: plan.iter().map(|(s, w)| (*s, w / total)).collect(),
            current: 0,
            running: false,
            started: Instant::now(),
            seconds: Vec::new(),
            reported: Cell::new(0.0),
        }
    }

    /// Starts `stage`, closing the timing of the previous one.
    pub fn enter(&mut self, stage: &'static str) {
        self.close();
        self.current = self
            .plan
            .iter()
            .position(|(s, _)| *s == stage)
            .unwrap_or(self.current);
        self.running = true;
        self.started = Instant::now();
    }

    /// Closes the timing of the running stage (call once at the end).
    pub fn close(&mut self) {
        if self.running
            && let Some((stage, _)) = self.plan.get(self.current)
        {
            self.seconds
                .push((stage, self.started.elapsed().as_secs_f64()));
        }
        self.running = false;
    }

    /// Reports `step` of `total` in the current stage.
    pub fn report(
        &self,
        progress: &mut dyn Progress,
        step: u64,
        total: u64,
        message: String,
        loss: Option<f64>,
    ) -> Result<(), Cancelled> {
        let done: f64 = self.plan[..self.current].iter().map(|(_, w)| w).sum();
        let (stage, weight) = self
            .plan
            .get(self.current)
            .copied()
            .unwrap_or(("done", 0.0));
        let within = if total == 0 {
            0.0
        } else {
            step as f64 / total as f64
        };
        let fraction = (done + weight * within)
            .clamp(0.0, 1.0)
            .max(self.reported.get());
        self.reported.set(fraction);
        progress.report(ProgressUpdate {
            stage,
            step,
            total,
            fraction,
            message,
            loss,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Record(Vec<ProgressUpdate>);

    impl Progress for Record {
        fn report(&mut self, update: ProgressUpdate) -> Result<(), Cancelled> {
            self.0.push(update);
            Ok(())
        }
    }

    #[test]
    fn fractions_follow_stage_weights() {
        let mut stages = Stages::new(&[("a", 3.0), ("b", 1.0)]);
        let mut record = Record(Vec::new());
        stages.enter("a");
        stages
            .report(&mut record, 1, 2, String::new(), None)
            .unwrap();
        stages.enter("b");
        std::thread::sleep(std::time::Duration::from_millis(20));
        stages
            .report(&mut record, 2, 2, String::new(), None)
            .unwrap();
        stages.close();
        stages.close();
        // A second network of the same stage starts its steps again; the fraction holds.
        stages
            .report(&mut record, 1, 2, String::new(), None)
            .unwrap();
        assert!((record.0[0].fraction - 0.375).abs() < 1e-12);
        assert!((record.0[1].fraction - 1.0).abs() < 1e-12);
        assert!((record.0[2].fraction - 1.0).abs() < 1e-12);
        assert_eq!(record.0[1].stage, "b");
        assert_eq!(stages.seconds.len(), 2);
        assert_eq!(stages.seconds[1].0, "b");
        assert!(stages.seconds[1].1 >= 0.02);
    }
}
