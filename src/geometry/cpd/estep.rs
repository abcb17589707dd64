//! CPD E-step: the posterior `P` (eq. 3.7) of template centroids given data points.
//!
//! Only the sums `P·1`, `Pᵀ·1` and `P·X` are needed by the M-step and by soft
//! correspondences, so they are accumulated column by column (one data point at a time)
//! without storing `P`. Columns are cut into a fixed number of blocks that depend only on
//! `N`; blocks run on scoped threads and their partial sums are added in block order, so
//! the result is bit-identical whatever the number of threads.

use std::ops::Range;

use crate::geometry::points::{self, dist2};

/// Number of column blocks (fixed, so the summation order never depends on threads).
const COLUMN_BLOCKS: usize = 16;
/// Below this many kernel evaluations a single thread is used.
const PARALLEL_MIN_WORK: usize = 200_000;
/// Kernel values `exp(−x)` with `x` beyond this are set to zero: they are below 2·10⁻²² of
/// the largest entry of the column (which is 1 after the shift), far under `f64` resolution
/// of the column sum even for 10⁵ template points; clamping also avoids subnormals.
const EXP_NEGLIGIBLE: f64 = 50.0;

/// Sums of the posterior `P` (`[M, N]`, `P[m][n] = p(yₘ | xₙ)`), without `P` itself.
#[derive(Debug, Clone, PartialEq)]
pub struct PosteriorSums {
    /// `P·1`, `[M]`: total responsibility of each template point.
    pub p1: Vec<f64>,
    /// `Pᵀ·1`, `[N]`: share of each data point explained by the template (1 − outlier share).
    pub pt1: Vec<f64>,
    /// `P·X`, `[M]` of 3-vectors, in the coordinates of the data given.
    pub px: Vec<[f64; 3]>,
    /// Negative log-likelihood `−Σₙ ln p(xₙ)` of the data under the mixture of eq. 3.2.
    pub negative_log_likelihood: f64,
}

/// Constants of one E-step.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Kernel {
    /// `1 / (2σ²)`.
    inv_two_sigma2: f64,
    /// Outlier term `c = (2πσ²)^{3/2}·w/(1−w)·M/N`.
    outlier: f64,
}

impl Kernel {
    pub(crate) fn new(sigma2: f64, w: f64, m: usize, n: usize) -> Self {
        let outlier =
            (2.0 * std::f64::consts::PI * sigma2).powf(1.5) * w / (1.0 - w) * m as f64 / n as f64;
        Self {
            inv_two_sigma2: 0.5 / sigma2,
            outlier,
        }
    }

    /// Fills `k` with the unnormalised column `exp(−(‖x − zₘ‖² − d²_min)/2σ²)` (shifted so
    /// that its largest entry is 1) and returns `(normaliser, ln_denominator, Σₘ k[m])` with
    /// `P[m][n] = k[m] / normaliser` and `ln_denominator = ln(Σₘ exp(−‖x − zₘ‖²/2σ²) + c)`.
    #[inline(always)]
    pub(crate) fn column(&self, moved: &[[f64; 3]], x: [f64; 3], k: &mut [f64]) -> (f64, f64, f64) {
        // Element-wise loops without reductions vectorise; reductions run over fixed lanes.
        for (km, z) in k.iter_mut().zip(moved) {
            *km = dist2(x, *z);
        }
        let d2_min = lane_min(k);
        for km in k.iter_mut() {
            let e = (*km - d2_min) * self.inv_two_sigma2;
            let v = exp_neg(e.min(EXP_NEGLIGIBLE));
            *km = if e > EXP_NEGLIGIBLE { 0.0 } else { v };
        }
        let sum = lane_sum(k);
        let shift = d2_min * self.inv_two_sigma2;
        let outlier_shifted = if self.outlier > 0.0 {
            self.outlier * shift.exp()
        } else {
            0.0
        };
        if outlier_shifted.is_finite() {
            let normaliser = sum + outlier_shifted;
            (normaliser, normaliser.ln() - shift, sum)
        } else {
            // The point is so far from every centroid that it is a pure outlier.
            (f64::INFINITY, self.outlier.ln(), sum)
        }
    }
}

