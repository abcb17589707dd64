//! Virtual cohorts: seeded draws from a model, each member's biomarkers judged against the
//! training population (clinical acceptance, SPEC §3 and thesis table 3.1).

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::clusters::{ClusterReport, cluster_reports};
use super::conditional::Conditional;
use super::folding::Folding;
use super::progress::{Progress, ProgressUpdate, Silent};
pub use super::targets_report::TargetsReport;
use super::{Draw, ModelError, ReferencePopulation, ShapeModel};
use crate::eval::Biomarkers;
use crate::eval::acceptance::{Flags, Intervals, Rates, ReferenceStats, joint_acceptance_rates};
use crate::eval::fidelity::Spread;
use crate::eval::metrics::parallel_map;
use crate::eval::privacy::{CorrespondedShapes, NearestTraining, PrivacyThreshold};
use crate::eval::stats::SummaryStats;
use crate::geometry::pca::Sampling;
use crate::mesh::Mesh;

/// Acceptance criterion that decides whether a member is kept with `only_accepted`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, utoipa::ToSchema)]
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
    /// Draw again instead of keeping a member that is a near copy of a training shape.
    pub exclude_near_copies: bool,
    /// Most draws before giving up (with `only_accepted` or `exclude_near_copies`).
    pub max_draws: usize,
}

/// One member of a cohort.
#[derive(Debug, Clone)]
pub struct Member {
    /// Position in the cohort, from 0.
    pub index: usize,
    /// Draw number it came from (equal to `index` unless members were rejected).
    pub draw: u64,
    /// The shape (mm, the connectivity of its cluster's atlas).
    pub mesh: Mesh,
    /// The cluster (atlas) it was drawn from; 0 for single-atlas models.
    pub cluster: usize,
    /// Its biomarkers.
    pub biomarkers: Biomarkers,
    /// Accepted on every biomarker, per criterion.
    pub accepted: Flags,
    /// The nearest training shape and the distance to it.
    pub nearest_training: NearestTraining,
    /// Nearer to a training shape than the privacy threshold.
    pub near_copy: bool,
}

/// Statistics of one biomarker in a cohort report.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
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
    /// The cohort's spread against the training values: mean and sd ratios, KS statistic
    /// (absent in reports stored before it existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spread: Option<Spread>,
}

/// The acceptance report of a cohort.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct CohortReport {
    /// Per biomarker, by name.
    pub biomarkers: BTreeMap<String, BiomarkerReport>,
    /// Share of members accepted on all biomarkers at once, per criterion.
    pub acceptance: Rates,
    /// Draws made (more than the size when members were rejected).
    pub draws: usize,
    /// Joint acceptance over every draw, rejected ones included.
    pub draw_acceptance: Rates,
    /// The privacy guard: threshold and how many members are near copies.
    pub privacy: PrivacyReport,
    /// Per cluster (atlas): count, share, acceptance and biomarker statistics of its
    /// members; one row for single-atlas models.
    #[serde(default)]
    pub clusters: Vec<ClusterReport>,
    /// Said when the training population is too small for its estimates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub population_note: Option<String>,
    /// Draws replaced because a biomarker fell outside the plausible range of a small
    /// population (the training range widened by half its width on either side).
    #[serde(default)]
    pub implausible_replaced: usize,
    /// The targets of a conditional cohort and how well its members meet them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub targets: Option<TargetsReport>,
    /// How often the members' surfaces fold over (absent in reports stored before it was
    /// measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub folding: Option<Folding>,
}

/// Privacy part of a cohort report.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct PrivacyReport {
    /// Members nearer than this (mm) to a training shape are near copies (atlas 0's
    /// threshold; see `thresholds_mm` for each atlas).
    pub threshold_mm: f64,
    /// The threshold of each atlas, mm: members of cluster `m` are compared with the
    /// training shapes normalised to atlas `m`.
    #[serde(default)]
    pub thresholds_mm: Vec<f64>,
    /// Percentile of the training nearest-neighbour distances used as the threshold.
    pub percentile: f64,
    /// How the distance is measured.
    pub distance: String,
    /// What the threshold's percentile is taken of: `nearest_training_shape` (each training
    /// shape's distance to its nearest other) or, below 20 training meshes,
    /// `leave_one_out_projection` (the distance from each training shape's projection on the
    /// affine hull of the others, which is what a model of a few shapes makes of a patient it
    /// has not seen). Absent in reports stored before it existed: `nearest_training_shape`.
    #[serde(default = "nearest_training_shape")]
    pub threshold_basis: String,
    /// Near copies among the members.
    pub near_copies: usize,
    /// Near copies drawn and replaced (with `exclude_near_copies`).
    pub near_copies_replaced: usize,
}

fn nearest_training_shape() -> String {
    "nearest_training_shape".to_owned()
}

/// The random stream of draw `draw`: independent of the others and of their order.
pub fn draw_rng(seed: u64, draw: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(draw);
    rng
}

