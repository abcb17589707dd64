//! Reading a directory of mesh files for the offline commands: every OBJ, STL, PLY or VTK
//! file (by extension), sorted by name, through the same parsing and validation as uploads.

use std::path::Path;

use crate::mesh::validate::{IngestOptions, ingest};
use crate::mesh::{Format, Mesh};

/// A mesh with the name of the file it came from.
#[derive(Debug, Clone)]
pub struct NamedMesh {
    /// File name, e.g. `lv_003.obj`.
    pub name: String,
    /// The validated, outward-oriented mesh (mm).
    pub mesh: Mesh,
}

/// Reads every mesh file of `dir` (other files are skipped), sorted by file name.
/// Validation warnings go to stderr; a file that fails validation is an error.
pub fn read_mesh_dir(dir: &Path) -> Result<Vec<NamedMesh>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut files: Vec<(String, Format)> = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| format!("{}: {e}", dir.display()))?;
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        let name = entry.file_name().to_string_lossy().into_owned();
        if let (true, Some(format)) = (is_file, Format::from_file_name(&name)) {
            files.push((name, format));
        }
    }
    if files.is_empty() {
        return Err(format!(
            "{} holds no mesh files (.obj, .stl, .ply, .vtk)",
            dir.display()
        ));
    }
    files.sort_by(|a, b| a.0.cmp(&b.0));
    let options = IngestOptions::default();
    files
        .into_iter()
        .map(|(name, format)| {
            let path = dir.join(&name);
            let bytes = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            let ingested =
                ingest(&bytes, format, &options).map_err(|e| format!("{}: {e}", path.display()))?;
            for warning in &ingested.warnings {
                eprintln!("warning: {name}: {}", warning.message);
            }
            Ok(NamedMesh {
                name,
                mesh: ingested.mesh,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::io;
    use crate::mesh::phantom::{self, Family};

    #[test]
    fn reads_mesh_files_sorted_and_skips_others() {
        let dir = tempfile::tempdir().unwrap();
        let phantoms = phantom::generate(Family::Liver, 2, 5);
        std::fs::write(
            dir.path().join("b.stl"),
            io::write(&phantoms[0].mesh, Format::Stl),
        )
        .unwrap();
        std::fs::write(
            dir.path().join("a.ply"),
            io::write(&phantoms[1].mesh, Format::Ply),
        )
        .unwrap();
        std::fs::write(dir.path().join("params.csv"), "name\n").unwrap();
        let meshes = read_mesh_dir(dir.path()).unwrap();
        let names: Vec<&str> = meshes.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["a.ply", "b.stl"]);
        assert_eq!(meshes[0].mesh.faces.len(), phantoms[1].mesh.faces.len());

        std::fs::write(dir.path().join("c.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
        let err = read_mesh_dir(dir.path()).unwrap_err();
        assert!(err.contains("c.obj"), "{err}");
        let empty = tempfile::tempdir().unwrap();
        assert!(
            read_mesh_dir(empty.path())
                .unwrap_err()
                .contains("no mesh files")
        );
    }
}
