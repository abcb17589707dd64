//! Checks of a whole ASMG fit on a few small LV phantoms.

use super::*;
use crate::geometry::pca::Sampling;
use crate::geometry::transform::RigidTransform;
use crate::mesh::laterality::mirror_image;
use crate::mesh::measures::{area_cm2, volume_ml};
use crate::mesh::phantom::{self, Family};
use crate::models::asmg::CalibrationKind;
use crate::models::asmg::biomarker_calibration::biomarkers;
use crate::models::cohort::draw_rng;
use crate::models::progress::{Cancelled, ProgressUpdate, Silent};
use crate::models::{FitOutcome, ModelType, ShapeModel, StoredModel};

/// Small and quick: meshes of about 300 vertices, an atlas of about 200, few epochs.
fn quick() -> AsmgParams {
    AsmgParams {
        max_vertices: 300,
        atlas_vertices: 200,
        epochs_graph: 2,
        epochs_vae: 30,
        cpd_max_iterations: 40,
        ..AsmgParams::default()
    }
}

/// A whole fit through the registry, as jobs run it.
fn fit(
    training: &[Mesh],
    holdout: &[Mesh],
    params: &AsmgParams,
    template_index: Option<usize>,
    seed: u64,
    progress: &mut dyn Progress,
) -> Result<FitOutcome, ModelError> {
    let params =
        ModelType::parse_name("asmg")?.parse_params(&serde_json::to_value(params).unwrap())?;
    let indices: Vec<usize> = template_index.into_iter().collect();
    let input = FitInput {
        training,
        holdout,
        training_laterality: &[],
        holdout_laterality: &[],
        template_indices: &indices,
        seed,
    };
    params.fit(&input, progress)
}

fn phantoms(count: usize) -> Vec<Mesh> {
    phantom::meshes(Family::Lv, count, 11)
}

