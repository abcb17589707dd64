-- A dataset may ask for every uploaded mesh to be simplified to about this many vertices.
ALTER TABLE datasets ADD COLUMN target_vertices INTEGER;
