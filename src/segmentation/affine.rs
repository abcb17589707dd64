//! The voxel-to-world map of a NIfTI volume: sform, else qform, else pixdim scaling.

use serde::Serialize;

use super::error::NiftiError;

/// Where the affine came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AffineSource {
    /// `srow_x/y/z` (sform_code > 0).
    Sform,
    /// The quaternion, offsets and pixdim (qform_code > 0).
    Qform,
    /// pixdim scaling only (neither code set).
    Pixdim,
}

/// An affine map from voxel indices `[i, j, k]` to world millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// Linear part, rows `[x, y, z]`, columns `[i, j, k]` (mm per voxel step).
    pub linear: [[f64; 3]; 3],
    /// World position of voxel `[0, 0, 0]`, mm.
    pub offset: [f64; 3],
    /// Which header fields it was taken from.
    pub source: AffineSource,
}

/// Smallest |determinant| (mm³ per voxel) of a usable affine.
pub const MIN_VOXEL_VOLUME_MM3: f64 = 1e-9;

/// The header fields an affine is made from (NIfTI-1 names).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpatialHeader {
    /// sform code; > 0 means the srows are valid.
    pub sform_code: i16,
    /// qform code; > 0 means the quaternion is valid.
    pub qform_code: i16,
    /// `srow_x`, `srow_y`, `srow_z`.
    pub srow: [[f32; 4]; 3],
    /// `quatern_b`, `quatern_c`, `quatern_d`.
    pub quatern: [f32; 3],
    /// `qoffset_x`, `qoffset_y`, `qoffset_z`.
    pub qoffset: [f32; 3],
    /// `pixdim[0..4]`: qfac and the voxel sizes.
    pub pixdim: [f32; 4],
    /// Millimetres per spatial unit of the file (1000 for metres).
    pub mm_per_unit: f64,
}

impl Affine {
    /// The affine a header describes, in mm.
    pub fn from_header(h: &SpatialHeader) -> Result<Self, NiftiError> {
        let f = |v: f32| f64::from(v) * h.mm_per_unit;
        let (linear, offset, source) = if h.sform_code > 0 {
            let linear = [0, 1, 2].map(|r| [0, 1, 2].map(|c| f(h.srow[r][c])));
            (
                linear,
                [0, 1, 2].map(|r| f(h.srow[r][3])),
                AffineSource::Sform,
            )
        } else if h.qform_code > 0 {
            let r = rotation(h.quatern.map(f64::from));
            let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
            let scale = [f(h.pixdim[1]), f(h.pixdim[2]), qfac * f(h.pixdim[3])];
            let linear = [0, 1, 2].map(|row| [0, 1, 2].map(|c| r[row][c] * scale[c]));
            (linear, h.qoffset.map(f), AffineSource::Qform)
        } else {
            let mut linear = [[0.0; 3]; 3];
            for (a, row) in linear.iter_mut().enumerate() {
                row[a] = f(h.pixdim[a + 1]);
            }
            (linear, [0.0; 3], AffineSource::Pixdim)
        };
        let affine = Self {
            linear,
            offset,
            source,
        };
        affine.check()?;
        Ok(affine)
    }

    fn check(&self) -> Result<(), NiftiError> {
        let finite = self
            .linear
            .iter()
            .flatten()
            .chain(&self.offset)
            .all(|v| v.is_finite());
        if !finite {
            return Err(NiftiError::parse(
                "the voxel-to-world transform has a non-finite entry; fix the sform/qform",
            ));
        }
        if self.determinant().abs() < MIN_VOXEL_VOLUME_MM3 {
            return Err(NiftiError::parse(format!(
                "the voxel-to-world transform ({:?}) is singular (voxel volume {:.3e} mm³); \
                 fix the voxel sizes (pixdim) or the sform/qform",
                self.source,
                self.determinant().abs()
            )));
        }
        Ok(())
    }

