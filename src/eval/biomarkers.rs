//! Per-mesh biomarkers (SPEC §3): enclosed volume (ml), surface area (cm²), sphericity and
//! principal extents (mm).

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use serde::{Deserialize, Serialize};

use super::EvalError;
use crate::mesh::Mesh;
use crate::mesh::measures::{MM2_PER_CM2, MM3_PER_ML, area_mm2, signed_volume_mm3};

/// Biomarker names, in the order of [`Biomarkers::values`].
pub const NAMES: [&str; 6] = Biomarkers::NAMES;

/// Shape biomarkers of one closed surface mesh.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Biomarkers {
    /// Enclosed volume in ml (signed: negative for inward-oriented faces).
    pub volume_ml: f64,
    /// Surface area in cm².
    pub area_cm2: f64,
    /// Sphericity `π^{1/3}·(6V)^{2/3} / A` (1 for a sphere; uses |V|).
    pub sphericity: f64,
    /// Range of the vertices along the principal axis of largest variance, mm.
    pub extent_major_mm: f64,
    /// Range along the middle principal axis, mm.
    pub extent_middle_mm: f64,
    /// Range along the principal axis of smallest variance, mm.
    pub extent_minor_mm: f64,
}

impl Biomarkers {
    /// Names of the biomarkers, in the order of [`values`](Self::values).
    pub const NAMES: [&'static str; 6] = [
        "volume_ml",
        "area_cm2",
        "sphericity",
        "extent_major_mm",
        "extent_middle_mm",
        "extent_minor_mm",
    ];
    /// Units of the biomarkers, in the same order ("" for unitless).
    pub const UNITS: [&'static str; 6] = ["ml", "cm²", "", "mm", "mm", "mm"];

    /// Biomarkers of a mesh, extents along the surface's principal axes; fails if a face
    /// refers to a missing vertex.
    pub fn from_mesh(mesh: &Mesh) -> Result<Self, EvalError> {
        Self::measure(mesh, ExtentAxes::Surface)
    }

    /// Biomarkers of a mesh with the extents measured along `axes`; fails if a face refers
    /// to a missing vertex.
    pub fn measure(mesh: &Mesh, axes: ExtentAxes) -> Result<Self, EvalError> {
        let count = mesh.vertices.len();
        for (face, f) in mesh.faces.iter().enumerate() {
            if let Some(&vertex) = f.iter().find(|v| **v as usize >= count) {
                return Err(EvalError::InvalidMesh {
                    face,
                    vertex,
                    vertex_count: count,
                });
            }
        }
        let volume_mm3 = signed_volume_mm3(mesh);
        let area = area_mm2(mesh);
        let [major, middle, minor] = principal_extents(mesh, axes);
        Ok(Self {
            volume_ml: volume_mm3 / MM3_PER_ML,
            area_cm2: area / MM2_PER_CM2,
            sphericity: sphericity(volume_mm3, area),
            extent_major_mm: major,
            extent_middle_mm: middle,
            extent_minor_mm: minor,
        })
    }

    /// Values in the order of [`NAMES`](Self::NAMES).
    pub fn values(&self) -> [f64; 6] {
        [
            self.volume_ml,
            self.area_cm2,
            self.sphericity,
            self.extent_major_mm,
            self.extent_middle_mm,
            self.extent_minor_mm,
        ]
    }

    /// `(name, value)` pairs, for reports that loop over biomarkers.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, f64)> {
        Self::NAMES.into_iter().zip(self.values())
    }

    /// The value of the biomarker called `name`.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.iter().find(|(n, _)| *n == name).map(|(_, v)| v)
    }
}

/// Sphericity `π^{1/3}·(6V)^{2/3} / A` from a volume in mm³ and an area in mm² (uses |V|;
/// 0 when the area is 0).
pub fn sphericity(volume_mm3: f64, area_mm2: f64) -> f64 {
    if area_mm2 <= 0.0 {
        return 0.0;
    }
    std::f64::consts::PI.cbrt() * (6.0 * volume_mm3.abs()).powf(2.0 / 3.0) / area_mm2
}

/// The principal axes along which extents are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExtentAxes {
    /// Eigenvectors of the covariance of the surface (each triangle weighted by its area):
    /// the same surface meshed more finely in one region has the same axes.
    #[default]
    Surface,
    /// Eigenvectors of the covariance of the vertices, each counted once: regions meshed
    /// more finely pull the axes. Kept for reference populations stored before `Surface`.
    Vertices,
}