#[test]
fn fit_samples_reconstructs_and_round_trips() {
    let meshes = phantoms(8);
    let (training, holdout) = meshes.split_at(6);
    let params = AsmgParams {
        procrustes: true,
        nonrigid: true,
        ..quick()
    };
    let outcome = fit(training, holdout, &params, None, 4, &mut Silent).unwrap();
    let model: &AsmgModel = outcome.model.downcast().expect("an asmg model");
    let atlas = &model.atlas;
    assert!(
        (150..=260).contains(&atlas.vertex_count()),
        "atlas of {} vertices",
        atlas.vertex_count()
    );
    assert_eq!(outcome.summary.atlas.vertex_count, atlas.vertex_count());
    let stages: Vec<&str> = outcome
        .summary
        .timings
        .iter()
        .map(|t| t.stage.as_str())
        .collect();
    assert_eq!(
        stages,
        ["alignment", "graph_vae", "atlas", "generator", "evaluation"]
    );
    let evaluation = &outcome.summary.evaluation;
    let matching = evaluation.matching.unwrap();
    let generalisation = evaluation.generalisation.unwrap();
    eprintln!(
        "asmg 6+2: matching HD {:.2} CD {:.2}, generalisation HD {:.2}, specificity HD {:.2} mm",
        matching.hd.mean, matching.cd.mean, generalisation.hd.mean, evaluation.specificity.hd.mean
    );
    assert!(matching.hd.mean > 0.0 && matching.hd.mean < 40.0);
    assert!(generalisation.hd.mean > 0.0 && generalisation.hd.mean < 60.0);
    assert_eq!(evaluation.per_item.specificity.len(), 6);
    // Six training shapes: the generator's β was chosen on folds, starting at the one asked.
    let [choice] = outcome.summary.beta_choices.as_slice() else {
        panic!(
            "one generator, one choice: {:?}",
            outcome.summary.beta_choices
        );
    };
    assert_eq!(choice.candidates[0].beta, params.beta);
    assert!(choice.candidates.iter().any(|c| c.beta == choice.chosen));

    let sample = model
        .sample(&mut draw_rng(5, 0), Sampling::Gaussian)
        .unwrap()
        .mesh;
    assert_eq!(sample.faces, atlas.faces);
    let volume = volume_ml(&sample);
    assert!(volume > 10.0 && volume < 500.0, "{volume} ml");

    let bytes = outcome.model.to_bytes().unwrap();
    let back = StoredModel::from_bytes(&bytes).unwrap();
    let back_model: &AsmgModel = back.downcast().expect("the stored model is asmg");
    let again = back_model
        .sample(&mut draw_rng(5, 0), Sampling::Gaussian)
        .unwrap()
        .mesh;
    for (a, b) in sample.vertices.iter().zip(&again.vertices) {
        for d in 0..3 {
            assert!((a[d] - b[d]).abs() < 1e-4, "{a:?} vs {b:?}");
        }
    }
    let r = back_model.reconstruct(&holdout[0], None).unwrap();
    assert_eq!(r.normalised.len(), atlas.vertex_count());
    assert_eq!(r.aligned_input.len(), holdout[0].vertex_count());
    assert_eq!(r.mesh.faces, atlas.faces);

    // The generator learned on shapes aligned to their mean: a patient turned by 10° comes
    // back turned by 10°, the same shape.
    assert!(back_model.procrustes_mean.is_some());
    let centre = r.normalised.iter().fold([0.0; 3], |acc, p| {
        [0, 1, 2].map(|k| acc[k] + p[k] / r.normalised.len() as f64)
    });
    let turn = RigidTransform::rotation_about(
        crate::geometry::points::axis_angle([0.3, 0.2, 0.93], 10f64.to_radians()),
        centre,
    );
    let plain = back_model.regenerate(&r.normalised).unwrap();
    let turned = back_model
        .regenerate(&turn.apply_all(&r.normalised))
        .unwrap();
    for (a, b) in turn.apply_all(&plain.vertices).iter().zip(&turned.vertices) {
        for d in 0..3 {
            assert!((a[d] - b[d]).abs() < 0.01, "{a:?} vs {b:?}");
        }
    }
    // With `nonrigid` a new mesh's normalised shape is deformed onto it: nearer to the mesh
    // than the attention's own, which a model stored before the refinement keeps.
    assert!(back_model.nonrigid.is_some());
    let mut stored = serde_json::to_value(back_model).unwrap();
    stored.as_object_mut().unwrap().remove("nonrigid");
    let unrefined: AsmgModel = serde_json::from_value(stored).unwrap();
    let attention_only = unrefined.reconstruct(&holdout[0], None).unwrap().normalised;
    let index = crate::geometry::PointCloudIndex::new(&r.aligned_input).unwrap();
    let gap = |shape: &[[f64; 3]]| {
        shape.iter().map(|p| index.nearest(*p).1).sum::<f64>() / shape.len() as f64
    };
    let (refined_gap, attention_gap) = (gap(&r.normalised), gap(&attention_only));
    assert!(
        refined_gap < attention_gap,
        "{refined_gap} vs {attention_gap} mm"
    );

    // A model stored before Procrustes existed encodes shapes as they come, as it did.
    let mut stored = serde_json::to_value(back_model).unwrap();
    stored.as_object_mut().unwrap().remove("procrustes_mean");
    let old: AsmgModel = serde_json::from_value(stored).unwrap();
    assert_eq!(old.procrustes_mean, None);
    let as_is = old.regenerate(&r.normalised).unwrap();
    assert_ne!(as_is.vertices, plain.vertices);
}

/// Cancels at the first report of the graph network's training.
struct CancelInGraphStage(usize);

impl Progress for CancelInGraphStage {
    fn report(&mut self, update: ProgressUpdate) -> Result<(), Cancelled> {
        if update.stage == "graph_vae" {
            self.0 += 1;
            return Err(Cancelled);
        }
        Ok(())
    }
}

