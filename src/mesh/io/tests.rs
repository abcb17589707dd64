//! Reader and writer tests: round trips for every format and the error codes of bad input.

use super::*;
use crate::mesh::fixtures::{cube, tetrahedron, uv_sphere};

fn limits() -> Limits {
    Limits::default()
}

fn parse(bytes: &[u8], format: Format) -> Mesh {
    read(bytes, format, &limits()).unwrap_or_else(|e| panic!("{format}: {e}"))
}

fn fail(bytes: &[u8], format: Format) -> MeshError {
    match read(bytes, format, &limits()) {
        Ok(m) => panic!(
            "{format}: accepted {} vertices {} faces",
            m.vertices.len(),
            m.faces.len()
        ),
        Err(e) => e,
    }
}

fn close(a: [f64; 3], b: [f64; 3], rel: f64) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() <= rel * a[k].abs().max(b[k].abs()).max(1.0))
}

fn assert_same_triangles(got: &Mesh, want: &Mesh, rel: f64) {
    assert_eq!(got.faces.len(), want.faces.len());
    for f in 0..want.faces.len() {
        let (g, w) = (got.triangle(f), want.triangle(f));
        for k in 0..3 {
            assert!(
                close(g[k], w[k], rel),
                "face {f} corner {k}: {:?} vs {:?}",
                g[k],
                w[k]
            );
        }
    }
}

fn test_meshes() -> Vec<Mesh> {
    let mut odd = uv_sphere(37.3, [-120.25, 4.0e3, 1.0 / 3.0], 16, 24);
    odd.vertices[5][0] = 1.0e-7;
    assert!(odd.vertices.len() > 300);
    vec![tetrahedron(0.25), cube(), odd]
}

#[test]
fn round_trip_exact_formats() {
    for format in [Format::Obj, Format::Ply, Format::Vtk] {
        for m in test_meshes() {
            let back = parse(&write(&m, format), format);
            assert_eq!(back.faces, m.faces, "{format}");
            assert_eq!(
                back.vertices, m.vertices,
                "{format}: coordinates must survive exactly"
            );
        }
    }
}

#[test]
fn round_trip_stl_to_f32_precision() {
    for m in test_meshes() {
        let bytes = write(&m, Format::Stl);
        assert_eq!(bytes.len(), 84 + 50 * m.faces.len());
        assert!(!bytes.starts_with(b"solid"));
        let back = parse(&bytes, Format::Stl);
        assert_eq!(back.vertices.len(), 3 * m.faces.len());
        assert_same_triangles(&back, &m, 1e-5);
    }
}

// ---------- OBJ ----------

#[test]
fn obj_quads_negative_indices_and_slashes() {
    let text = b"# a unit square pyramid\nmtllib x.mtl\no pyramid\nv 0 0 0\nv 1 0 0\n\
        v 1 1 0 1.0\nv 0 1 0 0.5 0.5 0.5\nvt 0 0\nvn 0 0 1\ng base\nusemtl red\ns off\n\
        f 1/1/1 4/1/1 3/1/1 2/1/1\nv 0.5 0.5 1\nf -5//1 -4//1 -1//1\nf 2/1 3/1 5/1\n\
        f -3 -2 -1\r\nf 4 1 5\n";
    let m = parse(text, Format::Obj);
    assert_eq!(m.vertices.len(), 5);
    assert_eq!(m.vertices[2], [1.0, 1.0, 0.0]);
    assert_eq!(
        m.faces,
        vec![
            [0, 3, 2],
            [0, 2, 1],
            [0, 1, 4],
            [1, 2, 4],
            [2, 3, 4],
            [3, 0, 4]
        ]
    );
}

