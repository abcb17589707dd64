//! Every malformed file in tests/fixtures/bad gets its 4xx and stable code, and nothing is stored.

use cohortforge::mesh::phantom::{self, Family};
use cohortforge::mesh::{Format, io};
use reqwest::StatusCode;

use crate::support::{TestServer, crate_dir, expect_problem};

fn status_of(code: &str) -> StatusCode {
    match code {
        "mesh.too_large" => StatusCode::PAYLOAD_TOO_LARGE,
        "mesh.unsupported_format" => StatusCode::UNSUPPORTED_MEDIA_TYPE,
        _ => StatusCode::UNPROCESSABLE_ENTITY,
    }
}

#[tokio::test]
async fn malformed_corpus_is_refused_with_stable_codes() {
    let s = TestServer::start().await;
    let dataset = s.dataset("bad", "lv").await;
    let dir = crate_dir().join("tests/fixtures/bad");
    let manifest = std::fs::read_to_string(dir.join("manifest.csv")).expect("manifest.csv");
    let mut cases = 0;
    for line in manifest.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let [file, format, code] = fields[..] else {
            panic!("bad manifest line: {line}")
        };
        let bytes = std::fs::read(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let response = s.upload(&dataset, format, bytes).await;
        let body = expect_problem(response, status_of(code), code).await;
        assert!(
            body["detail"].as_str().unwrap().len() > 20,
            "{file}: detail too thin: {body}"
        );
        assert_eq!(s.mesh_count(&dataset).await, 0, "{file} left a mesh behind");
        cases += 1;
    }
    assert!(cases >= 20, "the corpus holds only {cases} cases");
}

#[tokio::test]
async fn unknown_content_type_is_unsupported_media_type() {
    let s = TestServer::start().await;
    let dataset = s.dataset("bad", "lv").await;
    let url = s.url(&format!("/v1/datasets/{dataset}/meshes"));
    let response = s
        .client
        .post(&url)
        .header("content-type", "image/png")
        .body(vec![1, 2, 3])
        .send()
        .await
        .unwrap();
    expect_problem(
        response,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "mesh.unsupported_format",
    )
    .await;
    let response = s.client.post(&url).body("v 0 0 0").send().await.unwrap();
    expect_problem(
        response,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "mesh.unsupported_format",
    )
    .await;
    let response = s
        .client
        .post(format!("{url}?format=dicom"))
        .body("x")
        .send()
        .await
        .unwrap();
    expect_problem(
        response,
        StatusCode::UNSUPPORTED_MEDIA_TYPE,
        "mesh.unsupported_format",
    )
    .await;
    assert_eq!(s.mesh_count(&dataset).await, 0);
}

#[tokio::test]
async fn limits_on_body_size_and_vertex_count() {
    let s = TestServer::start_with(|c| {
        c.max_body_bytes = 64 * 1024;
        c.max_vertices = 500;
    })
    .await;
    let dataset = s.dataset("limits", "lv").await;
    let lv = &phantom::generate(Family::Lv, 1, 2)[0];
    let big = s.upload(&dataset, "obj", vec![b'#'; 65 * 1024]).await;
    expect_problem(big, StatusCode::PAYLOAD_TOO_LARGE, "request.body_too_large").await;
    let many = s
        .upload(&dataset, "ply", io::write(&lv.mesh, Format::Ply))
        .await;
    let body = expect_problem(many, StatusCode::PAYLOAD_TOO_LARGE, "mesh.too_large").await;
    assert!(body["detail"].as_str().unwrap().contains("500"), "{body}");
    assert_eq!(s.mesh_count(&dataset).await, 0);
}
