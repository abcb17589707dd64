//! The one list of model types. Each type lives in its own folder and describes itself by
//! implementing [`ModelFamily`]: its API name, its parameters (Params → `check()` → a checked
//! type that `fit` takes, as linfa does), its fewest training meshes, its fit and how its
//! fitted model is read back. Nothing above `models` names a model type: the API, the jobs
//! and the command line go through [`ModelType`] and [`ModelParams`].
//!
//! Adding a model type: a folder with its `ModelFamily` and one line in [`REGISTRY`].

use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

use serde::Serialize;
use serde::de::DeserializeOwned;

use super::fitting::{FitInput, FittedParts, finish};
use super::progress::{Progress, Stages};
use super::stored::{FittedModel, decode_named};
use super::{FitOutcome, ModelError, asmg, atlas_r_asmg, matlas_r_asmg, rsmp};

/// Every model type, in the order they are listed to users.
static REGISTRY: &[&dyn ModelKind] = &[
    &Family::<rsmp::Rsmp>(PhantomData),
    &Family::<asmg::Asmg>(PhantomData),
    &Family::<atlas_r_asmg::AtlasRAsmg>(PhantomData),
    &Family::<matlas_r_asmg::MatlasRAsmg>(PhantomData),
];

/// What a model type declares about itself.
pub trait ModelFamily: Send + Sync + 'static {
    /// Name in the API, kebab-case (`rsmp`, `atlas-r-asmg`).
    const NAME: &'static str;
    /// Fewest training meshes a fit accepts.
    const MIN_TRAINING_MESHES: usize;
    /// The parameter that names a mesh of the dataset as template or atlas.
    const TEMPLATE_FIELD: &'static str;
    /// Stages of a fit and their rough share of the time; the last is `evaluation`.
    const STAGES: &'static [(&'static str, f64)];
    /// The parameters as a user writes them (unknown fields refused, defaults filled in).
    type Params: Serialize + DeserializeOwned;
    /// Parameters that passed [`ModelFamily::check`]: what the fit takes.
    type Checked: fmt::Debug + Send + Sync + 'static;
    /// The fitted model as stored.
    type Model: FittedModel + DeserializeOwned + 'static;

    /// Reads the parameters from JSON (an object or null), naming the offending field.
    fn parse(params: &serde_json::Value) -> Result<Self::Params, ModelError> {
        parse_json(params)
    }
    /// Checks every value; the error names the parameter.
    fn check(params: Self::Params) -> Result<Self::Checked, ModelError>;
    /// The parameters as written (for echoing them with defaults).
    fn params(checked: &Self::Checked) -> &Self::Params;
    /// The mesh ids given as template or atlases, in order (empty: none given).
    fn template_mesh_ids(checked: &Self::Checked) -> Vec<&str>;
    /// Parameters implied by a bench label such as `m3` (none by default).
    fn label_params(_label: &str) -> Option<serde_json::Value> {
        None
    }
    /// Fits the model up to its evaluation (which [`finish`] does for every type).
    fn fit(
        params: &Self::Checked,
        input: &FitInput<'_>,
        stages: &mut Stages,
        progress: &mut dyn Progress,
    ) -> Result<FittedParts<Self::Model>, ModelError>;
}

/// A model type behind a trait object (what the registry holds).
trait ModelKind: Send + Sync {
    fn name(&self) -> &'static str;
    fn min_training_meshes(&self) -> usize;
    fn template_field(&self) -> &'static str;
    fn label_params(&self, label: &str) -> Option<serde_json::Value>;
    fn parse(&self, this: ModelType, params: &serde_json::Value)
    -> Result<ModelParams, ModelError>;
    fn decode(&self, payload: &[u8]) -> Result<Arc<dyn FittedModel>, ModelError>;
}

struct Family<F>(PhantomData<fn() -> F>);

impl<F: ModelFamily> ModelKind for Family<F> {
    fn name(&self) -> &'static str {
        F::NAME
    }

    fn min_training_meshes(&self) -> usize {
        F::MIN_TRAINING_MESHES
    }

    fn template_field(&self) -> &'static str {
        F::TEMPLATE_FIELD
    }

    fn label_params(&self, label: &str) -> Option<serde_json::Value> {
        F::label_params(label)
    }

    fn parse(
        &self,
        this: ModelType,
        params: &serde_json::Value,
    ) -> Result<ModelParams, ModelError> {
        let raw = F::parse(params)?;
        let checked = F::check(raw)?;
        Ok(ModelParams {
            model_type: this,
            checked: Arc::new(Checked::<F> {
                model_type: this,
                params: checked,
            }),
        })
    }

    fn decode(&self, payload: &[u8]) -> Result<Arc<dyn FittedModel>, ModelError> {
        let model: F::Model = decode_named(payload)?;
        Ok(Arc::new(model))
    }
}

