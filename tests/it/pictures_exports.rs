//! Pictures of shapes, conditional cohorts and CSV exports, end to end on an RSMP model of
//! LV phantoms.

use std::io::Read;
use std::process::Command;

use reqwest::StatusCode;
use serde_json::{Value, json};

use crate::jobs::fitted_rsmp;
use crate::support::{TestServer, expect_json, expect_problem};

const PNG: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

async fn get(s: &TestServer, path: &str) -> (StatusCode, String, Vec<u8>) {
    let r = s.client.get(s.url(path)).send().await.unwrap();
    let status = r.status();
    let kind = r
        .headers()
        .get("content-type")
        .map_or(String::new(), |v| v.to_str().unwrap().to_owned());
    (status, kind, r.bytes().await.unwrap().to_vec())
}

async fn png(s: &TestServer, path: &str) -> Vec<u8> {
    let (status, kind, body) = get(s, path).await;
    assert_eq!(
        (status, kind.as_str()),
        (StatusCode::OK, "image/png"),
        "{path}"
    );
    assert_eq!(body[..8], PNG, "{path}");
    body
}

async fn cohort(s: &TestServer, model: &str, body: Value, status: StatusCode) -> Value {
    let url = s.url(&format!("/v1/models/{model}/cohorts"));
    let response = s.client.post(url).json(&body).send().await.unwrap();
    expect_json(response, status).await
}

/// `rows` parsed by Python's csv module, as JSON: `[{column: text}]`.
fn python_csv(text: &str) -> Option<Vec<serde_json::Map<String, Value>>> {
    let script = "import csv, json, sys; print(json.dumps(list(csv.DictReader(sys.stdin))))";
    let mut child = Command::new("python3")
        .args(["-c", script])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .ok()?;
    std::io::Write::write_all(child.stdin.as_mut()?, text.as_bytes()).ok()?;
    let out = child.wait_with_output().ok()?;
    serde_json::from_slice(&out.stdout).ok()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn column(members: &Value, name: &str) -> Vec<f64> {
    members
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["biomarkers"][name].as_f64().unwrap())
        .collect()
}

