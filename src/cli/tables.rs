//! Markdown tables for the offline commands, laid out like the thesis's tables 4.4–4.7:
//! a metric per row, a model (or distance kind) per column, `mean ± sd` in mm.

use crate::eval::MeanStd;
use crate::eval::acceptance::Rates;
use crate::eval::metrics::DistanceSummary;
use crate::models::cohort::CohortReport;

/// Shown where a column has no value.
pub const MISSING: &str = "n/a";

/// One distance of a [`DistanceSummary`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Metric {
    /// Hausdorff distance.
    Hd,
    /// Mean closest-point distance `ED`.
    Ed,
    /// Reverse mean closest-point distance `ED*`.
    EdStar,
    /// Chamfer distance `CD`.
    Cd,
}

impl Metric {
    /// Row label.
    pub fn label(self) -> &'static str {
        match self {
            Self::Hd => "HD",
            Self::Ed => "ED",
            Self::EdStar => "ED*",
            Self::Cd => "CD",
        }
    }

    fn of(self, s: &DistanceSummary) -> MeanStd {
        match self {
            Self::Hd => s.hd,
            Self::Ed => s.ed,
            Self::EdStar => s.ed_star,
            Self::Cd => s.cd,
        }
    }
}

/// Metrics of the matching table (thesis table 4.4).
pub const MATCHING: [Metric; 2] = [Metric::Hd, Metric::Cd];
/// Metrics of the generalisation and specificity tables (thesis tables 4.5, 4.6).
pub const DISTANCES: [Metric; 3] = [Metric::Hd, Metric::Ed, Metric::EdStar];

/// `mean ± sd` with two decimals.
pub fn mean_std(m: MeanStd) -> String {
    format!("{:.2} ± {:.2}", m.mean, m.std)
}

/// A markdown table from a header and rows of cells.
pub fn table(header: &[String], rows: &[Vec<String>]) -> String {
    let line = |cells: &[String]| format!("| {} |\n", cells.join(" | "));
    let mut out = line(header);
    out.push_str(&line(&vec!["---".to_owned(); header.len()]));
    for row in rows {
        out.push_str(&line(row));
    }
    out
}

/// A distance table: one row per metric and distance kind, one column per model.
/// `columns[c].1[k]` is model `c`'s summary under distance kind `kinds[k]`.
pub fn distance_table(
    metrics: &[Metric],
    kinds: &[&str],
    columns: &[(String, Vec<Option<DistanceSummary>>)],
) -> String {
    let mut header = vec!["metric".to_owned(), "distance".to_owned()];
    header.extend(columns.iter().map(|(name, _)| name.clone()));
    let mut rows = Vec::new();
    for (k, kind) in kinds.iter().enumerate() {
        for metric in metrics {
            let mut row = vec![metric.label().to_owned(), (*kind).to_owned()];
            row.extend(columns.iter().map(|(_, summaries)| {
                summaries
                    .get(k)
                    .copied()
                    .flatten()
                    .map_or(MISSING.to_owned(), |s| mean_std(metric.of(&s)))
            }));
            rows.push(row);
        }
    }
    table(&header, &rows)
}

/// A share 0–1 as a percentage with two decimals.
pub fn percent(share: f64) -> String {
    format!("{:.2}", 100.0 * share)
}

fn rates_row(label: &str, r: &Rates) -> Vec<String> {
    vec![
        label.to_owned(),
        percent(r.range),
        percent(r.mode),
        percent(r.mean),
    ]
}

/// The acceptance table of a cohort (thesis table 4.7): A^r, A^M, A^μ in % per biomarker,
/// then jointly over all biomarkers.
pub fn acceptance_table(report: &CohortReport) -> String {
    let header = ["biomarker", "A^r [min, max]", "A^M M ± 3B", "A^μ μ ± 2σ"].map(String::from);
    let mut rows: Vec<Vec<String>> = report
        .biomarkers
        .iter()
        .map(|(name, b)| rates_row(name, &b.acceptance))
        .collect();
    rows.push(rates_row("all (joint)", &report.acceptance));
    table(&header, &rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn summary(hd: f64) -> DistanceSummary {
        let m = |mean| MeanStd { mean, std: 0.5 };
        DistanceSummary {
            hd: m(hd),
            ed: m(1.0),
            ed_star: m(2.0),
            cd: m(3.0),
        }
    }

    #[test]
    fn distance_table_layout() {
        let columns = vec![
            ("rsmp".to_owned(), vec![Some(summary(8.0)), None]),
            (
                "other".to_owned(),
                vec![Some(summary(6.25)), Some(summary(5.0))],
            ),
        ];
        let text = distance_table(&MATCHING, &["v2v", "p2s"], &columns);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "| metric | distance | rsmp | other |");
        assert_eq!(lines[1], "| --- | --- | --- | --- |");
        assert_eq!(lines[2], "| HD | v2v | 8.00 ± 0.50 | 6.25 ± 0.50 |");
        assert_eq!(lines[3], "| CD | v2v | 3.00 ± 0.50 | 3.00 ± 0.50 |");
        assert_eq!(lines[4], "| HD | p2s | n/a | 5.00 ± 0.50 |");
        assert_eq!(lines.len(), 6);
    }
}
