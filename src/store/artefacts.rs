//! Large binary artefacts (model payloads) behind one interface. By default they stay in the
//! database row they belong to, written in the same transaction as the row. An object store
//! (local files or S3, e.g. through the `object_store` crate) implements [`ArtefactStore`]
//! and the row keeps a reference instead; callers of [`Store::complete_job`],
//! [`Store::model_payload`] and [`Store::delete_model`] do not change.

use std::fmt::Debug;
use std::sync::Arc;

use futures_util::future::BoxFuture;

use super::{Store, StoreError};

/// Where an artefact's bytes were put.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Placed {
    /// In the database row (the default).
    InRow(Vec<u8>),
    /// Outside the database, under this reference.
    External(String),
}

/// A place for large artefacts.
pub trait ArtefactStore: Send + Sync + Debug {
    /// Puts the bytes of the artefact named `key` (e.g. `models/{id}`).
    fn put(&self, key: &str, bytes: Vec<u8>) -> BoxFuture<'_, Result<Placed, StoreError>>;
    /// Reads an artefact put outside the database.
    fn get(&self, reference: &str) -> BoxFuture<'_, Result<Vec<u8>, StoreError>>;
    /// Removes an artefact put outside the database.
    fn delete(&self, reference: &str) -> BoxFuture<'_, Result<(), StoreError>>;
}

/// The default: artefacts stay in their database row.
#[derive(Debug, Default)]
pub struct InDatabase;

impl ArtefactStore for InDatabase {
    fn put(&self, _key: &str, bytes: Vec<u8>) -> BoxFuture<'_, Result<Placed, StoreError>> {
        Box::pin(async move { Ok(Placed::InRow(bytes)) })
    }

    fn get(&self, reference: &str) -> BoxFuture<'_, Result<Vec<u8>, StoreError>> {
        let message = format!(
            "artefact {reference} is kept outside the database, but this process has no \
             object store configured"
        );
        Box::pin(async move { Err(StoreError::Corrupt(message)) })
    }

    fn delete(&self, _reference: &str) -> BoxFuture<'_, Result<(), StoreError>> {
        Box::pin(async { Ok(()) })
    }
}

impl Store {
    /// The same database with artefacts kept in `artefacts`.
    pub fn with_artefacts(mut self, artefacts: Arc<dyn ArtefactStore>) -> Self {
        self.artefacts = artefacts;
        self
    }

    /// Reads a payload: from its row, or from the artefact store when the row refers to one.
    pub(super) async fn payload_of(
        &self,
        in_row: Vec<u8>,
        reference: Option<String>,
    ) -> Result<Vec<u8>, StoreError> {
        match reference {
            Some(reference) => self.artefacts.get(&reference).await,
            None => Ok(in_row),
        }
    }

    /// Removes an artefact whose row was not written or is gone; a failure is logged (an
    /// orphaned object wastes space but is never read).
    pub(super) async fn discard(&self, placed: &Placed) {
        if let Placed::External(reference) = placed
            && let Err(e) = self.artefacts.delete(reference).await
        {
            tracing::warn!(error = %e, reference, "an orphaned artefact could not be removed");
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;
    use std::sync::Mutex;

    use super::*;
    use crate::store::jobs::NewJob;
    use crate::store::models::{NewModel, Provenance};

    /// An object store in memory: what a file or S3 store would do, observable.
    #[derive(Debug, Default)]
    struct Objects(Mutex<HashMap<String, Vec<u8>>>);

    impl ArtefactStore for Objects {
        fn put(&self, key: &str, bytes: Vec<u8>) -> BoxFuture<'_, Result<Placed, StoreError>> {
            let reference = format!("mem://{key}");
            self.0.lock().unwrap().insert(reference.clone(), bytes);
            Box::pin(async move { Ok(Placed::External(reference)) })
        }

        fn get(&self, reference: &str) -> BoxFuture<'_, Result<Vec<u8>, StoreError>> {
            let found = self.0.lock().unwrap().get(reference).cloned();
            let reference = reference.to_owned();
            Box::pin(async move { found.ok_or(StoreError::Corrupt(reference)) })
        }

        fn delete(&self, reference: &str) -> BoxFuture<'_, Result<(), StoreError>> {
            self.0.lock().unwrap().remove(reference);
            Box::pin(async { Ok(()) })
        }
    }

    fn model(payload: Vec<u8>) -> NewModel {
        NewModel {
            model_type: "rsmp".into(),
            params: serde_json::json!({}),
            seed: 1,
            dataset_id: "d".into(),
            provenance: Provenance {
                training_mesh_ids: vec![],
                holdout_mesh_ids: vec![],
                training_sha256: vec![],
                holdout_sha256: vec![],
                training_laterality: vec![],
                holdout_laterality: vec![],
            },
            summary: serde_json::json!({}),
            reference: serde_json::json!({"volume_ml": [1.0]}),
            payload,
        }
    }

    async fn running_job(store: &Store, worker: &str) -> String {
        let (job, _) = store
            .submit_job(NewJob {
                dataset_id: "d".into(),
                model_type: "rsmp".into(),
                params: serde_json::json!({}),
                seed: 1,
                holdout_fraction: 0.0,
                max_attempts: 3,
                idempotency_key: None,
                request_hash: String::new(),
            })
            .await
            .unwrap();
        let claimed = store.claim_job(worker, 30_000).await.unwrap().unwrap();
        assert_eq!(claimed.id, job.id);
        job.id
    }

    #[tokio::test]
    async fn payloads_stay_in_the_row_by_default() {
        let dir = tempfile::tempdir().unwrap();
        let store = Store::open(&dir.path().join("a.db")).await.unwrap();
        let job = running_job(&store, "w").await;
        let id = store
            .complete_job(&job, "w", model(vec![7, 8, 9]))
            .await
            .unwrap()
            .unwrap();
        let (payload, reference) = store.model_payload(&id).await.unwrap();
        assert_eq!(payload, vec![7, 8, 9]);
        assert_eq!(reference["volume_ml"][0], 1.0);
    }

    #[tokio::test]
    async fn an_object_store_keeps_payloads_without_changing_callers() {
        let dir = tempfile::tempdir().unwrap();
        let objects = Arc::new(Objects::default());
        let store = Store::open(&dir.path().join("a.db"))
            .await
            .unwrap()
            .with_artefacts(objects.clone());
        let job = running_job(&store, "w").await;
        let id = store
            .complete_job(&job, "w", model(vec![1, 2, 3]))
            .await
            .unwrap()
            .unwrap();
        let key = format!("mem://models/{id}");
        assert_eq!(objects.0.lock().unwrap().get(&key), Some(&vec![1, 2, 3]));
        let in_row: Vec<u8> = sqlx::query_scalar("SELECT payload FROM models WHERE id = $1")
            .bind(&id)
            .fetch_one(&store.read)
            .await
            .unwrap();
        assert!(in_row.is_empty(), "the row keeps only the reference");
        assert_eq!(store.model_payload(&id).await.unwrap().0, vec![1, 2, 3]);

        // A worker that lost its lease stores nothing, in the database or outside it.
        let lost = running_job(&store, "w").await;
        store.expire_lease(&lost).await.unwrap();
        store.recover_expired_leases().await.unwrap();
        assert!(
            store
                .complete_job(&lost, "w", model(vec![4]))
                .await
                .unwrap()
                .is_none()
        );
        assert_eq!(objects.0.lock().unwrap().len(), 1);

        store.delete_model(&id).await.unwrap();
        assert!(
            objects.0.lock().unwrap().is_empty(),
            "deleted with its model"
        );
    }
}
