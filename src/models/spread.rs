//! How faithfully a fitted model's cohorts vary like the training population: a seeded
//! cohort drawn at the end of every fit, each biomarker's spread against the training
//! values, the share of near copies, and a note when the population is too small.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::cohort::{CohortSpec, Criterion, Member, TrainingIndex, columns, sample_cohort};
use super::folding::{Folding, folding_warning};
use super::{ModelError, ReferencePopulation, ShapeModel, TrainingShapes};
use crate::eval::fidelity::Spread;
use crate::eval::gaussian_reference::{
    GAUSSIAN_REFERENCE_DRAWS, distance_quantile, gaussian_joint_acceptance,
};
use crate::eval::privacy::DEFAULT_PERCENTILE;
use crate::geometry::pca::Sampling;
use crate::mesh::Mesh;

/// Members of the cohort drawn to judge a fit's spread.
pub const FIDELITY_MEMBERS: usize = 1000;

/// Share of near copies above which a fit's summary warns that its generator hands
/// training shapes back (twice the share a model of new patients has).
pub const NEAR_COPY_WARNING: f64 = 2.0 * DEFAULT_PERCENTILE;

/// Added to the fit seed for the fidelity cohort, so that it differs from other draws.
const FIDELITY_SEED_OFFSET: u64 = 0xf1de_1175;

/// The spread of a fitted model's cohort against its training population.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct FidelitySummary {
    /// Members drawn (Gaussian sampling, every draw kept).
    pub members: usize,
    /// Seed of the draws.
    pub seed: u64,
    /// Per biomarker: means, sds, their ratios and the KS statistic against the training
    /// values.
    pub biomarkers: BTreeMap<String, Spread>,
    /// Members nearer to a training shape than the privacy threshold.
    pub near_copies: usize,
    /// Members drawn again because a biomarker fell outside a small population's plausible
    /// range.
    pub implausible_replaced: usize,
    /// Joint A^μ of the cohort: the share of members inside `μ ± 2σ` of every biomarker
    /// (absent in summaries stored before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_acceptance: Option<f64>,
    /// The joint A^μ of draws from the Gaussian with the training biomarkers' mean and
    /// covariance: what a generator with a Gaussian latent space can be expected to reach
    /// (populations with lighter tails than a Gaussian score higher themselves).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gaussian_joint_acceptance: Option<f64>,
    /// How far the members' biomarkers lie from the training mean jointly, beside the
    /// training meshes' own (absent for populations of fewer than 20 meshes, whose
    /// covariance is too uncertain, and in summaries stored before it was kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub biomarker_distance: Option<JointDistance>,
    /// Said when the training population is too small for its estimates.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub population_note: Option<String>,
    /// How often the members' surfaces fold over (absent in summaries stored before it was
    /// measured).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub folding: Option<Folding>,
    /// How often the training meshes' surfaces fold over, as uploaded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training_folding: Option<Folding>,
}

/// 95th percentiles of the Mahalanobis distance of the six biomarkers from the training
/// mean, under the training covariance (unitless: training sds along each principal
/// direction). Members whose biomarkers combine as no patient's do, such as a long axis too
/// long for the volume, lie far out even when each biomarker is inside its interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct JointDistance {
    /// The cohort's members.
    pub members_p95: f64,
    /// The training meshes themselves.
    pub training_p95: f64,
}

impl FidelitySummary {
    /// The cohort's joint A^μ beside the Gaussian yardstick, in words (absent in summaries
    /// stored before both were kept).
    pub fn acceptance_sentence(&self) -> Option<String> {
        let (cohort, gaussian) = (self.joint_acceptance?, self.gaussian_joint_acceptance?);
        Some(format!(
            "{:.1}% of the members lie inside μ ± 2σ of every biomarker (joint A^μ); draws from \
             a Gaussian with the training biomarkers' mean and covariance do {:.1}% of the \
             time, which is what a model with a Gaussian latent space can be expected to reach",
            100.0 * cohort,
            100.0 * gaussian
        ))
    }

