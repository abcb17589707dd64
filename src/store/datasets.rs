//! Datasets: named collections of meshes of one organ.

use serde::Serialize;
use utoipa::ToSchema;

use sqlx::AssertSqlSafe;

use super::{Page, Store, StoreError, new_id, now};

/// A dataset as stored.
#[derive(Debug, Clone, Serialize, ToSchema, sqlx::FromRow)]
pub struct Dataset {
    /// Identifier.
    pub id: String,
    /// Name given by the user.
    pub name: String,
    /// Organ the meshes show, e.g. "lv", "liver", "kidney".
    pub organ: String,
    /// Default simplification of uploads: about this many vertices per mesh (none: keep).
    pub target_vertices: Option<i64>,
    /// Number of meshes in the dataset.
    pub mesh_count: i64,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
}

const SELECT_DATASET: &str = "SELECT d.id, d.name, d.organ, d.target_vertices, d.created_at, \
     (SELECT COUNT(*) FROM meshes m WHERE m.dataset_id = d.id) AS mesh_count \
     FROM datasets d";

impl Store {
    /// Creates an empty dataset, optionally with a default simplification target.
    pub async fn create_dataset(
        &self,
        name: &str,
        organ: &str,
        target_vertices: Option<i64>,
    ) -> Result<Dataset, StoreError> {
        let dataset = Dataset {
            id: new_id(),
            name: name.to_owned(),
            organ: organ.to_owned(),
            target_vertices,
            mesh_count: 0,
            created_at: now(),
        };
        sqlx::query(
            "INSERT INTO datasets (id, name, organ, target_vertices, created_at) \
             VALUES ($1, $2, $3, $4, $5)",
        )
        .bind(&dataset.id)
        .bind(&dataset.name)
        .bind(&dataset.organ)
        .bind(dataset.target_vertices)
        .bind(&dataset.created_at)
        .execute(&self.write)
        .await?;
        Ok(dataset)
    }

    /// One dataset with its mesh count.
    pub async fn dataset(&self, id: &str) -> Result<Dataset, StoreError> {
        sqlx::query_as::<_, Dataset>(AssertSqlSafe(format!("{SELECT_DATASET} WHERE d.id = $1")))
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("dataset", id))
    }

    /// A page of datasets, oldest first, and the total count.
    pub async fn datasets(&self, page: Page) -> Result<(Vec<Dataset>, i64), StoreError> {
        let items = sqlx::query_as::<_, Dataset>(AssertSqlSafe(format!(
            "{SELECT_DATASET} ORDER BY {} LIMIT $1 OFFSET $2",
            self.dialect.dataset_order()
        )))
        .bind(page.limit)
        .bind(page.offset)
        .fetch_all(&self.read)
        .await?;
        let total: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM datasets")
            .fetch_one(&self.read)
            .await?;
        Ok((items, total))
    }

    /// Deletes a dataset and its meshes.
    pub async fn delete_dataset(&self, id: &str) -> Result<(), StoreError> {
        let done = sqlx::query("DELETE FROM datasets WHERE id = $1")
            .bind(id)
            .execute(&self.write)
            .await?;
        if done.rows_affected() == 0 {
            return Err(StoreError::not_found("dataset", id));
        }
        Ok(())
    }
}
