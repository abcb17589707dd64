//! The text header of a PLY file: encoding, elements, their counts and properties.

use super::text::{quote, reject_binary, trim_cr, words};
use crate::mesh::MeshError;
use crate::mesh::format::Format;

/// How the body after `end_header` is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Encoding {
    Ascii,
    BinaryLittleEndian,
}

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in bytes in the binary encoding.
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

/// One property of an element.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Property {
    /// A single value.
    Scalar { name: String, ty: Scalar },
    /// A count of type `count` followed by that many values of type `item`.
    List {
        name: String,
        count: Scalar,
        item: Scalar,
    },
}

impl Property {
    pub(super) fn name(&self) -> &str {
        match self {
            Property::Scalar { name, .. } | Property::List { name, .. } => name,
        }
    }
}

/// An element declaration: `element <name> <count>` and its properties.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) properties: Vec<Property>,
}

impl Element {
    /// Position of the property called `name`.
    pub(super) fn position(&self, name: &str) -> Option<usize> {
        self.properties.iter().position(|p| p.name() == name)
    }

    /// Fewest bytes one instance can take in `encoding`.
    pub(super) fn min_bytes(&self, encoding: Encoding) -> usize {
        let binary: usize = self
            .properties
            .iter()
            .map(|p| match p {
                Property::Scalar { ty, .. } => ty.size(),
                Property::List { count, .. } => count.size(),
            })
            .sum();
        match encoding {
            Encoding::BinaryLittleEndian => binary,
            // Each value is at least one digit and one separator.
            Encoding::Ascii => 2 * self.properties.len(),
        }
    }
}

/// A parsed PLY header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Header {
    pub(super) encoding: Encoding,
    pub(super) elements: Vec<Element>,
    /// Byte offset of the body.
    pub(super) body_offset: usize,
    /// Number of header lines, so the ASCII body starts at line `lines + 1`.
    pub(super) lines: usize,
}

/// Parses the header up to and including `end_header`.
pub(super) fn parse(bytes: &[u8]) -> Result<Header, MeshError> {
    let end = find_end(bytes)?;
    let text = &bytes[..end];
    reject_binary(text, Format::Ply)?;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let lines = text.iter().filter(|&&c| c == b'\n').count();
    for (i, raw) in text.split(|&c| c == b'\n').enumerate() {
        let at = format!("line {}", i + 1);
        let w: Vec<&[u8]> = words(trim_cr(raw)).collect();
        match w.as_slice() {
            [b"ply"] if i == 0 => {}
            _ if i == 0 => return Err(not_ply(raw)),
            [] | [b"comment", ..] | [b"obj_info", ..] | [b"end_header"] => {}
            [b"format", kind, _version] => encoding = Some(parse_encoding(kind, &at)?),
            [b"element", name, count] => elements.push(Element {
                name: String::from_utf8_lossy(name).into_owned(),
                count: parse_count(count, &at)?,
                properties: Vec::new(),
            }),
            [b"property", rest @ ..] => {
                let property = parse_property(rest, &at)?;
                let element = elements.last_mut().ok_or_else(|| {
                    header_error(&at, "a 'property' line comes before any 'element' line")
                })?;
                element.properties.push(property);
            }
            _ => {
                return Err(header_error(
                    &at,
                    &format!("{} is not a PLY header line", quote(trim_cr(raw))),
                ));
            }
        }
    }
    let encoding =
        encoding.ok_or_else(|| header_error("the header", "there is no 'format' line"))?;
    Ok(Header {
        encoding,
        elements,
        body_offset: end,
        lines,
    })
}

/// Offset just past the `end_header` line.
fn find_end(bytes: &[u8]) -> Result<usize, MeshError> {
    if !bytes.starts_with(b"ply") {
        let first = bytes.split(|&c| c == b'\n').next().unwrap_or(bytes);
        return Err(not_ply(first));
    }
    let mut offset = 0;
    for raw in bytes.split_inclusive(|&c| c == b'\n') {
        offset += raw.len();
        if raw.trim_ascii() == b"end_header" {
            return Ok(offset);
        }
    }
    Err(header_error(
        "the header",
        "there is no 'end_header' line, so the file is truncated or not PLY",
    ))
}

