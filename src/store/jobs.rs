//! Durable fit jobs: submission, atomic claiming with leases, heartbeats, completion.
//!
//! A worker claims the oldest queued job and holds a lease it renews with every progress
//! write. A job whose lease expired (its worker died) is requeued, or failed once it has
//! used all its attempts.

use serde::{Deserialize, Serialize};
use sqlx::Row;
use sqlx::any::AnyRow;
use utoipa::ToSchema;

use sqlx::AssertSqlSafe;

use super::{Page, Store, StoreError, new_id, now};

/// Where a job is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum JobStatus {
    /// Waiting for a worker.
    Queued,
    /// A worker holds it.
    Running,
    /// Finished with a model.
    Succeeded,
    /// Stopped with an error.
    Failed,
    /// Stopped on request.
    Cancelled,
}

impl JobStatus {
    /// The status as stored.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Queued => "queued",
            Self::Running => "running",
            Self::Succeeded => "succeeded",
            Self::Failed => "failed",
            Self::Cancelled => "cancelled",
        }
    }

    pub(crate) fn parse(s: &str) -> Result<Self, StoreError> {
        Ok(match s {
            "queued" => Self::Queued,
            "running" => Self::Running,
            "succeeded" => Self::Succeeded,
            "failed" => Self::Failed,
            "cancelled" => Self::Cancelled,
            other => return Err(StoreError::Corrupt(format!("job status {other}"))),
        })
    }

    /// Whether the job will not change any more.
    pub fn is_final(self) -> bool {
        matches!(self, Self::Succeeded | Self::Failed | Self::Cancelled)
    }
}

/// What a job computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum JobKind {
    /// Fits a model to a dataset (`model_id` is the model it produced).
    #[default]
    Fit,
    /// Draws a cohort from a model (`model_id` is the model drawn from, `cohort_id` the
    /// cohort).
    Cohort,
}

impl JobKind {
    /// The kind as stored.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Fit => "fit",
            Self::Cohort => "cohort",
        }
    }

    fn parse(s: &str) -> Result<Self, StoreError> {
        match s {
            "fit" => Ok(Self::Fit),
            "cohort" => Ok(Self::Cohort),
            other => Err(StoreError::Corrupt(format!("job kind {other}"))),
        }
    }
}

/// Progress of a running job.
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
pub struct JobProgress {
    /// Current stage, e.g. `alignment`, `pca`, `evaluation`.
    pub stage: String,
    /// Steps done in this stage.
    pub step: u64,
    /// Steps in this stage.
    pub total: u64,
    /// Fraction of the whole job done, 0–1.
    pub fraction: f64,
    /// What is happening, in words.
    pub message: String,
    /// Latest training loss, when the stage has one.
    pub loss: Option<f64>,
}

/// A fit job as stored.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct Job {
    /// Identifier.
    pub id: String,
    /// What the job computes: `fit` or `cohort`.
    pub kind: JobKind,
    /// Dataset the model is fitted to.
    pub dataset_id: String,
    /// Model type, e.g. `rsmp`.
    pub model_type: String,
    /// Parameters with defaults filled in.
    #[schema(value_type = Object)]
    pub params: serde_json::Value,
    /// Random seed.
    pub seed: u64,
    /// Share of the dataset's meshes held out for evaluation.
    pub holdout_fraction: f64,
    /// Where the job is.
    pub status: JobStatus,
    /// Progress of the current stage.
    pub progress: JobProgress,
    /// A fit's model, once succeeded; the model a cohort job draws from.
    pub model_id: Option<String>,
    /// The cohort a cohort job draws.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cohort_id: Option<String>,
    /// Why the job failed.
    pub error: Option<String>,
    /// Times a worker started it.
    pub attempts: i64,
    /// Submission time (RFC 3339, UTC).
    pub created_at: String,
    /// First start (RFC 3339, UTC).
    pub started_at: Option<String>,
    /// End time (RFC 3339, UTC).
    pub finished_at: Option<String>,
}

/// A job to submit.
#[derive(Debug, Clone)]
pub struct NewJob {
    /// Dataset to fit.
    pub dataset_id: String,
    /// Model type.
    pub model_type: String,
    /// Validated parameters with defaults filled in.
    pub params: serde_json::Value,
    /// Random seed.
    pub seed: u64,
    /// Share of meshes held out.
    pub holdout_fraction: f64,
    /// Times a worker may start the job before it is failed.
    pub max_attempts: i64,
    /// Client key that makes a retried submission return the same job.
    pub idempotency_key: Option<String>,
    /// SHA-256 of the canonical request, to detect a key reused for another request.
    pub request_hash: String,
}

