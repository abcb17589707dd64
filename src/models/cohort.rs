//! Virtual cohorts: seeded draws from a model, each member's biomarkers judged against the
//! training population (clinical acceptance, SPEC §3 and thesis table 3.1).

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{ModelError, ReferencePopulation, ShapeModel};
use crate::eval::Biomarkers;
use crate::eval::acceptance::{Flags, Intervals, Rates, ReferenceStats, joint_acceptance_rates};
use crate::eval::stats::SummaryStats;
use crate::geometry::pca::Sampling;
use crate::mesh::Mesh;

/// Acceptance criterion that decides whether a member is kept with `only_accepted`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// Inside the training range `[min, max]` (A^r).
    Range,
    /// Inside `M ± 3B` around the KDE mode (A^M).
    Mode,
    /// Inside `μ ± 2σ` (A^μ).
    #[default]
    Mean,
}

impl Criterion {
    /// Name as in the API.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Range => "range",
            Self::Mode => "mode",
            Self::Mean => "mean",
        }
    }

    fn passes(self, flags: Flags) -> bool {
        match self {
            Self::Range => flags.range,
            Self::Mode => flags.mode,
            Self::Mean => flags.mean,
        }
    }
}

/// What to sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CohortSpec {
    /// Members wanted.
    pub size: usize,
    /// Seed: the same seed and model give the same members.
    pub seed: u64,
    /// How latent coefficients are drawn.
    pub sampling: Sampling,
    /// Criterion for `only_accepted`.
    pub criterion: Criterion,
    /// Keep drawing until `size` members pass the criterion on every biomarker.
    pub only_accepted: bool,
    /// Most draws before giving up (with `only_accepted`).
    pub max_draws: usize,
}

/// One member of a cohort.
#[derive(Debug, Clone)]
pub struct Member {
    /// Position in the cohort, from 0.
    pub index: usize,
    /// Draw number it came from (equal to `index` unless members were rejected).
    pub draw: u64,
    /// The shape (mm, the model's connectivity).
    pub mesh: Mesh,
    /// Its biomarkers.
    pub biomarkers: Biomarkers,
    /// Accepted on every biomarker, per criterion.
    pub accepted: Flags,
}

/// Statistics of one biomarker in a cohort report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BiomarkerReport {
    /// Unit, e.g. `ml`.
    pub unit: String,
    /// The training population's statistics.
    pub reference: ReferenceStats,
    /// The three acceptance intervals.
    pub intervals: Intervals,
    /// The cohort's statistics.
    pub synthetic: SummaryStats,
    /// Share of members inside each interval.
    pub acceptance: Rates,
}

/// The acceptance report of a cohort.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CohortReport {
    /// Per biomarker, by name.
    pub biomarkers: BTreeMap<String, BiomarkerReport>,
    /// Share of members accepted on all biomarkers at once, per criterion.
    pub acceptance: Rates,
    /// Draws made (more than the size when members were rejected).
    pub draws: usize,
    /// Joint acceptance over every draw, rejected ones included.
    pub draw_acceptance: Rates,
}

/// The random stream of draw `draw`: independent of the others and of their order.
pub fn draw_rng(seed: u64, draw: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(draw);
    rng
}

fn joint_flags(intervals: &[Intervals], biomarkers: &Biomarkers) -> Flags {
    let all = Flags {
        range: true,
        mode: true,
        mean: true,
    };
    intervals
        .iter()
        .zip(biomarkers.values())
        .fold(all, |acc, (iv, v)| acc.and(iv.accepted(v)))
}

/// Draws a cohort and its report.
pub fn sample_cohort(
    model: &dyn ShapeModel,
    reference: &ReferencePopulation,
    spec: &CohortSpec,
) -> Result<(Vec<Member>, CohortReport), ModelError> {
    let intervals = reference.intervals();
    let limit = if spec.only_accepted {
        spec.max_draws.max(spec.size)
    } else {
        spec.size
    };
    let (mut members, mut all_draws) = (Vec::with_capacity(spec.size), Vec::new());
    let mut draw = 0u64;
    while members.len() < spec.size && (draw as usize) < limit {
        let mesh = model.sample(&mut draw_rng(spec.seed, draw), spec.sampling)?;
        let biomarkers = Biomarkers::from_mesh(&mesh)?;
        let accepted = joint_flags(&intervals, &biomarkers);
        all_draws.push(biomarkers);
        if !spec.only_accepted || spec.criterion.passes(accepted) {
            members.push(Member {
                index: members.len(),
                draw,
                mesh,
                biomarkers,
                accepted,
            });
        }
        draw += 1;
    }
    if members.len() < spec.size {
        return Err(ModelError::AcceptanceUnreachable {
            size: spec.size,
            accepted: members.len(),
            draws: draw as usize,
            criterion: spec.criterion.as_str(),
        });
    }
    let report = report(reference, &intervals, &members, &all_draws)?;
    Ok((members, report))
}

fn columns(biomarkers: &[&Biomarkers]) -> Vec<Vec<f64>> {
    (0..Biomarkers::NAMES.len())
        .map(|b| biomarkers.iter().map(|m| m.values()[b]).collect())
        .collect()
}

fn report(
    reference: &ReferencePopulation,
    intervals: &[Intervals],
    members: &[Member],
    all_draws: &[Biomarkers],
) -> Result<CohortReport, ModelError> {
    let member_columns = columns(&members.iter().map(|m| &m.biomarkers).collect::<Vec<_>>());
    let draw_columns = columns(&all_draws.iter().collect::<Vec<_>>());
    let mut biomarkers = BTreeMap::new();
    for (b, name) in reference.names.iter().enumerate() {
        biomarkers.insert(
            name.clone(),
            BiomarkerReport {
                unit: reference.units.get(b).cloned().unwrap_or_default(),
                reference: reference.stats[b],
                intervals: intervals[b],
                synthetic: SummaryStats::from_values(&member_columns[b])?,
                acceptance: intervals[b].acceptance_rates(&member_columns[b]),
            },
        );
    }
    Ok(CohortReport {
        biomarkers,
        acceptance: joint_acceptance_rates(intervals, &member_columns)?,
        draws: all_draws.len(),
        draw_acceptance: joint_acceptance_rates(intervals, &draw_columns)?,
    })
}
