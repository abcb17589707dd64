//! Isotropic resampling of a voxel mask (trilinear) and Gaussian smoothing of the result.
//!
//! The sample grid lies in the volume's index frame, with the same step in millimetres
//! along every index axis, centred on the mask so that a flipped or permuted volume of the
//! same object is sampled at the same world positions.

use super::error::NiftiError;
use super::field::{Field, Mask, cell_count, linear};

/// Samples kept between the smoothed object and the grid's border, beyond the kernel.
const BORDER_SAMPLES: usize = 2;
/// The Gaussian kernel is cut at this many standard deviations.
pub const KERNEL_SIGMAS: f64 = 3.0;

/// An isotropic grid of samples in the volume's index frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleGrid {
    /// Samples along each index axis.
    pub dims: [usize; 3],
    /// Volume index (continuous) of sample `[0, 0, 0]`.
    pub start: [f64; 3],
    /// Volume index step between neighbouring samples along each axis.
    pub step: [f64; 3],
}

impl SampleGrid {
    /// Plans a grid of `voxel_mm` spacing covering voxels `lo..=hi` (volume indices) of a
    /// volume with `spacing_mm` per index step, with room for a Gaussian of `sigma_mm`.
    pub fn plan(
        (lo, hi): ([i64; 3], [i64; 3]),
        spacing_mm: [f64; 3],
        voxel_mm: f64,
        sigma_mm: f64,
        max_samples: u64,
    ) -> Result<Self, NiftiError> {
        let radius_mm = kernel_radius(sigma_mm / voxel_mm) as f64 * voxel_mm;
        let mut dims = [0usize; 3];
        let mut start = [0.0; 3];
        let mut step = [0.0; 3];
        for a in 0..3 {
            let centre = (lo[a] + hi[a]) as f64 / 2.0;
            // One voxel of interpolation support, the kernel, and a border of samples.
            let pad_mm = spacing_mm[a] + radius_mm + BORDER_SAMPLES as f64 * voxel_mm;
            let half_mm = (hi[a] - lo[a]) as f64 / 2.0 * spacing_mm[a] + pad_mm;
            let half = (half_mm / voxel_mm).ceil();
            if !half.is_finite() || half > u32::MAX as f64 {
                return Err(too_many(u64::MAX, max_samples));
            }
            dims[a] = 2 * half as usize + 1;
            step[a] = voxel_mm / spacing_mm[a];
            start[a] = centre - half * step[a];
        }
        let count = cell_count(dims).map_or(u64::MAX, |n| n as u64);
        if count > max_samples {
            return Err(too_many(count, max_samples));
        }
        Ok(Self { dims, start, step })
    }

    /// Volume index (continuous) of grid position `g` (sample units).
    pub fn volume_index(&self, g: [f64; 3]) -> [f64; 3] {
        [0, 1, 2].map(|a| self.start[a] + g[a] * self.step[a])
    }
}

fn too_many(count: u64, limit: u64) -> NiftiError {
    NiftiError::TooLarge {
        what: "the resampled grid",
        count,
        limit,
        fix: "raise voxel_mm or select a smaller structure",
    }
}

/// Kernel radius in samples for a standard deviation in samples.
fn kernel_radius(sigma: f64) -> usize {
    if sigma > 0.0 {
        (KERNEL_SIGMAS * sigma).ceil() as usize
    } else {
        0
    }
}

/// The mask (1 inside, 0 outside) interpolated trilinearly at every sample of `grid`.
pub fn resample(mask: &Mask, grid: &SampleGrid) -> Field {
    // Per axis: the lower voxel and the weight of the upper one, for each sample.
    let taps: [Vec<(i64, f32)>; 3] = [0, 1, 2].map(|a| {
        (0..grid.dims[a])
            .map(|j| {
                let u = grid.start[a] + j as f64 * grid.step[a];
                let lower = u.floor();
                (lower as i64, (u - lower) as f32)
            })
            .collect()
    });
    let mut values = vec![0f32; cell_count(grid.dims).unwrap_or(0)];
    for (z, &(k, tz)) in taps[2].iter().enumerate() {
        for (y, &(j, ty)) in taps[1].iter().enumerate() {
            for (x, &(i, tx)) in taps[0].iter().enumerate() {
                let mut v = 0.0;
                for corner in 0..8 {
                    let d = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
                    if mask.at_volume_index([i + d[0] as i64, j + d[1] as i64, k + d[2] as i64]) {
                        let w = |t: f32, up: usize| if up == 1 { t } else { 1.0 - t };
                        v += w(tx, d[0]) * w(ty, d[1]) * w(tz, d[2]);
                    }
                }
                values[linear(grid.dims, [x, y, z])] = v;
            }
        }
    }
    Field {
        dims: grid.dims,
        values,
    }
}

