//! Surface mesh file formats and how they are named: by query parameter, content type or
//! file name.

/// A supported surface mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Wavefront OBJ (text).
    Obj,
    /// STL, ASCII or binary.
    Stl,
    /// Stanford PLY, ASCII or binary little-endian.
    Ply,
    /// Legacy VTK, ASCII `DATASET POLYDATA`.
    Vtk,
}

impl Format {
    /// Every supported format, in a stable order.
    pub const ALL: [Format; 4] = [Format::Obj, Format::Stl, Format::Ply, Format::Vtk];

    /// The format named `s` ("obj", "stl", "ply", "vtk"), case-insensitive.
    pub fn from_name(s: &str) -> Option<Format> {
        let s = s.trim();
        Format::ALL
            .into_iter()
            .find(|f| f.extension().eq_ignore_ascii_case(s))
    }

    /// The format of a MIME content type; parameters after `;` are ignored.
    pub fn from_content_type(ct: &str) -> Option<Format> {
        let essence = ct
            .split(';')
            .next()
            .unwrap_or("")
            .trim()
            .to_ascii_lowercase();
        match essence.as_str() {
            "model/obj" | "text/x-obj" | "application/x-tgif" => Some(Format::Obj),
            "model/stl"
            | "model/x.stl-binary"
            | "model/x.stl-ascii"
            | "application/sla"
            | "application/vnd.ms-pki.stl" => Some(Format::Stl),
            "application/x-ply" | "application/ply" | "model/ply" => Some(Format::Ply),
            "application/vnd.vtk" | "application/x-vtk" => Some(Format::Vtk),
            _ => None,
        }
    }

    /// The format of a file name, by its extension (case-insensitive).
    pub fn from_file_name(name: &str) -> Option<Format> {
        let (_, ext) = name.trim().rsplit_once('.')?;
        Format::from_name(ext)
    }

    /// The canonical MIME content type.
    pub fn content_type(self) -> &'static str {
        match self {
            Format::Obj => "model/obj",
            Format::Stl => "model/stl",
            Format::Ply => "application/x-ply",
            Format::Vtk => "application/vnd.vtk",
        }
    }

    /// The file extension without the dot, lowercase.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Obj => "obj",
            Format::Stl => "stl",
            Format::Ply => "ply",
            Format::Vtk => "vtk",
        }
    }

    /// The name users know the format by, for messages ("OBJ", "STL", ...).
    pub fn display_name(self) -> &'static str {
        match self {
            Format::Obj => "OBJ",
            Format::Stl => "STL",
            Format::Ply => "PLY",
            Format::Vtk => "VTK",
        }
    }
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.display_name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_case_insensitive() {
        assert_eq!(Format::from_name("OBJ"), Some(Format::Obj));
        assert_eq!(Format::from_name("Stl"), Some(Format::Stl));
        assert_eq!(Format::from_name("ply"), Some(Format::Ply));
        assert_eq!(Format::from_name("vtk"), Some(Format::Vtk));
        assert_eq!(Format::from_name("off"), None);
        assert_eq!(Format::from_name(""), None);
    }

    #[test]
    fn content_types_with_parameters_and_aliases() {
        assert_eq!(Format::from_content_type("model/obj"), Some(Format::Obj));
        assert_eq!(
            Format::from_content_type("Model/STL; charset=binary"),
            Some(Format::Stl)
        );
        assert_eq!(
            Format::from_content_type("application/sla"),
            Some(Format::Stl)
        );
        assert_eq!(
            Format::from_content_type("application/vnd.ms-pki.stl"),
            Some(Format::Stl)
        );
        assert_eq!(
            Format::from_content_type("model/x.stl-binary"),
            Some(Format::Stl)
        );
        assert_eq!(
            Format::from_content_type("application/ply"),
            Some(Format::Ply)
        );
        assert_eq!(Format::from_content_type("model/ply"), Some(Format::Ply));
        assert_eq!(
            Format::from_content_type("application/x-vtk"),
            Some(Format::Vtk)
        );
        assert_eq!(Format::from_content_type("application/json"), None);
        assert_eq!(Format::from_content_type(""), None);
    }

    #[test]
    fn canonical_content_types_map_back() {
        for f in Format::ALL {
            assert_eq!(Format::from_content_type(f.content_type()), Some(f));
            assert_eq!(Format::from_name(f.extension()), Some(f));
        }
    }

    #[test]
    fn file_names_by_extension() {
        assert_eq!(Format::from_file_name("kidney_01.OBJ"), Some(Format::Obj));
        assert_eq!(Format::from_file_name("a.b.stl"), Some(Format::Stl));
        assert_eq!(Format::from_file_name("scan.ply"), Some(Format::Ply));
        assert_eq!(Format::from_file_name("lv.vtk"), Some(Format::Vtk));
        assert_eq!(Format::from_file_name("obj"), None);
        assert_eq!(Format::from_file_name("mesh.nii.gz"), None);
    }

    #[test]
    fn serde_uses_lowercase_names() {
        assert_eq!(serde_json::to_string(&Format::Ply).unwrap(), "\"ply\"");
        let f: Format = serde_json::from_str("\"vtk\"").unwrap();
        assert_eq!(f, Format::Vtk);
    }
}
