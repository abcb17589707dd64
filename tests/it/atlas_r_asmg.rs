//! The `atlas-r-asmg` model type end to end: tiny LV phantoms → refined model → atlases
//! listed and downloaded → cohort whose members carry their cluster.

use std::time::Duration;

use cohortforge::mesh::{Format, io};
use reqwest::StatusCode;
use serde_json::json;

use crate::asmg::{get, submit, tiny_params, upload_small_phantoms, wait_for};
use crate::support::{TestServer, expect_json, expect_problem};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tiny_phantoms_to_refined_model_atlases_and_clustered_cohort() {
    let s = TestServer::start().await;
    let dataset = upload_small_phantoms(&s, 10, 8).await;
    let mut params = tiny_params();
    params["epochs_refine"] = json!(2);
    params["w_lap"] = json!(1.2);
    let body =
        json!({"dataset_id": dataset, "model_type": "atlas-r-asmg", "params": params, "seed": 4});
    let job = submit(&s, &body).await;
    let (done, seen) = wait_for(&s, job["id"].as_str().unwrap(), Duration::from_secs(400)).await;
    assert_eq!(done["status"], "succeeded", "{done}");
    // Polling may miss a short stage (the stored timings below show the refinement ran);
    // what a dashboard sees must only move forward.
    let fractions: Vec<f64> = seen.iter().filter_map(|p| p["fraction"].as_f64()).collect();
    assert!(!fractions.is_empty(), "no progress seen");
    assert!(
        fractions.windows(2).all(|w| w[0] <= w[1]),
        "progress went back: {fractions:?}"
    );

    let model_id = done["model_id"].as_str().unwrap();
    let model = get(&s, &format!("/v1/models/{model_id}")).await;
    assert_eq!(model["model_type"], "atlas-r-asmg");
    assert_eq!(model["params"]["w_lap"], 1.2);
    assert_eq!(model["params"]["epochs_refine"], 2);
    assert_eq!(model["params"]["features"], "hybrid");
    let timings: Vec<&str> = model["timings"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|t| t["stage"].as_str())
        .collect();
    assert!(timings.contains(&"refinement"), "{timings:?}");
    let clusters = &model["clusters"];
    assert_eq!(clusters["atlases"].as_array().unwrap().len(), 1);
    assert_eq!(clusters["atlases"][0]["prior"], 1.0);
    let assignments = clusters["assignments"].as_array().unwrap();
    assert_eq!(assignments.len(), 10, "every training and held-out mesh");
    assert!(
        assignments
            .iter()
            .all(|a| a["cluster"] == 0 && a["weights"] == json!([1.0]))
    );
    // The refinement's loss terms per epoch, each a plot of the report page.
    let page = format!("/v1/models/{model_id}/report.html");
    for term in ["refinement", "refinement_chamfer", "refinement_laplacian"] {
        crate::reports::check_single_plot(&s, &page, &format!("loss_{term}")).await;
    }

    // The atlases: one, listed, downloadable by index and as /atlas.
    let atlases = get(&s, &format!("/v1/models/{model_id}/atlases")).await;
    let atlases = atlases.as_array().unwrap();
    assert_eq!(atlases.len(), 1);
    assert_eq!(model["atlases"].as_array().unwrap().len(), 1);
    let vertex_count = atlases[0]["vertex_count"].as_u64().unwrap() as usize;
    assert_eq!(atlases[0]["euler_characteristic"], 2);
    let download = |path: String| {
        let url = s.url(&path);
        let client = s.client.clone();
        async move { client.get(url).send().await.unwrap() }
    };
    let first = download(format!("/v1/models/{model_id}/atlases/0?format=obj")).await;
    assert_eq!(first.status(), StatusCode::OK);
    let first = first.bytes().await.unwrap();
    let legacy = download(format!("/v1/models/{model_id}/atlas?format=obj"))
        .await
        .bytes()
        .await
        .unwrap();
    assert_eq!(first, legacy, "/atlas is atlas 0");
    let mesh = io::read(&first, Format::Obj, &Default::default()).unwrap();
    assert_eq!(mesh.vertex_count(), vertex_count);
    let missing = download(format!("/v1/models/{model_id}/atlases/1")).await;
    let problem = expect_problem(missing, StatusCode::NOT_FOUND, "atlas.not_found").await;
    assert!(problem["detail"].as_str().unwrap().contains("1 atlas"));

    // A cohort: every member in cluster 0, one cluster row holding them all.
    let url_of_cohorts = s.url(&format!("/v1/models/{model_id}/cohorts"));
    let cohort = expect_json(
        s.client
            .post(&url_of_cohorts)
            .json(&json!({"size": 5, "seed": 1}))
            .send()
            .await
            .unwrap(),
        StatusCode::CREATED,
    )
    .await;
    let members = cohort["members"].as_array().unwrap();
    assert!(members.iter().all(|m| m["cluster"] == 0), "{members:?}");
    let clusters = cohort["report"]["clusters"].as_array().unwrap();
    assert_eq!(clusters.len(), 1);
    assert_eq!(clusters[0]["count"], 5);
    assert_eq!(clusters[0]["share"], 1.0);
    assert!(
        clusters[0]["biomarkers"]["volume_ml"]["mean"]
            .as_f64()
            .unwrap()
            > 0.0
    );
    let cohort_id = cohort["id"].as_str().unwrap();
    let page = s
        .client
        .get(s.url(&format!("/v1/cohorts/{cohort_id}/report.html")))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(page.contains("<h2>Clusters</h2>") && page.contains("every member is in cluster 0"));

    // A model stored in a format this release does not read (here: unversioned, as before
    // format 2) is a clear 409, not a 500; its record still reads.
    let pool = s.database_pool().await;
    sqlx::query("UPDATE models SET payload = $1 WHERE id = $2")
        .bind(vec![0u8, 1, 2, 3])
        .bind(model_id)
        .execute(&pool)
        .await
        .unwrap();
    pool.close().await;
    let old = download(format!("/v1/models/{model_id}/atlases/0")).await;
    let problem = expect_problem(old, StatusCode::CONFLICT, "model.unsupported_version").await;
    assert!(
        problem["detail"].as_str().unwrap().contains("format 2"),
        "{problem}"
    );
    let response = s
        .client
        .post(&url_of_cohorts)
        .json(&json!({"size": 2}))
        .send()
        .await
        .unwrap();
    expect_problem(response, StatusCode::CONFLICT, "model.unsupported_version").await;
    get(&s, &format!("/v1/models/{model_id}")).await;
}
