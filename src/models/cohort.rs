//! Virtual cohorts: seeded draws from a model, each member's biomarkers judged against the
//! training population (clinical acceptance, SPEC §3 and thesis table 3.1).

use std::collections::BTreeMap;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use super::{ModelError, ReferencePopulation, ShapeModel};
use crate::eval::Biomarkers;
use crate::eval::acceptance::{Flags, Intervals, Rates, ReferenceStats, joint_acceptance_rates};
use crate::eval::metrics::{IndexedShapes, parallel_map};
use crate::eval::privacy::{NearestTraining, PrivacyThreshold};
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
    /// The shape (mm, the model's connectivity).
    pub mesh: Mesh,
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
    /// The privacy guard: threshold and how many members are near copies.
    pub privacy: PrivacyReport,
}

/// Privacy part of a cohort report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PrivacyReport {
    /// Members nearer than this (mm) to a training shape are near copies.
    pub threshold_mm: f64,
    /// Percentile of the training nearest-neighbour distances used as the threshold.
    pub percentile: f64,
    /// How the distance is measured.
    pub distance: String,
    /// Near copies among the members.
    pub near_copies: usize,
    /// Near copies drawn and replaced (with `exclude_near_copies`).
    pub near_copies_replaced: usize,
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

/// Draws evaluated together (in parallel, then taken in draw order).
const DRAW_BATCH: u64 = 32;
/// Every how many vertices the quick nearest-training estimate looks at.
const NEAREST_STRIDE: usize = 8;
/// Training shapes whose exact distance is computed after the quick estimate.
const NEAREST_CANDIDATES: usize = 3;

/// One draw: its shape, biomarkers, acceptance and nearest training shape.
type Draw = (Mesh, Biomarkers, Flags, NearestTraining);

fn evaluate_draw(
    model: &dyn ShapeModel,
    intervals: &[Intervals],
    training: &IndexedShapes<'_>,
    spec: &CohortSpec,
    draw: u64,
) -> Result<Draw, ModelError> {
    let mesh = model.sample(&mut draw_rng(spec.seed, draw), spec.sampling)?;
    let biomarkers = Biomarkers::from_mesh(&mesh)?;
    let accepted = joint_flags(intervals, &biomarkers);
    let nearest = training.nearest_pruned(&mesh.vertices, NEAREST_STRIDE, NEAREST_CANDIDATES)?;
    Ok((mesh, biomarkers, accepted, nearest))
}

/// The training shapes a cohort is checked against.
pub struct TrainingIndex<'a> {
    /// Indexed training shapes (model frame, mm).
    pub shapes: IndexedShapes<'a>,
    /// Near-copy threshold.
    pub privacy: &'a PrivacyThreshold,
}

