//! Stanford PLY, ASCII and binary little-endian: `vertex` x, y, z of any numeric type and
//! `face` `vertex_indices` (or `vertex_index`) lists; other elements and properties skipped.

use super::Limits;
use super::build::MeshBuilder;
use super::ply_header::{self, Element, Encoding, Header, Property, Scalar};
use super::text::{Tokens, ordinal, parse_f64, quote};
use crate::mesh::format::Format;
use crate::mesh::{Mesh, MeshError};
use std::io::Write;

/// What an element contributes to the mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    /// Vertex positions, with the property positions of x, y, z.
    Vertex([usize; 3]),
    /// Polygons, with the position of the index list.
    Face(usize),
    /// Skipped.
    Other,
}

/// The body after `end_header`, read value by value.
enum Body<'a> {
    Ascii(Tokens<'a>),
    Binary {
        bytes: &'a [u8],
        pos: usize,
        base: usize,
    },
}

/// Why a value could not be read.
enum Missing {
    End,
    NotNumber(String),
}

impl Body<'_> {
    fn value(&mut self, ty: Scalar) -> Result<f64, Missing> {
        match self {
            Body::Ascii(t) => {
                let tok = t.next_token().ok_or(Missing::End)?;
                parse_f64(tok).ok_or_else(|| Missing::NotNumber(quote(tok)))
            }
            Body::Binary { bytes, pos, .. } => {
                let raw = bytes.get(*pos..*pos + ty.size()).ok_or(Missing::End)?;
                *pos += ty.size();
                Ok(decode_le(raw, ty))
            }
        }
    }

    /// Skips `n` instances of `size` bytes; only for the binary body.
    fn skip(&mut self, n: u64, size: usize) -> Result<(), Missing> {
        if let Body::Binary { bytes, pos, .. } = self {
            let len = n
                .checked_mul(size as u64)
                .and_then(|l| usize::try_from(l).ok())
                .ok_or(Missing::End)?;
            if bytes.len() - *pos < len {
                *pos = bytes.len();
                return Err(Missing::End);
            }
            *pos += len;
        }
        Ok(())
    }

    fn at(&self) -> String {
        match self {
            Body::Ascii(t) => t.at(),
            Body::Binary { pos, base, .. } => format!("byte {}", base + pos),
        }
    }

    fn line(&self) -> Option<usize> {
        match self {
            Body::Ascii(t) => Some(t.line()),
            Body::Binary { .. } => None,
        }
    }
}

/// One little-endian scalar (`raw` has exactly `ty.size()` bytes) as f64.
fn decode_le(raw: &[u8], ty: Scalar) -> f64 {
    let mut b = [0u8; 8];
    b[..raw.len()].copy_from_slice(raw);
    match ty {
        Scalar::I8 => b[0] as i8 as f64,
        Scalar::U8 => b[0] as f64,
        Scalar::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
        Scalar::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
        Scalar::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        Scalar::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
        Scalar::F64 => f64::from_le_bytes(b),
    }
}

/// Parses a PLY file.
pub(super) fn read(bytes: &[u8], limits: &Limits) -> Result<Mesh, MeshError> {
    let h = ply_header::parse(bytes)?;
    let roles = roles(&h, limits)?;
    let body_bytes = &bytes[h.body_offset..];
    let hint = |role: fn(&Role) -> bool| {
        h.elements
            .iter()
            .zip(&roles)
            .find(|(_, r)| role(r))
            .map_or(0, |(e, _)| {
                let fit = body_bytes.len() / e.min_bytes(h.encoding).max(1);
                (e.count as usize).min(fit)
            })
    };
    let vertex_hint = hint(|r| matches!(r, Role::Vertex(_)));
    let face_hint = hint(|r| matches!(r, Role::Face(_)));
    let mut b = MeshBuilder::new(Format::Ply, limits, vertex_hint, face_hint);
    let mut body = match h.encoding {
        Encoding::Ascii => Body::Ascii(Tokens::new(body_bytes, h.lines + 1)),
        Encoding::BinaryLittleEndian => Body::Binary {
            bytes: body_bytes,
            pos: 0,
            base: h.body_offset,
        },
    };
    let mut polygon = Vec::with_capacity(8);
    for (element, role) in h.elements.iter().zip(roles) {
        let fixed = element
            .properties
            .iter()
            .all(|p| matches!(p, Property::Scalar { .. }));
        if element.properties.is_empty() {
            // Instances without properties take no bytes, whatever the count says.
            continue;
        }
        if role == Role::Other && fixed && h.encoding == Encoding::BinaryLittleEndian {
            let size = element.min_bytes(h.encoding);
            body.skip(element.count, size)
                .map_err(|m| missing(m, &body, element, element.count, "any"))?;
            continue;
        }
        for i in 0..element.count {
            read_instance(&mut body, element, i, role, &mut b, &mut polygon)?;
        }
    }
    b.finish()
}

