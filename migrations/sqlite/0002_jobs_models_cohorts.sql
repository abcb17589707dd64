-- Durable fit jobs, trained models and sampled cohorts.
CREATE TABLE jobs (
    id                TEXT PRIMARY KEY NOT NULL,
    dataset_id        TEXT NOT NULL,
    model_type        TEXT NOT NULL,
    params            TEXT NOT NULL,             -- JSON, validated at submission
    seed              INTEGER NOT NULL,
    holdout_fraction  REAL NOT NULL,
    status            TEXT NOT NULL CHECK (status IN ('queued', 'running', 'succeeded', 'failed', 'cancelled')),
    progress          TEXT NOT NULL,             -- JSON {stage, step, total, fraction, message, loss}
    model_id          TEXT,
    error             TEXT,
    attempts          INTEGER NOT NULL DEFAULT 0,
    max_attempts      INTEGER NOT NULL,
    cancel_requested  INTEGER NOT NULL DEFAULT 0,
    lease_owner       TEXT,
    lease_expires_at  INTEGER,                   -- unix milliseconds
    idempotency_key   TEXT UNIQUE,
    request_hash      TEXT NOT NULL,             -- SHA-256 of the canonical request
    created_at        TEXT NOT NULL,
    started_at        TEXT,
    finished_at       TEXT,
    seq               INTEGER NOT NULL
);
CREATE INDEX jobs_by_status ON jobs (status, seq);

CREATE TABLE models (
    id             TEXT PRIMARY KEY NOT NULL,
    job_id         TEXT NOT NULL,
    dataset_id     TEXT NOT NULL,                -- provenance: kept when the dataset goes
    model_type     TEXT NOT NULL,
    params         TEXT NOT NULL,                -- JSON, with defaults filled in
    seed           INTEGER NOT NULL,
    provenance     TEXT NOT NULL,                -- JSON {training_mesh_ids, holdout_mesh_ids, input_sha256}
    summary        TEXT NOT NULL,                -- JSON: atlas info, evaluation, explained variance, timings
    reference      TEXT NOT NULL,                -- JSON: biomarkers of the training population
    payload        BLOB NOT NULL,                -- the fitted model in binary form
    created_at     TEXT NOT NULL,
    seq            INTEGER NOT NULL
);

CREATE TABLE cohorts (
    id          TEXT PRIMARY KEY NOT NULL,
    model_id    TEXT NOT NULL REFERENCES models(id) ON DELETE CASCADE,
    request     TEXT NOT NULL,                   -- JSON, with defaults filled in
    report      TEXT NOT NULL,                   -- JSON acceptance report
    created_at  TEXT NOT NULL,
    seq         INTEGER NOT NULL
);

CREATE TABLE cohort_members (
    cohort_id   TEXT NOT NULL REFERENCES cohorts(id) ON DELETE CASCADE,
    member      INTEGER NOT NULL,
    summary     TEXT NOT NULL,                   -- JSON {index, draw, biomarkers, accepted, ...}
    geometry    BLOB NOT NULL,                   -- mesh::codec form, mm
    PRIMARY KEY (cohort_id, member)
);