    /// A warning when the cohort hands patients back: more than [`NEAR_COPY_WARNING`] of its
    /// members are near copies, where a model whose members are new patients flags about the
    /// threshold's percentile (5%). None otherwise.
    pub fn near_copy_sentence(&self) -> Option<String> {
        let share = self.near_copies as f64 / self.members.max(1) as f64;
        (share > NEAR_COPY_WARNING).then(|| {
            format!(
                "{} of the {} members ({:.1}%) are near copies of a training patient, where a \
                 model whose members are new patients has about {:.0}%: the generator hands \
                 training shapes back. Ask for cohorts with exclude_near_copies (near copies \
                 are drawn again), or fit on more meshes or with a model type whose near \
                 copies stay near {:.0}%",
                self.near_copies,
                self.members,
                100.0 * share,
                100.0 * DEFAULT_PERCENTILE,
                100.0 * DEFAULT_PERCENTILE
            )
        })
    }

    /// How often the members fold over beside the training meshes, in words (absent in
    /// summaries stored before it was measured).
    pub fn folding_sentence(&self) -> Option<String> {
        let (members, training) = (self.folding?, self.training_folding?);
        Some(format!(
            "Members: {}; training meshes: {}",
            members.describe(),
            training.describe()
        ))
    }

    /// A warning when the members fold over far more than the training meshes (see
    /// [`folding_warning`]).
    pub fn folding_warning(&self) -> Option<String> {
        folding_warning(&self.folding?, &self.training_folding?)
    }

    /// The members' joint distance from the training mean beside the training meshes', in
    /// words (absent when not computed).
    pub fn distance_sentence(&self) -> Option<String> {
        let d = self.biomarker_distance.as_ref()?;
        Some(format!(
            "One member in twenty lies farther than {:.1} from the training mean in all six \
             biomarkers together (Mahalanobis distance, in training sds), where one training \
             mesh in twenty lies beyond {:.1}",
            d.members_p95, d.training_p95
        ))
    }
}

/// Draws [`FIDELITY_MEMBERS`] members (seeded from `seed`) and compares them with the
/// training population (`training_meshes`: the meshes as uploaded).
pub fn fidelity_summary<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    reference: &ReferencePopulation,
    training: &TrainingShapes,
    training_meshes: &[Mesh],
    seed: u64,
) -> Result<FidelitySummary, ModelError> {
    let normalised = training.normalised_f64();
    let index = TrainingIndex::new(&normalised, &training.privacy)?;
    let spec = CohortSpec {
        size: FIDELITY_MEMBERS,
        seed: seed.wrapping_add(FIDELITY_SEED_OFFSET),
        sampling: Sampling::Gaussian,
        criterion: Criterion::Mean,
        only_accepted: false,
        exclude_near_copies: false,
        max_draws: 20 * FIDELITY_MEMBERS,
    };
    let (members, report) = sample_cohort(model, reference, &index, &spec)?;
    let biomarker_distance = joint_distance(reference, &members);
    Ok(FidelitySummary {
        members: FIDELITY_MEMBERS,
        seed: spec.seed,
        biomarkers: report
            .biomarkers
            .iter()
            .filter_map(|(name, b)| b.spread.map(|s| (name.clone(), s)))
            .collect(),
        near_copies: report.privacy.near_copies,
        joint_acceptance: Some(report.acceptance.mean),
        gaussian_joint_acceptance: gaussian_joint_acceptance(
            &reference.intervals(),
            &reference.values,
            GAUSSIAN_REFERENCE_DRAWS,
            spec.seed,
        )
        .ok()
        .map(|r| r.mean),
        implausible_replaced: report.implausible_replaced,
        biomarker_distance,
        population_note: report.population_note,
        folding: report.folding,
        training_folding: Folding::of(training_meshes),
    })
}

/// The members' and the training meshes' 95th-percentile distances from the training mean;
/// `None` for a small population or one whose covariance has no inverse.
fn joint_distance(reference: &ReferencePopulation, members: &[Member]) -> Option<JointDistance> {
    if reference.is_small() {
        return None;
    }
    let biomarkers: Vec<_> = members.iter().map(|m| &m.biomarkers).collect();
    let quantile = |samples: &[Vec<f64>]| distance_quantile(&reference.values, samples, 0.95);
    Some(JointDistance {
        members_p95: quantile(&columns(&biomarkers)).ok()?,
        training_p95: quantile(&reference.values).ok()?,
    })
}

#[cfg(test)]
mod tests {
    use rand::Rng;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::mesh::phantom::{self, Family};
    use crate::models::{Draw, Reconstruction};

