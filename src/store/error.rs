//! Storage errors.

/// What can go wrong reading or writing the database.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The addressed record does not exist.
    #[error("{entity} {id} does not exist")]
    NotFound {
        /// Kind of record, e.g. "dataset".
        entity: &'static str,
        /// The identifier that was looked up.
        id: String,
    },
    /// The same mesh geometry is already in the dataset.
    #[error("the dataset already holds this geometry as mesh {existing_id} ({existing_name})")]
    DuplicateMesh {
        /// The mesh that holds the same geometry.
        existing_id: String,
        /// Its name.
        existing_name: String,
    },
    /// An idempotency key was reused for a different request.
    #[error("the Idempotency-Key was already used for another request (job {existing_id})")]
    IdempotencyMismatch {
        /// The job created with that key.
        existing_id: String,
    },
    /// The job already ended.
    #[error("job {id} is already {status}")]
    JobFinished {
        /// The job.
        id: String,
        /// Its final status.
        status: &'static str,
    },
    /// The cohort's members are not drawn (yet, or ever).
    #[error("cohort {id} is {status}")]
    CohortNotReady {
        /// The cohort.
        id: String,
        /// Its status.
        status: &'static str,
    },
    /// A stored record could not be decoded: the database was changed outside the service.
    #[error("stored record is corrupt: {0}")]
    Corrupt(String),
    /// The database failed.
    #[error(transparent)]
    Database(#[from] sqlx::Error),
    /// Migrations could not be applied.
    #[error(transparent)]
    Migrate(#[from] sqlx::migrate::MigrateError),
}

impl StoreError {
    /// Whether a unique constraint refused the write: another request stored the same
    /// thing first.
    pub fn is_unique_violation(&self) -> bool {
        matches!(self, Self::Database(sqlx::Error::Database(e)) if e.is_unique_violation())
    }

    /// Whether a foreign key refused the write: what it refers to was deleted meanwhile.
    pub fn is_foreign_key_violation(&self) -> bool {
        matches!(self, Self::Database(sqlx::Error::Database(e)) if e.is_foreign_key_violation())
    }

    pub(crate) fn not_found(entity: &'static str, id: &str) -> Self {
        Self::NotFound {
            entity,
            id: id.to_owned(),
        }
    }
}
