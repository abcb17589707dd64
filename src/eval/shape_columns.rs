//! Shapes in correspondence stored as three coordinate columns, and the sum of distances
//! between corresponding vertices over a range of vertices: the inner loop of the privacy
//! guard. Coordinates are kept in single precision (a micrometre at most on shapes of tens
//! of centimetres, far below any privacy threshold) so that eight square roots run at once
//! with AVX2; the CPU-independent path performs the same operations, so every CPU gives the
//! same bits.

use std::ops::Range;

/// One shape's coordinates as columns `x`, `y`, `z` (`[n_vertices]` each, mm).
#[derive(Debug, Clone, PartialEq)]
pub struct ShapeColumns {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
}

/// Lanes summed separately, then added in a fixed order.
const LANES: usize = 8;

impl ShapeColumns {
    /// From vertices `[n_vertices, 3]`, mm.
    pub fn new(vertices: &[[f64; 3]]) -> Self {
        Self {
            x: vertices.iter().map(|p| p[0] as f32).collect(),
            y: vertices.iter().map(|p| p[1] as f32).collect(),
            z: vertices.iter().map(|p| p[2] as f32).collect(),
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether the shape has no vertex.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Sum over `range` of the distances (mm) between corresponding vertices of `self` and
    /// `other` (equal lengths; the range must lie within them). The same inputs give the
    /// same bits on every CPU.
    pub fn distance_sum(&self, other: &Self, range: Range<usize>) -> f64 {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { distance_sum_avx2(self, other, range) };
        }
        distance_sum_baseline(self, other, range)
    }
}

/// [`distance_sum_baseline`] eight lanes at a time: the same operations in the same order
/// per lane (no fused multiply-add), so the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn distance_sum_avx2(a: &ShapeColumns, b: &ShapeColumns, range: Range<usize>) -> f64 {
    use std::arch::x86_64::{
        _mm256_add_ps, _mm256_loadu_ps, _mm256_mul_ps, _mm256_setzero_ps, _mm256_sqrt_ps,
        _mm256_storeu_ps, _mm256_sub_ps,
    };
    let (start, end) = (range.start, range.end);
    assert!(start <= end && end <= a.len() && end <= b.len());
    let whole = start + (end - start) / LANES * LANES;
    let mut acc = _mm256_setzero_ps();
    let mut i = start;
    while i < whole {
        // SAFETY: i + LANES <= whole <= end, within all six columns (asserted above).
        unsafe {
            let dx = _mm256_sub_ps(
                _mm256_loadu_ps(a.x.as_ptr().add(i)),
                _mm256_loadu_ps(b.x.as_ptr().add(i)),
            );
            let dy = _mm256_sub_ps(
                _mm256_loadu_ps(a.y.as_ptr().add(i)),
                _mm256_loadu_ps(b.y.as_ptr().add(i)),
            );
            let dz = _mm256_sub_ps(
                _mm256_loadu_ps(a.z.as_ptr().add(i)),
                _mm256_loadu_ps(b.z.as_ptr().add(i)),
            );
            let squared = _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                _mm256_mul_ps(dz, dz),
            );
            acc = _mm256_add_ps(acc, _mm256_sqrt_ps(squared));
        }
        i += LANES;
    }
    let mut lanes = [0.0f32; LANES];
    // SAFETY: `lanes` holds eight f32.
    unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), acc) };
    reduce(lanes) + tail_sum(a, b, whole..end)
}

fn distance_sum_baseline(a: &ShapeColumns, b: &ShapeColumns, range: Range<usize>) -> f64 {
    let (start, end) = (range.start, range.end);
    let whole = start + (end - start) / LANES * LANES;
    let mut lanes = [0.0f32; LANES];
    for i in (start..whole).step_by(LANES) {
        for (l, lane) in lanes.iter_mut().enumerate() {
            *lane += vertex_distance(a, b, i + l);
        }
    }
    reduce(lanes) + tail_sum(a, b, whole..end)
}

/// Distance between vertex `i` of `a` and of `b`, single precision.
#[inline(always)]
fn vertex_distance(a: &ShapeColumns, b: &ShapeColumns, i: usize) -> f32 {
    let (dx, dy, dz) = (a.x[i] - b.x[i], a.y[i] - b.y[i], a.z[i] - b.z[i]);
    (dx * dx + dy * dy + dz * dz).sqrt()
}

/// The lanes' sum, in double precision and a fixed order.
fn reduce(lanes: [f32; LANES]) -> f64 {
    let l = lanes.map(f64::from);
    ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7]))
}

/// Sum of the distances over `range`, one vertex at a time.
fn tail_sum(a: &ShapeColumns, b: &ShapeColumns, range: Range<usize>) -> f64 {
    range.map(|i| f64::from(vertex_distance(a, b, i))).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_the_distances_of_corresponding_vertices_in_a_range() {
        // Vertex i of b is vertex i of a moved by i mm along x (and 0.5 mm along z for i = 5).
        let a: Vec<[f64; 3]> = (0..7).map(|i| [i as f64, 2.0, -1.0]).collect();
        let mut b: Vec<[f64; 3]> = a
            .iter()
            .enumerate()
            .map(|(i, p)| [p[0] + i as f64, p[1], p[2]])
            .collect();
        b[5] = [a[5][0] + 3.0, 2.0, -1.0 + 4.0];
        let (a, b) = (ShapeColumns::new(&a), ShapeColumns::new(&b));
        // 0 + 1 + 2 + 3 + 4 + 5 (a 3-4-5 triangle) + 6.
        assert_eq!(a.distance_sum(&b, 0..7), 21.0);
        assert_eq!(a.distance_sum(&b, 2..5), 9.0);
        assert_eq!(a.distance_sum(&b, 3..3), 0.0);
        assert_eq!(
            distance_sum_baseline(&a, &b, 0..7),
            a.distance_sum(&b, 0..7)
        );
    }
}
