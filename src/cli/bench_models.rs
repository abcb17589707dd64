//! The models of one `cohortforge bench` run, so that several parameterisations of one
//! model type can be compared side by side:
//!
//! - `--models` entries are `TYPE` or `TYPE:LABEL`, e.g. `rsmp,asmg:sgcn,asmg:hgcn`;
//! - `--params KEY=JSON` gives the parameters of the entry labelled `KEY`, or of every entry
//!   of type `KEY` without parameters of its own label (a label's parameters win);
//! - each model is named by its label, or by its type when it has none, in every table and
//!   in the JSON; names are unique.

use super::study::{parse_model_type, parse_params};
use crate::models::{ModelParams, ModelType};

/// One entry of `--models`: a model type, optionally labelled.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ModelEntry {
    /// The model type.
    pub model_type: ModelType,
    /// The label after `:`, if any.
    pub label: Option<String>,
}

impl ModelEntry {
    /// The model's name in tables and JSON: its label, else its type.
    pub fn name(&self) -> &str {
        self.label
            .as_deref()
            .unwrap_or_else(|| self.model_type.as_str())
    }
}

/// Parses `TYPE` or `TYPE:LABEL`. A label is letters, digits, `_` and `-`, and is no model
/// type's name (so that a `--params` key names one thing).
///
/// # Errors
/// A sentence naming the entry and what is wrong with it.
pub fn parse_model_entry(s: &str) -> Result<ModelEntry, String> {
    let s = s.trim();
    let (kind, label) = match s.split_once(':') {
        Some((kind, label)) => (kind.trim(), Some(label.trim())),
        None => (s, None),
    };
    let model_type = parse_model_type(kind)?;
    let label = match label {
        None => None,
        Some("") => return Err(format!("'{s}': the label after ':' is empty")),
        Some(label) => {
            if let Some(c) = label
                .chars()
                .find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-'))
            {
                return Err(format!(
                    "'{s}': the label may hold letters, digits, '_' and '-', not '{c}'"
                ));
            }
            if ModelType::from_name(label).is_some() {
                return Err(format!(
                    "'{s}': the label '{label}' is a model type's name; choose another, \
                     so that --params {label}=… is not ambiguous"
                ));
            }
            Some(label.to_owned())
        }
    };
    Ok(ModelEntry { model_type, label })
}

/// A model to bench: its name, its type and its checked parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchModel {
    /// The label, or the type when there is none.
    pub name: String,
    /// The model type.
    pub model_type: ModelType,
    /// Parameters, defaults filled in.
    pub params: ModelParams,
}

/// Whose parameters a `--params` key gives.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Key {
    Label(String),
    Type(ModelType),
}

/// The `--params` as `(key, JSON)`, each key a label of `entries` or a model type.
fn parse_keys<'a>(
    entries: &[ModelEntry],
    params: &'a [String],
) -> Result<Vec<(Key, &'a str)>, String> {
    let mut given: Vec<(Key, &str)> = Vec::new();
    for p in params {
        let (key, json) = p
            .split_once('=')
            .ok_or_else(|| format!("--params {p}: expected LABEL=JSON or TYPE=JSON"))?;
        let key = key.trim();
        let key = if entries.iter().any(|e| e.label.as_deref() == Some(key)) {
            Key::Label(key.to_owned())
        } else if let Some(t) = ModelType::from_name(key) {
            Key::Type(t)
        } else {
            return Err(format!(
                "--params {key}=…: '{key}' is neither a label of --models nor a model type"
            ));
        };
        if given.iter().any(|(k, _)| *k == key) {
            return Err(format!("--params {key}=… is given twice"));
        }
        given.push((key, json));
    }
    Ok(given)
}

/// The models to bench, in the order of `entries`, with the parameters of `params`
/// (`KEY=JSON` strings) checked for their types.
///
/// # Errors
/// A sentence for a malformed or unknown `--params` key, a key given twice, two entries
/// with one name, or parameters that do not suit the entry's type.
pub fn bench_models(entries: &[ModelEntry], params: &[String]) -> Result<Vec<BenchModel>, String> {
    for (i, e) in entries.iter().enumerate() {
        if entries[..i].iter().any(|o| o.name() == e.name()) {
            return Err(format!(
                "--models names '{}' twice; label the entries of one type apart, e.g. {t}:a,{t}:b",
                e.name(),
                t = e.model_type.as_str()
            ));
        }
    }
    let given = parse_keys(entries, params)?;
    let json_for = |key: &Key| given.iter().find(|(k, _)| k == key).map(|(_, j)| *j);
    entries
        .iter()
        .map(|e| {
            let json = e
                .label
                .as_ref()
                .and_then(|l| json_for(&Key::Label(l.clone())))
                .or_else(|| json_for(&Key::Type(e.model_type)));
            let json = with_label_params(e, json);
            let params = parse_params(e.model_type, json.as_deref())
                .map_err(|m| format!("{}: {m}", e.name()))?;
            Ok(BenchModel {
                name: e.name().to_owned(),
                model_type: e.model_type,
                params,
            })
        })
        .collect()
}

