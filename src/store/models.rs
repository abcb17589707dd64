//! Fitted models with provenance, evaluation and reference population, and the job
//! completion that stores them.

use serde::{Deserialize, Serialize};
use sqlx::any::AnyRow;
use sqlx::{AssertSqlSafe, Row};
use utoipa::ToSchema;

use super::artefacts::Placed;
use super::{Page, Store, StoreError, new_id, now};
use crate::mesh::Laterality;

/// Where a model's training data came from.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Provenance {
    /// Meshes the model was fitted to, in order.
    pub training_mesh_ids: Vec<String>,
    /// Meshes held out for evaluation.
    pub holdout_mesh_ids: Vec<String>,
    /// SHA-256 of each training mesh's geometry, in `training_mesh_ids` order.
    pub training_sha256: Vec<String>,
    /// SHA-256 of each held-out mesh's geometry.
    pub holdout_sha256: Vec<String>,
    /// The side of each training mesh when the fit read it (`null` where none was given), in
    /// `training_mesh_ids` order; absent when none was given.
    #[serde(default, skip_serializing_if = "no_side")]
    pub training_laterality: Vec<Option<Laterality>>,
    /// The side of each held-out mesh when the fit read it; absent when none was given.
    #[serde(default, skip_serializing_if = "no_side")]
    pub holdout_laterality: Vec<Option<Laterality>>,
}

fn no_side(sides: &[Option<Laterality>]) -> bool {
    sides.iter().all(Option::is_none)
}

/// A model to store when its job succeeds.
#[derive(Debug, Clone)]
pub struct NewModel {
    /// Model type.
    pub model_type: String,
    /// Parameters with defaults filled in.
    pub params: serde_json::Value,
    /// Seed of the fit.
    pub seed: u64,
    /// Dataset it was fitted to.
    pub dataset_id: String,
    /// Training and holdout meshes.
    pub provenance: Provenance,
    /// Atlas, evaluation, explained variance, timings (JSON).
    pub summary: serde_json::Value,
    /// Biomarkers of the training population (JSON).
    pub reference: serde_json::Value,
    /// The fitted model in binary form.
    pub payload: Vec<u8>,
}

/// A stored model's metadata.
#[derive(Debug, Clone)]
pub struct ModelRecord {
    /// Identifier.
    pub id: String,
    /// Job that fitted it.
    pub job_id: String,
    /// Dataset it was fitted to.
    pub dataset_id: String,
    /// Model type.
    pub model_type: String,
    /// Parameters with defaults filled in.
    pub params: serde_json::Value,
    /// Seed of the fit.
    pub seed: u64,
    /// Training and holdout meshes.
    pub provenance: Provenance,
    /// Atlas, evaluation, explained variance, timings.
    pub summary: serde_json::Value,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
}

const SELECT_MODEL: &str = "SELECT id, job_id, dataset_id, model_type, params, seed, \
     provenance, summary, created_at FROM models";

fn json<T: serde::de::DeserializeOwned>(row: &AnyRow, column: &str) -> Result<T, StoreError> {
    let text: String = row.try_get(column)?;
    serde_json::from_str(&text).map_err(|e| StoreError::Corrupt(format!("models.{column}: {e}")))
}

fn model(row: &AnyRow) -> Result<ModelRecord, StoreError> {
    Ok(ModelRecord {
        id: row.try_get("id")?,
        job_id: row.try_get("job_id")?,
        dataset_id: row.try_get("dataset_id")?,
        model_type: row.try_get("model_type")?,
        params: json(row, "params")?,
        seed: row.try_get::<i64, _>("seed")? as u64,
        provenance: json(row, "provenance")?,
        summary: json(row, "summary")?,
        created_at: row.try_get("created_at")?,
    })
}

fn to_text<T: Serialize>(value: &T) -> Result<String, StoreError> {
    serde_json::to_string(value).map_err(|e| StoreError::Corrupt(e.to_string()))
}

