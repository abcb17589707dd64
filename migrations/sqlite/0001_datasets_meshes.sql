-- Datasets of uploaded surface meshes. Later migrations add jobs, models and cohorts.
CREATE TABLE datasets (
    id          TEXT PRIMARY KEY NOT NULL,
    name        TEXT NOT NULL,
    organ       TEXT NOT NULL,
    created_at  TEXT NOT NULL
);

CREATE TABLE meshes (
    id                    TEXT PRIMARY KEY NOT NULL,
    dataset_id            TEXT NOT NULL REFERENCES datasets(id) ON DELETE CASCADE,
    name                  TEXT NOT NULL,
    source_format         TEXT NOT NULL,
    vertex_count          INTEGER NOT NULL,
    face_count            INTEGER NOT NULL,
    original_vertex_count INTEGER NOT NULL,
    volume_ml             REAL NOT NULL,
    area_cm2              REAL NOT NULL,
    watertight            INTEGER NOT NULL,
    components            INTEGER NOT NULL,
    euler_characteristic  INTEGER NOT NULL,
    bbox_min              TEXT NOT NULL,   -- JSON [x, y, z] in mm
    bbox_max              TEXT NOT NULL,   -- JSON [x, y, z] in mm
    warnings              TEXT NOT NULL,   -- JSON [{code, message}]
    source                TEXT,            -- JSON: how the mesh was derived (e.g. from a label volume)
    sha256                TEXT NOT NULL,   -- of the stored geometry
    geometry              BLOB NOT NULL,   -- mesh::codec form
    created_at            TEXT NOT NULL,
    seq                   INTEGER NOT NULL, -- upload order within the dataset
    UNIQUE (dataset_id, sha256)
);

CREATE INDEX meshes_by_dataset ON meshes (dataset_id, seq);
