//! Regular 3-D grids: a binary mask of voxels and a scalar field of samples, x fastest.

/// Position of `[x, y, z]` in a grid of `dims`, x fastest: `x + nx (y + ny z)`.
#[inline]
pub(crate) fn linear(dims: [usize; 3], [x, y, z]: [usize; 3]) -> usize {
    x + dims[0] * (y + dims[1] * z)
}

/// Number of cells of a grid, `None` on overflow.
pub(crate) fn cell_count(dims: [usize; 3]) -> Option<usize> {
    dims[0].checked_mul(dims[1])?.checked_mul(dims[2])
}

/// A binary mask on a box of voxels of a volume.
///
/// Voxel `[a, b, c]` of the mask is voxel `origin + [a, b, c]` of the volume; the origin may
/// lie outside the volume (a margin of background around the data).
#[derive(Debug, Clone, PartialEq)]
pub struct Mask {
    /// Voxels along each axis, `[nx, ny, nz]`.
    pub dims: [usize; 3],
    /// Volume index of the mask's first voxel.
    pub origin: [i64; 3],
    /// Inside (`true`) or outside, `[nx * ny * nz]`, x fastest.
    pub inside: Vec<bool>,
}

impl Mask {
    /// An all-outside mask.
    pub fn empty(dims: [usize; 3], origin: [i64; 3]) -> Self {
        let n = dims[0] * dims[1] * dims[2];
        Self {
            dims,
            origin,
            inside: vec![false; n],
        }
    }

    /// Number of inside voxels.
    pub fn count(&self) -> usize {
        self.inside.iter().filter(|&&v| v).count()
    }

    /// Whether volume voxel `index` (volume coordinates) is inside; outside the box it is not.
    pub fn at_volume_index(&self, index: [i64; 3]) -> bool {
        let mut local = [0usize; 3];
        for a in 0..3 {
            let l = index[a] - self.origin[a];
            if l < 0 || l >= self.dims[a] as i64 {
                return false;
            }
            local[a] = l as usize;
        }
        self.inside[linear(self.dims, local)]
    }

    /// Smallest and largest volume index of an inside voxel per axis, `None` when empty.
    pub fn bounds(&self) -> Option<([i64; 3], [i64; 3])> {
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        let [nx, ny, _] = self.dims;
        for (i, _) in self.inside.iter().enumerate().filter(|(_, v)| **v) {
            let local = [i % nx, (i / nx) % ny, i / (nx * ny)];
            for a in 0..3 {
                let v = self.origin[a] + local[a] as i64;
                lo[a] = lo[a].min(v);
                hi[a] = hi[a].max(v);
            }
        }
        (lo[0] <= hi[0]).then_some((lo, hi))
    }
}

/// A scalar field sampled on a regular grid, x fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Samples along each axis, `[nx, ny, nz]`.
    pub dims: [usize; 3],
    /// Values, `[nx * ny * nz]`.
    pub values: Vec<f32>,
}

impl Field {
    /// Value at sample `[x, y, z]`.
    #[inline]
    pub fn at(&self, p: [usize; 3]) -> f32 {
        self.values[linear(self.dims, p)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_index_is_x_fastest() {
        assert_eq!(linear([4, 3, 2], [1, 0, 0]), 1);
        assert_eq!(linear([4, 3, 2], [0, 1, 0]), 4);
        assert_eq!(linear([4, 3, 2], [3, 2, 1]), 23);
        assert_eq!(cell_count([usize::MAX, 2, 1]), None);
    }

    #[test]
    fn mask_bounds_are_in_volume_coordinates() {
        let mut m = Mask::empty([4, 3, 2], [-1, 5, 10]);
        assert_eq!(m.bounds(), None);
        m.inside[linear([4, 3, 2], [1, 2, 0])] = true;
        m.inside[linear([4, 3, 2], [3, 0, 1])] = true;
        assert_eq!(m.bounds(), Some(([0, 5, 10], [2, 7, 11])));
        assert!(m.at_volume_index([0, 7, 10]));
        assert!(!m.at_volume_index([0, 7, 11]));
        assert!(!m.at_volume_index([-2, 7, 10]));
        assert_eq!(m.count(), 2);
    }
}