impl Store {
    /// Stores the model of a job held by `worker` and marks the job succeeded, atomically.
    /// Returns `None` (and stores nothing) when the worker lost its lease.
    pub async fn complete_job(
        &self,
        job_id: &str,
        worker: &str,
        mut new: NewModel,
    ) -> Result<Option<String>, StoreError> {
        let id = new_id();
        let payload = std::mem::take(&mut new.payload);
        let placed = self.artefacts.put(&format!("models/{id}"), payload).await?;
        let stored = self.insert_model(job_id, worker, &id, &new, &placed).await;
        if !matches!(stored, Ok(true)) {
            self.discard(&placed).await;
        }
        Ok(stored?.then_some(id))
    }

    /// Marks the job succeeded and writes the model row, in one transaction; false when the
    /// worker lost its lease.
    async fn insert_model(
        &self,
        job_id: &str,
        worker: &str,
        id: &str,
        new: &NewModel,
        placed: &Placed,
    ) -> Result<bool, StoreError> {
        let (payload, payload_ref) = match placed {
            Placed::InRow(bytes) => (bytes.clone(), None),
            Placed::External(reference) => (Vec::new(), Some(reference.clone())),
        };
        let mut tx = self.begin_write().await?;
        if !Self::succeed_job_in(&mut tx, job_id, worker, Some(id), "model stored").await? {
            return Ok(false);
        }
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO models (id, job_id, dataset_id, model_type, params, seed, provenance, \
             summary, reference, payload, payload_ref, created_at, seq) \
             VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, {})",
            self.dialect.next_seq("models")
        )))
        .bind(id)
        .bind(job_id)
        .bind(&new.dataset_id)
        .bind(&new.model_type)
        .bind(new.params.to_string())
        .bind(new.seed as i64)
        .bind(to_text(&new.provenance)?)
        .bind(new.summary.to_string())
        .bind(new.reference.to_string())
        .bind(payload)
        .bind(payload_ref)
        .bind(now())
        .execute(&mut *tx)
        .await?;
        tx.commit().await?;
        Ok(true)
    }

    /// One model's metadata.
    pub async fn model(&self, id: &str) -> Result<ModelRecord, StoreError> {
        let row = sqlx::query(AssertSqlSafe(format!("{SELECT_MODEL} WHERE id = $1")))
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("model", id))?;
        model(&row)
    }

    /// A model's binary payload and reference population (JSON).
    pub async fn model_payload(
        &self,
        id: &str,
    ) -> Result<(Vec<u8>, serde_json::Value), StoreError> {
        let row = sqlx::query("SELECT payload, payload_ref, reference FROM models WHERE id = $1")
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("model", id))?;
        let payload = self
            .payload_of(row.try_get("payload")?, row.try_get("payload_ref")?)
            .await?;
        Ok((payload, json(&row, "reference")?))
    }

    /// A model's reference population (JSON), without its payload.
    pub async fn model_reference(&self, id: &str) -> Result<serde_json::Value, StoreError> {
        let row = sqlx::query("SELECT reference FROM models WHERE id = $1")
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("model", id))?;
        json(&row, "reference")
    }

    /// A page of models, newest first.
    pub async fn models(&self, page: Page) -> Result<(Vec<ModelRecord>, i64), StoreError> {
        let rows = sqlx::query(AssertSqlSafe(format!(
            "{SELECT_MODEL} ORDER BY seq DESC LIMIT $1 OFFSET $2"
        )))
        .bind(page.limit)
        .bind(page.offset)
        .fetch_all(&self.read)
        .await?;
        let total: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM models")
            .fetch_one(&self.read)
            .await?;
        Ok((rows.iter().map(model).collect::<Result<_, _>>()?, total))
    }

    /// Deletes a model and its cohorts.
    pub async fn delete_model(&self, id: &str) -> Result<(), StoreError> {
        let deleted: Option<Option<String>> =
            sqlx::query_scalar("DELETE FROM models WHERE id = $1 RETURNING payload_ref")
                .bind(id)
                .fetch_optional(&self.write)
                .await?;
        match deleted {
            None => Err(StoreError::not_found("model", id)),
            Some(reference) => {
                if let Some(reference) = reference {
                    self.discard(&Placed::External(reference)).await;
                }
                Ok(())
            }
        }
    }
}
