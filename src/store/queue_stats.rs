//! What the queue holds, for monitoring: jobs per status, kind and model type, and how long
//! the oldest queued job has waited.

use sqlx::Row;

use super::{Store, StoreError};

/// Jobs of one status, kind and model type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JobCount {
    /// Status as stored, e.g. `queued`.
    pub status: String,
    /// `fit` or `cohort`.
    pub kind: String,
    /// Model type, e.g. `rsmp`.
    pub model_type: String,
    /// Number of jobs.
    pub count: i64,
}

/// A snapshot of the queue.
#[derive(Debug, Clone, PartialEq)]
pub struct QueueStats {
    /// Every non-empty group of jobs.
    pub jobs: Vec<JobCount>,
    /// Seconds the oldest queued job has waited (0 when none waits).
    pub oldest_queued_seconds: f64,
}

impl Store {
    /// Counts jobs by status, kind and model type, and the wait of the oldest queued one.
    pub async fn queue_stats(&self) -> Result<QueueStats, StoreError> {
        let rows = sqlx::query(
            "SELECT status, kind, model_type, COUNT(*) AS n FROM jobs \
             GROUP BY status, kind, model_type ORDER BY status, kind, model_type",
        )
        .fetch_all(&self.read)
        .await?;
        let jobs = rows
            .iter()
            .map(|r| {
                Ok(JobCount {
                    status: r.try_get("status")?,
                    kind: r.try_get("kind")?,
                    model_type: r.try_get("model_type")?,
                    count: r.try_get("n")?,
                })
            })
            .collect::<Result<_, StoreError>>()?;
        let oldest: Option<String> = sqlx::query_scalar(
            "SELECT created_at FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1",
        )
        .fetch_optional(&self.read)
        .await?;
        let oldest_queued_seconds = match oldest {
            None => 0.0,
            Some(created) => {
                let created = chrono::DateTime::parse_from_rfc3339(&created)
                    .map_err(|e| StoreError::Corrupt(format!("jobs.created_at: {e}")))?;
                let waited = chrono::Utc::now().signed_duration_since(created);
                (waited.num_milliseconds().max(0) as f64) / 1000.0
            }
        };
        Ok(QueueStats {
            jobs,
            oldest_queued_seconds,
        })
    }
}
