//! Label volumes (NIfTI-1) to closed, outward-oriented surface meshes in millimetres.
//! Pure: no async, SQL or HTTP.
//!
//! The pipeline: read the volume ([`read`]), select the label(s) and a connected component
//! and fill cavities ([`labels`]), resample to isotropic voxels and smooth ([`resample`]),
//! extract the isosurface at 0.5 ([`marching`]), map it to world millimetres through the
//! volume's affine ([`affine`], [`surface`]), keep the largest surface part, and validate
//! it like any uploaded mesh ([`crate::mesh::validate::validate`]).

pub mod affine;
pub mod datatype;
pub mod error;
pub mod field;
pub mod labels;
pub mod marching;
mod options;
pub mod read;
pub mod resample;
pub mod surface;
mod tables;
pub mod write;

use serde::Serialize;

pub use error::NiftiError;
pub use options::{Component, Options, OptionsError};
pub use read::{LabelVolume, Limits, read};

use crate::mesh::validate::{IngestOptions, Ingested, validate};
use affine::AffineSource;
use resample::SampleGrid;

/// The isosurface level of the resampled, smoothed mask (half-way between out and in).
pub const ISO_LEVEL: f32 = 0.5;

/// A surface made from a label volume, and how.
#[derive(Debug, Clone)]
pub struct Segmented {
    /// The validated mesh and its summary.
    pub ingested: Ingested,
    /// Parameters and measures of the derivation, for the mesh record.
    pub source: Source,
}

/// How a mesh was derived from a label volume (stored as the mesh record's `source`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Source {
    /// Always `"nifti"`.
    pub kind: &'static str,
    /// Labels that were selected.
    pub labels: Vec<i64>,
    /// `largest` or `all`.
    pub component: Component,
    /// Whether cavities were filled.
    pub fill_holes: bool,
    /// Gaussian smoothing, mm.
    pub smooth_sigma_mm: f64,
    /// Isotropic resampling size, mm.
    pub voxel_mm: f64,
    /// Voxels of the volume along `[i, j, k]`.
    pub dims: [usize; 3],
    /// Voxel size along `[i, j, k]`, mm.
    pub voxel_spacing_mm: [f64; 3],
    /// Which header fields gave the affine: `sform`, `qform` or `pixdim`.
    pub affine: AffineSource,
    /// Whether the affine mirrors (negative determinant).
    pub mirrored: bool,
    /// 6-connected components of the selected labels before choosing.
    pub label_components: usize,
    /// Cavity voxels filled.
    pub filled_voxels: usize,
    /// Voxels of the final selection (labels, component, filled cavities).
    pub selected_voxels: usize,
    /// Their volume: `selected_voxels` × voxel volume, ml.
    pub voxel_volume_ml: f64,
    /// Surface parts dropped (all but the largest, and its cavities unless holes are kept).
    pub dropped_surface_parts: usize,
}

/// Reads a NIfTI-1 label volume (gzip or not) and makes its surface.
pub fn volume_to_mesh(
    bytes: &[u8],
    options: &Options,
    limits: &Limits,
    ingest: &IngestOptions,
) -> Result<Segmented, NiftiError> {
    options.check()?;
    let volume = read::read(bytes, limits)?;
    label_volume_to_mesh(&volume, options, limits, ingest)
}

/// Makes the surface of a volume already read.
pub fn label_volume_to_mesh(
    volume: &LabelVolume,
    options: &Options,
    limits: &Limits,
    ingest: &IngestOptions,
) -> Result<Segmented, NiftiError> {
    options.check()?;
    let (mut mask, _) = labels::select(volume, &options.labels)?;
    let label_components = match options.component {
        Component::Largest => labels::keep_largest_component(&mut mask),
        Component::All => labels::components(&mask).1.len(),
    };
    let filled_voxels = if options.fill_holes {
        labels::fill_holes(&mut mask)
    } else {
        0
    };
    let selected_voxels = mask.count();
    let bounds = mask
        .bounds()
        .ok_or_else(|| NiftiError::parse("the selection is empty"))?;
    let spacing = volume.affine.spacing_mm();
    let grid = SampleGrid::plan(
        bounds,
        spacing,
        options.voxel_mm,
        options.smooth_sigma_mm,
        limits.max_samples,
    )?;
    let mut field = resample::resample(&mask, &grid);
    drop(mask);
    resample::smooth(&mut field, options.smooth_sigma_mm / options.voxel_mm);
    let grid_surface = marching::march(&field, ISO_LEVEL);
    drop(field);
    if grid_surface.faces.is_empty() {
        return Err(NiftiError::EmptySurface {
            voxels: selected_voxels,
            voxel_mm: options.voxel_mm,
            smooth_sigma_mm: options.smooth_sigma_mm,
        });
    }
    let mesh = surface::to_world(grid_surface, &grid, &volume.affine);
    let (mesh, dropped_surface_parts) = match options.component {
        Component::Largest => surface::keep_largest(mesh, !options.fill_holes),
        Component::All => (mesh, 0),
    };
    let ingested = validate(mesh, ingest)?;
    let source = Source {
        kind: "nifti",
        labels: options.labels.clone(),
        component: options.component,
        fill_holes: options.fill_holes,
        smooth_sigma_mm: options.smooth_sigma_mm,
        voxel_mm: options.voxel_mm,
        dims: volume.dims,
        voxel_spacing_mm: spacing,
        affine: volume.affine.source,
        mirrored: volume.affine.determinant() < 0.0,
        label_components,
        filled_voxels,
        selected_voxels,
        voxel_volume_ml: selected_voxels as f64 * volume.affine.voxel_volume_mm3() / 1000.0,
        dropped_surface_parts,
    };
    Ok(Segmented { ingested, source })
}

#[cfg(test)]
mod read_tests;
#[cfg(test)]
mod tests;
