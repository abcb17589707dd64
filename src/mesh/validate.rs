//! The ingest pipeline: parse, check, weld, clean, check topology, orient, summarise.
//!
//! Rejections are [`MeshError`]s; repairs and doubts that still leave a usable surface are
//! [`Warning`]s.

use super::clean::{drop_degenerate, drop_unreferenced, weld};
use super::format::Format;
use super::io::text::ordinal;
use super::io::{self, Limits};
use super::manifold::{bowtie_vertices, check_edges};
use super::measures::{area_cm2, bounding_box, volume_ml};
use super::orient::orient;
use super::topology::{by_edge, connected_components};
use super::{Mesh, MeshError};

/// Fewest vertices of a surface (a tetrahedron).
pub const MIN_VERTICES: usize = 4;

/// How uploaded meshes are read and cleaned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IngestOptions {
    /// Size limits.
    pub limits: Limits,
    /// Vertices closer than this (mm) are merged; 0 merges only identical positions.
    pub weld_tolerance_mm: f64,
}

impl Default for IngestOptions {
    fn default() -> Self {
        Self {
            limits: Limits::default(),
            weld_tolerance_mm: 0.0,
        }
    }
}

/// Something repaired or doubtful about an accepted mesh.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Warning {
    /// Stable code, e.g. `mesh.not_watertight`.
    pub code: &'static str,
    /// What happened and what it means for the user.
    pub message: String,
}

/// Measures and topology of an accepted mesh.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct MeshSummary {
    /// Vertices after welding and clean-up.
    pub vertex_count: usize,
    /// Triangles after clean-up.
    pub face_count: usize,
    /// Enclosed volume in ml (meaningful only when `watertight`).
    pub volume_ml: f64,
    /// Surface area in cm².
    pub area_cm2: f64,
    /// Every edge borders exactly two triangles.
    pub watertight: bool,
    /// Connected parts.
    pub components: usize,
    /// V − E + F (2 for one closed surface without handles).
    pub euler_characteristic: i64,
    /// Smallest corner of the bounding box, mm.
    pub bbox_min: [f64; 3],
    /// Largest corner of the bounding box, mm.
    pub bbox_max: [f64; 3],
    /// Vertices as read from the file, before welding.
    pub original_vertex_count: usize,
}

/// An accepted mesh with its summary and warnings.
#[derive(Debug, Clone, PartialEq)]
pub struct Ingested {
    /// The cleaned, outward-oriented mesh.
    pub mesh: Mesh,
    /// Its measures.
    pub summary: MeshSummary,
    /// Repairs and doubts, in pipeline order.
    pub warnings: Vec<Warning>,
}

/// Parses `bytes` as `format` and runs [`validate`].
pub fn ingest(bytes: &[u8], format: Format, opts: &IngestOptions) -> Result<Ingested, MeshError> {
    validate(io::read(bytes, format, &opts.limits)?, opts)
}

/// Checks, cleans and orients a mesh made in code or parsed from a file.
pub fn validate(mut mesh: Mesh, opts: &IngestOptions) -> Result<Ingested, MeshError> {
    let original_vertex_count = mesh.vertices.len();
    check_input(&mesh, &opts.limits)?;
    let mut warnings = Vec::new();
    let mut warn = |code: &'static str, message: String| warnings.push(Warning { code, message });

    let welded = weld(&mut mesh, opts.weld_tolerance_mm);
    if welded > 0 {
        warn(
            "mesh.duplicate_vertices_welded",
            welded_message(welded, opts.weld_tolerance_mm),
        );
    }
    let mut origin: Vec<u32> = (0..mesh.faces.len() as u32).collect();
    let degenerate = drop_degenerate(&mut mesh, &mut origin);
    if degenerate > 0 {
        warn(
            "mesh.degenerate_faces_removed",
            format!("removed {degenerate} degenerate triangles (a repeated vertex or zero area)"),
        );
    }
    let unreferenced = drop_unreferenced(&mut mesh);
    if unreferenced > 0 {
        warn(
            "mesh.unreferenced_vertices_removed",
            format!("removed {unreferenced} vertices that no triangle uses"),
        );
    }
    check_not_empty(&mesh, degenerate)?;
    if mesh.vertices.len() > opts.limits.max_vertices {
        return Err(too_large(
            mesh.vertices.len(),
            "vertices",
            opts.limits.max_vertices,
        ));
    }

    let edges = check_edges(&mesh, &origin)?;
    let watertight = edges.boundary_edges == 0;
    if !watertight {
        warn(
            "mesh.not_watertight",
            format!(
                "the surface has {} boundary edges (holes), so it is not closed and its volume \
                 is not meaningful; close the holes if the organ volume matters",
                edges.boundary_edges
            ),
        );
    }
    let bowties = bowtie_vertices(&mesh, &edges.uses);
    if bowties > 0 {
        warn(
            "mesh.non_manifold_vertices",
            format!(
                "{bowties} vertices join parts of the surface at a single point (bow-tie); \
                 they were kept, but normals there are unreliable"
            ),
        );
    }
    let turned = orient(&mut mesh, &edges.uses, watertight);
    if turned.flipped > 0 {
        warn(
            "mesh.faces_reoriented",
            format!(
                "flipped {} of {} triangles so that all face outward (counter-clockwise seen \
                 from outside)",
                turned.flipped,
                mesh.faces.len()
            ),
        );
    }
    if turned.non_orientable_parts > 0 {
        warn(
            "mesh.inconsistent_orientation",
            format!(
                "{} parts of the surface cannot be oriented consistently (like a Möbius strip) \
                 and were left as they are; normals and volume may be wrong",
                turned.non_orientable_parts
            ),
        );
    }
    let edge_count = by_edge(&edges.uses).count();
    let summary = summarise(&mesh, watertight, edge_count, original_vertex_count);
    if summary.components > 1 {
        warn(
            "mesh.multiple_components",
            format!(
                "the mesh has {} separate parts; they are kept together as one shape",
                summary.components
            ),
        );
    }
    Ok(Ingested {
        mesh,
        summary,
        warnings,
    })
}

