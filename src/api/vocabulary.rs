//! Closed vocabularies of query parameters, as schemas for the OpenAPI document. The
//! handlers parse the plain strings themselves (their errors name the accepted values);
//! these types only tell generated clients and fuzzers which values exist.

use utoipa::ToSchema;

/// A mesh file format.
#[derive(ToSchema)]
#[schema(rename_all = "lowercase")]
#[allow(dead_code)]
pub enum MeshFormatName {
    /// Wavefront OBJ.
    Obj,
    /// Binary STL.
    Stl,
    /// Binary little-endian PLY.
    Ply,
    /// Legacy ASCII VTK polydata.
    Vtk,
}

/// A format a mesh upload may be in.
#[derive(ToSchema)]
#[schema(rename_all = "lowercase")]
#[allow(dead_code)]
pub enum UploadFormatName {
    /// Wavefront OBJ.
    Obj,
    /// STL, ASCII or binary.
    Stl,
    /// PLY, ASCII or binary little-endian.
    Ply,
    /// Legacy ASCII VTK polydata.
    Vtk,
    /// A NIfTI-1 label volume (`.nii` or gzip `.nii.gz`).
    Nifti,
}

/// A plot file format.
#[derive(ToSchema)]
#[schema(rename_all = "lowercase")]
#[allow(dead_code)]
pub enum PlotFormatName {
    /// The plot as on its page.
    Svg,
    /// The same plot rasterised.
    Png,
}

/// A camera of a picture.
#[derive(ToSchema)]
#[schema(rename_all = "lowercase")]
#[allow(dead_code)]
pub enum ViewName {
    /// From −y.
    Anterior,
    /// From +x.
    Lateral,
    /// From +z.
    Superior,
}

/// Which connected parts of a label volume to keep.
#[derive(ToSchema)]
#[schema(rename_all = "lowercase")]
#[allow(dead_code)]
pub enum ComponentName {
    /// The part with the most voxels.
    Largest,
    /// Every part.
    All,
}
