//! Triangle surface meshes in millimetres: the type, file formats, validation, measures
//! and synthetic phantoms. Pure: no async, SQL or HTTP.

pub mod adjacency;
mod clean;
pub mod codec;
pub mod error;
#[cfg(test)]
pub(crate) mod fixtures;
pub mod format;
pub mod io;
pub mod laterality;
mod manifold;
pub mod measures;
mod orient;
pub mod phantom;
pub mod simplify;
pub mod smooth;
pub mod topology;
pub mod validate;

pub use error::MeshError;
pub use format::Format;
pub use laterality::Laterality;

/// A triangle surface mesh.
///
/// Coordinates are in millimetres. Faces are counter-clockwise seen from outside, so that
/// the enclosed volume of a closed, outward-oriented mesh is positive.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Mesh {
    /// Vertex positions in mm, `[n_vertices]` of `[x, y, z]`.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles as indices into `vertices`, `[n_faces]` of `[a, b, c]`.
    pub faces: Vec<[u32; 3]>,
}

impl Mesh {
    /// Builds a mesh from vertex positions (mm) and triangles.
    pub fn new(vertices: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Self {
        Self { vertices, faces }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// Number of triangles.
    pub fn face_count(&self) -> usize {
        self.faces.len()
    }

    /// The three corner positions (mm) of face `f`.
    pub fn triangle(&self, f: usize) -> [[f64; 3]; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }
}
