-- The side of a paired organ (a left or right kidney) where the user gave it; NULL when not.
ALTER TABLE meshes ADD COLUMN laterality TEXT CHECK (laterality IN ('left', 'right'));
