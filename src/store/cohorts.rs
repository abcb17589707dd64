//! Virtual cohorts: the request, the acceptance report and each member's geometry.

use sqlx::any::AnyRow;
use sqlx::{Any, AssertSqlSafe, Row, Transaction};

use super::jobs::{JobProgress, JobStatus, queued_progress};
use super::{Page, Store, StoreError, new_id, now};
use crate::mesh::{Mesh, codec};

/// A cohort member to store: its shape is not stored but drawn again from the model when
/// asked for, and checked against `mesh_sha256`.
#[derive(Debug, Clone)]
pub struct NewMember {
    /// Position in the cohort.
    pub index: usize,
    /// Biomarkers, acceptance flags and draw number (JSON).
    pub summary: serde_json::Value,
    /// SHA-256 of the shape's storage form ([`codec::sha256_hex`]).
    pub mesh_sha256: String,
}

/// Where a member's shape comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum MemberGeometry {
    /// Stored with the member (cohorts drawn by releases that stored shapes).
    Stored(Mesh),
    /// To be drawn again from the cohort's model and request.
    Redraw {
        /// Draw number of the member.
        draw: u64,
        /// SHA-256 of the shape's storage form when it was first drawn.
        mesh_sha256: String,
    },
}

/// A cohort to be drawn by the worker pool.
#[derive(Debug, Clone)]
pub struct NewCohortJob {
    /// Model to draw from.
    pub model_id: String,
    /// The request with defaults filled in (JSON); the job's parameters.
    pub request: serde_json::Value,
    /// Members asked for.
    pub size: usize,
    /// Seed of the request.
    pub seed: u64,
    /// Times a worker may start the job before it is failed.
    pub max_attempts: i64,
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
    /// The acceptance report (JSON; null until the cohort is drawn).
    pub report: serde_json::Value,
    /// Member summaries in order (JSON): all of them from [`Store::cohort`], none from
    /// [`Store::cohort_head`].
    pub members: Vec<serde_json::Value>,
    /// Members stored.
    pub member_count: usize,
    /// Members asked for.
    pub size: usize,
    /// `succeeded` for a cohort drawn inside its request; its job's status otherwise.
    pub status: JobStatus,
    /// The job drawing it, for a cohort drawn by the worker pool.
    pub job_id: Option<String>,
    /// Progress of the drawing, for a cohort drawn by the worker pool.
    pub progress: Option<JobProgress>,
    /// Why drawing failed.
    pub error: Option<String>,
    /// Creation time (RFC 3339, UTC).
    pub created_at: String,
    /// When drawing ended (RFC 3339, UTC).
    pub finished_at: Option<String>,
}

impl CohortRecord {
    /// The record when its members are drawn, [`StoreError::CohortNotReady`] otherwise.
    pub fn drawn(self) -> Result<Self, StoreError> {
        match self.status {
            JobStatus::Succeeded => Ok(self),
            other => Err(StoreError::CohortNotReady {
                id: self.id,
                status: other.as_str(),
            }),
        }
    }
}

const SELECT_COHORT: &str = "SELECT c.id, c.model_id, c.request, c.report, c.created_at, \
     c.size, c.job_id, j.status AS job_status, j.progress, j.error, \
     COALESCE(j.finished_at, c.created_at) AS finished_at, \
     (SELECT COUNT(*) FROM cohort_members m WHERE m.cohort_id = c.id) AS member_count \
     FROM cohorts c LEFT JOIN jobs j ON j.id = c.job_id";

fn cohort_record(row: &AnyRow) -> Result<CohortRecord, StoreError> {
    let job_id: Option<String> = row.try_get("job_id")?;
    let status = match row.try_get::<Option<String>, _>("job_status")? {
        Some(s) => JobStatus::parse(&s)?,
        None if job_id.is_some() => JobStatus::Failed,
        None => JobStatus::Succeeded,
    };
    let progress = row
        .try_get::<Option<String>, _>("progress")?
        .map(|p| serde_json::from_str(&p))
        .transpose()
        .map_err(|e| StoreError::Corrupt(format!("jobs.progress: {e}")))?;
    let member_count: i64 = row.try_get("member_count")?;
    let size: Option<i64> = row.try_get("size")?;
    Ok(CohortRecord {
        id: row.try_get("id")?,
        model_id: row.try_get("model_id")?,
        request: json(row, "request")?,
        report: json(row, "report")?,
        members: Vec::new(),
        member_count: member_count as usize,
        size: size.map_or(member_count as usize, |s| s as usize),
        finished_at: status
            .is_final()
            .then(|| row.try_get("finished_at"))
            .transpose()?,
        status,
        job_id,
        progress,
        error: row.try_get("error")?,
        created_at: row.try_get("created_at")?,
    })
}

