-- Member shapes are drawn again from their model when they are downloaded instead of being
-- stored: each member keeps the SHA-256 of its shape's storage form, taken when it was drawn,
-- and a shape drawn again must match it. Members stored before keep their geometry; an empty
-- geometry means "draw again".
ALTER TABLE cohort_members ADD COLUMN mesh_sha256 TEXT;
