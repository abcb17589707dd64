-- Where a model payload kept outside the database is (an object store key); NULL when the
-- payload is in the row.
ALTER TABLE models ADD COLUMN payload_ref TEXT;
