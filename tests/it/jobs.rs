//! Fit jobs end to end: submission checks, idempotency, cancellation, lease recovery, and the
//! whole product loop (phantoms → RSMP job → model → cohort → member meshes).

use std::sync::Arc;
use std::time::Duration;

use cohortforge::jobs::{WorkerPool, WorkerSettings};
use cohortforge::mesh::phantom::{self, Family};
use cohortforge::mesh::validate::{IngestOptions, ingest};
use cohortforge::mesh::{Format, io};
use reqwest::StatusCode;
use reqwest::multipart::{Form, Part};
use serde_json::{Value, json};
use tokio_util::sync::CancellationToken;

use crate::support::{TestServer, expect_json, expect_problem};

/// Cheaper registration settings for tests (the defaults are tuned for quality).
pub fn quick_params() -> Value {
    json!({"cpd_max_iterations": 40, "variance_target": 0.95})
}

pub async fn upload_phantoms(s: &TestServer, family: Family, count: usize, seed: u64) -> String {
    let dataset = s.dataset("phantoms", family.as_str()).await;
    let mut form = Form::new();
    for p in phantom::generate(family, count, seed) {
        form = form.part(
            "file",
            Part::bytes(io::write(&p.mesh, Format::Stl)).file_name(format!("{}.stl", p.name)),
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

/// Fits a quick RSMP model to `count` LV phantoms (seed 5), holding out `holdout_fraction`
/// of them, and returns the model's id.
pub async fn fitted_rsmp(s: &TestServer, count: usize, holdout_fraction: f64) -> String {
    let dataset = upload_phantoms(s, Family::Lv, count, 5).await;
    let body = json!({"dataset_id": dataset, "model_type": "rsmp", "params": quick_params(), "seed": 2, "holdout_fraction": holdout_fraction});
    let job = expect_json(submit(s, body).await, StatusCode::ACCEPTED).await;
    let done = wait_for(s, job["id"].as_str().unwrap(), Duration::from_secs(900)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    done["model_id"].as_str().unwrap().to_owned()
}

async fn submit(s: &TestServer, body: Value) -> reqwest::Response {
    s.client
        .post(s.url("/v1/jobs"))
        .json(&body)
        .send()
        .await
        .unwrap()
}

pub async fn wait_for(s: &TestServer, job: &str, timeout: Duration) -> Value {
    let started = std::time::Instant::now();
    loop {
        let body = expect_json(
            s.client
                .get(s.url(&format!("/v1/jobs/{job}")))
                .send()
                .await
                .unwrap(),
            StatusCode::OK,
        )
        .await;
        if matches!(
            body["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            return body;
        }
        assert!(
            started.elapsed() < timeout,
            "job did not finish in time: {body}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// Reads `GET /v1/jobs/{id}/events` to its end: `(event name, job record)` in order.
async fn follow_events(s: &TestServer, job: &str, timeout: Duration) -> Vec<(String, Value)> {
    let mut response = s
        .client
        .get(s.url(&format!("/v1/jobs/{job}/events")))
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    assert_eq!(response.headers()["content-type"], "text/event-stream");
    let mut text = String::new();
    let read_all = async {
        while let Some(chunk) = response.chunk().await.unwrap() {
            text.push_str(&String::from_utf8_lossy(&chunk));
        }
    };
    tokio::time::timeout(timeout, read_all)
        .await
        .expect("the event stream did not end in time");
    text.split("\n\n")
        .filter_map(|block| {
            let field = |name: &str| {
                block
                    .lines()
                    .find_map(|l| l.strip_prefix(name).map(str::trim_start))
            };
            Some((
                field("event:")?.to_owned(),
                serde_json::from_str(field("data:")?).ok()?,
            ))
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn phantoms_to_model_to_reproducible_cohort() {
    let s = TestServer::start().await;
    let dataset = upload_phantoms(&s, Family::Lv, 30, 21).await;
    let response = submit(&s, json!({"dataset_id": dataset, "model_type": "rsmp", "params": quick_params(), "seed": 3, "holdout_fraction": 0.2})).await;
    let location = response.headers()["location"].to_str().unwrap().to_owned();
    let job = expect_json(response, StatusCode::ACCEPTED).await;
    assert_eq!(
        location,
        format!("/v1/jobs/{}", job["id"].as_str().unwrap())
    );
    assert_eq!(job["status"], "queued");
    let events = follow_events(&s, job["id"].as_str().unwrap(), Duration::from_secs(900)).await;
    let (last_kind, done) = events.last().unwrap().clone();
    assert_eq!(last_kind, "end");
    assert_eq!(done["status"], "succeeded", "{done}");
    let stages: Vec<&str> = events
        .iter()
        .filter(|(kind, job)| kind == "progress" && job["status"] == "running")
        .filter_map(|(_, job)| job["progress"]["stage"].as_str())
        .collect();
    assert!(
        stages.contains(&"alignment") && stages.contains(&"evaluation"),
        "stages seen in the event stream: {stages:?}"
    );
    assert_eq!(done["progress"]["fraction"], 1.0);

    let model_id = done["model_id"].as_str().unwrap();
    let model = expect_json(
        s.client
            .get(s.url(&format!("/v1/models/{model_id}")))
            .send()
            .await
            .unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(model["model_type"], "rsmp");
    assert_eq!(
        model["provenance"]["training_mesh_ids"]
            .as_array()
            .unwrap()
            .len(),
        24
    );
    assert_eq!(
        model["provenance"]["holdout_mesh_ids"]
            .as_array()
            .unwrap()
            .len(),
        6
    );
    for metric in ["generalisation", "specificity", "matching"] {
        for d in ["hd", "ed", "ed_star"] {
            let mean = model["evaluation"][metric][d]["mean"]
                .as_f64()
                .unwrap_or(-1.0);
            assert!(mean > 0.0 && mean < 30.0, "{metric}.{d} = {mean}");
            // Point-to-surface distances never exceed vertex-to-vertex ones.
            let surface = model["evaluation"]["point_to_surface"][metric][d]["mean"]
                .as_f64()
                .unwrap_or(-1.0);
            assert!(
                surface > 0.0 && surface <= mean + 1e-9,
                "point-to-surface {metric}.{d} = {surface} against {mean}"
            );
        }
    }
    assert_eq!(model["evaluation"]["distance"], "vertex-to-vertex");
    let explained = model["explained_variance"].as_array().unwrap();
    assert!((explained.last().unwrap().as_f64().unwrap() - 1.0).abs() < 1e-9);
    // The fit's own cohort against the training meshes, with the Gaussian yardstick.
    let fidelity = &model["fidelity"];
    assert_eq!(fidelity["members"], 1000);
    let sd_ratio = fidelity["biomarkers"]["volume_ml"]["sd_ratio"]
        .as_f64()
        .unwrap();
    assert!(sd_ratio > 0.0, "{fidelity}");
    let joint = fidelity["joint_acceptance"].as_f64().unwrap();
    let gaussian = fidelity["gaussian_joint_acceptance"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&joint), "{fidelity}");
    assert!(gaussian > 0.5 && gaussian < 1.0, "{fidelity}");

    let request = json!({"size": 50, "seed": 7, "acceptance": {"criterion": "mean"}});
    let url = s.url(&format!("/v1/models/{model_id}/cohorts"));
    let cohort = expect_json(
        s.client.post(&url).json(&request).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    assert_eq!(cohort["size"], 50);
    assert_eq!(cohort["members"].as_array().unwrap().len(), 50);
    let volume = &cohort["report"]["biomarkers"]["volume_ml"];
    for key in ["mean", "sd", "mode", "min", "max"] {
        assert!(volume["reference"][key].as_f64().unwrap() > 0.0, "{volume}");
    }
    for rate in ["range", "mode", "mean"] {
        let a = cohort["report"]["acceptance"][rate].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&a));
    }
    assert!(cohort["report"]["biomarkers"]["sphericity"].is_object());
    assert!(cohort["members"][0]["accepted"]["mean"].is_boolean());
    assert!(
        cohort["report"]["privacy"]["threshold_mm"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    // 24 training meshes: each one's distance to its nearest other.
    assert_eq!(
        cohort["report"]["privacy"]["threshold_basis"],
        "nearest_training_shape"
    );
    for m in cohort["members"].as_array().unwrap() {
        assert!(m["nearest_training_mm"].as_f64().unwrap() > 0.0);
        assert!(m["near_copy"].is_boolean());
        let nearest = m["nearest_training_mesh_id"].as_str().unwrap();
        assert!(
            model["provenance"]["training_mesh_ids"]
                .as_array()
                .unwrap()
                .iter()
                .any(|id| id == nearest)
        );
    }
    let filtered = json!({"size": 20, "seed": 7, "only_accepted": true, "exclude_near_copies": true, "acceptance": {"criterion": "range"}});
    let strict = expect_json(
        s.client.post(&url).json(&filtered).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    for m in strict["members"].as_array().unwrap() {
        assert_eq!(m["accepted"]["range"], true);
        assert_eq!(m["near_copy"], false);
    }
    assert_eq!(strict["report"]["acceptance"]["range"], 1.0);

    // Report pages: one violin per biomarker for the cohort; generalisation, specificity,
    // matching and cumulative explained variance for the model.
    let biomarkers = cohort["report"]["biomarkers"].as_object().unwrap().len();
    let cohort_page = format!("/v1/cohorts/{}/report.html", cohort["id"].as_str().unwrap());
    assert_eq!(
        crate::reports::plots_on_page(&s, &cohort_page).await,
        biomarkers
    );
    let model_page = format!("/v1/models/{model_id}/report.html");
    assert_eq!(crate::reports::plots_on_page(&s, &model_page).await, 4);
    // Each plot alone, as SVG and PNG, and the errors of the plot URLs.
    crate::reports::check_single_plot(&s, &cohort_page, "volume_ml").await;
    crate::reports::check_single_plot(&s, &model_page, "explained_variance").await;
    crate::reports::check_plot_errors(&s, &cohort_page, "volume_ml", None).await;
    let closed_form = Some("loss_graph_vae");
    crate::reports::check_plot_errors(&s, &model_page, "specificity", closed_form).await;

    let member = |cohort: &Value| {
        s.url(&format!(
            "/v1/cohorts/{}/members/3/file?format=obj",
            cohort["id"].as_str().unwrap()
        ))
    };
    let bytes = s.get_bytes(member(&cohort)).await;
    let parsed = ingest(&bytes, Format::Obj, &IngestOptions::default()).unwrap();
    assert!(parsed.summary.watertight);
    assert!(parsed.summary.volume_ml > 0.0);

    let again = expect_json(
        s.client.post(&url).json(&request).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    assert_ne!(again["id"], cohort["id"]);
    let bytes_again = s.get_bytes(member(&again)).await;
    assert_eq!(
        bytes, bytes_again,
        "the same request must give the same member file"
    );
    let archive = |c: &Value| {
        s.url(&format!(
            "/v1/cohorts/{}/archive?format=stl",
            c["id"].as_str().unwrap()
        ))
    };
    let a = s.get_bytes(archive(&cohort)).await;
    let b = s.get_bytes(archive(&again)).await;
    assert_eq!(a, b, "archives of identical cohorts must be identical");
    assert!(a.len() > 1000 && &a[..2] == b"PK");
}

#[tokio::test]
async fn invalid_submissions_name_the_field() {
    let s = TestServer::start_with(|c| c.workers = 0).await;
    let dataset = upload_phantoms(&s, Family::Liver, 4, 1).await;
    let cases = [
        (
            json!({"dataset_id": dataset, "model_type": "magic"}),
            "model_type",
        ),
        (
            json!({"dataset_id": dataset, "model_type": "rsmp", "params": {"n_modes": 0}}),
            "params.n_modes",
        ),
        (
            json!({"dataset_id": dataset, "model_type": "rsmp", "params": {"colour": 1}}),
            "params.colour",
        ),
        (
            json!({"dataset_id": dataset, "model_type": "rsmp", "holdout_fraction": 0.95}),
            "holdout_fraction",
        ),
        (
            json!({"dataset_id": "nope", "model_type": "rsmp"}),
            "dataset_id",
        ),
        (
            json!({"dataset_id": dataset, "model_type": "rsmp", "params": {"template": "nope"}}),
            "params.template",
        ),
    ];
    for (body, field) in cases {
        let problem = expect_problem(
            submit(&s, body).await,
            StatusCode::UNPROCESSABLE_ENTITY,
            "request.invalid_field",
        )
        .await;
        assert_eq!(problem["field"], field, "{problem}");
    }
    let few = submit(
        &s,
        json!({"dataset_id": dataset, "model_type": "rsmp", "holdout_fraction": 0.5}),
    )
    .await;
    expect_problem(
        few,
        StatusCode::UNPROCESSABLE_ENTITY,
        "model.too_few_meshes",
    )
    .await;
    let (jobs, total) = s
        .store
        .jobs(
            None,
            None,
            cohortforge::store::Page {
                limit: 10,
                offset: 0,
            },
        )
        .await
        .unwrap();
    assert!(
        jobs.is_empty() && total == 0,
        "a refused submission stored a job"
    );
}

#[tokio::test]
async fn idempotent_submission_and_cancellation() {
    let s = TestServer::start_with(|c| c.workers = 0).await;
    let dataset = upload_phantoms(&s, Family::Liver, 4, 2).await;
    let body = json!({"dataset_id": dataset, "model_type": "rsmp", "holdout_fraction": 0.0});
    let post = |body: &Value, key: &str| {
        s.client
            .post(s.url("/v1/jobs"))
            .header("idempotency-key", key)
            .json(body)
            .send()
    };
    let first = expect_json(post(&body, "k-1").await.unwrap(), StatusCode::ACCEPTED).await;
    let retry = expect_json(post(&body, "k-1").await.unwrap(), StatusCode::ACCEPTED).await;
    assert_eq!(first["id"], retry["id"]);
    let other =
        json!({"dataset_id": dataset, "model_type": "rsmp", "seed": 9, "holdout_fraction": 0.0});
    let conflict = expect_problem(
        post(&other, "k-1").await.unwrap(),
        StatusCode::CONFLICT,
        "job.idempotency_conflict",
    )
    .await;
    assert_eq!(conflict["existing_job_id"], first["id"]);

    let id = first["id"].as_str().unwrap();
    let listed = expect_json(
        s.client
            .get(s.url("/v1/jobs?status=queued"))
            .send()
            .await
            .unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(listed["total"], 1);
    let cancel = s
        .client
        .post(s.url(&format!("/v1/jobs/{id}/cancel")))
        .send()
        .await
        .unwrap();
    assert_eq!(
        expect_json(cancel, StatusCode::ACCEPTED).await["status"],
        "cancelled"
    );
    let again = s
        .client
        .post(s.url(&format!("/v1/jobs/{id}/cancel")))
        .send()
        .await
        .unwrap();
    expect_problem(again, StatusCode::CONFLICT, "job.already_finished").await;
    let missing = s.client.get(s.url("/v1/jobs/nope")).send().await.unwrap();
    expect_problem(missing, StatusCode::NOT_FOUND, "job.not_found").await;
    // The event stream of an ended job is its final record, then the end.
    let events = follow_events(&s, id, Duration::from_secs(10)).await;
    assert_eq!(events.len(), 1, "{events:?}");
    assert_eq!(events[0].0, "end");
    assert_eq!(events[0].1["status"], "cancelled");
    let missing = s
        .client
        .get(s.url("/v1/jobs/nope/events"))
        .send()
        .await
        .unwrap();
    expect_problem(missing, StatusCode::NOT_FOUND, "job.not_found").await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_whose_worker_died_is_requeued_and_finishes() {
    let s = TestServer::start_with(|c| c.workers = 0).await;
    let dataset = upload_phantoms(&s, Family::Liver, 5, 3).await;
    let body = json!({"dataset_id": dataset, "model_type": "rsmp", "params": quick_params(), "holdout_fraction": 0.0});
    let job = expect_json(submit(&s, body).await, StatusCode::ACCEPTED).await;
    let id = job["id"].as_str().unwrap();
    // A worker of a process that then died: it claimed the job and never renewed its lease.
    let claimed = s
        .store
        .claim_job("dead-worker", 60_000)
        .await
        .unwrap()
        .expect("claimed");
    assert_eq!(claimed.id, id);
    s.store.expire_lease(id).await.unwrap();

    let shutdown = CancellationToken::new();
    let pool = WorkerPool::start(
        s.store.clone(),
        1,
        tokio::runtime::Handle::current(),
        Arc::new(tokio::sync::Notify::new()),
        shutdown.clone(),
        WorkerSettings::default(),
    )
    .unwrap();
    let done = wait_for(&s, id, Duration::from_secs(600)).await;
    shutdown.cancel();
    tokio::task::spawn_blocking(move || pool.join())
        .await
        .unwrap();
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["attempts"], 2);
}
