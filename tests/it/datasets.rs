//! Datasets: create, list, get, delete, and invalid requests.

use reqwest::StatusCode;
use serde_json::json;

use crate::support::{TestServer, expect_json, expect_problem};

#[tokio::test]
async fn dataset_lifecycle() {
    let s = TestServer::start().await;
    let response = s
        .client
        .post(s.url("/v1/datasets"))
        .json(&json!({"name": "lv phantoms", "organ": "lv"}))
        .send()
        .await
        .unwrap();
    let location = response.headers()["location"].to_str().unwrap().to_owned();
    let created = expect_json(response, StatusCode::CREATED).await;
    let id = created["id"].as_str().unwrap();
    assert_eq!(location, format!("/v1/datasets/{id}"));
    assert_eq!(created["name"], "lv phantoms");
    assert_eq!(created["mesh_count"], 0);

    let got = expect_json(
        s.client.get(s.url(&location)).send().await.unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(got, created);

    s.dataset("second", "liver").await;
    let list = expect_json(
        s.client
            .get(s.url("/v1/datasets?limit=1"))
            .send()
            .await
            .unwrap(),
        StatusCode::OK,
    )
    .await;
    assert_eq!(list["total"], 2);
    assert_eq!(list["items"].as_array().unwrap().len(), 1);
    assert_eq!(list["items"][0]["id"], id);

    let deleted = s.client.delete(s.url(&location)).send().await.unwrap();
    assert_eq!(deleted.status(), StatusCode::NO_CONTENT);
    let gone = s.client.get(s.url(&location)).send().await.unwrap();
    expect_problem(gone, StatusCode::NOT_FOUND, "dataset.not_found").await;
    let again = s.client.delete(s.url(&location)).send().await.unwrap();
    expect_problem(again, StatusCode::NOT_FOUND, "dataset.not_found").await;
}

#[tokio::test]
async fn invalid_dataset_requests_name_the_problem() {
    let s = TestServer::start().await;
    let post = |body: serde_json::Value| s.client.post(s.url("/v1/datasets")).json(&body).send();

    let missing = post(json!({"name": "x"})).await.unwrap();
    expect_problem(
        missing,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;
    let unknown = post(json!({"name": "x", "organ": "lv", "colour": "red"}))
        .await
        .unwrap();
    let body = expect_problem(
        unknown,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;
    assert!(
        body["detail"].as_str().unwrap().contains("colour"),
        "{body}"
    );
    let blank = post(json!({"name": "  ", "organ": "lv"})).await.unwrap();
    let body = expect_problem(
        blank,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;
    assert_eq!(body["field"], "name");
    let long = post(json!({"name": "x", "organ": "o".repeat(65)}))
        .await
        .unwrap();
    let body = expect_problem(
        long,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;
    assert_eq!(body["field"], "organ");

    let malformed = s
        .client
        .post(s.url("/v1/datasets"))
        .header("content-type", "application/json")
        .body("{\"name\": ")
        .send()
        .await
        .unwrap();
    expect_problem(malformed, StatusCode::BAD_REQUEST, "request.malformed_json").await;
    let not_json = s
        .client
        .post(s.url("/v1/datasets"))
        .body("name=x")
        .send()
        .await
        .unwrap();
    expect_problem(
        not_json,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "request.unsupported_media_type",
    )
    .await;
    let bad_page = s
        .client
        .get(s.url("/v1/datasets?limit=0"))
        .send()
        .await
        .unwrap();
    expect_problem(
        bad_page,
        StatusCode::UNPROCESSABLE_ENTITY,
        "request.invalid_field",
    )
    .await;

    let (items, total) = s
        .store
        .datasets(cohortforge::store::Page {
            limit: 10,
            offset: 0,
        })
        .await
        .unwrap();
    assert!(
        items.is_empty() && total == 0,
        "a refused request stored a dataset"
    );
}

#[tokio::test]
async fn unknown_routes_and_methods_are_problems_with_request_ids() {
    let s = TestServer::start().await;
    let response = s
        .client
        .get(s.url("/v1/nothing-here"))
        .send()
        .await
        .unwrap();
    assert!(response.headers().contains_key("x-request-id"));
    expect_problem(response, StatusCode::NOT_FOUND, "request.no_route").await;
    let response = s.client.put(s.url("/v1/datasets")).send().await.unwrap();
    expect_problem(
        response,
        StatusCode::METHOD_NOT_ALLOWED,
        "request.method_not_allowed",
    )
    .await;
    let response = s
        .client
        .get(s.url("/healthz"))
        .header("x-request-id", "client-chosen-id")
        .send()
        .await
        .unwrap();
    assert_eq!(response.headers()["x-request-id"], "client-chosen-id");
    let ready = s.client.get(s.url("/readyz")).send().await.unwrap();
    assert_eq!(expect_json(ready, StatusCode::OK).await["status"], "ok");
}