#[test]
fn cancellation_stops_training_and_bad_input_is_refused() {
    let meshes = phantoms(4);
    let mut cancel = CancelInGraphStage(0);
    let err = fit(&meshes, &[], &quick(), None, 1, &mut cancel).unwrap_err();
    assert!(matches!(err, ModelError::Cancelled(_)), "{err:?}");
    assert_eq!(cancel.0, 1);
    let err = fit(&meshes[..2], &[], &quick(), None, 1, &mut Silent).unwrap_err();
    assert!(matches!(err, ModelError::TooFewMeshes { found: 2, .. }));
    let bad = AsmgParams {
        gamma: -1.0,
        ..quick()
    };
    let err = fit(&meshes, &[], &bad, None, 1, &mut Silent).unwrap_err();
    assert!(matches!(err, ModelError::InvalidParams { ref field, .. } if field == "gamma"));
    let given = AsmgParams {
        atlas: "m-7".into(),
        ..quick()
    };
    let err = fit(&meshes, &[], &given, None, 1, &mut Silent).unwrap_err();
    assert!(matches!(err, ModelError::InvalidParams { ref field, .. } if field == "atlas"));
}

#[test]
fn spread_calibration_is_fitted_kept_and_applied_to_draws() {
    let meshes = phantoms(8);
    let params = AsmgParams {
        calibrate_spread: true,
        calibration: CalibrationKind::Modes,
        ..quick()
    };
    let outcome = fit(&meshes, &[], &params, None, 4, &mut Silent).unwrap();
    let bytes = outcome.model.to_bytes().unwrap();
    let back = StoredModel::from_bytes(&bytes).unwrap();
    let model: &AsmgModel = back.downcast().expect("an asmg model");
    let calibration = model.spread_calibration.as_ref().expect("a calibration");
    assert!(calibration.mode_count() >= 1 && calibration.mode_count() < 8);
    assert_eq!(calibration.mean.len(), 3 * model.atlas.vertex_count());
    // Along the first mode, calibrated draws spread `gain` times the uncalibrated ones.
    let codes: Vec<Vec<f32>> = (0..200)
        .map(|k| model.draw_code(&mut draw_rng(9, k), Sampling::Gaussian))
        .collect();
    let raw = model.decode_uncalibrated(&codes).unwrap();
    let calibrated = model.decode(&codes).unwrap();
    let along = |shape: &[f32]| -> f64 {
        calibration.modes[0]
            .iter()
            .zip(shape.iter().zip(&calibration.mean))
            .map(|(u, (x, m))| f64::from(*u) * f64::from(x - m))
            .sum()
    };
    let sd = |values: Vec<f64>| {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
    };
    let raw_sd = sd(raw.iter().map(|s| along(s)).collect());
    let calibrated_sd = sd(calibrated
        .iter()
        .map(|m| {
            along(
                &m.vertices
                    .iter()
                    .flat_map(|p| p.map(|c| c as f32))
                    .collect::<Vec<_>>(),
            )
        })
        .collect());
    let ratio = calibrated_sd / raw_sd;
    assert!(
        (ratio - f64::from(calibration.gain[0])).abs() < 0.02 * ratio,
        "sd ratio {ratio} vs gain {}",
        calibration.gain[0]
    );
}