/// Limits, finite coordinates and index range, for meshes that did not come from a reader.
fn check_input(mesh: &Mesh, limits: &Limits) -> Result<(), MeshError> {
    if mesh.faces.len() > limits.max_faces {
        return Err(too_large(mesh.faces.len(), "triangles", limits.max_faces));
    }
    // Welding can only lower the count; STL repeats every corner, so allow three per face.
    let raw_vertex_limit = limits.max_vertices.max(3 * limits.max_faces);
    if mesh.vertices.len() > raw_vertex_limit {
        return Err(too_large(
            mesh.vertices.len(),
            "vertices",
            limits.max_vertices,
        ));
    }
    if let Some(v) = mesh
        .vertices
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(MeshError::NonFinite {
            at: format!("the {} vertex", ordinal(v)),
        });
    }
    for (f, face) in mesh.faces.iter().enumerate() {
        if let Some(&i) = face.iter().find(|&&i| i as usize >= mesh.vertices.len()) {
            return Err(MeshError::IndexOutOfRange {
                at: format!("the {} triangle", ordinal(f)),
                index: i as i64,
                vertex_count: mesh.vertices.len(),
                convention: "indices are 0-based",
            });
        }
    }
    Ok(())
}

fn check_not_empty(mesh: &Mesh, degenerate: usize) -> Result<(), MeshError> {
    if mesh.faces.is_empty() {
        return Err(MeshError::empty(if degenerate > 0 {
            format!("all {degenerate} triangles are degenerate (a repeated vertex or zero area)")
        } else {
            "the mesh has no triangles".to_string()
        }));
    }
    if mesh.vertices.len() < MIN_VERTICES {
        return Err(MeshError::empty(format!(
            "the mesh has only {} vertices in use, but a surface needs at least {MIN_VERTICES}",
            mesh.vertices.len()
        )));
    }
    Ok(())
}

fn too_large(count: usize, unit: &'static str, limit: usize) -> MeshError {
    MeshError::TooLarge {
        count: Some(count as u64),
        unit,
        limit,
        announced: false,
    }
}

fn welded_message(welded: usize, tolerance_mm: f64) -> String {
    let how = if tolerance_mm > 0.0 {
        format!("within {tolerance_mm} mm of an earlier vertex")
    } else {
        "at the same position as an earlier vertex".to_string()
    };
    format!("merged {welded} vertices {how} (STL files always repeat shared corners)")
}

fn summarise(
    mesh: &Mesh,
    watertight: bool,
    edge_count: usize,
    original_vertex_count: usize,
) -> MeshSummary {
    let (bbox_min, bbox_max) = bounding_box(mesh);
    MeshSummary {
        vertex_count: mesh.vertices.len(),
        face_count: mesh.faces.len(),
        volume_ml: volume_ml(mesh),
        area_cm2: area_cm2(mesh),
        watertight,
        components: connected_components(mesh).0,
        euler_characteristic: mesh.vertices.len() as i64 - edge_count as i64
            + mesh.faces.len() as i64,
        bbox_min,
        bbox_max,
        original_vertex_count,
    }
}

#[cfg(test)]
mod corpus;
#[cfg(test)]
mod tests;
