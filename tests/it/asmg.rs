//! The `asmg` model type end to end: tiny LV phantoms → asmg job → model with an atlas →
//! cohort → member meshes with the atlas connectivity.

use std::time::Duration;

use cohortforge::mesh::laterality::mirror_image;
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::mesh::simplify::simplify;
use cohortforge::mesh::validate::{IngestOptions, ingest};
use cohortforge::mesh::{Format, io};
use reqwest::StatusCode;
use reqwest::multipart::{Form, Part};
use serde_json::{Value, json};

use crate::support::{TestServer, expect_json, expect_problem};

/// Vertices of each uploaded phantom.
const PHANTOM_VERTICES: usize = 300;
/// Requested atlas resolution.
const ATLAS_VERTICES: usize = 200;

/// Few epochs and cheap registration: the test checks the plumbing, not the quality.
pub(crate) fn tiny_params() -> Value {
    json!({
        "features": "hybrid",
        "atlas_vertices": ATLAS_VERTICES,
        "max_vertices": 400,
        "epochs_graph": 2,
        "epochs_vae": 20,
        "cpd_max_iterations": 30,
        "max_em_steps": 3
    })
}

pub(crate) async fn upload_small_phantoms(s: &TestServer, count: usize, seed: u64) -> String {
    upload_phantoms(s, Family::Lv, count, seed).await
}

