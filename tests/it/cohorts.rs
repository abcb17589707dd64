//! Cohorts off the request path: 201 for small requests, 202 and the worker pool for large
//! ones or `Prefer: respond-async`, paging of members, cancellation while drawing.

use std::time::{Duration, Instant};

use reqwest::StatusCode;
use serde_json::{Value, json};

use cohortforge::store::cohorts::MemberGeometry;

use crate::jobs::fitted_rsmp;
use crate::support::{TestServer, expect_json, expect_problem};

async fn get(s: &TestServer, path: &str) -> reqwest::Response {
    s.client.get(s.url(path)).send().await.unwrap()
}

/// Polls a cohort until `done` says so.
async fn poll_cohort(s: &TestServer, id: &str, done: impl Fn(&Value) -> bool) -> Value {
    let started = Instant::now();
    loop {
        let cohort = expect_json(get(s, &format!("/v1/cohorts/{id}")).await, StatusCode::OK).await;
        if done(&cohort) {
            return cohort;
        }
        assert!(
            started.elapsed() < Duration::from_secs(300),
            "cohort did not get there in time: {cohort}"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

async fn member_obj(s: &TestServer, cohort: &str, index: usize) -> Vec<u8> {
    let response = get(
        s,
        &format!("/v1/cohorts/{cohort}/members/{index}/file?format=obj"),
    )
    .await;
    assert_eq!(response.status(), StatusCode::OK);
    response.bytes().await.unwrap().to_vec()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn large_cohorts_are_drawn_by_the_workers_and_paged() {
    let s = TestServer::start_with(|c| c.sync_cohort_max = 5).await;
    let model = fitted_rsmp(&s, 10, 0.2).await;
    let url = s.url(&format!("/v1/models/{model}/cohorts"));

    // Above the limit: 202, queued, no members yet, drawn by a worker.
    let request = json!({"size": 12, "seed": 7});
    let response = s.client.post(&url).json(&request).send().await.unwrap();
    let location = response.headers()["location"].to_str().unwrap().to_owned();
    let queued = expect_json(response, StatusCode::ACCEPTED).await;
    let id = queued["id"].as_str().unwrap().to_owned();
    assert_eq!(location, format!("/v1/cohorts/{id}"));
    assert!(
        matches!(queued["status"].as_str(), Some("queued" | "running")),
        "{queued}"
    );
    assert!(queued["members"].is_null() && queued["report"].is_null());
    assert_eq!(queued["size"], 12);
    let done = poll_cohort(&s, &id, |c| {
        c["status"] != "queued" && c["status"] != "running"
    })
    .await;
    assert_eq!(done["status"], "succeeded", "{done}");
    assert_eq!(done["member_count"], 12);
    assert_eq!(done["progress"]["fraction"], 1.0);
    assert!(done["report"]["biomarkers"]["volume_ml"].is_object());
    // 8 training meshes: the near-copy threshold compares like with like.
    assert_eq!(
        done["report"]["privacy"]["threshold_basis"],
        "leave_one_out_projection"
    );
    assert!(
        done["members"].is_null(),
        "12 members are above the inline limit of 5"
    );

    // Pages of members, in order.
    let page = expect_json(
        get(&s, &format!("/v1/cohorts/{id}/members?limit=5&offset=10")).await,
        StatusCode::OK,
    )
    .await;
    assert_eq!(
        (page["total"].as_i64(), page["limit"].as_i64()),
        (Some(12), Some(5))
    );
    let items = page["items"].as_array().unwrap();
    assert_eq!(items.len(), 2);
    assert_eq!(
        (items[0]["index"].as_u64(), items[1]["index"].as_u64()),
        (Some(10), Some(11))
    );
    assert!(items[0]["biomarkers"]["volume_ml"].as_f64().unwrap() > 0.0);
    assert!(items[0]["accepted"]["mean"].is_boolean());
    expect_problem(
        get(&s, &format!("/v1/cohorts/{id}/members?offset=-1")).await,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;

    // Small: 201 with the members inline; the same members as the worker drew.
    let small = json!({"size": 4, "seed": 7});
    let inline = expect_json(
        s.client.post(&url).json(&small).send().await.unwrap(),
        StatusCode::CREATED,
    )
    .await;
    assert_eq!(inline["status"], "succeeded");
    assert_eq!(inline["members"].as_array().unwrap().len(), 4);
    let inline_id = inline["id"].as_str().unwrap();
    assert_eq!(
        member_obj(&s, &id, 3).await,
        member_obj(&s, inline_id, 3).await,
        "the worker and the request path must draw identical members"
    );
    // Shapes are not stored: they are drawn again on download, checked by their checksum.
    match s.store.cohort_member_geometry(&id, 3).await.unwrap() {
        MemberGeometry::Redraw { draw, mesh_sha256 } => {
            assert_eq!((draw, mesh_sha256.len()), (3, 64));
        }
        other => panic!("member 3 was stored: {other:?}"),
    }

    // Small but asked to be asynchronous.
    let response = s
        .client
        .post(&url)
        .header("prefer", "respond-async, wait=10")
        .json(&small)
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()["preference-applied"], "respond-async");
    let asked = expect_json(response, StatusCode::ACCEPTED).await;
    let asked_id = asked["id"].as_str().unwrap();
    let asked = poll_cohort(&s, asked_id, |c| c["status"] == "succeeded").await;
    assert_eq!(asked["members"].as_array().unwrap().len(), 4);
    let jobs = expect_json(get(&s, "/v1/jobs?kind=cohort").await, StatusCode::OK).await;
    assert_eq!(jobs["total"], 2, "{jobs}");
    assert!(jobs["items"][0]["cohort_id"] == asked_id);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cohort_is_cancelled_while_it_is_drawn() {
    let s = TestServer::start().await;
    let model = fitted_rsmp(&s, 10, 0.2).await;
    let url = s.url(&format!("/v1/models/{model}/cohorts"));
    // Members above the training range of volume (a target the model reaches) that must
    // also lie inside that range (`only_accepted` by range) never exist: the only worker
    // draws until it has made 20 draws a member, far longer than the test needs.
    let probe = expect_json(
        s.client
            .post(&url)
            .json(&json!({"size": 3}))
            .send()
            .await
            .unwrap(),
        StatusCode::CREATED,
    )
    .await;
    let volume = &probe["report"]["biomarkers"]["volume_ml"]["reference"];
    let (low, high) = (
        volume["min"].as_f64().unwrap(),
        volume["max"].as_f64().unwrap(),
    );
    let strict = json!({"size": 10_000, "seed": 3, "only_accepted": true,
        "acceptance": {"criterion": "range"},
        "targets": {"volume_ml": {"min": high + 0.1 * (high - low)}}});
    let big = expect_json(
        s.client.post(&url).json(&strict).send().await.unwrap(),
        StatusCode::ACCEPTED,
    )
    .await;
    let id = big["id"].as_str().unwrap().to_owned();
    let running = poll_cohort(&s, &id, |c| {
        c["status"] == "running" && c["progress"]["stage"] == "sampling"
    })
    .await;
    assert!(running["progress"]["step"].as_u64().unwrap() < 10_000);

    // A second one waits in the queue behind it.
    let waiting = expect_json(
        s.client
            .post(&url)
            .header("prefer", "respond-async")
            .json(&json!({"size": 3}))
            .send()
            .await
            .unwrap(),
        StatusCode::ACCEPTED,
    )
    .await;
    let waiting_id = waiting["id"].as_str().unwrap();
    let not_ready = expect_problem(
        get(&s, &format!("/v1/cohorts/{waiting_id}/members/0/file")).await,
        StatusCode::CONFLICT,
        "cohort.not_ready",
    )
    .await;
    assert_eq!(not_ready["cohort_status"], "queued");
    let cancelled = expect_json(
        s.client
            .post(s.url(&format!("/v1/cohorts/{waiting_id}/cancel")))
            .send()
            .await
            .unwrap(),
        StatusCode::ACCEPTED,
    )
    .await;
    assert_eq!(
        cancelled["status"], "cancelled",
        "a queued cohort stops at once"
    );

    let response = s
        .client
        .post(s.url(&format!("/v1/cohorts/{id}/cancel")))
        .send()
        .await
        .unwrap();
    expect_json(response, StatusCode::ACCEPTED).await;
    let ended = poll_cohort(&s, &id, |c| c["status"] != "running").await;
    assert_eq!(ended["status"], "cancelled", "{ended}");
    assert_eq!(
        ended["member_count"], 0,
        "nothing of a cancelled cohort is kept"
    );
    expect_problem(
        get(&s, &format!("/v1/cohorts/{id}/members")).await,
        StatusCode::CONFLICT,
        "cohort.not_ready",
    )
    .await;
    expect_problem(
        s.client
            .post(s.url(&format!("/v1/cohorts/{id}/cancel")))
            .send()
            .await
            .unwrap(),
        StatusCode::CONFLICT,
        "cohort.already_finished",
    )
    .await;
    // The worker is free again.
    let next = expect_json(
        s.client
            .post(&url)
            .header("prefer", "respond-async")
            .json(&json!({"size": 2}))
            .send()
            .await
            .unwrap(),
        StatusCode::ACCEPTED,
    )
    .await;
    let next = poll_cohort(&s, next["id"].as_str().unwrap(), |c| {
        c["status"] == "succeeded"
    })
    .await;
    assert_eq!(next["member_count"], 2);
}
