//! The checked-in OpenAPI document equals what the service serves.

use reqwest::StatusCode;

use crate::support::{TestServer, crate_dir, expect_json};

#[tokio::test]
async fn checked_in_spec_matches_served_spec() {
    let s = TestServer::start().await;
    let served = expect_json(
        s.client.get(s.url("/openapi.json")).send().await.unwrap(),
        StatusCode::OK,
    )
    .await;
    let path = crate_dir().join("openapi/openapi.json");
    if std::env::var_os("UPDATE_OPENAPI").is_some() {
        let text = serde_json::to_string_pretty(&served).unwrap() + "\n";
        std::fs::write(&path, text).unwrap();
    }
    let checked_in: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap_or_default())
            .unwrap_or_default();
    assert!(
        checked_in == served,
        "openapi/openapi.json is stale: regenerate it with `UPDATE_OPENAPI=1 cargo test --test it openapi`"
    );
    for path in [
        "/v1/datasets",
        "/v1/datasets/{id}/meshes",
        "/v1/meshes/{id}/file",
        "/healthz",
    ] {
        assert!(
            served["paths"][path].is_object(),
            "{path} is not documented"
        );
    }
}

#[tokio::test]
async fn interactive_docs_are_served() {
    let s = TestServer::start().await;
    let response = s.client.get(s.url("/docs/")).send().await.unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let html = response.text().await.unwrap();
    assert!(html.contains("swagger"), "not the docs page");
}
