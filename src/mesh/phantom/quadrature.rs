//! Quadrature on the unit sphere: Gauss–Legendre in `cos θ`, trapezoid in `φ`.
//!
//! For a smooth function both rules converge exponentially; the trapezoid rule is exact
//! for trigonometric polynomials of degree below the number of `φ` samples.

use std::f64::consts::{PI, TAU};

/// Newton steps stop when a node moves less than this.
const NODE_TOLERANCE: f64 = 1e-15;
/// Newton steps per node at most.
const MAX_NEWTON_STEPS: usize = 100;

/// Gauss–Legendre nodes and weights on `[-1, 1]` for `n` points (exact to degree `2n − 1`).
pub(super) fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        // Tricomi's initial guess for the i-th largest root.
        let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        for _ in 0..MAX_NEWTON_STEPS {
            let (p, d) = legendre_with_derivative(n, x);
            let dx = p / d;
            x -= dx;
            if dx.abs() < NODE_TOLERANCE {
                break;
            }
        }
        let (_, d) = legendre_with_derivative(n, x);
        let w = 2.0 / ((1.0 - x * x) * d * d);
        nodes[i] = x;
        nodes[n - 1 - i] = -x;
        weights[i] = w;
        weights[n - 1 - i] = w;
    }
    (nodes, weights)
}

/// `P_n(x)` and `P_n'(x)` by the three-term recurrence.
fn legendre_with_derivative(n: usize, x: f64) -> (f64, f64) {
    let (mut p0, mut p1) = (1.0, x);
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let kf = k as f64;
        let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
        p0 = p1;
        p1 = p2;
    }
    let d = n as f64 * (x * p1 - p0) / (x * x - 1.0);
    (p1, d)
}

/// `∮ f(u) dΩ` over the unit sphere with `n_theta` Gauss–Legendre nodes in `cos θ` and
/// `n_phi` equal steps in `φ`; `u = (sin θ cos φ, sin θ sin φ, cos θ)`.
pub(super) fn sphere_integral(f: impl Fn([f64; 3]) -> f64, n_theta: usize, n_phi: usize) -> f64 {
    let (nodes, weights) = gauss_legendre(n_theta);
    let dphi = TAU / n_phi as f64;
    let mut total = 0.0;
    for (&t, &w) in nodes.iter().zip(&weights) {
        let s = (1.0 - t * t).max(0.0).sqrt();
        let ring: f64 = (0..n_phi)
            .map(|j| {
                let phi = dphi * j as f64;
                f([s * phi.cos(), s * phi.sin(), t])
            })
            .sum();
        total += w * ring * dphi;
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_legendre_integrates_polynomials_exactly() {
        let (x, w) = gauss_legendre(5);
        assert!((w.iter().sum::<f64>() - 2.0).abs() < 1e-14);
        // ∫ x^8 dx over [-1, 1] = 2/9, exact for 5 nodes (degree ≤ 9).
        let i8: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(8)).sum();
        assert!((i8 - 2.0 / 9.0).abs() < 1e-14);
        // Known 2-point rule: ±1/√3 with weights 1.
        let (x2, w2) = gauss_legendre(2);
        assert!((x2[0] - 1.0 / 3f64.sqrt()).abs() < 1e-15 && (w2[1] - 1.0).abs() < 1e-14);
    }

    #[test]
    fn sphere_area_and_ellipsoid_volume() {
        let area = sphere_integral(|_| 1.0, 8, 8);
        assert!((area - 4.0 * PI).abs() < 1e-12);
        // Ellipsoid volume via ⅓∮ r(u)³ dΩ with r = 1/√(x²/a² + y²/b² + z²/c²).
        let (a, b, c) = (3.0, 2.0, 1.5);
        let r = |u: [f64; 3]| {
            1.0 / (u[0].powi(2) / (a * a) + u[1].powi(2) / (b * b) + u[2].powi(2) / (c * c)).sqrt()
        };
        let v = sphere_integral(|u| r(u).powi(3) / 3.0, 64, 128);
        let exact = 4.0 / 3.0 * PI * a * b * c;
        assert!((v / exact - 1.0).abs() < 1e-10, "{v} vs {exact}");
    }
}
