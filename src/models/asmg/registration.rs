//! Pre-alignment of the ASMG family: every mesh is simplified and registered rigidly to the
//! alignment reference (the model frame), with the `mirror` option as it is and as its
//! mirror image (see [`crate::models::sides`]).

use crate::mesh::{Laterality, Mesh};
use crate::models::ModelError;
use crate::models::alignment::{self, AlignmentParams, Registration, mirror, simplified};
use crate::models::sides::{SideCandidates, takes_mirrored};

/// A mesh registered to the reference, in the model frame.
pub struct AlignedMesh {
    /// The simplified mesh (what the networks see), its triangles wound outwards.
    pub mesh: Mesh,
    /// All original vertices (mm).
    pub vertices: Vec<[f64; 3]>,
}

/// `small` (the simplified `mesh`) registered to `reference`, as it is or mirrored.
fn aligned_as(
    reference: &Mesh,
    small: &Mesh,
    mesh: &Mesh,
    params: &AlignmentParams,
    mirrored: bool,
) -> Result<AlignedMesh, ModelError> {
    let registered: Vec<[f64; 3]> = if mirrored {
        small.vertices.iter().map(|p| mirror(*p)).collect()
    } else {
        small.vertices.clone()
    };
    let cpd = alignment::register(&reference.vertices, &registered, params)?;
    let registration = Registration { cpd, mirrored };
    let frame = |v: &[[f64; 3]]| -> Vec<[f64; 3]> {
        v.iter()
            .map(|p| registration.to_template_frame(*p))
            .collect()
    };
    Ok(AlignedMesh {
        mesh: Mesh::new(frame(&small.vertices), registration.faces(&small.faces)),
        vertices: frame(&mesh.vertices),
    })
}

/// `mesh` registered to `reference` as it is and, with `params.mirror`, as its mirror image
/// (second).
pub fn align_sides(
    reference: &Mesh,
    mesh: &Mesh,
    params: &AlignmentParams,
    max_vertices: usize,
) -> Result<Vec<AlignedMesh>, ModelError> {
    let small = simplified(mesh, max_vertices)?;
    let mut sides = vec![aligned_as(reference, &small, mesh, params, false)?];
    if params.mirror {
        sides.push(aligned_as(reference, &small, mesh, params, true)?);
    }
    Ok(sides)
}

/// The two registrations of [`align_sides`] as points to compare (`None` with one).
pub fn side_candidates(sides: &[AlignedMesh]) -> Option<SideCandidates> {
    match sides {
        [own, flipped] => Some(SideCandidates {
            own: own.mesh.vertices.clone(),
            mirrored: flipped.mesh.vertices.clone(),
        }),
        _ => None,
    }
}

/// A new mesh registered rigidly to `reference`: the simplified mesh in the model frame (for
/// the networks) and all original vertices in the model frame (mm). With `params.mirror`,
/// as its mirror image when the user `given` the other side than the model's, or, without
/// either side, when its mirror image lies nearer the nearest of the model's `atlases`.
pub fn align(
    reference: &Mesh,
    mesh: &Mesh,
    given: Option<Laterality>,
    params: &AlignmentParams,
    max_vertices: usize,
    atlases: &[&[[f64; 3]]],
) -> Result<(Mesh, Vec<[f64; 3]>), ModelError> {
    let mut sides = align_sides(reference, mesh, params, max_vertices)?;
    let take_mirrored = match side_candidates(&sides) {
        Some(candidates) => takes_mirrored(&candidates, atlases, given, params.laterality)?,
        None => false,
    };
    let chosen = sides.swap_remove(usize::from(take_mirrored));
    Ok((chosen.mesh, chosen.vertices))
}
