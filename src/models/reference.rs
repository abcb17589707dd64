//! The reference population of a model: biomarkers of its training meshes, against which
//! the clinical acceptance of virtual cohort members is judged (SPEC §3, thesis table 3.1).

use serde::{Deserialize, Serialize};

use super::ModelError;
use crate::eval::Biomarkers;
use crate::eval::acceptance::{Intervals, ReferenceStats};
use crate::eval::biomarkers::ExtentAxes;
use crate::mesh::Mesh;

/// Below this many training meshes a population is small: its statistics are rough and
/// cohorts are kept near its range.
pub const SMALL_POPULATION: usize = 20;

/// Biomarkers of the training population and their reference statistics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReferencePopulation {
    /// Biomarker names, e.g. `volume_ml`.
    pub names: Vec<String>,
    /// Units of each biomarker.
    pub units: Vec<String>,
    /// `values[b][k]`: biomarker `b` of training mesh `k`.
    pub values: Vec<Vec<f64>>,
    /// Reference statistics of each biomarker.
    pub stats: Vec<ReferenceStats>,
    /// Axes of the extents in `values`; members are measured the same way (populations
    /// stored before surface axes existed read as `vertices`).
    #[serde(default = "axes_before_surface")]
    pub extent_axes: ExtentAxes,
}

fn axes_before_surface() -> ExtentAxes {
    ExtentAxes::Vertices
}

impl ReferencePopulation {
    /// From the training meshes (at least two).
    pub fn from_meshes(meshes: &[Mesh]) -> Result<Self, ModelError> {
        let biomarkers = meshes
            .iter()
            .map(Biomarkers::from_mesh)
            .collect::<Result<Vec<_>, _>>()?;
        let values: Vec<Vec<f64>> = (0..Biomarkers::NAMES.len())
            .map(|b| biomarkers.iter().map(|m| m.values()[b]).collect())
            .collect();
        let stats = values
            .iter()
            .map(|v| ReferenceStats::from_values(v))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            names: Biomarkers::NAMES.iter().map(|s| (*s).to_owned()).collect(),
            units: Biomarkers::UNITS.iter().map(|s| (*s).to_owned()).collect(),
            values,
            stats,
            extent_axes: ExtentAxes::Surface,
        })
    }

    /// Biomarkers of a mesh measured as the population's were, so that they can be judged
    /// against its intervals.
    pub fn measure(&self, mesh: &Mesh) -> Result<Biomarkers, ModelError> {
        Ok(Biomarkers::measure(mesh, self.extent_axes)?)
    }

    /// Training meshes behind the statistics.
    pub fn count(&self) -> usize {
        self.values.first().map_or(0, Vec::len)
    }

    /// Whether the population is too small for its estimates (fewer than
    /// [`SMALL_POPULATION`] meshes): cohorts then say so and stay near the training range.
    pub fn is_small(&self) -> bool {
        self.count() < SMALL_POPULATION
    }

    /// What a cohort of a small population tells its user (none for a large one).
    pub fn small_population_note(&self) -> Option<String> {
        self.is_small().then(|| {
            format!(
                "only {} training meshes (fewer than {SMALL_POPULATION}): the population's \
                 means, sds and ranges are rough estimates, so acceptance and spread figures \
                 are uncertain; members with a biomarker beyond the training range widened by \
                 half its width on either side are drawn again",
                self.count()
            )
        })
    }

    /// The plausible range of each biomarker for a small population: the training range
    /// widened by half its width on either side (`None` for a large population).
    pub fn plausible_ranges(&self) -> Option<Vec<(f64, f64)>> {
        self.is_small().then(|| {
            self.stats
                .iter()
                .map(|s| {
                    let half = 0.5 * (s.max - s.min);
                    (s.min - half, s.max + half)
                })
                .collect()
        })
    }

    /// The three acceptance intervals of each biomarker.
    pub fn intervals(&self) -> Vec<Intervals> {
        self.stats.iter().map(ReferenceStats::intervals).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{self, Family};

    #[test]
    fn stored_populations_keep_the_axes_they_were_measured_along() {
        let meshes: Vec<Mesh> = phantom::meshes(Family::Lv, 3, 5);
        let population = ReferencePopulation::from_meshes(&meshes).unwrap();
        assert_eq!(population.extent_axes, ExtentAxes::Surface);
        // A population stored before the field existed was measured along vertex axes,
        // and its members are measured the same way.
        let mut stored = serde_json::to_value(&population).unwrap();
        stored.as_object_mut().unwrap().remove("extent_axes");
        let old: ReferencePopulation = serde_json::from_value(stored).unwrap();
        assert_eq!(old.extent_axes, ExtentAxes::Vertices);
        assert_eq!(
            old.measure(&meshes[0]).unwrap(),
            Biomarkers::measure(&meshes[0], ExtentAxes::Vertices).unwrap()
        );
        assert_eq!(
            population.measure(&meshes[0]).unwrap(),
            Biomarkers::from_mesh(&meshes[0]).unwrap()
        );
    }
}
