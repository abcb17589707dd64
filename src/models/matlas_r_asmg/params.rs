//! Parameters of an mAtlas-R-ASMG fit (`model_type: "matlas-r-asmg"`): every
//! `atlas-r-asmg` parameter plus `atlases`, the number of atlases, `"auto"` or the meshes
//! that start them.

use serde::{Deserialize, Serialize};

use crate::models::ModelError;
use crate::models::atlas_r_asmg::AtlasRAsmgParams;
use crate::models::clusters::supported_atlases;

/// Most atlases `"auto"` chooses (thesis §5.4 uses three for the liver).
pub const DEFAULT_ATLASES: usize = 3;
/// Most atlases a fit accepts.
pub const MAX_ATLASES: usize = 16;

/// The word `"auto"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Auto {
    /// As many atlases as the population supports.
    #[serde(rename = "auto")]
    Auto,
}

/// How the initial atlases are chosen.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AtlasesChoice {
    /// `M` atlases started from the medoids of a k-medoids clustering of the pre-aligned
    /// training meshes.
    Count(usize),
    /// The given training meshes (mesh ids), one atlas each, in order.
    Meshes(Vec<String>),
    /// [`DEFAULT_ATLASES`] atlases, fewer when the population is small: as many as
    /// [`supported_atlases`] (the default).
    Auto(Auto),
}

impl Default for AtlasesChoice {
    fn default() -> Self {
        Self::Auto(Auto::Auto)
    }
}

impl AtlasesChoice {
    /// The number of atlases for `training_meshes` meshes.
    pub fn count(&self, training_meshes: usize) -> usize {
        match self {
            Self::Count(m) => *m,
            Self::Meshes(ids) => ids.len(),
            Self::Auto(_) => auto_count(training_meshes),
        }
    }

    /// The mesh ids given, in order (empty for a count).
    pub fn mesh_ids(&self) -> Vec<&str> {
        match self {
            Self::Count(_) | Self::Auto(_) => Vec::new(),
            Self::Meshes(ids) => ids.iter().map(String::as_str).collect(),
        }
    }
}

/// The atlases `"auto"` fits on `training_meshes` meshes: [`DEFAULT_ATLASES`], fewer so that
/// each generator learns from about ten meshes or more ([`supported_atlases`]), at least one.
/// On 8 LV phantoms three generators made 46% of their members near copies of a training
/// shape, two 37%, one 2%.
pub fn auto_count(training_meshes: usize) -> usize {
    supported_atlases(training_meshes).min(DEFAULT_ATLASES)
}

/// Parameters of an mAtlas-R-ASMG fit, written as one flat object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct MatlasParams {
    /// Everything `atlas-r-asmg` takes (its `atlas` field picks the single atlas of M = 1).
    #[serde(flatten)]
    pub refined: AtlasRAsmgParams,
    /// A count `M`, `"auto"` (the default: 3, fewer below 30 training meshes) or a list of
    /// mesh ids, one initial atlas each.
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
                    "must be a number of atlases (e.g. 3), \"auto\" or a list of mesh ids",
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
        let count = self.atlases.count(0);
        if !matches!(self.atlases, AtlasesChoice::Auto(_)) && !(1..=MAX_ATLASES).contains(&count) {
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
            AtlasesChoice::Count(_) | AtlasesChoice::Auto(_) => {
                self.refined.asmg.atlas_mesh_id().into_iter().collect()
            }
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
        assert_eq!(p.atlases, AtlasesChoice::Auto(Auto::Auto));
        let given = serde_json::json!({"atlases": "auto"});
        assert_eq!(MatlasParams::from_json(&given).unwrap().atlases, p.atlases);
        assert_eq!(field(serde_json::json!({"atlases": "many"})), "atlases");
        let p = MatlasParams::from_json(&serde_json::json!({"atlases": ["a", "b"], "w_cd": 2.0}))
            .unwrap();
        assert_eq!(p.atlases.count(100), 2);
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
        assert_eq!(json["atlases"], "auto");
        assert_eq!(json["epochs_refine"], 3);
        assert_eq!(
            MatlasParams::from_label("m5"),
            Some(serde_json::json!({"atlases": 5}))
        );
        assert_eq!(MatlasParams::from_label("hgcn"), None);
    }

    #[test]
    fn auto_gives_each_generator_about_ten_meshes() {
        let auto = AtlasesChoice::default();
        let counts: Vec<usize> = [0, 8, 19, 20, 29, 30, 139]
            .iter()
            .map(|&n| auto.count(n))
            .collect();
        assert_eq!(counts, vec![1, 1, 1, 2, 2, 3, 3]);
        assert_eq!(AtlasesChoice::Count(4).count(8), 4);
    }
}
