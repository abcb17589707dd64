//! Legacy VTK, ASCII `DATASET POLYDATA`: `POINTS` and `POLYGONS` (classic `n size` cells or
//! the 5.1 `OFFSETS`/`CONNECTIVITY` layout), `TRIANGLE_STRIPS`; `VERTICES`, `LINES` and
//! `FIELD` data are skipped and point or cell data ends the geometry.

use super::Limits;
use super::build::MeshBuilder;
use super::text::{Tokens, parse_f64, parse_i64, quote, reject_binary};
use crate::mesh::format::Format;
use crate::mesh::{Mesh, MeshError};
use std::io::Write;

/// Rough bytes per point or cell line, to size buffers from the file length.
const BYTES_PER_LINE_HINT: usize = 24;

/// The kind of a cell section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Cells {
    Polygons,
    Strips,
    Skipped,
}

/// Parses legacy ASCII VTK polydata.
pub(super) fn read(bytes: &[u8], limits: &Limits) -> Result<Mesh, MeshError> {
    let mut t = Tokens::new(bytes, 1);
    preamble(&mut t)?;
    reject_binary(bytes, Format::Vtk)?;
    let hint = bytes.len() / BYTES_PER_LINE_HINT;
    let mut b = MeshBuilder::new(Format::Vtk, limits, hint, hint);
    let mut has_points = false;
    while let Some(tok) = t.next_token() {
        match tok.to_ascii_uppercase().as_slice() {
            b"POINTS" => {
                points(&mut t, &mut b, limits)?;
                has_points = true;
            }
            b"POLYGONS" => cells(&mut t, &mut b, limits, Cells::Polygons)?,
            b"TRIANGLE_STRIPS" => cells(&mut t, &mut b, limits, Cells::Strips)?,
            b"VERTICES" | b"LINES" => cells(&mut t, &mut b, limits, Cells::Skipped)?,
            b"METADATA" => skip_metadata(&mut t),
            b"FIELD" => skip_field(&mut t)?,
            b"POINT_DATA" | b"CELL_DATA" => break,
            _ => {
                return Err(expected(
                    &t,
                    "POINTS, POLYGONS or another POLYDATA section",
                    tok,
                ));
            }
        }
    }
    if !has_points {
        return Err(MeshError::parse(
            Format::Vtk,
            "the end of the file",
            "there is no POINTS section, so the mesh has no vertices; re-export the mesh as \
             VTK polydata with points",
        ));
    }
    b.finish()
}

/// Checks the version line, skips the title, and requires ASCII `DATASET POLYDATA`.
fn preamble(t: &mut Tokens) -> Result<(), MeshError> {
    let first = t.rest_of_line();
    let lower = first.to_ascii_lowercase();
    if lower.trim_ascii_start().starts_with(b"<?xml") || lower.starts_with(b"<vtkfile") {
        return Err(MeshError::Unsupported {
            what: "XML VTK (.vtp, .vtu)".into(),
            fix: "save the mesh as legacy VTK polydata (.vtk), or as STL, OBJ or PLY".into(),
        });
    }
    if !(lower.starts_with(b"# vtk datafile version") || lower.starts_with(b"# vtk")) {
        return Err(MeshError::parse(
            Format::Vtk,
            "line 1",
            format!(
                "a legacy VTK file starts with '# vtk DataFile Version ...' but this one starts \
                 with {}; check that the file really is VTK",
                quote(first)
            ),
        ));
    }
    t.rest_of_line();
    let encoding = t.next_token().unwrap_or(b"");
    if encoding.eq_ignore_ascii_case(b"BINARY") {
        return Err(MeshError::Unsupported {
            what: "binary legacy VTK".into(),
            fix: "save the mesh as ASCII legacy VTK, or as STL, OBJ or PLY".into(),
        });
    }
    if !encoding.eq_ignore_ascii_case(b"ASCII") {
        return Err(expected(t, "ASCII or BINARY on line 3", encoding));
    }
    let dataset = t.next_token().unwrap_or(b"");
    if !dataset.eq_ignore_ascii_case(b"DATASET") {
        return Err(expected(t, "DATASET", dataset));
    }
    let kind = t.next_token().unwrap_or(b"");
    if !kind.eq_ignore_ascii_case(b"POLYDATA") {
        return Err(MeshError::Unsupported {
            what: format!("VTK dataset type {}", quote(kind)),
            fix: "extract the surface and save it as VTK POLYDATA, or as STL, OBJ or PLY".into(),
        });
    }
    Ok(())
}

