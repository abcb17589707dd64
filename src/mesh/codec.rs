//! Compact binary storage form of a mesh and its checksum.
//!
//! Layout (little-endian): magic `CFMESH1\0`, `u32` vertex count, `u32` face count, the
//! coordinates as `f64` (`[n_vertices, 3]`, mm), then the indices as `u32` (`[n_faces, 3]`).

use super::{Mesh, MeshError};
use sha2::{Digest, Sha256};

/// First eight bytes of every record.
pub const MAGIC: &[u8; 8] = b"CFMESH1\0";
/// Magic plus the two counts.
const HEADER_BYTES: usize = 16;
/// Bytes per vertex and per face.
const VERTEX_BYTES: usize = 24;
const FACE_BYTES: usize = 12;

/// Encodes `mesh` in the storage layout.
pub fn encode(mesh: &Mesh) -> Vec<u8> {
    let mut out = Vec::with_capacity(
        HEADER_BYTES + VERTEX_BYTES * mesh.vertices.len() + FACE_BYTES * mesh.faces.len(),
    );
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(mesh.vertices.len() as u32).to_le_bytes());
    out.extend_from_slice(&(mesh.faces.len() as u32).to_le_bytes());
    for c in mesh.vertices.iter().flatten() {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for i in mesh.faces.iter().flatten() {
        out.extend_from_slice(&i.to_le_bytes());
    }
    out
}

/// Decodes a storage record, checking the magic, the exact length, finiteness and that
/// every index names a vertex.
pub fn decode(bytes: &[u8]) -> Result<Mesh, MeshError> {
    let corrupt = |detail: String| MeshError::CorruptRecord { detail };
    if bytes.len() < HEADER_BYTES || &bytes[..8] != MAGIC {
        return Err(corrupt("it does not start with the CFMESH1 header".into()));
    }
    let n_vertices = u32_at(bytes, 8) as usize;
    let n_faces = u32_at(bytes, 12) as usize;
    let expected = HEADER_BYTES as u64
        + VERTEX_BYTES as u64 * n_vertices as u64
        + FACE_BYTES as u64 * n_faces as u64;
    if bytes.len() as u64 != expected {
        return Err(corrupt(format!(
            "it has {} bytes but {n_vertices} vertices and {n_faces} faces need {expected}",
            bytes.len()
        )));
    }
    let (coords, indices) = bytes[HEADER_BYTES..].split_at(VERTEX_BYTES * n_vertices);
    let mut vertices = Vec::with_capacity(n_vertices);
    for (v, chunk) in coords.chunks_exact(VERTEX_BYTES).enumerate() {
        let p = [0, 8, 16].map(|o| f64_at(chunk, o));
        if !p.iter().all(|c| c.is_finite()) {
            return Err(corrupt(format!("vertex {v} has a non-finite coordinate")));
        }
        vertices.push(p);
    }
    let mut faces = Vec::with_capacity(n_faces);
    for (f, chunk) in indices.chunks_exact(FACE_BYTES).enumerate() {
        let face = [0, 4, 8].map(|o| u32_at(chunk, o));
        if let Some(&bad) = face.iter().find(|&&i| i as usize >= n_vertices) {
            return Err(corrupt(format!(
                "face {f} refers to vertex {bad} of {n_vertices}"
            )));
        }
        faces.push(face);
    }
    Ok(Mesh::new(vertices, faces))
}

/// SHA-256 of [`encode`]`(mesh)`, lowercase hex (64 characters).
pub fn sha256_hex(mesh: &Mesh) -> String {
    hex::encode(Sha256::digest(encode(mesh)))
}

fn u32_at(bytes: &[u8], at: usize) -> u32 {
    let mut b = [0u8; 4];
    b.copy_from_slice(&bytes[at..at + 4]);
    u32::from_le_bytes(b)
}

fn f64_at(bytes: &[u8], at: usize) -> f64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&bytes[at..at + 8]);
    f64::from_le_bytes(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::{cube, tetrahedron};

    #[test]
    fn layout_and_round_trip() {
        let t = tetrahedron(0.5);
        let bytes = encode(&t);
        assert_eq!(bytes.len(), 16 + 4 * 24 + 4 * 12);
        assert_eq!(&bytes[..8], b"CFMESH1\0");
        assert_eq!(&bytes[8..16], &[4, 0, 0, 0, 4, 0, 0, 0]);
        assert_eq!(f64_at(&bytes, 16), 5.5);
        assert_eq!(decode(&bytes).unwrap(), t);
        assert_eq!(decode(&encode(&Mesh::default())).unwrap(), Mesh::default());
    }

    #[test]
    fn checksum_is_stable_and_sensitive() {
        let c = cube();
        let h = sha256_hex(&c);
        assert_eq!(h.len(), 64);
        assert!(
            h.chars()
                .all(|ch| ch.is_ascii_hexdigit() && !ch.is_ascii_uppercase())
        );
        assert_eq!(h, sha256_hex(&cube()));
        let mut moved = cube();
        moved.vertices[3][0] += 1e-9;
        assert_ne!(h, sha256_hex(&moved));
        // The empty mesh: SHA-256 of the 16-byte header with zero counts.
        assert_eq!(
            sha256_hex(&Mesh::default()),
            hex::encode(Sha256::digest(b"CFMESH1\0\0\0\0\0\0\0\0\0"))
        );
    }

    #[test]
    fn corrupt_records_are_rejected() {
        let good = encode(&tetrahedron(0.0));
        let mut bad_magic = good.clone();
        bad_magic[0] = b'X';
        let mut bad_index = good.clone();
        let last = bad_index.len() - 4;
        bad_index[last..].copy_from_slice(&4u32.to_le_bytes());
        let mut nan = good.clone();
        nan[16..24].copy_from_slice(&f64::NAN.to_le_bytes());
        for (bytes, needle) in [
            (&good[..good.len() - 1], "bytes"),
            (&bad_magic[..], "header"),
            (&bad_index[..], "face 3 refers to vertex 4"),
            (&nan[..], "vertex 0"),
            (&good[..10], "header"),
        ] {
            let e = decode(bytes).unwrap_err();
            assert_eq!(e.code(), "mesh.corrupt_record");
            assert!(e.to_string().contains(needle), "{e}");
        }
    }
}
