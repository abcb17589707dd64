//! Parameters of an mAtlas-R-ASMG fit (`model_type: "matlas-r-asmg"`): every
//! `atlas-r-asmg` parameter plus `atlases`, the number of atlases or the meshes that start
//! them.

use serde::{Deserialize, Serialize};

use crate::models::ModelError;
use crate::models::atlas_r_asmg::AtlasRAsmgParams;

/// Default number of atlases (thesis §5.4 uses three for the liver).
pub const DEFAULT_ATLASES: usize = 3;
/// Most atlases a fit accepts.
pub const MAX_ATLASES: usize = 16;

/// How the initial atlases are chosen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AtlasesChoice {
    /// `M` atlases started from the medoids of a k-medoids clustering of the pre-aligned
    /// training meshes.
    Count(usize),
    /// The given training meshes (mesh ids), one atlas each, in order.
    Meshes(Vec<String>),
}

impl Default for AtlasesChoice {
    fn default() -> Self {
        Self::Count(DEFAULT_ATLASES)
    }
}

impl AtlasesChoice {
    /// The number of atlases.
    pub fn count(&self) -> usize {
        match self {
            Self::Count(m) => *m,
            Self::Meshes(ids) => ids.len(),
        }
    }

    /// The mesh ids given, in order (empty for a count).
    pub fn mesh_ids(&self) -> Vec<&str> {
        match self {
            Self::Count(_) => Vec::new(),
            Self::Meshes(ids) => ids.iter().map(String::as_str).collect(),
        }
    }
}

/// Parameters of an mAtlas-R-ASMG fit, written as one flat object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct MatlasParams {
    /// Everything `atlas-r-asmg` takes (its `atlas` field picks the single atlas of M = 1).
    #[serde(flatten)]
    pub refined: AtlasRAsmgParams,
    /// A count `M` (default 3) or a list of mesh ids, one initial atlas each.
    pub atlases: AtlasesChoice,
}

impl MatlasParams {
    /// Reads the flat JSON object: `atlases`, then the `atlas-r-asmg` fields.
    pub fn from_json(params: &serde_json::Value) -> Result<Self, ModelError> {
        let mut rest = params.clone();
        let atlases = match rest.as_object_mut().and_then(|o| o.remove("atlases")) {
            None => AtlasesChoice::default(),
            Some(v) => serde_json::from_value(v).map_err(|_| {
                ModelError::invalid(
                    "atlases",
                    "must be a number of atlases (e.g. 3) or a list of mesh ids",
                )
            })?,
        };
        Ok(Self {
            refined: AtlasRAsmgParams::from_json(&rest)?,
            atlases,
        })
    }

    /// Checks every value (the error names the parameter): what a fit takes.
    pub fn check(self) -> Result<CheckedMatlasParams, ModelError> {
        let count = self.atlases.count();
        if !(1..=MAX_ATLASES).contains(&count) {
            return Err(ModelError::invalid(
                "atlases",
                format!("must give between 1 and {MAX_ATLASES} atlases, got {count}"),
            ));
        }
        let ids = self.atlases.mesh_ids();
        let mut seen = std::collections::HashSet::new();
        if let Some(id) = ids.iter().find(|id| !seen.insert(**id)) {
            return Err(ModelError::invalid(
                "atlases",
                format!("names mesh {id} twice; give each initial atlas once"),
            ));
        }
        if !ids.is_empty() && self.refined.asmg.atlas_mesh_id().is_some() {
            return Err(ModelError::invalid(
                "atlas",
                "give the initial atlases either as a list in `atlases` or one mesh in `atlas`, not both",
            ));
        }
        self.refined.clone().check()?;
        Ok(CheckedMatlasParams(self))
    }

    /// The parameters a bench label `m<N>` implies: `N` atlases.
    pub fn from_label(label: &str) -> Option<serde_json::Value> {
        let count: usize = label.strip_prefix('m')?.parse().ok()?;
        Some(serde_json::json!({ "atlases": count }))
    }

    /// The mesh ids that start atlases: the list, or the `atlas` mesh of M = 1.
    pub fn mesh_ids(&self) -> Vec<&str> {
        match &self.atlases {
            AtlasesChoice::Meshes(_) => self.atlases.mesh_ids(),
            AtlasesChoice::Count(_) => self.refined.asmg.atlas_mesh_id().into_iter().collect(),
        }
    }
}

/// mAtlas-R-ASMG parameters that passed [`MatlasParams::check`].
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedMatlasParams(MatlasParams);

impl CheckedMatlasParams {
    /// The parameters.
    pub fn get(&self) -> &MatlasParams {
        &self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn field(v: serde_json::Value) -> String {
        match MatlasParams::from_json(&v).and_then(MatlasParams::check) {
            Err(ModelError::InvalidParams { field, .. }) => field,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn atlases_are_a_count_or_mesh_ids() {
        let p = MatlasParams::from_json(&serde_json::Value::Null).unwrap();
        assert_eq!(p.atlases, AtlasesChoice::Count(3));
        let p = MatlasParams::from_json(&serde_json::json!({"atlases": ["a", "b"], "w_cd": 2.0}))
            .unwrap();
        assert_eq!(p.atlases.count(), 2);
        assert_eq!(p.mesh_ids(), vec!["a", "b"]);
        assert_eq!(p.refined.refinement.w_cd, 2.0);
        assert_eq!(field(serde_json::json!({"atlases": 0})), "atlases");
        assert_eq!(field(serde_json::json!({"atlases": "three"})), "atlases");
        assert_eq!(field(serde_json::json!({"atlases": ["a", "a"]})), "atlases");
        assert_eq!(
            field(serde_json::json!({"atlases": ["a"], "atlas": "b"})),
            "atlas"
        );
        assert_eq!(
            field(serde_json::json!({"epochs_refine": 0})),
            "epochs_refine"
        );
        assert_eq!(
            field(serde_json::json!({"atlases": 2, "colour": 1})),
            "colour"
        );
        // Echoed flat, with `atlases` beside the other fields.
        let json = serde_json::to_value(MatlasParams::default()).unwrap();
        assert_eq!(json["atlases"], 3);
        assert_eq!(json["epochs_refine"], 3);
        assert_eq!(
            MatlasParams::from_label("m5"),
            Some(serde_json::json!({"atlases": 5}))
        );
        assert_eq!(MatlasParams::from_label("hgcn"), None);
    }
}
