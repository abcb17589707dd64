//! Why a label volume could not become a surface, with stable `nifti.*` codes.

use crate::mesh::MeshError;

/// A label volume that cannot be read or turned into a surface.
#[derive(Debug, thiserror::Error)]
pub enum NiftiError {
    /// Not a NIfTI-1 file, or a damaged one (bad magic, truncated data, broken gzip).
    #[error("the NIfTI file could not be read: {problem}")]
    Parse {
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// A NIfTI variant that is not read (NIfTI-2, header/image pairs, time series).
    #[error("{what} is not supported; {fix}")]
    UnsupportedFormat {
        /// The unsupported variant.
        what: String,
        /// How to get a supported file.
        fix: String,
    },
    /// A voxel type that cannot hold labels (complex, RGB, 128-bit float, bit masks).
    #[error(
        "NIfTI datatype {code} ({name}) is not supported for label volumes; save the \
         segmentation with an integer type (uint8, int16, uint16, int32) or float32/float64"
    )]
    UnsupportedDatatype {
        /// The header's datatype code.
        code: i16,
        /// Its name.
        name: &'static str,
    },
    /// Voxel values that are not whole numbers: a probability map or an image, not labels.
    #[error(
        "the volume holds non-integer values (e.g. {value} at voxel {voxel:?}), so it is not a \
         label volume; threshold it into integer labels first"
    )]
    NotLabels {
        /// A non-integer value found.
        value: f64,
        /// Where, as `[i, j, k]`.
        voxel: [usize; 3],
    },
    /// The asked label is absent from the volume.
    #[error("{}", empty_label_message(requested, present))]
    EmptyLabel {
        /// Labels asked for.
        requested: Vec<i64>,
        /// Non-zero labels present, with their voxel counts.
        present: Vec<(i64, u64)>,
    },
    /// The selected voxels are too thin to leave a surface after smoothing.
    #[error(
        "the {voxels} selected voxels leave no surface after resampling to {voxel_mm} mm and \
         smoothing with sigma {smooth_sigma_mm} mm; lower smooth_sigma_mm or voxel_mm"
    )]
    EmptySurface {
        /// Selected voxels.
        voxels: usize,
        /// Resampling size, mm.
        voxel_mm: f64,
        /// Smoothing, mm.
        smooth_sigma_mm: f64,
    },
    /// More voxels (or resampled samples) than the limit.
    #[error("{what} has {count} voxels, more than the limit of {limit}; {fix}")]
    TooLarge {
        /// Which grid, e.g. "the volume".
        what: &'static str,
        /// Its voxel count.
        count: u64,
        /// The limit.
        limit: u64,
        /// How to get under it.
        fix: &'static str,
    },
    /// A parameter out of range.
    #[error("{0}")]
    InvalidOption(#[from] super::options::OptionsError),
    /// The surface was made but failed mesh validation (e.g. over the vertex limit).
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

fn empty_label_message(requested: &[i64], present: &[(i64, u64)]) -> String {
    let asked = join(requested.iter().map(i64::to_string));
    let which = if requested.len() == 1 {
        format!("label {asked} is")
    } else {
        format!("labels {asked} are")
    };
    if present.is_empty() {
        return format!("{which} absent: the volume holds only background (0)");
    }
    let listed = join(
        present
            .iter()
            .map(|(label, n)| format!("{label} ({n} voxels)")),
    );
    format!("{which} absent from the volume; labels present: {listed}; choose one with ?label=")
}

fn join(items: impl Iterator<Item = String>) -> String {
    items.collect::<Vec<_>>().join(", ")
}

impl NiftiError {
    /// The stable machine-readable code, e.g. `nifti.empty_label`.
    pub fn code(&self) -> &'static str {
        match self {
            NiftiError::Parse { .. } => "nifti.parse_error",
            NiftiError::UnsupportedFormat { .. } => "nifti.unsupported_format",
            NiftiError::UnsupportedDatatype { .. } => "nifti.unsupported_datatype",
            NiftiError::NotLabels { .. } => "nifti.not_labels",
            NiftiError::EmptyLabel { .. } => "nifti.empty_label",
            NiftiError::EmptySurface { .. } => "nifti.empty_surface",
            NiftiError::TooLarge { .. } => "nifti.too_large",
            NiftiError::InvalidOption(_) => "nifti.invalid_option",
            NiftiError::Mesh(e) => e.code(),
        }
    }

    /// A parse error.
    pub(crate) fn parse(problem: impl Into<String>) -> Self {
        NiftiError::Parse {
            problem: problem.into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_label_names_the_labels_present() {
        let e = NiftiError::EmptyLabel {
            requested: vec![3],
            present: vec![(1, 1200), (2, 35)],
        };
        assert_eq!(e.code(), "nifti.empty_label");
        assert_eq!(
            e.to_string(),
            "label 3 is absent from the volume; labels present: 1 (1200 voxels), 2 (35 voxels); \
             choose one with ?label="
        );
        let e = NiftiError::EmptyLabel {
            requested: vec![1, 2],
            present: vec![],
        };
        assert_eq!(
            e.to_string(),
            "labels 1, 2 are absent: the volume holds only background (0)"
        );
    }

    #[test]
    fn mesh_errors_keep_their_code() {
        let e = NiftiError::from(MeshError::Empty { what: "x".into() });
        assert_eq!(e.code(), "mesh.empty");
        assert_eq!(NiftiError::parse("x").code(), "nifti.parse_error");
    }
}