async fn insert_members(
    tx: &mut Transaction<'_, Any>,
    cohort_id: &str,
    members: Vec<NewMember>,
) -> Result<(), StoreError> {
    for member in members {
        sqlx::query(
            "INSERT INTO cohort_members (cohort_id, member, summary, geometry, mesh_sha256) \
             VALUES ($1, $2, $3, $4, $5)",
        )
        .bind(cohort_id)
        .bind(member.index as i64)
        .bind(member.summary.to_string())
        .bind(Vec::<u8>::new())
        .bind(&member.mesh_sha256)
        .execute(&mut **tx)
        .await?;
    }
    Ok(())
}

/// A foreign-key refusal (the model was deleted while the cohort was written) as the
/// model's not-found; other errors unchanged.
fn model_deleted(model_id: &str) -> impl Fn(StoreError) -> StoreError + '_ {
    move |e| {
        if e.is_foreign_key_violation() {
            StoreError::not_found("model", model_id)
        } else {
            e
        }
    }
}

fn json(row: &AnyRow, column: &str) -> Result<serde_json::Value, StoreError> {
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
        let mut tx = self.begin_write().await?;
        let exists: Option<i64> = sqlx::query_scalar("SELECT 1 FROM models WHERE id = $1")
            .bind(model_id)
            .fetch_optional(&mut *tx)
            .await?;
        if exists.is_none() {
            return Err(StoreError::not_found("model", model_id));
        }
        let size = members.len() as i64;
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO cohorts (id, model_id, request, report, created_at, size, seq) VALUES \
             ($1, $2, $3, $4, $5, $6, {})",
            self.dialect.next_seq("cohorts")
        )))
        .bind(&id)
        .bind(model_id)
        .bind(request.to_string())
        .bind(report.to_string())
        .bind(now())
        .bind(size)
        .execute(&mut *tx)
        .await
        .map_err(|e| model_deleted(model_id)(e.into()))?;
        insert_members(&mut tx, &id, members).await?;
        tx.commit().await?;
        Ok(id)
    }

    /// Creates a cohort to be drawn by the worker pool and queues its job, atomically.
    /// Returns the cohort's id.
    pub async fn queue_cohort(&self, new: NewCohortJob) -> Result<String, StoreError> {
        let mut tx = self.begin_write().await?;
        let model = sqlx::query("SELECT dataset_id, model_type FROM models WHERE id = $1")
            .bind(&new.model_id)
            .fetch_optional(&mut *tx)
            .await?
            .ok_or_else(|| StoreError::not_found("model", &new.model_id))?;
        let (id, job_id) = (new_id(), new_id());
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO jobs (id, kind, dataset_id, model_type, params, seed, holdout_fraction, \
             status, progress, model_id, cohort_id, max_attempts, request_hash, created_at, seq) \
             VALUES ($1, 'cohort', $2, $3, $4, $5, 0, 'queued', $6, $7, $8, $9, '', $10, {})",
            self.dialect.next_seq("jobs")
        )))
        .bind(&job_id)
        .bind(model.try_get::<String, _>("dataset_id")?)
        .bind(model.try_get::<String, _>("model_type")?)
        .bind(new.request.to_string())
        .bind(new.seed as i64)
        .bind(queued_progress()?)
        .bind(&new.model_id)
        .bind(&id)
        .bind(new.max_attempts)
        .bind(now())
        .execute(&mut *tx)
        .await?;
        sqlx::query(AssertSqlSafe(format!(
            "INSERT INTO cohorts (id, model_id, request, report, created_at, size, job_id, seq) \
             VALUES ($1, $2, $3, 'null', $4, $5, $6, {})",
            self.dialect.next_seq("cohorts")
        )))
        .bind(&id)
        .bind(&new.model_id)
        .bind(new.request.to_string())
        .bind(now())
        .bind(new.size as i64)
        .bind(&job_id)
        .execute(&mut *tx)
        .await
        .map_err(|e| model_deleted(&new.model_id)(e.into()))?;
        self.notify_job_queued(&mut tx).await?;
        tx.commit().await?;
        Ok(id)
    }

    /// Ends a cohort job held by `worker` with its drawn members, atomically. Returns false
    /// when the lease was lost or the cohort was deleted meanwhile (nothing is written).
    pub async fn complete_cohort_job(
        &self,
        job_id: &str,
        worker: &str,
        cohort_id: &str,
        report: serde_json::Value,
        members: Vec<NewMember>,
    ) -> Result<bool, StoreError> {
        let mut tx = self.begin_write().await?;
        let held = Self::succeed_job_in(&mut tx, job_id, worker, None, "cohort stored").await?;
        let cohort = sqlx::query("UPDATE cohorts SET report = $1 WHERE id = $2 AND job_id = $3")
            .bind(report.to_string())
            .bind(cohort_id)
            .bind(job_id)
            .execute(&mut *tx)
            .await?
            .rows_affected();
        if !held || cohort == 0 {
            return Ok(false);
        }
        insert_members(&mut tx, cohort_id, members).await?;
        tx.commit().await?;
        Ok(true)
    }

    /// A drawn cohort with its report and every member summary;
    /// [`StoreError::CohortNotReady`] while it is not drawn.
    pub async fn cohort(&self, id: &str) -> Result<CohortRecord, StoreError> {
        let mut record = self.cohort_head(id).await?.drawn()?;
        record.members =
            sqlx::query("SELECT summary FROM cohort_members WHERE cohort_id = $1 ORDER BY member")
                .bind(id)
                .fetch_all(&self.read)
                .await?
                .iter()
                .map(|r| json(r, "summary"))
                .collect::<Result<_, _>>()?;
        Ok(record)
    }

    /// A cohort with its report and status, without member summaries.
    pub async fn cohort_head(&self, id: &str) -> Result<CohortRecord, StoreError> {
        let row = sqlx::query(AssertSqlSafe(format!("{SELECT_COHORT} WHERE c.id = $1")))
            .bind(id)
            .fetch_optional(&self.read)
            .await?
            .ok_or_else(|| StoreError::not_found("cohort", id))?;
        cohort_record(&row)
    }

    /// A page of a cohort's member summaries, in member order, with the number of members.
    pub async fn cohort_members(
        &self,
        id: &str,
        page: Page,
    ) -> Result<(Vec<serde_json::Value>, i64), StoreError> {
        let head = self.cohort_head(id).await?.drawn()?;
        let items = sqlx::query(
            "SELECT summary FROM cohort_members WHERE cohort_id = $1 ORDER BY member \
             LIMIT $2 OFFSET $3",
        )
        .bind(id)
        .bind(page.limit)
        .bind(page.offset)
        .fetch_all(&self.read)
        .await?
        .iter()
        .map(|r| json(r, "summary"))
        .collect::<Result<_, _>>()?;
        Ok((items, head.member_count as i64))
    }

    /// Where one member's shape comes from.
    pub async fn cohort_member_geometry(
        &self,
        cohort_id: &str,
        index: i64,
    ) -> Result<MemberGeometry, StoreError> {
        self.cohort_head(cohort_id).await?.drawn()?;
        let row = sqlx::query(
            "SELECT geometry, mesh_sha256, summary FROM cohort_members \
             WHERE cohort_id = $1 AND member = $2",
        )
        .bind(cohort_id)
        .bind(index)
        .fetch_optional(&self.read)
        .await?
        .ok_or_else(|| StoreError::not_found("cohort member", &format!("{cohort_id}/{index}")))?;
        member_geometry(&row)
    }

    /// Where every member's shape comes from, in member order.
    pub async fn cohort_geometries(
        &self,
        cohort_id: &str,
    ) -> Result<Vec<MemberGeometry>, StoreError> {
        self.cohort_head(cohort_id).await?.drawn()?;
        sqlx::query(
            "SELECT geometry, mesh_sha256, summary FROM cohort_members WHERE cohort_id = $1 \
             ORDER BY member",
        )
        .bind(cohort_id)
        .fetch_all(&self.read)
        .await?
        .iter()
        .map(member_geometry)
        .collect()
    }
}

fn member_geometry(row: &AnyRow) -> Result<MemberGeometry, StoreError> {
    let blob: Vec<u8> = row.try_get("geometry")?;
    if !blob.is_empty() {
        return codec::decode(&blob)
            .map(MemberGeometry::Stored)
            .map_err(|e| StoreError::Corrupt(format!("cohort member: {e}")));
    }
    let mesh_sha256: Option<String> = row.try_get("mesh_sha256")?;
    let draw = json(row, "summary")?
        .get("draw")
        .and_then(serde_json::Value::as_u64);
    match (draw, mesh_sha256) {
        (Some(draw), Some(mesh_sha256)) => Ok(MemberGeometry::Redraw { draw, mesh_sha256 }),
        _ => Err(StoreError::Corrupt(
            "cohort member without geometry, draw number or checksum".into(),
        )),
    }
}