fn joint_flags(intervals: &[Intervals], biomarkers: &Biomarkers) -> Flags {
    intervals
        .iter()
        .zip(biomarkers.values())
        .fold(Flags::ALL, |acc, (iv, v)| acc.and(iv.accepted(v)))
}

/// Fewest draws evaluated together (in parallel, then taken in draw order).
const DRAW_BATCH: u64 = 32;
/// Most draws evaluated together: progress is reported (and cancellation checked) between
/// batches. The batch size never changes which members are drawn.
const MAX_DRAW_BATCH: u64 = 1024;

/// One draw evaluated.
struct Evaluated {
    mesh: Mesh,
    cluster: usize,
    biomarkers: Biomarkers,
    accepted: Flags,
    nearest: NearestTraining,
    near_copy: bool,
}

/// The shape of draw `draw` of a cohort: from its own random stream, through the
/// conditional sampler when there are targets. The same inputs give the same shape, which is
/// how a member is drawn again.
pub fn draw_shape<M: ShapeModel + ?Sized>(
    model: &M,
    spec: &CohortSpec,
    conditional: Option<&Conditional>,
    draw: u64,
) -> Result<Draw, ModelError> {
    let mut rng = draw_rng(spec.seed, draw);
    match conditional {
        Some(c) => c.draw(model, &mut rng),
        None => model.sample(&mut rng, spec.sampling),
    }
}

fn evaluate_draw<M: ShapeModel + ?Sized>(
    model: &M,
    reference: &ReferencePopulation,
    intervals: &[Intervals],
    training: &TrainingIndex<'_>,
    spec: &CohortSpec,
    conditional: Option<&Conditional>,
    draw: u64,
) -> Result<Evaluated, ModelError> {
    let sampled = draw_shape(model, spec, conditional, draw)?;
    let (shapes, privacy) = training.of_cluster(sampled.cluster)?;
    let biomarkers = reference.measure(&sampled.mesh)?;
    let accepted = joint_flags(intervals, &biomarkers);
    let nearest = shapes.nearest(&sampled.mesh.vertices)?;
    Ok(Evaluated {
        near_copy: nearest.distance_mm < privacy.threshold_mm,
        mesh: sampled.mesh,
        cluster: sampled.cluster,
        biomarkers,
        accepted,
        nearest,
    })
}

/// The training shapes a cohort is checked against, per atlas.
pub struct TrainingIndex<'a> {
    /// `shapes[m]`: the training shapes normalised to atlas `m`, in correspondence with the
    /// members of cluster `m` (model frame, mm).
    pub shapes: Vec<CorrespondedShapes>,
    /// Near-copy threshold of each atlas.
    pub privacy: &'a [PrivacyThreshold],
}

impl<'a> TrainingIndex<'a> {
    /// From the training shapes normalised to each atlas (`[atlas][shape]`) and the
    /// thresholds of each atlas.
    pub fn new(
        normalised: &'a [Vec<Vec<[f64; 3]>>],
        privacy: &'a [PrivacyThreshold],
    ) -> Result<Self, ModelError> {
        if normalised.len() != privacy.len() {
            return Err(ModelError::InvalidInput(format!(
                "{} atlases of training shapes but {} privacy thresholds",
                normalised.len(),
                privacy.len()
            )));
        }
        let shapes = normalised
            .iter()
            .map(|s| CorrespondedShapes::new(s))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { shapes, privacy })
    }

    fn of_cluster(
        &self,
        cluster: usize,
    ) -> Result<(&CorrespondedShapes, &PrivacyThreshold), ModelError> {
        match (self.shapes.get(cluster), self.privacy.get(cluster)) {
            (Some(s), Some(p)) => Ok((s, p)),
            _ => Err(ModelError::InvalidInput(format!(
                "a draw of cluster {cluster} but training shapes for {} atlases",
                self.shapes.len()
            ))),
        }
    }
}

/// Draws a cohort and its report.
pub fn sample_cohort<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    reference: &ReferencePopulation,
    training: &TrainingIndex<'_>,
    spec: &CohortSpec,
) -> Result<(Vec<Member>, CohortReport), ModelError> {
    sample_cohort_given(model, reference, training, spec, None, &mut Silent)
}