/// The role of each element; rejects counts over the limits before anything is allocated.
fn roles(h: &Header, limits: &Limits) -> Result<Vec<Role>, MeshError> {
    let mut roles = Vec::with_capacity(h.elements.len());
    let mut has_vertex = false;
    for e in &h.elements {
        let role = match e.name.as_str() {
            "vertex" if !has_vertex => {
                has_vertex = true;
                over_limit(e.count, limits.max_vertices, "vertices")?;
                Role::Vertex(xyz(e)?)
            }
            "face" => {
                over_limit(e.count, limits.max_faces, "faces")?;
                Role::Face(index_list(e)?)
            }
            _ => Role::Other,
        };
        roles.push(role);
    }
    if !has_vertex {
        return Err(MeshError::parse(
            Format::Ply,
            "the header",
            "there is no 'element vertex' declaration; re-export the mesh as PLY with vertices",
        ));
    }
    Ok(roles)
}

fn over_limit(count: u64, limit: usize, unit: &'static str) -> Result<(), MeshError> {
    if count > limit as u64 {
        return Err(MeshError::TooLarge {
            count: Some(count),
            unit,
            limit,
            announced: true,
        });
    }
    Ok(())
}

fn xyz(e: &Element) -> Result<[usize; 3], MeshError> {
    let mut out = [0; 3];
    for (k, axis) in ["x", "y", "z"].into_iter().enumerate() {
        out[k] = e
            .position(axis)
            .filter(|&p| matches!(e.properties[p], Property::Scalar { .. }))
            .ok_or_else(|| {
                MeshError::parse(
                    Format::Ply,
                    "the header",
                    format!(
                        "the vertex element has no scalar property '{axis}'; vertices need x, y \
                         and z coordinates"
                    ),
                )
            })?;
    }
    Ok(out)
}

fn index_list(e: &Element) -> Result<usize, MeshError> {
    e.position("vertex_indices")
        .or_else(|| e.position("vertex_index"))
        .filter(|&p| matches!(e.properties[p], Property::List { .. }))
        .ok_or_else(|| {
            MeshError::parse(
                Format::Ply,
                "the header",
                "the face element has no list property 'vertex_indices' (or 'vertex_index'); \
                 re-export the mesh with faces as vertex index lists",
            )
        })
}

/// Reads the `i`-th instance of `element` and hands vertices or polygons to the builder.
fn read_instance(
    body: &mut Body,
    element: &Element,
    i: u64,
    role: Role,
    b: &mut MeshBuilder,
    polygon: &mut Vec<i64>,
) -> Result<(), MeshError> {
    let mut v = [0.0; 3];
    polygon.clear();
    for (p, property) in element.properties.iter().enumerate() {
        let name = property.name();
        match *property {
            Property::Scalar { ty, .. } => {
                let x = body
                    .value(ty)
                    .map_err(|m| missing(m, body, element, i, name))?;
                if let Role::Vertex(axes) = role
                    && let Some(k) = axes.iter().position(|&a| a == p)
                {
                    v[k] = x;
                }
            }
            Property::List { count, item, .. } => {
                let n = body
                    .value(count)
                    .map_err(|m| missing(m, body, element, i, name))?;
                let n = whole(n, body, element, i, name)?;
                let keep = role == Role::Face(p);
                for _ in 0..n {
                    let x = body
                        .value(item)
                        .map_err(|m| missing(m, body, element, i, name))?;
                    if keep {
                        polygon.push(whole(x, body, element, i, name)?);
                    }
                }
            }
        }
    }
    match role {
        Role::Vertex(_) => b.push_vertex(v, body.line()),
        Role::Face(_) => b.push_polygon(polygon, body.line()),
        Role::Other => Ok(()),
    }
}

/// A list count or index, which must be a whole number.
fn whole(x: f64, body: &Body, element: &Element, i: u64, name: &str) -> Result<i64, MeshError> {
    if x.fract() == 0.0 && x.abs() < i64::MAX as f64 {
        return Ok(x as i64);
    }
    Err(MeshError::parse(
        Format::Ply,
        body.at(),
        format!(
            "property '{name}' of the {} {} element is {x}, not a whole number; fix the file or \
             re-export the mesh",
            ordinal(i as usize),
            element.name
        ),
    ))
}

fn missing(m: Missing, body: &Body, element: &Element, i: u64, name: &str) -> MeshError {
    let which = format!("the {} '{}' element", ordinal(i as usize), element.name);
    let problem = match m {
        Missing::End => format!(
            "the file ends inside {which} although the header announces {} of them; the file \
             is truncated, upload the complete file",
            element.count
        ),
        Missing::NotNumber(found) => format!(
            "expected a number for property '{name}' of {which} but found {found}; fix the \
             file or re-export the mesh"
        ),
    };
    MeshError::parse(Format::Ply, body.at(), problem)
}

/// Binary little-endian PLY with `double` coordinates and `uchar`/`int` index lists.
pub(super) fn write(mesh: &Mesh) -> Vec<u8> {
    let mut out = Vec::with_capacity(256 + 24 * mesh.vertices.len() + 13 * mesh.faces.len());
    let _ = write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment cohortforge surface mesh, coordinates in \
         mm\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.vertices.len(),
        mesh.faces.len()
    );
    for v in &mesh.vertices {
        for c in v {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    for f in &mesh.faces {
        out.push(3);
        for &i in f {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    out
}
