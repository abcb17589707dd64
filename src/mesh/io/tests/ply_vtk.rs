//! PLY and VTK reading.

use super::*;
use crate::mesh::fixtures::tetrahedron;

// ---------- PLY ----------

#[test]
fn ply_ascii_with_extra_properties_and_elements() {
    let text = b"ply\nformat ascii 1.0\ncomment test\nelement vertex 5\nproperty int x\n\
        property uchar red\nproperty float32 y\nproperty double z\nelement edge 1\n\
        property list uchar int ids\nproperty float w\nelement face 2\n\
        property uchar flags\nproperty list uint8 uint32 vertex_index\nend_header\n\
        0 255 0 0\n10 1 0 0\n10 2 10 0\n0 3 10 0\n5 4 5 10.5\n\
        3 0 1 2 0.5\n\
        7 4 0 1 2 3\n1 3 0 1 4\n";
    let m = parse(text, Format::Ply);
    assert_eq!(m.vertices[4], [5.0, 5.0, 10.5]);
    assert_eq!(m.faces, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
}

/// A binary little-endian PLY with float vertices, an extra per-vertex property and a
/// fixed-size element to skip.
pub(super) fn binary_ply(index: i32, count_override: Option<u32>) -> Vec<u8> {
    let n_vertices = count_override.unwrap_or(4);
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {n_vertices}\nproperty float x\n\
         property float y\nproperty float z\nproperty ushort quality\nelement material 2\n\
         property double shininess\nelement face 4\nproperty list uchar int vertex_indices\n\
         end_header\n"
    )
    .into_bytes();
    for v in tetrahedron(0.0).vertices {
        for c in v {
            out.extend_from_slice(&(c as f32).to_le_bytes());
        }
        out.extend_from_slice(&7u16.to_le_bytes());
    }
    out.extend_from_slice(&[0; 16]);
    for (f, face) in tetrahedron(0.0).faces.iter().enumerate() {
        out.push(3);
        for (k, &i) in face.iter().enumerate() {
            let i = if f == 3 && k == 2 { index } else { i as i32 };
            out.extend_from_slice(&i.to_le_bytes());
        }
    }
    out
}

#[test]
fn ply_binary_little_endian() {
    let m = parse(&binary_ply(2, None), Format::Ply);
    assert_eq!(m, tetrahedron(0.0));
}

#[test]
fn ply_errors() {
    let e = fail(&binary_ply(9, None), Format::Ply);
    assert_eq!(e.code(), "mesh.index_out_of_range");
    assert!(
        e.to_string()
            .starts_with("the 4th face refers to vertex 9 but the file has only 4"),
        "{e}"
    );
    assert_eq!(
        fail(&binary_ply(-1, None), Format::Ply).code(),
        "mesh.index_out_of_range"
    );
    let full = binary_ply(2, None);
    let e = fail(&full[..full.len() - 5], Format::Ply);
    assert_eq!(e.code(), "mesh.parse_error");
    assert!(
        e.to_string().contains("ends inside the 4th 'face' element"),
        "{e}"
    );
    let e = fail(&binary_ply(2, Some(10_000_000)), Format::Ply);
    assert_eq!(e.code(), "mesh.too_large");
    assert!(e.to_string().contains("announces 10000000 vertices"), "{e}");
    let big =
        b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n";
    assert_eq!(fail(big, Format::Ply).code(), "mesh.unsupported_format");
    let inf = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
        property float z\nend_header\n0 0 0\n1 inf 0\n";
    let e = fail(inf, Format::Ply);
    assert_eq!(e.code(), "mesh.non_finite");
    assert!(e.to_string().starts_with("the 2nd vertex (line 9)"), "{e}");
    let no_z = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n";
    assert!(
        fail(no_z, Format::Ply)
            .to_string()
            .contains("no scalar property 'z'")
    );
    let words = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
        property float z\nend_header\n0 zero 0\n";
    assert!(
        fail(words, Format::Ply)
            .to_string()
            .contains("property 'y' of the 1st 'vertex' element but found 'zero'")
    );
    assert_eq!(fail(&garbage(300), Format::Ply).code(), "mesh.parse_error");
    let empty_element = b"ply\nformat ascii 1.0\nelement nothing 1000000000000000000\n\
        element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
    assert_eq!(
        parse(empty_element, Format::Ply).vertices,
        vec![[1.0, 2.0, 3.0]]
    );
}

// ---------- VTK ----------

const VTK_CLASSIC: &str = "# vtk DataFile Version 3.0\nsquare pyramid\nASCII\nDATASET POLYDATA\n\
POINTS 5 float\n0 0 0 1 0 0 1 1 0\n0 1 0 0.5 0.5 1\nVERTICES 1 2\n1 4\n\
POLYGONS 3 13\n4 0 3 2 1\n3 0 1 4\n3 1 2 4\nTRIANGLE_STRIPS 1 5\n4 3 0 2 4\n\
POINT_DATA 5\nSCALARS t float 1\nLOOKUP_TABLE default\n0 1 2 3 4\n";