/// `exp(−e)` for `e` in `[0, EXP_NEGLIGIBLE]`, to a few ulp, in plain arithmetic that the
/// compiler vectorises (the E-step spends most of its time here; libm's `exp` is scalar).
///
/// Range reduction `−e = k·ln2 + r` with `|r| ≤ ln2/2`, a degree-12 Taylor polynomial for
/// `exp(r)` (truncation below 1e-16 relative), and `2^k` built from the exponent bits.
#[inline(always)]
pub(crate) fn exp_neg(e: f64) -> f64 {
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    // Adding then subtracting 1.5·2⁵² rounds to the nearest integer without a branch.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    let x = -e;
    let t = x * std::f64::consts::LOG2_E + ROUND;
    let k = t - ROUND;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let mut p = 1.0 / 479_001_600.0;
    for d in [
        39_916_800.0,
        3_628_800.0,
        362_880.0,
        40_320.0,
        5_040.0,
        720.0,
        120.0,
        24.0,
        6.0,
        2.0,
        1.0,
        1.0,
    ] {
        p = p * r + 1.0 / d;
    }
    // The low mantissa bits of `t` hold k (two's complement); shifted into the exponent
    // field and biased, they make 2^k, a normal number for k ∈ [−73, 0].
    let two_k = f64::from_bits(t.to_bits().wrapping_shl(52).wrapping_add(1023 << 52));
    p * two_k
}

/// Independent partial reductions, so the order of additions is fixed and loops vectorise.
const LANES: usize = 4;

/// `Σ v` over [`LANES`] interleaved partial sums.
#[inline(always)]
fn lane_sum(v: &[f64]) -> f64 {
    let mut acc = [0.0; LANES];
    let chunks = v.chunks_exact(LANES);
    let tail: f64 = chunks.remainder().iter().sum();
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a += x;
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// `min v` (∞ for an empty slice; inputs are never NaN here).
#[inline(always)]
fn lane_min(v: &[f64]) -> f64 {
    let mut acc = [f64::INFINITY; LANES];
    let chunks = v.chunks_exact(LANES);
    let tail = chunks
        .remainder()
        .iter()
        .fold(f64::INFINITY, |m, x| if *x < m { *x } else { m });
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a = if *x < *a { *x } else { *a };
        }
    }
    acc.iter().fold(tail, |m, x| if *x < m { *x } else { m })
}

/// Partial sums over one block of columns.
struct Partial {
    p1: Vec<f64>,
    px: Vec<[f64; 3]>,
    pt1: Vec<f64>,
    ln_denominators: f64,
}

fn block_ranges(n: usize) -> Vec<Range<usize>> {
    let blocks = COLUMN_BLOCKS.min(n).max(1);
    (0..blocks)
        .map(|b| (b * n / blocks)..((b + 1) * n / blocks))
        .collect()
}

/// Partial sums over the columns `cols`: on x86-64 CPUs with AVX2 (most since 2013) the same
/// arithmetic compiled for 4-wide vectors, otherwise for the baseline 2-wide ones. No
/// fused multiply-adds either way, so both give the same bits.
fn accumulate(
    moved: &[[f64; 3]],
    data: &[[f64; 3]],
    cols: Range<usize>,
    kernel: Kernel,
) -> Partial {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        return unsafe { accumulate_avx2(moved, data, cols, kernel) };
    }
    accumulate_baseline(moved, data, cols, kernel)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn accumulate_avx2(
    moved: &[[f64; 3]],
    data: &[[f64; 3]],
    cols: Range<usize>,
    kernel: Kernel,
) -> Partial {
    accumulate_baseline(moved, data, cols, kernel)
}