    /// World position (mm) of a continuous voxel index.
    pub fn apply(&self, u: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|r| {
            self.offset[r]
                + self.linear[r][0] * u[0]
                + self.linear[r][1] * u[1]
                + self.linear[r][2] * u[2]
        })
    }

    /// Length (mm) of one voxel step along each index axis.
    pub fn spacing_mm(&self) -> [f64; 3] {
        [0, 1, 2].map(|c| {
            (0..3)
                .map(|r| self.linear[r][c].powi(2))
                .sum::<f64>()
                .sqrt()
        })
    }

    /// Determinant of the linear part: ± the voxel volume in mm³; negative for a mirroring map.
    pub fn determinant(&self) -> f64 {
        let m = &self.linear;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    /// Volume of one voxel, mm³.
    pub fn voxel_volume_mm3(&self) -> f64 {
        self.determinant().abs()
    }
}

/// Rotation of the unit quaternion `(a, b, c, d)` with `a = sqrt(1 − b² − c² − d²)`
/// (NIfTI-1 header documentation, method 2).
fn rotation([b, c, d]: [f64; 3]) -> [[f64; 3]; 3] {
    let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
    [
        [
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
        ],
        [
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
        ],
        [
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        ],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> SpatialHeader {
        SpatialHeader {
            pixdim: [1.0, 0.8, 0.9, 3.0],
            mm_per_unit: 1.0,
            ..SpatialHeader::default()
        }
    }

    #[test]
    fn sform_wins_over_qform_and_permutes_axes() {
        let mut h = header();
        h.sform_code = 1;
        h.qform_code = 1;
        h.srow = [
            [0.0, 0.0, -0.9, 10.0],
            [0.0, -0.8, 0.0, 20.0],
            [-3.0, 0.0, 0.0, 30.0],
        ];
        let a = Affine::from_header(&h).unwrap();
        assert_eq!(a.source, AffineSource::Sform);
        let (p, s) = (a.apply([1.0, 2.0, 3.0]), a.spacing_mm());
        for k in 0..3 {
            assert!((p[k] - [7.3, 18.4, 27.0][k]).abs() < 1e-5, "{p:?}");
            assert!((s[k] - [3.0, 0.8, 0.9][k]).abs() < 1e-6, "{s:?}");
        }
        // Swapping i and k and flipping all three: a proper rotation times scaling.
        assert!((a.determinant() - 3.0 * 0.8 * 0.9).abs() < 1e-6);
    }

    #[test]
    fn qform_with_a_half_turn_and_negative_qfac() {
        let mut h = header();
        h.qform_code = 1;
        // b = 0, c = 0, d = 1: a half turn about z, x → −x, y → −y.
        h.quatern = [0.0, 0.0, 1.0];
        h.qoffset = [5.0, 6.0, 7.0];
        h.pixdim[0] = -1.0;
        let a = Affine::from_header(&h).unwrap();
        assert_eq!(a.source, AffineSource::Qform);
        let p = a.apply([1.0, 1.0, 1.0]);
        let expect = [5.0 - 0.8, 6.0 - 0.9, 7.0 - 3.0];
        for k in 0..3 {
            assert!((p[k] - expect[k]).abs() < 1e-6, "{p:?}");
        }
        assert!(a.determinant() < 0.0, "qfac −1 mirrors the third axis");
    }

    #[test]
    fn pixdim_only_and_units() {
        let mut h = header();
        h.mm_per_unit = 1000.0;
        h.pixdim = [1.0, 0.001, 0.002, 0.003];
        let a = Affine::from_header(&h).unwrap();
        assert_eq!(a.source, AffineSource::Pixdim);
        let s = a.spacing_mm();
        assert!(
            (s[0] - 1.0).abs() < 1e-6 && (s[2] - 3.0).abs() < 1e-6,
            "{s:?}"
        );
    }

    #[test]
    fn singular_or_non_finite_transforms_are_refused() {
        let mut h = header();
        h.pixdim[2] = 0.0;
        assert_eq!(
            Affine::from_header(&h).unwrap_err().code(),
            "nifti.parse_error"
        );
        let mut h = header();
        h.sform_code = 2;
        h.srow[0][0] = f32::NAN;
        assert_eq!(
            Affine::from_header(&h).unwrap_err().code(),
            "nifti.parse_error"
        );
    }
}
