//! The standard normal distribution: its distribution function, its quantile function and
//! draws truncated to an interval (by inversion, exact at any distance from the mean).

/// `Φ(x)`, the standard normal distribution function.
pub fn cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
}

/// The density `φ(x)`.
pub fn pdf(x: f64) -> f64 {
    (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// `Φ⁻¹(p)` for `p` in `(0, 1)` (±∞ at the ends): Acklam's rational approximation refined
/// by one Halley step on `Φ`, accurate to about 1e-12.
pub fn quantile(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    let x = if p < 0.024_25 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.024_25 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    };
    let e = cdf(x) - p;
    let u = e * (2.0 * std::f64::consts::PI).sqrt() * (0.5 * x * x).exp();
    x - u / (1.0 + 0.5 * x * u)
}

/// The value of `N(mean, sd²)` truncated to `[lo, hi]` at uniform `u` in `[0, 1)`; `None`
/// when the interval holds no probability that f64 can resolve.
pub fn truncated(mean: f64, sd: f64, lo: f64, hi: f64, u: f64) -> Option<f64> {
    if sd <= 0.0 || !sd.is_finite() {
        return (lo..=hi).contains(&mean).then_some(mean);
    }
    let (a, b) = ((lo - mean) / sd, (hi - mean) / sd);
    // Work in the tail nearer zero so that 1 − Φ does not cancel.
    let (flip, a, b) = if a > 0.0 { (-1.0, -b, -a) } else { (1.0, a, b) };
    let (pa, pb) = (cdf(a), cdf(b));
    if pb.partial_cmp(&pa) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let z = quantile(pa + u * (pb - pa)).clamp(a, b);
    Some(mean + flip * z * sd)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        assert!((cdf(0.0) - 0.5).abs() < 1e-15);
        assert!((cdf(1.959_963_984_540_054) - 0.975).abs() < 1e-12);
        assert!((cdf(-3.0) - 0.001_349_898_031_630_094_6).abs() < 1e-15);
        for p in [1e-10, 0.001, 0.02, 0.3, 0.5, 0.77, 0.99, 1.0 - 1e-9] {
            assert!(
                (cdf(quantile(p)) - p).abs() < 1e-12 * p.max(1e-3),
                "p = {p}"
            );
        }
        assert!((quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-10);
        assert!((pdf(0.0) - 0.398_942_280_401_432_7).abs() < 1e-15);
    }

    #[test]
    fn truncated_draws_stay_inside_and_follow_the_shape() {
        // N(0, 1) on [1, 2]: the median solves Φ(m) = (Φ(1) + Φ(2)) / 2.
        let m = truncated(0.0, 1.0, 1.0, 2.0, 0.5).unwrap();
        assert!((cdf(m) - (cdf(1.0) + cdf(2.0)) / 2.0).abs() < 1e-12);
        // Far in the upper tail (8 to 9 sd) it is still resolved, near the lower end.
        let far = truncated(100.0, 10.0, 180.0, 190.0, 0.5).unwrap();
        assert!((180.0..181.0).contains(&far), "{far}");
        for u in [0.0, 0.1, 0.9, 0.999_999] {
            let v = truncated(5.0, 2.0, 4.0, 9.0, u).unwrap();
            assert!((4.0..=9.0).contains(&v));
        }
        assert_eq!(truncated(0.0, 1.0, 50.0, 60.0, 0.5), None);
        assert_eq!(truncated(3.0, 0.0, 1.0, 4.0, 0.2), Some(3.0));
    }
}
