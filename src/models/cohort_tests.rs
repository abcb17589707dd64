use super::*;
use crate::mesh::phantom::{self, Family};
use crate::models::{Draw, ModelError, Reconstruction};

/// Hands out training shape 0 on even draws and a copy of it scaled by `.1` on odd draws.
struct Copier(Vec<Mesh>, f64);

impl ShapeModel for Copier {
    fn atlases(&self) -> &[Mesh] {
        &self.0[..1]
    }
    fn sample(&self, rng: &mut ChaCha8Rng, _: Sampling) -> Result<Draw, ModelError> {
        let mut mesh = self.0[0].clone();
        if rng.get_stream() % 2 == 1 {
            mesh.vertices
                .iter_mut()
                .for_each(|p| *p = p.map(|c| self.1 * c));
        }
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

/// One phantom (canonical frame, as after pre-alignment) scaled by 1, 0.9, 1.1 and 0.95
/// about the origin: training shapes in correspondence, as normalised shapes are.
fn scaled_copies(family: Family, seed: u64) -> Vec<Mesh> {
    let mesh = phantom::subject(family, seed, 0).canonical_mesh();
    [1.0, 0.9, 1.1, 0.95]
        .iter()
        .map(|k| {
            let mut m = mesh.clone();
            m.vertices.iter_mut().for_each(|p| *p = p.map(|c| k * c));
            m
        })
        .collect()
}

/// The meshes' vertices as corresponding training shapes of one atlas, and their
/// privacy threshold.
/// Training shapes per atlas, `[atlas][shape][vertex]`.
type PerAtlas = Vec<Vec<Vec<[f64; 3]>>>;

fn privacy_of(meshes: &[Mesh]) -> (PerAtlas, Vec<PrivacyThreshold>) {
    let shapes: Vec<Vec<[f64; 3]>> = meshes.iter().map(|m| m.vertices.clone()).collect();
    let privacy = CorrespondedShapes::new(&shapes)
        .unwrap()
        .privacy_threshold(0.05)
        .unwrap();
    (vec![shapes], vec![privacy])
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
    let meshes = scaled_copies(Family::Liver, 8);
    let (shapes, privacy) = privacy_of(&meshes);
    let training = TrainingIndex::new(&shapes, &privacy).unwrap();
    let reference = ReferencePopulation::from_meshes(&meshes).unwrap();
    let model = Copier(meshes.clone(), 1.17);

    let (members, report) = sample_cohort(&model, &reference, &training, &spec(4, false)).unwrap();
    assert!(members[0].near_copy && members[2].near_copy);
    assert_eq!(
        members[0].nearest_training,
        NearestTraining {
            index: 0,
            distance_mm: 0.0
        }
    );
    assert!(
        !members[1].near_copy && members[1].nearest_training.distance_mm > privacy[0].threshold_mm
    );
    assert_eq!(report.privacy.near_copies, 2);
    // A single-atlas model: every member in cluster 0, one cluster row for all of them.
    assert!(members.iter().all(|m| m.cluster == 0));
    assert_eq!(report.clusters.len(), 1);
    assert_eq!(
        (report.clusters[0].count, report.clusters[0].share),
        (4, 1.0)
    );
    assert_eq!(report.clusters[0].acceptance, Some(report.acceptance));

    let (members, report) = sample_cohort(&model, &reference, &training, &spec(3, true)).unwrap();
    assert!(members.iter().all(|m| !m.near_copy && m.draw % 2 == 1));
    assert_eq!(report.privacy.near_copies_replaced, 3);
    assert_eq!(report.draws, 6);
}

#[test]
fn a_small_population_says_so_and_keeps_members_near_its_range() {
    let meshes = scaled_copies(Family::Lv, 4);
    let (shapes, privacy) = privacy_of(&meshes);
    let training = TrainingIndex::new(&shapes, &privacy).unwrap();
    let reference = ReferencePopulation::from_meshes(&meshes).unwrap();
    // Odd draws are twice as large (volume 8×): far outside the widened training range.
    let model = Copier(meshes.clone(), 2.0);
    let (members, report) = sample_cohort(&model, &reference, &training, &spec(4, false)).unwrap();
    assert!(members.iter().all(|m| m.draw % 2 == 0), "{members:?}");
    assert_eq!((report.implausible_replaced, report.draws), (3, 7));
    let note = report
        .population_note
        .expect("a note for 4 training meshes");
    assert!(note.contains("only 4 training meshes"), "{note}");
    let volume = &report.biomarkers["volume_ml"];
    let spread = volume.spread.expect("a spread per biomarker");
    assert!((spread.training_mean - volume.reference.mean).abs() < 1e-9);
    assert_eq!(spread.synthetic_sd, 0.0);
}

#[test]
fn acceptance_filter_and_its_bound() {
    let meshes = scaled_copies(Family::Lv, 2);
    let (shapes, privacy) = privacy_of(&meshes);
    let training = TrainingIndex::new(&shapes, &privacy).unwrap();
    let reference = ReferencePopulation::from_meshes(&meshes).unwrap();
    let model = Copier(meshes.clone(), 1.17);
    let only = CohortSpec {
        only_accepted: true,
        ..spec(3, false)
    };
    // Odd draws are 1.17× larger (volume 1.6×): outside the training range.
    let (members, _) = sample_cohort(&model, &reference, &training, &only).unwrap();
    assert!(members.iter().all(|m| m.accepted.range && m.draw % 2 == 0));
    let unreachable = CohortSpec {
        max_draws: 4,
        ..only
    };
    let err = sample_cohort(&model, &reference, &training, &unreachable).unwrap_err();
    assert_eq!(err.code(), "cohort.acceptance_unreachable");
}
