//! The model file written by `cohortforge fit` and read by `cohortforge evaluate`: one
//! binary file (a magic header with the format version, then MessagePack with named fields)
//! holding the model type, its parameters, the seed, the summary, the reference population,
//! the training meshes' faces (for point-to-surface specificity) and the stored model (with
//! its own format version, see [`crate::models::stored`]).
//!
//! JSON-shaped parts (parameters, summary, reference population) are kept as JSON text,
//! which stays readable across versions of those structures.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::models::stored::{decode_named, encode_named};
use crate::models::{FitOutcome, ModelError, ModelParams, ModelSummary, ModelType};
use crate::models::{ReferencePopulation, StoredModel, TrainingShapes};

/// First bytes of every model file: a name, then the format version byte.
pub const MAGIC_NAME: &[u8; 7] = b"CFMODEL";
/// The file format this release writes.
pub const FILE_VERSION: u8 = 2;
/// The file formats this release reads.
pub const SUPPORTED_FILE_VERSIONS: &[u8] = &[2];

/// Why a model file could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// The file does not start with [`MAGIC`].
    #[error("not a cohortforge model file (or a version this build cannot read)")]
    NotAModelFile,
    /// The content could not be decoded or does not fit together.
    #[error("corrupt model file: {0}")]
    Corrupt(String),
    /// The stored model or its parameters are unusable.
    #[error(transparent)]
    Model(#[from] ModelError),
}

fn corrupt(e: impl std::fmt::Display) -> ModelFileError {
    ModelFileError::Corrupt(e.to_string())
}

/// Everything a fit leaves for later evaluation and sampling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// Model type name, e.g. `rsmp`.
    pub model_type: String,
    /// Parameters with defaults filled in, as JSON text.
    pub params_json: String,
    /// Seed of the fit.
    pub seed: u64,
    /// [`ModelSummary`] as JSON text.
    pub summary_json: String,
    /// [`ReferencePopulation`] as JSON text.
    pub reference_json: String,
    /// File names of the training meshes, in fit order.
    pub training_names: Vec<String>,
    /// File names of the held-out meshes.
    pub holdout_names: Vec<String>,
    /// Faces of each training mesh (`[n_faces, 3]`), matching the training shapes of the
    /// stored model vertex for vertex.
    pub training_faces: Vec<Vec<[u32; 3]>>,
    /// [`StoredModel::to_bytes`].
    #[serde(with = "serde_bytes")]
    pub model_bytes: Vec<u8>,
}

/// Names of the meshes a model was fitted and evaluated on.
#[derive(Debug, Clone)]
pub struct FitInputs<'a> {
    /// Training mesh names, in fit order.
    pub training_names: &'a [String],
    /// Held-out mesh names.
    pub holdout_names: &'a [String],
    /// Faces of each training mesh.
    pub training_faces: Vec<&'a [[u32; 3]]>,
}

impl ModelFile {
    /// Describes a finished fit.
    pub fn new(
        params: &ModelParams,
        seed: u64,
        outcome: &FitOutcome,
        inputs: &FitInputs<'_>,
    ) -> Result<Self, ModelFileError> {
        Ok(Self {
            model_type: params.model_type().as_str().to_owned(),
            params_json: params.to_json().to_string(),
            seed,
            summary_json: serde_json::to_string(&outcome.summary).map_err(corrupt)?,
            reference_json: serde_json::to_string(&outcome.reference).map_err(corrupt)?,
            training_names: inputs.training_names.to_vec(),
            holdout_names: inputs.holdout_names.to_vec(),
            training_faces: inputs.training_faces.iter().map(|f| f.to_vec()).collect(),
            model_bytes: outcome.model.to_bytes()?,
        })
    }

    /// The file's bytes: [`MAGIC_NAME`], [`FILE_VERSION`], then the named-field encoding.
    pub fn to_bytes(&self) -> Result<Vec<u8>, ModelFileError> {
        let mut bytes = MAGIC_NAME.to_vec();
        bytes.push(FILE_VERSION);
        bytes.extend(encode_named(self)?);
        Ok(bytes)
    }