/// `POINTS n type` followed by `3n` numbers.
fn points(t: &mut Tokens, b: &mut MeshBuilder, limits: &Limits) -> Result<(), MeshError> {
    let n = count(t)?;
    if n > limits.max_vertices as u64 {
        return Err(MeshError::TooLarge {
            count: Some(n),
            unit: "vertices",
            limit: limits.max_vertices,
            announced: true,
        });
    }
    t.next_token().ok_or_else(|| truncated(t, "POINTS"))?;
    for _ in 0..n {
        let v = [number(t)?, number(t)?, number(t)?];
        b.push_vertex(v, Some(t.line()))?;
    }
    Ok(())
}

/// A cell section in either layout, after its keyword.
fn cells(
    t: &mut Tokens,
    b: &mut MeshBuilder,
    limits: &Limits,
    kind: Cells,
) -> Result<(), MeshError> {
    let n = count(t)?;
    let size = count(t)?;
    if n > limits.max_faces as u64 || size > 3 * limits.max_faces as u64 {
        return Err(MeshError::TooLarge {
            count: Some(n),
            unit: "faces",
            limit: limits.max_faces,
            announced: true,
        });
    }
    let mut cell: Vec<i64> = Vec::with_capacity(8);
    let first = t.next_token().ok_or_else(|| truncated(t, "cells"))?;
    if first.eq_ignore_ascii_case(b"OFFSETS") {
        return offset_cells(t, b, n, size, kind);
    }
    let mut size_left = size;
    let mut len_token = Some(first);
    for _ in 0..n {
        let tok = match len_token.take() {
            Some(tok) => tok,
            None => t.next_token().ok_or_else(|| truncated(t, "cells"))?,
        };
        let len = parse_i64(tok)
            .and_then(|l| u64::try_from(l).ok())
            .filter(|&l| l < size_left)
            .ok_or_else(|| expected(t, "a cell size that fits the section size", tok))?;
        size_left -= len + 1;
        cell.clear();
        for _ in 0..len {
            cell.push(index(t)?);
        }
        emit(b, &cell, kind, t.line())?;
    }
    Ok(())
}

/// The VTK 5.1 layout: `OFFSETS type` with `n` offsets, `CONNECTIVITY type` with `size`.
fn offset_cells(
    t: &mut Tokens,
    b: &mut MeshBuilder,
    n: u64,
    size: u64,
    kind: Cells,
) -> Result<(), MeshError> {
    t.next_token().ok_or_else(|| truncated(t, "OFFSETS"))?;
    let mut offsets = Vec::with_capacity(n.min(1 << 16) as usize);
    for _ in 0..n {
        let o = index(t)?;
        let previous = offsets.last().copied().unwrap_or(0);
        if o < previous || o as u64 > size {
            return Err(expected(
                t,
                "offsets that increase up to the connectivity size",
                b"?",
            ));
        }
        offsets.push(o);
    }
    let keyword = t.next_token().unwrap_or(b"");
    if !keyword.eq_ignore_ascii_case(b"CONNECTIVITY") {
        return Err(expected(t, "CONNECTIVITY", keyword));
    }
    t.next_token().ok_or_else(|| truncated(t, "CONNECTIVITY"))?;
    let mut cell: Vec<i64> = Vec::with_capacity(8);
    for pair in offsets.windows(2) {
        cell.clear();
        for _ in pair[0]..pair[1] {
            cell.push(index(t)?);
        }
        emit(b, &cell, kind, t.line())?;
    }
    if let (Some(&last), true) = (offsets.last(), size > 0) {
        for _ in last as u64..size {
            index(t)?;
        }
    }
    Ok(())
}

/// Hands a cell to the builder: polygons as they are, strips as alternating triangles.
fn emit(b: &mut MeshBuilder, cell: &[i64], kind: Cells, line: usize) -> Result<(), MeshError> {
    match kind {
        Cells::Polygons => b.push_polygon(cell, Some(line)),
        Cells::Strips => {
            for (k, w) in cell.windows(3).enumerate() {
                let tri = if k % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                };
                b.push_polygon(&tri, Some(line))?;
            }
            Ok(())
        }
        Cells::Skipped => Ok(()),
    }
}

