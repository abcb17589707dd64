//! Taubin λ|μ smoothing (Taubin 1995): a shrinking Laplacian step followed by an inflating
//! one, so that ripples between neighbouring vertices fade while the overall shape and its
//! volume stay.

use super::adjacency::Adjacency;

/// Shrinking factor λ of each step.
pub const TAUBIN_LAMBDA: f64 = 0.5;
/// Inflating factor μ of each step (|μ| slightly above λ keeps the volume).
pub const TAUBIN_MU: f64 = -0.53;

/// `steps` λ|μ steps on vertex positions (mm) with the umbrella Laplacian of `adjacency`;
/// vertices without neighbours stay. `[n_vertices, 3]` in, same out.
pub fn taubin(vertices: &[[f64; 3]], adjacency: &Adjacency, steps: usize) -> Vec<[f64; 3]> {
    let mut x = vertices.to_vec();
    for _ in 0..steps {
        for factor in [TAUBIN_LAMBDA, TAUBIN_MU] {
            let previous = x.clone();
            for (v, out) in x.iter_mut().enumerate() {
                let neighbours = adjacency.neighbours(v);
                if neighbours.is_empty() {
                    continue;
                }
                let n = neighbours.len() as f64;
                for k in 0..3 {
                    let centre = neighbours
                        .iter()
                        .map(|&u| previous[u as usize][k])
                        .sum::<f64>()
                        / n;
                    out[k] = previous[v][k] + factor * (centre - previous[v][k]);
                }
            }
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;

    /// A flat 5 × 5 grid (1 mm spacing) in z = 0, two triangles per cell.
    fn grid() -> Mesh {
        let vertices = (0..25)
            .map(|i| [(i % 5) as f64, (i / 5) as f64, 0.0])
            .collect();
        let mut faces = Vec::new();
        for y in 0..4u32 {
            for x in 0..4u32 {
                let v = y * 5 + x;
                faces.push([v, v + 1, v + 6]);
                faces.push([v, v + 6, v + 5]);
            }
        }
        Mesh::new(vertices, faces)
    }

    #[test]
    fn a_spike_fades_and_a_plane_stays() {
        let mut mesh = grid();
        let adjacency = Adjacency::from_mesh(&mesh);
        // A plane is its own average: nothing moves off it.
        let flat = taubin(&mesh.vertices, &adjacency, 3);
        assert!(flat.iter().all(|p| p[2] == 0.0));
        // A 1 mm spike at the centre vertex: about half of it is gone after two steps
        // (0.55 mm left), and more with more steps.
        mesh.vertices[12][2] = 1.0;
        let two = taubin(&mesh.vertices, &adjacency, 2)[12][2];
        let ten = taubin(&mesh.vertices, &adjacency, 10)[12][2];
        assert!(two < 0.6 && ten < two, "{two} {ten}");
        assert_eq!(taubin(&mesh.vertices, &adjacency, 0), mesh.vertices);
    }
}
