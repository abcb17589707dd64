//! What `bench` reports about the clusters of a multi-atlas model: how many training
//! phantoms each cluster won, the priors, and with labelled phantoms (the `mixed` family)
//! the adjusted Rand index of the winning clusters against the labels, the table of labels
//! by cluster, and how many cohort members lie outside every sub-population's biomarker
//! ranges (a member that mixes sub-populations).

use serde::Serialize;

use crate::eval::biomarkers::Biomarkers;
use crate::eval::clustering::adjusted_rand_index;
use crate::models::ClusterSummary;
use crate::models::clusters::winning_cluster;

/// The clusters of one benched model.
#[derive(Debug, Clone, Serialize)]
pub struct ClusterBench {
    /// Training phantoms won by each cluster.
    pub sizes: Vec<usize>,
    /// `π_m`.
    pub priors: Vec<f64>,
    /// Effective training meshes (Kish) each cluster's generator learned from.
    pub effective_meshes: Vec<f64>,
    /// Adjusted Rand index of the winning clusters against the labels (labelled families).
    pub adjusted_rand_index: Option<f64>,
    /// Per label, the training phantoms each cluster won.
    pub by_label: Vec<(String, Vec<usize>)>,
    /// Cohort members whose biomarkers are not all within the training range of any one
    /// sub-population (labelled families).
    pub mixing_members: Option<usize>,
    /// The same count among fresh phantoms of the true population, and their number: how
    /// often a real subject falls outside every range.
    pub mixing_fresh: Option<(usize, usize)>,
}

impl ClusterBench {
    /// From the fit's clusters, the training labels (if any), the training biomarkers
    /// (`values[b][k]`, in [`Biomarkers::NAMES`] order) and the cohort's biomarkers.
    pub fn new(
        clusters: &ClusterSummary,
        labels: Option<&[String]>,
        training_values: &[Vec<f64>],
        members: &[Biomarkers],
        fresh: &[Biomarkers],
    ) -> Self {
        let count = clusters.priors.len();
        let won: Vec<usize> = clusters
            .training
            .iter()
            .map(|w| winning_cluster(w))
            .collect();
        let mut sizes = vec![0; count];
        for &c in &won {
            sizes[c] += 1;
        }
        let mut bench = Self {
            sizes,
            priors: clusters.priors.clone(),
            effective_meshes: clusters.effective_meshes(),
            adjusted_rand_index: None,
            by_label: Vec::new(),
            mixing_members: None,
            mixing_fresh: None,
        };
        let Some(labels) = labels.filter(|l| l.len() == won.len()) else {
            return bench;
        };
        let mut names: Vec<String> = labels.to_vec();
        names.sort();
        names.dedup();
        let ids: Vec<usize> = labels
            .iter()
            .map(|l| names.iter().position(|n| n == l).unwrap_or(0))
            .collect();
        bench.adjusted_rand_index = adjusted_rand_index(&won, &ids).ok();
        bench.by_label = names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let mut row = vec![0; count];
                for (k, &c) in won.iter().enumerate() {
                    if ids[k] == i {
                        row[c] += 1;
                    }
                }
                (name.clone(), row)
            })
            .collect();
        let ranges: Vec<Vec<(f64, f64)>> = (0..names.len())
            .map(|i| {
                training_values
                    .iter()
                    .map(|column| {
                        column
                            .iter()
                            .zip(&ids)
                            .filter(|(_, l)| **l == i)
                            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (v, _)| {
                                (lo.min(*v), hi.max(*v))
                            })
                    })
                    .collect()
            })
            .collect();
        let within = |m: &Biomarkers, range: &[(f64, f64)]| {
            m.values()
                .iter()
                .zip(range)
                .all(|(v, (lo, hi))| v >= lo && v <= hi)
        };
        let outside = |set: &[Biomarkers]| {
            set.iter()
                .filter(|m| !ranges.iter().any(|r| within(m, r)))
                .count()
        };
        bench.mixing_members = Some(outside(members));
        bench.mixing_fresh = Some((outside(fresh), fresh.len()));
        bench
    }
}

/// The markdown lines of one model's clusters.
pub fn cluster_markdown(model: &str, c: &ClusterBench) -> String {
    let list = |v: &[usize]| {
        v.iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(" / ")
    };
    let priors: Vec<String> = c.priors.iter().map(|p| format!("{p:.3}")).collect();
    let effective: Vec<String> = c
        .effective_meshes
        .iter()
        .map(|e| format!("{e:.1}"))
        .collect();
    let mut out = format!(
        "- **{model}**: training phantoms per cluster {} (effective training meshes, Kish: {}); priors π {}",
        list(&c.sizes),
        effective.join(" / "),
        priors.join(" / ")
    );
    if let Some(ari) = c.adjusted_rand_index {
        out.push_str(&format!(
            "; adjusted Rand index against the labels {ari:.3}"
        ));
    }
    for (label, row) in &c.by_label {
        out.push_str(&format!("; {label}: {}", list(row)));
    }
    if let Some(n) = c.mixing_members {
        out.push_str(&format!(
            "; cohort members outside every sub-population's biomarker ranges: {n}"
        ));
    }
    if let Some((n, of)) = c.mixing_fresh {
        out.push_str(&format!(" (fresh phantoms of the population: {n} of {of})"));
    }
    out.push('\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_rand_index_and_mixing_members() {
        let clusters = ClusterSummary {
            priors: vec![0.5, 0.5],
            training: vec![
                vec![0.9, 0.1],
                vec![0.8, 0.2],
                vec![0.3, 0.7],
                vec![0.1, 0.9],
            ],
            holdout: Vec::new(),
        };
        let labels: Vec<String> = ["bean", "bean", "ring", "ring"].map(String::from).to_vec();
        // Volume 100–110 for beans, 200–210 for rings; other biomarkers all 1.
        let mut values = vec![vec![100.0, 110.0, 200.0, 210.0]];
        values.extend((1..6).map(|_| vec![1.0; 4]));
        let member = |volume_ml: f64| Biomarkers {
            volume_ml,
            area_cm2: 1.0,
            sphericity: 1.0,
            extent_major_mm: 1.0,
            extent_middle_mm: 1.0,
            extent_minor_mm: 1.0,
        };
        let members = [member(105.0), member(205.0), member(150.0)];
        let c = ClusterBench::new(&clusters, Some(&labels), &values, &members, &members[..2]);
        assert_eq!(c.sizes, [2, 2]);
        assert_eq!(c.adjusted_rand_index, Some(1.0));
        assert_eq!(c.by_label[0], ("bean".to_owned(), vec![2, 0]));
        assert_eq!(c.mixing_members, Some(1), "only the 150 ml member mixes");
        assert_eq!(c.mixing_fresh, Some((0, 2)));
        let unlabelled = ClusterBench::new(&clusters, None, &values, &members, &[]);
        assert_eq!(unlabelled.adjusted_rand_index, None);
    }
}
