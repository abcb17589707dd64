//! How the near-copy threshold treats patients the model has not seen: each held-out mesh is
//! reconstructed through the model (a shape the generator can make, of a patient who is no
//! training patient) and compared with the training shapes exactly as a cohort member is. A
//! threshold at the 5th percentile flags about 5% of them; far fewer means it is lenient (a
//! member could be nearer a patient than a new patient comes without being flagged), far more
//! that it flags shapes which copy no one.

use serde::Serialize;

use crate::eval::SummaryStats;
use crate::eval::metrics::parallel_map;
use crate::eval::privacy::PrivacyThreshold;
use crate::mesh::Mesh;
use crate::models::ShapeModel;
use crate::models::cohort::TrainingIndex;

/// Held-out meshes, through the model, against the near-copy threshold.
#[derive(Debug, Serialize)]
pub struct HeldOutPrivacy {
    /// Held-out meshes reconstructed.
    pub meshes: usize,
    /// Those nearer a training shape than the threshold of their atlas.
    pub flagged: usize,
    /// Distance of each reconstruction to its nearest training shape, mm (absent with
    /// fewer than two held-out meshes).
    pub nearest_mm: Option<SummaryStats>,
    /// The thresholds, mm, per atlas.
    pub threshold_mm: Vec<f64>,
    /// Whether the thresholds come from leave-one-out projections (few training shapes).
    pub leave_one_out: bool,
    /// Flagged by the plain threshold instead: the percentile of the training shapes' own
    /// nearest-neighbour distances (the same as `flagged` from 20 training meshes on).
    pub flagged_by_nearest_training_shape: usize,
}

/// Reconstructs every `held_out` mesh and measures it against the training shapes
/// normalised to each atlas (`[atlas][shape]`, model frame, mm) and their thresholds.
pub fn held_out_privacy<M: ShapeModel + Sync + ?Sized>(
    model: &M,
    held_out: &[Mesh],
    normalised: &[Vec<Vec<[f64; 3]>>],
    privacy: &[PrivacyThreshold],
) -> Result<HeldOutPrivacy, String> {
    let index = TrainingIndex::new(normalised, privacy).map_err(|e| e.to_string())?;
    let plain = index
        .shapes
        .iter()
        .zip(privacy)
        .map(|(shapes, p)| shapes.privacy_threshold(p.percentile))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())?;
    let nearest = parallel_map(held_out, |mesh| -> Result<(f64, bool, bool), String> {
        let reconstruction = model.reconstruct(mesh, None).map_err(|e| e.to_string())?;
        let m = reconstruction.atlas;
        let (shapes, (threshold, plain)) = index
            .shapes
            .get(m)
            .zip(privacy.get(m).zip(plain.get(m)))
            .ok_or("a reconstruction on an atlas without training shapes")?;
        let d = shapes
            .nearest(&reconstruction.mesh.vertices)
            .map_err(|e| e.to_string())?
            .distance_mm;
        Ok((d, d < threshold.threshold_mm, d < plain.threshold_mm))
    })
    .into_iter()
    .collect::<Result<Vec<_>, _>>()?;
    let distances: Vec<f64> = nearest.iter().map(|(d, _, _)| *d).collect();
    Ok(HeldOutPrivacy {
        meshes: held_out.len(),
        flagged: nearest.iter().filter(|(_, flagged, _)| *flagged).count(),
        nearest_mm: SummaryStats::from_values(&distances).ok(),
        threshold_mm: privacy.iter().map(|p| p.threshold_mm).collect(),
        leave_one_out: privacy.iter().any(|p| p.leave_one_out),
        flagged_by_nearest_training_shape: nearest.iter().filter(|(_, _, f)| *f).count(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::phantom::{self, Family};
    use crate::models::test_fits::fitted;

    #[test]
    fn a_training_patient_comes_back_flagged_and_a_new_one_is_measured() {
        let meshes: Vec<Mesh> = phantom::meshes(Family::Lv, 8, 3);
        let (training, holdout) = meshes.split_at(6);
        let outcome = fitted("rsmp", training, serde_json::Value::Null);
        let stored = &outcome.model;
        let normalised = stored.training.normalised_f64();
        // A training patient sent in again, and two patients the model has not seen.
        let held_out = [training[2].clone(), holdout[0].clone(), holdout[1].clone()];
        let found = held_out_privacy(
            stored.model.as_ref(),
            &held_out,
            &normalised,
            &stored.training.privacy,
        )
        .unwrap();
        assert_eq!(found.meshes, 3);
        // Six training meshes: the threshold comes from leave-one-out projections.
        assert!(found.leave_one_out);
        assert_eq!(found.threshold_mm.len(), 1);
        let nearest = found.nearest_mm.unwrap();
        assert!(nearest.min < found.threshold_mm[0], "{found:?}");
        assert!(found.flagged >= 1, "{found:?}");
        assert!(nearest.max > nearest.min, "{found:?}");
    }
}