/// What a heartbeat tells the worker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lease {
    /// Keep going.
    Held,
    /// Cancellation was requested: stop at this checkpoint.
    CancelRequested,
    /// The lease was lost (expired and taken over): stop without writing.
    Lost,
}

const SELECT_JOB: &str = "SELECT id, kind, dataset_id, model_type, params, seed, \
     holdout_fraction, status, progress, model_id, cohort_id, error, attempts, created_at, \
     started_at, finished_at FROM jobs";

fn corrupt(column: &str, e: impl std::fmt::Display) -> StoreError {
    StoreError::Corrupt(format!("jobs.{column}: {e}"))
}

fn job(row: &AnyRow) -> Result<Job, StoreError> {
    let params: String = row.try_get("params")?;
    let progress: String = row.try_get("progress")?;
    let seed: i64 = row.try_get("seed")?;
    Ok(Job {
        id: row.try_get("id")?,
        kind: JobKind::parse(&row.try_get::<String, _>("kind")?)?,
        dataset_id: row.try_get("dataset_id")?,
        model_type: row.try_get("model_type")?,
        params: serde_json::from_str(&params).map_err(|e| corrupt("params", e))?,
        seed: seed as u64,
        holdout_fraction: row.try_get("holdout_fraction")?,
        status: JobStatus::parse(&row.try_get::<String, _>("status")?)?,
        progress: serde_json::from_str(&progress).map_err(|e| corrupt("progress", e))?,
        model_id: row.try_get("model_id")?,
        cohort_id: row.try_get("cohort_id")?,
        error: row.try_get("error")?,
        attempts: row.try_get("attempts")?,
        created_at: row.try_get("created_at")?,
        started_at: row.try_get("started_at")?,
        finished_at: row.try_get("finished_at")?,
    })
}

/// The progress of a job at `stage`, as stored.
fn progress_text(stage: &str, message: &str) -> Result<String, StoreError> {
    serde_json::to_string(&JobProgress {
        stage: stage.into(),
        message: message.into(),
        ..JobProgress::default()
    })
    .map_err(|e| corrupt("progress", e))
}

/// The progress of a job waiting for a worker, as stored.
pub(super) fn queued_progress() -> Result<String, StoreError> {
    progress_text("queued", "waiting for a worker")
}

/// The progress of a finished job: its last progress at fraction 1 with stage `done`.
pub(super) fn done_progress(last: &str, message: &str) -> Result<String, StoreError> {
    let mut progress: JobProgress =
        serde_json::from_str(last).map_err(|e| corrupt("progress", e))?;
    progress.stage = "done".into();
    progress.fraction = 1.0;
    progress.message = message.into();
    serde_json::to_string(&progress).map_err(|e| corrupt("progress", e))
}

impl Store {
    /// Queues a job. With an idempotency key already used for the same request, returns the
    /// existing job and `false`; for another request, [`StoreError::IdempotencyMismatch`].
    pub async fn submit_job(&self, new: NewJob) -> Result<(Job, bool), StoreError> {
        if let Some(found) = self.idempotent_replay(&new).await? {
            return Ok((found, false));
        }
        match self.insert_job(&new).await {
            Ok(created) => Ok((created, true)),
            // Another process inserted the same key meanwhile (PostgreSQL, where the read
            // and the insert do not hold one lock): answer as if it had come first.
            Err(e) if e.is_unique_violation() && new.idempotency_key.is_some() => {
                match self.idempotent_replay(&new).await? {
                    Some(found) => Ok((found, false)),
                    None => Err(e),
                }
            }
            Err(e) => Err(e),
        }
    }

    /// The job already created with `new`'s idempotency key, if any.
    async fn idempotent_replay(&self, new: &NewJob) -> Result<Option<Job>, StoreError> {
        let Some(key) = &new.idempotency_key else {
            return Ok(None);
        };
        let existing = sqlx::query("SELECT id, request_hash FROM jobs WHERE idempotency_key = $1")
            .bind(key)
            .fetch_optional(&self.write)
            .await?;
        let Some(row) = existing else {
            return Ok(None);
        };
        let hash: String = row.try_get("request_hash")?;
        let id: String = row.try_get("id")?;
        if hash != new.request_hash {
            return Err(StoreError::IdempotencyMismatch { existing_id: id });
        }
        Ok(Some(self.job(&id).await?))
    }