#[test]
fn biomarker_calibration_gives_draws_the_training_volume_and_area() {
    let meshes = phantoms(8);
    let params = AsmgParams {
        calibrate_spread: true,
        ..quick()
    };
    assert_eq!(
        params.calibration,
        CalibrationKind::Biomarkers,
        "the default"
    );
    let outcome = fit(&meshes, &[], &params, None, 4, &mut Silent).unwrap();
    let bytes = outcome.model.to_bytes().unwrap();
    let back = StoredModel::from_bytes(&bytes).unwrap();
    let model: &AsmgModel = back.downcast().expect("an asmg model");
    assert!(
        model.spread_calibration.is_none(),
        "one calibration, not both"
    );
    let calibration = model.biomarker_calibration.as_ref().expect("a calibration");
    let codes: Vec<Vec<f32>> = (0..300)
        .map(|k| model.draw_code(&mut draw_rng(11, k), Sampling::Gaussian))
        .collect();
    let faces = &model.atlas.faces;
    let mean =
        |rows: &[[f64; 2]], k: usize| rows.iter().map(|r| r[k]).sum::<f64>() / rows.len() as f64;
    let raw: Vec<[f64; 2]> = model
        .decode_uncalibrated(&codes)
        .unwrap()
        .iter()
        .map(|s| biomarkers(s, faces))
        .collect();
    let calibrated: Vec<[f64; 2]> = model
        .decode(&codes)
        .unwrap()
        .iter()
        .map(|m| [volume_ml(m).abs(), area_cm2(m)])
        .collect();
    for k in 0..2 {
        // The calibration's own draws had `drawn_mean`; these are others of the same prior.
        let (before, after, target) = (
            mean(&raw, k),
            mean(&calibrated, k),
            calibration.target_mean[k],
        );
        assert!(
            (before / calibration.drawn_mean[k] - 1.0).abs() < 0.02,
            "{k}: {before}"
        );
        assert!(
            (after / target - 1.0).abs() < 0.02,
            "{k}: {after} vs {target}"
        );
    }
    // The calibration's draws come in pairs mirrored about the latent prior's centre, so
    // that what is linear in the code cancels from `drawn_mean`.
    let prior = model.latent_prior.as_ref().expect("a latent prior");
    let pairs = model.antithetic_codes(&mut draw_rng(12, 0), 6);
    assert_eq!(pairs.len(), 6);
    for pair in pairs.chunks_exact(2) {
        assert_ne!(pair[0], pair[1]);
        for (i, centre) in prior.centre.iter().enumerate() {
            let midpoint = 0.5 * (pair[0][i] + pair[1][i]);
            assert!((midpoint - centre).abs() < 1e-5, "{midpoint} vs {centre}");
        }
    }
}

/// An elongated blob (mm) with three bumps of different heights towards +x, +y and +z: no
/// rotation turns it into its mirror image. `k` varies its size and proportions a little.
fn chiral_blob(k: f64) -> Mesh {
    let sphere = super::super::icosphere::icosphere(3).unwrap();
    let bump = |p: [f64; 3], axis: usize, height: f64| {
        height * (-(1.0 - p[axis]) * (1.0 - p[axis]) * 8.0).exp()
    };
    let vertices = sphere
        .vertices
        .iter()
        .map(|p| {
            let r = 1.0 + bump(*p, 0, 0.5) + bump(*p, 1, 0.3) + bump(*p, 2, 0.15);
            let size = [40.0 + k, 25.0 - 0.5 * k, 15.0 + 0.5 * k];
            std::array::from_fn(|a| p[a] * r * size[a])
        })
        .collect();
    Mesh::new(vertices, sphere.faces)
}

/// Which of [`chiral_population`]'s blobs are mirror images.
const GIVEN_MIRRORED: [bool; 5] = [false, true, false, true, false];

/// Five chiral blobs, those of [`GIVEN_MIRRORED`] as mirror images; parameters with
/// `mirror`; the alignment stage entered.
fn chiral_population() -> (Vec<Mesh>, AsmgParams, Stages) {
    let meshes = GIVEN_MIRRORED
        .iter()
        .enumerate()
        .map(|(k, m)| {
            let blob = chiral_blob(k as f64);
            if *m { mirror_image(&blob) } else { blob }
        })
        .collect();
    let params = AsmgParams {
        mirror: true,
        ..AsmgParams::default()
    };
    let mut stages = Stages::new(&[("alignment", 1.0)]);
    stages.enter("alignment");
    (meshes, params, stages)
}

