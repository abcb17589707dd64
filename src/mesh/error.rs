//! Why a mesh was rejected, in words a user can act on, with stable codes for clients.

use super::format::Format;

/// A mesh that cannot be read, stored or accepted.
///
/// Each message says what is wrong and how to fix it; [`MeshError::code`] gives the stable
/// machine-readable code clients branch on.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The bytes do not follow the format's grammar (or are truncated).
    #[error("the {format} file could not be read at {at}: {problem}")]
    Parse {
        /// The format the bytes were read as.
        format: Format,
        /// Where the problem was found, e.g. "line 12" or "byte 84".
        at: String,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// A variant of a format (or a dataset type) that is not read.
    #[error("{what} is not supported; {fix}")]
    Unsupported {
        /// The unsupported variant, e.g. "binary big-endian PLY".
        what: String,
        /// How to get a supported file instead.
        fix: String,
    },
    /// Nothing left to make a surface from.
    #[error("{what}; upload a surface mesh with at least one triangle and four vertices")]
    Empty {
        /// What is missing, e.g. "the file is empty (0 bytes)".
        what: String,
    },
    /// A face refers to a vertex that does not exist.
    #[error(
        "{at} refers to vertex {index} but the file has only {vertex_count} vertices \
         ({convention}); fix the face list or re-export the mesh"
    )]
    IndexOutOfRange {
        /// The face, e.g. "line 37 (face 12)" or "face 12".
        at: String,
        /// The index as written in the file.
        index: i64,
        /// How many vertices the file has.
        vertex_count: usize,
        /// How the format counts, e.g. "indices are 1-based in OBJ".
        convention: &'static str,
    },
    /// A coordinate is NaN or infinite.
    #[error(
        "{at} has a coordinate that is not a finite number (NaN or infinity); \
         fix that vertex or re-export the mesh"
    )]
    NonFinite {
        /// The vertex, e.g. "vertex 17" or "line 23 (vertex 17)".
        at: String,
    },
    /// More vertices or faces than the configured limits allow.
    #[error("{}", too_large_message(*count, unit, *limit, *announced))]
    TooLarge {
        /// How many the file holds or announces; `None` when reading stopped at the limit.
        count: Option<u64>,
        /// "vertices", "faces" or "triangles".
        unit: &'static str,
        /// The limit.
        limit: usize,
        /// Whether the count comes from a header rather than from the data.
        announced: bool,
    },
    /// An edge shared by more than two faces, or a face given twice.
    #[error(
        "the surface is not manifold: {detail}; repair the mesh (remove duplicate, \
         overlapping or fin faces) and upload it again"
    )]
    NonManifold {
        /// Which edge or faces, with positions in mm.
        detail: String,
    },
    /// A stored mesh record does not decode.
    #[error("the stored mesh record is corrupt: {detail}; delete the mesh and upload it again")]
    CorruptRecord {
        /// What does not match.
        detail: String,
    },
}

fn too_large_message(count: Option<u64>, unit: &str, limit: usize, announced: bool) -> String {
    let claim = match (count, announced) {
        (Some(n), true) => format!("the file header announces {n} {unit}, more than"),
        (Some(n), false) => format!("the mesh has {n} {unit}, more than"),
        (None, _) => format!("the mesh has more {unit} than"),
    };
    format!(
        "{claim} the limit of {limit}; simplify (decimate) the mesh to at most {limit} {unit} \
         before uploading"
    )
}

impl MeshError {
    /// The stable machine-readable code, e.g. `mesh.parse_error`.
    pub fn code(&self) -> &'static str {
        match self {
            MeshError::Parse { .. } => "mesh.parse_error",
            MeshError::Unsupported { .. } => "mesh.unsupported_format",
            MeshError::Empty { .. } => "mesh.empty",
            MeshError::IndexOutOfRange { .. } => "mesh.index_out_of_range",
            MeshError::NonFinite { .. } => "mesh.non_finite",
            MeshError::TooLarge { .. } => "mesh.too_large",
            MeshError::NonManifold { .. } => "mesh.non_manifold",
            MeshError::CorruptRecord { .. } => "mesh.corrupt_record",
        }
    }

    /// A parse error in `format` at `at` (e.g. "line 3").
    pub(crate) fn parse(format: Format, at: impl Into<String>, problem: impl Into<String>) -> Self {
        MeshError::Parse {
            format,
            at: at.into(),
            problem: problem.into(),
        }
    }

    /// An empty result, with `what` saying what is missing.
    pub(crate) fn empty(what: impl Into<String>) -> Self {
        MeshError::Empty { what: what.into() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_carry_specifics() {
        let e = MeshError::IndexOutOfRange {
            at: "line 37 (face 12)".into(),
            index: 907,
            vertex_count: 900,
            convention: "indices are 1-based in OBJ",
        };
        assert_eq!(e.code(), "mesh.index_out_of_range");
        assert_eq!(
            e.to_string(),
            "line 37 (face 12) refers to vertex 907 but the file has only 900 vertices \
             (indices are 1-based in OBJ); fix the face list or re-export the mesh"
        );
        let e = MeshError::TooLarge {
            count: Some(10_000_000),
            unit: "vertices",
            limit: 1_000_000,
            announced: true,
        };
        assert_eq!(e.code(), "mesh.too_large");
        assert!(e.to_string().starts_with(
            "the file header announces 10000000 vertices, more than the limit of 1000000"
        ));
    }

    #[test]
    fn every_variant_has_a_mesh_code() {
        let all = [
            MeshError::parse(Format::Stl, "byte 84", "x"),
            MeshError::Unsupported {
                what: "a".into(),
                fix: "b".into(),
            },
            MeshError::empty("the file is empty"),
            MeshError::NonFinite {
                at: "vertex 1".into(),
            },
            MeshError::NonManifold { detail: "d".into() },
            MeshError::CorruptRecord { detail: "d".into() },
        ];
        let codes: Vec<&str> = all.iter().map(MeshError::code).collect();
        assert_eq!(
            codes,
            [
                "mesh.parse_error",
                "mesh.unsupported_format",
                "mesh.empty",
                "mesh.non_finite",
                "mesh.non_manifold",
                "mesh.corrupt_record"
            ]
        );
    }
}
