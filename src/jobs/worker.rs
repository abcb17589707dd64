//! The worker pool: OS threads that claim jobs, fit models off the async runtime, and keep
//! their lease alive with a heartbeat task.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use tokio::runtime::Handle;
use tokio::sync::Notify;
use tokio_util::sync::CancellationToken;

use super::run::{JobOutput, RunError, run_job};
use crate::models::ModelError;
use crate::models::progress::{Cancelled, Progress, ProgressUpdate};
use crate::store::Store;
use crate::store::jobs::{Job, JobProgress, JobStatus, Lease};

/// Timing of the pool.
#[derive(Debug, Clone, Copy)]
pub struct WorkerSettings {
    /// Lease length; a job whose worker is silent this long is requeued.
    pub lease: Duration,
    /// Interval of lease renewal and progress writes.
    pub heartbeat: Duration,
    /// Longest wait for work between polls of the queue.
    pub poll: Duration,
}

impl Default for WorkerSettings {
    fn default() -> Self {
        Self {
            lease: Duration::from_secs(30),
            heartbeat: Duration::from_secs(1),
            poll: Duration::from_millis(500),
        }
    }
}

/// Running workers.
pub struct WorkerPool {
    threads: Vec<JoinHandle<()>>,
}

struct Worker {
    id: String,
    store: Store,
    handle: Handle,
    wake: Arc<Notify>,
    shutdown: CancellationToken,
    settings: WorkerSettings,
}

impl WorkerPool {
    /// Starts `count` workers on `handle`'s runtime; `wake` is notified on new jobs.
    pub fn start(
        store: Store,
        count: usize,
        handle: Handle,
        wake: Arc<Notify>,
        shutdown: CancellationToken,
        settings: WorkerSettings,
    ) -> std::io::Result<Self> {
        if count > 0 {
            handle.spawn(recover_leases(
                store.clone(),
                settings.poll,
                shutdown.clone(),
            ));
            let (listener, wake, stop) = (store.clone(), wake.clone(), shutdown.clone());
            handle.spawn(async move { listener.forward_job_notifications(wake, stop).await });
        }
        let instance = uuid::Uuid::new_v4().simple().to_string();
        let mut threads = Vec::with_capacity(count);
        for n in 0..count {
            let worker = Worker {
                id: format!("{}-{n}", &instance[..8]),
                store: store.clone(),
                handle: handle.clone(),
                wake: wake.clone(),
                shutdown: shutdown.clone(),
                settings,
            };
            threads.push(
                std::thread::Builder::new()
                    .name(format!("worker-{n}"))
                    .spawn(move || worker.run())?,
            );
        }
        Ok(Self { threads })
    }

    /// Waits for every worker to stop (after the shutdown token is cancelled).
    pub fn join(self) {
        for t in self.threads {
            let _ = t.join();
        }
    }
}

/// Every `interval`, requeues the jobs of workers whose lease expired (or fails those out
/// of attempts), also while every worker of this pool is busy, so a dead worker's job goes
/// to the next free worker of any process.
async fn recover_leases(store: Store, interval: Duration, shutdown: CancellationToken) {
    loop {
        match store.recover_expired_leases().await {
            Ok((requeued, failed)) if requeued + failed > 0 => {
                tracing::warn!(requeued, failed, "recovered jobs whose worker stopped")
            }
            Ok(_) => {}
            Err(e) => tracing::error!(error = %e, "lease recovery failed"),
        }
        tokio::select! {
            _ = shutdown.cancelled() => return,
            _ = tokio::time::sleep(interval) => {}
        }
    }
}

impl Worker {
    fn run(self) {
        tracing::info!(worker = %self.id, "worker started");
        while !self.shutdown.is_cancelled() {
            let lease_ms = self.settings.lease.as_millis() as i64;
            match self
                .handle
                .block_on(self.store.claim_job(&self.id, lease_ms))
            {
                Ok(Some(job)) => self.execute(job),
                Ok(None) => self.wait(),
                Err(e) => {
                    tracing::error!(error = %e, "claiming a job failed");
                    self.wait();
                }
            }
        }
        tracing::info!(worker = %self.id, "worker stopped");
    }

    fn wait(&self) {
        let (wake, shutdown, poll) = (self.wake.clone(), self.shutdown.clone(), self.settings.poll);
        self.handle.block_on(async move {
            tokio::select! {
                _ = wake.notified() => {}
                _ = shutdown.cancelled() => {}
                _ = tokio::time::sleep(poll) => {}
            }
        });
    }

