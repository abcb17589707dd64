//! Meshes: validated geometry in compact binary form with its summary.

use serde::Serialize;
use sqlx::any::AnyRow;
use sqlx::{Any, Row, Transaction};
use utoipa::ToSchema;

use sqlx::AssertSqlSafe;

use super::{Page, Store, StoreError, new_id, now};
use crate::mesh::validate::Ingested;
use crate::mesh::{Format, Laterality, Mesh, codec};

/// A mesh to store: validated geometry plus how it arrived.
#[derive(Debug)]
pub struct NewMesh {
    /// Name given by the user or taken from the file name.
    pub name: String,
    /// Format the mesh was uploaded in.
    pub source_format: String,
    /// Validated geometry and its summary.
    pub ingested: Ingested,
    /// How the mesh was derived, when not uploaded as a mesh (JSON).
    pub source: Option<serde_json::Value>,
    /// The side of a paired organ, when the user gave it.
    pub laterality: Option<Laterality>,
}

/// What a fit needs to know of a dataset's mesh before loading its geometry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MeshKey {
    /// Identifier.
    pub id: String,
    /// SHA-256 of the stored geometry (hex).
    pub sha256: String,
    /// The side of a paired organ, when the user gave it.
    pub laterality: Option<Laterality>,
}

/// A stored mesh's metadata (the geometry is fetched separately).
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct MeshRecord {
    /// Identifier.
    pub id: String,
    /// Dataset the mesh belongs to.
    pub dataset_id: String,
    /// Name given by the user or taken from the file name.
    pub name: String,
    /// Format of the uploaded file (`obj`, `stl`, `ply`, `vtk`).
    pub source_format: String,
    /// Vertices after welding duplicates.
    pub vertex_count: i64,
    /// Triangles after removing degenerate ones.
    pub face_count: i64,
    /// Vertices in the uploaded file.
    pub original_vertex_count: i64,
    /// Enclosed volume in ml (meaningful when `watertight`).
    pub volume_ml: f64,
    /// Surface area in cm².
    pub area_cm2: f64,
    /// Every edge is shared by exactly two triangles.
    pub watertight: bool,
    /// Connected components.
    pub components: i64,
    /// V − E + F (2 for a closed surface of genus 0).
    pub euler_characteristic: i64,
    /// Bounding box corner with the smallest coordinates, mm.
    pub bbox_min: [f64; 3],
    /// Bounding box corner with the largest coordinates, mm.
    pub bbox_max: [f64; 3],
    /// SHA-256 of the stored geometry (hex).
    pub sha256: String,
    /// What was repaired or is unusual about the upload.
    pub warnings: Vec<MeshWarning>,
    /// How the mesh was derived, when not uploaded as a mesh.
    #[schema(value_type = Option<Object>)]
    pub source: Option<serde_json::Value>,
    /// The side of a paired organ (`left` or `right` kidney, lung, ...) when the user gave it;
    /// absent otherwise. Models that learn both sides on one (`mirror`) take it as given.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<crate::mesh::Laterality>)]
    pub laterality: Option<Laterality>,
    /// Upload time (RFC 3339, UTC).
    pub created_at: String,
}

/// Something repaired or unusual about an upload; the mesh was stored anyway.
#[derive(Debug, Clone, Serialize, serde::Deserialize, ToSchema)]
pub struct MeshWarning {
    /// Stable code, e.g. `mesh.not_watertight`.
    pub code: String,
    /// What happened, in a sentence.
    pub message: String,
}

const SELECT_MESH: &str = "SELECT id, dataset_id, name, source_format, vertex_count, face_count, \
     original_vertex_count, volume_ml, area_cm2, watertight, components, euler_characteristic, \
     bbox_min, bbox_max, warnings, source, laterality, sha256, created_at FROM meshes";

fn json_column<T: serde::de::DeserializeOwned>(
    row: &AnyRow,
    column: &str,
) -> Result<T, StoreError> {
    let text: String = row.try_get(column)?;
    serde_json::from_str(&text).map_err(|e| StoreError::Corrupt(format!("meshes.{column}: {e}")))
}

fn mesh_record(row: &AnyRow) -> Result<MeshRecord, StoreError> {
    let source: Option<String> = row.try_get("source")?;
    Ok(MeshRecord {
        id: row.try_get("id")?,
        dataset_id: row.try_get("dataset_id")?,
        name: row.try_get("name")?,
        source_format: row.try_get("source_format")?,
        vertex_count: row.try_get("vertex_count")?,
        face_count: row.try_get("face_count")?,
        original_vertex_count: row.try_get("original_vertex_count")?,
        volume_ml: row.try_get("volume_ml")?,
        area_cm2: row.try_get("area_cm2")?,
        watertight: row.try_get::<i64, _>("watertight")? != 0,
        components: row.try_get("components")?,
        euler_characteristic: row.try_get("euler_characteristic")?,
        bbox_min: json_column(row, "bbox_min")?,
        bbox_max: json_column(row, "bbox_max")?,
        warnings: json_column(row, "warnings")?,
        source: source
            .map(|s| serde_json::from_str(&s))
            .transpose()
            .map_err(|e| StoreError::Corrupt(format!("meshes.source: {e}")))?,
        laterality: laterality_column(row)?,
        sha256: row.try_get("sha256")?,
        created_at: row.try_get("created_at")?,
    })
}

