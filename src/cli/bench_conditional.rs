//! The bench's conditional cohort: as many members as the plain cohort, drawn with their
//! volume inside the large-organ range of the training population.

use std::time::Instant;

use super::bench_report::ConditionalBench;
use crate::eval::privacy::PrivacyThreshold;
use crate::eval::stats;
use crate::models::cohort::{CohortSpec, Member, TrainingIndex, sample_cohort_given};
use crate::models::progress::Silent;
use crate::models::{ReferencePopulation, ShapeModel};

/// The interval the conditional cohort of the bench asks for (ml): the large organs of the
/// training population, its volume mean plus one to three sd, rounded to whole ml (LV
/// phantoms: about 118–148 ml, liver phantoms about 1,590–2,010 ml). `None` without volumes.
pub fn bench_volume_target(reference: &ReferencePopulation) -> Option<(f64, f64)> {
    let b = reference.names.iter().position(|n| n == "volume_ml")?;
    let volumes = reference.values.get(b)?;
    if volumes.len() < 2 {
        return None;
    }
    let (mean, sd) = (stats::mean(volumes), stats::sample_sd(volumes));
    Some(((mean + sd).round(), (mean + 3.0 * sd).round()))
}

/// A cohort of the same size whose volume is conditioned on [`bench_volume_target`].
pub(super) fn bench_conditional<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    reference: &ReferencePopulation,
    normalised: &[Vec<Vec<[f64; 3]>>],
    privacy: &[PrivacyThreshold],
    spec: &CohortSpec,
    plain: &[Member],
) -> ConditionalBench {
    use crate::models::conditional::{Conditional, Target};
    let (min, max) = bench_volume_target(reference).unwrap_or((f64::NAN, f64::NAN));
    let targets = [(
        "volume_ml".to_owned(),
        Target::Interval {
            min: Some(min),
            max: Some(max),
        },
    )];
    let spec = CohortSpec {
        max_draws: 20 * spec.size,
        ..*spec
    };
    let started = Instant::now();
    let drawn = Conditional::new(model, &targets, spec.seed).and_then(|c| {
        let index = TrainingIndex::new(normalised, privacy)?;
        sample_cohort_given(model, reference, &index, &spec, Some(&c), &mut Silent)
    });
    let mean_area =
        |m: &[Member]| m.iter().map(|m| m.biomarkers.area_cm2).sum::<f64>() / m.len().max(1) as f64;
    match drawn {
        Ok((members, report)) => ConditionalBench {
            target_ml: (min, max),
            seconds: started.elapsed().as_secs_f64(),
            inside: members
                .iter()
                .filter(|m| (min..=max).contains(&m.biomarkers.volume_ml))
                .count() as f64
                / members.len().max(1) as f64,
            draws_per_member: report.draws as f64 / members.len().max(1) as f64,
            area_cm2: Some((mean_area(plain), mean_area(&members))),
            error: None,
        },
        Err(e) => ConditionalBench {
            target_ml: (min, max),
            seconds: started.elapsed().as_secs_f64(),
            inside: 0.0,
            draws_per_member: f64::NAN,
            area_cm2: None,
            error: Some(e.to_string()),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_target_is_the_training_volume_mean_plus_one_to_three_sd() {
        let reference = ReferencePopulation {
            names: vec!["area_cm2".into(), "volume_ml".into()],
            units: vec!["cm²".into(), "ml".into()],
            values: vec![vec![1.0, 2.0, 3.0], vec![100.0, 110.0, 120.0]],
            stats: Vec::new(),
            extent_axes: crate::eval::biomarkers::ExtentAxes::Surface,
        };
        // Mean 110 ml, sample sd 10 ml.
        assert_eq!(bench_volume_target(&reference), Some((120.0, 140.0)));
        let without_volume = ReferencePopulation {
            names: vec!["area_cm2".into()],
            values: vec![vec![1.0, 2.0, 3.0]],
            ..reference
        };
        assert_eq!(bench_volume_target(&without_volume), None);
    }
}
