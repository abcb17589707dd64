//! The database: SQLite (one file, the embedded default) or PostgreSQL (shared by API
//! replicas and worker processes on many machines). All SQL lives here, so HTTP handlers
//! and workers share it; statements are one text for both (sqlx's `Any` driver, `$N`
//! placeholders) except the few in [`dialect`].
//!
//! SQLite: one writer connection (SQLite allows one writer at a time; a single connection
//! avoids `SQLITE_BUSY`) and a small pool of readers, both in WAL mode with foreign keys on.
//! Other processes may share the file: write transactions take the write lock when they
//! begin and wait for it up to the busy timeout. PostgreSQL: one pool for reads and writes.

pub mod artefacts;
pub mod cohorts;
pub mod datasets;
pub mod dialect;
mod error;
pub mod jobs;
mod listen;
mod location;
pub mod meshes;
pub mod models;
pub mod queue_stats;

use std::path::Path;
use std::sync::{Arc, Once};
use std::time::Duration;

use sqlx::AnyPool;
use sqlx::any::AnyPoolOptions;
use sqlx::{Any, Executor};

pub use dialect::Dialect;
pub use error::StoreError;
pub use location::Location;

/// How long a connection waits for a lock before failing (SQLite).
const BUSY_TIMEOUT: Duration = Duration::from_secs(10);
/// Reader connections (SQLite).
const READERS: u32 = 4;
/// Connections of a process to PostgreSQL.
const PG_CONNECTIONS: u32 = 8;

/// Handle to the database: cheap to clone.
#[derive(Clone, Debug)]
pub struct Store {
    read: AnyPool,
    write: AnyPool,
    dialect: Dialect,
    /// PostgreSQL URL, for the LISTEN connection.
    listen_url: Option<String>,
    /// Where model payloads are kept.
    artefacts: Arc<dyn artefacts::ArtefactStore>,
}

/// A page of a listing.
#[derive(Debug, Clone, Copy)]
pub struct Page {
    /// Most items to return.
    pub limit: i64,
    /// Items to skip.
    pub offset: i64,
}

impl Store {
    /// Opens (creating if needed) a SQLite file and applies pending migrations.
    pub async fn open(path: &Path) -> Result<Self, StoreError> {
        Self::connect(&Location::Sqlite(path.to_owned())).await
    }

    /// Connects to the database at `location` and applies pending migrations.
    pub async fn connect(location: &Location) -> Result<Self, StoreError> {
        static DRIVERS: Once = Once::new();
        DRIVERS.call_once(sqlx::any::install_default_drivers);
        match location {
            Location::Sqlite(path) => Self::open_sqlite(path).await,
            Location::Postgres(url) => Self::connect_postgres(url).await,
        }
    }

    async fn open_sqlite(path: &Path) -> Result<Self, StoreError> {
        let url = sqlite_url(path)?;
        let write = AnyPoolOptions::new()
            .max_connections(1)
            .after_connect(|conn, _| {
                Box::pin(async move {
                    conn.execute("PRAGMA journal_mode = WAL").await?;
                    sqlite_pragmas(conn).await
                })
            })
            .connect(&format!("{url}?mode=rwc"))
            .await?;
        sqlx::migrate!("./migrations/sqlite").run(&write).await?;
        let read = AnyPoolOptions::new()
            .max_connections(READERS)
            .after_connect(|conn, _| Box::pin(sqlite_pragmas(conn)))
            .connect(&format!("{url}?mode=ro"))
            .await?;
        Ok(Self {
            read,
            write,
            dialect: Dialect::Sqlite,
            listen_url: None,
            artefacts: Arc::new(artefacts::InDatabase),
        })
    }

    async fn connect_postgres(url: &str) -> Result<Self, StoreError> {
        let pool = AnyPoolOptions::new()
            .max_connections(PG_CONNECTIONS)
            .acquire_timeout(BUSY_TIMEOUT)
            .connect(url)
            .await?;
        sqlx::migrate!("./migrations/postgres").run(&pool).await?;
        Ok(Self {
            read: pool.clone(),
            write: pool,
            dialect: Dialect::Postgres,
            listen_url: Some(url.to_owned()),
            artefacts: Arc::new(artefacts::InDatabase),
        })
    }

    /// The database's dialect.
    pub fn dialect(&self) -> Dialect {
        self.dialect
    }

    /// A write transaction. On SQLite it holds the write lock from its first statement
    /// (`BEGIN IMMEDIATE`): a read-then-write transaction (an idempotency key, a duplicate
    /// mesh) cannot interleave with another process's, which waits for the lock instead. On
    /// PostgreSQL such races end in a unique violation, which the callers turn into the
    /// answer the first writer got.
    pub(crate) async fn begin_write(&self) -> Result<sqlx::Transaction<'static, Any>, StoreError> {
        Ok(self.write.begin_with(self.dialect.begin_write()).await?)
    }

    /// Checks that the database answers.
    pub async fn ping(&self) -> Result<(), StoreError> {
        sqlx::query("SELECT 1").execute(&self.read).await?;
        Ok(())
    }

    /// Closes both pools, waiting for open connections.
    pub async fn close(&self) {
        self.write.close().await;
        self.read.close().await;
    }
}

/// Settings every SQLite connection gets: durable commits and a patient lock wait.
async fn sqlite_pragmas(conn: &mut sqlx::AnyConnection) -> Result<(), sqlx::Error> {
    // FULL: every commit reaches the disk before it is acknowledged, so a power cut loses
    // nothing committed (NORMAL could lose the last commits in WAL mode).
    conn.execute("PRAGMA synchronous = FULL").await?;
    conn.execute(sqlx::AssertSqlSafe(format!(
        "PRAGMA busy_timeout = {}",
        BUSY_TIMEOUT.as_millis()
    )))
    .await?;
    Ok(())
}

/// The `sqlite:` URL of a file, absolute, with the characters SQLite's URL reading treats
/// specially escaped.
fn sqlite_url(path: &Path) -> Result<String, StoreError> {
    let absolute = std::path::absolute(path).map_err(|e| {
        StoreError::Database(sqlx::Error::Configuration(
            format!("database path {}: {e}", path.display()).into(),
        ))
    })?;
    let text = absolute.to_str().ok_or_else(|| {
        StoreError::Database(sqlx::Error::Configuration(
            format!("database path {} is not UTF-8", path.display()).into(),
        ))
    })?;
    let mut url = String::from("sqlite:");
    for c in text.chars() {
        match c {
            '%' => url.push_str("%25"),
            '?' => url.push_str("%3F"),
            '#' => url.push_str("%23"),
            ' ' => url.push_str("%20"),
            c => url.push(c),
        }
    }
    Ok(url)
}

/// A new random identifier.
pub(crate) fn new_id() -> String {
    uuid::Uuid::new_v4().to_string()
}

/// The current time as RFC 3339 in UTC with millisecond precision.
pub(crate) fn now() -> String {
    chrono::Utc::now().to_rfc3339_opts(chrono::SecondsFormat::Millis, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn commits_are_durable_and_the_journal_is_wal() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("t #1?.db")).await.unwrap();
        assert!(
            dir.path().join("t #1?.db").exists(),
            "the file keeps its name"
        );
        for pool in [&store.write, &store.read] {
            let synchronous: i64 = sqlx::query_scalar("PRAGMA synchronous")
                .fetch_one(pool)
                .await
                .unwrap();
            assert_eq!(synchronous, 2, "synchronous = FULL");
        }
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode")
            .fetch_one(&store.write)
            .await
            .unwrap();
        assert_eq!(mode, "wal");
        store.close().await;
    }
}