fn not_ply(first_line: &[u8]) -> MeshError {
    MeshError::parse(
        Format::Ply,
        "line 1",
        format!(
            "a PLY file starts with the line 'ply' but this one starts with {}; check that the \
             file really is PLY",
            quote(trim_cr(first_line))
        ),
    )
}

fn header_error(at: &str, problem: &str) -> MeshError {
    MeshError::parse(
        Format::Ply,
        at,
        format!("{problem}; fix the header or re-export the mesh as PLY"),
    )
}

fn parse_encoding(kind: &[u8], at: &str) -> Result<Encoding, MeshError> {
    match kind {
        b"ascii" => Ok(Encoding::Ascii),
        b"binary_little_endian" => Ok(Encoding::BinaryLittleEndian),
        b"binary_big_endian" => Err(MeshError::Unsupported {
            what: "binary big-endian PLY".into(),
            fix: "re-export the mesh as ASCII or binary little-endian PLY (or as STL or OBJ)"
                .into(),
        }),
        other => Err(header_error(
            at,
            &format!(
                "unknown PLY format {} (expected ascii or binary_little_endian)",
                quote(other)
            ),
        )),
    }
}

fn parse_count(count: &[u8], at: &str) -> Result<u64, MeshError> {
    super::text::parse_i64(count)
        .and_then(|c| u64::try_from(c).ok())
        .ok_or_else(|| {
            header_error(
                at,
                &format!("element count {} is not a whole number ≥ 0", quote(count)),
            )
        })
}

fn parse_property(rest: &[&[u8]], at: &str) -> Result<Property, MeshError> {
    let scalar = |name: &[u8]| {
        Scalar::from_name(name)
            .ok_or_else(|| header_error(at, &format!("unknown property type {}", quote(name))))
    };
    let name = |n: &[u8]| String::from_utf8_lossy(n).into_owned();
    match rest {
        [b"list", count, item, n] => Ok(Property::List {
            name: name(n),
            count: scalar(count)?,
            item: scalar(item)?,
        }),
        [ty, n] => Ok(Property::Scalar {
            name: name(n),
            ty: scalar(ty)?,
        }),
        _ => Err(header_error(
            at,
            "a property line must be 'property <type> <name>' or 'property list <count type> \
             <item type> <name>'",
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_with_types_and_comments() {
        let text = b"ply\r\nformat ascii 1.0\ncomment made by hand\nelement vertex 3\n\
            property float32 x\nproperty double y\nproperty int z\nproperty uchar red\n\
            element face 1\nproperty list uint8 int32 vertex_indices\nend_header\n0 0 0 0\n";
        let h = parse(text).unwrap();
        assert_eq!(h.encoding, Encoding::Ascii);
        assert_eq!(h.lines, 11);
        assert_eq!(&text[h.body_offset..], b"0 0 0 0\n");
        assert_eq!(h.elements.len(), 2);
        assert_eq!(h.elements[0].count, 3);
        assert_eq!(h.elements[0].position("z"), Some(2));
        assert_eq!(
            h.elements[0].min_bytes(Encoding::BinaryLittleEndian),
            4 + 8 + 4 + 1
        );
        assert_eq!(
            h.elements[1].properties[0],
            Property::List {
                name: "vertex_indices".into(),
                count: Scalar::U8,
                item: Scalar::I32
            }
        );
    }

    #[test]
    fn header_errors() {
        let big = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nend_header\n";
        assert_eq!(parse(big).unwrap_err().code(), "mesh.unsupported_format");
        let e = parse(b"solid x\n").unwrap_err();
        assert!(e.to_string().contains("starts with 'solid x'"), "{e}");
        let e = parse(b"ply\nformat ascii 1.0\nelement vertex 3\n").unwrap_err();
        assert!(e.to_string().contains("end_header"), "{e}");
        let e = parse(b"ply\nformat ascii 1.0\nproperty float x\nend_header\n").unwrap_err();
        assert!(e.to_string().contains("line 3"), "{e}");
        let e = parse(b"ply\nformat ascii 1.0\nelement vertex -3\nend_header\n").unwrap_err();
        assert!(e.to_string().contains("'-3'"), "{e}");
    }
}