#[test]
fn obj_index_errors_name_the_line() {
    let e = fail(
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 907\n",
        Format::Obj,
    );
    assert_eq!(e.code(), "mesh.index_out_of_range");
    assert_eq!(
        e.to_string(),
        "the 2nd face (line 5) refers to vertex 907 but the file has only 3 vertices (indices \
         are 1-based in OBJ and negative ones count back from the latest vertex); fix the face \
         list or re-export the mesh"
    );
    let e = fail(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", Format::Obj);
    assert!(e.to_string().contains("vertex 0 but"), "{e}");
    let e = fail(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", Format::Obj);
    assert!(
        e.to_string().contains("(line 4) refers to vertex -4"),
        "{e}"
    );
}

#[test]
fn obj_grammar_errors() {
    let e = fail(b"v 0 0 0\nv 1 0\n", Format::Obj);
    assert_eq!(e.code(), "mesh.parse_error");
    assert!(
        e.to_string()
            .contains("at line 2: a 'v' line needs three numbers"),
        "{e}"
    );
    let e = fail(b"v 0 0 0\nhello world\n", Format::Obj);
    assert!(
        e.to_string().contains("'hello' is not an OBJ statement"),
        "{e}"
    );
    let e = fail(b"v 0 0 0\nv 1 0 0\nf 1 2\n", Format::Obj);
    assert!(e.to_string().contains("at least 3 vertices"), "{e}");
    let e = fail(b"v 0 0 0\nf 1 x 2\n", Format::Obj);
    assert!(e.to_string().contains("'x' is not a vertex index"), "{e}");
    assert_eq!(
        fail(b"v 0 0 0\nv nan 0 0\n", Format::Obj).code(),
        "mesh.non_finite"
    );
    assert_eq!(fail(b"# nothing\ng x\n", Format::Obj).code(), "mesh.empty");
    assert_eq!(fail(b"", Format::Obj).code(), "mesh.empty");
    assert_eq!(fail(b" \n\t\n", Format::Obj).code(), "mesh.empty");
    assert_eq!(fail(&garbage(500), Format::Obj).code(), "mesh.parse_error");
}

#[test]
fn obj_vertex_limit() {
    let small = Limits {
        max_vertices: 3,
        max_faces: 10,
    };
    let e = read(b"v 0 0 0\nv 0 0 0\nv 0 0 0\nv 0 0 0\n", Format::Obj, &small).unwrap_err();
    assert_eq!(e.code(), "mesh.too_large");
    assert!(e.to_string().contains("limit of 3"), "{e}");
}

/// Deterministic bytes that look like nothing (a 64-bit LCG).
pub(crate) fn garbage(n: usize) -> Vec<u8> {
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (x >> 33) as u8
        })
        .collect()
}

// ---------- STL ----------

const ASCII_TETRA: &str = "solid tetra\n facet normal 0 0 -1\n  outer loop\n   vertex 0 0 0\n\
   vertex 0 10 0\n   vertex 10 0 0\n  endloop\n endfacet\n\
 FACET NORMAL 0 0 0\n  OUTER LOOP\n   VERTEX 0 0 0\n   VERTEX 10 0 0\n   VERTEX 0 0 10\n  ENDLOOP\n ENDFACET\n\
 facet normal 0 0 0\n  outer loop\n   vertex 0 0 0\n   vertex 0 0 10\n   vertex 0 10 0\n  endloop\n endfacet\n\
 facet normal 1 1 1\n  outer loop\n   vertex 10 0 0\n   vertex 0 10 0\n   vertex 0 0 1e1\n  endloop\n endfacet\n\
endsolid tetra\n";

#[test]
fn stl_ascii_is_read() {
    let m = parse(ASCII_TETRA.as_bytes(), Format::Stl);
    assert_eq!(m.vertices.len(), 12);
    assert_eq!(m.faces[3], [9, 10, 11]);
    assert_eq!(m.vertices[11], [0.0, 0.0, 10.0]);
}

#[test]
fn stl_binary_with_solid_header_is_binary() {
    let mut bytes = write(&tetrahedron(0.0), Format::Stl);
    bytes[..12].copy_from_slice(b"solid tetra ");
    let m = parse(&bytes, Format::Stl);
    assert_same_triangles(&m, &tetrahedron(0.0), 1e-6);
}

