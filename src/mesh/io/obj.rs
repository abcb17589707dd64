//! Wavefront OBJ: `v` and `f` statements (with `v/vt/vn` face syntax and negative indices);
//! every other standard statement is skipped.

use super::Limits;
use super::build::MeshBuilder;
use super::text::{parse_f64, parse_i64, quote, reject_binary, words};
use crate::mesh::format::Format;
use crate::mesh::{Mesh, MeshError};
use std::io::Write;

/// Rough bytes per `v` or `f` line, to size buffers from the file length.
const BYTES_PER_LINE_HINT: usize = 32;

/// OBJ statements that carry no triangle geometry and are skipped.
#[rustfmt::skip]
const SKIPPED_STATEMENTS: &[&[u8]] = &[
    b"vt", b"vn", b"vp", b"l", b"p", b"g", b"o", b"s", b"mg", b"usemtl", b"mtllib",
    b"maplib", b"usemap", b"lod", b"shadow_obj", b"trace_obj", b"bevel", b"c_interp",
    b"d_interp", b"ctech", b"stech", b"cstype", b"deg", b"bmat", b"step", b"curv", b"curv2",
    b"surf", b"parm", b"trim", b"hole", b"scrv", b"sp", b"end", b"con", b"call", b"csh",
];

/// Parses OBJ text.
pub(super) fn read(bytes: &[u8], limits: &Limits) -> Result<Mesh, MeshError> {
    reject_binary(bytes, Format::Obj)?;
    let hint = bytes.len() / BYTES_PER_LINE_HINT;
    let mut b = MeshBuilder::new(Format::Obj, limits, hint, hint);
    let mut polygon: Vec<i64> = Vec::with_capacity(8);
    for (i, raw) in bytes.split(|&c| c == b'\n').enumerate() {
        let line = i + 1;
        let mut w = words(raw);
        let Some(key) = w.next() else { continue };
        match key {
            b"v" => b.push_vertex(vertex(&mut w, line)?, Some(line))?,
            b"f" | b"fo" => {
                polygon.clear();
                for corner in w {
                    polygon.push(resolve(corner, &b, line)?);
                }
                b.push_polygon(&polygon, Some(line))?;
            }
            _ if key.starts_with(b"#") || SKIPPED_STATEMENTS.contains(&key) => {}
            _ => {
                return Err(MeshError::parse(
                    Format::Obj,
                    format!("line {line}"),
                    format!(
                        "{} is not an OBJ statement (expected v, f, vt, vn, g, o, ...); check \
                         that the file really is OBJ",
                        quote(key)
                    ),
                ));
            }
        }
    }
    if b.vertex_count() == 0 {
        return Err(MeshError::empty(
            "the OBJ file defines no vertices ('v' lines)",
        ));
    }
    b.finish()
}

/// The x, y, z of a `v` line (further values such as w or colours are ignored).
fn vertex<'a>(w: &mut impl Iterator<Item = &'a [u8]>, line: usize) -> Result<[f64; 3], MeshError> {
    let mut v = [0.0; 3];
    for (k, c) in v.iter_mut().enumerate() {
        let token = w.next();
        *c = token.and_then(parse_f64).ok_or_else(|| {
            let found = token.map_or("the end of the line".to_string(), quote);
            MeshError::parse(
                Format::Obj,
                format!("line {line}"),
                format!(
                    "a 'v' line needs three numbers x y z, but coordinate {} is {found}; fix \
                     the line or re-export the mesh",
                    k + 1
                ),
            )
        })?;
    }
    Ok(v)
}

/// The 0-based vertex of one face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`.
fn resolve(corner: &[u8], b: &MeshBuilder, line: usize) -> Result<i64, MeshError> {
    let v = corner.split(|&c| c == b'/').next().unwrap_or(corner);
    let written = parse_i64(v).ok_or_else(|| {
        MeshError::parse(
            Format::Obj,
            format!("line {line}"),
            format!(
                "face corner {} is not a vertex index (expected v, v/vt, v//vn or v/vt/vn); \
                 fix the line or re-export the mesh",
                quote(corner)
            ),
        )
    })?;
    let n = b.vertex_count() as i64;
    match written {
        w if w > 0 => Ok(w - 1),
        w if w < 0 && n + w >= 0 => Ok(n + w),
        w => Err(b.index_error(w, Some(line))),
    }
}

/// OBJ text: `v x y z` with shortest round-trip decimals, then 1-based `f a b c`.
pub(super) fn write(mesh: &Mesh) -> Vec<u8> {
    let mut out =
        Vec::with_capacity(BYTES_PER_LINE_HINT * (mesh.vertices.len() + mesh.faces.len()));
    let _ = writeln!(
        out,
        "# cohortforge surface mesh in mm: {} vertices, {} triangles",
        mesh.vertices.len(),
        mesh.faces.len()
    );
    for [x, y, z] in &mesh.vertices {
        let _ = writeln!(out, "v {x:?} {y:?} {z:?}");
    }
    for [a, b, c] in &mesh.faces {
        let _ = writeln!(out, "f {} {} {}", a + 1, b + 1, c + 1);
    }
    out
}