/// A model type: a handle on its registry entry.
#[derive(Clone, Copy)]
pub struct ModelType(&'static dyn ModelKind);

impl ModelType {
    /// Every model type.
    pub fn all() -> impl Iterator<Item = ModelType> {
        REGISTRY.iter().map(|k| ModelType(*k))
    }

    /// The names of every model type, for error messages.
    pub fn names() -> Vec<&'static str> {
        Self::all().map(ModelType::as_str).collect()
    }

    /// From its API name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::all().find(|t| t.as_str() == name)
    }

    /// From its API name, or an error listing the known names.
    pub fn parse_name(name: &str) -> Result<Self, ModelError> {
        Self::from_name(name).ok_or_else(|| ModelError::UnknownModelType {
            name: name.to_owned(),
            known: Self::names().join(", "),
        })
    }

    /// The name used in the API.
    pub fn as_str(self) -> &'static str {
        self.0.name()
    }

    /// Fewest training meshes a fit accepts.
    pub fn min_training_meshes(self) -> usize {
        self.0.min_training_meshes()
    }

    /// The parameters a bench label such as `m3` implies for this type, if any.
    pub fn label_params(self, label: &str) -> Option<serde_json::Value> {
        self.0.label_params(label)
    }

    /// Parses and checks `params` (a JSON object or null) for this type.
    pub fn parse_params(self, params: &serde_json::Value) -> Result<ModelParams, ModelError> {
        self.0.parse(self, params)
    }

    /// Reads this type's fitted model from its stored payload.
    pub(crate) fn decode(self, payload: &[u8]) -> Result<Arc<dyn FittedModel>, ModelError> {
        self.0.decode(payload)
    }
}

impl PartialEq for ModelType {
    fn eq(&self, other: &Self) -> bool {
        self.as_str() == other.as_str()
    }
}

impl Eq for ModelType {}

impl fmt::Debug for ModelType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl fmt::Display for ModelType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for ModelType {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

/// Checked parameters of one model type, behind one interface.
trait AnyParams: fmt::Debug + Send + Sync {
    fn to_json(&self) -> serde_json::Value;
    fn template_mesh_ids(&self) -> Vec<&str>;
    fn fit(
        &self,
        input: &FitInput<'_>,
        progress: &mut dyn Progress,
    ) -> Result<FitOutcome, ModelError>;
}

struct Checked<F: ModelFamily> {
    model_type: ModelType,
    params: F::Checked,
}

impl<F: ModelFamily> fmt::Debug for Checked<F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.params.fmt(f)
    }
}

impl<F: ModelFamily> AnyParams for Checked<F> {
    fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(F::params(&self.params)).unwrap_or_default()
    }

    fn template_mesh_ids(&self) -> Vec<&str> {
        F::template_mesh_ids(&self.params)
    }

    fn fit(
        &self,
        input: &FitInput<'_>,
        progress: &mut dyn Progress,
    ) -> Result<FitOutcome, ModelError> {
        if input.training.len() < F::MIN_TRAINING_MESHES {
            return Err(ModelError::TooFewMeshes {
                required: F::MIN_TRAINING_MESHES,
                found: input.training.len(),
            });
        }
        let mut stages = Stages::new(F::STAGES);
        let parts = F::fit(&self.params, input, &mut stages, progress)?;
        finish(self.model_type, parts, input, stages, progress)
    }
}

/// A model type's parameters, checked and with defaults filled in.
#[derive(Debug, Clone)]
pub struct ModelParams {
    model_type: ModelType,
    checked: Arc<dyn AnyParams>,
}

impl PartialEq for ModelParams {
    fn eq(&self, other: &Self) -> bool {
        self.model_type == other.model_type && self.to_json() == other.to_json()
    }
}

impl ModelParams {
    /// Parses and checks `params` (a JSON object or null) for `model_type`.
    pub fn parse(model_type: ModelType, params: &serde_json::Value) -> Result<Self, ModelError> {
        model_type.parse_params(params)
    }

    /// The model type.
    pub fn model_type(&self) -> ModelType {
        self.model_type
    }

    /// The parameters as JSON, defaults included.
    pub fn to_json(&self) -> serde_json::Value {
        self.checked.to_json()
    }

    /// The name of the parameter that names a mesh as template or atlas.
    pub fn template_field(&self) -> &'static str {
        self.model_type.0.template_field()
    }

    /// The mesh ids the user chose as template or atlases, in order (empty: none chosen).
    pub fn template_mesh_ids(&self) -> Vec<&str> {
        self.checked.template_mesh_ids()
    }

    /// Fits the model these parameters describe to `input.training` and evaluates it on
    /// `input.holdout`. The same inputs and seed give the same model.
    pub fn fit(
        &self,
        input: &FitInput<'_>,
        progress: &mut dyn Progress,
    ) -> Result<FitOutcome, ModelError> {
        self.checked.fit(input, progress)
    }
}

/// Deserialises parameters, naming the offending field in the error.
pub(crate) fn parse_json<T: DeserializeOwned>(params: &serde_json::Value) -> Result<T, ModelError> {
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

#[cfg(test)]
#[path = "registry_tests.rs"]
mod tests;
