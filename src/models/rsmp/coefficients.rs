//! Mode coefficients drawn from the training shapes' own. A Gaussian `bᵢ ~ N(0, λᵢ)` gives
//! every mode tails the patients do not have: PCA coefficients of a population of organs
//! are often skewed or bounded (a ventricle is never shorter than some length), and on 100
//! LV phantoms 19% of Gaussian draws lay farther from the training mean in biomarker space
//! than any patient. Here each mode's coefficient is that of a training shape chosen at
//! random for that mode alone, so that every mode keeps the training shapes' distribution
//! (its variance `λᵢ` among them) while the combination of modes is new: a member takes
//! its modes from different patients and so copies none of them.

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::geometry::GeometryError;
use crate::geometry::pca::PcaModel;

/// The training shapes' coefficients on the kept modes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModeCoefficients {
    /// `[n_modes][n_training]`: each mode's coefficient `bᵢ` of every training shape, in the
    /// PCA's normalised units.
    pub by_mode: Vec<Vec<f64>>,
}

impl ModeCoefficients {
    /// The coefficients of `shapes` (each `[D]`, in the PCA's space) on `pca`'s modes.
    pub fn of_shapes(pca: &PcaModel, shapes: &[Vec<f64>]) -> Result<Self, GeometryError> {
        let projected = shapes
            .iter()
            .map(|x| pca.project(x))
            .collect::<Result<Vec<_>, _>>()?;
        let by_mode = (0..pca.n_modes())
            .map(|k| projected.iter().map(|b| b[k]).collect())
            .collect();
        Ok(Self { by_mode })
    }

    /// Coefficients `[n_modes]` of a new shape: mode `i` takes the coefficient of a training
    /// shape drawn uniformly for that mode alone.
    pub fn draw<R: Rng + ?Sized>(&self, rng: &mut R) -> Vec<f64> {
        self.by_mode
            .iter()
            .map(|values| match values.len() {
                0 => 0.0,
                n => values[rng.random_range(0..n)],
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A PCA of two axis-aligned modes in 2-D: `b = (x₀, x₁)` about a zero mean.
    fn axes() -> PcaModel {
        PcaModel {
            mean: vec![0.0, 0.0],
            modes: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
            variances: vec![2.0, 1.0],
            cumulative_explained: vec![2.0 / 3.0, 1.0],
        }
    }

    #[test]
    fn coefficients_are_the_projections_by_mode() {
        let shapes = vec![vec![3.0, -1.0], vec![-2.0, 4.0], vec![0.5, 0.0]];
        let c = ModeCoefficients::of_shapes(&axes(), &shapes).unwrap();
        assert_eq!(c.by_mode, vec![vec![3.0, -2.0, 0.5], vec![-1.0, 4.0, 0.0]]);
        assert!(ModeCoefficients::of_shapes(&axes(), &[vec![1.0]]).is_err());
    }

    #[test]
    fn draws_combine_modes_of_different_shapes() {
        let shapes = vec![vec![1.0, 10.0], vec![2.0, 20.0], vec![3.0, 30.0]];
        let c = ModeCoefficients::of_shapes(&axes(), &shapes).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let draws: Vec<Vec<f64>> = (0..200).map(|_| c.draw(&mut rng)).collect();
        // Every coefficient is one a training shape has on that mode.
        assert!(draws.iter().all(|b| c.by_mode[0].contains(&b[0])));
        assert!(draws.iter().all(|b| c.by_mode[1].contains(&b[1])));
        // Modes are drawn independently: some draws pair modes of two shapes.
        let mixed = draws.iter().filter(|b| b[1] != 10.0 * b[0]).count();
        assert!(mixed > 100, "{mixed} of 200 mixed");
        // Every training value of each mode turns up.
        for (k, values) in c.by_mode.iter().enumerate() {
            assert!(values.iter().all(|v| draws.iter().any(|b| b[k] == *v)));
        }
        // The same seed gives the same draws.
        let mut again = ChaCha8Rng::seed_from_u64(7);
        assert_eq!(c.draw(&mut again), draws[0]);
    }
}