    /// Inserts a queued job; returns it as committed (a worker may claim it at once).
    async fn insert_job(&self, new: &NewJob) -> Result<Job, StoreError> {
        let mut tx = self.begin_write().await?;
        let id = new_id();
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO jobs (id, dataset_id, model_type, params, seed, holdout_fraction, status, \
             progress, max_attempts, idempotency_key, request_hash, created_at, seq) \
             VALUES ($1, $2, $3, $4, $5, $6, 'queued', $7, $8, $9, $10, $11, {})",
            self.dialect.next_seq("jobs")
        )))
        .bind(&id)
        .bind(&new.dataset_id)
        .bind(&new.model_type)
        .bind(new.params.to_string())
        .bind(new.seed as i64)
        .bind(new.holdout_fraction)
        .bind(queued_progress()?)
        .bind(new.max_attempts)
        .bind(&new.idempotency_key)
        .bind(&new.request_hash)
        .bind(now())
        .execute(&mut *tx)
        .await?;
        let created = sqlx::query(AssertSqlSafe(format!("{SELECT_JOB} WHERE id = $1")))
            .bind(&id)
            .fetch_one(&mut *tx)
            .await?;
        let created = job(&created)?;
        self.notify_job_queued(&mut tx).await?;
        tx.commit().await?;
        Ok(created)
    }

    /// One job.
    pub async fn job(&self, id: &str) -> Result<Job, StoreError> {
        let row = sqlx::query(AssertSqlSafe(format!("{SELECT_JOB} WHERE id = $1")))
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("job", id))?;
        job(&row)
    }

    /// A page of jobs, newest first, optionally of one status and of one kind.
    pub async fn jobs(
        &self,
        status: Option<JobStatus>,
        kind: Option<JobKind>,
        page: Page,
    ) -> Result<(Vec<Job>, i64), StoreError> {
        let filter = status.map(JobStatus::as_str);
        let kind = kind.map(JobKind::as_str);
        const WHERE: &str = "WHERE ($1 IS NULL OR status = $1) AND ($2 IS NULL OR kind = $2)";
        let rows = sqlx::query(AssertSqlSafe(format!(
            "{SELECT_JOB} {WHERE} ORDER BY seq DESC LIMIT $3 OFFSET $4"
        )))
        .bind(filter)
        .bind(kind)
        .bind(page.limit)
        .bind(page.offset)
        .fetch_all(&self.read)
        .await?;
        let total: i64 =
            sqlx::query_scalar(AssertSqlSafe(format!("SELECT COUNT(*) FROM jobs {WHERE}")))
                .bind(filter)
                .bind(kind)
                .fetch_one(&self.read)
                .await?;
        Ok((rows.iter().map(job).collect::<Result<_, _>>()?, total))
    }

    /// Requeues running jobs whose lease expired on the database's clock, or fails those out
    /// of attempts. Returns how many were requeued and how many failed.
    pub async fn recover_expired_leases(&self) -> Result<(u64, u64), StoreError> {
        let now_ms = self.dialect.now_ms();
        let mut tx = self.begin_write().await?;
        let failed = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET status = 'failed', lease_owner = NULL, lease_expires_at = NULL, \
             finished_at = $1, error = 'the worker running this job stopped ' || attempts || \
             ' times (process crash or restart); giving up' \
             WHERE status = 'running' AND lease_expires_at < {now_ms} AND attempts >= max_attempts"
        )))
        .bind(now())
        .execute(&mut *tx)
        .await?
        .rows_affected();
        let requeued = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET status = CASE WHEN cancel_requested <> 0 THEN 'cancelled' ELSE 'queued' END, \
             lease_owner = NULL, lease_expires_at = NULL \
             WHERE status = 'running' AND lease_expires_at < {now_ms}"
        )))
        .execute(&mut *tx)
        .await?
        .rows_affected();
        if requeued > 0 {
            self.notify_job_queued(&mut tx).await?;
        }
        tx.commit().await?;
        Ok((requeued, failed))
    }

    /// Atomically claims the oldest queued job for `worker`, with a lease of `lease_ms` on
    /// the database's clock. On PostgreSQL, rows another worker is claiming are skipped.
    pub async fn claim_job(&self, worker: &str, lease_ms: i64) -> Result<Option<Job>, StoreError> {
        let row = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET status = 'running', lease_owner = $1, \
             lease_expires_at = {now_ms} + $2, \
             attempts = attempts + 1, started_at = COALESCE(started_at, $3), progress = $4 \
             WHERE id = (SELECT id FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1 {skip}) \
             AND status = 'queued' RETURNING id",
            now_ms = self.dialect.now_ms(),
            skip = self.dialect.skip_locked(),
        )))
        .bind(worker)
        .bind(lease_ms)
        .bind(now())
        .bind(progress_text("starting", "claimed by a worker")?)
        .fetch_optional(&self.write)
        .await?;
        match row {
            Some(row) => Ok(Some(self.job(&row.try_get::<String, _>("id")?).await?)),
            None => Ok(None),
        }
    }

    /// Writes progress and renews the lease; tells the worker whether to go on.
    pub async fn heartbeat(
        &self,
        job_id: &str,
        worker: &str,
        progress: &JobProgress,
        lease_ms: i64,
    ) -> Result<Lease, StoreError> {
        let progress = serde_json::to_string(progress).map_err(|e| corrupt("progress", e))?;
        let row = sqlx::query(AssertSqlSafe(format!(
            "UPDATE jobs SET progress = $1, lease_expires_at = {} + $2 \
             WHERE id = $3 AND lease_owner = $4 AND status = 'running' RETURNING cancel_requested",
            self.dialect.now_ms()
        )))
        .bind(progress)
        .bind(lease_ms)
        .bind(job_id)
        .bind(worker)
        .fetch_optional(&self.write)
        .await?;
        Ok(match row {
            None => Lease::Lost,
            Some(row) if row.try_get::<i64, _>("cancel_requested")? != 0 => Lease::CancelRequested,
            Some(_) => Lease::Held,
        })
    }

    /// Ends a job held by `worker` with a final status. Returns false when the lease was lost.
    pub async fn finish_job(
        &self,
        job_id: &str,
        worker: &str,
        status: JobStatus,
        error: Option<&str>,
    ) -> Result<bool, StoreError> {
        let done = sqlx::query(
            "UPDATE jobs SET status = $1, error = $2, finished_at = $3, lease_owner = NULL, \
             lease_expires_at = NULL WHERE id = $4 AND lease_owner = $5 AND status = 'running'",
        )
        .bind(status.as_str())
        .bind(error)
        .bind(now())
        .bind(job_id)
        .bind(worker)
        .execute(&self.write)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    /// Marks a job held by `worker` succeeded inside `tx`, keeping its last progress at
    /// fraction 1. Returns false (writing nothing) when the lease was lost.
    pub(super) async fn succeed_job_in(
        tx: &mut sqlx::Transaction<'static, sqlx::Any>,
        job_id: &str,
        worker: &str,
        model_id: Option<&str>,
        message: &str,
    ) -> Result<bool, StoreError> {
        let held: Option<String> = sqlx::query_scalar(
            "SELECT progress FROM jobs WHERE id = $1 AND lease_owner = $2 AND status = 'running'",
        )
        .bind(job_id)
        .bind(worker)
        .fetch_optional(&mut **tx)
        .await?;
        let Some(last) = held else {
            return Ok(false);
        };
        let done = sqlx::query(
            "UPDATE jobs SET status = 'succeeded', model_id = COALESCE($1, model_id), \
             finished_at = $2, lease_owner = NULL, lease_expires_at = NULL, progress = $3 \
             WHERE id = $4 AND lease_owner = $5 AND status = 'running'",
        )
        .bind(model_id)
        .bind(now())
        .bind(done_progress(&last, message)?)
        .bind(job_id)
        .bind(worker)
        .execute(&mut **tx)
        .await?;
        Ok(done.rows_affected() == 1)
    }

    /// Gives a job back to the queue without counting the attempt (worker shutting down).
    pub async fn release_job(&self, job_id: &str, worker: &str) -> Result<bool, StoreError> {
        let mut tx = self.begin_write().await?;
        let done = sqlx::query(
            "UPDATE jobs SET status = 'queued', lease_owner = NULL, lease_expires_at = NULL, \
             attempts = CASE WHEN attempts > 0 THEN attempts - 1 ELSE 0 END \
             WHERE id = $1 AND lease_owner = $2 AND status = 'running'",
        )
        .bind(job_id)
        .bind(worker)
        .execute(&mut *tx)
        .await?;
        self.notify_job_queued(&mut tx).await?;
        tx.commit().await?;
        Ok(done.rows_affected() == 1)
    }

    /// Requests cancellation: a queued job is cancelled at once, a running one at its next
    /// checkpoint. A finished job cannot be cancelled.
    pub async fn cancel_job(&self, id: &str) -> Result<Job, StoreError> {
        let current = self.job(id).await?;
        if current.status.is_final() {
            return Err(StoreError::JobFinished {
                id: id.to_owned(),
                status: current.status.as_str(),
            });
        }
        sqlx::query(
            "UPDATE jobs SET cancel_requested = 1, \
             status = CASE WHEN status = 'queued' THEN 'cancelled' ELSE status END, \
             finished_at = CASE WHEN status = 'queued' THEN $1 ELSE finished_at END \
             WHERE id = $2",
        )
        .bind(now())
        .bind(id)
        .execute(&self.write)
        .await?;
        self.job(id).await
    }

    /// Test support: makes a running job's lease look expired, as if its worker had died.
    pub async fn expire_lease(&self, id: &str) -> Result<(), StoreError> {
        sqlx::query("UPDATE jobs SET lease_expires_at = 0 WHERE id = $1 AND status = 'running'")
            .bind(id)
            .execute(&self.write)
            .await?;
        Ok(())
    }
}
