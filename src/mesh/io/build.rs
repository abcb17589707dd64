//! Collects vertices and polygons while a file is parsed: enforces the limits as it goes,
//! fan-triangulates polygons, rejects non-finite coordinates and checks face indices.

use super::Limits;
use super::text::ordinal;
use crate::mesh::format::Format;
use crate::mesh::{Mesh, MeshError};

/// Where an index was used: the 0-based polygon and, for text formats, the line.
#[derive(Debug, Clone, Copy)]
struct Use {
    index: u32,
    polygon: usize,
    line: Option<usize>,
}

/// A mesh under construction from file content.
pub(crate) struct MeshBuilder {
    format: Format,
    limits: Limits,
    /// How the format counts vertices, for messages.
    convention: &'static str,
    /// Added to a 0-based index to show it as written in the file (1 for OBJ).
    index_base: i64,
    vertices: Vec<[f64; 3]>,
    faces: Vec<[u32; 3]>,
    polygons: usize,
    /// The largest vertex index used so far, checked against the vertex count at the end.
    max_use: Option<Use>,
}

impl MeshBuilder {
    /// A builder for `format`, reserving room for at most the limits.
    pub(crate) fn new(
        format: Format,
        limits: &Limits,
        vertex_hint: usize,
        face_hint: usize,
    ) -> Self {
        let (convention, index_base) = match format {
            Format::Obj => (
                "indices are 1-based in OBJ and negative ones count back from the latest vertex",
                1,
            ),
            Format::Ply => ("indices are 0-based in PLY", 0),
            Format::Vtk => ("indices are 0-based in VTK", 0),
            Format::Stl => ("STL has no indices", 0),
        };
        Self {
            format,
            limits: *limits,
            convention,
            index_base,
            vertices: Vec::with_capacity(vertex_hint.min(limits.max_vertices)),
            faces: Vec::with_capacity(face_hint.min(limits.max_faces)),
            polygons: 0,
            max_use: None,
        }
    }

    /// Number of vertices read so far.
    pub(crate) fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// Adds a vertex (mm); `line` locates it in text formats.
    pub(crate) fn push_vertex(
        &mut self,
        v: [f64; 3],
        line: Option<usize>,
    ) -> Result<(), MeshError> {
        if self.vertices.len() >= self.limits.max_vertices {
            return Err(MeshError::TooLarge {
                count: None,
                unit: "vertices",
                limit: self.limits.max_vertices,
                announced: false,
            });
        }
        if !v.iter().all(|c| c.is_finite()) {
            let vertex = format!("the {} vertex", ordinal(self.vertices.len()));
            return Err(MeshError::NonFinite {
                at: located(vertex, line),
            });
        }
        self.vertices.push(v);
        Ok(())
    }

    /// Adds a polygon of 0-based vertex indices, fan-triangulated.
    pub(crate) fn push_polygon(
        &mut self,
        polygon: &[i64],
        line: Option<usize>,
    ) -> Result<(), MeshError> {
        let this = self.polygons;
        self.polygons += 1;
        if polygon.len() < 3 {
            let at = located(format!("the {} face", ordinal(this)), line);
            return Err(MeshError::parse(
                self.format,
                at,
                format!(
                    "a face needs at least 3 vertices but this one has {}; remove it or \
                     re-export the mesh as a surface",
                    polygon.len()
                ),
            ));
        }
        let mut ids = [0u32; 3];
        for (k, &i) in polygon.iter().enumerate() {
            let index = self.check_index(i, this, line)?;
            if k < 3 {
                ids[k] = index;
            }
        }
        if self.faces.len() + polygon.len() - 2 > self.limits.max_faces {
            return Err(MeshError::TooLarge {
                count: None,
                unit: "triangles",
                limit: self.limits.max_faces,
                announced: false,
            });
        }
        self.faces.push(ids);
        for pair in polygon[2..].windows(2) {
            // Indices were checked above, so these conversions cannot fail.
            let (b, c) = (pair[0] as u32, pair[1] as u32);
            self.faces.push([ids[0], b, c]);
        }
        Ok(())
    }

