//! Left and right. Kidneys, lungs and other paired organs come as mirror images of one
//! another, and no rotation turns a left kidney into a right one: registered as they are,
//! half the meshes of a mixed population are laid onto the reference back to front, and
//! their correspondences follow. With the `mirror` option every mesh is registered both as
//! it is and as its mirror image, and the population decides which of the two each mesh
//! takes: the one nearer the other meshes as they were taken (a consensus, reached by
//! sweeps from the reference's own side). A new mesh takes the side nearer the model's
//! atlas. A shape that is nearly its own mirror image (an LV cup) fits about as well either
//! way, so its side is arbitrary; on 100 LV phantoms that cost joint acceptance and
//! generalisation, which is why the option is off by default.
//!
//! Points are in the reference's frame, mm.

use crate::eval::metrics::parallel_map;
use crate::geometry::GeometryError;
use crate::geometry::distance::surface_distances_indexed;
use crate::geometry::kdtree::PointCloudIndex;

/// Points per candidate compared (every k-th of each).
pub const SIDE_POINTS: usize = 600;
/// Most consensus sweeps over the meshes.
const MAX_SWEEPS: usize = 20;

/// One mesh registered as it is (`own`) and as its mirror image (`mirrored`), both in the
/// reference's frame (mm); every k-th of their points is compared.
pub struct SideCandidates {
    pub own: Vec<[f64; 3]>,
    pub mirrored: Vec<[f64; 3]>,
}

/// Point clouds with their search indices.
struct Indexed {
    points: Vec<[f64; 3]>,
    index: PointCloudIndex,
}

impl Indexed {
    fn new(points: &[[f64; 3]]) -> Result<Self, GeometryError> {
        let points = crate::models::alignment::subsample(points, SIDE_POINTS);
        let index = PointCloudIndex::new(&points)?;
        Ok(Self { points, index })
    }

    /// Symmetric mean closest-point distance (mm).
    fn distance(&self, other: &Indexed) -> f64 {
        let d = surface_distances_indexed(&self.points, &self.index, &other.points, &other.index);
        0.5 * (d.ed + d.ed_star)
    }
}

/// Which meshes take their mirror image (`true`): starting from the side nearer the
/// `reference`'s own registration (which stays as it is), each mesh in turn takes the side
/// whose mean distance to the other meshes, as currently taken, is smaller, until a sweep
/// changes nothing. Deterministic for given candidates.
pub fn choose_sides(
    candidates: &[SideCandidates],
    reference: usize,
) -> Result<Vec<bool>, GeometryError> {
    let indexed = candidates
        .iter()
        .map(|c| Ok([Indexed::new(&c.own)?, Indexed::new(&c.mirrored)?]))
        .collect::<Result<Vec<_>, GeometryError>>()?;
    let n = indexed.len();
    if reference >= n {
        return Ok(vec![false; n]);
    }
    // distance[i][j][2·a + b]: mesh i taken as side a (0 own, 1 mirrored) against mesh j
    // taken as side b, computed once for all sweeps.
    let rows: Vec<usize> = (0..n).collect();
    let distance: Vec<Vec<[f64; 4]>> = parallel_map(&rows, |&i| {
        (0..n)
            .map(|j| std::array::from_fn(|k| indexed[i][k / 2].distance(&indexed[j][k % 2])))
            .collect()
    });
    let mut mirrored: Vec<bool> = (0..n)
        .map(|i| distance[i][reference][2] < distance[i][reference][0])
        .collect();
    mirrored[reference] = false;
    for _ in 0..MAX_SWEEPS {
        let mut changed = false;
        for i in (0..n).filter(|i| *i != reference) {
            let (mut own, mut flipped) = (0.0, 0.0);
            for j in (0..n).filter(|j| *j != i) {
                let taken = usize::from(mirrored[j]);
                own += distance[i][j][taken];
                flipped += distance[i][j][2 + taken];
            }
            let choice = flipped < own;
            changed |= choice != mirrored[i];
            mirrored[i] = choice;
        }
        if !changed {
            break;
        }
    }
    Ok(mirrored)
}

/// Whether a new mesh takes its mirror image: when that lies nearer the nearest of the
/// `atlases` (each `[N_μ, 3]` mm, the model's side) than the mesh as it is.
pub fn nearer_mirrored(
    candidate: &SideCandidates,
    atlases: &[&[[f64; 3]]],
) -> Result<bool, GeometryError> {
    let (own, flipped) = (
        Indexed::new(&candidate.own)?,
        Indexed::new(&candidate.mirrored)?,
    );
    let (mut best_own, mut best_flipped) = (f64::INFINITY, f64::INFINITY);
    for atlas in atlases {
        let atlas = Indexed::new(atlas)?;
        best_own = best_own.min(own.distance(&atlas));
        best_flipped = best_flipped.min(flipped.distance(&atlas));
    }
    Ok(best_flipped < best_own)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::alignment::mirror;

    /// A lopsided "L" of points: its mirror image differs from it under any rotation.
    fn chiral(size: f64) -> Vec<[f64; 3]> {
        let mut points = Vec::new();
        for i in 0..40 {
            let t = f64::from(i) / 4.0;
            points.push([t * size, 0.0, 0.0]);
            points.push([0.0, t * size * 0.5, 0.0]);
            points.push([0.0, 0.0, t * size * 0.25]);
        }
        points
    }

    /// The candidates of a shape given as `mirrored_input` or not: its own registration is
    /// the input itself, its mirror image's the input mirrored.
    fn candidates_of(shape: &[[f64; 3]], mirrored_input: bool) -> SideCandidates {
        let input: Vec<[f64; 3]> = if mirrored_input {
            shape.iter().map(|p| mirror(*p)).collect()
        } else {
            shape.to_vec()
        };
        SideCandidates {
            mirrored: input.iter().map(|p| mirror(*p)).collect(),
            own: input,
        }
    }

    #[test]
    fn mirrored_meshes_of_a_population_take_the_reference_side() {
        // Five shapes of different sizes, the second and fourth given as mirror images.
        let flipped_inputs = [false, true, false, true, false];
        let candidates: Vec<_> = flipped_inputs
            .iter()
            .enumerate()
            .map(|(i, f)| candidates_of(&chiral(1.0 + 0.05 * i as f64), *f))
            .collect();
        let chosen = choose_sides(&candidates, 0).unwrap();
        assert_eq!(chosen, flipped_inputs.to_vec());
    }

    #[test]
    fn the_reference_keeps_its_side_even_when_it_is_the_odd_one() {
        let flipped_inputs = [true, false, false, false];
        let candidates: Vec<_> = flipped_inputs
            .iter()
            .map(|f| candidates_of(&chiral(1.0), *f))
            .collect();
        // The reference (0) was given mirrored: the others follow it.
        assert_eq!(
            choose_sides(&candidates, 0).unwrap(),
            vec![false, true, true, true]
        );
    }

    #[test]
    fn a_new_mesh_takes_the_side_of_the_atlas() {
        let atlas = chiral(1.0);
        let given_mirrored = candidates_of(&chiral(1.1), true);
        let given_as_is = candidates_of(&chiral(1.1), false);
        assert!(nearer_mirrored(&given_mirrored, &[&atlas]).unwrap());
        assert!(!nearer_mirrored(&given_as_is, &[&atlas]).unwrap());
    }
}