#[inline(always)]
fn accumulate_baseline(
    moved: &[[f64; 3]],
    data: &[[f64; 3]],
    cols: Range<usize>,
    kernel: Kernel,
) -> Partial {
    let m = moved.len();
    let mut part = Partial {
        p1: vec![0.0; m],
        px: vec![[0.0; 3]; m],
        pt1: Vec::with_capacity(cols.len()),
        ln_denominators: 0.0,
    };
    let mut k = vec![0.0; m];
    for x in &data[cols] {
        let (normaliser, ln_den, kernel_sum) = kernel.column(moved, *x, &mut k);
        part.ln_denominators += ln_den;
        let inv = 1.0 / normaliser;
        for ((km, p1), px) in k.iter().zip(&mut part.p1).zip(&mut part.px) {
            let p = km * inv;
            *p1 += p;
            *px = points::add(*px, points::scale(*x, p));
        }
        part.pt1.push(kernel_sum * inv);
    }
    part
}

fn thread_count(work: usize, blocks: usize) -> usize {
    if work < PARALLEL_MIN_WORK {
        return 1;
    }
    std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(blocks)
}

/// Posterior sums for the moved template `moved = T(Y)` (`[M, 3]`) and data `X` (`[N, 3]`).
///
/// Inputs must be non-empty and finite, `sigma2 > 0`, `0 ≤ w < 1` (checked by callers).
pub(crate) fn posterior_sums_moved(
    moved: &[[f64; 3]],
    data: &[[f64; 3]],
    sigma2: f64,
    w: f64,
) -> PosteriorSums {
    let (m, n) = (moved.len(), data.len());
    let kernel = Kernel::new(sigma2, w, m, n);
    let ranges = block_ranges(n);
    let threads = thread_count(m * n, ranges.len());
    let mut partials: Vec<Option<Partial>> = ranges.iter().map(|_| None).collect();
    if threads <= 1 {
        for (slot, r) in partials.iter_mut().zip(&ranges) {
            *slot = Some(accumulate(moved, data, r.clone(), kernel));
        }
    } else {
        let per_thread = ranges.len().div_ceil(threads);
        std::thread::scope(|scope| {
            for (slots, rs) in partials
                .chunks_mut(per_thread)
                .zip(ranges.chunks(per_thread))
            {
                scope.spawn(move || {
                    for (slot, r) in slots.iter_mut().zip(rs) {
                        *slot = Some(accumulate(moved, data, r.clone(), kernel));
                    }
                });
            }
        });
    }
    let mut sums = PosteriorSums {
        p1: vec![0.0; m],
        pt1: Vec::with_capacity(n),
        px: vec![[0.0; 3]; m],
        negative_log_likelihood: 0.0,
    };
    let mut ln_denominators = 0.0;
    for part in partials.into_iter().flatten() {
        for (a, b) in sums.p1.iter_mut().zip(&part.p1) {
            *a += b;
        }
        for (a, b) in sums.px.iter_mut().zip(&part.px) {
            *a = points::add(*a, *b);
        }
        sums.pt1.extend_from_slice(&part.pt1);
        ln_denominators += part.ln_denominators;
    }
    // −ln p(xₙ) = −ln(Σₘ kₘₙ + c) + (3/2)·ln(2πσ²) − ln((1−w)/M), eqs. 3.2–3.3.
    let per_point = 1.5 * (2.0 * std::f64::consts::PI * sigma2).ln() - ((1.0 - w) / m as f64).ln();
    sums.negative_log_likelihood = n as f64 * per_point - ln_denominators;
    sums
}

