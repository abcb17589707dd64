//! The per-cluster breakdown of a cohort: how many members each atlas (cluster) produced,
//! how they fare against the training population, and their biomarker statistics; and how
//! many training meshes, effectively, each cluster's generator learns from.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::ReferencePopulation;
use super::cohort::{Member, columns};
use super::{ClusterSummary, ModelError};
use crate::eval::acceptance::{Intervals, Rates, joint_acceptance_rates};
use crate::eval::stats::SummaryStats;

/// One cluster's members in a cohort report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ClusterReport {
    /// The cluster (atlas index).
    pub cluster: usize,
    /// Members drawn from it.
    pub count: usize,
    /// Its share of the cohort, 0–1.
    pub share: f64,
    /// Share of its members accepted on all biomarkers at once, per criterion (against the
    /// whole training population); absent when it has no members.
    pub acceptance: Option<Rates>,
    /// Its members' statistics per biomarker; empty when it has no members.
    pub biomarkers: BTreeMap<String, SummaryStats>,
}

/// The breakdown of `members` over `clusters` clusters (every cluster gets a row, empty
/// ones included).
pub fn cluster_reports(
    reference: &ReferencePopulation,
    intervals: &[Intervals],
    members: &[Member],
    clusters: usize,
) -> Result<Vec<ClusterReport>, ModelError> {
    let total = members.len().max(1) as f64;
    (0..clusters.max(1))
        .map(|cluster| {
            let of: Vec<&Member> = members.iter().filter(|m| m.cluster == cluster).collect();
            let mut report = ClusterReport {
                cluster,
                count: of.len(),
                share: of.len() as f64 / total,
                acceptance: None,
                biomarkers: BTreeMap::new(),
            };
            if of.is_empty() {
                return Ok(report);
            }
            let cols = columns(&of.iter().map(|m| &m.biomarkers).collect::<Vec<_>>());
            report.acceptance = Some(joint_acceptance_rates(intervals, &cols)?);
            for (name, values) in reference.names.iter().zip(&cols) {
                report
                    .biomarkers
                    .insert(name.clone(), SummaryStats::from_values(values)?);
            }
            Ok(report)
        })
        .collect()
}

/// The index of the largest weight (the winning cluster); 0 for an empty row.
pub fn winning_cluster(weights: &[f64]) -> usize {
    weights
        .iter()
        .enumerate()
        .fold((0, f64::NEG_INFINITY), |best, (m, &w)| {
            if w > best.1 { (m, w) } else { best }
        })
        .0
}

/// Effective training meshes a cluster's generator needs for its draws to vary rather
/// than repeat its meshes. On 8 LV phantoms (seed 1), generators of about 3, 4 and 8 meshes
/// made 46%, 37% and 2% of their members near copies of a training shape.
pub const MESHES_PER_GENERATOR: usize = 10;

/// How many atlases `training_meshes` meshes support: one per [`MESHES_PER_GENERATOR`],
/// at least one.
pub fn supported_atlases(training_meshes: usize) -> usize {
    (training_meshes / MESHES_PER_GENERATOR).max(1)
}

impl ClusterSummary {
    /// How many training meshes each cluster's generator learns from: Kish's effective
    /// sample size of its weights, `(Σ_k w_km)² / Σ_k w_km²` (its member count when the
    /// weights are 0 or 1). A mesh with weight in several clusters counts in each: with
    /// even weights every cluster learns from all the meshes, so the sizes need not add up
    /// to the training count.
    pub fn effective_meshes(&self) -> Vec<f64> {
        (0..self.priors.len())
            .map(|m| {
                let (sum, squares) = self
                    .training
                    .iter()
                    .filter_map(|row| row.get(m))
                    .fold((0.0, 0.0), |(s, q), w| (s + w, q + w * w));
                if squares > 0.0 {
                    sum * sum / squares
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// A warning when a cluster's generator learns from fewer than
    /// [`MESHES_PER_GENERATOR`] effective meshes (none otherwise).
    pub fn thin_cluster_note(&self) -> Option<String> {
        let effective = self.effective_meshes();
        if effective.len() < 2 {
            return None;
        }
        let thin: Vec<String> = effective
            .iter()
            .enumerate()
            .filter(|(_, e)| **e < MESHES_PER_GENERATOR as f64)
            .enumerate()
            .map(|(k, (m, e))| match k {
                0 => format!("cluster {m} learns from {e:.1} effective training meshes"),
                _ => format!("cluster {m} from {e:.1}"),
            })
            .collect();
        if thin.is_empty() {
            return None;
        }
        let supported = supported_atlases(self.training.len());
        Some(format!(
            "{} (fewer than {MESHES_PER_GENERATOR}): a generator fitted on so few mostly \
             reproduces its meshes, so many draws are near copies that the privacy guard \
             rejects. {} training meshes support {supported} atlas{}: fit with fewer atlases \
             (\"atlases\": \"auto\" chooses) or add meshes",
            thin.join(", "),
            self.training.len(),
            if supported == 1 { "" } else { "es" },
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(training: Vec<Vec<f64>>) -> ClusterSummary {
        let count = training.first().map_or(0, Vec::len);
        ClusterSummary {
            priors: vec![1.0 / count as f64; count],
            training,
            holdout: Vec::new(),
        }
    }

    #[test]
    fn hard_weights_count_members_and_soft_ones_less() {
        let hard = summary(vec![vec![1.0, 0.0], vec![1.0, 0.0], vec![0.0, 1.0]]);
        assert_eq!(hard.effective_meshes(), vec![2.0, 1.0]);
        // Two meshes of weight 0.5 and one of 1.0: (2)² / 1.5 = 2.67 effective meshes.
        let soft = summary(vec![vec![0.5, 0.5], vec![0.5, 0.5], vec![1.0, 0.0]]);
        let e = soft.effective_meshes();
        assert!((e[0] - 4.0 / 1.5).abs() < 1e-12 && (e[1] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn thin_clusters_are_named_and_enough_meshes_say_nothing() {
        let rows = |n: usize| (0..n).map(|k| vec![(k % 2) as f64, ((k + 1) % 2) as f64]);
        let thin = summary(rows(8).collect()).thin_cluster_note().unwrap();
        assert!(
            thin.starts_with(
                "cluster 0 learns from 4.0 effective training meshes, cluster 1 from 4.0 (fewer than 10):"
            ),
            "{thin}"
        );
        assert!(
            thin.contains("8 training meshes support 1 atlas:"),
            "{thin}"
        );
        assert_eq!(summary(rows(40).collect()).thin_cluster_note(), None);
        // One atlas: nothing to choose.
        assert_eq!(summary(vec![vec![1.0]; 3]).thin_cluster_note(), None);
    }
}