fn laterality_column(row: &AnyRow) -> Result<Option<Laterality>, StoreError> {
    let text: Option<String> = row.try_get("laterality")?;
    text.map(|t| t.parse())
        .transpose()
        .map_err(|e| StoreError::Corrupt(format!("meshes.laterality: {e}")))
}

fn to_json<T: Serialize>(value: &T) -> String {
    serde_json::to_string(value).expect("plain data serialises")
}

impl Store {
    /// Stores meshes in a dataset, all or none. A geometry already in the dataset (or twice
    /// in the batch) fails the whole batch with [`StoreError::DuplicateMesh`].
    pub async fn insert_meshes(
        &self,
        dataset_id: &str,
        meshes: Vec<NewMesh>,
    ) -> Result<Vec<MeshRecord>, StoreError> {
        let hashes: Vec<String> = meshes
            .iter()
            .map(|m| codec::sha256_hex(&m.ingested.mesh))
            .collect();
        match self.insert_mesh_batch(dataset_id, meshes).await {
            // Another request stored one of these geometries meanwhile (PostgreSQL, where
            // the duplicate check and the insert do not hold one lock), or deleted the
            // dataset: answer as if it had come first.
            Err(e) if e.is_unique_violation() => Err(self
                .stored_duplicate(dataset_id, &hashes)
                .await?
                .unwrap_or(e)),
            Err(e) if e.is_foreign_key_violation() => {
                Err(StoreError::not_found("dataset", dataset_id))
            }
            other => other,
        }
    }

    async fn insert_mesh_batch(
        &self,
        dataset_id: &str,
        meshes: Vec<NewMesh>,
    ) -> Result<Vec<MeshRecord>, StoreError> {
        let mut tx = self.begin_write().await?;
        let exists: Option<i64> = sqlx::query_scalar("SELECT 1 FROM datasets WHERE id = $1")
            .bind(dataset_id)
            .fetch_optional(&mut *tx)
            .await?;
        if exists.is_none() {
            return Err(StoreError::not_found("dataset", dataset_id));
        }
        let next_seq = self.dialect.next_seq("meshes");
        let mut records = Vec::with_capacity(meshes.len());
        for new in meshes {
            records.push(insert_one(&mut tx, dataset_id, new, &next_seq).await?);
        }
        tx.commit().await?;
        Ok(records)
    }

    /// The first of `hashes` the dataset already holds, as [`StoreError::DuplicateMesh`].
    async fn stored_duplicate(
        &self,
        dataset_id: &str,
        hashes: &[String],
    ) -> Result<Option<StoreError>, StoreError> {
        for sha256 in hashes {
            if let Some(found) = duplicate_of(&self.write, dataset_id, sha256).await? {
                return Ok(Some(found));
            }
        }
        Ok(None)
    }

    /// One mesh's metadata.
    pub async fn mesh(&self, id: &str) -> Result<MeshRecord, StoreError> {
        let row = sqlx::query(AssertSqlSafe(format!("{SELECT_MESH} WHERE id = $1")))
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("mesh", id))?;
        mesh_record(&row)
    }

    /// One mesh's geometry.
    pub async fn mesh_geometry(&self, id: &str) -> Result<Mesh, StoreError> {
        let blob: Vec<u8> = sqlx::query_scalar("SELECT geometry FROM meshes WHERE id = $1")
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("mesh", id))?;
        codec::decode(&blob).map_err(|e| StoreError::Corrupt(format!("mesh {id}: {e}")))
    }

    /// A page of a dataset's meshes in upload order, and the total count.
    pub async fn meshes(
        &self,
        dataset_id: &str,
        page: Page,
    ) -> Result<(Vec<MeshRecord>, i64), StoreError> {
        self.dataset(dataset_id).await?;
        let rows = sqlx::query(AssertSqlSafe(format!(
            "{SELECT_MESH} WHERE dataset_id = $1 ORDER BY seq LIMIT $2 OFFSET $3"
        )))
        .bind(dataset_id)
        .bind(page.limit)
        .bind(page.offset)
        .fetch_all(&self.read)
        .await?;
        let total: i64 = sqlx::query_scalar("SELECT COUNT(*) FROM meshes WHERE dataset_id = $1")
            .bind(dataset_id)
            .fetch_one(&self.read)
            .await?;
        let items = rows.iter().map(mesh_record).collect::<Result<_, _>>()?;
        Ok((items, total))
    }

    /// Id, SHA-256 and side of a dataset's meshes in upload order.
    pub async fn dataset_mesh_keys(&self, dataset_id: &str) -> Result<Vec<MeshKey>, StoreError> {
        self.dataset(dataset_id).await?;
        let rows = sqlx::query(
            "SELECT id, sha256, laterality FROM meshes WHERE dataset_id = $1 ORDER BY seq",
        )
        .bind(dataset_id)
        .fetch_all(&self.read)
        .await?;
        rows.iter()
            .map(|r| {
                Ok(MeshKey {
                    id: r.try_get("id")?,
                    sha256: r.try_get("sha256")?,
                    laterality: laterality_column(r)?,
                })
            })
            .collect()
    }

    /// Sets (or, with `None`, clears) the side of a mesh; the updated record.
    pub async fn set_mesh_laterality(
        &self,
        id: &str,
        laterality: Option<Laterality>,
    ) -> Result<MeshRecord, StoreError> {
        let done = sqlx::query("UPDATE meshes SET laterality = $1 WHERE id = $2")
            .bind(laterality.map(Laterality::as_str))
            .bind(id)
            .execute(&self.write)
            .await?;
        if done.rows_affected() == 0 {
            return Err(StoreError::not_found("mesh", id));
        }
        self.mesh(id).await
    }

    /// Deletes one mesh.
    pub async fn delete_mesh(&self, id: &str) -> Result<(), StoreError> {
        let done = sqlx::query("DELETE FROM meshes WHERE id = $1")
            .bind(id)
            .execute(&self.write)
            .await?;
        if done.rows_affected() == 0 {
            return Err(StoreError::not_found("mesh", id));
        }
        Ok(())
    }
}

