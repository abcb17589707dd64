-- Cohorts drawn by the worker pool. A job of kind 'cohort' draws the members of a cohort row
-- created when the request was accepted; such a cohort's status is its job's. Cohorts drawn
-- inside the request have no job and are finished when they are stored.
ALTER TABLE jobs ADD COLUMN kind TEXT NOT NULL DEFAULT 'fit' CHECK (kind IN ('fit', 'cohort'));
ALTER TABLE jobs ADD COLUMN cohort_id TEXT;
ALTER TABLE cohorts ADD COLUMN job_id TEXT;
ALTER TABLE cohorts ADD COLUMN size INTEGER;
CREATE INDEX cohorts_by_job ON cohorts (job_id);