    fn execute(&self, job: Job) {
        let span = tracing::info_span!("job", job_id = %job.id, kind = job.kind.as_str(), model_type = %job.model_type);
        let _entered = span.enter();
        tracing::info!(attempt = job.attempts, "job started");
        let shared = Arc::new(Mutex::new(job.progress.clone()));
        let flags = Arc::new(Flags::default());
        let heartbeat = CancellationToken::new();
        self.handle.spawn(self.heartbeat(
            job.id.clone(),
            shared.clone(),
            flags.clone(),
            heartbeat.clone(),
        ));
        let mut sink = ProgressSink {
            shared,
            flags: flags.clone(),
        };
        let started = std::time::Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            run_job(&self.handle, &self.store, &job, &mut sink)
        }));
        heartbeat.cancel();
        let finish = |status: JobStatus, error: Option<String>| {
            self.handle.block_on(
                self.store
                    .finish_job(&job.id, &self.id, status, error.as_deref()),
            )
        };
        let (ended, written) = match outcome {
            Ok(Ok(output)) => self.complete(&job, output),
            Ok(Err(RunError::Model(ModelError::Cancelled(_))))
                if flags.shutdown.load(Ordering::SeqCst) =>
            {
                let released = self.store.release_job(&job.id, &self.id);
                ("released", self.handle.block_on(released))
            }
            Ok(Err(RunError::Model(ModelError::Cancelled(_)))) => {
                ("cancelled", finish(JobStatus::Cancelled, None))
            }
            Ok(Err(e)) => ("failed", finish(JobStatus::Failed, Some(e.to_string()))),
            Err(panic) => {
                let what = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_default();
                tracing::error!(panic = %what, "job panicked");
                let error = format!("internal error during the job: {what}");
                ("failed", finish(JobStatus::Failed, Some(error)))
            }
        };
        let outcome = match written {
            Ok(true) => ended,
            Ok(false) => "lease_lost",
            Err(_) => "not_recorded",
        };
        crate::telemetry::record_job_run(
            job.kind.as_str(),
            &job.model_type,
            outcome,
            started.elapsed().as_secs_f64(),
        );
        match written {
            Ok(true) => tracing::info!("job ended"),
            Ok(false) => tracing::warn!("job ended after its lease was lost; result discarded"),
            Err(e) => tracing::error!(error = %e, "could not record the end of the job"),
        }
    }

    /// Stores what a job produced: the job's final status, and false when the lease was
    /// lost.
    fn complete(
        &self,
        job: &Job,
        output: JobOutput,
    ) -> (&'static str, Result<bool, crate::store::StoreError>) {
        let failed = |error: &str| {
            let finished = self
                .store
                .finish_job(&job.id, &self.id, JobStatus::Failed, Some(error));
            ("failed", self.handle.block_on(finished))
        };
        match (output, job.cohort_id.as_deref()) {
            (JobOutput::Model(model), _) => {
                let stored = self.store.complete_job(&job.id, &self.id, *model);
                (
                    "succeeded",
                    self.handle.block_on(stored).map(|m| m.is_some()),
                )
            }
            (JobOutput::Cohort(drawn), Some(cohort_id)) => {
                let stored = self.handle.block_on(self.store.complete_cohort_job(
                    &job.id,
                    &self.id,
                    cohort_id,
                    drawn.report,
                    drawn.members,
                ));
                match stored {
                    Ok(false) => failed("the cohort was deleted while it was drawn"),
                    other => ("succeeded", other),
                }
            }
            (JobOutput::Cohort(_), None) => failed("a cohort job without a cohort"),
        }
    }

    fn heartbeat(
        &self,
        job_id: String,
        shared: Arc<Mutex<JobProgress>>,
        flags: Arc<Flags>,
        stop: CancellationToken,
    ) -> impl Future<Output = ()> + Send + 'static {
        let (store, worker, settings, shutdown) = (
            self.store.clone(),
            self.id.clone(),
            self.settings,
            self.shutdown.clone(),
        );
        async move {
            let lease_ms = settings.lease.as_millis() as i64;
            loop {
                tokio::select! {
                    _ = stop.cancelled() => return,
                    _ = shutdown.cancelled() => {
                        flags.shutdown.store(true, Ordering::SeqCst);
                        flags.cancel.store(true, Ordering::SeqCst);
                        return;
                    }
                    _ = tokio::time::sleep(settings.heartbeat) => {}
                }
                let progress = shared.lock().map(|p| p.clone()).unwrap_or_default();
                match store.heartbeat(&job_id, &worker, &progress, lease_ms).await {
                    Ok(Lease::Held) => {}
                    Ok(Lease::CancelRequested | Lease::Lost) => {
                        flags.cancel.store(true, Ordering::SeqCst)
                    }
                    Err(e) => tracing::warn!(error = %e, "heartbeat failed"),
                }
            }
        }
    }
}

#[derive(Default)]
struct Flags {
    cancel: AtomicBool,
    shutdown: AtomicBool,
}

/// Receives the fit's progress on the worker thread; the heartbeat task writes it.
struct ProgressSink {
    shared: Arc<Mutex<JobProgress>>,
    flags: Arc<Flags>,
}

impl Progress for ProgressSink {
    fn report(&mut self, update: ProgressUpdate) -> Result<(), Cancelled> {
        if let Ok(mut p) = self.shared.lock() {
            *p = JobProgress {
                stage: update.stage.to_owned(),
                step: update.step,
                total: update.total,
                fraction: update.fraction,
                message: update.message,
                loss: update.loss,
            };
        }
        if self.flags.cancel.load(Ordering::SeqCst) {
            Err(Cancelled)
        } else {
            Ok(())
        }
    }
}