/// Draws a cohort whose members meet the targets of `conditional` (drawn from the model's
/// conditional Gaussian; members outside an interval target are drawn again), or a plain
/// cohort without it. Progress is reported to `progress` after every batch of draws, which
/// may stop the sampling with [`ModelError::Cancelled`].
pub fn sample_cohort_given<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    reference: &ReferencePopulation,
    training: &TrainingIndex<'_>,
    spec: &CohortSpec,
    conditional: Option<&Conditional>,
    progress: &mut dyn Progress,
) -> Result<(Vec<Member>, CohortReport), ModelError> {
    let intervals = reference.intervals();
    let plausible = reference.plausible_ranges();
    let filtering = spec.only_accepted
        || spec.exclude_near_copies
        || conditional.is_some()
        || plausible.is_some();
    let limit = if filtering {
        spec.max_draws.max(spec.size)
    } else {
        spec.size
    } as u64;
    let (mut members, mut all_draws, mut replaced) = (Vec::with_capacity(spec.size), Vec::new(), 0);
    let mut implausible = 0;
    let mut next = 0u64;
    while members.len() < spec.size && next < limit {
        let wanted = (spec.size - members.len()) as u64;
        let step = wanted.clamp(DRAW_BATCH, MAX_DRAW_BATCH);
        let batch: Vec<u64> = (next..limit.min(next + step)).collect();
        let evaluated = parallel_map(&batch, |&d| {
            evaluate_draw(model, reference, &intervals, training, spec, conditional, d)
        });
        for (draw, result) in batch.iter().zip(evaluated) {
            next = draw + 1;
            let e = result?;
            all_draws.push(e.biomarkers);
            if conditional.is_some_and(|c| !c.meets(&e.biomarkers)) {
                continue;
            }
            if plausible
                .as_ref()
                .is_some_and(|ranges| !within(ranges, &e.biomarkers))
            {
                implausible += 1;
                continue;
            }
            if spec.exclude_near_copies && e.near_copy {
                replaced += 1;
                continue;
            }
            if spec.only_accepted && !spec.criterion.passes(e.accepted) {
                continue;
            }
            let index = members.len();
            members.push(Member {
                index,
                draw: *draw,
                mesh: e.mesh,
                cluster: e.cluster,
                biomarkers: e.biomarkers,
                accepted: e.accepted,
                nearest_training: e.nearest,
                near_copy: e.near_copy,
            });
            if members.len() == spec.size {
                break;
            }
        }
        progress.report(ProgressUpdate {
            stage: "sampling",
            step: members.len() as u64,
            total: spec.size as u64,
            fraction: members.len() as f64 / spec.size as f64,
            message: format!(
                "{} of {} members after {next} draws",
                members.len(),
                spec.size
            ),
            loss: None,
        })?;
    }
    if let Some(c) = conditional
        && members.len() < spec.size
        && all_draws.iter().filter(|b| c.meets(b)).count() < spec.size
    {
        return Err(c.unreachable(
            0,
            &format!(
                "only {} of {next} draws met the targets, short of the {} asked for",
                all_draws.iter().filter(|b| c.meets(b)).count(),
                spec.size
            ),
        ));
    }
    if members.len() < spec.size {
        return Err(ModelError::AcceptanceUnreachable {
            size: spec.size,
            accepted: members.len(),
            draws: next as usize,
            criterion: spec.criterion.as_str(),
        });
    }
    let first = training.of_cluster(0)?.1;
    let privacy = PrivacyReport {
        threshold_mm: first.threshold_mm,
        thresholds_mm: training.privacy.iter().map(|p| p.threshold_mm).collect(),
        percentile: first.percentile,
        distance: "mean distance between corresponding vertices".to_owned(),
        threshold_basis: if first.leave_one_out {
            "leave_one_out_projection".to_owned()
        } else {
            nearest_training_shape()
        },
        near_copies: members.iter().filter(|m| m.near_copy).count(),
        near_copies_replaced: replaced,
    };
    let mut report = report(reference, &intervals, &members, &all_draws, privacy)?;
    report.clusters = cluster_reports(reference, &intervals, &members, model.atlases().len())?;
    report.targets = conditional.map(|c| TargetsReport::new(c, &members, all_draws.len()));
    report.population_note = reference.small_population_note();
    report.implausible_replaced = implausible;
    Ok((members, report))
}

/// Whether every biomarker lies in its range `(low, high)`.
fn within(ranges: &[(f64, f64)], biomarkers: &Biomarkers) -> bool {
    ranges
        .iter()
        .zip(biomarkers.values())
        .all(|((low, high), v)| (*low..=*high).contains(&v))
}

/// `columns[b][k]`: biomarker `b` of the `k`-th of `biomarkers`.
pub(crate) fn columns(biomarkers: &[&Biomarkers]) -> Vec<Vec<f64>> {
    (0..Biomarkers::NAMES.len())
        .map(|b| biomarkers.iter().map(|m| m.values()[b]).collect())
        .collect()
}

fn report(
    reference: &ReferencePopulation,
    intervals: &[Intervals],
    members: &[Member],
    all_draws: &[Biomarkers],
    privacy: PrivacyReport,
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
                spread: Some(Spread::between(&member_columns[b], &reference.values[b])?),
            },
        );
    }
    Ok(CohortReport {
        biomarkers,
        acceptance: joint_acceptance_rates(intervals, &member_columns)?,
        draws: all_draws.len(),
        draw_acceptance: joint_acceptance_rates(intervals, &draw_columns)?,
        privacy,
        clusters: Vec::new(),
        population_note: None,
        implausible_replaced: 0,
        targets: None,
        folding: Folding::of(members.iter().map(|m| &m.mesh)),
    })
}

#[cfg(test)]
#[path = "cohort_tests.rs"]
mod tests;