#[test]
fn stl_binary_size_and_count_errors() {
    let bytes = write(&cube(), Format::Stl);
    let e = fail(&bytes[..bytes.len() - 20], Format::Stl);
    assert_eq!(e.code(), "mesh.parse_error");
    assert!(
        e.to_string()
            .contains("announces 12 triangles (684 bytes) but the file has only 664"),
        "{e}"
    );
    let mut long = bytes.clone();
    long.extend_from_slice(&[0; 7]);
    assert_eq!(fail(&long, Format::Stl).code(), "mesh.parse_error");
    let mut huge = bytes[..84].to_vec();
    huge[80..84].copy_from_slice(&10_000_000u32.to_le_bytes());
    let e = fail(&huge, Format::Stl);
    assert_eq!(e.code(), "mesh.too_large");
    assert!(
        e.to_string().contains("announces 10000000 triangles"),
        "{e}"
    );
    assert_eq!(fail(b"abc", Format::Stl).code(), "mesh.parse_error");
    let prose =
        "This is a plain text file that is long enough to fill a binary STL header. ".repeat(3);
    let e = fail(prose.as_bytes(), Format::Stl);
    assert!(
        e.to_string().contains("starts with 'This is a plain"),
        "{e}"
    );
    // Random bytes announce a random triangle count: almost surely over the limit.
    let noise = garbage(1000);
    assert!(u32::from_le_bytes([noise[80], noise[81], noise[82], noise[83]]) > 2_000_000);
    assert_eq!(fail(&noise, Format::Stl).code(), "mesh.too_large");
    let mut small_count = noise;
    small_count[80..84].copy_from_slice(&[5, 0, 0, 0]);
    assert_eq!(fail(&small_count, Format::Stl).code(), "mesh.parse_error");
    let empty = parse(
        &bytes[..84]
            .iter()
            .enumerate()
            .map(|(i, &b)| if i >= 80 { 0 } else { b })
            .collect::<Vec<_>>(),
        Format::Stl,
    );
    assert!(empty.faces.is_empty());
}

#[test]
fn stl_ascii_errors() {
    let nan = ASCII_TETRA.replacen("vertex 10 0 0", "vertex NaN 0 0", 1);
    let e = fail(nan.as_bytes(), Format::Stl);
    assert_eq!(e.code(), "mesh.non_finite");
    assert_eq!(
        e.to_string(),
        "corner 3 of the 1st triangle (line 6) has a coordinate that is not a finite number \
         (NaN or infinity); fix that vertex or re-export the mesh"
    );
    let cut = &ASCII_TETRA[..ASCII_TETRA.find("vertex 0 0 1e1").unwrap()];
    assert!(
        fail(cut.as_bytes(), Format::Stl)
            .to_string()
            .contains("truncated")
    );
    let typo = ASCII_TETRA.replacen("endloop", "end loop", 1);
    let e = fail(typo.as_bytes(), Format::Stl);
    assert!(
        e.to_string()
            .contains("at line 7: expected 'vertex' or 'endloop' but found 'end'"),
        "{e}"
    );
}

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
fn binary_ply(index: i32, count_override: Option<u32>) -> Vec<u8> {
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

const VTK_51: &str = "# vtk DataFile Version 5.1\nvtk output\nASCII\nDATASET POLYDATA\n\
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

// ---------- robustness ----------

/// Every prefix and many single-byte corruptions of valid files either parse or fail with
/// an error; none panics.
#[test]
fn truncated_and_corrupted_files_never_panic() {
    let t = tetrahedron(1.0);
    let mut samples: Vec<(Format, Vec<u8>)> =
        Format::ALL.iter().map(|&f| (f, write(&t, f))).collect();
    samples.push((Format::Stl, ASCII_TETRA.as_bytes().to_vec()));
    samples.push((Format::Vtk, VTK_51.as_bytes().to_vec()));
    samples.push((Format::Ply, binary_ply(2, None)));
    let noise = garbage(4096);
    for (format, bytes) in &samples {
        for cut in 0..bytes.len() {
            let _ = read(&bytes[..cut], *format, &limits());
        }
        for (k, pair) in noise.chunks_exact(2).take(300).enumerate() {
            let mut m = bytes.clone();
            let at = (k * 7919 + pair[0] as usize) % m.len();
            m[at] = pair[1];
            let _ = crate::mesh::validate::ingest(&m, *format, &Default::default());
        }
    }
}
