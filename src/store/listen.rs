//! Wake-ups across processes: on PostgreSQL, a transaction that queues a job sends
//! `NOTIFY cohortforge_jobs` (delivered when it commits) and every worker process LISTENs,
//! so an idle worker on another machine starts a job at once instead of at its next poll.
//! SQLite has no such channel: its workers poll.

use std::sync::Arc;
use std::time::Duration;

use sqlx::postgres::PgListener;
use tokio::sync::Notify;
use tokio_util::sync::CancellationToken;

use super::{Dialect, Store, StoreError};

/// The channel job notifications use.
const CHANNEL: &str = "cohortforge_jobs";
/// Wait before listening again after the connection dropped.
const RECONNECT: Duration = Duration::from_secs(1);

impl Store {
    /// Tells listening worker processes that a job is queued, when `tx` commits
    /// (PostgreSQL; nothing on SQLite).
    pub(crate) async fn notify_job_queued(
        &self,
        tx: &mut sqlx::Transaction<'static, sqlx::Any>,
    ) -> Result<(), StoreError> {
        if self.dialect == Dialect::Postgres {
            sqlx::query(sqlx::AssertSqlSafe(format!("NOTIFY {CHANNEL}")))
                .execute(&mut **tx)
                .await?;
        }
        Ok(())
    }

    /// Until `shutdown`, wakes one waiting worker of this process (`wake`) on every job any
    /// process queues. Returns at once on SQLite.
    pub async fn forward_job_notifications(&self, wake: Arc<Notify>, shutdown: CancellationToken) {
        let Some(url) = self.listen_url.clone() else {
            return;
        };
        while !shutdown.is_cancelled() {
            match listen(&url, &wake, &shutdown).await {
                Ok(()) => return,
                Err(e) => {
                    tracing::warn!(error = %e, "job notifications interrupted; listening again")
                }
            }
            tokio::select! {
                _ = shutdown.cancelled() => return,
                _ = tokio::time::sleep(RECONNECT) => {}
            }
            // Jobs queued while the connection was down are found by the workers' polls.
            wake.notify_waiters();
        }
    }
}

/// Listens until `shutdown` (Ok) or until the connection fails (Err).
async fn listen(url: &str, wake: &Notify, shutdown: &CancellationToken) -> Result<(), sqlx::Error> {
    let mut listener = PgListener::connect(url).await?;
    listener.listen(CHANNEL).await?;
    loop {
        tokio::select! {
            _ = shutdown.cancelled() => return Ok(()),
            received = listener.try_recv() => match received? {
                Some(_) => wake.notify_one(),
                // The connection dropped and was made again: notifications may be lost.
                None => wake.notify_waiters(),
            },
        }
    }
}