/// Gaussian smoothing with standard deviation `sigma` (in samples), separable, with zeros
/// beyond the border; `sigma` ≤ 0 leaves the field as it is.
pub fn smooth(field: &mut Field, sigma: f64) {
    let radius = kernel_radius(sigma);
    if radius == 0 {
        return;
    }
    let raw: Vec<f64> = (0..=2 * radius)
        .map(|i| (-((i as f64 - radius as f64).powi(2)) / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = raw.iter().sum();
    let kernel: Vec<f32> = raw.iter().map(|w| (w / total) as f32).collect();
    for axis in 0..3 {
        convolve_axis(field, &kernel, axis);
    }
}

fn convolve_axis(field: &mut Field, kernel: &[f32], axis: usize) {
    let dims = field.dims;
    let n = dims[axis];
    let radius = kernel.len() / 2;
    let (u, v) = match axis {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let mut line = vec![0f32; n];
    for q in 0..dims[v] {
        for p in 0..dims[u] {
            let at = |s: usize| {
                let mut c = [0; 3];
                (c[axis], c[u], c[v]) = (s, p, q);
                linear(dims, c)
            };
            for (s, l) in line.iter_mut().enumerate() {
                *l = field.values[at(s)];
            }
            for s in 0..n {
                let from = s.saturating_sub(radius);
                let to = (s + radius).min(n - 1);
                let mut acc = 0.0;
                for t in from..=to {
                    acc += kernel[t + radius - s] * line[t];
                }
                field.values[at(s)] = acc;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_is_centred_isotropic_and_padded() {
        let g = SampleGrid::plan(
            ([10, 20, 5], [20, 40, 7]),
            [0.5, 1.0, 3.0],
            1.5,
            1.0,
            1 << 30,
        )
        .unwrap();
        assert_eq!(g.step, [3.0, 1.5, 0.5]);
        for a in 0..3 {
            let mid = g.start[a] + (g.dims[a] - 1) as f64 / 2.0 * g.step[a];
            assert!((mid - [15.0, 30.0, 6.0][a]).abs() < 1e-9);
            assert_eq!(g.dims[a] % 2, 1);
        }
        // Axis 2: 6 mm wide, padded by 3 mm (a voxel) + 3 mm (kernel) + 3 mm (border).
        assert_eq!(g.dims[2], 2 * (12.0f64 / 1.5).ceil() as usize + 1);
        let e = SampleGrid::plan(([0; 3], [500; 3]), [1.0; 3], 0.1, 0.0, 1 << 20).unwrap_err();
        assert_eq!(e.code(), "nifti.too_large");
    }

    #[test]
    fn trilinear_values_halfway_between_voxels() {
        let mut mask = Mask::empty([3, 3, 3], [0; 3]);
        mask.inside[linear([3, 3, 3], [1, 1, 1])] = true;
        let grid = SampleGrid {
            dims: [3, 1, 1],
            start: [0.5, 1.0, 1.0],
            step: [0.5, 1.0, 1.0],
        };
        let f = resample(&mask, &grid);
        assert_eq!(f.values, vec![0.5, 1.0, 0.5]);
    }

    #[test]
    fn smoothing_keeps_the_total_and_spreads_a_spike() {
        let dims = [21, 21, 21];
        let mut values = vec![0f32; 21 * 21 * 21];
        values[linear(dims, [10, 10, 10])] = 1.0;
        let mut f = Field { dims, values };
        smooth(&mut f, 1.5);
        let total: f32 = f.values.iter().sum();
        assert!((total - 1.0).abs() < 1e-5, "{total}");
        assert!(f.at([10, 10, 10]) < 0.1 && f.at([11, 10, 10]) > 0.0);
        assert!(
            (f.at([11, 10, 10]) - f.at([10, 9, 10])).abs() < 1e-7,
            "isotropic"
        );
        assert_eq!(f.at([0, 0, 0]), 0.0);
    }
}
