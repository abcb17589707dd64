//! The spread table shown on model and cohort pages: each biomarker's cohort mean and sd
//! against the training population's, their ratios and the KS statistic.

use std::fmt::Write;

use super::{escape, mean_sd};
use crate::eval::fidelity::Spread;

/// sd ratios outside this band are marked: the cohort is narrower or wider than the
/// population by more than 15%.
pub const SD_RATIO_BAND: (f64, f64) = (0.85, 1.15);

/// One row: biomarker name, unit and its spread.
pub struct SpreadRow<'a> {
    /// Biomarker name, e.g. `volume_ml`.
    pub name: &'a str,
    /// Unit, e.g. `ml`.
    pub unit: &'a str,
    /// The comparison.
    pub spread: &'a Spread,
}

/// `<h2>` title, a sentence, then the table; empty without rows.
pub fn spread_table(title: &str, sentence: &str, rows: &[SpreadRow<'_>]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut t = format!(
        "<h2>{}</h2><p>{}</p><table><tr><th>biomarker</th><th>unit</th><th>training mean ± sd</th><th>cohort mean ± sd</th><th>mean ratio</th><th>sd ratio</th><th>KS D against training</th></tr>",
        escape(title),
        escape(sentence)
    );
    for r in rows {
        let s = r.spread;
        let outside = !(SD_RATIO_BAND.0..=SD_RATIO_BAND.1).contains(&s.sd_ratio);
        let _ = write!(
            t,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.3}</td><td{}>{:.3}</td><td>{:.3} ({})</td></tr>",
            escape(r.name),
            escape(r.unit),
            mean_sd(s.training_mean, s.training_sd),
            mean_sd(s.synthetic_mean, s.synthetic_sd),
            s.mean_ratio,
            if outside { " class=\"warn\"" } else { "" },
            s.sd_ratio,
            s.ks_statistic,
            p_value(s.ks_p_value)
        );
    }
    t.push_str("</table>");
    t
}

/// `p = 0.47`, or `p = 3.2e-9` when it would round to zero.
fn p_value(p: f64) -> String {
    if p >= 0.001 {
        format!("p = {p:.3}")
    } else {
        format!("p = {p:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_show_the_ratios_and_mark_a_narrow_cohort() {
        let narrow = Spread::between(&[9.0, 10.0, 11.0], &[0.0, 10.0, 20.0]).unwrap();
        let html = spread_table(
            "Spread",
            "1,000 members.",
            &[SpreadRow {
                name: "volume_ml",
                unit: "ml",
                spread: &narrow,
            }],
        );
        assert!(html.contains("<td>volume_ml</td>"), "{html}");
        assert!(html.contains("<td class=\"warn\">0.100</td>"), "{html}");
        assert!(spread_table("Spread", "", &[]).is_empty());
        assert_eq!(
            (p_value(0.4731), p_value(3.2e-9)),
            ("p = 0.473".to_owned(), "p = 3.2e-9".to_owned())
        );
    }
}