    /// From [`ModelFile::to_bytes`] of this or an earlier supported release.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ModelFileError> {
        let rest = bytes
            .strip_prefix(MAGIC_NAME.as_slice())
            .ok_or(ModelFileError::NotAModelFile)?;
        let (&version, body) = rest.split_first().ok_or(ModelFileError::NotAModelFile)?;
        if !SUPPORTED_FILE_VERSIONS.contains(&version) {
            return Err(ModelError::UnsupportedVersion {
                found: Some(u16::from(version)),
                supported: SUPPORTED_FILE_VERSIONS
                    .iter()
                    .map(|&v| u16::from(v))
                    .collect(),
            }
            .into());
        }
        decode_named(body).map_err(corrupt)
    }

    /// Writes the file.
    pub fn save(&self, path: &Path) -> Result<(), ModelFileError> {
        std::fs::write(path, self.to_bytes()?).map_err(|source| ModelFileError::Io {
            path: path.display().to_string(),
            source,
        })
    }

    /// Reads a file written by [`ModelFile::save`].
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        let bytes = std::fs::read(path).map_err(|source| ModelFileError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_bytes(&bytes)
    }

    /// The parameters, checked again for this build.
    pub fn params(&self) -> Result<ModelParams, ModelFileError> {
        let model_type = ModelType::parse_name(&self.model_type)?;
        let json: serde_json::Value = serde_json::from_str(&self.params_json).map_err(corrupt)?;
        Ok(ModelParams::parse(model_type, &json)?)
    }

    /// The parameters as JSON.
    pub fn params_value(&self) -> serde_json::Value {
        serde_json::from_str(&self.params_json).unwrap_or(serde_json::Value::Null)
    }

    /// The fit's summary.
    pub fn summary(&self) -> Result<ModelSummary, ModelFileError> {
        serde_json::from_str(&self.summary_json).map_err(corrupt)
    }

    /// The training population's biomarkers.
    pub fn reference(&self) -> Result<ReferencePopulation, ModelFileError> {
        serde_json::from_str(&self.reference_json).map_err(corrupt)
    }

    /// The fitted model, after checking that the training faces fit its training shapes.
    pub fn stored_model(&self) -> Result<StoredModel, ModelFileError> {
        let stored = StoredModel::from_bytes(&self.model_bytes)?;
        check_faces(&stored.training, &self.training_faces)?;
        Ok(stored)
    }
}

/// Every training shape has faces, and no face names a vertex the shape lacks.
fn check_faces(training: &TrainingShapes, faces: &[Vec<[u32; 3]>]) -> Result<(), ModelFileError> {
    if training.shapes.len() != faces.len() {
        return Err(corrupt(format!(
            "{} training shapes but {} face lists",
            training.shapes.len(),
            faces.len()
        )));
    }
    for (k, (shape, faces)) in training.shapes.iter().zip(faces).enumerate() {
        if faces.iter().flatten().any(|&v| v as usize >= shape.len()) {
            return Err(corrupt(format!(
                "training shape {k} has a face naming a vertex beyond its {}",
                shape.len()
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::fit::fit_model;
    use crate::mesh::Mesh;
    use crate::mesh::phantom::{self, Family};
    use crate::models::FitInput;
    use crate::models::progress::Silent;

    fn quick_params() -> ModelParams {
        let json = serde_json::json!({"cpd_max_iterations": 30, "multistart": false});
        ModelType::parse_name("rsmp")
            .unwrap()
            .parse_params(&json)
            .unwrap()
    }

    fn fitted() -> ModelFile {
        let meshes: Vec<Mesh> = phantom::generate(Family::Lv, 5, 4)
            .iter()
            .map(|p| p.canonical_mesh())
            .collect();
        let params = quick_params();
        let outcome = fit_model(
            &params,
            &FitInput::new(&meshes[..4], &meshes[4..], 9),
            &mut Silent,
        )
        .unwrap();
        let names: Vec<String> = (0..5).map(|i| format!("lv_{i:03}.obj")).collect();
        let inputs = FitInputs {
            training_names: &names[..4],
            holdout_names: &names[4..],
            training_faces: meshes[..4].iter().map(|m| m.faces.as_slice()).collect(),
        };
        ModelFile::new(&params, 9, &outcome, &inputs).unwrap()
    }

    #[test]
    fn round_trip_keeps_every_part() {
        let file = fitted();
        let back = ModelFile::from_bytes(&file.to_bytes().unwrap()).unwrap();
        assert_eq!(back, file);
        assert_eq!(back.params().unwrap(), quick_params());
        assert_eq!(back.params_value()["cpd_max_iterations"], 30);
        assert_eq!(back.seed, 9);
        let summary = back.summary().unwrap();
        assert_eq!((summary.training_count, summary.holdout_count), (4, 1));
        assert_eq!(back.reference().unwrap().values[0].len(), 4);
        let stored = back.stored_model().unwrap();
        assert_eq!(stored.training.shapes.len(), 4);
        assert_eq!(back.holdout_names, vec!["lv_004.obj".to_owned()]);

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.cfmodel");
        file.save(&path).unwrap();
        assert_eq!(ModelFile::load(&path).unwrap(), file);
    }

    #[test]
    fn foreign_truncated_or_inconsistent_files_are_errors() {
        assert!(matches!(
            ModelFile::from_bytes(b"solid cube\n"),
            Err(ModelFileError::NotAModelFile)
        ));
        let file = fitted();
        let bytes = file.to_bytes().unwrap();
        assert!(matches!(
            ModelFile::from_bytes(&bytes[..bytes.len() / 2]),
            Err(ModelFileError::Corrupt(_))
        ));
        let mut short = file.clone();
        short.training_faces.pop();
        assert!(matches!(
            short.stored_model(),
            Err(ModelFileError::Corrupt(_))
        ));
        let mut wrong = file;
        wrong.training_faces[0][0] = [0, 1, u32::MAX];
        assert!(matches!(
            wrong.stored_model(),
            Err(ModelFileError::Corrupt(_))
        ));
    }
}

#[cfg(test)]
#[path = "model_file_fixture.rs"]
mod fixture;