/// Draws a cohort and its report.
pub fn sample_cohort(
    model: &(dyn ShapeModel + Sync),
    reference: &ReferencePopulation,
    training: &TrainingIndex<'_>,
    spec: &CohortSpec,
) -> Result<(Vec<Member>, CohortReport), ModelError> {
    let intervals = reference.intervals();
    let filtering = spec.only_accepted || spec.exclude_near_copies;
    let limit = if filtering {
        spec.max_draws.max(spec.size)
    } else {
        spec.size
    } as u64;
    let (mut members, mut all_draws, mut replaced) = (Vec::with_capacity(spec.size), Vec::new(), 0);
    let mut next = 0u64;
    while members.len() < spec.size && next < limit {
        let wanted = (spec.size - members.len()) as u64;
        let batch: Vec<u64> = (next..limit.min(next + wanted.max(DRAW_BATCH))).collect();
        let evaluated = parallel_map(&batch, |&d| {
            evaluate_draw(model, &intervals, &training.shapes, spec, d)
        });
        for (draw, result) in batch.iter().zip(evaluated) {
            next = draw + 1;
            let (mesh, biomarkers, accepted, nearest_training) = result?;
            let near_copy = nearest_training.distance_mm < training.privacy.threshold_mm;
            all_draws.push(biomarkers);
            if spec.exclude_near_copies && near_copy {
                replaced += 1;
                continue;
            }
            if spec.only_accepted && !spec.criterion.passes(accepted) {
                continue;
            }
            let index = members.len();
            members.push(Member {
                index,
                draw: *draw,
                mesh,
                biomarkers,
                accepted,
                nearest_training,
                near_copy,
            });
            if members.len() == spec.size {
                break;
            }
        }
    }
    if members.len() < spec.size {
        return Err(ModelError::AcceptanceUnreachable {
            size: spec.size,
            accepted: members.len(),
            draws: next as usize,
            criterion: spec.criterion.as_str(),
        });
    }
    let privacy = PrivacyReport {
        threshold_mm: training.privacy.threshold_mm,
        percentile: training.privacy.percentile,
        distance: "symmetric mean closest-point distance".to_owned(),
        near_copies: members.iter().filter(|m| m.near_copy).count(),
        near_copies_replaced: replaced,
    };
    let report = report(reference, &intervals, &members, &all_draws, privacy)?;
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
            },
        );
    }
    Ok(CohortReport {
        biomarkers,
        acceptance: joint_acceptance_rates(intervals, &member_columns)?,
        draws: all_draws.len(),
        draw_acceptance: joint_acceptance_rates(intervals, &draw_columns)?,
        privacy,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{self, Family};
    use crate::models::{ModelError, Reconstruction};

    /// Hands out training shape 0 on even draws and a 20% larger copy of it on odd draws.
    struct Copier(Vec<Mesh>);

    impl ShapeModel for Copier {
        fn atlas(&self) -> &Mesh {
            &self.0[0]
        }
        fn sample(&self, rng: &mut ChaCha8Rng, _: Sampling) -> Result<Mesh, ModelError> {
            let mut mesh = self.0[0].clone();
            if rng.get_stream() % 2 == 1 {
                mesh.vertices
                    .iter_mut()
                    .for_each(|p| *p = p.map(|c| 1.2 * c));
            }
            Ok(mesh)
        }
        fn reconstruct(&self, _: &Mesh) -> Result<Reconstruction, ModelError> {
            unreachable!("not used by cohorts")
        }
    }

    fn spec(size: usize, exclude_near_copies: bool) -> CohortSpec {
        CohortSpec {
            size,
            seed: 3,
            sampling: Sampling::Gaussian,
            criterion: Criterion::Range,
            only_accepted: false,
            exclude_near_copies,
            max_draws: 100,
        }
    }

    #[test]
    fn exact_training_shapes_are_flagged_and_can_be_replaced() {
        // In their canonical frame, as after pre-alignment.
        let meshes: Vec<Mesh> = phantom::generate(Family::Liver, 4, 8)
            .iter()
            .map(|p| p.canonical_mesh())
            .collect();
        let shapes: Vec<Vec<[f64; 3]>> = meshes.iter().map(|m| m.vertices.clone()).collect();
        let privacy = IndexedShapes::new(&shapes)
            .unwrap()
            .privacy_threshold(0.05)
            .unwrap();
        let training = TrainingIndex {
            shapes: IndexedShapes::new(&shapes).unwrap(),
            privacy: &privacy,
        };
        let reference = ReferencePopulation::from_meshes(&meshes).unwrap();
        let model = Copier(meshes.clone());

        let (members, report) =
            sample_cohort(&model, &reference, &training, &spec(4, false)).unwrap();
        assert!(members[0].near_copy && members[2].near_copy);
        assert_eq!(
            members[0].nearest_training,
            NearestTraining {
                index: 0,
                distance_mm: 0.0
            }
        );
        assert!(
            !members[1].near_copy && members[1].nearest_training.distance_mm > privacy.threshold_mm
        );
        assert_eq!(report.privacy.near_copies, 2);

        let (members, report) =
            sample_cohort(&model, &reference, &training, &spec(3, true)).unwrap();
        assert!(members.iter().all(|m| !m.near_copy && m.draw % 2 == 1));
        assert_eq!(report.privacy.near_copies_replaced, 3);
        assert_eq!(report.draws, 6);
    }

    #[test]
    fn acceptance_filter_and_its_bound() {
        let meshes: Vec<Mesh> = phantom::generate(Family::Lv, 5, 2)
            .iter()
            .map(|p| p.canonical_mesh())
            .collect();
        let shapes: Vec<Vec<[f64; 3]>> = meshes.iter().map(|m| m.vertices.clone()).collect();
        let privacy = IndexedShapes::new(&shapes)
            .unwrap()
            .privacy_threshold(0.05)
            .unwrap();
        let training = TrainingIndex {
            shapes: IndexedShapes::new(&shapes).unwrap(),
            privacy: &privacy,
        };
        let reference = ReferencePopulation::from_meshes(&meshes).unwrap();
        let model = Copier(meshes.clone());
        let only = CohortSpec {
            only_accepted: true,
            ..spec(3, false)
        };
        // Odd draws are 1.2× larger (volume 1.73×): outside the training range.
        let (members, _) = sample_cohort(&model, &reference, &training, &only).unwrap();
        assert!(members.iter().all(|m| m.accepted.range && m.draw % 2 == 0));
        let unreachable = CohortSpec {
            max_draws: 4,
            ..only
        };
        let err = sample_cohort(&model, &reference, &training, &unreachable).unwrap_err();
        assert_eq!(err.code(), "cohort.acceptance_unreachable");
    }
}