/// Uploads `count` phantoms of `family`, each simplified to a few hundred vertices.
pub(crate) async fn upload_phantoms(
    s: &TestServer,
    family: Family,
    count: usize,
    seed: u64,
) -> String {
    let dataset = s.dataset("tiny phantoms", family.as_str()).await;
    let mut form = Form::new();
    for p in phantom::generate(family, count, seed) {
        let small = simplify(&p.mesh, PHANTOM_VERTICES).unwrap().mesh;
        form = form.part(
            "file",
            Part::bytes(io::write(&small, Format::Stl)).file_name(format!("{}.stl", p.name)),
        );
    }
    let url = s.url(&format!("/v1/datasets/{dataset}/meshes"));
    expect_json(
        s.client.post(url).multipart(form).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    dataset
}

/// Submits a job; answers the 202 body.
pub(crate) async fn submit(s: &TestServer, body: &Value) -> Value {
    expect_json(
        s.client
            .post(s.url("/v1/jobs"))
            .json(body)
            .send()
            .await
            .unwrap(),
        StatusCode::ACCEPTED,
    )
    .await
}

pub(crate) async fn get(s: &TestServer, path: &str) -> Value {
    expect_json(
        s.client.get(s.url(path)).send().await.unwrap(),
        StatusCode::OK,
    )
    .await
}

pub(crate) async fn wait_for(s: &TestServer, job: &str, timeout: Duration) -> (Value, Vec<Value>) {
    let started = std::time::Instant::now();
    let mut seen = Vec::new();
    loop {
        let body = get(s, &format!("/v1/jobs/{job}")).await;
        if body["status"] == "running" {
            seen.push(body["progress"].clone());
        }
        if matches!(
            body["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            return (body, seen);
        }
        assert!(
            started.elapsed() < timeout,
            "job did not finish in time: {body}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tiny_phantoms_to_asmg_model_to_cohort() {
    let s = TestServer::start().await;
    let dataset = upload_small_phantoms(&s, 12, 5).await;
    let body = json!({"dataset_id": dataset, "model_type": "asmg", "params": tiny_params(), "seed": 2, "holdout_fraction": 0.2});
    let job = submit(&s, &body).await;
    let (done, seen) = wait_for(&s, job["id"].as_str().unwrap(), Duration::from_secs(300)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let losses: Vec<f64> = seen
        .iter()
        .filter(|p| p["stage"] == "graph_vae" || p["stage"] == "generator")
        .filter_map(|p| p["loss"].as_f64())
        .collect();
    assert!(
        losses.iter().all(|l| l.is_finite()),
        "losses seen: {losses:?}"
    );

    let model_id = done["model_id"].as_str().unwrap();
    let model = get(&s, &format!("/v1/models/{model_id}")).await;
    assert_eq!(model["model_type"], "asmg");
    assert_eq!(model["params"]["features"], "hybrid");
    assert_eq!(model["params"]["gamma"], 0.1);
    assert_eq!(model["params"]["calibrate_spread"], true);
    let atlas_vertices = model["atlas"]["vertex_count"].as_u64().unwrap() as usize;
    assert!(
        (100..=ATLAS_VERTICES + ATLAS_VERTICES / 4).contains(&atlas_vertices),
        "atlas of {atlas_vertices} vertices"
    );
    for metric in ["generalisation", "specificity", "matching"] {
        let hd = model["evaluation"][metric]["hd"]["mean"]
            .as_f64()
            .unwrap_or(-1.0);
        assert!(hd > 0.0 && hd < 100.0, "{metric} HD = {hd}");
    }
    // The report page: three distance distributions and the two networks' loss curves.
    let page = format!("/v1/models/{model_id}/report.html");
    assert_eq!(crate::reports::plots_on_page(&s, &page).await, 5);
    crate::reports::check_single_plot(&s, &page, "loss_graph_vae").await;
    let no_pca = Some("explained_variance");
    crate::reports::check_plot_errors(&s, &page, "loss_beta_vae", no_pca).await;

    let url = s.url(&format!("/v1/models/{model_id}/cohorts"));
    // Fitted without sides, the model cannot serve members of a given side.
    let sided = json!({"size": 6, "seed": 3, "laterality": "left"});
    let refused = s.client.post(&url).json(&sided).send().await.unwrap();
    let problem = expect_problem(
        refused,
        StatusCode::UNPROCESSABLE_ENTITY,
        "cohort.laterality_unknown",
    )
    .await;
    assert_eq!(problem["field"], "laterality");
    let request = json!({"size": 6, "seed": 3});
    let cohort = expect_json(
        s.client.post(&url).json(&request).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    assert_eq!(cohort["members"].as_array().unwrap().len(), 6);
    let cohort_id = cohort["id"].as_str().unwrap();
    for index in [0, 5] {
        let bytes = s
            .get_bytes(s.url(&format!(
                "/v1/cohorts/{cohort_id}/members/{index}/file?format=obj"
            )))
            .await;
        let member = io::read(&bytes, Format::Obj, &Default::default()).unwrap();
        assert_eq!(member.vertex_count(), atlas_vertices);
        let parsed = ingest(&bytes, Format::Obj, &IngestOptions::default()).unwrap();
        assert!(parsed.summary.vertex_count <= atlas_vertices);
    }
    let again = expect_json(
        s.client.post(&url).json(&request).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    assert_eq!(
        cohort["members"][2]["biomarkers"], again["members"][2]["biomarkers"],
        "the same seed must give the same cohort"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn asmg_params_are_checked_at_submission() {
    let s = TestServer::start().await;
    let dataset = upload_small_phantoms(&s, 4, 1).await;
    for (params, field) in [
        (json!({"latent_dim": 0}), "latent_dim"),
        (json!({"features": "colour"}), "features"),
        (json!({"epoch": 3}), "epoch"),
        (json!({"atlas": "no-such-mesh"}), "atlas"),
    ] {
        let body = json!({"dataset_id": dataset, "model_type": "asmg", "params": params});
        let response = s
            .client
            .post(s.url("/v1/jobs"))
            .json(&body)
            .send()
            .await
            .unwrap();
        let problem = expect_problem(
            response,
            StatusCode::UNPROCESSABLE_ENTITY,
            "request.invalid_field",
        )
        .await;
        assert_eq!(problem["field"], format!("params.{field}"), "{problem}");
    }
}

/// Uploads `meshes` in one multipart request with `?laterality=side`; their ids.
async fn upload_sided(
    s: &TestServer,
    dataset: &str,
    meshes: &[(String, Vec<u8>)],
    side: &str,
) -> Vec<String> {
    let mut form = Form::new();
    for (name, bytes) in meshes {
        form = form.part("file", Part::bytes(bytes.clone()).file_name(name.clone()));
    }
    let url = s.url(&format!("/v1/datasets/{dataset}/meshes?laterality={side}"));
    let body = expect_json(
        s.client.post(url).multipart(form).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    body["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| {
            assert_eq!(m["laterality"], side);
            m["id"].as_str().unwrap().to_owned()
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn with_mirror_the_given_sides_decide_which_meshes_are_mirrored() {
    let s = TestServer::start().await;
    let dataset = s.dataset("paired", "kidney").await;
    // Half the phantoms as they are ("left"), half as mirror images ("right").
    let files: Vec<(String, Vec<u8>, bool)> = phantom::generate(Family::Lv, 8, 6)
        .into_iter()
        .enumerate()
        .map(|(k, p)| {
            let small = simplify(&p.mesh, PHANTOM_VERTICES).unwrap().mesh;
            let right = k % 2 == 1;
            let small = if right { mirror_image(&small) } else { small };
            (
                format!("{}.stl", p.name),
                io::write(&small, Format::Stl),
                right,
            )
        })
        .collect();
    let of_side = |right: bool| -> Vec<(String, Vec<u8>)> {
        files
            .iter()
            .filter(|f| f.2 == right)
            .map(|f| (f.0.clone(), f.1.clone()))
            .collect()
    };
    let left = upload_sided(&s, &dataset, &of_side(false), "left").await;
    let right = upload_sided(&s, &dataset, &of_side(true), "right").await;
    let mut params = tiny_params();
    params["mirror"] = json!(true);
    let body = json!({"dataset_id": dataset, "model_type": "asmg", "params": params, "seed": 1, "holdout_fraction": 0.25});
    let job = submit(&s, &body).await;
    let (done, _) = wait_for(&s, job["id"].as_str().unwrap(), Duration::from_secs(300)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    let model = get(
        &s,
        &format!("/v1/models/{}", done["model_id"].as_str().unwrap()),
    )
    .await;
    let side = model["laterality"].as_str().expect("the model's side");
    let other = if side == "left" { &right } else { &left };
    let training: Vec<&str> = model["provenance"]["training_mesh_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    // The provenance keeps the side each training mesh was fitted with.
    let sides = model["provenance"]["training_laterality"]
        .as_array()
        .unwrap();
    for (id, given) in training.iter().zip(sides) {
        let uploaded = if left.iter().any(|l| l == id) {
            "left"
        } else {
            "right"
        };
        assert_eq!(given, uploaded);
    }
    let mut expected: Vec<&str> = training
        .iter()
        .copied()
        .filter(|id| other.iter().any(|o| o == id))
        .collect();
    let mut mirrored: Vec<&str> = model["mirrored_mesh_ids"]
        .as_array()
        .map(|a| a.iter().map(|v| v.as_str().unwrap()).collect())
        .unwrap_or_default();
    expected.sort_unstable();
    mirrored.sort_unstable();
    assert!(!expected.is_empty());
    assert_eq!(mirrored, expected);

    // A cohort of the other side is the same cohort mirrored: x negated, biomarkers equal.
    let url = s.url(&format!(
        "/v1/models/{}/cohorts",
        model["id"].as_str().unwrap()
    ));
    let other_side = if side == "left" { "right" } else { "left" };
    let mut members = Vec::new();
    for asked in [side, other_side] {
        let request = json!({"size": 2, "seed": 4, "laterality": asked});
        let cohort = expect_json(
            s.client.post(&url).json(&request).send().await.unwrap(),
            StatusCode::CREATED,
        )
        .await;
        let id = cohort["id"].as_str().unwrap();
        let file = s.url(&format!("/v1/cohorts/{id}/members/1/file?format=obj"));
        let bytes = s.get_bytes(file).await;
        let mesh = io::read(&bytes, Format::Obj, &Default::default()).unwrap();
        members.push((cohort["members"][1]["biomarkers"].clone(), mesh));
        // The report page says which side the members are and whether they are mirrored.
        let page = s
            .get_bytes(s.url(&format!("/v1/cohorts/{id}/report.html")))
            .await;
        let page = String::from_utf8_lossy(&page);
        let expected = match asked == side {
            true => format!("Every member is a {side} organ, the side of the model's shapes."),
            false => format!(
                "Every member is a {asked} organ, served as mirror images of the model's {side} shapes."
            ),
        };
        assert!(page.contains(&expected), "{expected}");
    }
    let ((as_drawn_biomarkers, as_drawn), (mirrored_biomarkers, mirrored)) =
        (&members[0], &members[1]);
    assert_eq!(as_drawn_biomarkers, mirrored_biomarkers);
    assert_eq!(as_drawn.vertex_count(), mirrored.vertex_count());
    for (a, b) in as_drawn.vertices.iter().zip(&mirrored.vertices) {
        assert!(
            (a[0] + b[0]).abs() < 1e-4 && (a[1] - b[1]).abs() < 1e-4,
            "{a:?} {b:?}"
        );
    }
    assert!(as_drawn.vertices.iter().any(|p| p[0].abs() > 1.0));
}
