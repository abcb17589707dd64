//! The layer rule of SPEC §4: pure modules import no async, SQL or HTTP crates, and no
//! module reaches up to a layer above it.

use std::path::Path;

use crate::support::crate_dir;

/// Modules that must stay free of I/O frameworks.
const PURE: [&str; 7] = [
    "mesh",
    "geometry",
    "segmentation",
    "nn",
    "eval",
    "models",
    "report",
];
/// Crates a pure module must not use.
const FORBIDDEN_CRATES: [&str; 5] = ["axum", "sqlx", "tokio", "tower", "reqwest"];
/// Layers from top to bottom; a module may use only modules after it.
const LAYERS: [&[&str]; 8] = [
    &["api"],
    &["jobs"],
    &["telemetry"],
    &["report"],
    &["store", "models"],
    &["nn", "eval"],
    &["geometry", "segmentation"],
    &["mesh"],
];

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

fn module_sources(module: &str) -> Vec<(String, String)> {
    let src = crate_dir().join("src");
    let mut files = Vec::new();
    rust_files(&src.join(module), &mut files);
    let single = src.join(format!("{module}.rs"));
    if single.exists() {
        files.push(single);
    }
    files
        .into_iter()
        .map(|p| {
            (
                p.display().to_string(),
                std::fs::read_to_string(&p).expect("readable"),
            )
        })
        .collect()
}

fn uses(source: &str, path_prefix: &str) -> bool {
    source.lines().any(|line| {
        let line = line.trim_start();
        !line.starts_with("//") && line.contains(path_prefix)
    })
}

#[test]
fn pure_modules_do_not_use_io_frameworks() {
    let mut offences = Vec::new();
    for module in PURE {
        for (file, source) in module_sources(module) {
            for krate in FORBIDDEN_CRATES {
                if uses(&source, &format!("{krate}::")) {
                    offences.push(format!("{file} uses {krate}"));
                }
            }
        }
    }
    assert!(
        offences.is_empty(),
        "pure modules must not do I/O: {offences:#?}"
    );
}

#[test]
fn modules_only_use_layers_below_them() {
    let mut offences = Vec::new();
    for (rank, layer) in LAYERS.iter().enumerate() {
        let above: Vec<&str> = LAYERS[..rank]
            .iter()
            .flat_map(|l| l.iter().copied())
            .collect();
        for module in *layer {
            for (file, source) in module_sources(module) {
                for upper in &above {
                    if uses(&source, &format!("crate::{upper}::")) {
                        offences.push(format!("{file} ({module}) uses {upper}, a layer above"));
                    }
                }
            }
        }
    }
    assert!(
        offences.is_empty(),
        "dependencies must point down: {offences:#?}"
    );
}

#[test]
fn the_check_sees_an_offence() {
    assert!(uses("use sqlx::SqlitePool;", "sqlx::"));
    assert!(!uses("// sqlx::is mentioned in a comment", "sqlx::"));
}

/// Layers above `models` that must reach model types only through its registry.
const ABOVE_MODELS: [&str; 5] = ["api", "jobs", "cli", "store", "report"];

#[test]
fn nothing_above_models_names_a_model_type() {
    let mut offences = Vec::new();
    for module in ABOVE_MODELS {
        for (file, source) in module_sources(module) {
            for path in [
                "models::rsmp",
                "models::asmg",
                "models::atlas_r_asmg",
                "models::matlas_r_asmg",
            ] {
                if uses(&source, path) {
                    offences.push(format!("{file} uses {path}"));
                }
            }
        }
    }
    assert!(
        offences.is_empty(),
        "model types are reached through models::registry: {offences:#?}"
    );
}