#[tokio::test]
async fn pictures_conditional_cohorts_and_tables() {
    let s = TestServer::start().await;
    let model = fitted_rsmp(&s, 16, 0.25).await;

    // Pictures: deterministic PNGs, names listed on a 404, sizes checked.
    let atlas = png(&s, &format!("/v1/models/{model}/renders/atlas")).await;
    assert_eq!(
        atlas,
        png(&s, &format!("/v1/models/{model}/renders/atlas")).await
    );
    let one = png(
        &s,
        &format!("/v1/models/{model}/renders/atlas?view=lateral&size=100"),
    )
    .await;
    assert!(one.len() < atlas.len());
    png(&s, &format!("/v1/models/{model}/renders/modes")).await;
    png(&s, &format!("/v1/models/{model}/renders/reconstruction_0")).await;
    let r = s
        .client
        .get(s.url(&format!("/v1/models/{model}/renders/atlas_7")))
        .send()
        .await
        .unwrap();
    let problem = expect_problem(r, StatusCode::NOT_FOUND, "render.not_found").await;
    let names: Vec<&str> = problem["available"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(Value::as_str)
        .collect();
    assert_eq!(
        names,
        [
            "atlas",
            "modes",
            "reconstruction_0",
            "reconstruction_1",
            "reconstruction_2",
            "reconstruction_3"
        ]
    );
    for bad in ["view=posterior", "size=10"] {
        let r = s
            .client
            .get(s.url(&format!("/v1/models/{model}/renders/atlas?{bad}")))
            .send()
            .await
            .unwrap();
        expect_problem(r, StatusCode::UNPROCESSABLE_ENTITY, "request.invalid_field").await;
    }

    // An unreachable target names the range the model reaches.
    let body = json!({"size": 20, "seed": 1, "targets": {"volume_ml": {"min": 5000, "max": 6000}}});
    let problem = cohort(&s, &model, body, StatusCode::UNPROCESSABLE_ENTITY).await;
    assert_eq!(problem["code"], "cohort.target_unreachable");
    assert_eq!(problem["field"], "targets.volume_ml");
    let (lo, hi) = (
        problem["reachable"]["min"].as_f64().unwrap(),
        problem["reachable"]["max"].as_f64().unwrap(),
    );
    assert!(lo < hi && problem["detail"].as_str().unwrap().contains("reach"));
    for bad in [
        json!({"volume": {"min": 1}}),
        json!({"volume_ml": {}}),
        json!({"volume_ml": {"mean": 100, "sd": 0}}),
        json!({"volume_ml": {"min": 9, "max": 1}}),
    ] {
        let problem = cohort(
            &s,
            &model,
            json!({"size": 5, "targets": bad}),
            StatusCode::UNPROCESSABLE_ENTITY,
        )
        .await;
        assert_eq!(problem["code"], "request.invalid_field", "{problem}");
    }

    // A volume interval in the upper part of the model's reach: met by conditioning, with
    // area following volume up as in the training population.
    let (min, max) = (lo + 0.6 * (hi - lo), lo + 0.85 * (hi - lo));
    let plain = cohort(
        &s,
        &model,
        json!({"size": 200, "seed": 4}),
        StatusCode::CREATED,
    )
    .await;
    let body = json!({"size": 200, "seed": 4, "targets": {"volume_ml": {"min": min, "max": max}}});
    let conditioned = cohort(&s, &model, body, StatusCode::CREATED).await;
    let volumes = column(&conditioned["members"], "volume_ml");
    let inside = volumes.iter().filter(|v| (min..=max).contains(*v)).count();
    assert!(
        inside as f64 >= 0.95 * 200.0,
        "{inside} of 200 inside [{min}, {max}]"
    );
    let report = &conditioned["report"]["targets"];
    assert!(
        report["draws_per_member"].as_f64().unwrap() <= 1.5,
        "{report}"
    );
    assert_eq!(report["targets"][0]["biomarker"], "volume_ml");
    assert!(
        mean(&column(&conditioned["members"], "area_cm2"))
            > mean(&column(&plain["members"], "area_cm2"))
    );
    let cohort_id = conditioned["id"].as_str().unwrap();
    let page =
        crate::reports::rendered_page(&s, &format!("/v1/cohorts/{cohort_id}/report.html")).await;
    assert!(page.contains("<h2>Targets</h2>") && page.contains("id=\"render-members\""));
    assert!(page.contains("data:image/png;base64,"));
    let page = crate::reports::rendered_page(&s, &format!("/v1/models/{model}/report.html")).await;
    for name in ["atlas", "modes", "reconstruction_0"] {
        assert!(
            page.contains(&format!("id=\"render-{name}\"")),
            "{name} missing on the model page"
        );
    }

    // Members: pictures, the CSV table against the JSON, provenance in VTK, the archive.
    png(
        &s,
        &format!("/v1/cohorts/{cohort_id}/members/3/render?view=superior"),
    )
    .await;
    let grid = png(
        &s,
        &format!("/v1/cohorts/{cohort_id}/renders/members?indices=0,5,9"),
    )
    .await;
    assert_eq!(
        grid,
        png(
            &s,
            &format!("/v1/cohorts/{cohort_id}/renders/members?indices=0,5,9")
        )
        .await
    );
    let r = s
        .client
        .get(s.url(&format!(
            "/v1/cohorts/{cohort_id}/renders/members?indices=0,999"
        )))
        .send()
        .await
        .unwrap();
    expect_problem(r, StatusCode::UNPROCESSABLE_ENTITY, "request.invalid_field").await;
    let (status, kind, body) = get(
        &s,
        &format!("/v1/cohorts/{cohort_id}/members.csv?format=vtk"),
    )
    .await;
    assert_eq!(
        (status, kind.as_str()),
        (StatusCode::OK, "text/csv; charset=utf-8")
    );
    let text = String::from_utf8(body).unwrap();
    let rows = python_csv(&text).expect("python3 parses the table");
    let members = conditioned["members"].as_array().unwrap();
    assert_eq!(rows.len(), members.len());
    for (row, m) in rows.iter().zip(members) {
        assert_eq!(row["index"], m["index"].to_string());
        let v: f64 = row["volume_ml"].as_str().unwrap().parse().unwrap();
        assert_eq!(v, m["biomarkers"]["volume_ml"].as_f64().unwrap());
        assert_eq!(row["accepted_mean"], m["accepted"]["mean"].to_string());
        assert_eq!(row["near_copy"], m["near_copy"].to_string());
        assert_eq!(
            row["nearest_training_mesh_id"],
            m["nearest_training_mesh_id"]
        );
        assert_eq!(
            row["file"],
            format!("member_{:05}.vtk", m["index"].as_u64().unwrap())
        );
    }
    let (_, _, vtk) = get(
        &s,
        &format!("/v1/cohorts/{cohort_id}/members/2/file?format=vtk"),
    )
    .await;
    let title = String::from_utf8(vtk)
        .unwrap()
        .lines()
        .nth(1)
        .unwrap()
        .to_owned();
    assert!(
        title.contains(&format!("model={model}"))
            && title.contains("seed=4")
            && title.contains("index=2"),
        "{title}"
    );
    let (_, _, zip) = get(&s, &format!("/v1/cohorts/{cohort_id}/archive?format=vtk")).await;
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(zip)).unwrap();
    let mut inner = String::new();
    archive
        .by_name("members.csv")
        .unwrap()
        .read_to_string(&mut inner)
        .unwrap();
    assert_eq!(inner, text);

    // Model tables.
    let (status, _, modes) = get(&s, &format!("/v1/models/{model}/modes.csv")).await;
    assert_eq!(status, StatusCode::OK);
    let modes = python_csv(&String::from_utf8(modes).unwrap()).unwrap();
    assert!(!modes.is_empty());
    let eigen: Vec<f64> = modes
        .iter()
        .map(|r| r["eigenvalue_mm2"].as_str().unwrap().parse().unwrap())
        .collect();
    assert!(eigen.windows(2).all(|w| w[0] >= w[1]) && eigen[0] > 0.0);
    let (_, _, training) = get(&s, &format!("/v1/models/{model}/training.csv")).await;
    let rows = python_csv(&String::from_utf8(training).unwrap()).unwrap();
    assert_eq!(rows.len(), 16);
    assert_eq!(rows.iter().filter(|r| r["role"] == "holdout").count(), 4);
    assert!(
        rows.iter()
            .filter(|r| r["role"] == "holdout")
            .all(|r| !r["generalisation_hd_mm"].as_str().unwrap().is_empty())
    );
    assert!(
        rows.iter()
            .filter(|r| r["role"] == "training")
            .all(|r| r["generalisation_hd_mm"] == "")
    );
}
