//! The offline commands end to end: `phantoms`, then `fit` on the files, then `evaluate`
//! on unseen phantoms, through the real binary.

use std::path::Path;
use std::process::{Command, Output};

use serde_json::Value;

fn cohortforge(args: &[&str]) -> Output {
    let output = Command::new(env!("CARGO_BIN_EXE_cohortforge"))
        .args(args)
        .env("COHORTFORGE_LOG", "warn")
        .output()
        .expect("the binary runs");
    assert!(
        output.status.success(),
        "cohortforge {args:?} failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    output
}

fn path(p: &Path) -> &str {
    p.to_str().expect("utf-8 temporary path")
}

fn mean_of(v: &Value) -> f64 {
    v["mean"].as_f64().expect("a mean")
}

#[test]
fn phantoms_fit_and_evaluate() {
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = (dir.path().join("train"), dir.path().join("test"));
    let (model, json) = (dir.path().join("lv.cfmodel"), dir.path().join("eval.json"));
    cohortforge(&[
        "phantoms",
        "--family",
        "lv",
        "--count",
        "12",
        "--seed",
        "3",
        "--out",
        path(&train),
    ]);
    cohortforge(&[
        "phantoms",
        "--family",
        "lv",
        "--count",
        "3",
        "--seed",
        "4",
        "--format",
        "stl",
        "--out",
        path(&test),
    ]);

    let params = r#"{"cpd_max_iterations": 40, "variance_target": 0.95}"#;
    let fit = cohortforge(&[
        "fit",
        "--train",
        path(&train),
        "--model",
        "rsmp",
        "--params",
        params,
        "--holdout-fraction",
        "0.25",
        "--seed",
        "1",
        "--out",
        path(&model),
    ]);
    let stdout = String::from_utf8_lossy(&fit.stdout);
    assert!(stdout.contains("| HD | vertex-to-vertex |"), "{stdout}");
    assert!(String::from_utf8_lossy(&fit.stderr).contains("alignment"));

    let evaluate = cohortforge(&[
        "evaluate",
        "--model",
        path(&model),
        "--test",
        path(&test),
        "--samples",
        "20",
        "--json",
        path(&json),
    ]);
    let stdout = String::from_utf8_lossy(&evaluate.stdout);
    assert!(stdout.contains("A^μ"), "{stdout}");
    let report: Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(report["model_type"], "rsmp");
    assert_eq!(report["params"]["cpd_max_iterations"], 40);
    assert_eq!(report["training_count"], 9);
    assert_eq!(report["samples"], 20);
    assert_eq!(report["seed"], 1);
    assert_eq!(report["test_meshes"].as_array().unwrap().len(), 3);
    let evaluation = &report["evaluation"];
    let generalisation = mean_of(&evaluation["generalisation"]["hd"]);
    assert!(
        generalisation > 0.0 && generalisation < 20.0,
        "{generalisation}"
    );
    assert!(mean_of(&evaluation["matching"]["cd"]) > 0.0);
    assert_eq!(
        evaluation["per_item"]["specificity"]
            .as_array()
            .unwrap()
            .len(),
        20
    );
    let surface = &evaluation["point_to_surface"];
    // A vertex's closest point on a surface is never farther than its closest vertex.
    assert!(mean_of(&surface["specificity"]["ed"]) <= mean_of(&evaluation["specificity"]["ed"]));
    let volume = &report["cohort"]["biomarkers"]["volume_ml"];
    assert_eq!(volume["synthetic"]["n"], 20);
    let mean_rate = report["cohort"]["acceptance"]["mean"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&mean_rate));
    let stages: Vec<&str> = report["timings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        stages,
        [
            "load_model",
            "read_test_meshes",
            "evaluation",
            "cohort",
            "total"
        ]
    );
}

#[test]
fn a_file_that_is_not_a_model_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("fake.cfmodel");
    std::fs::write(&fake, b"solid nothing").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_cohortforge"))
        .args([
            "evaluate",
            "--model",
            path(&fake),
            "--test",
            path(dir.path()),
            "--json",
        ])
        .arg(dir.path().join("out.json"))
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("not a cohortforge model file"), "{stderr}");
}

#[test]
fn a_laterality_file_naming_no_mesh_file_is_refused_before_fitting() {
    let dir = tempfile::tempdir().unwrap();
    let train = dir.path().join("train");
    cohortforge(&[
        "phantoms",
        "--family",
        "lv",
        "--count",
        "4",
        "--seed",
        "1",
        "--out",
        path(&train),
    ]);
    let sides = dir.path().join("sides.csv");
    std::fs::write(&sides, "mesh,laterality\nlv_000,left\nlv_0001.obj,right\n").unwrap();
    let output = Command::new(env!("CARGO_BIN_EXE_cohortforge"))
        .args([
            "fit",
            "--train",
            path(&train),
            "--model",
            "rsmp",
            "--laterality",
        ])
        .args([path(&sides), "--out", path(&dir.path().join("m.cfmodel"))])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("the laterality file names lv_0001.obj, which is not a mesh file here"),
        "{stderr}"
    );
}

#[test]
fn a_database_that_cannot_be_opened_is_refused_with_what_to_give() {
    let run = |database: &str| {
        let output = Command::new(env!("CARGO_BIN_EXE_cohortforge"))
            .args(["worker", "--bind", "127.0.0.1:0", "--database", database])
            .output()
            .unwrap();
        assert!(!output.status.success(), "{database} was accepted");
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let stderr = run("mysql://user@db.example/cohorts");
    assert!(
        stderr.contains("sqlite://FILE") && stderr.contains("postgres://"),
        "{stderr}"
    );
    // A PostgreSQL server that does not answer (a closed loopback port): the error names
    // the database without its password.
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .unwrap()
        .port();
    let stderr = run(&format!(
        "postgres://cf:hunter2secret@127.0.0.1:{port}/cohorts?connect_timeout=2"
    ));
    assert!(
        stderr.contains("cannot open database postgres://cf:***@127.0.0.1"),
        "{stderr}"
    );
    assert!(!stderr.contains("hunter2secret"), "{stderr}");
}
