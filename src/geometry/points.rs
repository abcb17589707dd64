//! Small helpers on 3-vectors `[f64; 3]` (mm) and 3×3 matrices `[[f64; 3]; 3]` (row-major).

/// A 3×3 matrix, row-major: `m[row][col]`.
pub type Mat3 = [[f64; 3]; 3];

/// The 3×3 identity.
pub const IDENTITY3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// `a + b`.
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `k·a`.
pub fn scale(a: [f64; 3], k: f64) -> [f64; 3] {
    [k * a[0], k * a[1], k * a[2]]
}

/// Dot product.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Squared Euclidean norm.
pub fn norm2(a: [f64; 3]) -> f64 {
    dot(a, a)
}

/// Squared distance between two points.
pub fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm2(sub(a, b))
}

/// `M·v`.
pub fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `Mᵀ·v`.
pub fn mat_t_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `A·B`.
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for (i, row) in c.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// `Aᵀ`.
pub fn transpose(a: &Mat3) -> Mat3 {
    let mut t = [[0.0; 3]; 3];
    for (i, row) in a.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            t[j][i] = *v;
        }
    }
    t
}

/// Determinant.
pub fn det(a: &Mat3) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// Root-mean-square distance of `points` from their centroid (mm): their size.
pub fn rms_radius(points: &[[f64; 3]]) -> f64 {
    let c = centroid(points, None);
    let sum: f64 = points.iter().map(|p| dist2(*p, c)).sum();
    (sum / points.len().max(1) as f64).sqrt()
}

/// Weighted centroid `Σ wᵢ pᵢ / Σ wᵢ`; the plain centroid when `weights` is `None`.
/// Returns the origin for an empty set or zero total weight.
pub fn centroid(points: &[[f64; 3]], weights: Option<&[f64]>) -> [f64; 3] {
    let mut c = [0.0; 3];
    let mut total = 0.0;
    for (i, p) in points.iter().enumerate() {
        let w = weights.map_or(1.0, |w| w.get(i).copied().unwrap_or(0.0));
        c = add(c, scale(*p, w));
        total += w;
    }
    if total > 0.0 {
        scale(c, 1.0 / total)
    } else {
        [0.0; 3]
    }
}

/// Rotation by `angle` radians about the unit `axis` (Rodrigues' formula).
pub fn axis_angle(axis: [f64; 3], angle: f64) -> Mat3 {
    let n = norm2(axis).sqrt();
    let [x, y, z] = if n > 0.0 {
        scale(axis, 1.0 / n)
    } else {
        [0.0, 0.0, 1.0]
    };
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// Rotation angle (radians, in [0, π]) of a rotation matrix.
pub fn rotation_angle(r: &Mat3) -> f64 {
    let trace = r[0][0] + r[1][1] + r[2][2];
    ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rodrigues_quarter_turn_about_z() {
        let r = axis_angle([0.0, 0.0, 2.0], std::f64::consts::FRAC_PI_2);
        let p = mat_vec(&r, [1.0, 0.0, 0.0]);
        assert!(dist2(p, [0.0, 1.0, 0.0]) < 1e-24);
        assert!((det(&r) - 1.0).abs() < 1e-12);
        assert!((rotation_angle(&r) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let back = mat_t_vec(&r, p);
        assert!(dist2(back, [1.0, 0.0, 0.0]) < 1e-24);
        assert_eq!(transpose(&transpose(&r)), r);
        let rr = mat_mul(&r, &r);
        assert!(dist2(mat_vec(&rr, [1.0, 0.0, 0.0]), [-1.0, 0.0, 0.0]) < 1e-24);
    }

    #[test]
    fn weighted_centroid() {
        let pts = [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]];
        assert_eq!(centroid(&pts, None), [2.0, 0.0, 0.0]);
        assert_eq!(centroid(&pts, Some(&[1.0, 3.0])), [3.0, 0.0, 0.0]);
        assert_eq!(centroid(&[], None), [0.0; 3]);
    }
}
