//! The closest point of a triangle to a point, by the region of the triangle's plane the
//! point projects into (a vertex, an edge or the interior).

use super::points::{add, dot, scale, sub};

/// The point of triangle `(a, b, c)` (mm) closest to `p`. Degenerate triangles (collinear
/// or coincident corners) are handled: the answer is then on one of their edges.
pub fn closest_point_on_triangle(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return on_segment(a, ab, d1, d1 - d3);
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return on_segment(a, ac, d2, d2 - d6);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return on_segment(b, sub(c, b), d4 - d3, (d4 - d3) + (d5 - d6));
    }
    let denominator = va + vb + vc;
    if denominator.abs() <= f64::MIN_POSITIVE {
        return closest_on_edges(p, a, b, c);
    }
    let (v, w) = (vb / denominator, vc / denominator);
    add(a, add(scale(ab, v), scale(ac, w)))
}

/// `origin + t·direction` with `t = numerator / denominator` clamped to `[0, 1]`.
fn on_segment(origin: [f64; 3], direction: [f64; 3], numerator: f64, denominator: f64) -> [f64; 3] {
    let t = if denominator > 0.0 {
        (numerator / denominator).clamp(0.0, 1.0)
    } else {
        0.0
    };
    add(origin, scale(direction, t))
}

/// The closest point on the three edges (for degenerate triangles).
fn closest_on_edges(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f64; 3] {
    [(a, b), (b, c), (c, a)]
        .into_iter()
        .map(|(s, e)| {
            let d = sub(e, s);
            on_segment(s, d, dot(sub(p, s), d), dot(d, d))
        })
        .min_by(|x, y| super::points::dist2(*x, p).total_cmp(&super::points::dist2(*y, p)))
        .unwrap_or(a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::points::dist2;

    const A: [f64; 3] = [0.0, 0.0, 0.0];
    const B: [f64; 3] = [1.0, 0.0, 0.0];
    const C: [f64; 3] = [0.0, 1.0, 0.0];

    fn distance(p: [f64; 3]) -> f64 {
        dist2(p, closest_point_on_triangle(p, A, B, C)).sqrt()
    }

    #[test]
    fn unit_triangle_regions() {
        // Above the interior: the foot of the perpendicular.
        assert_eq!(
            closest_point_on_triangle([0.25, 0.25, 2.0], A, B, C),
            [0.25, 0.25, 0.0]
        );
        assert!((distance([0.25, 0.25, 2.0]) - 2.0).abs() < 1e-12);
        // Beyond each corner.
        assert_eq!(closest_point_on_triangle([-1.0, -1.0, 0.0], A, B, C), A);
        assert_eq!(closest_point_on_triangle([2.0, -0.5, 1.0], A, B, C), B);
        assert_eq!(closest_point_on_triangle([-0.5, 3.0, 0.0], A, B, C), C);
        // Beside the edges: AB (y < 0), AC (x < 0) and the hypotenuse BC.
        assert_eq!(
            closest_point_on_triangle([0.5, -2.0, 0.0], A, B, C),
            [0.5, 0.0, 0.0]
        );
        assert_eq!(
            closest_point_on_triangle([-3.0, 0.4, 4.0], A, B, C),
            [0.0, 0.4, 0.0]
        );
        let q = closest_point_on_triangle([1.0, 1.0, 0.0], A, B, C);
        assert!(dist2(q, [0.5, 0.5, 0.0]) < 1e-24);
        assert!((distance([1.0, 1.0, 0.0]) - 0.5f64.sqrt()).abs() < 1e-12);
        // A point on the triangle is its own closest point.
        assert!(distance([0.2, 0.3, 0.0]) < 1e-15);
    }

    #[test]
    fn degenerate_triangles_fall_back_to_edges() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let q = closest_point_on_triangle([1.5, 1.0, 0.0], a, b, c);
        assert!(dist2(q, [1.5, 0.0, 0.0]) < 1e-24, "{q:?}");
        let q = closest_point_on_triangle([3.0, 1.0, 0.0], a, a, a);
        assert_eq!(q, a);
    }

    #[test]
    fn agrees_with_dense_sampling_of_the_triangle() {
        let (a, b, c) = ([0.3, -0.2, 0.1], [2.0, 0.5, -0.4], [-0.6, 1.7, 0.9]);
        let n = 200;
        for p in [
            [1.0, 1.0, 1.0],
            [-2.0, 0.0, 0.5],
            [0.5, 0.4, -3.0],
            [3.0, 3.0, 0.0],
        ] {
            let exact = dist2(p, closest_point_on_triangle(p, a, b, c)).sqrt();
            let mut sampled = f64::INFINITY;
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let q = add(a, add(scale(sub(b, a), u), scale(sub(c, a), v)));
                    sampled = sampled.min(dist2(p, q).sqrt());
                }
            }
            assert!(
                exact <= sampled + 1e-12 && sampled - exact < 2e-2,
                "{exact} {sampled}"
            );
        }
    }
}
