//! Validation of a job's model type and parameters at submission, so that a job that
//! reaches a worker can only fail on its data.

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::models::asmg::AsmgParams;
use crate::models::rsmp::RsmpParams;
use crate::models::{ModelError, ModelType};

/// A model's parameters, validated and with defaults filled in.
#[derive(Debug, Clone, PartialEq)]
pub enum ModelParams {
    /// Parameters of `rsmp`.
    Rsmp(RsmpParams),
    /// Parameters of `asmg`.
    Asmg(AsmgParams),
}

fn parse<T: DeserializeOwned>(params: &serde_json::Value) -> Result<T, ModelError> {
    let params = if params.is_null() {
        serde_json::json!({})
    } else {
        params.clone()
    };
    serde_path_to_error::deserialize(params).map_err(|e| {
        let path = e.path().to_string();
        let field = if path == "." { String::new() } else { path };
        let message = e.into_inner().to_string();
        let field = if field.is_empty() {
            unknown_field(&message).unwrap_or_default()
        } else {
            field
        };
        ModelError::InvalidParams { field, message }
    })
}

/// The field named by serde's "unknown field `x`" message.
fn unknown_field(message: &str) -> Option<String> {
    let rest = message.strip_prefix("unknown field `")?;
    Some(rest.split('`').next()?.to_owned())
}

impl ModelParams {
    /// Parses and checks `params` (a JSON object or null) for `model_type`.
    pub fn parse(model_type: ModelType, params: &serde_json::Value) -> Result<Self, ModelError> {
        match model_type {
            ModelType::Rsmp => {
                let p: RsmpParams = parse(params)?;
                p.check()?;
                Ok(Self::Rsmp(p))
            }
            ModelType::Asmg => {
                let p: AsmgParams = parse(params)?;
                p.check()?;
                Ok(Self::Asmg(p))
            }
        }
    }

    /// The parameters as JSON, defaults included.
    pub fn to_json(&self) -> serde_json::Value {
        fn value<T: Serialize>(p: &T) -> serde_json::Value {
            serde_json::to_value(p).unwrap_or_default()
        }
        match self {
            Self::Rsmp(p) => value(p),
            Self::Asmg(p) => value(p),
        }
    }

    /// The name of the parameter that names a mesh as template or atlas.
    pub fn template_field(&self) -> &'static str {
        match self {
            Self::Rsmp(_) => "template",
            Self::Asmg(_) => "atlas",
        }
    }

    /// The mesh id the user chose as template or atlas, if any.
    pub fn template_mesh_id(&self) -> Option<&str> {
        match self {
            Self::Rsmp(p) => p.template.as_deref(),
            Self::Asmg(p) => p.atlas_mesh_id(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn field_of(params: serde_json::Value) -> String {
        match ModelParams::parse(ModelType::Rsmp, &params) {
            Err(ModelError::InvalidParams { field, .. }) => field,
            other => panic!("expected invalid params, got {other:?}"),
        }
    }

    #[test]
    fn defaults_fill_in_and_errors_name_the_field() {
        let p = ModelParams::parse(ModelType::Rsmp, &serde_json::Value::Null).unwrap();
        assert_eq!(p.to_json()["variance_target"], 0.95);
        assert_eq!(field_of(json!({"n_modes": "many"})), "n_modes");
        assert_eq!(field_of(json!({"n_modes": 0})), "n_modes");
        assert_eq!(field_of(json!({"variance": 0.9})), "variance");
        assert_eq!(field_of(json!({"cpd_w": 1.5})), "cpd_w");
    }

    fn asmg_field_of(params: serde_json::Value) -> String {
        match ModelParams::parse(ModelType::Asmg, &params) {
            Err(ModelError::InvalidParams { field, .. }) => field,
            other => panic!("expected invalid params, got {other:?}"),
        }
    }

    #[test]
    fn asmg_params_fill_in_defaults_and_reject_bad_fields() {
        let p = ModelParams::parse(ModelType::Asmg, &serde_json::Value::Null).unwrap();
        let json = p.to_json();
        assert_eq!(json["features"], "hybrid");
        assert_eq!(json["atlas"], "auto");
        assert_eq!(json["latent_dim"], 16);
        assert_eq!(json["smoothing"], "displacement");
        assert!(json["temperature"].is_null());
        assert_eq!(p.template_mesh_id(), None);
        let p = ModelParams::parse(
            ModelType::Asmg,
            &json!({"features": "hybrid", "atlas": "m1", "temperature": 10000.0}),
        )
        .unwrap();
        assert_eq!(p.template_mesh_id(), Some("m1"));
        assert_eq!(p.to_json()["features"], "hybrid");
        assert_eq!(asmg_field_of(json!({"features": "spectral"})), "features");
        assert_eq!(asmg_field_of(json!({"epochs": 3})), "epochs");
        assert_eq!(asmg_field_of(json!({"latent_dim": 0})), "latent_dim");
        assert_eq!(asmg_field_of(json!({"beta": -1.0})), "beta");
        assert_eq!(asmg_field_of(json!({"smoothing": "both"})), "smoothing");
    }
}
