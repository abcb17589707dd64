//! Reading and writing surface meshes in OBJ, STL, PLY and legacy VTK.
//!
//! Readers only parse: they fan-triangulate polygons, enforce [`Limits`] before allocating,
//! reject non-finite coordinates and out-of-range indices. Welding, cleaning and topology
//! checks happen in [`crate::mesh::validate`].

mod build;
mod obj;
mod ply;
mod ply_header;
mod stl;
pub(crate) mod text;
mod vtk;

use super::format::Format;
use super::{Mesh, MeshError};

/// Default largest number of vertices a file may hold.
pub const DEFAULT_MAX_VERTICES: usize = 1_000_000;
/// Default largest number of triangles a file may hold (after triangulating polygons).
pub const DEFAULT_MAX_FACES: usize = 2_000_000;

/// Size limits checked while parsing, before anything large is allocated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest number of vertices.
    pub max_vertices: usize,
    /// Largest number of triangles.
    pub max_faces: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_vertices: DEFAULT_MAX_VERTICES,
            max_faces: DEFAULT_MAX_FACES,
        }
    }
}

/// A mesh as parsed from a file, before welding and validation.
pub type RawMesh = Mesh;

/// Parses `bytes` as `format` into triangles (polygons fan-triangulated).
///
/// Checks indices, finiteness and `limits`, nothing about topology.
pub fn read(bytes: &[u8], format: Format, limits: &Limits) -> Result<Mesh, MeshError> {
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(MeshError::empty(if bytes.is_empty() {
            "the file is empty (0 bytes)"
        } else {
            "the file contains only whitespace"
        }));
    }
    match format {
        Format::Obj => obj::read(bytes, limits),
        Format::Stl => stl::read(bytes, limits),
        Format::Ply => ply::read(bytes, limits),
        Format::Vtk => vtk::read(bytes, limits),
    }
}

/// Encodes `mesh` as `format`: OBJ text, binary STL, binary little-endian PLY, or legacy
/// ASCII VTK 4.2 `POLYDATA`.
pub fn write(mesh: &Mesh, format: Format) -> Vec<u8> {
    match format {
        Format::Obj => obj::write(mesh),
        Format::Stl => stl::write(mesh),
        Format::Ply => ply::write(mesh),
        Format::Vtk => vtk::write(mesh),
    }
}

/// As [`write`], with `provenance` (one line, e.g. the model, seed and member index) kept
/// inside the file where the format has a place for it: the title line of VTK. Other
/// formats are written as by [`write`].
pub fn write_with_provenance(mesh: &Mesh, format: Format, provenance: &str) -> Vec<u8> {
    match format {
        Format::Vtk => vtk::write_titled(mesh, provenance),
        other => write(mesh, other),
    }
}

#[cfg(test)]
mod tests;
