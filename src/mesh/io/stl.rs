//! STL, ASCII and binary. Every triangle carries its own three corners, so the mesh comes
//! back unwelded (`3 · n_triangles` vertices); welding happens during validation.

use super::Limits;
use super::text::{Tokens, parse_f64, quote, reject_binary};
use crate::mesh::format::Format;
use crate::mesh::measures::{cross, norm, sub};
use crate::mesh::{Mesh, MeshError};

/// Bytes of the free-form header of a binary STL.
const HEADER_BYTES: usize = 80;
/// Header plus the little-endian `u32` triangle count.
const PREAMBLE_BYTES: usize = 84;
/// Normal, three corners (12 × f32) and the `u16` attribute.
const TRIANGLE_BYTES: usize = 50;
/// Header written by [`write`]; it must not start with "solid".
const WRITTEN_HEADER: &[u8] = b"cohortforge binary STL, coordinates in mm";

/// Parses ASCII or binary STL, telling them apart by size and leading "solid".
pub(super) fn read(bytes: &[u8], limits: &Limits) -> Result<Mesh, MeshError> {
    let sized_binary = bytes.len() >= PREAMBLE_BYTES
        && announced(bytes) * TRIANGLE_BYTES as u64 + PREAMBLE_BYTES as u64 == bytes.len() as u64;
    let starts_solid = bytes
        .trim_ascii_start()
        .get(..5)
        .is_some_and(|s| s.eq_ignore_ascii_case(b"solid"));
    // Some binary files start with "solid" too; their float data is never plain text.
    let is_text = reject_binary(bytes, Format::Stl).is_ok();
    if starts_solid && (!sized_binary || is_text) {
        read_ascii(bytes, limits)
    } else if is_text && !sized_binary {
        let first = bytes.split(|&c| c == b'\n').next().unwrap_or(bytes);
        Err(MeshError::parse(
            Format::Stl,
            "line 1",
            format!(
                "the file is text but starts with {} instead of 'solid', so it is neither an \
                 ASCII nor a binary STL; check that the file really is STL",
                quote(first.trim_ascii())
            ),
        ))
    } else {
        read_binary(bytes, limits)
    }
}

/// The triangle count in a binary header (`bytes` has at least 84 bytes).
fn announced(bytes: &[u8]) -> u64 {
    let mut n = [0u8; 4];
    n.copy_from_slice(&bytes[HEADER_BYTES..PREAMBLE_BYTES]);
    u32::from_le_bytes(n) as u64
}

fn read_binary(bytes: &[u8], limits: &Limits) -> Result<Mesh, MeshError> {
    if bytes.len() < PREAMBLE_BYTES {
        return Err(MeshError::parse(
            Format::Stl,
            "byte 0",
            format!(
                "the file has only {} bytes, less than the 84-byte header of a binary STL, and \
                 does not start with 'solid' like an ASCII STL; check that the file really is STL",
                bytes.len()
            ),
        ));
    }
    let n = announced(bytes);
    if n > limits.max_faces as u64 {
        return Err(MeshError::TooLarge {
            count: Some(n),
            unit: "triangles",
            limit: limits.max_faces,
            announced: true,
        });
    }
    let expected = PREAMBLE_BYTES as u64 + n * TRIANGLE_BYTES as u64;
    let len = bytes.len() as u64;
    if len != expected {
        let problem = if len < expected {
            format!(
                "the header announces {n} triangles ({expected} bytes) but the file has only \
                 {len} bytes; the file is truncated, upload the complete file"
            )
        } else {
            format!(
                "the header announces {n} triangles ({expected} bytes) but the file has {len} \
                 bytes; this is not a valid binary STL (and an ASCII STL must start with 'solid')"
            )
        };
        return Err(MeshError::parse(Format::Stl, "byte 80", problem));
    }
    let n = n as usize;
    let mut vertices = Vec::with_capacity(3 * n);
    for (t, record) in bytes[PREAMBLE_BYTES..]
        .chunks_exact(TRIANGLE_BYTES)
        .enumerate()
    {
        for corner in 0..3 {
            let mut v = [0.0; 3];
            for (k, c) in v.iter_mut().enumerate() {
                let at = 12 + 12 * corner + 4 * k;
                let mut word = [0u8; 4];
                word.copy_from_slice(&record[at..at + 4]);
                *c = f32::from_le_bytes(word) as f64;
            }
            if !v.iter().all(|c| c.is_finite()) {
                return Err(non_finite(corner, t, None));
            }
            vertices.push(v);
        }
    }
    Ok(Mesh::new(vertices, corner_faces(n)))
}

