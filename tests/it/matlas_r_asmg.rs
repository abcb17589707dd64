//! The `matlas-r-asmg` model type end to end: small phantoms of two sub-populations (beans
//! of genus 0, rings of genus 1) → a model of two atlases → its clusters, its atlases, and
//! a cohort whose members come from both, each with its cluster's connectivity.

use std::time::Duration;

use cohortforge::mesh::phantom::Family;
use cohortforge::mesh::validate::{IngestOptions, ingest};
use cohortforge::mesh::{Format, io};
use reqwest::StatusCode;
use serde_json::json;

use crate::asmg::{get, submit, tiny_params, upload_phantoms, wait_for};
use crate::support::{TestServer, expect_json};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mixed_phantoms_to_two_atlases_and_a_cohort_of_both() {
    let s = TestServer::start().await;
    let dataset = upload_phantoms(&s, Family::Mixed, 12, 5).await;
    let mut params = tiny_params();
    params["atlases"] = json!(2);
    params["epochs_refine"] = json!(1);
    let body = json!({"dataset_id": dataset, "model_type": "matlas-r-asmg", "params": params,
        "seed": 3, "holdout_fraction": 0.2});
    let job = submit(&s, &body).await;
    let (done, _) = wait_for(&s, job["id"].as_str().unwrap(), Duration::from_secs(600)).await;
    assert_eq!(done["status"], "succeeded", "{done}");

    let model_id = done["model_id"].as_str().unwrap();
    let model = get(&s, &format!("/v1/models/{model_id}")).await;
    assert_eq!(model["params"]["atlases"], 2);
    let clusters = &model["clusters"];
    let atlases = clusters["atlases"].as_array().unwrap();
    assert_eq!(atlases.len(), 2);
    let mut chi: Vec<i64> = atlases
        .iter()
        .map(|a| a["euler_characteristic"].as_i64().unwrap())
        .collect();
    chi.sort();
    assert_eq!(chi, [0, 2], "a genus-1 and a genus-0 atlas: {atlases:?}");
    let prior_sum: f64 = atlases.iter().map(|a| a["prior"].as_f64().unwrap()).sum();
    assert!((prior_sum - 1.0).abs() < 1e-9);
    let assignments = clusters["assignments"].as_array().unwrap();
    assert_eq!(assignments.len(), 12, "every training and held-out mesh");
    // Ten or so training meshes over two clusters: each generator learns from a few
    // effective training meshes, and the model says so.
    let training = model["training_count"].as_f64().unwrap();
    for a in atlases {
        let e = a["effective_meshes"].as_f64().unwrap();
        assert!(e >= 1.0 && e <= training, "{a}");
    }
    let note = clusters["note"].as_str().unwrap_or_default();
    assert!(note.contains("effective training meshes"), "{clusters}");
    for a in assignments {
        let w: Vec<f64> = serde_json::from_value(a["weights"].clone()).unwrap();
        assert_eq!(w.len(), 2);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{a}");
        let best = if w[0] >= w[1] { 0 } else { 1 };
        assert_eq!(a["cluster"], best, "{a}");
    }

    // The atlases download with their own vertex counts.
    for (m, atlas) in atlases.iter().enumerate() {
        let bytes = s
            .get_bytes(s.url(&format!("/v1/models/{model_id}/atlases/{m}?format=obj")))
            .await;
        let mesh = io::read(&bytes, Format::Obj, &Default::default()).unwrap();
        assert_eq!(
            mesh.vertex_count() as u64,
            atlas["vertex_count"].as_u64().unwrap()
        );
    }

    // A cohort from both clusters: each member closed, with its cluster's vertex count.
    let url = s.url(&format!("/v1/models/{model_id}/cohorts"));
    let cohort = expect_json(
        s.client
            .post(&url)
            .json(&json!({"size": 24, "seed": 2}))
            .send()
            .await
            .unwrap(),
        StatusCode::CREATED,
    )
    .await;
    let cohort_id = cohort["id"].as_str().unwrap();
    let members = cohort["members"].as_array().unwrap();
    let of = |c: u64| members.iter().position(|m| m["cluster"] == c);
    let (Some(first), Some(second)) = (of(0), of(1)) else {
        panic!("24 members all from one cluster: {members:?}");
    };
    let mut counts = Vec::new();
    for index in [first, second] {
        let bytes = s
            .get_bytes(s.url(&format!(
                "/v1/cohorts/{cohort_id}/members/{index}/file?format=obj"
            )))
            .await;
        let parsed = ingest(&bytes, Format::Obj, &IngestOptions::default()).unwrap();
        assert!(parsed.summary.watertight, "member {index} is not closed");
        let cluster = members[index]["cluster"].as_u64().unwrap() as usize;
        assert_eq!(
            parsed.summary.euler_characteristic,
            atlases[cluster]["euler_characteristic"].as_i64().unwrap()
        );
        counts.push(
            io::read(&bytes, Format::Obj, &Default::default())
                .unwrap()
                .vertex_count(),
        );
    }
    for (c, count) in counts.iter().enumerate() {
        assert_eq!(*count as u64, atlases[c]["vertex_count"].as_u64().unwrap());
    }
    let rows = cohort["report"]["clusters"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    let total: u64 = rows.iter().map(|r| r["count"].as_u64().unwrap()).sum();
    assert_eq!(total, 24);

    // The pages, as a browser shows them: the model's atlases and weight matrix, the
    // cohort's per-cluster table.
    let page =
        crate::reports::rendered_page(&s, &format!("/v1/models/{model_id}/report.html")).await;
    assert!(
        page.contains("<h2>Atlases and clusters</h2>"),
        "model page without clusters"
    );
    assert!(
        page.contains("class=\"weights\""),
        "model page without the weight matrix"
    );
    let page =
        crate::reports::rendered_page(&s, &format!("/v1/cohorts/{cohort_id}/report.html")).await;
    assert!(
        page.contains("<h2>Clusters</h2>") && page.contains("<th>cluster 1</th>"),
        "{page}"
    );
}
