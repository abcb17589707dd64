//! Parameters of an Atlas-R-ASMG fit (`model_type: "atlas-r-asmg"`): every `asmg`
//! parameter plus the refinement's weights and epochs.

use serde::{Deserialize, Serialize};

use crate::models::ModelError;
use crate::models::asmg::AsmgParams;
use crate::models::registry::parse_json;

/// Default weight of the Chamfer term (thesis §5.2: 1).
pub const DEFAULT_W_CD: f64 = 1.0;
/// Default weight of the Laplacian term (thesis: 1 for LV, 1.2 for liver).
pub const DEFAULT_W_LAP: f64 = 1.0;
/// Default refinement epochs. Each costs about a Ψ epoch and a half plus an atlas update
/// (≈ 65 s on 100 LV phantoms, 2 cores); three keep a fit of 100 LV phantoms within its
/// 15-minute budget.
pub const DEFAULT_EPOCHS_REFINE: usize = 3;
/// Largest number of refinement epochs accepted.
pub const MAX_EPOCHS_REFINE: usize = 1000;
/// The parameters the refinement adds to `asmg`'s.
pub const REFINEMENT_FIELDS: [&str; 3] = ["w_cd", "w_lap", "epochs_refine"];

/// What the refinement adds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RefinementParams {
    /// Weight of the Chamfer term `CD(g_k, h'_k)` (sum of squared nearest-neighbour
    /// distances both ways, mm²).
    pub w_cd: f64,
    /// Weight of the Laplacian term `Σ_j‖h'_kj − mean_{q∈N(j)} h'_kq‖²` (mm²).
    pub w_lap: f64,
    /// Epochs of end-to-end refinement of Ψ, each followed by an atlas update.
    pub epochs_refine: usize,
}

impl Default for RefinementParams {
    fn default() -> Self {
        Self {
            w_cd: DEFAULT_W_CD,
            w_lap: DEFAULT_W_LAP,
            epochs_refine: DEFAULT_EPOCHS_REFINE,
        }
    }
}

/// Parameters of an Atlas-R-ASMG fit, written as one flat object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct AtlasRAsmgParams {
    /// The ASMG parameters (features, atlas, networks, attention, smoothing).
    #[serde(flatten)]
    pub asmg: AsmgParams,
    /// The refinement.
    #[serde(flatten)]
    pub refinement: RefinementParams,
}

impl AtlasRAsmgParams {
    /// Reads the flat JSON object: the refinement's fields, then `asmg`'s, each refusing
    /// unknown fields and naming the offending one.
    pub fn from_json(params: &serde_json::Value) -> Result<Self, ModelError> {
        let mut rest = match params {
            serde_json::Value::Null => serde_json::Map::new(),
            serde_json::Value::Object(map) => map.clone(),
            other => {
                return Err(ModelError::invalid(
                    "",
                    format!("params must be a JSON object, got {other}"),
                ));
            }
        };
        let own: serde_json::Map<String, serde_json::Value> = REFINEMENT_FIELDS
            .iter()
            .filter_map(|k| rest.remove(*k).map(|v| ((*k).to_owned(), v)))
            .collect();
        Ok(Self {
            refinement: parse_json(&serde_json::Value::Object(own))?,
            asmg: parse_json(&serde_json::Value::Object(rest))?,
        })
    }

    /// Checks every value (the error names the parameter): what a fit takes.
    pub fn check(self) -> Result<CheckedAtlasRAsmgParams, ModelError> {
        self.asmg.validate()?;
        let r = &self.refinement;
        for (field, w) in [("w_cd", r.w_cd), ("w_lap", r.w_lap)] {
            if !(w.is_finite() && w >= 0.0) {
                return Err(ModelError::invalid(
                    field,
                    format!("must be a number >= 0, got {w}"),
                ));
            }
        }
        if !(1..=MAX_EPOCHS_REFINE).contains(&r.epochs_refine) {
            return Err(ModelError::invalid(
                "epochs_refine",
                format!(
                    "must be between 1 and {MAX_EPOCHS_REFINE}, got {}",
                    r.epochs_refine
                ),
            ));
        }
        Ok(CheckedAtlasRAsmgParams(self))
    }
}

/// Atlas-R-ASMG parameters that passed [`AtlasRAsmgParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedAtlasRAsmgParams(AtlasRAsmgParams);

impl CheckedAtlasRAsmgParams {
    /// The parameters.
    pub fn get(&self) -> &AtlasRAsmgParams {
        &self.0
    }
}