#[test]
fn with_mirror_the_mirror_images_among_the_training_meshes_take_the_reference_side() {
    let (meshes, params, stages) = chiral_population();
    let given_mirrored = GIVEN_MIRRORED;
    let aligned = align_training(&meshes, &[], &params, 0, &stages, &mut Silent).unwrap();
    assert_eq!(aligned.mirrored, given_mirrored.to_vec());
    assert_eq!(aligned.mirrored_positions(), vec![1, 3]);
    // Every registered mesh, mirrored or not, still encloses a positive volume.
    for mesh in &aligned.meshes {
        assert!(volume_ml(mesh) > 0.0, "{} ml", volume_ml(mesh));
    }
    // Without the option nothing is mirrored.
    let plain = align_training(
        &meshes,
        &[],
        &AsmgParams::default(),
        0,
        &stages,
        &mut Silent,
    )
    .unwrap();
    assert_eq!(plain.mirrored, vec![false; 5]);
}

#[test]
fn sides_the_user_gave_override_the_shapes_and_name_the_models_side() {
    use crate::mesh::Laterality::{Left, Right};
    use crate::models::asmg::registration::{align, align_sides};
    let (meshes, params, stages) = chiral_population();
    // Mesh 2 has the reference's form but is said to be a left one, the reference a right
    // one: it is mirrored all the same; mesh 3, without a side, joins the majority.
    let given = [Some(Right), Some(Left), Some(Left), None, None];
    let aligned = align_training(&meshes, &given, &params, 0, &stages, &mut Silent).unwrap();
    assert_eq!(aligned.mirrored, vec![false, true, true, true, false]);
    assert_eq!(aligned.laterality, Some(Right));

    // A new mesh of a given side takes the model's side without comparison.
    let alignment = crate::models::alignment::AlignmentParams {
        laterality: Some(Right),
        ..params.alignment()
    };
    let reference = &aligned.reference;
    let atlas = [aligned.meshes[0].vertices.as_slice()];
    let [own, mirrored] =
        <[_; 2]>::try_from(align_sides(reference, &meshes[4], &alignment, 3000).unwrap())
            .ok()
            .unwrap();
    let taken = |given| {
        align(reference, &meshes[4], given, &alignment, 3000, &atlas)
            .unwrap()
            .0
    };
    assert_eq!(taken(Some(Left)).vertices, mirrored.mesh.vertices);
    assert_eq!(taken(Some(Right)).vertices, own.mesh.vertices);
    // Without a side, the shape decides: mesh 4 has the reference's form.
    assert_eq!(taken(None).vertices, own.mesh.vertices);
}

/// The real KiTS19 kidneys (skipped without `../shared/data/kits19/`): left and right
/// kidneys are mirror images, and with `mirror` nearly every one takes the side of the
/// reference that `manifest.csv` says (`side_vs_other_kidney`); measured: 18 of 20.
#[test]
fn kits19_kidneys_take_the_side_of_the_reference() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/kits19/kidney-meshes");
    let Ok(manifest) = std::fs::read_to_string(dir.join("manifest.csv")) else {
        return;
    };
    let named = crate::cli::mesh_dir::read_mesh_dir(&dir).unwrap();
    let side_of = |file: &str| {
        manifest
            .lines()
            .find(|l| l.contains(file))
            .map(|l| l.contains("higher_x"))
            .unwrap()
    };
    let sides: Vec<bool> = named.iter().map(|m| side_of(&m.name)).collect();
    let meshes: Vec<Mesh> = named.into_iter().map(|m| m.mesh).collect();
    let reference = crate::models::alignment::median_resolution_index(&meshes);
    let params = AsmgParams {
        mirror: true,
        ..AsmgParams::default()
    };
    let mut stages = Stages::new(&[("alignment", 1.0)]);
    stages.enter("alignment");
    let aligned = align_training(&meshes, &[], &params, reference, &stages, &mut Silent).unwrap();
    let agreeing = (0..meshes.len())
        .filter(|k| aligned.mirrored[*k] == (sides[*k] != sides[reference]))
        .count();
    assert!(agreeing >= 17, "{agreeing} of {} agree", meshes.len());
}