/// The parameters a label implies for its type (e.g. `matlas-r-asmg:m5`: five atlases),
/// with those given for the entry on top.
fn with_label_params(entry: &ModelEntry, given: Option<&str>) -> Option<String> {
    let implied = entry
        .label
        .as_deref()
        .and_then(|l| entry.model_type.label_params(l));
    let Some(mut implied) = implied else {
        return given.map(str::to_owned);
    };
    if let Some(text) = given {
        match (
            implied.as_object_mut(),
            serde_json::from_str::<serde_json::Value>(text),
        ) {
            (Some(base), Ok(serde_json::Value::Object(own))) => base.extend(own),
            // Not an object: let the parameter check say what is wrong with it.
            _ => return Some(text.to_owned()),
        }
    }
    Some(implied.to_string())
}

impl std::fmt::Display for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Label(l) => f.write_str(l),
            Self::Type(t) => f.write_str(t.as_str()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(list: &str) -> Vec<ModelEntry> {
        list.split(',')
            .map(|s| parse_model_entry(s).unwrap())
            .collect()
    }

    fn features(m: &BenchModel) -> String {
        assert_eq!(m.model_type.as_str(), "asmg");
        m.params.to_json()["features"].as_str().unwrap().to_owned()
    }

    #[test]
    fn entries_are_types_with_optional_labels() {
        let e = parse_model_entry(" asmg:hgcn ").unwrap();
        assert_eq!(e.model_type.as_str(), "asmg");
        assert_eq!((e.label.as_deref(), e.name()), (Some("hgcn"), "hgcn"));
        let e = parse_model_entry("rsmp").unwrap();
        assert_eq!((e.label.as_deref(), e.name()), (None, "rsmp"));
    }

    #[test]
    fn the_command_line_takes_labelled_entries() {
        use clap::Parser;

        use crate::cli::{Cli, Command};
        let argv = [
            "cohortforge",
            "bench",
            "--family",
            "lv",
            "--json",
            "out.json",
            "--models",
            "rsmp,asmg:sgcn,asmg:hgcn",
            "--params",
            r#"hgcn={"features":"hybrid"}"#,
        ];
        let Ok(Cli {
            command: Some(Command::Bench(args)),
            ..
        }) = Cli::try_parse_from(argv)
        else {
            panic!("bench arguments do not parse");
        };
        let names: Vec<&str> = args.models.iter().map(ModelEntry::name).collect();
        assert_eq!(names, ["rsmp", "sgcn", "hgcn"]);
        let models = bench_models(&args.models, &args.params).unwrap();
        assert_eq!(features(&models[2]), "hybrid");
        assert!(
            Cli::try_parse_from([
                "cohortforge",
                "bench",
                "--family",
                "lv",
                "--json",
                "o",
                "--models",
                "asmg:"
            ])
            .is_err()
        );
    }

    #[test]
    fn bad_entries_are_refused() {
        for (entry, says) in [
            ("pca", "unknown model type"),
            ("asmg:", "empty"),
            ("asmg:a b", "not ' '"),
            ("asmg:x=1", "not '='"),
            ("asmg:rsmp", "model type's name"),
        ] {
            let e = parse_model_entry(entry).unwrap_err();
            assert!(e.contains(says), "{entry}: {e}");
        }
    }

    #[test]
    fn label_params_win_over_type_params() {
        let params = [
            r#"hgcn={"features":"hybrid"}"#.to_owned(),
            r#"asmg={"features":"spatial","latent_dim":4}"#.to_owned(),
        ];
        let models = bench_models(&entries("rsmp,asmg:sgcn,asmg:hgcn,asmg"), &params).unwrap();
        let names: Vec<&str> = models.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["rsmp", "sgcn", "hgcn", "asmg"]);
        assert_eq!(
            models[0].params,
            parse_params(ModelType::parse_name("rsmp").unwrap(), None).unwrap()
        );
        assert_eq!(features(&models[1]), "spatial");
        assert_eq!(features(&models[2]), "hybrid");
        assert_eq!(features(&models[3]), "spatial");
        // The type's parameters reach labelled entries without their own, not those with.
        assert_eq!(models[1].params.to_json()["latent_dim"], 4);
        assert_eq!(models[3].params.to_json()["latent_dim"], 4);
        assert_ne!(models[2].params.to_json()["latent_dim"], 4);
    }

    #[test]
    fn duplicate_names_and_bad_keys_are_refused() {
        for (list, params, says) in [
            ("rsmp,rsmp", "", "names 'rsmp' twice"),
            ("asmg:a,rsmp:a", "", "names 'a' twice"),
            ("asmg:a", "b={}", "neither a label"),
            ("asmg:a", "a", "expected LABEL=JSON"),
            ("asmg:a", "a={}|a={}", "given twice"),
            ("asmg:a", r#"a={"features":"colour"}"#, "a: "),
            ("asmg:a", "a=not json", "a: --params"),
        ] {
            let params: Vec<String> = params
                .split('|')
                .filter(|p| !p.is_empty())
                .map(String::from)
                .collect();
            let e = bench_models(&entries(list), &params).unwrap_err();
            assert!(e.contains(says), "{list} {params:?}: {e}");
        }
    }
}
