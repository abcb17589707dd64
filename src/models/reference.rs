//! The reference population of a model: biomarkers of its training meshes, against which
//! the clinical acceptance of virtual cohort members is judged (SPEC §3, thesis table 3.1).

use serde::{Deserialize, Serialize};

use super::ModelError;
use crate::eval::Biomarkers;
use crate::eval::acceptance::{Intervals, ReferenceStats};
use crate::mesh::Mesh;

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
        })
    }

    /// The three acceptance intervals of each biomarker.
    pub fn intervals(&self) -> Vec<Intervals> {
        self.stats.iter().map(ReferenceStats::intervals).collect()
    }
}
