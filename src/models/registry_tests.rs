//! The registry: names, unknown types, parameters checked by each type.

use super::*;
use serde_json::json;

fn field_of(model_type: &str, params: serde_json::Value) -> String {
    let t = ModelType::parse_name(model_type).unwrap();
    match t.parse_params(&params) {
        Err(ModelError::InvalidParams { field, .. }) => field,
        other => panic!("expected invalid params, got {other:?}"),
    }
}

#[test]
fn the_registry_lists_every_type_and_refuses_unknown_ones() {
    assert_eq!(
        ModelType::names(),
        ["rsmp", "asmg", "atlas-r-asmg", "matlas-r-asmg"]
    );
    for t in ModelType::all() {
        assert_eq!(ModelType::from_name(t.as_str()), Some(t));
        assert!(t.min_training_meshes() >= 3, "{t}");
        assert!(t.parse_params(&serde_json::Value::Null).is_ok(), "{t}");
    }
    let err = ModelType::parse_name("pca").unwrap_err();
    assert_eq!(err.code(), "model.unknown_type");
    assert!(
        err.to_string()
            .contains("use one of: rsmp, asmg, atlas-r-asmg"),
        "{err}"
    );
    assert_eq!(
        serde_json::to_value(ModelType::parse_name("atlas-r-asmg").unwrap()).unwrap(),
        "atlas-r-asmg"
    );
}

#[test]
fn rsmp_defaults_fill_in_and_errors_name_the_field() {
    let p = ModelType::parse_name("rsmp")
        .unwrap()
        .parse_params(&serde_json::Value::Null)
        .unwrap();
    assert_eq!(p.to_json()["variance_target"], 0.95);
    assert_eq!(p.template_field(), "template");
    assert_eq!(field_of("rsmp", json!({"n_modes": "many"})), "n_modes");
    assert_eq!(field_of("rsmp", json!({"n_modes": 0})), "n_modes");
    assert_eq!(field_of("rsmp", json!({"variance": 0.9})), "variance");
    assert_eq!(field_of("rsmp", json!({"cpd_w": 1.5})), "cpd_w");
}

#[test]
fn asmg_params_fill_in_defaults_and_reject_bad_fields() {
    let asmg = ModelType::parse_name("asmg").unwrap();
    let p = asmg.parse_params(&serde_json::Value::Null).unwrap();
    let json = p.to_json();
    assert_eq!(json["features"], "hybrid");
    assert_eq!(json["atlas"], "auto");
    assert_eq!(json["latent_dim"], 16);
    assert_eq!(json["smoothing"], "displacement");
    assert!(json["temperature"].is_null());
    assert_eq!(p.template_mesh_ids(), Vec::<&str>::new());
    assert_eq!(p.template_field(), "atlas");
    let p = asmg
        .parse_params(&json!({"features": "hybrid", "atlas": "m1", "temperature": 10000.0}))
        .unwrap();
    assert_eq!(p.template_mesh_ids(), vec!["m1"]);
    assert_eq!(p.to_json()["features"], "hybrid");
    assert_eq!(
        field_of("asmg", json!({"features": "spectral"})),
        "features"
    );
    assert_eq!(field_of("asmg", json!({"epochs": 3})), "epochs");
    assert_eq!(field_of("asmg", json!({"latent_dim": 0})), "latent_dim");
    assert_eq!(field_of("asmg", json!({"beta": -1.0})), "beta");
    assert_eq!(field_of("asmg", json!({"smoothing": "both"})), "smoothing");
}

#[test]
fn atlas_r_asmg_params_add_the_refinement_and_name_unknown_fields() {
    let t = ModelType::parse_name("atlas-r-asmg").unwrap();
    let p = t
        .parse_params(&json!({"w_lap": 1.2, "atlas": "m7"}))
        .unwrap();
    let json = p.to_json();
    assert_eq!(json["w_cd"], 1.0);
    assert_eq!(json["w_lap"], 1.2);
    assert!(json["epochs_refine"].as_u64().unwrap() >= 1);
    assert_eq!(json["features"], "hybrid");
    assert_eq!(p.template_mesh_ids(), vec!["m7"]);
    assert_eq!(
        field_of("atlas-r-asmg", json!({"w_chamfer": 1.0})),
        "w_chamfer"
    );
    assert_eq!(field_of("atlas-r-asmg", json!({"w_cd": -1.0})), "w_cd");
    assert_eq!(
        field_of("atlas-r-asmg", json!({"epochs_refine": 0})),
        "epochs_refine"
    );
    assert_eq!(
        field_of("atlas-r-asmg", json!({"latent_dim": 0})),
        "latent_dim"
    );
}