    /// Hands out training mesh `d mod n` on draw `d`, scaled by `.1` about the origin.
    struct Cycler(Vec<Mesh>, f64);

    impl ShapeModel for Cycler {
        fn atlases(&self) -> &[Mesh] {
            &self.0[..1]
        }
        fn sample(&self, rng: &mut ChaCha8Rng, _: Sampling) -> Result<Draw, ModelError> {
            let mut mesh = self.0[rng.get_stream() as usize % self.0.len()].clone();
            mesh.vertices
                .iter_mut()
                .for_each(|p| *p = p.map(|c| self.1 * c));
            Ok(Draw { mesh, cluster: 0 })
        }
        fn reconstruct(
            &self,
            _: &Mesh,
            _: Option<crate::mesh::Laterality>,
        ) -> Result<Reconstruction, ModelError> {
            unreachable!("not used by cohorts")
        }
    }

    /// `count` copies of one LV phantom, each stretched along x, y and z by its own factor
    /// in [0.85, 1.15]: corresponded shapes whose six biomarkers all vary.
    fn stretched(count: usize) -> Vec<Mesh> {
        let mesh = phantom::subject(Family::Lv, 4, 0).canonical_mesh();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        (0..count)
            .map(|_| {
                let k: [f64; 3] = std::array::from_fn(|_| rng.random_range(0.85..1.15));
                let mut m = mesh.clone();
                m.vertices
                    .iter_mut()
                    .for_each(|p| *p = [k[0] * p[0], k[1] * p[1], k[2] * p[2]]);
                m
            })
            .collect()
    }

    fn summary(meshes: &[Mesh], scale: f64) -> FidelitySummary {
        let shapes: Vec<Vec<[f64; 3]>> = meshes.iter().map(|m| m.vertices.clone()).collect();
        let training = TrainingShapes::new(&shapes, std::slice::from_ref(&shapes), 0.05).unwrap();
        let reference = ReferencePopulation::from_meshes(meshes).unwrap();
        fidelity_summary(
            &Cycler(meshes.to_vec(), scale),
            &reference,
            &training,
            meshes,
            1,
        )
        .unwrap()
    }

    #[test]
    fn members_that_are_the_patients_lie_as_far_out_as_the_patients() {
        let meshes = stretched(25);
        let f = summary(&meshes, 1.0);
        let d = f
            .biomarker_distance
            .clone()
            .expect("25 meshes are not a small population");
        // 1,000 members cycle through the 25 meshes: the same distances, 40 times each.
        assert!(d.training_p95 > 1.0, "{d:?}");
        assert!(
            (d.members_p95 - d.training_p95).abs() < 0.05 * d.training_p95,
            "{d:?}"
        );
        let sentence = f.distance_sentence().unwrap();
        assert!(
            sentence.contains(&format!("{:.1}", d.members_p95)),
            "{sentence}"
        );
        // Members that are the patients fold over exactly as often as the patients (40
        // members for each), so no folding warning.
        let (members, patients) = (f.folding.unwrap(), f.training_folding.unwrap());
        assert!((members.per_mille - patients.per_mille).abs() < 1e-9);
        assert_eq!((members.surfaces, patients.surfaces), (1000, 25));
        assert!(f.folding_warning().is_none());
        assert!(f.folding_sentence().unwrap().starts_with("Members: "));
        // Members that are the patients: every one a near copy, and the summary says so.
        assert_eq!(f.near_copies, f.members);
        let warning = f.near_copy_sentence().expect("a warning");
        assert!(
            warning.starts_with("1000 of the 1000 members (100.0%)"),
            "{warning}"
        );
        // Every member 30% larger: each biomarker far out, and jointly farther still; no
        // member is anyone's copy.
        let larger_summary = summary(&meshes, 1.3);
        assert_eq!(larger_summary.near_copies, 0);
        assert!(larger_summary.near_copy_sentence().is_none());
        let larger = larger_summary.biomarker_distance.unwrap();
        assert!(larger.members_p95 > 3.0 * d.training_p95, "{larger:?}");
        assert_eq!(larger.training_p95, d.training_p95);
    }

    #[test]
    fn a_small_population_gets_no_distance() {
        let f = summary(&stretched(8), 1.0);
        assert!(f.biomarker_distance.is_none());
        assert!(f.distance_sentence().is_none());
    }
}