/// Skips dataset field data: `FIELD name n`, then per array `name components tuples type`
/// and its values (each optionally followed by a `METADATA` block).
fn skip_field(t: &mut Tokens) -> Result<(), MeshError> {
    t.next_token().ok_or_else(|| truncated(t, "FIELD"))?;
    let arrays = count(t)?;
    for _ in 0..arrays {
        t.next_token().ok_or_else(|| truncated(t, "FIELD"))?;
        let values = count(t)?.saturating_mul(count(t)?);
        t.next_token().ok_or_else(|| truncated(t, "FIELD"))?;
        for _ in 0..values {
            t.next_token().ok_or_else(|| truncated(t, "FIELD"))?;
        }
        let mut probe = t.clone();
        if probe
            .next_token()
            .is_some_and(|k| k.eq_ignore_ascii_case(b"METADATA"))
        {
            *t = probe;
            skip_metadata(t);
        }
    }
    Ok(())
}

/// Skips a 5.1 `METADATA` block, which ends at a blank line.
fn skip_metadata(t: &mut Tokens) {
    t.rest_of_line();
    loop {
        let line = t.rest_of_line();
        if line.trim_ascii().is_empty() {
            break;
        }
    }
}

fn count(t: &mut Tokens) -> Result<u64, MeshError> {
    let tok = t
        .next_token()
        .ok_or_else(|| truncated(t, "a section header"))?;
    parse_i64(tok)
        .and_then(|c| u64::try_from(c).ok())
        .ok_or_else(|| expected(t, "a count (whole number ≥ 0)", tok))
}

fn index(t: &mut Tokens) -> Result<i64, MeshError> {
    let tok = t.next_token().ok_or_else(|| truncated(t, "cells"))?;
    parse_i64(tok).ok_or_else(|| expected(t, "a whole number", tok))
}

fn number(t: &mut Tokens) -> Result<f64, MeshError> {
    let tok = t.next_token().ok_or_else(|| truncated(t, "POINTS"))?;
    parse_f64(tok).ok_or_else(|| expected(t, "a coordinate", tok))
}

fn expected(t: &Tokens, what: &str, found: &[u8]) -> MeshError {
    if t.at_end() {
        // A cut-off last token is a truncated file, not a grammar mistake.
        return truncated(t, "the last section");
    }
    MeshError::parse(
        Format::Vtk,
        t.at(),
        format!(
            "expected {what} but found {}; fix the file or re-export it as legacy VTK polydata",
            quote(found)
        ),
    )
}

fn truncated(t: &Tokens, section: &str) -> MeshError {
    MeshError::parse(
        Format::Vtk,
        t.at(),
        format!("the file ends inside {section}; it is truncated, upload the complete file"),
    )
}

/// The title line of files written without one of their own.
const DEFAULT_TITLE: &str = "cohortforge surface mesh, coordinates in mm";
/// Longest title line the legacy format allows.
const MAX_TITLE: usize = 255;

/// Legacy ASCII VTK 4.2 polydata with `double` points and classic `POLYGONS`.
pub(super) fn write(mesh: &Mesh) -> Vec<u8> {
    write_titled(mesh, DEFAULT_TITLE)
}

/// As [`write`], with `title` (one line, at most 255 bytes; longer is cut, line breaks
/// become spaces) as the file's title line.
pub(super) fn write_titled(mesh: &Mesh, title: &str) -> Vec<u8> {
    let mut title: String = title
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    while title.len() > MAX_TITLE {
        title.pop();
    }
    let mut out =
        Vec::with_capacity(BYTES_PER_LINE_HINT * (mesh.vertices.len() + mesh.faces.len()));
    let _ = write!(
        out,
        "# vtk DataFile Version 4.2\n{title}\nASCII\n\
         DATASET POLYDATA\nPOINTS {} double\n",
        mesh.vertices.len()
    );
    for [x, y, z] in &mesh.vertices {
        let _ = writeln!(out, "{x:?} {y:?} {z:?}");
    }
    let m = mesh.faces.len();
    let _ = writeln!(out, "POLYGONS {m} {}", 4 * m);
    for [a, b, c] in &mesh.faces {
        let _ = writeln!(out, "3 {a} {b} {c}");
    }
    out
}
