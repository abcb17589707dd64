//! The few statements that differ between SQLite and PostgreSQL. Everything else in
//! `store` is one SQL text with `$N` placeholders, run through sqlx's `Any` driver.

/// Which database a [`super::Store`] talks to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dialect {
    /// One file, one writer at a time (the embedded default).
    Sqlite,
    /// A server shared by processes on many machines.
    Postgres,
}

impl Dialect {
    /// Statement that opens a write transaction. SQLite's `IMMEDIATE` takes the write lock
    /// at once, so read-then-write transactions of two processes serialise; PostgreSQL
    /// relies on row locks and unique constraints instead.
    pub(crate) fn begin_write(self) -> &'static str {
        match self {
            Self::Sqlite => "BEGIN IMMEDIATE",
            Self::Postgres => "BEGIN",
        }
    }

    /// Expression for the next insertion-order number of `table`: an identity column on
    /// PostgreSQL; the largest so far plus one on SQLite, where the writer holds the lock.
    pub(crate) fn next_seq(self, table: &str) -> String {
        match self {
            Self::Sqlite => format!("(SELECT COALESCE(MAX(seq), 0) + 1 FROM {table})"),
            Self::Postgres => "DEFAULT".to_owned(),
        }
    }

    /// Expression for the database's clock in unix milliseconds, so that leases of
    /// workers on different machines are compared on one clock.
    pub(crate) fn now_ms(self) -> &'static str {
        match self {
            Self::Sqlite => "CAST((julianday('now') - 2440587.5) * 86400000.0 AS INTEGER)",
            Self::Postgres => "CAST(EXTRACT(EPOCH FROM clock_timestamp()) * 1000 AS BIGINT)",
        }
    }

    /// Column giving the creation order of datasets (aliased `d`).
    pub(crate) fn dataset_order(self) -> &'static str {
        match self {
            Self::Sqlite => "d.created_at, d.rowid",
            Self::Postgres => "d.created_at, d.seq",
        }
    }

    /// Clause that makes a claim skip rows another transaction is claiming.
    pub(crate) fn skip_locked(self) -> &'static str {
        match self {
            Self::Sqlite => "",
            Self::Postgres => "FOR UPDATE SKIP LOCKED",
        }
    }
}