/// The mesh of the dataset with geometry `sha256`, as [`StoreError::DuplicateMesh`].
async fn duplicate_of<'e, E: sqlx::Executor<'e, Database = Any>>(
    executor: E,
    dataset_id: &str,
    sha256: &str,
) -> Result<Option<StoreError>, StoreError> {
    let existing = sqlx::query("SELECT id, name FROM meshes WHERE dataset_id = $1 AND sha256 = $2")
        .bind(dataset_id)
        .bind(sha256)
        .fetch_optional(executor)
        .await?;
    existing
        .map(|row| {
            Ok(StoreError::DuplicateMesh {
                existing_id: row.try_get("id")?,
                existing_name: row.try_get("name")?,
            })
        })
        .transpose()
}

async fn insert_one(
    tx: &mut Transaction<'_, Any>,
    dataset_id: &str,
    new: NewMesh,
    next_seq: &str,
) -> Result<MeshRecord, StoreError> {
    let geometry = codec::encode(&new.ingested.mesh);
    let sha256 = codec::sha256_hex(&new.ingested.mesh);
    if let Some(duplicate) = duplicate_of(&mut **tx, dataset_id, &sha256).await? {
        return Err(duplicate);
    }
    let s = &new.ingested.summary;
    let record = MeshRecord {
        id: new_id(),
        dataset_id: dataset_id.to_owned(),
        name: new.name,
        source_format: new.source_format,
        vertex_count: s.vertex_count as i64,
        face_count: s.face_count as i64,
        original_vertex_count: s.original_vertex_count as i64,
        volume_ml: s.volume_ml,
        area_cm2: s.area_cm2,
        watertight: s.watertight,
        components: s.components as i64,
        euler_characteristic: s.euler_characteristic,
        bbox_min: s.bbox_min,
        bbox_max: s.bbox_max,
        sha256,
        warnings: new
            .ingested
            .warnings
            .iter()
            .map(|w| MeshWarning {
                code: w.code.to_owned(),
                message: w.message.clone(),
            })
            .collect(),
        source: new.source,
        laterality: new.laterality,
        created_at: now(),
    };
    sqlx::query(AssertSqlSafe(format!(
        "INSERT INTO meshes (id, dataset_id, name, source_format, vertex_count, face_count, \
         original_vertex_count, volume_ml, area_cm2, watertight, components, \
         euler_characteristic, bbox_min, bbox_max, warnings, source, sha256, geometry, \
         created_at, laterality, seq) VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, \
         $12, $13, $14, $15, $16, $17, $18, $19, $20, {next_seq})"
    )))
    .bind(&record.id)
    .bind(&record.dataset_id)
    .bind(&record.name)
    .bind(&record.source_format)
    .bind(record.vertex_count)
    .bind(record.face_count)
    .bind(record.original_vertex_count)
    .bind(record.volume_ml)
    .bind(record.area_cm2)
    .bind(i64::from(record.watertight))
    .bind(record.components)
    .bind(record.euler_characteristic)
    .bind(to_json(&record.bbox_min))
    .bind(to_json(&record.bbox_max))
    .bind(to_json(&record.warnings))
    .bind(record.source.as_ref().map(to_json))
    .bind(&record.sha256)
    .bind(geometry)
    .bind(&record.created_at)
    .bind(record.laterality.map(Laterality::as_str))
    .execute(&mut **tx)
    .await?;
    Ok(record)
}

/// Format name as stored in `source_format`.
pub fn format_name(format: Format) -> String {
    format.extension().to_owned()
}
