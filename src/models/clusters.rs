//! The per-cluster breakdown of a cohort: how many members each atlas (cluster) produced,
//! how they fare against the training population, and their biomarker statistics.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::ModelError;
use super::ReferencePopulation;
use super::cohort::{Member, columns};
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
