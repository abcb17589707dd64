//! Initial atlases from the data (ours; the thesis starts from shapes an expert chose): the
//! medoids of a k-medoids clustering of the pre-aligned training meshes under the
//! symmetric surface distance.
//!
//! The distance of two meshes is the mean of their two mean nearest-vertex distances (mm).
//! The clustering is PAM's, deterministic (ties to the lower index).

use crate::geometry::kdtree::PointCloudIndex;
use crate::mesh::Mesh;
use crate::models::ModelError;
use crate::models::workers::map_items;

/// Most swaps of the medoid search.
const MAX_ROUNDS: usize = 100;

/// The symmetric surface distances between every pair of meshes, `[K, K]` mm.
pub fn distance_matrix(meshes: &[Mesh]) -> Result<Vec<Vec<f64>>, ModelError> {
    let indices = meshes
        .iter()
        .map(|m| PointCloudIndex::new(&m.vertices))
        .collect::<Result<Vec<_>, _>>()?;
    let one_way = |from: &Mesh, to: &PointCloudIndex| -> f64 {
        let sum: f64 = from.vertices.iter().map(|p| to.nearest(*p).1).sum();
        sum / from.vertices.len().max(1) as f64
    };
    let rows: Vec<usize> = (0..meshes.len()).collect();
    let upper = map_items(
        &rows,
        |&i| -> Result<Vec<f64>, ModelError> {
            Ok((i + 1..meshes.len())
                .map(|j| {
                    0.5 * (one_way(&meshes[i], &indices[j]) + one_way(&meshes[j], &indices[i]))
                })
                .collect())
        },
        |_| Ok(()),
    )?;
    let k = meshes.len();
    let mut d = vec![vec![0.0; k]; k];
    for (i, row) in upper.iter().enumerate() {
        for (offset, &v) in row.iter().enumerate() {
            let j = i + 1 + offset;
            d[i][j] = v;
            d[j][i] = v;
        }
    }
    Ok(d)
}

/// The medoids (indices, in order of choice) of `m` clusters of the items of distance
/// matrix `d`, and each item's cluster: PAM (Kaufman & Rousseeuw), its greedy build then
/// the best single swap of a medoid for another item until none lowers the total distance
/// of the items to their medoids. A far outlier lowers that total only by its own distance,
/// so it is not made a medoid in place of a sub-population.
pub fn k_medoids(d: &[Vec<f64>], m: usize) -> Result<(Vec<usize>, Vec<usize>), ModelError> {
    let k = d.len();
    if m == 0 || m > k {
        return Err(ModelError::invalid(
            "atlases",
            format!("{m} atlases need at least as many training meshes, got {k}"),
        ));
    }
    let mut medoids: Vec<usize> = Vec::with_capacity(m);
    while medoids.len() < m {
        let next = (0..k)
            .filter(|i| !medoids.contains(i))
            .map(|i| {
                let mut with = medoids.clone();
                with.push(i);
                (i, cost(d, &with))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(0, |(i, _)| i);
        medoids.push(next);
    }
    let mut current = cost(d, &medoids);
    for _ in 0..MAX_ROUNDS {
        let mut best: Option<(usize, usize, f64)> = None;
        for slot in 0..m {
            for candidate in (0..k).filter(|i| !medoids.contains(i)) {
                let mut swapped = medoids.clone();
                swapped[slot] = candidate;
                let c = cost(d, &swapped);
                if c < best.map_or(current, |b| b.2) - 1e-12 {
                    best = Some((slot, candidate, c));
                }
            }
        }
        let Some((slot, candidate, c)) = best else {
            break;
        };
        medoids[slot] = candidate;
        current = c;
    }
    Ok((medoids.clone(), assign(d, &medoids)))
}

/// The total distance of the items to their nearest medoid.
fn cost(d: &[Vec<f64>], medoids: &[usize]) -> f64 {
    d.iter()
        .map(|row| {
            medoids
                .iter()
                .map(|&c| row[c])
                .fold(f64::INFINITY, f64::min)
        })
        .sum()
}

/// Each item's nearest medoid (ties to the earlier medoid).
fn assign(d: &[Vec<f64>], medoids: &[usize]) -> Vec<usize> {
    (0..d.len())
        .map(|i| {
            (0..medoids.len())
                .min_by(|&a, &b| d[i][medoids[a]].total_cmp(&d[i][medoids[b]]))
                .unwrap_or(0)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::fixtures::cube;

    #[test]
    fn two_groups_of_points_give_their_medoids() {
        // Items on a line: 0, 1, 2 and 10, 11, 12, 13; the medoids are 1 and 11 or 12.
        let x = [0.0, 1.0, 2.0, 10.0, 11.0, 12.0, 13.0];
        let d: Vec<Vec<f64>> = x
            .iter()
            .map(|a| x.iter().map(|b| f64::abs(a - b)).collect())
            .collect();
        let (medoids, labels) = k_medoids(&d, 2).unwrap();
        assert_eq!(labels[..3], [labels[0]; 3]);
        assert_eq!(labels[3..], [labels[3]; 4]);
        assert_ne!(labels[0], labels[3]);
        let mut sorted = medoids.clone();
        sorted.sort();
        assert_eq!(sorted[0], 1);
        assert!(sorted[1] == 4 || sorted[1] == 5, "{medoids:?}");
        assert!(k_medoids(&d, 8).is_err());
        assert_eq!(k_medoids(&d, 1).unwrap().1, vec![0; 7]);
        // A far outlier does not take a medoid from the second group.
        let x = [0.0, 1.0, 2.0, 3.0, 4.0, 20.0, 21.0, 22.0, 23.0, 24.0, -12.0];
        let d: Vec<Vec<f64>> = x
            .iter()
            .map(|a| x.iter().map(|b| f64::abs(a - b)).collect())
            .collect();
        let (mut medoids, _) = k_medoids(&d, 2).unwrap();
        medoids.sort();
        assert!(medoids[0] <= 2 && medoids[1] == 7, "{medoids:?}");
    }

    #[test]
    fn surface_distance_is_symmetric_and_zero_on_the_diagonal() {
        let a = cube();
        let b = Mesh::new(
            a.vertices
                .iter()
                .map(|p| [p[0] + 0.5, p[1], p[2]])
                .collect(),
            a.faces.clone(),
        );
        let d = distance_matrix(&[a.clone(), b, a]).unwrap();
        assert_eq!(d[0][0], 0.0);
        assert!((d[0][1] - d[1][0]).abs() < 1e-12);
        assert!(d[0][1] > 0.0 && d[0][1] <= 0.5 + 1e-12, "{d:?}");
        assert!(d[0][2].abs() < 1e-12);
    }
}