/// Ranges (mm) of the vertices along the principal axes, sorted descending (largest extent
/// first). With [`ExtentAxes::Surface`], a mesh without area (no faces) falls back to the
/// covariance of its vertices. Zeros for a mesh without vertices.
pub fn principal_extents(mesh: &Mesh, axes: ExtentAxes) -> [f64; 3] {
    let vertices = &mesh.vertices;
    if vertices.is_empty() {
        return [0.0; 3];
    }
    let covariance = match axes {
        ExtentAxes::Surface => surface_covariance(mesh),
        ExtentAxes::Vertices => None,
    };
    let axes =
        SymmetricEigen::new(covariance.unwrap_or_else(|| vertex_covariance(vertices))).eigenvectors;
    let mut extents: [f64; 3] = std::array::from_fn(|k| {
        let axis = axes.column(k);
        let (lo, hi) = vertices
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                let p = axis[0] * v[0] + axis[1] * v[1] + axis[2] * v[2];
                (lo.min(p), hi.max(p))
            });
        hi - lo
    });
    extents.sort_by(|a, b| b.total_cmp(a));
    extents
}

/// Covariance (mm²) of the vertices, each counted once.
fn vertex_covariance(vertices: &[[f64; 3]]) -> Matrix3<f64> {
    let n = vertices.len() as f64;
    let c = Vector3::from(std::array::from_fn(|k| {
        vertices.iter().map(|v| v[k]).sum::<f64>() / n
    }));
    let mut cov = Matrix3::<f64>::zeros();
    for v in vertices {
        let d = Vector3::from(*v) - c;
        cov += d * d.transpose();
    }
    cov / n
}

