//! OBJ and STL reading.

use super::*;
use crate::mesh::fixtures::{cube, tetrahedron};

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

// ---------- STL ----------

pub(super) const ASCII_TETRA: &str = "solid tetra\n facet normal 0 0 -1\n  outer loop\n   vertex 0 0 0\n\
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
