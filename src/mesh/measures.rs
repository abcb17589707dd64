//! Whole-mesh measures: enclosed volume (ml) and surface area (cm²).

use super::Mesh;

/// Cubic millimetres per millilitre.
pub const MM3_PER_ML: f64 = 1000.0;
/// Square millimetres per square centimetre.
pub const MM2_PER_CM2: f64 = 100.0;

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Signed enclosed volume in mm³ by the divergence theorem.
///
/// Positive for a closed mesh whose faces are oriented outward. The sum is taken relative
/// to the vertex centroid to keep rounding small for meshes far from the origin.
pub fn signed_volume_mm3(mesh: &Mesh) -> f64 {
    let n = mesh.vertices.len().max(1) as f64;
    let mut c = [0.0; 3];
    for v in &mesh.vertices {
        for k in 0..3 {
            c[k] += v[k] / n;
        }
    }
    let mut six_v = 0.0;
    for f in 0..mesh.faces.len() {
        let [a, b, d] = mesh.triangle(f);
        six_v += dot(sub(a, c), cross(sub(b, c), sub(d, c)));
    }
    six_v / 6.0
}

/// Enclosed volume in ml (signed; see [`signed_volume_mm3`]).
pub fn volume_ml(mesh: &Mesh) -> f64 {
    signed_volume_mm3(mesh) / MM3_PER_ML
}

/// Total surface area in mm².
pub fn area_mm2(mesh: &Mesh) -> f64 {
    (0..mesh.faces.len())
        .map(|f| {
            let [a, b, c] = mesh.triangle(f);
            0.5 * norm(cross(sub(b, a), sub(c, a)))
        })
        .sum()
}

/// Total surface area in cm².
pub fn area_cm2(mesh: &Mesh) -> f64 {
    area_mm2(mesh) / MM2_PER_CM2
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetrahedron() -> Mesh {
        // Corner tetrahedron with legs of 10 mm: volume 1000/6 mm³.
        Mesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [10.0, 0.0, 0.0],
                [0.0, 10.0, 0.0],
                [0.0, 0.0, 10.0],
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn tetrahedron_volume_and_area() {
        let t = tetrahedron();
        assert!((signed_volume_mm3(&t) - 1000.0 / 6.0).abs() < 1e-9);
        // Three right triangles of 50 mm² and one equilateral with side 10√2: (√3/4)·200.
        let equilateral = 3.0f64.sqrt() / 4.0 * 200.0;
        assert!((area_mm2(&t) - (150.0 + equilateral)).abs() < 1e-9);
    }

    #[test]
    fn flipped_faces_give_negative_volume() {
        let mut t = tetrahedron();
        for f in &mut t.faces {
            f.swap(1, 2);
        }
        assert!(signed_volume_mm3(&t) < 0.0);
    }
}