/// Covariance (mm²) of a point drawn uniformly from the surface, or `None` when the faces
/// have no area. A triangle with corners `a, b, c` (sum `s`) contributes its area times
/// `E[x xᵀ] = (a aᵀ + b bᵀ + c cᵀ + s sᵀ) / 12` about the vertex mean.
fn surface_covariance(mesh: &Mesh) -> Option<Matrix3<f64>> {
    let n = mesh.vertices.len() as f64;
    let origin = Vector3::from(std::array::from_fn(|k| {
        mesh.vertices.iter().map(|v| v[k]).sum::<f64>() / n
    }));
    let (mut area, mut first, mut second) = (0.0, Vector3::zeros(), Matrix3::zeros());
    for f in &mesh.faces {
        let [a, b, c] = f.map(|i| Vector3::from(mesh.vertices[i as usize]) - origin);
        let weight = 0.5 * (b - a).cross(&(c - a)).norm();
        let s = a + b + c;
        area += weight;
        first += weight * s / 3.0;
        second += weight
            * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose())
            / 12.0;
    }
    if area <= 0.0 {
        return None;
    }
    let mean = first / area;
    Some(second / area - mean * mean.transpose())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Axis-aligned box `[0, a] × [0, b] × [0, c]` (mm), faces counter-clockwise from outside.
    fn cuboid(a: f64, b: f64, c: f64) -> Mesh {
        let v = (0..8)
            .map(|i| {
                [
                    a * (i & 1) as f64,
                    b * ((i >> 1) & 1) as f64,
                    c * ((i >> 2) & 1) as f64,
                ]
            })
            .collect();
        let faces = vec![
            [0, 2, 1],
            [1, 2, 3], // z = 0, normal −z
            [4, 5, 6],
            [5, 7, 6], // z = c, normal +z
            [0, 1, 4],
            [1, 5, 4], // y = 0, normal −y
            [2, 6, 3],
            [3, 6, 7], // y = b, normal +y
            [0, 4, 2],
            [2, 4, 6], // x = 0, normal −x
            [1, 3, 5],
            [3, 7, 5], // x = a, normal +x
        ];
        Mesh::new(v, faces)
    }

    /// Latitude–longitude sphere of radius `r` mm.
    fn uv_sphere(r: f64, stacks: u32, slices: u32) -> Mesh {
        let mut v = vec![[0.0, 0.0, r]];
        for i in 1..stacks {
            let theta = std::f64::consts::PI * i as f64 / stacks as f64;
            for j in 0..slices {
                let phi = 2.0 * std::f64::consts::PI * j as f64 / slices as f64;
                v.push([
                    r * theta.sin() * phi.cos(),
                    r * theta.sin() * phi.sin(),
                    r * theta.cos(),
                ]);
            }
        }
        v.push([0.0, 0.0, -r]);
        let south = v.len() as u32 - 1;
        let ring = |i: u32, j: u32| 1 + (i - 1) * slices + j % slices;
        let mut f = Vec::new();
        for j in 0..slices {
            f.push([0, ring(1, j), ring(1, j + 1)]);
            f.push([south, ring(stacks - 1, j + 1), ring(stacks - 1, j)]);
        }
        for i in 1..stacks - 1 {
            for j in 0..slices {
                f.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
                f.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
            }
        }
        Mesh::new(v, f)
    }

    #[test]
    fn cube_of_side_10_mm() {
        let b = Biomarkers::from_mesh(&cuboid(10.0, 10.0, 10.0)).unwrap();
        assert!((b.volume_ml - 1.0).abs() < 1e-12);
        assert!((b.area_cm2 - 6.0).abs() < 1e-12);
        // π^{1/3}·(6·1000)^{2/3}/600 = π^{1/3}·6^{2/3}/6 ≈ 0.806.
        let expected = std::f64::consts::PI.cbrt() * 6f64.powf(2.0 / 3.0) / 6.0;
        assert!((b.sphericity - expected).abs() < 1e-12);
        assert!((b.sphericity - 0.806).abs() < 1e-3);
    }

    #[test]
    fn box_extents_sorted_descending() {
        let b = Biomarkers::from_mesh(&cuboid(20.0, 40.0, 10.0)).unwrap();
        assert!((b.volume_ml - 8.0).abs() < 1e-12);
        assert!((b.extent_major_mm - 40.0).abs() < 1e-9);
        assert!((b.extent_middle_mm - 20.0).abs() < 1e-9);
        assert!((b.extent_minor_mm - 10.0).abs() < 1e-9);
    }

    /// Variance along x (mm²) of a point uniform on the surface of an `a × b × c` box: the
    /// two faces across x sit at ±a/2, the four along x spread uniformly (a²/12).
    fn box_surface_variance(a: f64, b: f64, c: f64) -> f64 {
        (2.0 * b * c * a * a / 4.0 + 2.0 * (a * b + a * c) * a * a / 12.0)
            / (2.0 * (a * b + b * c + c * a))
    }

    #[test]
    fn surface_covariance_of_a_box_and_of_the_same_box_meshed_unevenly() {
        let mut mesh = cuboid(20.0, 40.0, 10.0);
        let expected = [
            box_surface_variance(20.0, 40.0, 10.0),
            box_surface_variance(40.0, 20.0, 10.0),
            box_surface_variance(10.0, 40.0, 20.0),
        ];
        let cov = surface_covariance(&mesh).unwrap();
        for k in 0..3 {
            assert!((cov[(k, k)] - expected[k]).abs() < 1e-9, "{k}: {cov}");
        }
        // Split the z = c face into four triangles around a new centre vertex: the surface
        // and its covariance stay; the vertex covariance moves towards that face.
        mesh.vertices.push([10.0, 20.0, 10.0]);
        mesh.faces
            .splice(2..4, [[4, 5, 8], [5, 7, 8], [7, 6, 8], [6, 4, 8]]);
        let split = surface_covariance(&mesh).unwrap();
        assert!((split - cov).abs().max() < 1e-9, "{split} vs {cov}");
        assert!((vertex_covariance(&mesh.vertices) - cov).abs().max() > 1.0);
        let by_vertices = Biomarkers::measure(&mesh, ExtentAxes::Vertices).unwrap();
        assert!((by_vertices.extent_major_mm - 40.0).abs() < 1e-9);
        let extents = principal_extents(&mesh, ExtentAxes::Surface);
        for (got, want) in extents.iter().zip([40.0, 20.0, 10.0]) {
            assert!((got - want).abs() < 1e-9, "{extents:?}");
        }
    }

    #[test]
    fn fine_sphere_is_nearly_spherical() {
        let b = Biomarkers::from_mesh(&uv_sphere(10.0, 64, 128)).unwrap();
        assert!(
            b.sphericity > 0.995 && b.sphericity <= 1.0,
            "{}",
            b.sphericity
        );
        let exact_ml = 4.0 / 3.0 * std::f64::consts::PI * 1000.0 / MM3_PER_ML;
        assert!((b.volume_ml / exact_ml - 1.0).abs() < 0.01);
        assert!((b.extent_major_mm - 20.0).abs() < 0.1);
    }

    #[test]
    fn names_values_and_lookup_agree() {
        let b = Biomarkers::from_mesh(&cuboid(10.0, 10.0, 10.0)).unwrap();
        let pairs: Vec<_> = b.iter().collect();
        assert_eq!(pairs.len(), 6);
        assert_eq!(pairs[0].0, "volume_ml");
        assert_eq!(b.get("area_cm2"), Some(b.area_cm2));
        assert_eq!(b.get("nope"), None);
        assert_eq!(NAMES, Biomarkers::NAMES);
    }

    #[test]
    fn rejects_dangling_face_index() {
        let mesh = Mesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 7]]);
        assert_eq!(
            Biomarkers::from_mesh(&mesh).unwrap_err().code(),
            "eval.invalid_mesh"
        );
    }
}
