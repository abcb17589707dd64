//! Stored models that later releases can read.
//!
//! A stored model is `CFSTORE` (7 bytes), the format version (u16, little-endian), then a
//! MessagePack map with named fields: the model type, the training shapes and the type's
//! own model, itself a MessagePack map. Maps with named fields tolerate fields added later
//! (`#[serde(default)]`), unlike a positional encoding; network weights stay binary (burn
//! records, stored as MessagePack byte strings). A payload without the header, or with a
//! version this release does not read, fails with `model.unsupported_version` naming the
//! versions.

use std::sync::Arc;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use super::registry::ModelType;
use super::{ModelError, ShapeModel, TrainingShapes};

/// First bytes of every stored model.
pub const MAGIC: &[u8; 7] = b"CFSTORE";
/// The format this release writes.
pub const FORMAT_VERSION: u16 = 2;
/// The formats this release reads.
pub const SUPPORTED_VERSIONS: &[u16] = &[2];

/// A fitted model of any type: what sampling, reconstruction and storage need.
pub trait FittedModel: ShapeModel + Send + Sync + std::fmt::Debug {
    /// The model in its stored form (see [`encode_named`]).
    fn encode(&self) -> Result<Vec<u8>, ModelError>;
    /// The concrete model, for tests and tools that know its type.
    fn as_any(&self) -> &dyn std::any::Any;
}

/// `value` as a MessagePack map with named fields.
pub fn encode_named<T: Serialize>(value: &T) -> Result<Vec<u8>, ModelError> {
    rmp_serde::to_vec_named(value).map_err(|e| ModelError::Corrupt(e.to_string()))
}

/// The inverse of [`encode_named`].
pub fn decode_named<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ModelError> {
    rmp_serde::from_slice(bytes).map_err(|e| ModelError::Corrupt(e.to_string()))
}

/// What is stored for a model: the fitted model and its training shapes.
#[derive(Debug, Clone)]
pub struct StoredModel {
    /// Its type.
    pub model_type: ModelType,
    /// The fitted model.
    pub model: Arc<dyn FittedModel>,
    /// Training shapes and privacy thresholds.
    pub training: TrainingShapes,
}

#[derive(Serialize)]
struct EnvelopeOut<'a> {
    model_type: &'a str,
    training: &'a TrainingShapes,
    #[serde(with = "serde_bytes")]
    model: Vec<u8>,
}

#[derive(Deserialize)]
struct EnvelopeIn {
    model_type: String,
    training: TrainingShapes,
    #[serde(with = "serde_bytes")]
    model: Vec<u8>,
}

/// The format version of stored bytes, `None` when they carry no header (models stored
/// before versioning).
pub fn format_version(bytes: &[u8]) -> Option<u16> {
    let rest = bytes.strip_prefix(MAGIC.as_slice())?;
    let v = rest.get(..2)?;
    Some(u16::from_le_bytes([v[0], v[1]]))
}

impl StoredModel {
    /// The stored form: header, then the named-field encoding.
    pub fn to_bytes(&self) -> Result<Vec<u8>, ModelError> {
        let envelope = EnvelopeOut {
            model_type: self.model_type.as_str(),
            training: &self.training,
            model: self.model.encode()?,
        };
        let mut bytes = MAGIC.to_vec();
        bytes.extend(FORMAT_VERSION.to_le_bytes());
        bytes.extend(encode_named(&envelope)?);
        Ok(bytes)
    }

    /// From [`StoredModel::to_bytes`] of this or an earlier supported release.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, ModelError> {
        let version = format_version(bytes);
        if !version.is_some_and(|v| SUPPORTED_VERSIONS.contains(&v)) {
            return Err(ModelError::UnsupportedVersion {
                found: version,
                supported: SUPPORTED_VERSIONS.to_vec(),
            });
        }
        let envelope: EnvelopeIn = decode_named(&bytes[MAGIC.len() + 2..])?;
        let model_type = ModelType::from_name(&envelope.model_type).ok_or_else(|| {
            ModelError::Corrupt(format!(
                "the stored model is of type '{}', which this release does not know (known: {})",
                envelope.model_type,
                ModelType::names().join(", ")
            ))
        })?;
        Ok(Self {
            model_type,
            model: model_type.decode(&envelope.model)?,
            training: envelope.training,
        })
    }

    /// The concrete model, when it is a `T`.
    pub fn downcast<T: 'static>(&self) -> Option<&T> {
        self.model.as_any().downcast_ref::<T>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unversioned_and_future_payloads_name_the_versions() {
        let err = StoredModel::from_bytes(b"\x00\x01postcard-era").unwrap_err();
        assert_eq!(err.code(), "model.unsupported_version");
        assert!(
            err.to_string().contains("without a format version"),
            "{err}"
        );
        assert!(err.to_string().contains('2'), "{err}");
        let mut future = MAGIC.to_vec();
        future.extend(99u16.to_le_bytes());
        let err = StoredModel::from_bytes(&future).unwrap_err();
        assert_eq!(err.code(), "model.unsupported_version");
        assert!(err.to_string().contains("99"), "{err}");
        assert_eq!(format_version(&future), Some(99));
        assert_eq!(format_version(b"CFST"), None);
    }
}
