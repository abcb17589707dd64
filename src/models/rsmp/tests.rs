use super::*;
use crate::mesh::phantom::{self, Family};
use crate::models::progress::Silent;
use crate::models::test_fits::fitted;
use crate::models::{ModelType, StoredModel};

#[test]
fn fit_samples_and_reconstructs_phantoms() {
    let meshes: Vec<Mesh> = phantom::meshes(Family::Lv, 8, 3);
    let (training, holdout) = meshes.split_at(6);
    let started = std::time::Instant::now();
    let input = FitInput {
        training,
        holdout,
        training_laterality: &[],
        holdout_laterality: &[],
        template_indices: &[],
        seed: 1,
    };
    let params = ModelType::parse_name("rsmp")
        .unwrap()
        .parse_params(&serde_json::Value::Null)
        .unwrap();
    let outcome = params.fit(&input, &mut Silent).unwrap();
    eprintln!(
        "rsmp fit of 6+2 LV phantoms: {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let model: &RsmpModel = outcome.model.downcast().expect("an rsmp model");
    let summary = &outcome.summary;
    assert_eq!(summary.training_count, 6);
    assert!(summary.n_modes.unwrap() >= 1 && summary.n_modes.unwrap() <= 5);
    let generalisation = summary.evaluation.generalisation.unwrap();
    eprintln!(
        "generalisation HD {:.2} mm, specificity HD {:.2} mm",
        generalisation.hd.mean, summary.evaluation.specificity.hd.mean
    );
    assert!(generalisation.hd.mean > 0.0 && generalisation.hd.mean < 20.0);
    // The fit's own cohort: its joint A^μ beside the Gaussian yardstick of the six
    // training biomarkers (a fraction that 100,000 Gaussian draws of six biomarkers
    // cannot make 0 or 1).
    let fidelity = summary.fidelity.as_ref().expect("a fidelity summary");
    let joint = fidelity.joint_acceptance.expect("the cohort's joint A^μ");
    let gaussian = fidelity.gaussian_joint_acceptance.expect("the yardstick");
    assert!((0.0..=1.0).contains(&joint), "{joint}");
    assert!(gaussian > 0.5 && gaussian < 1.0, "{gaussian}");
    let sentence = fidelity.acceptance_sentence().unwrap();
    assert!(
        sentence.contains(&format!("{:.1}%", 100.0 * gaussian)),
        "{sentence}"
    );
    assert!(fidelity.population_note.is_some());
    let sample = model
        .sample(
            &mut crate::models::cohort::draw_rng(5, 0),
            Sampling::Gaussian,
        )
        .unwrap();
    assert_eq!(sample.cluster, 0);
    let sample = sample.mesh;
    assert_eq!(sample.faces, model.template.faces);
    let volume = crate::mesh::measures::volume_ml(&sample);
    let reference = &outcome.reference.stats[0];
    assert!(
        volume > 0.5 * reference.min && volume < 1.5 * reference.max,
        "{volume} ml"
    );
    // The refined correspondences keep a held-out heart's wall volume (rigid ones lost up
    // to 60% of it by matching template points to the nearer wall).
    for mesh in holdout {
        let normalised = model.reconstruct(mesh, None).unwrap().normalised;
        let shape = Mesh::new(normalised, model.template.faces.clone());
        let (kept, truth) = (
            crate::mesh::measures::volume_ml(&shape),
            crate::mesh::measures::volume_ml(mesh),
        );
        assert!(
            (kept / truth - 1.0).abs() < 0.03,
            "{kept:.1} of {truth:.1} ml"
        );
    }
    // A training patient sent in again comes back nearest to itself and is flagged (six
    // meshes: the guard keeps the normalised shapes with the leave-one-out threshold).
    let guard = &outcome.model.training;
    let index = crate::eval::privacy::CorrespondedShapes::new(&guard.normalised_f64()[0]).unwrap();
    for (k, mesh) in training.iter().enumerate() {
        let again = model.reconstruct(mesh, None).unwrap().mesh.vertices;
        let nearest = index.nearest(&again).unwrap();
        assert_eq!(nearest.index, k);
        assert!(
            nearest.distance_mm < guard.privacy[0].threshold_mm,
            "{nearest:?} against {} mm",
            guard.privacy[0].threshold_mm
        );
    }
    let bytes = outcome.model.to_bytes().unwrap();
    let back = StoredModel::from_bytes(&bytes).unwrap();
    let back_model: &RsmpModel = back.downcast().expect("the stored model is rsmp");
    assert_eq!(back_model.pca, model.pca);
    assert_eq!(back.training.shapes.len(), 6);
    assert!(back.training.privacy[0].threshold_mm > 0.0);
    assert_eq!(back_model.draw_smoothing_steps, 2);
    assert!(back_model.procrustes);
    // Six meshes are too few for their own coefficients to be the draws' distribution.
    assert!(back_model.mode_coefficients.is_none());

    // Drawn shapes are smoothed by the model's Taubin steps; without them the same draw
    // is the plain PCA shape, with more surface (folds).
    let mut plain = back_model.clone();
    plain.draw_smoothing_steps = 0;
    let draw = |m: &RsmpModel| {
        m.sample(
            &mut crate::models::cohort::draw_rng(5, 1),
            Sampling::Gaussian,
        )
        .unwrap()
        .mesh
    };
    let (smoothed, unsmoothed) = (draw(back_model), draw(&plain));
    let area = crate::mesh::measures::area_mm2;
    assert!(area(&smoothed) < area(&unsmoothed));
    let volumes = (
        crate::mesh::measures::volume_ml(&smoothed),
        crate::mesh::measures::volume_ml(&unsmoothed),
    );
    assert!((volumes.0 / volumes.1 - 1.0).abs() < 0.02, "{volumes:?}");
    // A model stored before the field existed draws unsmoothed, as it did.
    let mut stored = serde_json::to_value(back_model).unwrap();
    stored
        .as_object_mut()
        .unwrap()
        .remove("draw_smoothing_steps");
    stored.as_object_mut().unwrap().remove("procrustes");
    stored.as_object_mut().unwrap().remove("max_vertices");
    stored.as_object_mut().unwrap().remove("mode_coefficients");
    let old: RsmpModel = serde_json::from_value(stored).unwrap();
    assert_eq!(old.draw_smoothing_steps, 0);
    assert!(!old.procrustes);
    // ... and registers every vertex of a mesh, as it did.
    assert_eq!(old.max_vertices, usize::MAX);
    assert_eq!(draw(&old), unsmoothed);
}

#[test]
fn meshes_above_the_vertex_budget_are_registered_simplified() {
    let meshes: Vec<Mesh> = phantom::meshes(Family::Lv, 7, 4);
    let budget = 600;
    assert!(meshes.iter().all(|m| m.vertex_count() > budget));
    let (training, holdout) = meshes.split_at(6);
    let outcome = fitted(
        "rsmp",
        training,
        serde_json::json!({ "max_vertices": budget }),
    );
    let model: &RsmpModel = outcome.model.downcast().expect("an rsmp model");
    // The template, and so every output, has the simplified surface (about the budget).
    let n = model.template.vertex_count();
    assert!(n <= budget + budget / 10 && n > budget / 2, "{n} vertices");
    assert_eq!(model.max_vertices, budget);
    // A held-out mesh above the budget: its normalised shape keeps the wall volume, and
    // every one of its vertices comes back in the template frame for the distances.
    let mesh = &holdout[0];
    let reconstruction = model.reconstruct(mesh, None).unwrap();
    assert_eq!(reconstruction.aligned_input.len(), mesh.vertex_count());
    let shape = Mesh::new(reconstruction.normalised, model.template.faces.clone());
    let (kept, truth) = (
        crate::mesh::measures::volume_ml(&shape),
        crate::mesh::measures::volume_ml(mesh),
    );
    assert!(
        (kept / truth - 1.0).abs() < 0.05,
        "{kept:.1} of {truth:.1} ml"
    );
    // A budget below what a surface can be simplified to is refused by name.
    let refused = ModelType::parse_name("rsmp")
        .unwrap()
        .parse_params(&serde_json::json!({ "max_vertices": 3 }));
    assert!(refused.unwrap_err().to_string().contains("max_vertices"));
}

#[test]
fn draws_take_each_mode_from_the_training_shapes_from_twenty_meshes_on() {
    let training: Vec<Mesh> = phantom::meshes(Family::Lv, 20, 5);
    let budget = serde_json::json!({ "max_vertices": 300 });
    let outcome = fitted("rsmp", &training, budget.clone());
    let model: &RsmpModel = outcome.model.downcast().expect("an rsmp model");
    let coefficients = model
        .mode_coefficients
        .as_ref()
        .expect("empirical coefficients");
    assert_eq!(coefficients.by_mode.len(), model.pca.n_modes());
    assert!(coefficients.by_mode.iter().all(|values| values.len() == 20));
    // The coefficients are the training shapes' projections: the first mode's spread among
    // them is its PCA variance (n − 1 in both).
    let first = &coefficients.by_mode[0];
    let variance = first.iter().map(|b| b * b).sum::<f64>() / 19.0;
    assert!((variance / model.pca.variances[0] - 1.0).abs() < 1e-6);
    // A Gaussian-sampling draw is the shape of coefficients drawn from them, seeded.
    let rng = || crate::models::cohort::draw_rng(3, 0);
    let drawn = model.sample(&mut rng(), Sampling::Gaussian).unwrap().mesh;
    let expected = model.drawn_mesh(
        &model
            .pca
            .reconstruct(&coefficients.draw(&mut rng()))
            .unwrap(),
    );
    assert_eq!(drawn, expected);
    assert_eq!(
        drawn,
        model.sample(&mut rng(), Sampling::Gaussian).unwrap().mesh
    );
    // Uniform sampling stays uniform, and the model stored without them draws Gaussians.
    let uniform = model.sample(&mut rng(), Sampling::Uniform).unwrap().mesh;
    assert_eq!(
        uniform,
        model.drawn_mesh(&model.pca.sample(&mut rng(), Sampling::Uniform))
    );
    let mut old = serde_json::to_value(model).unwrap();
    old.as_object_mut().unwrap().remove("mode_coefficients");
    let old: RsmpModel = serde_json::from_value(old).unwrap();
    let gaussian = old.sample(&mut rng(), Sampling::Gaussian).unwrap().mesh;
    assert_eq!(
        gaussian,
        model.drawn_mesh(&model.pca.sample(&mut rng(), Sampling::Gaussian))
    );
    assert_ne!(gaussian, drawn);
    // Off by request: Gaussian coefficients.
    let mut params = budget;
    params["empirical_coefficients"] = false.into();
    let gaussian_fit = fitted("rsmp", &training, params);
    let gaussian_model: &RsmpModel = gaussian_fit.model.downcast().unwrap();
    assert!(gaussian_model.mode_coefficients.is_none());
}