/// The dense posterior `P`, `[M, N]` row-major (`P[m·N + n]`), for the moved template.
pub(crate) fn dense_posterior_moved(
    moved: &[[f64; 3]],
    data: &[[f64; 3]],
    sigma2: f64,
    w: f64,
) -> Vec<f64> {
    let (m, n) = (moved.len(), data.len());
    let kernel = Kernel::new(sigma2, w, m, n);
    let mut p = vec![0.0; m * n];
    let mut k = vec![0.0; m];
    for (col, x) in data.iter().enumerate() {
        let (normaliser, _, _) = kernel.column(moved, *x, &mut k);
        for (row, km) in k.iter().enumerate() {
            p[row * n + col] = km / normaliser;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_exponential_matches_libm() {
        let mut worst: f64 = 0.0;
        for i in 0..=500_000 {
            let e = EXP_NEGLIGIBLE * i as f64 / 500_000.0;
            let exact = (-e).exp();
            worst = worst.max((exp_neg(e) - exact).abs() / exact);
        }
        assert!(worst < 1e-14, "largest relative error {worst}");
        assert_eq!(exp_neg(0.0), 1.0);
    }

    /// Direct evaluation of eq. 3.7 for one entry.
    fn direct(moved: &[[f64; 3]], data: &[[f64; 3]], s2: f64, w: f64, m: usize, n: usize) -> f64 {
        let c = (2.0 * std::f64::consts::PI * s2).powf(1.5) * w / (1.0 - w) * moved.len() as f64
            / data.len() as f64;
        let k = |a: [f64; 3], b: [f64; 3]| (-dist2(a, b) / (2.0 * s2)).exp();
        let den: f64 = moved.iter().map(|z| k(data[n], *z)).sum::<f64>() + c;
        k(data[n], moved[m]) / den
    }

    #[test]
    fn sums_match_direct_evaluation() {
        let moved = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
        let data = [
            [0.1, 0.0, 0.0],
            [0.9, 0.2, 0.0],
            [0.0, 1.5, 0.3],
            [3.0, 3.0, 3.0],
        ];
        let (s2, w) = (0.5, 0.2);
        let sums = posterior_sums_moved(&moved, &data, s2, w);
        let dense = dense_posterior_moved(&moved, &data, s2, w);
        let mut nll = 0.0;
        for n in 0..4 {
            let mut col = 0.0;
            for m in 0..3 {
                let p = direct(&moved, &data, s2, w, m, n);
                assert!((dense[m * 4 + n] - p).abs() < 1e-14);
                col += p;
            }
            assert!((sums.pt1[n] - col).abs() < 1e-14);
            // p(x) = w/N + (1−w)/M·Σ N(x; zₘ, σ²I).
            let gauss: f64 = moved
                .iter()
                .map(|z| {
                    (-dist2(data[n], *z) / (2.0 * s2)).exp()
                        / (2.0 * std::f64::consts::PI * s2).powf(1.5)
                })
                .sum();
            nll -= (w / 4.0 + (1.0 - w) / 3.0 * gauss).ln();
        }
        for m in 0..3 {
            let row: f64 = (0..4).map(|n| direct(&moved, &data, s2, w, m, n)).sum();
            assert!((sums.p1[m] - row).abs() < 1e-14);
            let px0: f64 = (0..4)
                .map(|n| direct(&moved, &data, s2, w, m, n) * data[n][0])
                .sum();
            assert!((sums.px[m][0] - px0).abs() < 1e-14);
        }
        assert!((sums.negative_log_likelihood - nll).abs() < 1e-10 * nll.abs());
    }

    #[test]
    fn far_outlier_without_uniform_term_is_finite() {
        let moved = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
        let data = [[1e4, 0.0, 0.0]];
        let sums = posterior_sums_moved(&moved, &data, 1e-3, 0.0);
        assert!(sums.negative_log_likelihood.is_finite());
        // The whole column goes to the nearer centroid.
        assert!((sums.p1[1] - 1.0).abs() < 1e-12 && sums.p1[0] == 0.0);
    }

    #[test]
    fn threaded_and_serial_agree_bitwise() {
        let moved: Vec<[f64; 3]> = (0..600)
            .map(|i| {
                let t = i as f64 * 0.01;
                [t.cos() * 10.0, t.sin() * 7.0, t]
            })
            .collect();
        let data: Vec<[f64; 3]> = moved
            .iter()
            .map(|p| [p[0] + 0.3, p[1] - 0.2, p[2] * 1.1])
            .collect();
        let all = posterior_sums_moved(&moved, &data, 2.0, 0.1);
        // Serial reference: blocks in order on this thread.
        let kernel = Kernel::new(2.0, 0.1, moved.len(), data.len());
        let mut p1 = vec![0.0; moved.len()];
        for r in block_ranges(data.len()) {
            let part = accumulate(&moved, &data, r, kernel);
            for (a, b) in p1.iter_mut().zip(&part.p1) {
                *a += b;
            }
        }
        assert_eq!(all.p1, p1);
    }
}