    /// Checks one index for sign and size and remembers the largest.
    fn check_index(
        &mut self,
        i: i64,
        polygon: usize,
        line: Option<usize>,
    ) -> Result<u32, MeshError> {
        let index = match u32::try_from(i) {
            Ok(index) if (index as usize) < self.limits.max_vertices => index,
            _ => {
                return Err(self.out_of_range(i, polygon, line));
            }
        };
        if self.max_use.is_none_or(|m| index > m.index) {
            self.max_use = Some(Use {
                index,
                polygon,
                line,
            });
        }
        Ok(index)
    }

    /// An out-of-range error for the polygon about to be pushed, with the index as written.
    pub(crate) fn index_error(&self, written: i64, line: Option<usize>) -> MeshError {
        self.out_of_range(written - self.index_base, self.polygons, line)
    }

    fn out_of_range(&self, i: i64, polygon: usize, line: Option<usize>) -> MeshError {
        MeshError::IndexOutOfRange {
            at: located(format!("the {} face", ordinal(polygon)), line),
            index: i + self.index_base,
            vertex_count: self.vertices.len(),
            convention: self.convention,
        }
    }

    /// The parsed mesh, after checking every face index against the vertex count.
    pub(crate) fn finish(self) -> Result<Mesh, MeshError> {
        if let Some(u) = self.max_use
            && u.index as usize >= self.vertices.len()
        {
            return Err(self.out_of_range(u.index as i64, u.polygon, u.line));
        }
        Ok(Mesh::new(self.vertices, self.faces))
    }
}

/// "the 3rd face (line 12)" or "the 3rd face".
pub(crate) fn located(what: String, line: Option<usize>) -> String {
    match line {
        Some(l) => format!("{what} (line {l})"),
        None => what,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn builder() -> MeshBuilder {
        let limits = Limits {
            max_vertices: 5,
            max_faces: 3,
        };
        MeshBuilder::new(Format::Ply, &limits, 100, 100)
    }

    #[test]
    fn polygons_are_fans() {
        let mut b = builder();
        for k in 0..5 {
            b.push_vertex([k as f64, 0.0, 0.0], None).unwrap();
        }
        b.push_polygon(&[0, 1, 2, 3, 4], None).unwrap();
        let m = b.finish().unwrap();
        assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }

    #[test]
    fn limits_and_indices() {
        let mut b = builder();
        for _ in 0..5 {
            b.push_vertex([0.0; 3], None).unwrap();
        }
        let e = b.push_vertex([0.0; 3], None).unwrap_err();
        assert_eq!(e.code(), "mesh.too_large");
        let e = b.push_polygon(&[0, 1, 2, 3, 4, 0], Some(9)).unwrap_err();
        assert_eq!(e.code(), "mesh.too_large");
        let e = b.push_polygon(&[0, -1, 2], Some(9)).unwrap_err();
        assert_eq!(e.code(), "mesh.index_out_of_range");
        assert!(
            e.to_string()
                .starts_with("the 2nd face (line 9) refers to vertex -1"),
            "{e}"
        );
    }

    #[test]
    fn late_index_check_names_the_largest() {
        let mut b = builder();
        b.push_polygon(&[0, 1, 2], Some(1)).unwrap();
        b.push_polygon(&[0, 3, 4], Some(2)).unwrap();
        for _ in 0..4 {
            b.push_vertex([0.0; 3], None).unwrap();
        }
        let e = b.finish().unwrap_err();
        assert_eq!(
            e.to_string(),
            "the 2nd face (line 2) refers to vertex 4 but the file has only 4 vertices \
             (indices are 0-based in PLY); fix the face list or re-export the mesh"
        );
    }

    #[test]
    fn non_finite_names_the_vertex() {
        let mut b = builder();
        b.push_vertex([0.0; 3], Some(3)).unwrap();
        let e = b.push_vertex([0.0, f64::NAN, 0.0], Some(4)).unwrap_err();
        assert_eq!(e.code(), "mesh.non_finite");
        assert!(
            e.to_string().starts_with("the 2nd vertex (line 4) has"),
            "{e}"
        );
    }
}
