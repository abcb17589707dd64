//! Virtual cohorts: the request, the acceptance report and each member's geometry.

use sqlx::Row;
use sqlx::sqlite::SqliteRow;

use super::{Store, StoreError, new_id, now};
use crate::mesh::{Mesh, codec};

/// A cohort member to store.
#[derive(Debug, Clone)]
pub struct NewMember {
    /// Position in the cohort.
    pub index: usize,
    /// Biomarkers, acceptance flags and draw number (JSON).
    pub summary: serde_json::Value,
    /// The shape.
    pub mesh: Mesh,
}

/// A stored cohort without member geometry.
#[derive(Debug, Clone)]
pub struct CohortRecord {
    /// Identifier.
    pub id: String,
    /// Model it was drawn from.
    pub model_id: String,
    /// The request with defaults filled in (JSON).
    pub request: serde_json::Value,
    /// The acceptance report (JSON).
    pub report: serde_json::Value,
    /// Member summaries in order (JSON).
    pub members: Vec<serde_json::Value>,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
}

fn json(row: &SqliteRow, column: &str) -> Result<serde_json::Value, StoreError> {
    let text: String = row.try_get(column)?;
    serde_json::from_str(&text).map_err(|e| StoreError::Corrupt(format!("cohorts.{column}: {e}")))
}

impl Store {
    /// Stores a cohort and all its members, atomically.
    pub async fn insert_cohort(
        &self,
        model_id: &str,
        request: serde_json::Value,
        report: serde_json::Value,
        members: Vec<NewMember>,
    ) -> Result<String, StoreError> {
        let id = new_id();
        let mut tx = self.write.begin().await?;
        let exists: Option<i64> = sqlx::query_scalar("SELECT 1 FROM models WHERE id = ?")
            .bind(model_id)
            .fetch_optional(&mut *tx)
            .await?;
        if exists.is_none() {
            return Err(StoreError::not_found("model", model_id));
        }
        sqlx::query(
            "INSERT INTO cohorts (id, model_id, request, report, created_at, seq) VALUES \
             (?, ?, ?, ?, ?, (SELECT COALESCE(MAX(seq), 0) + 1 FROM cohorts))",
        )
        .bind(&id)
        .bind(model_id)
        .bind(request.to_string())
        .bind(report.to_string())
        .bind(now())
        .execute(&mut *tx)
        .await?;
        for member in members {
            sqlx::query(
                "INSERT INTO cohort_members (cohort_id, member, summary, geometry) VALUES (?, ?, ?, ?)",
            )
            .bind(&id)
            .bind(member.index as i64)
            .bind(member.summary.to_string())
            .bind(codec::encode(&member.mesh))
            .execute(&mut *tx)
            .await?;
        }
        tx.commit().await?;
        Ok(id)
    }

    /// A cohort with its report and member summaries.
    pub async fn cohort(&self, id: &str) -> Result<CohortRecord, StoreError> {
        let row = sqlx::query(
            "SELECT id, model_id, request, report, created_at FROM cohorts WHERE id = ?",
        )
        .bind(id)
        .fetch_optional(&self.read)
        .await?
        .ok_or_else(|| StoreError::not_found("cohort", id))?;
        let members =
            sqlx::query("SELECT summary FROM cohort_members WHERE cohort_id = ? ORDER BY member")
                .bind(id)
                .fetch_all(&self.read)
                .await?
                .iter()
                .map(|r| json(r, "summary"))
                .collect::<Result<_, _>>()?;
        Ok(CohortRecord {
            id: row.try_get("id")?,
            model_id: row.try_get("model_id")?,
            request: json(&row, "request")?,
            report: json(&row, "report")?,
            members,
            created_at: row.try_get("created_at")?,
        })
    }

    /// One member's shape.
    pub async fn cohort_member_mesh(
        &self,
        cohort_id: &str,
        index: i64,
    ) -> Result<Mesh, StoreError> {
        let blob: Vec<u8> = sqlx::query_scalar(
            "SELECT geometry FROM cohort_members WHERE cohort_id = ? AND member = ?",
        )
        .bind(cohort_id)
        .bind(index)
        .fetch_optional(&self.read)
        .await?
        .ok_or_else(|| StoreError::not_found("cohort member", &format!("{cohort_id}/{index}")))?;
        codec::decode(&blob).map_err(|e| StoreError::Corrupt(format!("cohort member: {e}")))
    }

    /// Every member's shape, in order.
    pub async fn cohort_meshes(&self, cohort_id: &str) -> Result<Vec<Mesh>, StoreError> {
        sqlx::query_scalar::<_, Vec<u8>>(
            "SELECT geometry FROM cohort_members WHERE cohort_id = ? ORDER BY member",
        )
        .bind(cohort_id)
        .fetch_all(&self.read)
        .await?
        .iter()
        .map(|b| codec::decode(b).map_err(|e| StoreError::Corrupt(format!("cohort member: {e}"))))
        .collect()
    }
}