pub(super) const VTK_51: &str = "# vtk DataFile Version 5.1\nvtk output\nASCII\nDATASET POLYDATA\n\
POINTS 5 double\n0 0 0 1 0 0 1 1 0\n0 1 0 0.5 0.5 1\nMETADATA\nINFORMATION 0\n\n\
POLYGONS 4 10\nOFFSETS vtktypeint64\n0 4 7 10\nCONNECTIVITY vtktypeint64\n0 3 2 1 0 1 4 1 2 4\n\
CELL_DATA 3\n";

#[test]
fn vtk_classic_layout_with_strips() {
    let m = parse(VTK_CLASSIC.as_bytes(), Format::Vtk);
    assert_eq!(m.vertices.len(), 5);
    // Strip 3 0 2 4: (3, 0, 2), then (2, 0, 4) with the winding of odd triangles swapped.
    assert_eq!(
        m.faces,
        vec![
            [0, 3, 2],
            [0, 2, 1],
            [0, 1, 4],
            [1, 2, 4],
            [3, 0, 2],
            [2, 0, 4]
        ]
    );
}

#[test]
fn vtk_51_offsets_layout() {
    let m = parse(VTK_51.as_bytes(), Format::Vtk);
    assert_eq!(m.faces, vec![[0, 3, 2], [0, 2, 1], [0, 1, 4], [1, 2, 4]]);
    assert_eq!(m.vertices[4], [0.5, 0.5, 1.0]);
}

#[test]
fn vtk_errors() {
    let binary = VTK_CLASSIC.replace("ASCII", "BINARY");
    assert_eq!(
        fail(binary.as_bytes(), Format::Vtk).code(),
        "mesh.unsupported_format"
    );
    let grid = VTK_CLASSIC.replace("POLYDATA", "UNSTRUCTURED_GRID");
    assert_eq!(
        fail(grid.as_bytes(), Format::Vtk).code(),
        "mesh.unsupported_format"
    );
    let xml = b"<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\">\n";
    assert_eq!(fail(xml, Format::Vtk).code(), "mesh.unsupported_format");
    let no_points =
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOLYGONS 1 4\n3 0 1 2\n";
    let e = fail(no_points.as_bytes(), Format::Vtk);
    assert!(e.to_string().contains("no POINTS section"), "{e}");
    let out = VTK_CLASSIC.replace("3 1 2 4", "3 1 2 5");
    let e = fail(out.as_bytes(), Format::Vtk);
    assert_eq!(e.code(), "mesh.index_out_of_range");
    assert!(
        e.to_string()
            .contains("the 3rd face (line 13) refers to vertex 5"),
        "{e}"
    );
    let short = VTK_CLASSIC.replace("POLYGONS 3 13", "POLYGONS 3 10");
    assert_eq!(
        fail(short.as_bytes(), Format::Vtk).code(),
        "mesh.parse_error"
    );
    let nan = VTK_CLASSIC.replace("0.5 0.5 1", "0.5 nan 1");
    assert_eq!(fail(nan.as_bytes(), Format::Vtk).code(), "mesh.non_finite");
    let huge = VTK_CLASSIC.replace("POINTS 5", "POINTS 10000000");
    assert_eq!(fail(huge.as_bytes(), Format::Vtk).code(), "mesh.too_large");
    assert_eq!(fail(&garbage(400), Format::Vtk).code(), "mesh.parse_error");
    assert_eq!(fail(b"hello", Format::Vtk).code(), "mesh.parse_error");
}

#[test]
fn vtk_field_data_is_skipped() {
    let with_field = VTK_51.replace(
        "POINTS 5 double",
        "FIELD FieldData 2\nTimeValue 1 1 double\n0.5\nMETADATA\nINFORMATION 0\n\n\
         Labels 2 2 int\n1 2 3 4\nPOINTS 5 double",
    );
    let m = parse(with_field.as_bytes(), Format::Vtk);
    assert_eq!(m.faces.len(), 4);
    assert_eq!(m.vertices[1], [1.0, 0.0, 0.0]);
}

#[test]
fn vtk_keeps_a_provenance_title_and_reads_back() {
    let mesh = Mesh::new(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2]],
    );
    let bytes = write_with_provenance(&mesh, Format::Vtk, "cohortforge model=m1 seed=7\nindex=3");
    let text = String::from_utf8(bytes.clone()).unwrap();
    assert_eq!(
        text.lines().nth(1),
        Some("cohortforge model=m1 seed=7 index=3")
    );
    let back = parse(&bytes, Format::Vtk);
    assert_eq!(back.vertices, mesh.vertices);
    let long = "x".repeat(400);
    let text = String::from_utf8(write_with_provenance(&mesh, Format::Vtk, &long)).unwrap();
    assert_eq!(text.lines().nth(1).map(str::len), Some(255));
    assert_eq!(
        write_with_provenance(&mesh, Format::Obj, "p"),
        write(&mesh, Format::Obj)
    );
}
