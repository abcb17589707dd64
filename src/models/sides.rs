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
use crate::mesh::Laterality;

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

/// The side each training mesh takes, and the side of the model's shapes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SideChoice {
    /// Per mesh, whether it takes its mirror image.
    pub mirrored: Vec<bool>,
    /// The side of the reference, which every shape of the model then has: known when the
    /// user gave the side of the reference or of any other mesh, `None` otherwise.
    pub laterality: Option<Laterality>,
}

/// Which meshes take their mirror image: starting from the side nearer the `reference`'s
/// own registration (which stays as it is), each mesh in turn takes the side whose mean
/// distance to the other meshes, as currently taken, is smaller, until a sweep changes
/// nothing. A mesh whose side the user `given` (empty, or one entry per mesh) takes the
/// reference's side without a vote: the reference's own side when given, otherwise the
/// side that lays the given meshes nearer the reference. Deterministic for given candidates.
pub fn choose_sides(
    candidates: &[SideCandidates],
    reference: usize,
    given: &[Option<Laterality>],
) -> Result<SideChoice, GeometryError> {
    let indexed = candidates
        .iter()
        .map(|c| Ok([Indexed::new(&c.own)?, Indexed::new(&c.mirrored)?]))
        .collect::<Result<Vec<_>, GeometryError>>()?;
    let n = indexed.len();
    let given = |i: usize| given.get(i).copied().flatten();
    if reference >= n {
        return Ok(SideChoice {
            mirrored: vec![false; n],
            laterality: None,
        });
    }
    // distance[i][j][2·a + b]: mesh i taken as side a (0 own, 1 mirrored) against mesh j
    // taken as side b, computed once for all sweeps.
    let rows: Vec<usize> = (0..n).collect();
    let distance: Vec<Vec<[f64; 4]>> = parallel_map(&rows, |&i| {
        (0..n)
            .map(|j| std::array::from_fn(|k| indexed[i][k / 2].distance(&indexed[j][k % 2])))
            .collect()
    });
    let to_reference = |i: usize, mirrored: bool| distance[i][reference][2 * usize::from(mirrored)];
    let laterality = given(reference).or_else(|| {
        let cost = |side: Laterality| -> f64 {
            (0..n)
                .filter_map(|i| given(i).map(|g| to_reference(i, g != side)))
                .sum()
        };
        let [left, right] = Laterality::ALL;
        (0..n).any(|i| given(i).is_some()).then(|| {
            if cost(right) < cost(left) {
                right
            } else {
                left
            }
        })
    });
    let fixed: Vec<Option<bool>> = (0..n)
        .map(|i| match (given(i), laterality) {
            _ if i == reference => Some(false),
            (Some(g), Some(side)) => Some(g != side),
            _ => None,
        })
        .collect();
    let mut mirrored: Vec<bool> = (0..n)
        .map(|i| fixed[i].unwrap_or_else(|| to_reference(i, true) < to_reference(i, false)))
        .collect();
    sweep(&distance, &fixed, &mut mirrored);
    Ok(SideChoice {
        mirrored,
        laterality,
    })
}

/// The consensus sweeps: each mesh not `fixed` in turn takes the side whose summed distance
/// to the others, as currently taken, is smaller, until a sweep changes nothing (at most
/// [`MAX_SWEEPS`]). `distance[i][j][2·a + b]` as in [`choose_sides`].
fn sweep(distance: &[Vec<[f64; 4]>], fixed: &[Option<bool>], mirrored: &mut [bool]) {
    let n = mirrored.len();
    for _ in 0..MAX_SWEEPS {
        let mut changed = false;
        for i in (0..n).filter(|i| fixed[*i].is_none()) {
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
}

/// Whether a new mesh takes its mirror image: when the user `given` its side and the model's
/// side is known, exactly when the two differ; otherwise when its mirror image lies nearer
/// the nearest of the `atlases` (each `[N_μ, 3]` mm, the model's side) than the mesh as it is.
pub fn takes_mirrored(
    candidate: &SideCandidates,
    atlases: &[&[[f64; 3]]],
    given: Option<Laterality>,
    model: Option<Laterality>,
) -> Result<bool, GeometryError> {
    match (given, model) {
        (Some(g), Some(m)) => Ok(g != m),
        _ => nearer_mirrored(candidate, atlases),
    }
}

/// Whether a new mesh takes its mirror image: when that lies nearer the nearest of the
/// `atlases` (each `[N_μ, 3]` mm, the model's side) than the mesh as it is.
fn nearer_mirrored(
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
        let chosen = choose_sides(&candidates, 0, &[]).unwrap();
        assert_eq!(chosen.mirrored, flipped_inputs.to_vec());
        assert_eq!(chosen.laterality, None);
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
            choose_sides(&candidates, 0, &[]).unwrap().mirrored,
            vec![false, true, true, true]
        );
    }

    /// Five chiral shapes, the second and fourth given as mirror images.
    fn population() -> Vec<SideCandidates> {
        [false, true, false, true, false]
            .iter()
            .enumerate()
            .map(|(i, f)| candidates_of(&chiral(1.0 + 0.05 * i as f64), *f))
            .collect()
    }

    #[test]
    fn sides_the_user_gave_are_kept_even_against_the_shapes() {
        use Laterality::{Left, Right};
        // Mesh 2 is of the reference's form but said to be a right one: it is mirrored.
        let given = [Some(Left), Some(Right), Some(Right), None, None];
        let chosen = choose_sides(&population(), 0, &given).unwrap();
        assert_eq!(chosen.laterality, Some(Left));
        assert_eq!(chosen.mirrored[..3], [false, true, true]);
        // Meshes without a side still vote: mesh 3 (mirrored input) joins the reference.
        assert!(chosen.mirrored[3]);
    }

    #[test]
    fn without_the_references_side_the_given_ones_name_it() {
        use Laterality::{Left, Right};
        // Mesh 1 (mirrored input) is a left one, so the reference's form is right.
        let given = [None, Some(Left), None, None, None];
        let chosen = choose_sides(&population(), 0, &given).unwrap();
        assert_eq!(chosen.laterality, Some(Right));
        assert_eq!(chosen.mirrored, vec![false, true, false, true, false]);
        let given = [None, None, Some(Left), None, None];
        let chosen = choose_sides(&population(), 0, &given).unwrap();
        assert_eq!(chosen.laterality, Some(Left));
        assert_eq!(chosen.mirrored, vec![false, true, false, true, false]);
    }

    #[test]
    fn a_new_mesh_of_a_given_side_takes_the_models_side() {
        use Laterality::{Left, Right};
        let atlas = chiral(1.0);
        let as_is = candidates_of(&chiral(1.1), false);
        assert!(takes_mirrored(&as_is, &[&atlas], Some(Right), Some(Left)).unwrap());
        assert!(!takes_mirrored(&as_is, &[&atlas], Some(Left), Some(Left)).unwrap());
        // Without either side, the atlas decides.
        assert!(!takes_mirrored(&as_is, &[&atlas], Some(Right), None).unwrap());
        assert!(!takes_mirrored(&as_is, &[&atlas], None, Some(Left)).unwrap());
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
