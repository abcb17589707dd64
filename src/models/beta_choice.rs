//! How a generator's KL weight β was chosen on held-out folds of its training shapes: the
//! figures of every candidate and the one kept, for the model summary.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Most near copies among a candidate's fold draws for it to be kept (a generator that
/// draws from the population flags about the threshold's percentile, 5%).
pub const NEAR_COPY_BOUND: f64 = 0.08;

/// One candidate β measured on the folds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BetaCandidate {
    /// The KL weight.
    pub beta: f64,
    /// Share (0–1) of the draws of the fold generators nearer to one of their training
    /// shapes than the near-copy threshold of those shapes.
    pub near_copy_fraction: f64,
    /// Mean distance between corresponding vertices of each held-out shape and its
    /// reconstruction by the generator that did not see it, mm.
    pub holdout_error_mm: f64,
}

/// The KL weight of one generator, chosen on held-out folds of its training shapes: the
/// candidate with the smallest held-out error among those whose draws are near copies of
/// their training shapes at most 8% of the time (none: the fewest near copies).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BetaChoice {
    /// Cluster of the generator (models with several atlases); absent for one generator.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cluster: Option<usize>,
    /// Folds the training shapes were split into; each is held out once.
    pub folds: usize,
    /// Shapes drawn from each fold's generator.
    pub draws_per_fold: usize,
    /// Every candidate, in increasing β.
    pub candidates: Vec<BetaCandidate>,
    /// The β the generator was trained with.
    pub chosen: f64,
    /// Whether the chosen β keeps the folds' near copies within 8% of their draws.
    pub within_bound: bool,
}

impl BetaChoice {
    /// Picks among measured candidates (see [`BetaChoice`]); `None` without candidates.
    pub fn pick(
        cluster: Option<usize>,
        folds: usize,
        draws_per_fold: usize,
        candidates: Vec<BetaCandidate>,
    ) -> Option<Self> {
        let within = candidates
            .iter()
            .filter(|c| c.near_copy_fraction <= NEAR_COPY_BOUND)
            .min_by(|a, b| a.holdout_error_mm.total_cmp(&b.holdout_error_mm));
        let fewest = || {
            candidates
                .iter()
                .min_by(|a, b| a.near_copy_fraction.total_cmp(&b.near_copy_fraction))
        };
        let chosen = within.or_else(fewest)?.beta;
        Some(Self {
            cluster,
            folds,
            draws_per_fold,
            within_bound: within.is_some(),
            chosen,
            candidates,
        })
    }

    /// What was kept and why, without the candidates' figures.
    pub fn outcome(&self) -> String {
        let whose = match self.cluster {
            Some(m) => format!("The generator of cluster {}", m + 1),
            None => "The generator".to_owned(),
        };
        let why = if self.within_bound {
            format!(
                "the smallest held-out error among those with at most {:.0}% near copies",
                100.0 * NEAR_COPY_BOUND
            )
        } else {
            format!(
                "no candidate kept near copies within {:.0}%, so the fewest",
                100.0 * NEAR_COPY_BOUND
            )
        };
        format!(
            "{whose} was trained with KL weight β {} chosen on {} held-out folds of its \
             training shapes ({why})",
            self.chosen, self.folds
        )
    }

    /// One sentence for the model summary: [`Self::outcome`] and every candidate's figures.
    pub fn sentence(&self) -> String {
        let measured = self
            .candidates
            .iter()
            .map(|c| {
                format!(
                    "β {}: {:.1}% near copies, held-out error {:.2} mm",
                    c.beta,
                    100.0 * c.near_copy_fraction,
                    c.holdout_error_mm
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        format!("{}: {measured}.", self.outcome())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(beta: f64, near_copy_fraction: f64, holdout_error_mm: f64) -> BetaCandidate {
        BetaCandidate {
            beta,
            near_copy_fraction,
            holdout_error_mm,
        }
    }

    #[test]
    fn the_best_held_out_error_among_candidates_within_the_near_copy_bound_is_kept() {
        let candidates = vec![
            candidate(1.0, 0.40, 1.0),
            candidate(3.0, 0.05, 1.4),
            candidate(10.0, 0.02, 1.2),
            candidate(30.0, 0.00, 2.0),
        ];
        let choice = BetaChoice::pick(None, 4, 100, candidates).unwrap();
        assert_eq!(choice.chosen, 10.0);
        assert!(choice.within_bound);
        assert!(
            choice
                .sentence()
                .contains("β 10 chosen on 4 held-out folds")
        );
    }

    #[test]
    fn without_a_candidate_within_the_bound_the_fewest_near_copies_are_kept() {
        let candidates = vec![candidate(1.0, 0.5, 1.0), candidate(3.0, 0.2, 1.5)];
        let choice = BetaChoice::pick(Some(1), 4, 100, candidates).unwrap();
        assert_eq!(choice.chosen, 3.0);
        assert!(!choice.within_bound);
        let sentence = choice.sentence();
        assert!(
            sentence.starts_with("The generator of cluster 2"),
            "{sentence}"
        );
        assert!(sentence.contains("no candidate kept"), "{sentence}");
        assert!(BetaChoice::pick(None, 4, 100, vec![]).is_none());
    }
}