/// Faces `[3t, 3t+1, 3t+2]` of an unwelded triangle soup.
fn corner_faces(n: usize) -> Vec<[u32; 3]> {
    (0..n as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect()
}

fn non_finite(corner: usize, triangle: usize, line: Option<usize>) -> MeshError {
    let what = format!(
        "corner {} of the {} triangle",
        corner + 1,
        super::text::ordinal(triangle)
    );
    MeshError::NonFinite {
        at: super::build::located(what, line),
    }
}

fn read_ascii(bytes: &[u8], limits: &Limits) -> Result<Mesh, MeshError> {
    reject_binary(bytes, Format::Stl)?;
    let mut t = Tokens::new(bytes, 1);
    let mut vertices: Vec<[f64; 3]> = Vec::with_capacity(bytes.len() / 64);
    let mut faces: Vec<[u32; 3]> = Vec::with_capacity(bytes.len() / 200);
    let mut polygon: Vec<[f64; 3]> = Vec::with_capacity(4);
    while let Some(tok) = t.next_token() {
        if keyword(tok, b"solid") || keyword(tok, b"endsolid") {
            t.rest_of_line();
        } else if keyword(tok, b"facet") {
            polygon.clear();
            facet(&mut t, &mut polygon, faces.len())?;
            if faces.len() + polygon.len() - 2 > limits.max_faces
                || vertices.len() + polygon.len() > 3 * limits.max_faces
            {
                return Err(MeshError::TooLarge {
                    count: None,
                    unit: "triangles",
                    limit: limits.max_faces,
                    announced: false,
                });
            }
            let first = vertices.len() as u32;
            vertices.extend_from_slice(&polygon);
            for k in 1..polygon.len() as u32 - 1 {
                faces.push([first, first + k, first + k + 1]);
            }
        } else {
            return Err(expected(&t, "'facet' or 'endsolid'", tok));
        }
    }
    Ok(Mesh::new(vertices, faces))
}

/// Reads `normal nx ny nz outer loop (vertex x y z)+ endloop endfacet` after `facet`.
fn facet(t: &mut Tokens, polygon: &mut Vec<[f64; 3]>, triangle: usize) -> Result<(), MeshError> {
    expect(t, b"normal")?;
    for _ in 0..3 {
        number(t)?;
    }
    expect(t, b"outer")?;
    expect(t, b"loop")?;
    loop {
        let tok = t.next_token().ok_or_else(|| truncated(t))?;
        if keyword(tok, b"endloop") {
            break;
        }
        if !keyword(tok, b"vertex") {
            return Err(expected(t, "'vertex' or 'endloop'", tok));
        }
        let v = [number(t)?, number(t)?, number(t)?];
        if !v.iter().all(|c| c.is_finite()) {
            return Err(non_finite(polygon.len(), triangle, Some(t.line())));
        }
        polygon.push(v);
    }
    expect(t, b"endfacet")?;
    if polygon.len() < 3 {
        return Err(MeshError::parse(
            Format::Stl,
            t.at(),
            format!(
                "a facet needs 3 vertices but this one has {}; fix the facet or re-export the mesh",
                polygon.len()
            ),
        ));
    }
    Ok(())
}

fn keyword(tok: &[u8], word: &[u8]) -> bool {
    tok.eq_ignore_ascii_case(word)
}

fn expect(t: &mut Tokens, word: &[u8]) -> Result<(), MeshError> {
    match t.next_token() {
        Some(tok) if keyword(tok, word) => Ok(()),
        Some(tok) => Err(expected(t, &quote(word), tok)),
        None => Err(truncated(t)),
    }
}

fn number(t: &mut Tokens) -> Result<f64, MeshError> {
    let tok = t.next_token().ok_or_else(|| truncated(t))?;
    parse_f64(tok).ok_or_else(|| expected(t, "a number", tok))
}

fn expected(t: &Tokens, what: &str, found: &[u8]) -> MeshError {
    if t.at_end() {
        // A cut-off last token is a truncated file, not a grammar mistake.
        return truncated(t);
    }
    MeshError::parse(
        Format::Stl,
        t.at(),
        format!(
            "expected {what} but found {}; fix the file or re-export it as STL",
            quote(found)
        ),
    )
}

fn truncated(t: &Tokens) -> MeshError {
    MeshError::parse(
        Format::Stl,
        t.at(),
        "the file ends in the middle of a facet; it is truncated, upload the complete file",
    )
}

/// Binary STL: 80-byte header, `u32` count, then per triangle its unit normal and corners
/// as little-endian `f32` and a zero attribute.
pub(super) fn write(mesh: &Mesh) -> Vec<u8> {
    let mut out = Vec::with_capacity(PREAMBLE_BYTES + TRIANGLE_BYTES * mesh.faces.len());
    out.extend_from_slice(WRITTEN_HEADER);
    out.resize(HEADER_BYTES, b' ');
    out.extend_from_slice(&(mesh.faces.len() as u32).to_le_bytes());
    for f in 0..mesh.faces.len() {
        let [a, b, c] = mesh.triangle(f);
        let n = cross(sub(b, a), sub(c, a));
        let len = norm(n);
        let unit = if len > 0.0 {
            n.map(|x| x / len)
        } else {
            [0.0; 3]
        };
        for x in unit.iter().chain(&a).chain(&b).chain(&c) {
            out.extend_from_slice(&(*x as f32).to_le_bytes());
        }
        out.extend_from_slice(&0u16.to_le_bytes());
    }
    out
}
