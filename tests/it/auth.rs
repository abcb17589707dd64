//! Bearer tokens: admin may do everything, read may only GET; probes stay open.

use reqwest::StatusCode;
use serde_json::json;

use crate::support::{TestServer, expect_json, expect_problem};

const ADMIN: &str = "admin-token-for-tests-0001";
const READ: &str = "read-token-for-tests-00001";

#[tokio::test]
async fn tokens_guard_v1_by_scope() {
    let s = TestServer::start_with(|c| {
        c.admin_token = Some(ADMIN.into());
        c.read_token = Some(READ.into());
    })
    .await;
    let create = |token: Option<&str>| {
        let mut request = s
            .client
            .post(s.url("/v1/datasets"))
            .json(&json!({"name": "a", "organ": "lv"}));
        if let Some(t) = token {
            request = request.bearer_auth(t);
        }
        request.send()
    };
    expect_problem(
        create(None).await.unwrap(),
        StatusCode::UNAUTHORIZED,
        "auth.missing_token",
    )
    .await;
    expect_problem(
        create(Some("not-the-token-at-all")).await.unwrap(),
        StatusCode::UNAUTHORIZED,
        "auth.invalid_token",
    )
    .await;
    expect_problem(
        create(Some(READ)).await.unwrap(),
        StatusCode::FORBIDDEN,
        "auth.read_only",
    )
    .await;
    let created = expect_json(create(Some(ADMIN)).await.unwrap(), StatusCode::CREATED).await;
    let id = created["id"].as_str().unwrap();

    let read = s
        .client
        .get(s.url(&format!("/v1/datasets/{id}")))
        .bearer_auth(READ)
        .send()
        .await
        .unwrap();
    expect_json(read, StatusCode::OK).await;
    let anonymous = s.client.get(s.url("/v1/datasets")).send().await.unwrap();
    expect_problem(anonymous, StatusCode::UNAUTHORIZED, "auth.missing_token").await;
    let delete = s
        .client
        .delete(s.url(&format!("/v1/datasets/{id}")))
        .bearer_auth(READ)
        .send()
        .await
        .unwrap();
    expect_problem(delete, StatusCode::FORBIDDEN, "auth.read_only").await;

    for open in ["/healthz", "/readyz", "/openapi.json"] {
        let response = s.client.get(s.url(open)).send().await.unwrap();
        assert_eq!(response.status(), StatusCode::OK, "{open}");
    }
}

#[tokio::test]
async fn without_tokens_the_api_is_open_on_loopback() {
    let s = TestServer::start().await;
    let response = s.client.get(s.url("/v1/datasets")).send().await.unwrap();
    expect_json(response, StatusCode::OK).await;
}
