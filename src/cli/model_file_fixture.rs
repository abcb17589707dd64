//! A model file written by an earlier release stays readable: the checked-in fixture
//! (`tests/fixtures/models/rsmp-format2.cfmodel`, an RSMP model of four small LV phantoms)
//! loads, samples and reconstructs. Rewrite it with `UPDATE_FIXTURES=1` only when the format
//! version changes on purpose (and keep the old one readable or say so).

use super::*;
use crate::geometry::pca::Sampling;
use crate::jobs::fit::fit_model;
use crate::mesh::Mesh;
use crate::mesh::phantom::{self, Family};
use crate::mesh::simplify::simplify;
use crate::models::FitInput;
use crate::models::cohort::draw_rng;
use crate::models::progress::Silent;

fn path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/models/rsmp-format2.cfmodel")
}

fn small_phantoms() -> Vec<Mesh> {
    phantom::generate(Family::Lv, 5, 17)
        .iter()
        .map(|p| simplify(&p.canonical_mesh(), 120).unwrap().mesh)
        .collect()
}

fn write_fixture() {
    let meshes = small_phantoms();
    let json = serde_json::json!({"cpd_max_iterations": 20, "multistart": false});
    let params = ModelType::parse_name("rsmp")
        .unwrap()
        .parse_params(&json)
        .unwrap();
    let outcome = fit_model(
        &params,
        &FitInput::new(&meshes[..4], &meshes[4..], 5),
        &mut Silent,
    )
    .unwrap();
    let names: Vec<String> = (0..5).map(|i| format!("lv_{i:03}.obj")).collect();
    let inputs = FitInputs {
        training_names: &names[..4],
        holdout_names: &names[4..],
        training_faces: meshes[..4].iter().map(|m| m.faces.as_slice()).collect(),
    };
    let file = ModelFile::new(&params, 5, &outcome, &inputs).unwrap();
    std::fs::create_dir_all(path().parent().unwrap()).unwrap();
    file.save(&path()).unwrap();
}

#[test]
fn the_checked_in_model_of_an_earlier_release_loads_samples_and_reconstructs() {
    if std::env::var_os("UPDATE_FIXTURES").is_some() {
        write_fixture();
    }
    let file = ModelFile::load(&path()).expect("the fixture model file loads");
    assert_eq!(file.model_type, "rsmp");
    assert_eq!(file.params().unwrap().to_json()["cpd_max_iterations"], 20);
    let summary = file.summary().unwrap();
    assert_eq!((summary.training_count, summary.holdout_count), (4, 1));
    let stored = file.stored_model().unwrap();
    assert_eq!(stored.model_type.as_str(), "rsmp");
    let atlases = stored.model.atlases();
    assert_eq!(atlases.len(), 1);
    let draw = stored
        .model
        .sample(&mut draw_rng(1, 0), Sampling::Gaussian)
        .unwrap();
    assert_eq!(draw.cluster, 0);
    assert_eq!(draw.mesh.faces, atlases[0].faces);
    assert!(crate::mesh::measures::volume_ml(&draw.mesh) > 1.0);
    let holdout = &small_phantoms()[4];
    let r = stored.model.reconstruct(holdout, None).unwrap();
    assert_eq!(r.mesh.vertex_count(), atlases[0].vertex_count());
    // What it stores today reads back the same way.
    let again = StoredModel::from_bytes(&stored.to_bytes().unwrap()).unwrap();
    assert_eq!(again.training.shapes, stored.training.shapes);
}

#[test]
fn a_model_file_of_format_1_names_the_versions() {
    let mut bytes = MAGIC_NAME.to_vec();
    bytes.push(1);
    bytes.extend([0u8; 16]);
    let err = ModelFile::from_bytes(&bytes).unwrap_err();
    let ModelFileError::Model(inner) = &err else {
        panic!("expected a model error, got {err}")
    };
    assert_eq!(inner.code(), "model.unsupported_version");
    assert!(err.to_string().contains("format 1"), "{err}");
    assert!(err.to_string().contains("format 2"), "{err}");
}
